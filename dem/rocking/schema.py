"""Case files of the two-body rocking model (``dem rocking CASE.yaml --out DIR``).

The format of ../shared/DESIGN.md ("The two-body rocking model reads a case like this") is accepted
exactly as written; everything below ``# extensions`` is optional.  SI units, angles in radians::

    name: model-ii-facade-y
    rocking:
      thickness: 0.050                   # m, both parts (T)
      lower: {height: 0.140, mass: 6.05} # Part 1: H1 (m), m1 (kg)
      upper: {height: 0.140, mass: 9.41} # Part 2: H2 (m), m2 (kg)
      top_load: 58.8                     # N, vertical, on top of Part 2
      top_friction: 0.81                 # mu of the sliding friction mu * N at the top
      restitution: housner               # or a number in [0, 1]
      initial: {theta1: 0.0, theta2: 0.0, omega1: 0.0, omega2: 0.0}   # rad, rad/s (absolute)
      # extensions
      top_load_point: corner             # corner (thesis eq. 5-9..5-14) | centre (eq. 5-3)
      locked: false                      # true: the parts never separate (one block)
      top_contact: sliding               # sliding (thesis: N fixed in space, friction mu N) |
                                         # co-moving (N a mass N/g moving with the top, no friction)
    loading: {type: shake, direction: [0, 1, 0], frequency: 2.8, amplitude: 0.00469, cycles: 50}
    run: {duration: 20.0, output_interval: 0.001}   # extension: collapse_angle (rad)
    # extensions
    gravity: 9.81                        # m/s2
    solver: {method: DOP853, rtol: 1.0e-10, atol: 1.0e-12, max_step_fraction: 0.0625,
             zeno_velocity: 1.0e-6, zeno_time: 1.0e-4, max_events: 200000}

The shake is the DEM's (:class:`dem.case.ShakeLoading`: the same fields, defaults and checks, and
the same table motion, dem.table_motion), with a horizontal ``direction``: used as given, the
rocking plane contains it and the displacement amplitude is ``amplitude * |direction|``; give
``amplitude`` (m) or ``peak_acceleration`` (m/s2).  After the last cycle a = 0 (the table keeps
its final velocity, dem.table_motion).
``loading: {type: none}`` is free motion from ``initial``.
Unknown keys are rejected; errors name the field, e.g. ``rocking.lower.mass: must be > 0 kg``.
"""

from __future__ import annotations

import math
from pathlib import Path
from typing import Annotated, Literal, Union

from pydantic import Field, ValidationError, field_validator, model_validator
from pydantic.json_schema import SkipJsonSchema

from dem.case import Distortion
from dem.case import ShakeLoading as DemShakeLoading
from dem.case.base import StrictModel


class RockingCaseError(ValueError):
    """A rocking case that cannot be used; the message names the bad field(s)."""


class _Strict(StrictModel):
    """The DEM case's base (one dialect for both case kinds): unknown keys refused, NaN and inf
    refused in every number."""


def _positive(unit: str):
    def check(v: float) -> float:
        if not (math.isfinite(v) and v > 0):
            raise ValueError(f"must be > 0 {unit}, got {v}".replace("  ", " "))
        return v
    return check


def _non_negative(unit: str):
    def check(v: float) -> float:
        if not (math.isfinite(v) and v >= 0):
            raise ValueError(f"must be >= 0 {unit}, got {v}".replace("  ", " "))
        return v
    return check


def _finite(v: float) -> float:
    if not math.isfinite(v):
        raise ValueError(f"must be finite, got {v}")
    return v


class PartSpec(_Strict):
    """One rigid part (a rectangle of the wall's thickness)."""

    height: float = Field(description="H, m")
    mass: float = Field(description="kg")

    _h = field_validator("height")(lambda cls, v: _positive("m")(v))
    _m = field_validator("mass")(lambda cls, v: _positive("kg")(v))


