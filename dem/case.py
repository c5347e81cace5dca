"""Case files: the validated description of one simulation.

Units: SI everywhere (m, kg, s, N, Pa), except angles, which are in degrees (as in
``../shared/DESIGN.md``).  The base is the table plane z = 0 with z up; positions are in the
table's frame.  Unknown keys are rejected everywhere.

The minimal schema of DESIGN.md is accepted exactly as written there::

    name: block-on-tilt
    scene:
      blocks:
        - {size: [0.2, 0.2, 0.1], position: [0.0, 0.0, 0.05], mass: 4.0}
    material: {friction: 0.5}
    loading: {type: tilt, axis: x, rate: 2.0, max_angle: 40.0}
    run: {duration: 25.0, output_interval: 0.01}

Loading functions (gravity and base acceleration versus time) live in :mod:`dem.loading`.
"""

from __future__ import annotations

import math
from pathlib import Path
from typing import Annotated, Literal, Union

import yaml
from pydantic import (
    BaseModel,
    ConfigDict,
    Field,
    ValidationError,
    field_validator,
    model_validator,
)

from dem.builders.spec import BoxModelSpec, FacadeSpec, WallSpec

Vec3 = Annotated[list[float], Field(min_length=3, max_length=3)]


class _Strict(BaseModel):
    # NaN and inf are refused in every number ("Input should be a finite number"), before any
    # range check could give a misleading message about them
    model_config = ConfigDict(extra="forbid", validate_assignment=True, allow_inf_nan=False)


# --------------------------------------------------------------------------------------------
# scene
# --------------------------------------------------------------------------------------------
class BlockSpec(_Strict):
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


class SceneSpec(_Strict):
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


# --------------------------------------------------------------------------------------------
# material
# --------------------------------------------------------------------------------------------
# Friction coefficients of dry masonry joints are 0.5-0.9 (thesis Section 4.2.3: 0.81), of the
# stickiest dry solid pairs (rubber on rough concrete) about 1-2.  mu = 10 is a friction angle of
# 84.3 deg: a joint that never slides in any scene this model can stand up (a block slides before
# it tips only if mu < b/h, and b/h > 10 is a plate lying flat).  Above it the number is a typo or
# a unit slip (1000 for 1.000, a percentage), so it is refused rather than run.
MAX_FRICTION = 10.0


class Material(_Strict):
    """Joint properties, given the way masonry engineers give them (3DEC style).

    Joint stiffness is per unit area of joint (Pa/m = N/m^3): a contact patch of area A closed by
    a gap d pushes back with kn * A * d.  It is converted to point springs by tributary area
    (see ``dem.engine.laws``).
    """

    friction: float = Field(ge=0.0, le=MAX_FRICTION,
                            description="Coulomb friction coefficient mu, - (at most 10, see "
                            "MAX_FRICTION)")
    normal_stiffness: Union[Literal["rigid"], Annotated[float, Field(gt=0.0)]] = Field(
        default=5.0e9,
        description="kn, Pa/m; or 'rigid': the kn that keeps the elastic offset of every block's "
        "tipping load factor at 0.5 % (dem/compliance.py; the run reports the kn chosen)")
    shear_stiffness: float | None = Field(
        default=None, gt=0.0, description="ks, Pa/m (default 0.4 kn)"
    )
    damping: float = Field(
        default=0.5, ge=0.0, lt=1.0,
        description="viscous contact damping, fraction of critical (0.5: near-plastic impacts "
        "of masonry units, normal restitution 0.16; see docs/engine.md)",
    )
    base_friction: float | None = Field(
        default=None, ge=0.0, le=MAX_FRICTION,
        description="friction against the table (default: friction; at most 10)"
    )

    def ks(self, kn: float) -> float:
        """Shear stiffness, Pa/m, for the normal stiffness ``kn`` in use."""
        return self.shear_stiffness if self.shear_stiffness is not None else 0.4 * kn

    @property
    def mu_base(self) -> float:
        return self.base_friction if self.base_friction is not None else self.friction


