"""Case-file schema of the scene builders (``scene.wall``, ``scene.facade``, ``scene.box_model``).

Units: SI (m, kg); angles in degrees.  Every model forbids unknown keys.  This module imports only
pydantic so that :mod:`dem.case` can use it without import cycles; the geometry is built by
:mod:`dem.builders`.

Conventions shared by all builders (table frame, z up, the table plane is z = 0):

* a wall runs along +x, its thickness along y, its courses up z; course 0 is the bottom course;
* ``origin`` is where the centre of the structure's footprint goes on the table (its z is the
  height of the bottom of course 0, normally 0);
* ``yaw`` turns the whole structure about the vertical through ``origin`` by 0, 90, 180 or 270
  degrees (counter-clockwise seen from above).
"""

from __future__ import annotations

import math
from typing import Annotated, Literal, Union

from pydantic import BaseModel, ConfigDict, Field, field_validator, model_validator

Vec3 = Annotated[list[float], Field(min_length=3, max_length=3)]


class _Strict(BaseModel):
    # NaN and inf are refused in every number ("Input should be a finite number"), before any
    # range check could give a misleading message about them
    model_config = ConfigDict(extra="forbid", validate_assignment=True, allow_inf_nan=False)


def _finite_vec(v: list[float]) -> list[float]:
    if any(not math.isfinite(x) for x in v):
        raise ValueError(f"must be finite, got {v}")
    return v


class BrickSpec(_Strict):
    """A custom brick: a solid box of uniform density."""

    size: Vec3 = Field(
        description="[length, width, height] of the brick, m (length along the wall when laid as "
        "a stretcher, width across it, height up when laid flat)"
    )
    mass: float | None = Field(default=None, gt=0.0, description="kg (give mass or density)")
    density: float | None = Field(default=None, gt=0.0, description="kg/m3 (give mass or density)")

    @field_validator("size")
    @classmethod
    def _positive(cls, v: list[float]) -> list[float]:
        if any(not (x > 0) or not math.isfinite(x) for x in v):
            raise ValueError(f"every edge length must be > 0 m, got {v}")
        return v

    @model_validator(mode="after")
    def _mass_or_density(self) -> "BrickSpec":
        if (self.mass is None) == (self.density is None):
            raise ValueError("give exactly one of mass (kg) or density (kg/m3)")
        return self


BrickRef = Annotated[
    Union[Literal["small", "large"], BrickSpec],
    Field(
        description="brick preset ('small' 105 x 50 x 35 mm, 0.336 kg; 'large' 152 x 75 x 50 mm, "
        "1.042 kg) or a custom brick {size: [L, W, H] m, mass kg | density kg/m3}"
    ),
]
Yaw = Literal[0, 90, 180, 270]


class _Placed(_Strict):
    brick: BrickRef = "small"
    origin: Vec3 = Field(
        default=[0.0, 0.0, 0.0],
        description="m, table frame: centre of the footprint (x, y) and base height (z)",
    )
    yaw: Yaw = Field(default=0, description="rotation of the whole structure about z, degrees")
    min_piece: float | None = Field(
        default=None,
        gt=0.0,
        description="m: cut pieces shorter than this are left out (a gap stays); "
        "default 0.15 x brick length",
    )
    materials: dict[str, str] = Field(
        default_factory=dict, exclude_if=lambda v: not v,  # not in the dump while empty
        description="material per group of this builder's blocks, e.g. {roof-beam: timber} "
        "(names declared in material.materials; the other groups are brick)")

    def group_names(self) -> list[str]:
        """The groups this builder lays (the keys ``materials`` may name)."""
        return []

    @model_validator(mode="after")
    def _material_groups(self):
        from pydantic import ValidationError
        from pydantic_core import InitErrorDetails, PydanticCustomError

        groups = self.group_names()
        errs = [InitErrorDetails(type=PydanticCustomError(
                    "value_error", f"no group '{g}' in this builder (groups: {', '.join(groups)})"),
                    loc=("materials", g), input=g)
                for g in self.materials if g not in groups]
        if errs:
            raise ValidationError.from_exception_data(type(self).__name__, errs)
        return self

    @field_validator("origin")
    @classmethod
    def _origin_finite(cls, v: list[float]) -> list[float]:
        return _finite_vec(v)