class InitialSpec(_Strict):
    """Initial absolute angles (rad, positive when the top moves towards +direction) and rates."""

    theta1: float = 0.0
    theta2: float = 0.0
    omega1: float = 0.0
    omega2: float = 0.0

    _f = field_validator("theta1", "theta2", "omega1", "omega2")(lambda cls, v: _finite(v))

    @model_validator(mode="after")
    def _angles(self) -> "InitialSpec":
        for k in ("theta1", "theta2"):
            if abs(getattr(self, k)) >= math.pi / 2:
                raise ValueError(f"{k} must be within (-pi/2, pi/2) rad, got {getattr(self, k)}")
        return self


class RockingSpec(_Strict):
    """The two-body model of the thesis (Chapter 5, Table 5.1)."""

    thickness: float = Field(description="T, m, both parts")
    lower: PartSpec = Field(description="Part 1 (on the base)")
    upper: PartSpec = Field(description="Part 2 (on Part 1)")
    top_load: float = Field(default=0.0, description="N, N: vertical load on top of Part 2")
    top_friction: float = Field(default=0.0, description="mu, -: friction mu N at the top")
    restitution: Union[str, float] = Field(
        default="housner",
        description="'housner' (plastic impact, momentum-conserving) or e in [0, 1]: "
                    "plastic velocity direction with e^2 of the kinetic energy kept")
    initial: InitialSpec = Field(default_factory=InitialSpec)
    top_load_point: Literal["corner", "centre"] = Field(
        default="corner", description="where N acts: the raised top corner or the top centre")
    locked: bool = Field(default=False, description="the parts never separate (one block)")
    top_contact: Literal["sliding", "co-moving"] = Field(
        default="sliding",
        description="'sliding': the thesis' top load N fixed in space, sliding over Part 2 with "
                    "friction mu N; 'co-moving': N is a mass N/g moving with the top of Part 2 "
                    "(its inertia added, its weight where it bears), no friction")

    _t = field_validator("thickness")(lambda cls, v: _positive("m")(v))
    _n = field_validator("top_load")(lambda cls, v: _non_negative("N")(v))
    _mu = field_validator("top_friction")(lambda cls, v: _non_negative("")(v))

    @field_validator("restitution", mode="before")
    @classmethod
    def _restitution(cls, v):
        if isinstance(v, str):
            if v != "housner":
                raise ValueError(f"must be 'housner' or a number in [0, 1], got {v!r}")
            return v
        if isinstance(v, bool) or not isinstance(v, (int, float)):
            raise ValueError(f"must be 'housner' or a number in [0, 1], got {v!r}")
        if not (math.isfinite(v) and 0.0 <= v <= 1.0):
            raise ValueError(f"must be 'housner' or a number in [0, 1], got {v}")
        return float(v)


class ShakeLoading(DemShakeLoading):
    """The DEM's shake (dem.case.ShakeLoading: the same fields, defaults and checks), with a
    horizontal direction: the rocking plane contains it."""

    # refused by _sine_only, and so left out of the two-body schema
    distortion: SkipJsonSchema[Distortion | None] = None

    @field_validator("direction")
    @classmethod
    def _horizontal(cls, v):
        if abs(v[2]) > 1e-12:
            raise ValueError(f"must be horizontal (z = 0) for the rocking model, got {v}")
        return v

    @model_validator(mode="after")
    def _sine_only(self):
        """The two-body model shakes with dem.table_motion.SineMotion as given (the DEM's
        default start); the DEM's other starts (``start``, ``ramp_cycles``) are not implemented
        here: refused rather than ignored."""
        fields = getattr(type(self), "model_fields", {})
        start = getattr(self, "start", None)
        default = fields["start"].default if "start" in fields else None
        if start is not None and start != default:
            raise ValueError(f"start: {start!r} is not implemented in the two-body model (only "
                             f"the default {default!r})")
        if getattr(self, "ramp_cycles", None) is not None:
            raise ValueError("ramp_cycles: not implemented in the two-body model")
        if getattr(self, "distortion", None) is not None:
            raise ValueError("distortion: the table's waveform distortion is not implemented in "
                             "the two-body model (only the plain sine)")
        return self

    @model_validator(mode="after")
    def _table_frame_start(self) -> "ShakeLoading":
        """The DEM's ``start: lab`` / ``ramp`` are not taken by the two-body model:
        it starts in the table's frame (dem.table_motion), as it always has."""
        if self.start != "table-frame":
            raise ValueError(f"start: the two-body model takes only start: table-frame, got "
                             f"{self.start}")
        return self


