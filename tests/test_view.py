"""``dem view DIR`` (a look at a run without ParaView): an animation and a frame
strip drawn off-screen from frames.npz, on a tilt, a shake, a sweep and an ensemble directory
(tests/view_runs.py), and the geometry of the drawing (dem.output.animation) against closed
forms: a block resting on a tilted table lies on the table's plane, a magnified motion is the
motion times the factor (displacement and rotation angle)."""

from __future__ import annotations

import json

import numpy as np
import pytest
from PIL import Image
from scipy.spatial.transform import Rotation
from typer.testing import CliRunner

from dem import quaternion
from dem_cli.app import app
from dem.output import animation
from dem.output.vtk import block_corners, rotation_angle_deg


def _view(*args):
    return CliRunner().invoke(app, ["view", *map(str, args)])


def _gif_frames(path) -> int:
    with Image.open(path) as im:
        return im.n_frames


@pytest.mark.parametrize("kind", ["tilt", "shake"])
def test_view_of_a_run_writes_an_animation_and_a_strip(view_runs, tmp_path, kind):
    out = tmp_path / kind
    res = _view(view_runs[kind], "--out", out, "--frames", "7", "--panels", "3")
    assert res.exit_code == 0, res.output
    with np.load(view_runs[kind] / "frames.npz") as z:
        n = len(z["t"])
    assert n > 7
    assert _gif_frames(out / "animation.gif") == 7          # --frames of the n recorded
    with Image.open(out / "strip.png") as im:
        assert im.width > 2.5 * im.height                   # three panels side by side
    assert f"7 of {n} frames" in res.output and "3 panels" in res.output
    if kind == "shake":  # millimetres on a 0.2 m block: drawn magnified, and said so
        assert "relative to the table drawn x" in res.output
    assert not (view_runs[kind] / "animation.gif").exists()  # --out was honoured


def test_view_of_a_sweep_draws_the_point_of_largest_amplification_or_the_one_asked(view_runs,
                                                                                  tmp_path):
    sweep = view_runs["sweep"]
    points = json.loads((sweep / "sweep.json").read_text())["points"]
    best = max(points, key=lambda p: p["amplification"]["ds"])
    res = _view(sweep, "--out", tmp_path / "a", "--frames", "4", "--panels", "2")
    assert res.exit_code == 0, res.output
    assert f"drawing {best['dir']}: the largest ds amplification" in res.output
    assert _gif_frames(tmp_path / "a" / "animation.gif") == 4
    other = next(p for p in points if p["dir"] != best["dir"])
    for point in (other["dir"], f"{other['frequency_hz']:g}"):      # by name or by Hz
        res = _view(sweep, "--out", tmp_path / "b", "--point", point, "--frames", "3",
                    "--panels", "2")
        assert res.exit_code == 0, res.output
        assert f"drawing {other['dir']}" in res.output
    res = _view(sweep, "--point", "f9.999Hz")
    assert res.exit_code == 2 and "no point 'f9.999Hz'" in res.output


def test_view_of_an_ensemble_draws_the_realisation_nearest_the_median(view_runs, tmp_path):
    ens = view_runs["ensemble"]
    rows = json.loads((ens / "ensemble.json").read_text())["realisations"]
    med = float(np.median([r["lambda"] for r in rows]))
    nearest = min(rows, key=lambda r: (abs(r["lambda"] - med), r["name"]))
    res = _view(ens, "--out", tmp_path, "--frames", "3", "--panels", "2")
    assert res.exit_code == 0, res.output
    assert f"drawing {nearest['name']}: lambda" in res.output
    assert (tmp_path / "animation.gif").is_file() and (tmp_path / "strip.png").is_file()
    res = _view(ens, "--point", "seed-99")
    assert res.exit_code == 2 and "seed-99" in res.output


def test_view_refuses_bad_input_with_exit_2(view_runs, tmp_path):
    empty = tmp_path / "empty"
    empty.mkdir()
    assert _view(empty).exit_code == 2
    res = _view(view_runs["tilt"], "--format", "avi")
    assert res.exit_code == 2 and "--format" in res.output
    res = _view(view_runs["tilt"], "--frames", "0")
    assert res.exit_code == 2 and "--frames" in res.output
    res = _view(view_runs["tilt"], "--point", "seed-1")
    assert res.exit_code == 2 and "--point" in res.output
    if not animation.ffmpeg_available():
        res = _view(view_runs["tilt"], "--format", "mp4")
        assert res.exit_code == 2 and "ffmpeg" in res.output


