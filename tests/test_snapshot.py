"""PNG snapshots render off-screen (pyvista on this headless machine) and show the scene."""

from __future__ import annotations

import numpy as np
from PIL import Image

from dem.builders import build_box_model
from dem.output.snapshot import matplotlib_snapshot, snapshot_png


def _colours(path) -> int:
    img = np.asarray(Image.open(path).convert("RGB"))
    return len(np.unique(img.reshape(-1, 3), axis=0)), img.shape


def test_snapshot_png_offscreen(tmp_path):
    s = build_box_model("II")
    used = snapshot_png(tmp_path / "a.png", s, s.position, s.quat, title="Model II", window_size=(400, 300))
    assert used == "pyvista"  # off-screen OpenGL (EGL / OSMesa) works here
    n, shape = _colours(tmp_path / "a.png")
    assert shape == (300, 400, 3) and n > 20  # not a blank image
    # coloured by a per-block value (e.g. displacement) instead of the group
    d = np.linalg.norm(s.position, axis=1)
    snapshot_png(tmp_path / "b.png", s, s.position, s.quat, scalars=d, window_size=(400, 300))
    assert _colours(tmp_path / "b.png")[0] > 20


def test_matplotlib_fallback(tmp_path):
    s = build_box_model("I", courses=2, roof=None)
    matplotlib_snapshot(tmp_path / "c.png", s, s.position, s.quat, None, "fallback", (400, 300))
    n, shape = _colours(tmp_path / "c.png")
    assert shape == (300, 400, 3) and n > 20