class NoneSpec(_Strict):
    type: Literal["none"]


LoadingSpec = Annotated[Union[ShakeLoading, NoneSpec], Field(discriminator="type")]


class RockingRunSpec(_Strict):
    """``run:`` of a two-body case: its own schedule (samples of two bodies, every ms by default),
    not the DEM's dem.case.RunSpec (frames of every block, every 10 ms)."""

    duration: float = Field(description="simulated time, s")
    output_interval: float = Field(default=0.001, description="s between output samples")
    collapse_angle: float = Field(default=1.0, description="rad: the run stops when a part "
                                  "tilts further (status 'collapsed')")

    _d = field_validator("duration", "output_interval")(lambda cls, v: _positive("s")(v))

    @field_validator("collapse_angle")
    @classmethod
    def _ca(cls, v):
        if not (0.0 < v <= math.pi / 2):
            raise ValueError(f"must be in (0, pi/2] rad, got {v}")
        return v

    @model_validator(mode="after")
    def _interval(self) -> "RockingRunSpec":
        if self.output_interval > self.duration:
            raise ValueError("output_interval must not exceed duration")
        if self.duration / self.output_interval > 5e7:
            raise ValueError("more than 5e7 output samples: raise output_interval")
        return self


class RockingSolverSpec(_Strict):
    """``solver:`` of a two-body case: integration settings (solve_ivp; not the DEM's
    dem.case.SolverSpec); defaults justified in results/two-body/README.md (convergence)."""

    method: Literal["DOP853", "RK45", "Radau", "LSODA", "BDF"] = "DOP853"
    rtol: float = 1e-10
    atol: float = 1e-12
    max_step_fraction: float = Field(default=1.0 / 16.0, description="max step / period")
    zeno_velocity: float = Field(default=1e-6, description="rad/s: slower closing rates lock")
    zeno_time: float = Field(default=1e-4, ge=0.0, description="s: a joint whose next flight "
                             "would be shorter is locked (end of an accumulation of impacts)")
    max_events: int = Field(default=200000, ge=1, description="more events stop the run (error)")

    _p = field_validator("rtol", "atol", "max_step_fraction", "zeno_velocity")(
        lambda cls, v: _positive("")(v))


class RockingCase(_Strict):
    name: str = Field(min_length=1)
    description: str = ""
    rocking: RockingSpec
    loading: LoadingSpec = Field(default_factory=lambda: NoneSpec(type="none"))
    run: RockingRunSpec
    solver: RockingSolverSpec = Field(default_factory=RockingSolverSpec)
    gravity: float = Field(default=9.81, description="m/s2")

    _g = field_validator("gravity")(lambda cls, v: _non_negative("m/s2")(v))


def parse_rocking_case(data: dict, node=None, source: str | None = None) -> RockingCase:
    """Validate a two-body case; errors in the DEM's dialect (dem.case_errors.format_errors:
    ``FILE:LINE: field.path: message`` when the YAML node tree and the file are given)."""
    from dem.case_errors import format_errors

    try:
        return RockingCase.model_validate(data)
    except ValidationError as err:
        raise RockingCaseError(format_errors(err, RockingCase, data=data, node=node,
                                             source=source)) from None