# --------------------------------------------------------------------------------------------
# loading
# --------------------------------------------------------------------------------------------
class CollapseSpec(_Strict):
    """When a tilt run counts as collapsed and stops (see dem.collapse for the rule)."""

    enabled: bool = Field(default=True, description="detect collapse and stop the run after it")
    onset_speed: float = Field(
        default=1e-3, gt=0.0, description="m/s: blocks slower than this are at rest (onset)"
    )
    confirm: float = Field(default=5e-3, gt=0.0, description="motion (m) that confirms collapse")
    after: float = Field(default=1.0, ge=0.0, description="s to run on after confirmation")
    stop: float = Field(default=0.03, gt=0.0, description="stop earlier once a block moved this, m")

    @model_validator(mode="after")
    def _ordered(self) -> "CollapseSpec":
        if not self.confirm < self.stop:
            raise ValueError("need confirm < stop")
        return self


class QuasiStaticSpec(_Strict):
    """How a quasi-static tilt finds the angle at which equilibrium is lost (dem.run.quasi_static).

    The angle advances by ``increment``; after each advance the scene relaxes with Cundall local
    damping (``local_damping``: it does not change a static equilibrium, it only removes the
    motion) until the unbalanced-force ratio (sum over blocks of |net force| + |net torque| /
    radius, over the sum of their weights) is below ``tolerance``; equilibrium is lost when a
    block moves ``collapse.confirm`` while relaxing or ``max_relax_time`` passes without
    reaching the tolerance while still moving.  The first failing increment is bisected down to
    ``resolution``;
    lambda = tan(last angle in equilibrium).  Then the run goes on dynamically (no local damping)
    at the failing angle for ``collapse.after`` s or until a block moved ``collapse.stop``, to
    show the mechanism.
    """

    increment: float = Field(default=1.0, gt=0.0, le=10.0, description="degrees per advance")
    resolution: float = Field(default=0.05, gt=0.0, description="bisection width, degrees")
    tolerance: float = Field(
        default=1e-3, gt=0.0, lt=1.0,
        description="unbalanced-force ratio of equilibrium, -: an angle up to about this much "
        "load factor above a sliding limit can pass (benchmarks/quasi_static_tilt.py: 1e-3 "
        "reads lambda within 0.2 %; 1e-4 is below the floor some walls' joint vibrations give)")
    local_damping: float = Field(default=0.8, gt=0.0, lt=1.0,
                                 description="Cundall local damping while relaxing, -")
    ramp_time: float = Field(default=0.005, ge=0.0,
                             description="s over which each advance turns the table (smoothstep)")
    max_relax_time: float = Field(default=1.0, gt=0.0,
                                  description="s of relaxation before an angle counts as failed")


