"""Scene builders: brick presets, walls, facades with wings, the shaking-table box models, and
the checks every built scene goes through (overlaps, floating blocks, report).

All builders return a :class:`dem.scene.Scene` (m, kg, table frame, z up, the table plane z = 0)
of axis-aligned boxes, with group names and course indices (0 = bottom course).

    from dem.builders import build_wall, build_facade, Wing, build_box_model, check_scene
    wall = build_wall("small", length=9, courses=15)            # 142 blocks
    facade = build_facade("large", 5, 9, left=Wing(3, "poor"), right=Wing(3, "strong"))
    model = build_box_model("II")                               # 198 bricks + roof
    print(check_scene(model).format())

Layering: builders import dem.scene and their own spec models (dem.builders.spec), never the case
schema; the schema (dem.case) imports the specs, and dem.run.build turns a case into a scene.
"""

from __future__ import annotations

from dem.builders.box_model import build_box_model
from dem.builders.bricks import FRICTION, PRESETS, Brick, brick
from dem.builders.checks import SceneError, SceneReport, block_label, check_scene, require_valid
from dem.builders.facade import Wing, build_facade, corner_lap
from dem.builders.from_spec import build_from_spec
from dem.builders.wall import build_wall

__all__ = ["Brick", "FRICTION", "PRESETS", "SceneError", "SceneReport", "Wing", "block_label",
           "brick", "build_box_model", "build_facade", "build_from_spec", "build_wall",
           "check_scene", "corner_lap", "require_valid"]