def load_rocking_case(path: str | Path, overrides: dict | None = None) -> RockingCase:
    """Read and validate a rocking case file (``overrides`` are merged into the top level)
    through the DEM's reader (dem.case.document.read_case_yaml: duplicate keys refused, empty
    files and non-mappings named)."""
    from dem.case.document import key_line, read_case_yaml

    path = Path(path)
    data, node = read_case_yaml(path, RockingCaseError)
    if "rocking" not in data:
        raise RockingCaseError(f"{path}: rocking: required field missing (this is not a "
                               f"rocking case)")
    if "scene" in data:
        raise RockingCaseError(
            f"{path}:{key_line(node, 'scene')}: scene: a case is either a two-body case "
            f"(rocking:; dem rocking) or a DEM case (scene:, material:, ...; dem run), not both: "
            f"remove one of 'rocking:' (line {key_line(node, 'rocking')}) and 'scene:'")
    for k, v in (overrides or {}).items():
        if isinstance(v, dict) and isinstance(data.get(k), dict):
            data[k] = {**data[k], **v}
        else:
            data[k] = v
    return parse_rocking_case(data, node=node, source=str(path))


def rocking_case_json_schema() -> str:
    """JSON schema of two-body case files (``dem schema --rocking``; committed as
    ``cases/rocking/rocking.schema.json``, for editor completion)."""
    import json

    schema = RockingCase.model_json_schema()
    schema = {"$schema": "https://json-schema.org/draft/2020-12/schema", **schema,
              "title": "dem-masonry two-body rocking case file"}
    return json.dumps(schema, indent=2) + "\n"


def rocking_plausibility(case: RockingCase, source=None) -> tuple[list[str], list[str]]:
    """(warnings, errors) on the table motion of a two-body case: the DEM's thresholds
    (dem.validate.table_plausibility: g-level, stroke, table speed, justified there)."""
    from dem.validate import table_plausibility

    L = case.loading
    if L.type != "shake":
        return [], []
    stroke = L.axis_amplitude
    a_peak = stroke * (2.0 * math.pi * L.frequency) ** 2
    field = "amplitude" if L.amplitude is not None else "peak_acceleration"
    return table_plausibility(a_peak, stroke, L.frequency, "",
                              f"{source}: loading.{field}" if source else f"loading.{field}")


# ------------------------------------------------------------------------------------------
# from the case to the model's objects
# ------------------------------------------------------------------------------------------
def params_from_case(case: RockingCase):
    from dem.rocking.params import RockingParams

    r = case.rocking
    return RockingParams(
        thickness=r.thickness, h1=r.lower.height, m1=r.lower.mass, h2=r.upper.height,
        m2=r.upper.mass, top_load=r.top_load, top_friction=r.top_friction,
        gravity=case.gravity, load_point=r.top_load_point, locked=r.locked,
        top_contact=r.top_contact)


def excitation_from_case(case: RockingCase):
    """The table motion along the rocking plane (dem.table_motion, shared with the DEM)."""
    from dem.table_motion import SineMotion, TableMotion

    L = case.loading
    if L.type == "none":
        return TableMotion()
    return SineMotion(L.axis_amplitude, L.frequency, L.cycles)


def settings_from_case(case: RockingCase):
    from dem.rocking.integrate import Settings

    s = case.solver
    return Settings(duration=case.run.duration, output_interval=case.run.output_interval,
                    restitution=case.rocking.restitution, method=s.method, rtol=s.rtol,
                    atol=s.atol, max_step_fraction=s.max_step_fraction,
                    zeno_velocity=s.zeno_velocity, zeno_time=s.zeno_time,
                    collapse_angle=case.run.collapse_angle,
                    max_events=s.max_events)


def initial_from_case(case: RockingCase) -> tuple:
    i = case.rocking.initial
    return (i.theta1, i.theta2, i.omega1, i.omega2)
