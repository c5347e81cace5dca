"""Scene builders: brick presets, walls, facades with wings, the shaking-table box models, and
the checks every built scene goes through (overlaps, floating blocks, report).

All builders return a :class:`dem.scene.Scene` (m, kg, table frame, z up, the table plane z = 0)
of axis-aligned boxes, with group names and course indices (0 = bottom course).

    from dem.builders import build_wall, build_facade, Wing, build_box_model, check_scene
    wall = build_wall("small", length=9, courses=15)            # 142 blocks
    facade = build_facade("large", 5, 9, left=Wing(3, "poor"), right=Wing(3, "strong"))
    model = build_box_model("II")                               # 198 bricks + roof
    print(check_scene(model).format())

The submodules are imported lazily so that :mod:`dem.case` can import :mod:`dem.builders.spec`
without an import cycle (dem.case -> dem.builders.spec; dem.builders.wall -> dem.scene -> dem.case).
"""

from __future__ import annotations

import importlib

_EXPORTS = {
    "Brick": "bricks",
    "PRESETS": "bricks",
    "FRICTION": "bricks",
    "brick": "bricks",
    "build_wall": "wall",
    "build_facade": "facade",
    "Wing": "facade",
    "corner_lap": "facade",
    "build_box_model": "box_model",
    "check_scene": "checks",
    "require_valid": "checks",
    "SceneReport": "checks",
    "SceneError": "checks",
    "block_label": "checks",
    "build_from_spec": "from_spec",
}

__all__ = sorted(_EXPORTS)


def __getattr__(name: str):
    if name in _EXPORTS:
        return getattr(importlib.import_module(f"dem.builders.{_EXPORTS[name]}"), name)
    raise AttributeError(f"module 'dem.builders' has no attribute {name!r}")
