"""One validation path for ``dem check`` and ``dem run`` (and each sweep point): what one
accepts the other runs, what one rejects the other rejects, with the same message.

:func:`check_case` takes a validated :class:`dem.case.Case` (the schema has already refused
wrong types, unknown keys, NaN / inf, out-of-range numbers) and checks what needs the scene,
the time step or the loading together:

size (before anything is built)
    the block count is estimated from the case (:func:`estimate_blocks`, an upper bound) with the
    memory the run will take (engine arrays, frames kept in memory, files written); above
    ``max_blocks`` (default dem.environment.DEFAULT_MAX_BLOCKS, or ``DEM_MAX_BLOCKS``, or
    ``--max-blocks``) the case is refused without building it, as it is when the estimated memory
    exceeds the machine's.
scene
    built and checked (:func:`dem.builders.check_scene`: initial overlaps deeper than
    ``solver.overlap_tolerance``, floating blocks).
time step
    the critical step of the scene (:mod:`dem.engine.timestep` with the face-area caps at their
    smallest: the largest the engine can find, so a step above it is certainly unstable);
    ``solver.dt`` above it is refused.  The step the run will use is ``solver.dt`` or
    ``solver.safety`` times it (the engine may find a slightly smaller one once it sees the
    contacts at the start).
initial state
    a block whose initial speed |v| + |omega| r (r = half its diagonal: the engine's measure)
    reaches ``solver.max_speed`` would stop the run at step 1: refused.
plausibility (a typo or a unit slip that still validates: warned, or refused when impossible)
    block densities, a block far from all others (:func:`scene_plausibility`), the table's
    g-level, stroke and speed (:func:`table_plausibility`): warnings (``IMPLAUSIBLE``) for what
    no masonry experiment would do, errors for the impossible; thresholds and their
    justification at the top of this module.
loading
    shake: the period must span at least :data:`MIN_STEPS_PER_PERIOD` = 20 time steps.  With 20
    samples per cycle the sampled table acceleration reaches its peak within 1 - cos(pi/20) =
    1.2 %, and the phase error of the explicit scheme, (omega dt)^2 / 24, is 0.4 %; with fewer
    the excitation is aliased (at 1e6 Hz and dt 1e-5 s the table is never felt at all).
    record: a record that ends before ``run.duration`` is accepted only if the table is at rest
    at its end (|v_end| <= 1e-3 of the record's peak velocity): after the end the acceleration
    is zero, so the table stops where the record left it; a table still moving would drift
    |v_end| (duration - t_end) metres: refused, naming the drift.  Samples closer than the time
    step: warning (the engine samples the record once per step).
output
    ``run.output_interval`` shorter than the time step would write a frame (and a VTK file)
    every step: refused (error), with the frame count.  Longer than ``run.duration``: warning
    (only the first and last states are written).

Messages are ``FILE:LINE: field: what is wrong (the numbers)``, as the schema's.
"""

from __future__ import annotations

import importlib.util
import math
import os
from dataclasses import dataclass, field
from pathlib import Path

import numpy as np

from dem.case import (Case, NoiseLoading, RecordLoading, ShakeLoading, SteppedShakeLoading,
                      SweepLoading)
from dem.environment import max_blocks_default

# --- plausibility: warn loudly on the implausible, refuse the impossible ----------------------
# density of a block, kg/m3.  Plausible: what masonry, timber and steel span, from the lightest
# timber (balsa, ~ 150 kg/m3; aerated concrete 300-800, brick 1600-2000, stone 2000-3000) to
# steel (7850; stainless 8000): outside it the case most likely mixes units (sizes in mm with
# masses in kg, masses in g).  Impossible: lighter than air (1.2 kg/m3: even silica aerogel,
# the lightest solid, is ~ 1-3 kg/m3) or denser than osmium (22 590 kg/m3, the densest material
# at ambient conditions).
DENSITY_PLAUSIBLE_KG_M3 = (150.0, 8100.0)
DENSITY_POSSIBLE_KG_M3 = (1.2, 22_590.0)
# table motion.  Plausible: peak acceleration up to 5 g (the strongest building shaking tables
# reach ~ 1-4.7 g bare: E-Defense 0.9 g loaded, UCSD LHPOST 4.7 g bare) and a stroke up to 1 m
# (E-Defense +-1 m, LHPOST +-0.75 m).  Impossible (refused): a peak table velocity above
# 100 m/s, fifty times the fastest tables' (~ 2 m/s, E-Defense and LHPOST 1.8-2 m/s) - and
# in the DEM a table faster than solver.max_speed with blocks that slide on it (peak
# acceleration above mu g) stops the run as a runaway once a block slides, so it is refused
# as well.
G_STANDARD = 9.80665
TABLE_ACCELERATION_PLAUSIBLE_G = 5.0
TABLE_STROKE_PLAUSIBLE_M = 1.0
TABLE_SPEED_POSSIBLE_M_S = 100.0
# gravity, m/s2: on the Earth's surface it spans 9.780 (equator) to 9.832 (poles) at sea level
# (normal gravity, GRS80), a little less on mountains; outside 9.7 - 9.9 a case most likely
# mixes units (9810: mm/s2) or forgot it (0: nothing holds the blocks on the table)
GRAVITY_PLAUSIBLE_M_S2 = (9.7, 9.9)
# the joints' elastic offset of tipping load factors (dem.compliance) above which dem check warns
# instead of informing: at 5 % the joint law's compliance, a modelling choice and not a property
# of the masonry, moves a load factor in its second digit, the digit the thesis' series differ in
ELASTIC_OFFSET_WARN = 0.05
# a block whose gap to its nearest neighbour exceeds this many times the scene's largest block
# dimension cannot meet the others during a run (a block moves a few table strokes at most): it
# is almost always a typo (mm for m, a sign), and it stretches the neighbour grid.
FAR_BLOCK_FACTOR = 100.0