class TiltLoading(_Strict):
    """The table turns about a horizontal axis (pseudo-static collapse, thesis Chapter 3).

    Modelled in the table's frame: gravity turns, the table stays.  With the right-hand rule about
    ``axis`` a positive angle theta gives gravity g_t = -g cos(theta) z + g sin(theta) (axis x z),
    so about +x blocks are pushed towards -y, about +y towards +x; the load factor is
    lambda = tan(theta).  Where the pivot edge is does not matter in this frame: the fictitious
    forces of the rotation (of order rate^2 * size, < 1e-5 g at 2 deg/s) are neglected.
    ``method``: "constant_rate": the angle rises at ``rate``; with ``step`` it rises by ``step``
    degrees, then holds for ``hold`` seconds, and so on; it stays at ``max_angle`` once reached;
    collapse as dem.collapse detects it.  "quasi_static": the angle advances by increments, each
    followed by relaxation to equilibrium, until equilibrium is lost (``quasi_static``).
    """

    type: Literal["tilt"]
    axis: Union[Literal["x", "y", "-x", "-y"], Vec3] = Field(
        description="table rotation axis (horizontal): x, y, -x, -y or a vector"
    )
    method: Literal["constant_rate", "quasi_static"] = Field(
        default="quasi_static",
        description="quasi_static (the default, and what a tilt without a rate gets): "
        "increments, each relaxed to equilibrium, then bisection of the first that fails "
        "(`quasi_static`); constant_rate (what a tilt with a rate gets): the angle rises at "
        "`rate`")
    rate: float | None = Field(default=None, gt=0.0,
                               description="tilt rate while turning, degrees per second "
                               "(constant_rate)")
    quasi_static: QuasiStaticSpec = Field(default_factory=QuasiStaticSpec)
    max_angle: float = Field(default=60.0, gt=0.0, le=90.0, description="degrees")
    start_angle: float = Field(default=0.0, ge=0.0, le=90.0, description="degrees at t = 0")
    start_time: float = Field(
        default=0.0, ge=0.0,
        description="s to bring the table smoothly (smoothstep) from 0 to start_angle; 0 = the "
        "table starts at start_angle (a sudden load: right for a block released on an incline, "
        "a shock for a wall)",
    )
    step: float | None = Field(default=None, gt=0.0, description="degrees per step (with holds)")
    hold: float = Field(default=0.0, ge=0.0, description="s held after every step")
    collapse: CollapseSpec = Field(default_factory=CollapseSpec)

    @model_validator(mode="before")
    @classmethod
    def _method_from_rate(cls, data):
        """A tilt that gives a rate and no method is a constant-rate tilt (every case file
        written before the quasi-static tilt existed); without a rate it is quasi-static."""
        if isinstance(data, dict) and "method" not in data and data.get("rate") is not None:
            data = {**data, "method": "constant_rate"}
        return data

    @field_validator("axis")
    @classmethod
    def _horizontal(cls, v):
        if isinstance(v, list):
            if abs(v[2]) > 1e-12 or math.hypot(v[0], v[1]) == 0.0:
                raise ValueError(f"axis must be a non-zero horizontal vector, got {v}")
        return v

    @model_validator(mode="after")
    def _start_below_max(self) -> "TiltLoading":
        if self.start_angle > self.max_angle:
            raise ValueError("start_angle must not exceed max_angle")
        if self.method == "constant_rate" and self.rate is None:
            raise ValueError("rate: a constant_rate tilt needs a rate (degrees per second); or "
                             "give method: quasi_static")
        if self.method == "quasi_static" and (self.rate is not None or self.step is not None):
            raise ValueError("rate / step: they apply to method: constant_rate; a quasi_static "
                             "tilt advances by quasi_static.increment")
        return self


class ShakeLoading(_Strict):
    """Sinusoidal table displacement u(t) = A * direction * sin(2 pi f t) for ``cycles`` cycles.

    ``direction`` is used as given (not normalised): [1, 1, 0] moves x and y each by the amplitude
    (the thesis' diagonal tests).  Give the amplitude A (m) or the peak acceleration
    a_p = A (2 pi f)^2 (m/s2).  After the last cycle a = 0 and the table keeps its final velocity (see dem.table_motion).  The
    motion itself is dem.table_motion.SineMotion; the two-body model's case format uses this
    class too (dem.rocking.schema.ShakeLoading adds that its direction must be horizontal).
    """

    type: Literal["shake"]
    direction: Vec3 = Field(description="displacement direction, multiplied by the amplitude")
    frequency: float = Field(gt=0.0, description="Hz")
    amplitude: float | None = Field(default=None, gt=0.0, description="displacement amplitude, m")
    peak_acceleration: float | None = Field(default=None, gt=0.0, description="m/s2")
    cycles: float = Field(default=50.0, gt=0.0, description="number of cycles")

    @field_validator("direction")
    @classmethod
    def _nonzero(cls, v):
        if math.sqrt(sum(x * x for x in v)) == 0.0 or any(not math.isfinite(x) for x in v):
            raise ValueError(f"direction must be a finite non-zero vector, got {v}")
        return v

    @model_validator(mode="after")
    def _one_of(self) -> "ShakeLoading":
        if (self.amplitude is None) == (self.peak_acceleration is None):
            raise ValueError("give exactly one of amplitude (m) or peak_acceleration (m/s2)")
        return self

    @property
    def displacement_amplitude(self) -> float:
        """A, m: the amplitude given, or the one of the peak acceleration given."""
        if self.amplitude is not None:
            return self.amplitude
        return self.peak_acceleration / (2.0 * math.pi * self.frequency) ** 2

    @property
    def axis_amplitude(self) -> float:
        """Displacement amplitude along the direction, m (= A * |direction|)."""
        return self.displacement_amplitude * math.sqrt(sum(x * x for x in self.direction))