def test_a_block_on_the_tilted_table_lies_on_the_drawn_table():
    """A block resting on the table (its bottom at z = 0 in the table frame), the table turned
    by 20 deg about y: in the drawing its four bottom corners lie in the plane of the drawn
    table's corners (to rounding), and the block leans by the table's angle."""
    size = np.array([[0.2, 0.1, 0.4]])
    pos = np.array([[[0.05, 0.0, 0.2]]] * 2)
    quat = np.array([[[1.0, 0.0, 0.0, 0.0]]] * 2)
    poses = animation.lab_poses(size, np.array([0.0, 1.0]), pos, quat,
                                tilt_angle=np.array([0.0, 20.0]),
                                tilt_axis=np.array([0.0, 1.0, 0.0]))
    table = poses.table[1]
    normal = np.cross(table[1] - table[0], table[3] - table[0])
    normal /= np.linalg.norm(normal)
    corners = block_corners(size, poses.pos[1], poses.quat[1])[0]
    bottom = corners[np.argsort(corners @ normal)[:4]]
    assert np.abs((bottom - table[0]) @ normal).max() < 1e-12
    assert np.degrees(np.arccos(abs(normal[2]))) == pytest.approx(20.0, abs=1e-9)
    assert rotation_angle_deg(poses.quat[1], poses.quat[0])[0] == pytest.approx(20.0, abs=1e-9)
    assert np.allclose(poses.disp, 0.0)  # it did not move on the table


def test_magnified_motion_is_the_motion_times_the_factor():
    rng = np.random.default_rng(3)
    pos0 = rng.normal(size=(5, 3))
    q0 = quaternion.from_rotation(Rotation.random(5, random_state=1))
    step = Rotation.from_rotvec(rng.normal(scale=0.01, size=(5, 3)))
    q1 = quaternion.from_rotation(step * quaternion.rotation(q0))
    pos1 = pos0 + rng.normal(scale=1e-3, size=(5, 3))
    p, q = animation.magnified(pos1, q1, pos0, q0, 20.0)
    assert np.allclose(p - pos0, 20.0 * (pos1 - pos0), rtol=0, atol=1e-15)
    assert np.allclose(rotation_angle_deg(q, q0), 20.0 * rotation_angle_deg(q1, q0), rtol=1e-9)
    # the same axis: the magnified rotation vector is parallel to the original one
    rv = (quaternion.rotation(q) * quaternion.rotation(q0).inv()).as_rotvec()
    assert np.allclose(rv, 20.0 * step.as_rotvec(), rtol=1e-9, atol=1e-15)


def test_frame_indices_and_auto_magnification():
    assert animation.frame_indices(100, 5).tolist() == [0, 25, 50, 74, 99]
    assert animation.frame_indices(3, 10).tolist() == [0, 1, 2]
    from dem_cli.commands.view import auto_magnify

    size = np.array([[0.2, 0.2, 0.1]])
    pos = np.zeros((3, 1, 3))
    pos[2, 0, 0] = 1e-4                        # 0.1 mm on a 0.2 m block: 5 % is 10 mm
    k = auto_magnify(size, pos)
    assert k == 100.0 and 1e-4 * k <= 0.05 * 0.2 < 1e-4 * k * 2.5
    pos[2, 0, 0] = 0.05                        # a large motion is drawn as it is
    assert auto_magnify(size, pos) == 1.0


def test_drawings_of_several_blocks(tmp_path):
    """Three blocks of different sizes, three frames: every frame drawn (the GIF's frames), the
    strip written, and the colour of each block is its own displacement on the table."""
    size = np.array([[0.2, 0.1, 0.1], [0.1, 0.1, 0.3], [0.3, 0.2, 0.05]])
    pos0 = np.array([[0.0, 0.0, 0.05], [0.5, 0.0, 0.15], [1.0, 0.0, 0.025]])
    moves = np.array([0.0, 1e-3, 2e-3])
    pos = np.stack([pos0 + np.outer(moves, [1.0, 0.0, 0.0]) * k for k in range(3)])
    quat = np.tile([1.0, 0.0, 0.0, 0.0], (3, 3, 1))
    poses = animation.lab_poses(size, np.array([0.0, 0.1, 0.2]), pos, quat,
                                base_disp=np.zeros((3, 3)))
    assert np.allclose(poses.disp[2], 2 * moves, rtol=0, atol=1e-15)
    animation.write_animation(tmp_path / "a.gif", size, poses, "three")
    animation.write_strip(tmp_path / "s.png", size, poses, "three", panels=3)
    assert _gif_frames(tmp_path / "a.gif") == 3
    assert (tmp_path / "s.png").stat().st_size > 0