# DEFAULT_MAX_BLOCKS = 20 000 and max_blocks_default (DEM_MAX_BLOCKS): dem.environment
MIN_STEPS_PER_PERIOD = 20
RECORD_REST_FRACTION = 1e-3
# memory per block of the engine (Model / State / Contacts: ~ 60 reals per body, pair buffers of
# max_pairs_per_block / 2 pairs with 4 points of ~ 20 reals each, neighbour list, kernels'
# temporaries): measured order of magnitude, ~ 8 kB per block at the default 16 pairs
ENGINE_BYTES_PER_BLOCK = 8_000
FRAME_BYTES_PER_BLOCK = 16 * 8       # pos, quat, vel, omega per frame in memory (float64)
DISK_BYTES_PER_BLOCK = 150 + 60      # per frame: .vtu (float32 + zlib) + frames.npz (compressed)
NPZ_BYTES_PER_BLOCK = 60             # per frame, frames.npz only (run.vtk: false)
# run-time estimate: the serial kernel's throughput is flat at 1.0-1.3e6 brick-steps/s from 55 to
# 3078 bricks on the 2-core test machine (benchmarks/RESULTS.md, "serial kernel"); the estimate
# takes the low end, and says it is that machine's figure
BRICK_STEPS_PER_SECOND = 1.0e6


@dataclass
class Checked:
    """The result of :func:`check_case`."""

    case: Case
    errors: list[str] = field(default_factory=list)
    warnings: list[str] = field(default_factory=list)
    scene: object = None
    report: object = None
    blocks_estimate: int = 0
    dt: float | None = None
    dt_critical: float | None = None
    n_frames: int | None = None
    memory_bytes: float | None = None
    disk_bytes: float | None = None
    joints: dict | None = None
    imperfections: dict | None = None
    n_steps: int | None = None

    @property
    def ok(self) -> bool:
        return not self.errors

    def size_line(self) -> str:
        parts = [f"about {self.blocks_estimate:,} blocks"]
        if self.memory_bytes is not None:
            parts.append(f"estimated memory {_fmt_bytes(self.memory_bytes)}")
        if self.disk_bytes is not None and self.n_frames is not None:
            parts.append(f"{self.n_frames:,} frames, output about {_fmt_bytes(self.disk_bytes)}")
        if self.dt is not None:
            parts.append(f"time step {self.dt:.3g} s")
        if self.n_steps is not None:
            secs = self.n_steps * max(self.blocks_estimate, 1) / BRICK_STEPS_PER_SECOND
            parts.append(f"{self.n_steps:,} steps, run time about {_fmt_seconds(secs)} of "
                         f"stepping at {BRICK_STEPS_PER_SECOND:.0e} brick-steps/s (the 2-core "
                         f"test machine's serial kernel, benchmarks/RESULTS.md; plus ~10 s of "
                         f"start-up)")
        return "size: " + ", ".join(parts) + (f"\n{joint_line(self.joints)}" if self.joints
                                                else "") + (
            f"\n{imperfection_line(self.imperfections)}" if self.imperfections else "")


def imperfection_line(imp: dict) -> str:
    """One line on the realised imperfections (dem.imperfections.realised_summary)."""
    mm = 1e3
    parts = [f"bed unevenness {imp['bed_unevenness_m'] * mm:.3g} mm ({imp['face_shape']} faces)"]
    if "faces" in imp:
        parts[-1] += (f" (largest recess {imp['faces']['largest_recess_m'] * mm:.3g} mm, mean "
                      f"|twist| {imp['faces']['twist_mean_abs_m'] * mm:.3g} mm)")
    parts.append("size scatter [" + ", ".join(f"{v * mm:.3g}" for v in imp["size_scatter_m"])
                 + "] mm")
    if "sizes" in imp:
        parts[-1] += f" (largest deviation {imp['sizes']['largest_deviation_m'] * mm:.3g} mm)"
    parts.append(f"arris {imp['arris_m'] * mm:.3g} mm")
    ab = imp.get("as_built", {})
    for key, what in (("corner_gap", "corner ends"), ("head_gap", "head joints")):
        if key in ab:
            r = ab[key]
            parts.append(f"{key.replace('_', ' ')}s {r['mean_m'] * mm:.3g} +- "
                         f"{r['scatter_m'] * mm:.3g} mm ({r['n_open']} of {r['n_joints']} "
                         f"{what} open, largest {r['largest_m'] * mm:.3g} mm)")
    if "plumb" in ab:
        r = ab["plumb"]
        parts.append(f"out of plumb [{r['sigma_m'][0] * mm:.3g}, {r['sigma_m'][1] * mm:.3g}] mm "
                     f"per course, lean [{r['lean_deg'][0]:.3g}, {r['lean_deg'][1]:.3g}] deg "
                     f"(top course offset [{r['top_offset_m'][0] * mm:.3g}, "
                     f"{r['top_offset_m'][1] * mm:.3g}] mm, largest step between courses "
                     f"{r['largest_course_step_m'] * mm:.3g} mm)")
    return (f"imperfections (seed {imp['seed']}): " + ", ".join(parts)
            + "; the scene settles under gravity before it is loaded (docs/imperfections.md)")