class RecordLoading(_Strict):
    """Table acceleration from a record (an earthquake, a pulse), in the table's frame.

    Give either ``file`` (CSV with columns t, ax, ay and optionally az: s and m/s2; a header line
    is allowed; a relative path is relative to the case file) or the arrays ``time``, ``ax``,
    ``ay`` (and ``az``) inline.  Between samples the acceleration is interpolated linearly, outside
    the record it is zero; the table starts at rest and its velocity and displacement are the
    integrals of the acceleration (no baseline correction: a record that does not integrate to
    zero velocity leaves the table drifting, as it would).  ``scale`` multiplies the record.
    """

    type: Literal["record"]
    file: str | None = Field(default=None, description="CSV: t, ax, ay[, az] (s, m/s2)")
    time: list[float] | None = Field(default=None, description="s, strictly increasing")
    ax: list[float] | None = Field(default=None, description="m/s2")
    ay: list[float] | None = Field(default=None, description="m/s2")
    az: list[float] | None = Field(default=None, description="m/s2")
    scale: float = Field(default=1.0, description="factor on the record")

    @model_validator(mode="after")
    def _source(self) -> "RecordLoading":
        if (self.file is None) == (self.time is None):
            raise ValueError("give either file (CSV) or time with ax, ay (inline arrays)")
        if self.time is not None:
            n = len(self.time)
            if n < 2:
                raise ValueError("time needs at least 2 samples")
            for name in ("ax", "ay", "az"):
                arr = getattr(self, name)
                if arr is not None and len(arr) != n:
                    raise ValueError(f"{name} has {len(arr)} samples, time has {n}")
            if self.ax is None and self.ay is None and self.az is None:
                raise ValueError("give at least one of ax, ay, az")
            check_record_time(self.time)
        return self

    def samples(self):
        """(t [K] s, acceleration [K,3] m/s2) with the scale applied; reads the file if given."""
        import numpy as np

        if self.file is not None:
            t, acc = read_record_csv(self.file)
        else:
            t = np.asarray(self.time, dtype=float)
            acc = np.zeros((len(t), 3))
            for k, name in enumerate(("ax", "ay", "az")):
                if getattr(self, name) is not None:
                    acc[:, k] = getattr(self, name)
        return t, self.scale * acc


def check_record_time(t) -> None:
    import numpy as np

    t = np.asarray(t, dtype=float)
    if not np.all(np.isfinite(t)) or np.any(np.diff(t) <= 0):
        raise ValueError("time must be finite and strictly increasing")


def read_record_csv(path):
    """t [K], acceleration [K,3] from a CSV of t, ax, ay[, az]; raises ValueError naming the
    problem and the row (1-based line of the file): ``pulse.csv:7: 'abc' is not a number``.
    Lines starting with '#' and blank lines are skipped; the first data-like line may be a header
    (non-numeric)."""
    import csv

    import numpy as np

    try:
        with open(path, newline="") as fh:
            lines = list(enumerate(csv.reader(fh), start=1))
    except (OSError, UnicodeDecodeError) as err:
        raise ValueError(f"cannot read {path}: {getattr(err, 'strerror', None) or err}") from None
    except csv.Error as err:
        raise ValueError(f"{path}: not a CSV file: {err}") from None
    rows, ncol, header_seen = [], None, False
    for line, cells in lines:
        cells = [c.strip() for c in cells]
        if not any(cells) or cells[0].startswith("#"):
            continue
        try:
            values = [float(c) for c in cells]
        except ValueError:
            bad = next(c for c in cells if not _is_number(c))
            if not rows and not header_seen:
                header_seen = True  # a header line
                continue
            raise ValueError(f"{path}:{line}: {bad!r} is not a number (columns t, ax, ay[, az]: "
                             "s, m/s2)") from None
        if len(values) not in (3, 4):
            raise ValueError(f"{path}:{line}: {len(values)} columns, need 3 or 4 columns "
                             "(t, ax, ay[, az])")
        if ncol is not None and len(values) != ncol:
            raise ValueError(f"{path}:{line}: {len(values)} columns, the rows above have {ncol}")
        if not all(np.isfinite(values)):
            raise ValueError(f"{path}:{line}: values must be finite, got {', '.join(cells)}")
        if rows and not values[0] > rows[-1][1][0]:
            raise ValueError(f"{path}:{line}: time {values[0]:g} s is not after the previous "
                             f"row's {rows[-1][1][0]:g} s (time must increase strictly)")
        ncol = len(values)
        rows.append((line, values))
    if len(rows) < 2:
        raise ValueError(f"{path}: need at least 2 rows of 3 or 4 columns (t, ax, ay[, az])")
    data = np.array([v for _, v in rows], dtype=float)
    acc = np.zeros((len(data), 3))
    acc[:, : data.shape[1] - 1] = data[:, 1:]
    return data[:, 0], acc


