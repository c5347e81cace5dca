"""Simulation: owns Model / State / Contacts and drives the stepping kernels.

Typical use::

    sim = Simulation(scene, joints, options)             # JointLaw, StepOptions (options.py)
    sim.advance(n_steps, loads)                          # loads(t) -> (gravity [K,3], a_base [K,3])
    sim.state.pos[:sim.n_blocks]

Time is kept as an integer step count (t = step * dt) so that long runs do not accumulate
rounding in t.
"""

from __future__ import annotations

import json
import os
import time
from typing import Callable

import numpy as np

from dem import ti_runtime
from dem.engine import coherence
from dem.engine import step as stepk
from dem.engine.broadphase import candidate_pairs
from dem.engine.containers import (ENERGY_TERMS, NONFINITE, REBUILD, SERIAL_CHUNK, STOP,
                                   Contacts, Control, Model, State)
from dem.engine.launch import CachedLaunch
from dem.engine.options import JointLaw, StepOptions
from dem.engine.errors import CapacityError, InputError, InstabilityError, SimulationError
from dem.engine.timestep import Clock, critical_time_step, face_area_caps, full_face_areas
from dem.scene import Scene

# loads(t [K]) -> (gravity [K,3], base acceleration [K,3]), both in the table frame, m/s^2
LoadFn = Callable[[np.ndarray], tuple[np.ndarray, np.ndarray]]

# auto mode: the parallel kernel from this many bodies on, by the threads Taichi runs (measured,
# benchmarks/RESULTS.md, issue 10, with the cached launch): a parallel step pays ~30-100 us of
# thread-pool dispatch for its two parallel loops, and its loops run slower per CPU-second than
# the serial kernel.  On the 2-core test machine (2 threads) the parallel kernel lost up to 1624
# bricks and won at 3078; on a 16-core machine (4-8 threads) it won from ~300-500.
# solver.mode: serial / parallel forces either.
PARALLEL_MIN_BODIES = {2: 2500, 4: 500}  # threads (at most) -> bodies


def parallel_min_bodies(threads: int) -> int | float:
    """Bodies from which auto mode takes the parallel kernel with ``threads`` threads."""
    if threads <= 1:
        return float("inf")
    return PARALLEL_MIN_BODIES[2] if threads < 4 else PARALLEL_MIN_BODIES[4]