def joint_line(joints: dict) -> str:
    """One line on the joint stiffness and what its compliance does to tipping load factors."""
    eo = joints["elastic_offset"]
    line = (f"joints: kn = {joints['normal_stiffness_Pa_m']:.3g} Pa/m ({joints['chosen']}); "
            f"estimated elastic offset of tipping load factors: single blocks "
            f"{100 * eo['block']['relative']:.2g} %, columns on the table "
            f"{100 * eo['column']['relative']:.2g} % (dem/compliance.py)")
    cost = joints.get("time_step_cost")
    if cost:
        line += f"; {cost['steps_factor']:.3g} x the steps of kn = {cost['vs_kn_Pa_m']:.3g}"
    return line


def _fmt_seconds(s: float) -> str:
    if s < 120:
        return f"{s:.2g} s"
    if s < 7200:
        return f"{s / 60:.3g} min"
    return f"{s / 3600:.3g} h"


def _fmt_bytes(b: float) -> str:
    for unit in ("B", "kB", "MB", "GB", "TB"):
        if b < 1000 or unit == "TB":
            return f"{b:.3g} {unit}"
        b /= 1000
    return f"{b:.3g} TB"


def estimate_blocks(case: Case) -> int:
    """Upper bound of the block count, from the case alone (nothing built)."""
    s = case.scene
    n = len(s.blocks)
    if s.wall is not None:
        w = s.wall
        per = w.length + 1
        if getattr(w, "bond", "stretcher") == "english":
            per = 2 * w.length + 2
        n += w.courses * per
    if s.facade is not None:
        f = s.facade
        wings = sum(x.length for x in (f.left, f.right) if x is not None)
        n += f.courses * (f.length + wings + 3)
    if s.box_model is not None:
        b = s.box_model
        courses = b.courses or {"I": 9, "II": 9, "III": 15}[b.model]
        n += courses * 2 * (b.length + b.width + 1)
        roof = b.roof
        if roof is not None:
            n += roof.beams * 3 + 4
    return n


def _machine_memory() -> float | None:
    try:
        return float(os.sysconf("SC_PAGE_SIZE") * os.sysconf("SC_PHYS_PAGES"))
    except (ValueError, OSError, AttributeError):
        return None


def _timestep_module():
    """dem/engine/timestep.py is numpy only; loaded by path because importing the dem.engine
    package starts Taichi (a second of start-up that ``dem check`` does not need)."""
    path = Path(__file__).parent / "engine" / "timestep.py"
    spec = importlib.util.spec_from_file_location("dem._timestep_numpy", path)
    mod = importlib.util.module_from_spec(spec)
    spec.loader.exec_module(mod)
    return mod


def critical_step(case: Case, scene) -> float:
    """The largest critical time step the engine can find for this scene (s)."""
    from dem.run.build import case_joint_law

    ts = _timestep_module()
    jl = case_joint_law(case, scene)
    movable = ~np.asarray(scene.fixed, dtype=bool)
    kn, ks, zeta = jl.step_stiffness()  # per-pair materials, the hyperbolic law's tangent
    face, _ = ts.face_area_caps(scene.size, scene.mass, scene.inertia(), movable,
                                kn, ks, case.solver.safety)
    return float(ts.critical_time_step(scene.size, scene.mass, scene.inertia(), movable,
                                       kn, ks, zeta, face, beta=jl.step_beta()))


def table_plausibility(peak_acceleration: float, stroke: float, frequency: float | None,
                       where_freq: str, where: str) -> tuple[list[str], list[str]]:
    """(warnings, errors) on a sinusoidal table motion of peak acceleration a_p (m/s2) and
    displacement amplitude A (m) at f (Hz): peak velocity v_p = A 2 pi f = a_p / (2 pi f);
    thresholds above (TABLE_*).  Used by the DEM (check_case) and the two-body model
    (dem.rocking.schema.rocking_plausibility)."""
    warnings, errors = [], []
    g = peak_acceleration / G_STANDARD
    if frequency:
        v = stroke * 2.0 * math.pi * frequency
        if v > TABLE_SPEED_POSSIBLE_M_S:
            errors.append(
                f"{where}: the table would move at up to {v:.3g} m/s (amplitude {stroke:.3g} m "
                f"at {frequency:g} Hz, {g:.3g} g), above {TABLE_SPEED_POSSIBLE_M_S:g} m/s, "
                f"fifty times the fastest shaking tables (~ 2 m/s): impossible; check the units "
                f"of amplitude (m), peak_acceleration (m/s2) and frequency (Hz)")
            return warnings, errors
    if g > TABLE_ACCELERATION_PLAUSIBLE_G:
        warnings.append(
            f"{where}: IMPLAUSIBLE: peak table acceleration {peak_acceleration:.3g} m/s2 = "
            f"{g:.3g} g, far above any shaking table (the strongest reach ~ 1-4.7 g); check "
            f"the units (m, m/s2, Hz)")
    if stroke > TABLE_STROKE_PLAUSIBLE_M:
        warnings.append(
            f"{where}: IMPLAUSIBLE: table displacement amplitude {stroke:.3g} m, beyond any "
            f"shaking table's stroke (~ +-1 m); check the units (m)")
    return warnings, errors