def _is_number(text: str) -> bool:
    try:
        float(text)
        return True
    except ValueError:
        return False


class NoLoading(_Strict):
    """Free motion from the initial state under gravity (e.g. a block released tilted)."""

    type: Literal["none"]


Loading = Annotated[Union[TiltLoading, ShakeLoading, RecordLoading, NoLoading],
                    Field(discriminator="type")]


# --------------------------------------------------------------------------------------------
# run and solver
# --------------------------------------------------------------------------------------------
class RunSpec(_Strict):
    """How long to run and what to write (frames.npz always holds every output frame)."""

    duration: float = Field(gt=0.0, description="simulated time, s")
    output_interval: float = Field(default=0.01, gt=0.0, description="time between frames, s")
    vtk: bool = Field(default=True, description="write vtk/ (one .vtu per written frame)")
    vtk_every: int = Field(
        default=1, ge=1, description="write a .vtu for every k-th output frame"
    )
    contacts: bool = Field(
        default=False, description="also write contact points and forces (vtk/contacts_*.vtp)"
    )
    snapshot: bool = Field(default=True, description="write final.png (off-screen rendering)")
    instruments: Literal["auto", "none", "thesis"] = Field(
        default="auto",
        description="virtual instruments (instruments.npz): 'thesis' = Fig 4.4 on a box model; "
        "'auto' = thesis for a shaken box model, none otherwise",
    )
    instrument_interval: float = Field(
        default=0.002, gt=0.0, description="s between instrument samples (500 Hz)"
    )


class SolverSpec(_Strict):
    """Numerical knobs.  Every default is justified by a measurement in benchmarks/RESULTS.md."""

    dt: float | None = Field(default=None, gt=0.0, description="time step, s (default: automatic)")
    safety: float = Field(
        default=0.3, gt=0.0, le=1.0,
        description="automatic dt = safety * critical dt (0.3: results equal to a 6x smaller "
        "step; 0.6 breaks down, benchmarks/speed_error.md)",
    )
    skin: float | None = Field(
        default=None, gt=0.0, description="neighbour-list skin, m (default 0.05 * smallest block edge)"
    )
    max_pairs_per_block: int = Field(
        default=16, ge=2, description="neighbour-list capacity per block (overflow stops the run)"
    )
    overlap_tolerance: float = Field(
        default=1e-4, gt=0.0, description="largest initial overlap accepted, m"
    )
    max_speed: float = Field(
        default=50.0, gt=0.0, description="a block faster than this stops the run (runaway), m/s"
    )
    local_damping: float = Field(
        default=0.0, ge=0.0, lt=1.0, description="Cundall local (non-viscous) damping, -"
    )
    mode: Literal["auto", "serial", "parallel"] = Field(
        default="auto", description="serial multi-step kernel or one parallel kernel per step"
    )
    threads: int | None = Field(default=None, ge=1, description="CPU threads (default: all)")
    precision: Literal["f64", "f32"] = Field(
        default="f64",
        description="floating point of the engine (f32 only for speed/error studies: one "
        "precision per process)",
    )