class WallSpec(_Placed):
    """A single straight wall (in-plane tilting-table specimens, Section 3.3 of the thesis).

    ``length`` whole bricks per full course, ``courses`` courses.  Stretcher bond: every other
    course is shifted by ``stagger``; with ``flush_ends`` the shifted courses are cut at both ends
    (pieces of length s and L - s, e.g. two half bricks) so that both wall ends are plane; without
    it every course holds ``length`` whole bricks and the ends step by s.  English bond: stretcher
    courses of two rows of stretchers alternate with header courses (headers + one queen closer
    near each end); the wall is one brick length thick.
    """

    length: int = Field(ge=1, description="wall length in whole bricks (stretchers per full course)")
    courses: int = Field(ge=1, description="number of courses (rows)")
    bond: Literal["stretcher", "english"] = Field(default="stretcher", description="bond pattern")
    laying: Literal["flat", "on_edge"] = Field(
        default="flat",
        description="flat: course height = brick height, thickness = brick width (large bricks "
        "h/t = 50/75); on_edge: course height = brick width, thickness = brick height (h/t = 75/50)",
    )
    stagger: float | None = Field(
        default=None,
        gt=0.0,
        description="m, offset of the vertical joints of successive courses (stretcher bond); "
        "default half a brick length",
    )
    flush_ends: bool = Field(
        default=True, description="cut the shifted courses so both wall ends are plane"
    )
    group: str = Field(default="wall", min_length=1, description="group label in the output")

    def group_names(self) -> list[str]:
        return [self.group]

    @model_validator(mode="after")
    def _bond_options(self) -> "WallSpec":
        from dem.builders.bricks import brick as as_brick

        if self.stagger is not None and self.stagger >= as_brick(self.brick).length:
            raise ValueError(f"stagger must be smaller than the brick length {as_brick(self.brick).length} m")
        if self.bond == "english":
            if self.stagger is not None:
                raise ValueError("stagger applies to stretcher bond only (English bond laps by a quarter brick)")
            if self.length < 2:
                raise ValueError("an English-bond wall needs length >= 2 bricks")
        return self


Connection = Annotated[
    Union[Literal["poor", "good", "strong", "unbonded"], float],
    Field(
        description="corner connection: the lap of the bricks of one wall into the other wall's "
        "thickness in alternate courses, m, 0 < lap <= wall thickness; or 'poor' (0.010 m), "
        "'good' (= course height), 'strong' (= wall thickness: a fully interlocked corner) or "
        "'unbonded' (a straight vertical joint: the facade runs through every course, the wing "
        "butts against it; a bound)"
    ),
]


class WingSpec(_Strict):
    """A side wall (wing) at one end of a facade."""

    length: int = Field(ge=1, description="wing length in whole bricks, measured from the corner")
    connection: Connection = "strong"

    @field_validator("connection")
    @classmethod
    def _positive(cls, v):
        if not isinstance(v, str) and (not (v > 0) or not math.isfinite(v)):
            raise ValueError(f"a corner lap must be > 0 m, got {v}")
        return v


class FacadeSpec(_Placed):
    """A facade with side walls (out-of-plane tilting-table specimens, Section 3.3.3, 3.5).

    The facade runs along x with its outer face towards -y; the wings run from its ends towards +y
    (behind it).  Tilting about +x pushes the facade outwards, away from the wings.  Even courses
    (0, 2, ...) run the facade through the corners, odd courses the wings.
    """

    length: int = Field(ge=1, description="facade length in whole bricks (through courses)")
    courses: int = Field(ge=1, description="number of courses")
    laying: Literal["flat", "on_edge"] = Field(default="flat", description="as in scene.wall")
    stagger: float | None = Field(
        default=None, gt=0.0, description="m, joint offset between courses inside the walls; default half a brick"
    )
    left: WingSpec | None = Field(default=None, description="wing at the -x end (none: free end)")
    right: WingSpec | None = Field(default=None, description="wing at the +x end (none: free end)")

    def group_names(self) -> list[str]:
        return ["facade", "wing-left", "wing-right"]
    flush_ends: bool = Field(default=True, description="plane free ends of the facade and wings")

    @model_validator(mode="after")
    def _laps_fit(self) -> "FacadeSpec":
        from dem.builders.bricks import brick as as_brick

        b = as_brick(self.brick)
        _, t, _ = b.dims(self.laying)
        for side in ("left", "right"):
            wing = getattr(self, side)
            if wing is not None and not isinstance(wing.connection, str) and wing.connection > t + 1e-12:
                raise ValueError(
                    f"{side}.connection: a corner lap of {wing.connection} m exceeds the wall "
                    f"thickness {t} m"
                )
        if self.stagger is not None and self.stagger >= b.length:
            raise ValueError(f"stagger must be smaller than the brick length {b.length} m")
        return self