def gravity_plausibility(case: Case, where) -> list[str]:
    """Warnings (``IMPLAUSIBLE``) on a gravity magnitude outside GRAVITY_PLAUSIBLE_M_S2 (a
    gravity that does not point down, and a tilt without gravity, are refused by the schema:
    dem.case.document)."""
    g = float(np.linalg.norm(case.gravity_vector()))
    lo, hi = GRAVITY_PLAUSIBLE_M_S2
    if lo <= g <= hi:
        return []
    if g == 0.0:
        what = "no gravity: nothing holds the blocks on the table"
    else:
        what = f"gravity {g:.4g} m/s2 = {g / G_STANDARD:.3g} g"
    return [f"{where(('gravity',))}: IMPLAUSIBLE: {what}; on the Earth's surface it is "
            f"{lo:g} - {hi:g} m/s2; check the units (m/s2, not mm/s2)"]


def shake_cut(ld, duration: float, where) -> tuple[list[str], list[str]]:
    """(warnings, errors) of a shake (or stepped shake) that the run ends before it is over: the
    engine stops at run.duration whatever the table still had to do, so a result would be that of
    a shorter test than the case asks for (its description says 50 cycles, the blocks feel 34).
    Refused when the run ends before the last full cycle of the shake (of the last step, for a
    stepped shake) is over: the shake is cut by at least one cycle; warned of when only a
    fraction of a cycle at the end is cut (cycles: 10.5, or a stepped shake's run-on to the
    table's next extreme)."""
    tol = 1e-9 * max(duration, 1.0)
    if isinstance(ld, ShakeLoading):
        f, end = ld.frequency, ld.cycles / ld.frequency
        last_full = math.floor(ld.cycles + 1e-9) / f
        shaken = duration * f
        what = f"{ld.cycles:g} cycles at {f:g} Hz, {end:.4g} s"
        fewer = "loading.cycles"
    elif isinstance(ld, SteppedShakeLoading):
        motion = ld.motion()
        f = float(motion.freq[-1])
        end = float(motion.t_end)
        last_full = float(motion.t0[-2]) + math.floor(ld.steps[-1].cycles + 1e-9) / f
        k = int(motion.step_of(duration)) if duration < end else len(ld.steps) - 1
        shaken = None
        what = (f"{len(ld.steps)} steps, {sum(s.cycles for s in ld.steps):g} cycles, ending at "
                f"{end:.4g} s; the run ends in step {k} ({float(motion.freq[k]):g} Hz)")
        fewer = "cycles in loading.steps"
    else:
        return [], []
    if duration + tol >= end:
        return [], []
    head = f"{where(('run', 'duration'))}: {duration:g} s ends the run before the shake ({what})"
    head += f" is over: the table shakes {shaken:.3g} of them" if shaken is not None else \
        " is over"
    fix = (f"; make run.duration at least {end:.4g} s (plus the free motion after it you want "
           f"to see) or give fewer {fewer}")
    if duration + tol < last_full:
        return [], [head + fix]
    return [head + " (the last fraction of a cycle is cut)" + fix], []


def unused_pair_warnings(case: Case, scene, where) -> list[str]:
    """``material.pairs`` entries naming a material no block of the built scene has (the table
    is always there): their constants would apply to no joint."""
    used = {scene.material_names[m] for m in np.unique(scene.material)} | {"table"}
    out = []
    for k, pair in enumerate(case.material.pairs):
        for m, name in enumerate(pair.between):
            if name not in used:
                out.append(f"{where(('material', 'pairs', k, 'between', m))}: no block of this "
                           f"scene is '{name}' (the blocks are {', '.join(sorted(used))}): this "
                           f"pair's constants apply to no joint")
                break
    return out


def static_pressure(scene, g: float) -> np.ndarray:
    """Pa: an estimate of the static pressure on each block's bottom face: the weight of the
    block and of every block whose centre stands above its footprint (axis-aligned, the block's
    size), over that footprint.  Exact for a column of equal blocks; a running bond spreads
    the load, so it errs high by up to the ratio of a block to its overlap with the ones above
    (at most ~ 2).  Fixed blocks carry nothing (they are supports)."""
    from scipy.spatial import cKDTree

    pos = np.asarray(scene.position, dtype=float)
    size = np.asarray(scene.size, dtype=float)
    mass = np.asarray(scene.mass, dtype=float)
    movable = ~np.asarray(scene.fixed, dtype=bool)
    p = np.zeros(len(pos))
    if not movable.any():
        return p
    tree = cKDTree(pos[:, :2])
    for i in np.flatnonzero(movable):
        half = 0.5 * size[i, :2]
        near = np.asarray(tree.query_ball_point(pos[i, :2], float(np.linalg.norm(half))),
                          dtype=int)
        inside = near[(np.abs(pos[near, 0] - pos[i, 0]) <= half[0]) &
                      (np.abs(pos[near, 1] - pos[i, 1]) <= half[1]) &
                      (pos[near, 2] >= pos[i, 2]) & movable[near]]
        p[i] = mass[inside].sum() * g / (size[i, 0] * size[i, 1])
    return p


# the first settling of a scene released touching overshoots its static closures: measured on
# cases/joint/hyperbolic-column.yaml (nine bricks, hyperbolic joints), the base joint reaches
# 0.52 d_max against 0.36 at rest, 1.44 times
SETTLING_OVERSHOOT = 1.44