class Case(_Strict):
    name: str = Field(min_length=1)
    description: str = ""
    scene: SceneSpec
    material: Material
    loading: Loading = Field(default_factory=lambda: NoLoading(type="none"))
    run: RunSpec
    solver: SolverSpec = Field(default_factory=SolverSpec)
    gravity: Union[float, Vec3] = Field(
        default=9.81,
        description="m/s2: a magnitude (pointing -z) or a vector in the table frame",
    )

    @field_validator("gravity", mode="before")
    @classmethod
    def _gravity_finite(cls, v):
        # before the union is tried: its branches would each report on their own ("a valid
        # number" for the vector)
        vals = v if isinstance(v, (list, tuple)) else [v]
        if all(isinstance(x, (int, float)) for x in vals) and \
                not all(math.isfinite(x) for x in vals):
            raise ValueError(f"must be a finite number or vector (m/s2), got {v}")
        return v

    @field_validator("gravity")
    @classmethod
    def _gravity(cls, v):
        if isinstance(v, (int, float)):
            if v < 0 or not math.isfinite(v):
                raise ValueError(f"gravity magnitude must be >= 0, got {v}")
        return v

    def gravity_vector(self) -> list[float]:
        if isinstance(self.gravity, (int, float)):
            return [0.0, 0.0, -float(self.gravity)]
        return [float(x) for x in self.gravity]


# --------------------------------------------------------------------------------------------
# loading from files, with errors that name the field
# --------------------------------------------------------------------------------------------
class CaseError(Exception):
    """A case that cannot be used; the message names the bad field(s)."""


def format_validation_error(
    err: ValidationError, data=None, node=None, source: str | None = None
) -> str:
    """One line per problem naming the field path (and ``source:line`` when the YAML node tree is
    given), e.g. ``case.yaml:12: loading.frequency: Input should be greater than 0``.  The union
    tags pydantic inserts (``loading.shake.frequency``) are dropped; see :mod:`dem.case_errors`."""
    from dem.case_errors import format_errors

    return format_errors(err, Case, data=data, node=node, source=source)


def parse_case(data: dict, node=None, source: str | None = None) -> Case:
    try:
        return Case.model_validate(data)
    except ValidationError as err:
        raise CaseError(format_validation_error(err, data=data, node=node, source=source)) from None


def load_case(path: str | Path) -> Case:
    from dem.case_errors import DuplicateKeyError, compose

    path = Path(path)
    try:
        text = path.read_text()
    except (OSError, UnicodeDecodeError) as err:
        raise CaseError(f"{path}: cannot read: {getattr(err, 'strerror', None) or err}") from None
    try:
        node = compose(text)
        data = yaml.safe_load(text)
    except yaml.YAMLError as err:
        mark = getattr(err, "problem_mark", None)
        where = f"{path}:{mark.line + 1}" if mark is not None else f"{path}"
        raise CaseError(f"{where}: not valid YAML: {err}") from None
    except DuplicateKeyError as err:
        raise CaseError(f"{path}: {err}") from None
    if not isinstance(data, dict):
        raise CaseError(f"{path}: the case must be a YAML mapping, got {type(data).__name__}")
    case = parse_case(data, node=node, source=str(path))
    ld = case.loading
    if isinstance(ld, RecordLoading) and ld.file is not None:
        f = Path(ld.file)
        ld.file = str(f if f.is_absolute() else path.parent / f)
        try:
            ld.samples()
        except ValueError as err:
            raise CaseError(f"{path}: loading.file: {err}") from None
    return case


def case_json_schema() -> str:
    """JSON schema of case files (``dem schema``; committed as ``cases/case.schema.json``).

    Editors with a YAML language server pick it up from a first line
    ``# yaml-language-server: $schema=<relative path>/case.schema.json``.
    """
    import json

    schema = Case.model_json_schema()
    schema = {
        "$schema": "https://json-schema.org/draft/2020-12/schema",
        **schema,
        "title": "dem-masonry case file",
    }
    return json.dumps(schema, indent=2) + "\n"
