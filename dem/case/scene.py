"""``scene:`` of a case file: explicit blocks and the builder entries (wall, facade, box model)."""

from __future__ import annotations

import math

from pydantic import Field, field_validator, model_validator

from dem.builders.spec import BoxModelSpec, FacadeSpec, WallSpec
from dem.case.base import Vec3, StrictModel


class BlockSpec(StrictModel):
    """One rigid box given explicitly."""

    size: Vec3 = Field(description="full edge lengths [lx, ly, lz] in the block's own axes, m")
    position: Vec3 = Field(description="centre [x, y, z] in the table frame, m")
    rotation: Vec3 = Field(
        default=[0.0, 0.0, 0.0],
        description="XYZ Euler angles, degrees (intrinsic x, then y, then z: R = Rx Ry Rz)",
    )
    mass: float | None = Field(default=None, description="kg (give mass or density)")
    density: float | None = Field(default=None, description="kg/m3 (give mass or density)")
    velocity: Vec3 = Field(default=[0.0, 0.0, 0.0], description="initial velocity, m/s")
    angular_velocity: Vec3 = Field(
        default=[0.0, 0.0, 0.0], description="initial angular velocity (table frame), rad/s"
    )
    fixed: bool = Field(default=False, description="a fixed support box (does not move)")
    group: str = Field(default="blocks", description="label used in the output (wall, roof ...)")
    material: str = Field(
        default="brick", min_length=1, exclude_if=lambda v: v == "brick",
        description="the block's material: brick (default), table or a name declared in "
        "material.materials (joint constants per pair of materials: material.pairs)")

    @field_validator("size")
    @classmethod
    def _positive_size(cls, v: list[float]) -> list[float]:
        if any(not (x > 0) or not math.isfinite(x) for x in v):
            raise ValueError(f"every edge length must be > 0 m, got {v}")
        return v

    @field_validator("position", "rotation", "velocity", "angular_velocity")
    @classmethod
    def _finite(cls, v: list[float]) -> list[float]:
        if any(not math.isfinite(x) for x in v):
            raise ValueError(f"must be finite, got {v}")
        return v

    @model_validator(mode="after")
    def _mass_or_density(self) -> "BlockSpec":
        if (self.mass is None) == (self.density is None):
            raise ValueError("give exactly one of mass (kg) or density (kg/m3)")
        value = self.mass if self.mass is not None else self.density
        if not (value > 0) or not math.isfinite(value):
            which = "mass" if self.mass is not None else "density"
            raise ValueError(f"{which} must be > 0, got {value}")
        return self

    def block_mass(self) -> float:
        if self.mass is not None:
            return float(self.mass)
        return float(self.density) * self.size[0] * self.size[1] * self.size[2]


class SceneSpec(StrictModel):
    """The blocks of a scene: explicit ``blocks`` and/or builder entries (``wall``, ``facade``,
    ``box_model``; see :mod:`dem.builders`).  Order in every output array: explicit blocks first,
    then wall, facade, box_model."""

    blocks: list[BlockSpec] = Field(default_factory=list, description="explicit blocks")
    wall: WallSpec | None = Field(default=None, description="a single wall (in-plane specimens)")
    facade: FacadeSpec | None = Field(
        default=None, description="a facade with side walls (out-of-plane specimens)"
    )
    box_model: BoxModelSpec | None = Field(
        default=None, description="a one-storey box model (shaking-table Models I, II, III)"
    )
    allow_floating: bool = Field(
        default=False,
        description="accept blocks that start in the air (else dem check rejects them)",
    )

    @model_validator(mode="after")
    def _not_empty(self) -> "SceneSpec":
        if not (self.blocks or self.wall or self.facade or self.box_model):
            raise ValueError("the scene has no blocks (give blocks, wall, facade or box_model)")
        return self