def hyperbolic_closure_check(case: Case, scene, where) -> tuple[list[str], list[str]]:
    """(warnings, errors) of a hyperbolic joint law's max_closure against the scene: larger than
    the smallest block dimension (no joint closes by a brick), or so small that the static
    closure under gravity alone, d = p / (kn0 + p / d_max) with p from :func:`static_pressure`,
    passes closure_limit x d_max (the run would stop as it settles: refused when the static
    closure passes it, warned of when the settling overshoot may: SETTLING_OVERSHOOT).  The
    material's own constants; pairs with their own are not checked."""
    mat = case.material
    if mat.normal_law != "hyperbolic" or mat.max_closure is None:
        return [], []
    dmax, kn0, lim = float(mat.max_closure), float(mat.normal_stiffness), mat.closure_limit
    movable = ~np.asarray(scene.fixed, dtype=bool)
    size = np.asarray(scene.size, dtype=float)
    smallest = float(size[movable].min()) if movable.any() else float(size.min())
    loc = where(("material", "max_closure"))
    if dmax >= smallest:
        return [], [f"{loc}: {dmax:g} m is not smaller than the smallest block dimension "
                    f"({smallest:g} m): a joint closes by fractions of a millimetre (a seating "
                    f"test measures it: docs/engine.md); check the units (m)"]
    g = float(np.linalg.norm(case.gravity_vector()))
    p = float(static_pressure(scene, g).max())
    if p <= 0.0:
        return [], []
    d = p / (kn0 + p / dmax)
    needed = p * (1.0 - lim) / (lim * kn0)          # d_max with d = closure_limit d_max
    text = (f"{loc}: under gravity alone the most loaded joint (static pressure about "
            f"{p:.3g} Pa) closes by about {d:.3g} m = {d / dmax:.2f} x max_closure")
    if mat.beyond_closure_limit == "stop" and d > lim * dmax:
        return [], [text + f", beyond closure_limit = {lim:g}: the run would stop as the scene "
                    f"settles; give max_closure >= {needed:.3g} m (or a larger closure_limit, "
                    f"or beyond_closure_limit: tangent)"]
    if d * SETTLING_OVERSHOOT > lim * dmax:
        return [text + f"; the first settling overshoots it (~ {SETTLING_OVERSHOOT:g} x) "
                f"past closure_limit = {lim:g}: the run may "
                + ("stop at its start" if mat.beyond_closure_limit == "stop"
                   else "go on along the tangent") + f" (max_closure >= "
                f"{needed * SETTLING_OVERSHOOT:.3g} m, or closure_limit "
                f"{min(d * SETTLING_OVERSHOOT / dmax, 0.99):.2g}, avoids it)"], []
    return [], []


def _block_loc(i: int, n_listed: int) -> tuple:
    return ("scene", "blocks", i) if i < n_listed else ("scene",)


def scene_plausibility(scene, where, n_listed: int = 0) -> tuple[list[str], list[str]]:
    """(warnings, errors): block densities (DENSITY_*) and blocks far from all others
    (FAR_BLOCK_FACTOR); ``where(loc)`` prefixes FILE:LINE: field; ``n_listed``: the scene's
    first blocks are the case's ``scene.blocks`` (their line is named)."""
    warnings, errors = [], []
    size = np.asarray(scene.size, dtype=float)
    n = len(size)
    if n == 0:
        return warnings, errors
    rho = np.asarray(scene.mass, dtype=float) / np.prod(size, axis=1)
    lo, hi = DENSITY_POSSIBLE_KG_M3
    plo, phi = DENSITY_PLAUSIBLE_KG_M3
    bad = np.flatnonzero((rho < lo) | (rho > hi))
    odd = np.flatnonzero((rho < plo) | (rho > phi))
    if len(bad):
        i = int(bad[0])
        errors.append(
            f"{where(_block_loc(i, n_listed))}: block {i} has a density of {rho[i]:.3g} kg/m3 (mass "
            f"{scene.mass[i]:.3g} kg, size {' x '.join(f'{x:.3g}' for x in size[i])} m)"
            + (f" ({len(bad)} blocks like it)" if len(bad) > 1 else "")
            + f": impossible (outside {lo:g} - {hi:g} kg/m3, air to osmium); sizes are in m, "
              f"masses in kg, densities in kg/m3")
    elif len(odd):
        i = int(odd[0])
        warnings.append(
            f"{where(_block_loc(i, n_listed))}: IMPLAUSIBLE: block {i} has a density of {rho[i]:.3g} kg/m3"
            + (f" ({len(odd)} blocks outside the range)" if len(odd) > 1 else "")
            + f", outside what masonry, timber and steel span ({plo:g} - {phi:g} kg/m3); check "
              f"the units (m, kg, kg/m3)")
    if n >= 2:
        from scipy.spatial import cKDTree

        centre = np.asarray(scene.position, dtype=float)
        radius = 0.5 * np.linalg.norm(size, axis=1)
        dist, idx = cKDTree(centre).query(centre, k=2)
        gap = dist[:, 1] - radius - radius[idx[:, 1]]  # a lower bound of the true gap
        limit = FAR_BLOCK_FACTOR * float(size.max())
        far = np.flatnonzero(gap > limit)
        if len(far):
            # of two far-apart groups, name the block farthest from the median of all centres
            off = np.linalg.norm(centre[far] - np.median(centre, axis=0), axis=1)
            i = int(far[int(np.argmax(off))])
            warnings.append(
                f"{where(_block_loc(i, n_listed))}: IMPLAUSIBLE: block {i} at "
                f"[{', '.join(f'{x:.3g}' for x in centre[i])}] m is {gap[i]:.3g} m from the "
                f"nearest other block (more than {FAR_BLOCK_FACTOR:g} x the largest block, "
                f"{limit:.3g} m): it can never meet the others; check its position (m)")
    return warnings, errors