class Simulation:
    def __init__(self, scene: Scene, joints: JointLaw, options: StepOptions,
                 gravity=(0.0, 0.0, -9.81), fast_launch: bool = True):
        ti_runtime.init(threads=options.threads, precision=options.precision)
        self.fast_launch = fast_launch
        self.scene = scene
        self.options = options
        self.n_blocks = scene.n_blocks
        self.gravity0 = np.asarray(gravity, dtype=float)
        self.model = Model.from_scene(scene, joints)
        self.state = State.from_scene(scene, self.model)
        # capacity: max_pairs_per_block counts each pair for both blocks, plus one table pair each
        capacity = int(np.ceil(0.5 * options.max_pairs_per_block * self.model.n_bodies)) + \
            self.model.n_bodies + 8
        self.contacts = Contacts(self.model.n_bodies, capacity)
        movable = ~self.model.fixed_np
        movable[self.model.table] = False
        self._movable = movable
        self.joints = joints
        hmin = float(self.model.half_np[: self.n_blocks].min())
        self.skin = float(options.skin) if options.skin is not None else 0.1 * hmin
        self.step_count = 0
        self._deepest_time = 0.0
        # dt (set below, once the contacts at the start are known), dt_crit, the anchors of t
        # and the area caps: dem.engine.timestep.Clock
        self.clock = Clock()
        self.n_rebuilds = 0
        self.mode = options.mode
        if self.mode == "auto":
            threads = ti_runtime.settings()["threads"] or os.cpu_count() or 1
            self.mode = ("parallel" if self.model.n_bodies >= parallel_min_bodies(threads)
                         else "serial")
        self.control = Control(self.skin, options.max_speed, options.local_damping,
                               options.patch_reuse)
        t0 = time.perf_counter()
        self._warm_up()
        self.compile_seconds = time.perf_counter() - t0
        self.rebuild()
        patch = self.check_initial_overlaps(options.overlap_tolerance)
        # face areas in the critical-step bound, capped for light blocks with large faces; a
        # contact patch larger than its cap lifts the cap and recomputes dt (_check_caps)
        # the stiffest pair of materials in use (one pair: the material's kn, ks, zeta; the
        # hyperbolic law: its tangent at the largest closure the step is made for)
        self._kn_step, self._ks_step, self._zeta_step = self.model.stiffest()
        self._closure_limit = self.model.closure_limit()
        self._face_area, self.area_cap = face_area_caps(
            2 * self.model.half_np, self.model.mass_np, self.model.inertia_np, movable,
            self._kn_step, self._ks_step, options.safety, patch)
        self.dt_changes: list[dict] = []
        self.dt_crit = self._critical_step()
        if options.dt is not None:
            if options.dt > self.dt_crit:
                raise InputError(
                    f"solver.dt = {options.dt:.3g} s is above the critical time step "
                    f"{self.dt_crit:.3g} s of this scene (stiffest block, kn = "
                    f"{self._kn_step:.3g} Pa/m); use solver.dt <= "
                    f"{options.safety * self.dt_crit:.3g} s or leave it out")
            self.dt = float(options.dt)
        else:
            self.dt = float(options.safety * self.dt_crit) if np.isfinite(self.dt_crit) else 1e-4
        self.energy_initial = self.mechanical_energy()

    # ------------------------------------------------------------------------------------
    @property
    def t(self) -> float:
        return self.clock.time(self.step_count)

    # the clock's fields under the names Simulation always had (restart points save them so)
    def _clock_field(name: str, doc: str):  # a helper of the class body, deleted below
        return property(lambda self: getattr(self.clock, name),
                        lambda self, v: setattr(self.clock, name, v), doc=doc)

    dt = _clock_field("dt", "time step in use (s)")
    dt_crit = _clock_field("dt_crit", "critical time step with the present area caps (s)")
    _t_anchor = _clock_field("t_anchor", "time at the last change of dt (s)")
    _step_anchor = _clock_field("step_anchor", "step count at the last change of dt")
    area_cap = _clock_field("area_cap", "per body, the capped contact area (m^2, inf: none)")
    _face_area = _clock_field("face_area", "per body and face, the areas in the bound (m^2)")
    del _clock_field

    def _critical_step(self) -> float:
        m = self.model
        return critical_time_step(2 * m.half_np, m.mass_np, m.inertia_np, self._movable,
                                  self._kn_step, self._ks_step, self._zeta_step, self._face_area)

    def _check_caps(self) -> None:
        """Raise the area cap of any body whose contact patch outgrew it, and shorten dt.

        Caps are never below the smallest cap whose bound is within 0.5 / safety^2 of the
        full-face one (dem.engine.timestep.face_area_caps), so the step in use was still stable;
        the new cap is twice the patch that exceeded the old one (the whole faces, no cap, once
        that reaches the block's largest face)."""
        capped = np.isfinite(self.area_cap)
        c = self.contacts
        n = c.n_pairs
        if not capped.any() or n == 0:
            return
        pairs = c.pairs[:n]
        watch = np.flatnonzero(capped[pairs[:, 0]] | capped[pairs[:, 1]])
        if len(watch) == 0:
            return
        mask = np.arange(c.area.shape[1])[None, :] < c.npts[watch, None]
        area = (c.area[watch] * mask).sum(axis=1)
        limit = np.minimum(self.area_cap[pairs[watch, 0]], self.area_cap[pairs[watch, 1]])
        over = watch[area > limit]
        if len(over) == 0:
            return
        bodies = np.unique(pairs[over].ravel())
        bodies = bodies[capped[bodies]]
        patch = np.zeros(self.model.n_bodies)
        for side in (0, 1):
            np.maximum.at(patch, pairs[over, side], area[np.isin(watch, over)])
        full = full_face_areas(2 * self.model.half_np[bodies])
        new_cap = 2.0 * patch[bodies]
        new_cap = np.where(new_cap >= full.max(axis=(1, 2)), np.inf, new_cap)
        self.area_cap[bodies] = new_cap
        self._face_area[bodies] = np.minimum(full, new_cap[:, None, None])
        old = self.dt
        self.dt_crit = self._critical_step()
        if self.options.dt is not None:
            if self.options.dt > self.dt_crit:
                raise SimulationError(
                    f"at t = {self.t:.4f} s block(s) {bodies.tolist()} made a contact patch "
                    f"larger than assumed: the critical step is now {self.dt_crit:.3g} s, below "
                    f"solver.dt = {self.options.dt:.3g} s; leave solver.dt out (automatic) or "
                    f"lower it")
            return
        new = float(self.options.safety * self.dt_crit)
        if new < old:
            self.clock.anchor(self.t, self.step_count)
            self.dt = new
            self.dt_changes.append({"t": self._t_anchor, "step": self.step_count, "old_dt": old,
                                    "new_dt": new, "blocks": bodies.tolist(),
                                    "new_area_cap_m2": [float(x) for x in new_cap]})

    def _check_closure(self) -> None:
        """The hyperbolic law: stop when a joint closed beyond the closure the step is made for
        (d_lim = closure_limit x d_max; dem.engine.laws: past it the law is linearised, stable
        but no longer the hyperbolic law)."""
        deepest = float(self.control.deepest[0])
        if deepest > self._closure_limit:
            raise SimulationError(
                f"a joint closed by {deepest:.4g} m by t = {self.t:.5f} s, beyond "
                f"{self._closure_limit:.4g} m (material.closure_limit x max_closure), the "
                f"largest closure the time step is made for: the hyperbolic law's tangent "
                f"stiffness grows without bound as the closure nears max_closure; raise "
                f"material.closure_limit (a shorter step) or check max_closure and the loads")

    def rebuild(self) -> None:
        """Broad phase: new neighbour list, history carried over for pairs that stay."""
        st = self.state
        pos = st.pos
        quat = st.quat
        rot = st.rot
        m = self.model
        pairs = candidate_pairs(pos, rot, m.half_np, m.radius_np, m.fixed_np, m.table, self.skin)
        c = self.contacts
        if len(pairs) > c.capacity:
            counts = np.bincount(pairs.ravel(), minlength=m.n_bodies)[: self.n_blocks]
            worst = int(np.argmax(counts))
            raise CapacityError(
                f"neighbour list overflow at step {self.step_count} (t = {self.t:.4f} s): "
                f"{len(pairs)} candidate pairs > capacity {c.capacity} (block {worst} has "
                f"{counts[worst]} neighbours); raise solver.max_pairs_per_block "
                f"(now {self.options.max_pairs_per_block}) or lower solver.skin ({self.skin:.3g} m)")
        old_pairs = c.pairs[: c.n_pairs].copy() if c.n_pairs else None
        history = c.read_history() if c.n_pairs else None
        c.write_pairs(pairs, m.n_bodies, history, old_pairs)
        c.ref_pos[...] = pos
        c.ref_quat[...] = quat
        self.n_rebuilds += 1

    def check_initial_overlaps(self, tolerance: float) -> np.ndarray:
        """Raise if two bodies overlap by more than ``tolerance`` at the start; returns each
        body's largest contact patch area (m^2) at the start."""
        c = self.contacts
        patch = np.zeros(self.model.n_bodies)
        if c.n_pairs == 0:
            return patch
        depth = ti_nd_real(c.capacity)
        area = ti_nd_real(c.capacity)
        stepk.probe_contacts(c.n_pairs, depth, area, self.model.args, self.state.args, c.args,
                             self._warped)
        d = depth[: c.n_pairs]
        worst = int(np.argmax(d))
        if d[worst] > tolerance:
            i, j = c.pairs[worst]
            name = lambda b: "the table" if b == self.model.table else f"block {b}"  # noqa: E731
            raise InputError(
                f"{name(i)} and {name(j)} overlap by {d[worst] * 1e3:.3f} mm at the start "
                f"(tolerance solver.overlap_tolerance = {tolerance * 1e3:.3f} mm); "
                f"{int((d > tolerance).sum())} pair(s) overlap in all")
        pairs = c.pairs[: c.n_pairs]
        for side in (0, 1):
            np.maximum.at(patch, pairs[:, side], area[: c.n_pairs])
        return patch

    # ------------------------------------------------------------------------------------
    def advance(self, n_steps: int, loads: LoadFn, on_chunk: Callable[[int], None] | None = None
                ) -> None:
        """Advance n_steps steps.  Raises InstabilityError / CapacityError on failure (the state
        is then that of the failing step)."""
        done_total = 0
        while done_total < n_steps:
            k = min(n_steps - done_total, SERIAL_CHUNK if self.mode == "serial" else 1)
            done = self._launch(k, loads)
            done_total += done
            status = int(self.control.status[0])
            if status & STOP:
                self._raise_instability()
            if status & REBUILD:
                self.rebuild()
            if self._closure_limit is not None:
                self._check_closure()
            self._check_caps()
            if on_chunk is not None:
                on_chunk(done)

    def _launch(self, k: int, loads: LoadFn) -> int:
        # step n's time counted from the last change of dt, as self.t: the same loads for a
        # step however the run is cut into launches (frames, the parallel kernel)
        t = self.clock.times(self.step_count, k)
        g, a = loads(t)
        ctl = self.control
        ctl.loads[:k, 0] = g
        ctl.loads[:k, 1] = a
        ctl.status[0] = 0
        ctl.bad_body[0] = 0
        ctl.deepest_step[0] = -1
        if self._warped and self._overlap_wanted() != self._overlap:
            self._choose_launch()  # coherence.set_overlap_reuse switched the overlap reuse
        if self.mode == "serial":
            self._advance(k, self.contacts.n_pairs, self.dt)
            done = int(ctl.steps_done[0])
        else:
            self._advance(self.contacts.n_pairs, self.dt)
            done = 1
        if ctl.deepest_step[0] >= 0:  # the time of that step's start, as self.t counts it
            steps = self.step_count + int(ctl.deepest_step[0]) - self._step_anchor
            self._deepest_time = self._t_anchor + steps * self.dt
        self.step_count += done
        return done

    def unbalanced_force_ratio(self, gravity, base_accel=(0.0, 0.0, 0.0)) -> float:
        """Mean unbalanced-force ratio (the static-convergence measure of 3DEC / UDEC / PFC):
        sum over movable blocks of |F_i| + |T_i| / r_i over the sum of their weights m_i |g|,
        where F_i, T_i are the net force and torque of the last step's contact wrenches plus
        m_i (gravity - base_accel) (m/s^2, table frame), before any local damping, r_i the
        bounding radius.  Zero in static equilibrium; -.  Computed on the host from
        Contacts.wrench, so the kernels are untouched."""
        m, c = self.model, self.contacts
        n = c.n_pairs
        F = np.zeros((m.n_bodies, 3))
        T = np.zeros((m.n_bodies, 3))
        if n:
            pairs, w = c.pairs[:n], c.wrench[:n]
            np.add.at(F, pairs[:, 0], w[:, 0])
            np.add.at(F, pairs[:, 1], -w[:, 0])
            np.add.at(T, pairs[:, 0], w[:, 1])
            np.add.at(T, pairs[:, 1], w[:, 2])
        g = np.asarray(gravity, dtype=float) - np.asarray(base_accel, dtype=float)
        mov = self._movable
        F = F[mov] + m.mass_np[mov, None] * g
        num = (np.linalg.norm(F, axis=1) + np.linalg.norm(T[mov], axis=1)
               / m.radius_np[mov]).sum()
        den = (m.mass_np[mov] * np.linalg.norm(gravity)).sum()
        return float(num / den) if den > 0 else 0.0

    def restart_clock(self) -> float:
        """Start the clock again at t = 0 from the present state (the loading clock after a
        settling phase); returns the time that had passed (s).  Steps and energy sums go on."""
        elapsed = self.t
        self.clock.anchor(0.0, self.step_count)
        return elapsed

    def set_local_damping(self, alpha: float) -> None:
        """Cundall local damping coefficient from the next step on (0: none)."""
        self.control.local_damping[0] = alpha

    def save_point(self) -> dict:
        """Copies of everything that evolves: State, Contacts (neighbour list, shear history),
        the energy sums.  :meth:`restore_point` puts them back in place (the arrays the kernels
        hold do not move); time and step count go on."""
        return {"state": {k: a.copy() for k, a in self.state.arrays().items()},
                "contacts": {k: a.copy() for k, a in self.contacts.arrays().items()},
                "n_pairs": self.contacts.n_pairs,
                "energy": {k: getattr(self.control, k).copy() for k in ENERGY_TERMS}}

    def restore_point(self, point: dict) -> None:
        for k, a in point["state"].items():
            getattr(self.state, k)[...] = a
        for k, a in point["contacts"].items():
            getattr(self.contacts, k)[...] = a
        self.contacts.n_pairs = point["n_pairs"]
        for k, a in point["energy"].items():
            getattr(self.control, k)[...] = a

    # what evolves on the host beside the containers' arrays: the clock, the time step and the
    # area caps behind it, counters, the energy at t = 0 (saved by snapshot)
    EVOLVING = ("step_count", "_t_anchor", "_step_anchor", "dt", "dt_crit", "n_rebuilds",
                "_deepest_time", "energy_initial", "area_cap", "_face_area")

    def snapshot(self) -> dict[str, np.ndarray]:
        """Everything that evolves, as named arrays (an npz file's content): every array of
        State, Contacts and Control, the pair count, :attr:`EVOLVING`, ``dt_changes`` and the
        kernel in use.  :meth:`restore` on a Simulation built from the same scene and options
        goes on bit for bit as this one would (tests/test_resume.py).  The Model is static,
        rebuilt from the scene, never saved."""
        out = {f"{name}.{k}": a.copy() for name, box in self._boxes()
               for k, a in box.arrays().items()}
        out["contacts.n_pairs"] = np.array(self.contacts.n_pairs)
        out.update({f"sim.{k}": np.array(getattr(self, k)) for k in self.EVOLVING})
        out["sim.dt_changes"] = np.array(json.dumps(self.dt_changes))
        out["sim.mode"] = np.array(self.mode)
        return out

    def restore(self, snap) -> None:
        """Put a :meth:`snapshot` back (the arrays in place: the cached launches hold them).
        Raises ValueError, naming the entry, where it does not fit this simulation (another
        kernel, precision, scene size or pair capacity); nothing is changed then."""
        if str(snap["sim.mode"]) != self.mode:
            raise ValueError(f"the snapshot was taken with the {snap['sim.mode']} kernel, this "
                             f"simulation runs the {self.mode} one")
        for name, box in self._boxes():
            for k, a in box.arrays().items():
                key = f"{name}.{k}"
                if key not in snap:
                    raise ValueError(f"the snapshot has no {key}")
                b = snap[key]
                if b.shape != a.shape or b.dtype != a.dtype:
                    raise ValueError(f"{key}: {b.dtype} {b.shape} in the snapshot, {a.dtype} "
                                     f"{a.shape} in this simulation")
        for name, box in self._boxes():
            for k, a in box.arrays().items():
                a[...] = snap[f"{name}.{k}"]
        self.contacts.n_pairs = int(snap["contacts.n_pairs"])
        for k in self.EVOLVING:
            v = np.asarray(snap[f"sim.{k}"])
            setattr(self, k, v.copy() if v.ndim else v.item())
        self.dt_changes = json.loads(str(snap["sim.dt_changes"]))

    def _boxes(self) -> tuple:
        return (("state", self.state), ("contacts", self.contacts), ("control", self.control))

    def deepest_penetration(self) -> tuple[float, float]:
        """(depth in m, time in s) of the deepest penetration of any contact point at any step
        since t = 0 (kept by the kernel every step: dem.engine.step.deepest_stage)."""
        return float(self.control.deepest[0]), self._deepest_time

    def containers(self) -> tuple:
        """The argpacks of (Model, State, Contacts, Control), as the kernels take them."""
        return (self.model.args, self.state.args, self.contacts.args, self.control.args)

    def _warm_up(self) -> None:
        """Compile every kernel (or load it from Taichi's offline cache) with zero work, and
        record the stepping kernel's launch (dem.engine.launch: later launches skip Taichi's
        per-call argument handling unless ``fast_launch`` is False)."""
        # the kernels' compile-time variants (dem.engine.step): the imperfect faces' code only
        # for scenes that have some, each pair's normal law only for scenes with a hyperbolic
        # pair; a perfect, linear scene runs the perfect model's code (bit for bit, at its speed)
        self._warped = bool(self.model.imperfect.any())
        self._hyperbolic = self.model.closure_limit() is not None
        self._choose_launch()
        m, st, c = self.model.args, self.state.args, self.contacts.args
        depth = ti_nd_real(1)
        stepk.probe_contacts(0, depth, depth, m, st, c, self._warped)
        stepk.elastic_energy(0, m, c, self._hyperbolic)

    def _overlap_wanted(self) -> bool:
        """Whether the overlap reuse variant should run: a warped scene whose overlap reuse
        tolerance (coherence.set_overlap_reuse, read from the contacts) is > 0."""
        return self._warped and coherence.overlap_reuse_tolerance(self.contacts) > 0.0

    def _choose_launch(self) -> None:
        """Record the stepping kernel's launch for the compile-time variants (warped,
        hyperbolic, overlap; dem.engine.step.advance_serial).  ``overlap`` follows
        coherence.set_overlap_reuse, which may be called after construction: _launch checks it
        before each launch of a warped scene and records a new launch when it changed."""
        self._overlap = self._overlap_wanted()
        variants = (self._warped, self._hyperbolic, self._overlap)
        if self.mode == "serial":
            kernel, scalars = stepk.advance_serial, (0, 0, float(self.dt))
        else:
            kernel, scalars = stepk.advance_parallel, (0, float(self.dt))
        if self.fast_launch:
            self._advance = CachedLaunch(kernel, scalars, *self.containers(), *variants)
        else:
            kernel(*scalars, *self.containers(), *variants)
            self._advance = lambda *sc: kernel(*sc, *self.containers(), *variants)

    def _raise_instability(self) -> None:
        b = int(self.control.bad_body[0])
        st = self.state
        v = st.vel[b]
        x = st.pos[b]
        what = "became NaN/inf" if self.control.status[0] & NONFINITE else (
            f"moves faster than solver.max_speed = {self.options.max_speed} m/s")
        raise InstabilityError(
            f"block {b} {what} at step {self.step_count} (t = {self.t:.5f} s): position "
            f"{np.array2string(x, precision=4)} m, velocity {np.array2string(v, precision=3)} m/s;"
            f" dt = {self.dt:.3g} s (critical {self.dt_crit:.3g} s)", self.step_count, b)

    # ------------------------------------------------------------------------------------
    def kinetic_energy(self) -> float:
        st, m = self.state, self.model
        v = st.vel
        w = st.omega
        L = st.angmom
        movable = ~m.fixed_np
        return float(0.5 * (m.mass_np[movable] * (v[movable] ** 2).sum(1)).sum()
                     + 0.5 * (w[movable] * L[movable]).sum())

    def elastic_energy(self) -> float:
        c, m = self.contacts, self.model
        if c.n_pairs == 0:
            return 0.0
        return float(stepk.elastic_energy(c.n_pairs, m.args, c.args, self._hyperbolic))

    def mechanical_energy(self) -> float:
        return self.kinetic_energy() + self.elastic_energy()

    def energy_report(self) -> dict[str, float]:
        """Energy balance since t = 0 (J).

        kinetic + elastic - initial = work_gravity + work_base - dissipation + residual, where
        ``residual`` is what the explicit scheme created (> 0) or lost beyond the modelled
        dissipation (< 0); ``gain`` = kinetic + elastic - initial - work supplied is the energy
        beyond what the loads supplied (> 0: the scheme created energy).
        """
        e = self.control.energy()
        kin = self.kinetic_energy()
        el = self.elastic_energy()
        diss = sum(v for name, v in e.items() if name.startswith("dissipated_"))
        supplied = e["work_gravity"] + e["work_base"]
        residual = kin + el - self.energy_initial - supplied + diss
        return {
            "kinetic": kin,
            "elastic": el,
            "initial": self.energy_initial,
            **e,
            "residual": float(residual),
            "gain": float(kin + el - self.energy_initial - supplied),
        }


def ti_nd_real(n):
    return np.zeros(n, dtype=ti_runtime.real_dtype())

