"""``imperfections:`` of a case file: the geometry of imperfect dry joints as seeded random fields.

Every length is in metres and every parameter is zero by default; zero reproduces the perfect
model bit for bit.  What each parameter represents, how it enters the contact law and how to
measure it on real bricks: docs/imperfections.md.  The realisation (the random draws) is made by
:mod:`dem.imperfections`.
"""

from __future__ import annotations

import math
from typing import Literal

from pydantic import Field, field_validator

from dem.case.base import Vec3, StrictModel

#: an imperfection may be at most this fraction of the smallest brick dimension
MAX_FRACTION = 0.10


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

    def any(self) -> bool:
        return any(v > 0 for v in self.lengths().values())