class _Where:
    """``FILE:LINE: field`` prefixes from the case file's YAML nodes."""

    def __init__(self, source: str | Path | None):
        self.source = str(source) if source is not None else None
        self.node = self.data = None
        if source is not None:
            try:
                from dem.case.document import read_case_yaml

                self.data, self.node = read_case_yaml(source)  # parsed once (kept)
            except Exception:  # noqa: BLE001 - the line is a nicety
                pass

    def __call__(self, loc: tuple) -> str:
        from dem.case_errors import join_field_path, walk_yaml

        field_path = join_field_path([f"[{p}]" if isinstance(p, int) else p for p in loc])
        line = None
        if self.data is not None:
            path, line = walk_yaml(self.node, self.data, loc)
            field_path = join_field_path(path) or field_path
        if self.source and line:
            return f"{self.source}:{line}: {field_path}"
        return f"{self.source}: {field_path}" if self.source else field_path


def load_and_check(path: str | Path, say, max_blocks: int | None = None) -> Checked | None:
    """``dem check`` and ``dem run``'s first step: load the case file at ``path`` and run
    :func:`check_case`, printing each warning and error as one line through ``say``
    (``warning: ...``, ``error: FILE:LINE: field: ...``).  None when the file or the case is bad
    (exit 2)."""
    from dem.case import CaseError, load_case

    try:
        case = load_case(path, max_blocks)
    except CaseError as err:
        say(f"error: {err}" if str(err).startswith(str(path)) else f"error: {path}: {err}")
        return None
    checked = check_case(case, path, max_blocks=max_blocks)
    for w in checked.warnings:
        say(f"warning: {w}")
    for e in checked.errors:
        say(f"error: {e}")
    return checked if checked.ok else None


SCENE_FIELDS = ("scene", "material", "solver", "imperfections", "gravity")


def same_scene(a: Case, b: Case) -> bool:
    """True when two cases build the same scene with the same joints and step (they differ at
    most in name, loading and run: a sweep's points)."""
    return all(getattr(a, f) == getattr(b, f) for f in SCENE_FIELDS)


def _check_scene(case: Case, out: Checked, where) -> float | None:
    """check_case's scene part: build it, check it, its joints and its critical step (s; None
    when the scene could not be built)."""
    from dem.builders import check_scene
    from dem.run.build import scene_from_case

    try:
        scene = scene_from_case(case, check=False)
    except ValueError as err:
        out.errors.append(f"{where(('scene',))}: {err}")
        return None
    out.scene = scene
    n = scene.n_blocks
    out.blocks_estimate = n
    # size scatter: two bricks' heights differ by up to 6 sigma (each truncated at 3 sigma), so
    # a brick bridging them may rock that far onto the lower one while the scene settles
    report = check_scene(scene, overlap_tolerance=case.solver.overlap_tolerance,
                         allow_floating=case.scene.allow_floating,
                         settle_gap=6.0 * max(case.imperfections.size_scatter))
    out.report = report
    w, e = scene_plausibility(scene, where, len(case.scene.blocks))
    out.warnings += gravity_plausibility(case, where) + w
    out.errors += e
    out.warnings += unused_pair_warnings(case, scene, where)
    w, e = hyperbolic_closure_check(case, scene, where)
    out.warnings += w
    out.errors += e
    if not report.ok:
        out.errors.append(f"{where(('scene',))}: the scene cannot be run:\n{report.format()}")

    # joints, time step
    from dem.run.build import case_joint_law, joint_summary

    out.joints = joint_summary(case, scene, case_joint_law(case, scene))
    eo = out.joints["elastic_offset"]
    worst = max(eo["block"]["relative"], eo["column"]["relative"])
    if worst > ELASTIC_OFFSET_WARN and case.material.normal_stiffness != "rigid" and \
            case.loading.type == "tilt":  # a tilt's result is the load factor
        out.warnings.append(
            f"{where(('material', 'normal_stiffness'))}: the joints' elastic offset of tipping "
            f"load factors is up to {100 * worst:.2g} % (single blocks "
            f"{100 * eo['block']['relative']:.2g} %, columns {100 * eo['column']['relative']:.2g}"
            f" %) at kn = {out.joints['normal_stiffness_Pa_m']:.3g} Pa/m: a tilt's load factor "
            f"comes out that much below the rigid-block value; 'normal_stiffness: rigid' brings "
            f"it to 0.5 % (dem/compliance.py)")
    if case.imperfections.any():
        from dem.imperfections import realised_summary
        from dem.run.build import as_built_record, imperfection_params, size_reference

        out.imperfections = realised_summary(scene, imperfection_params(case),
                                             size_reference(case), as_built_record(case))
    dt_crit = critical_step(case, scene)
    return dt_crit


