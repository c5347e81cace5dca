"""``imperfections:`` of a case file: the geometry of imperfect dry joints as seeded random fields.

Every length is in metres, every angle in degrees, and every parameter is zero by default; zero
reproduces the perfect model bit for bit.  The as-built fields (``corner_gap``, ``head_gap``,
``plumb``: free play where the builders' bricks meet, courses out of plumb) act on builder walls
only and are left out of the case's dump while zero, so recorded cases keep their identity.  What each parameter represents, how it enters the contact law and how to
measure it on real bricks: docs/imperfections.md.  The realisation (the random draws) is made by
:mod:`dem.imperfections`.
"""

from __future__ import annotations

import math
from typing import Annotated, Literal

from pydantic import Field, field_validator

from dem.case.base import Vec3, StrictModel

#: an imperfection may be at most this fraction of the smallest brick dimension
MAX_FRACTION = 0.10
#: the largest gap a draw can give (mean + 3 scatter) may be at most this fraction of the brick
#: length: a larger one is a missing brick, not a loose joint
MAX_GAP_FRACTION = 0.10
#: the largest initial lean of a builder structure, degrees
MAX_LEAN_DEG = 5.0

Vec2 = Annotated[list[float], Field(min_length=2, max_length=2)]


class GapSpec(StrictModel):
    """A gap drawn per joint: mean + scatter z, z a standard normal truncated at -3 and +3 and
    where the gap would be negative (so a gap is never negative), m."""

    mean: float = Field(default=0.0, ge=0.0, description="m: mean gap")
    scatter: float = Field(default=0.0, ge=0.0, description="m: standard deviation of the gap "
                                                             "(before truncation)")

    def any(self) -> bool:
        return self.mean > 0 or self.scatter > 0

    def largest(self) -> float:
        """The largest gap a draw can give, m."""
        return self.mean + 3.0 * self.scatter


class PlumbSpec(StrictModel):
    """Courses out of plumb, in the builder's frame before ``yaw`` (x along a wall or a box
    model's L walls, y across: a facade's outer face is at -y)."""

    sigma: Vec2 = Field(
        default=[0.0, 0.0],
        description="m: standard deviations [sigma_x, sigma_y] of each course's offset from the "
                    "course below (a random walk, steps truncated at 3 sigma); for a wall x is "
                    "in plane and y out of plane")
    lean: Vec2 = Field(
        default=[0.0, 0.0],
        description="degrees: initial lean of the whole structure [about y: its top towards "
                    "+x, about x: its top towards +y]; course k is moved by k h tan(lean)")

    @field_validator("sigma")
    @classmethod
    def _sigma_non_negative(cls, v: list[float]) -> list[float]:
        if any(not (x >= 0) or not math.isfinite(x) for x in v):
            raise ValueError(f"every standard deviation must be >= 0 m, got {v}")
        return v

    @field_validator("lean")
    @classmethod
    def _lean_small(cls, v: list[float]) -> list[float]:
        if any(not math.isfinite(x) or abs(x) > MAX_LEAN_DEG for x in v):
            raise ValueError(f"a lean must be within +-{MAX_LEAN_DEG:g} degrees, got {v}")
        return v

    def any(self) -> bool:
        return any(x > 0 for x in self.sigma) or any(x != 0 for x in self.lean)


class Imperfections(StrictModel):
    bed_unevenness: float = Field(
        default=0.0, ge=0.0,
        description="m: standard deviation of independent random offsets of each face's four "
                    "corners along its normal (a warped face; truncated at 3 sigma)")
    face_shape: Literal["bilinear", "planar"] = Field(
        default="bilinear",
        description="warped faces: 'bilinear' (the four corners as drawn: a twisted face, which "
                    "frees rotation in every joint) or 'planar' (the corners' best-fit plane: "
                    "tilted flat faces, free play only where bricks bridge)")
    size_scatter: Vec3 = Field(
        default=[0.0, 0.0, 0.0],
        description="m: standard deviations [sigma_L, sigma_W, sigma_H] of each builder brick's "
                    "dimensions (truncated at 3 sigma); explicit blocks keep their sizes")
    arris: float = Field(
        default=0.0, ge=0.0,
        description="m: radius of the rounded edges: every contact patch is inset by it, so a "
                    "block rocks about a pivot this far inside its edge")
    seed: int = Field(default=0, ge=0, description="seed of the random fields (same seed, same "
                                                   "scene, bit for bit)")
    # the as-built fields: not in the dump while zero (recorded cases keep their identity)
    corner_gap: GapSpec = Field(
        default_factory=GapSpec, exclude_if=lambda v: not v.any(),
        description="m: at each corner of a box model or facade, per corner and course, the "
                    "butting wall's end brick stops this much short of the through wall's, on "
                    "top of the layout's own gap (docs/imperfections.md)")
    head_gap: GapSpec = Field(
        default_factory=GapSpec, exclude_if=lambda v: not v.any(),
        description="m: gap of each head joint inside a course (the two bricks shortened by "
                    "half of it each at the joint, which stays where the bond puts it)")
    plumb: PlumbSpec = Field(
        default_factory=PlumbSpec, exclude_if=lambda v: not v.any(),
        description="courses out of plumb (a seeded random walk) and an initial lean")

    @field_validator("size_scatter")
    @classmethod
    def _non_negative(cls, v: list[float]) -> list[float]:
        if any(not (x >= 0) or not math.isfinite(x) for x in v):
            raise ValueError(f"every standard deviation must be >= 0 m, got {v}")
        return v

    def lengths(self) -> dict[str, float]:
        """Every length parameter by its field name (for the range check against the bricks)."""
        out = {"bed_unevenness": self.bed_unevenness, "arris": self.arris}
        for i, v in enumerate(self.size_scatter):
            out[f"size_scatter.{i}"] = v
        return out

    def as_built(self) -> bool:
        """Whether any as-built field (corner_gap, head_gap, plumb) is set."""
        return self.corner_gap.any() or self.head_gap.any() or self.plumb.any()

    def any(self) -> bool:
        return any(v > 0 for v in self.lengths().values()) or self.as_built()
