"""Build the scene of a case's builder entries (``scene.wall``, ``scene.facade``, ``scene.box_model``)."""

from __future__ import annotations

from dem.builders.box_model import build_box_model
from dem.builders.facade import build_facade
from dem.builders.spec import BoxModelSpec, FacadeSpec, WallSpec
from dem.builders.wall import build_wall
from dem.scene import Scene


def _placement(spec) -> dict:
    return dict(brick=spec.brick, origin=spec.origin, yaw=spec.yaw, min_piece=spec.min_piece)


def build_from_spec(spec: WallSpec | FacadeSpec | BoxModelSpec) -> Scene:
    """Scene of one builder entry of a case file, its groups given the materials of the
    entry's ``materials: {group: name}`` (the others are brick)."""
    scene = _build(spec)
    if spec.materials:
        scene.set_materials({g: m for g, m in spec.materials.items() if g in scene.group_names})
    return scene


def _build(spec: WallSpec | FacadeSpec | BoxModelSpec) -> Scene:
    if isinstance(spec, WallSpec):
        return build_wall(
            length=spec.length, courses=spec.courses, bond=spec.bond, laying=spec.laying,
            stagger=spec.stagger, flush_ends=spec.flush_ends, group=spec.group, **_placement(spec),
        )
    if isinstance(spec, FacadeSpec):
        return build_facade(
            length=spec.length, courses=spec.courses, left=spec.left, right=spec.right,
            laying=spec.laying, stagger=spec.stagger, flush_ends=spec.flush_ends, **_placement(spec),
        )
    if isinstance(spec, BoxModelSpec):
        return build_box_model(
            model=spec.model, length=spec.length, width=spec.width, courses=spec.n_courses,
            roof=spec.roof, corners=spec.corners, **_placement(spec),
        )
    raise TypeError(f"not a builder spec: {type(spec).__name__}")