class RoofSpec(_Strict):
    """Roof load of the shaking-table models (Section 4.2.3).

    ``beams`` beams span the plan between the long walls L1 and L2 (along y), evenly spaced along x;
    each end carries a steel mass over the wall.  The thesis gives only the masses (1 kg per beam
    end, 0.5 kg per corner for Models II and III); the beam section, beam mass and the steel blocks'
    sizes are assumptions (timber 30 x 20 mm, 500 kg/m3; steel ~7850 kg/m3).
    """

    beams: int = Field(default=5, ge=0, description="number of roof beams")
    beam_width: float = Field(default=0.030, gt=0.0, description="beam width along x, m")
    beam_depth: float = Field(default=0.020, gt=0.0, description="beam depth (height), m")
    beam_mass: float = Field(
        default=0.158, gt=0.0, description="kg per beam (0.525 x 0.03 x 0.02 m of timber at 500 kg/m3)"
    )
    end_mass: float = Field(default=1.0, ge=0.0, description="kg on each beam end (0: none)")
    end_mass_size: Vec3 = Field(
        default=[0.040, 0.050, 0.064], description="m, steel block on each beam end (x, y, z)"
    )
    corner_mass: float | None = Field(
        default=None,
        ge=0.0,
        description="kg on top of each corner (default: 0 for Model I, 0.5 for Models II and III)",
    )
    corner_mass_size: Vec3 = Field(
        default=[0.050, 0.050, 0.0255], description="m, steel block on each corner (x, y, z)"
    )

    @field_validator("end_mass_size", "corner_mass_size")
    @classmethod
    def _positive(cls, v: list[float]) -> list[float]:
        if any(not (x > 0) or not math.isfinite(x) for x in v):
            raise ValueError(f"every edge length must be > 0 m, got {v}")
        return v


MODEL_COURSES = {"I": 9, "II": 9, "III": 15}
MODEL_CORNER_MASS = {"I": 0.0, "II": 0.5, "III": 0.5}


class BoxModelSpec(_Placed):
    """One-storey box model of the shaking-table tests (Section 4.2.3, Models I, II, III).

    Long walls L1 (y < 0, back) and L2 (y > 0, front) run along x, short walls T1 (x < 0, back)
    and T2 (x > 0, front) along y; the corners are fully interlocked (even courses run L through,
    odd courses T).  ``model`` sets the thesis defaults: I = 9 courses, no corner masses;
    II = 9 courses, 0.5 kg corner masses; III = 15 courses, 0.5 kg corner masses; all carry the
    roof of five beams with 1 kg at each end.
    """

    model: Literal["I", "II", "III"] | None = Field(
        default=None, description="thesis model preset (sets courses and corner masses)"
    )
    length: int = Field(default=7, ge=2, description="L walls (along x): bricks per through course")
    width: int = Field(default=5, ge=2, description="T walls (along y): bricks per through course")
    courses: int | None = Field(
        default=None, ge=1, description="number of courses (default from model: 9, 9, 15)"
    )
    roof: RoofSpec | None = Field(
        default_factory=RoofSpec, description="roof beams and masses (null: bare walls)"
    )
    corners: Literal["interlocked", "unbonded"] = Field(
        default="interlocked",
        # not in the dump while interlocked: recorded cases keep their identity
        exclude_if=lambda v: v == "interlocked",
        description="interlocked: the thesis' corners (L and T walls run through the corners in "
        "alternate courses); unbonded: a straight vertical joint at each corner (L walls run "
        "through in every course, T walls butt between them; no brick of one wall overlaps the "
        "other's in plan), a bound on what the corners contribute",
    )

    @model_validator(mode="after")
    def _courses_known(self) -> "BoxModelSpec":
        if self.courses is None and self.model is None:
            raise ValueError("give courses (or a thesis model: I, II or III)")
        return self

    def group_names(self) -> list[str]:
        return ["L1", "L2", "T1", "T2", "roof-beam", "roof-mass", "corner-mass"]

    @property
    def n_courses(self) -> int:
        return self.courses if self.courses is not None else MODEL_COURSES[self.model]

    @property
    def corner_mass(self) -> float:
        if self.roof is None:
            return 0.0
        if self.roof.corner_mass is not None:
            return self.roof.corner_mass
        return MODEL_CORNER_MASS[self.model] if self.model is not None else 0.0