def check_case(case: Case, source: str | Path | None = None,
               max_blocks: int | None = None, build: bool = True,
               like: Checked | None = None) -> Checked:
    """Check a validated case (module docstring).  Never raises for a bad case: the problems are
    in ``Checked.errors`` / ``warnings``; ``Checked.scene`` is the built scene (None when the
    check stopped before building it).  ``like``: the result of an earlier check of a case with
    the same scene (:func:`same_scene`): its scene and step are reused, and only what depends on
    the loading and the run is checked again."""
    where = _Where(source)
    out = Checked(case=case)
    max_blocks = max_blocks_default() if max_blocks is None else int(max_blocks)
    run = case.run
    n_est = estimate_blocks(case)
    out.blocks_estimate = n_est
    frames = int(math.floor(run.duration / run.output_interval + 1e-9)) + 2
    out.n_frames = frames
    out.memory_bytes = n_est * (ENGINE_BYTES_PER_BLOCK + frames * FRAME_BYTES_PER_BLOCK)
    per_frame = DISK_BYTES_PER_BLOCK if run.vtk else NPZ_BYTES_PER_BLOCK
    out.disk_bytes = n_est * frames * per_frame
    ram = _machine_memory()
    if n_est > max_blocks:
        out.errors.append(
            f"{where(('scene',))}: about {n_est:,} blocks (estimated memory "
            f"{_fmt_bytes(out.memory_bytes)}, output {_fmt_bytes(out.disk_bytes)}), above the "
            f"limit of {max_blocks:,} blocks; not built.  Raise the limit with --max-blocks or "
            f"DEM_MAX_BLOCKS if this is meant")
        return out
    if not build:
        return out
    if like is not None and like.scene is not None and same_scene(case, like.case):
        # the same scene, material, solver and imperfections as a case checked already (a
        # sweep's points): its scene, joints and critical step are those
        out.scene, out.report, out.joints = like.scene, like.report, like.joints
        out.imperfections = like.imperfections
        dt_crit = like.dt_critical if like.dt_critical is not None else math.inf
    else:
        dt_crit = _check_scene(case, out, where)
        if dt_crit is None:
            return out
    scene = out.scene
    n = scene.n_blocks
    out.blocks_estimate = n
    out.dt_critical = dt_crit if math.isfinite(dt_crit) else None
    sv = case.solver
    if sv.dt is not None:
        if math.isfinite(dt_crit) and sv.dt > dt_crit:
            out.errors.append(
                f"{where(('solver', 'dt'))}: {sv.dt:.3g} s is above the critical time step "
                f"{dt_crit:.3g} s of this scene (kn = {out.joints['normal_stiffness_Pa_m']:.3g} "
                f"Pa/m); "
                f"use solver.dt <= {sv.safety * dt_crit:.3g} s or leave it out")
            dt = float(sv.safety * dt_crit)  # the other checks with a step that can run
        else:
            dt = float(sv.dt)
    else:
        dt = float(sv.safety * dt_crit) if math.isfinite(dt_crit) else 1e-4
    out.dt = dt
    frames_by_step = int(run.duration / max(run.output_interval, dt)) + 2
    out.n_frames = frames_by_step
    out.memory_bytes = n * (ENGINE_BYTES_PER_BLOCK + frames_by_step * FRAME_BYTES_PER_BLOCK)
    out.disk_bytes = n * frames_by_step * per_frame
    out.n_steps = int(math.ceil(run.duration / dt))
    if ram is not None and out.memory_bytes > ram:
        out.errors.append(
            f"{where(('run', 'output_interval'))}: the run would need about "
            f"{_fmt_bytes(out.memory_bytes)} of memory ({frames_by_step:,} frames of {n:,} "
            f"blocks kept in memory), more than this machine's {_fmt_bytes(ram)}")

    # initial speeds
    radius = 0.5 * np.linalg.norm(scene.size, axis=1)
    speed = np.linalg.norm(scene.velocity, axis=1) + \
        np.linalg.norm(scene.angular_velocity, axis=1) * radius
    speed[np.asarray(scene.fixed, dtype=bool)] = 0.0
    if n and speed.max() >= sv.max_speed:
        i = int(np.argmax(speed))
        loc = ("scene", "blocks", i) if i < len(case.scene.blocks) else ("scene",)
        out.errors.append(
            f"{where(loc)}: block {i} starts at {speed[i]:.3g} m/s (|v| + |omega| r), at or "
            f"above solver.max_speed = {sv.max_speed:g} m/s, which stops the run as a runaway; "
            f"raise solver.max_speed or lower the initial velocity")

    # loading
    ld = case.loading
    if isinstance(ld, ShakeLoading):
        stroke = ld.axis_amplitude
        a_peak = stroke * (2.0 * math.pi * ld.frequency) ** 2
        if ld.distortion is not None:   # the distorted table's own peak (dem.table_motion)
            motion = ld.motion()
            a_peak *= motion.distorted_peak_acceleration / motion.peak_acceleration
            spike = ld.distortion.reversal_spike
            if spike is not None and 2.0 * spike.duration < MIN_STEPS_PER_PERIOD * dt:
                out.errors.append(
                    f"{where(('loading', 'distortion', 'reversal_spike', 'duration'))}: a "
                    f"pulse of {spike.duration:.3g} s spans fewer than "
                    f"{MIN_STEPS_PER_PERIOD // 2} time steps ({dt:.3g} s): the table motion "
                    f"cannot be resolved")
        w, e = table_plausibility(a_peak, stroke, ld.frequency, "",
                                  where(("loading", "amplitude" if ld.amplitude is not None
                                         else "peak_acceleration")))
        resolved = 1.0 / ld.frequency >= MIN_STEPS_PER_PERIOD * dt
        if not resolved:
            w, e = [], []  # a motion the step cannot resolve: that error (below) comes first
        out.warnings += w
        out.errors += e
        v_peak = stroke * 2.0 * math.pi * ld.frequency
        if resolved and not e and v_peak >= sv.max_speed and a_peak > case.material.friction * \
                float(np.linalg.norm(case.gravity_vector())):
            out.errors.append(
                f"{where(('loading',))}: the table moves at up to {v_peak:.3g} m/s, at or above "
                f"solver.max_speed = {sv.max_speed:g} m/s, and its peak acceleration "
                f"{a_peak:.3g} m/s2 exceeds mu g: a block that slides reaches that speed "
                f"relative to the table and stops the run as a runaway; lower the motion or "
                f"raise solver.max_speed")
        period = 1.0 / ld.frequency
        if period < MIN_STEPS_PER_PERIOD * dt:
            out.errors.append(
                f"{where(('loading', 'frequency'))}: {ld.frequency:g} Hz has a period of "
                f"{period:.3g} s, shorter than {MIN_STEPS_PER_PERIOD} time steps "
                f"({MIN_STEPS_PER_PERIOD} x {dt:.3g} s): the table motion cannot be resolved "
                f"(highest frequency for this scene: {1.0 / (MIN_STEPS_PER_PERIOD * dt):.4g} Hz)")
    elif isinstance(ld, SteppedShakeLoading):  # each step checked as a shake (dem.loading)
        from dem.loading import stepped_shake_errors, stepped_shake_plausibility

        out.errors += stepped_shake_errors(ld, dt, MIN_STEPS_PER_PERIOD, where)
        w, e = stepped_shake_plausibility(ld, table_plausibility, where)
        out.warnings += w
        out.errors += e
    elif isinstance(ld, (SweepLoading, NoiseLoading)):   # dem.loading.identification_errors
        from dem.loading import identification_errors

        w, e = identification_errors(ld, dt, MIN_STEPS_PER_PERIOD, case.run, scene,
                                     table_plausibility, where)
        out.warnings += w
        out.errors += e
    elif isinstance(ld, RecordLoading):
        try:
            t, acc = ld.samples()
        except ValueError as err:
            out.errors.append(f"{where(('loading',))}: {err}")
        else:
            from dem.loading import Record

            rec = Record(case.gravity_vector(), t, acc)
            w, e = table_plausibility(float(np.linalg.norm(rec.acc, axis=1).max()),
                                      float(np.linalg.norm(rec.disp, axis=1).max()), None,
                                      "", where(("loading",)))
            out.warnings += w
            out.errors += e
            if t[-1] < run.duration:
                v_end = rec.vel[-1]
                v_peak = float(np.linalg.norm(rec.vel, axis=1).max())
                speed_end = float(np.linalg.norm(v_end))
                if speed_end > max(RECORD_REST_FRACTION * v_peak, 1e-12):
                    drift = speed_end * (run.duration - t[-1])
                    out.errors.append(
                        f"{where(('loading',))}: the record ends at {t[-1]:g} s, before "
                        f"run.duration = {run.duration:g} s, with the table still moving at "
                        f"{speed_end:.3g} m/s; with zero acceleration after the end it would "
                        f"drift {drift:.3g} m.  Extend the record to the end of the run, "
                        f"baseline-correct it (final velocity 0), or shorten run.duration")
            h = float(np.diff(t).min())
            if h < dt:
                out.warnings.append(
                    f"{where(('loading',))}: record samples {h:.3g} s apart, closer than the "
                    f"time step {dt:.3g} s: the engine samples the record once per step")

    w, e = shake_cut(ld, run.duration, where)
    out.warnings += w
    out.errors += e

    # output
    if run.output_interval < dt:
        out.errors.append(
            f"{where(('run', 'output_interval'))}: {run.output_interval:.3g} s is shorter than "
            f"the time step {dt:.3g} s: a frame (and a VTK file) every step, "
            f"{int(run.duration / dt):,} frames; give output_interval >= {dt:.3g} s "
            f"(e.g. 0.01 s)")
    elif run.output_interval > run.duration:
        out.warnings.append(
            f"{where(('run', 'output_interval'))}: {run.output_interval:g} s is longer than "
            f"run.duration = {run.duration:g} s: only the first and the last states are written")
    return out


def check_points(cases, source, max_blocks: int | None = None) -> tuple[list[str], list[str]]:
    """(warnings, errors) of every point of a sweep or realisation of an ensemble (``cases``:
    (name, Case) pairs), each checked as ``dem check`` checks a case (:func:`check_case`; points
    that share a scene share its build), before anything runs: each line names the point.  A
    problem of the scene itself (the same for every point) is named once."""
    warnings, errors = [], []
    seen: set[str] = set()
    like = None
    for name, case in cases:
        checked = check_case(case, source, max_blocks=max_blocks, like=like)
        if checked.scene is not None:
            like = checked
        for kind, lines in (("warning", checked.warnings), ("error", checked.errors)):
            for line in lines:
                if line in seen:  # the scene's own: the same text at every point
                    continue
                seen.add(line)
                (warnings if kind == "warning" else errors).append(f"{name}: {line}")
    return warnings, errors
