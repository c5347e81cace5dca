"""Engine: owns Model / State / Contacts / Control of one or several scenes and drives the
stepping kernels; Simulation: one scene of an engine, the object the run loop drives.

Typical use::

    sim = Simulation(scene, joints, options)             # JointLaw, StepOptions (options.py)
    sim.advance(n_steps, loads)                          # loads(t) -> (gravity [K,3], a_base [K,3])
    sim.state.pos[:sim.n_blocks]

Several scenes in one engine (the realisations of an ensemble, the points of a sweep side by
side, one kernel launch for all: fewer processes, and a GPU's width to fill)::

    engine = Engine([scene_a, scene_b], [joints_a, joints_b], options)
    sim_a, sim_b = engine.simulations                    # each behaves as a lone Simulation
    engine.advance(n_steps, [loads_a, loads_b])          # every active scene, n_steps each

The scenes share the time step (the smallest of their critical steps) and the kernel; each keeps
its own clock, loads, energy sums, deepest penetration, status and neighbour list (the containers
of scene g are slices of the engine's: dem.engine.containers), so that a scene of an engine
gives the trajectory of the same scene alone, to round-off (tests/test_engine_batch.py).  A scene
whose step fails is frozen (its failure kept in ``sim.failure``); the others go on.

Time is kept as an integer step count (t = step * dt) so that long runs do not accumulate
rounding in t.
"""

from __future__ import annotations

import json
import os
import time
from typing import Callable

import numpy as np
import taichi as ti

from dem import ti_runtime
from dem.engine import coherence
from dem.engine import step as stepk
from dem.engine.broadphase import candidate_pairs
from dem.engine.containers import (NONFINITE, PROBE_SLOTS, PROBES_PER_SCENE, REBUILD,
                                   SERIAL_CHUNK, STOP, Contacts, Control, Model, State,
                                   pair_lists)
from dem.engine.launch import CachedLaunch
from dem.engine.options import JointLaw, StepOptions
from dem.engine.errors import CapacityError, InputError, InstabilityError, SimulationError
from dem.engine.timestep import Clock, critical_time_step, face_area_caps, full_face_areas
from dem.scene import Scene

# loads(t [K]) -> (gravity [K,3], base acceleration [K,3]), both in the table frame, m/s^2
LoadFn = Callable[[np.ndarray], tuple[np.ndarray, np.ndarray]]

# auto mode: the parallel kernel from this many bodies on, by the threads Taichi runs (measured,
# benchmarks/RESULTS.md "Thread scaling by scene size", with the cached launch): a parallel step pays ~30-100 us of
# thread-pool dispatch for its two parallel loops, and its loops run slower per CPU-second than
# the serial kernel.  On the 2-core test machine (2 threads) the parallel kernel lost up to 1624
# bricks and won at 3078; on a 16-core machine (4-8 threads) it won from ~300-500.
# solver.mode: serial / parallel forces either.
PARALLEL_MIN_BODIES = {2: 2500, 4: 500}  # threads (at most) -> bodies

# an engine on a device: steps per chunk of launches (the loads of a chunk are copied to the
# device before it; the host reads the status back after it)
DEVICE_CHUNK = 256

# an engine on a device: probed steps of a scene per chunk (its probe_buf, Q x G x 16 x 13
# reals, is copied back whole after a chunk with a probe: 4 slots hold the samples of a chunk
# of DEVICE_CHUNK steps down to 64 steps apart; more shorten the chunk)
DEVICE_PROBE_SLOTS = 4

# an engine on a device: a patch is counted as possibly over its area cap from (1 - this) x the
# cap (Engine._patches_over_caps); the device's and the host's sums of a patch's <= 9 point
# areas differ by ~1e-15 relative, so 1e-9 never hides a patch the host would find over
CAP_CHECK_MARGIN = 1e-9


def parallel_min_bodies(threads: int) -> int | float:
    """Bodies from which auto mode takes the parallel kernel with ``threads`` threads."""
    if threads <= 1:
        return float("inf")
    return PARALLEL_MIN_BODIES[2] if threads < 4 else PARALLEL_MIN_BODIES[4]


class Engine:
    """The containers of ``len(scenes)`` scenes side by side and the kernels that step them.

    scenes   : the scenes (dem.scene.Scene), in order; scene g's bodies are rows
               model.scene_bodies[g] of every body array
    joints   : one JointLaw per scene (or one for all)
    options  : the StepOptions of every scene (one time step, one kernel, one skin)
    gravity  : per scene, the gravity at rest (m/s^2, table frame), or one 3-vector for all
    device_arrays : keep the arrays on the device (dem.engine.device); None: where Taichi runs
               on a GPU (dem.ti_runtime.init(arch="cuda")); True on the CPU runs the device
               path in host memory (its tests)
    """

    def __init__(self, scenes: list[Scene], joints, options: StepOptions, gravity=None,
                 fast_launch: bool = True, lone: "Simulation | None" = None,
                 device_arrays: bool | None = None):
        # Taichi is started by the process's entry point (dem.run.build, dem.batch,
        # dem.run.batched: arch, threads, precision); for a library user who did not, this
        # starts it with the options' settings, and otherwise checks that they agree
        ti_runtime.init(threads=options.threads, precision=options.precision)
        # on a GPU always (numpy arguments would be copied at every launch, and a reused launch
        # context of copied arrays crashed Taichi 1.7.4); on the CPU where asked (its tests)
        self.on_device = (ti_runtime.settings()["arch"] == "cuda" or bool(device_arrays))
        scenes = list(scenes)
        G = len(scenes)
        if G == 0:
            raise InputError("an engine needs at least one scene")
        joints = list(joints) if isinstance(joints, (list, tuple)) else [joints] * G
        gravity = np.broadcast_to(np.asarray((0.0, 0.0, -9.81) if gravity is None else gravity,
                                             dtype=float), (G, 3))
        self.n_scenes = G
        self.batched = G > 1
        self.options = options
        self.fast_launch = fast_launch
        self.hub = None  # with several scenes: what Simulation.advance calls (dem.run.batched)
        self._cap_dev = None  # on a device: the area caps, for _patches_over_caps
        self.n_chunks = 0  # chunks launched (_launch: one launch, or k of the parallel kernel)
        self._installs = {"calls": 0, "bytes": 0}  # install_pairs' host arrays (a device)
        models = [Model.from_scene(sc, j) for sc, j in zip(scenes, joints)]
        self.model = Model.concat(models)
        states = [State.from_scene(sc, m) for sc, m in zip(scenes, models)]
        if G == 1:
            self.state = states[0]
        else:
            self.state = State(self.model.n_bodies)
            for g, st in enumerate(states):
                b0, b1 = self.model.scene_bodies[g]
                for k, a in st.arrays().items():
                    getattr(self.state, k)[b0:b1] = a
        # capacity of one scene: max_pairs_per_block counts each pair for both blocks, plus one
        # table pair each (the largest scene's, for every scene)
        capacity = max(int(np.ceil(0.5 * options.max_pairs_per_block * m.n_bodies))
                       + m.n_bodies + 8 for m in models)
        self.contacts = Contacts(self.model.n_bodies, capacity, G)
        self._movable = ~self.model.fixed_np
        hmin = min(float(m.half_np[: m.n_blocks].min()) for m in models)
        self.skin = float(options.skin) if options.skin is not None else 0.1 * hmin
        self.mode = options.mode
        if self.on_device:  # the serial kernel would run on one GPU thread
            self.mode = "parallel"
        elif self.mode == "auto":
            threads = ti_runtime.settings()["threads"] or os.cpu_count() or 1
            self.mode = ("parallel" if self.model.n_bodies >= parallel_min_bodies(threads)
                         else "serial")
        self.control = Control(self.skin, options.max_speed, options.local_damping,
                               options.patch_reuse, G,
                               DEVICE_CHUNK if self.on_device else SERIAL_CHUNK,
                               DEVICE_PROBE_SLOTS if self.on_device else PROBE_SLOTS)
        # dt, dt_crit and the area caps of every body (each scene's clock keeps its anchors)
        self.clock = Clock()
        self.dt_changes: list[dict] = []
        sims = []
        for g in range(G):
            sim = lone if (lone is not None and G == 1) else Simulation.__new__(Simulation)
            sim._bind(self, g, scenes[g], models[g], joints[g], gravity[g])
            sims.append(sim)
        self.simulations = sims
        self._device_init()
        t0 = time.perf_counter()
        self._warm_up()
        self.compile_seconds = time.perf_counter() - t0
        patch = np.zeros(self.model.n_bodies)
        for g, sim in enumerate(sims):
            try:
                sim.rebuild()
                b0, b1 = self.model.scene_bodies[g]
                patch[b0:b1] = sim.check_initial_overlaps(options.overlap_tolerance)
            except (InputError, CapacityError) as err:
                self._fail(g, err)
        # face areas in the critical-step bound, capped for light blocks with large faces; a
        # contact patch larger than its cap lifts the cap and recomputes dt (_check_caps)
        # the stiffest pair of materials in use (one pair: the material's kn, ks, zeta; the
        # hyperbolic law: its tangent at the largest closure the step is made for)
        stiff = [m.stiffest() for m in models]
        self._kn_step, self._ks_step, self._zeta_step = (max(x[k] for x in stiff)
                                                         for k in range(3))
        # the largest damping time of a stiffness-proportional dashpot (s; 0: none)
        self._beta_step = max(m.largest_beta() for m in models)
        # per scene, the closure its hyperbolic pairs may reach before the run stops (None:
        # linear, or a capped law that goes on along its tangent: JointLaw.beyond_closure_limit);
        # the step is made for the stiffest tangent of them all, so each scene's own limit holds
        # in the batch
        self._closure_limits = [
            None if getattr(j, "beyond_closure_limit", "stop") == "tangent" else m.closure_limit()
            for m, j in zip(models, joints)]
        self.clock.face_area, self.clock.area_cap = face_area_caps(
            2 * self.model.half_np, self.model.mass_np, self.model.inertia_np, self._movable,
            self._kn_step, self._ks_step, options.safety, patch)
        self.clock.dt_crit = self._critical_step()
        if options.dt is not None:
            if options.dt > self.clock.dt_crit:
                raise InputError(
                    f"solver.dt = {options.dt:.3g} s is above the critical time step "
                    f"{self.clock.dt_crit:.3g} s of this scene (stiffest block, kn = "
                    f"{self._kn_step:.3g} Pa/m); use solver.dt <= "
                    f"{options.safety * self.clock.dt_crit:.3g} s or leave it out")
            self.clock.dt = float(options.dt)
        else:
            self.clock.dt = (float(options.safety * self.clock.dt_crit)
                             if np.isfinite(self.clock.dt_crit) else 1e-4)
        for sim in sims:
            if G > 1:
                sim.clock.dt = self.clock.dt
            sim.energy_initial = sim.mechanical_energy()

    # ------------------------------------------------------------------------------------
    @property
    def dt(self) -> float:
        return self.clock.dt

    def active(self, g: int) -> bool:
        return bool(self.control.active[g])

    def deactivate(self, g: int) -> None:
        """Freeze scene g (its run finished or failed): its bodies and pairs are skipped."""
        self.control.active[g] = 0

    def _fail(self, g: int, err: Exception) -> None:
        """Scene g failed: a lone scene raises, a scene among others is frozen and keeps it."""
        if not self.batched:
            raise err
        self.simulations[g].failure = err
        self.deactivate(g)

    def _critical_step(self) -> float:
        m = self.model
        return critical_time_step(2 * m.half_np, m.mass_np, m.inertia_np, self._movable,
                                  self._kn_step, self._ks_step, self._zeta_step,
                                  self.clock.face_area, beta=self._beta_step)

    def _set_dt(self, new: float, why: dict | None = None) -> None:
        """Change the time step of every scene: each clock is re-anchored at its present step
        (its t does not move)."""
        old = self.clock.dt
        for sim in self.simulations:
            sim.clock.anchor(sim.t, sim.step_count)
            sim.clock.dt = new
        self.clock.dt = new
        if why is not None:
            self.dt_changes.append({**why, "old_dt": old, "new_dt": new})

    def adopt_dt(self, dt: float) -> None:
        """A scene restored from a restart point taken with ``dt``: the engine takes the smaller
        of the two steps (several scenes share one)."""
        if dt < self.clock.dt:
            self._set_dt(float(dt))

    def _check_caps(self) -> None:
        """Raise the area cap of any body whose contact patch outgrew it, and shorten dt.

        Caps are never below the smallest cap whose bound is within 0.5 / safety^2 of the
        full-face one (dem.engine.timestep.face_area_caps), so the step in use was still stable;
        the new cap is twice the patch that exceeded the old one (the whole faces, no cap, once
        that reaches the block's largest face)."""
        area_cap = self.clock.area_cap
        capped = np.isfinite(area_cap)
        if not capped.any():
            return
        if self.on_device and not self._patches_over_caps():
            return  # no patch near its cap: the areas need not come to the host
        self.host("contacts", write=False, fields=("area", "npts"))  # the patches' areas
        patch = np.zeros(self.model.n_bodies)
        over_any = False
        for g, sim in enumerate(self.simulations):
            c = sim._contacts
            n = c.n_pairs
            if n == 0 or not self.control.active[g]:
                continue
            b0 = int(self.model.scene_bodies[g][0])
            pairs = c.pairs[:n] + b0
            watch = np.flatnonzero(capped[pairs[:, 0]] | capped[pairs[:, 1]])
            if len(watch) == 0:
                continue
            mask = np.arange(c.area.shape[1])[None, :] < c.npts[watch, None]
            area = (c.area[watch] * mask).sum(axis=1)
            limit = np.minimum(area_cap[pairs[watch, 0]], area_cap[pairs[watch, 1]])
            over = area > limit
            if not over.any():
                continue
            over_any = True
            for side in (0, 1):
                np.maximum.at(patch, pairs[watch[over], side], area[over])
        if not over_any:
            return
        bodies = np.flatnonzero((patch > 0) & capped)
        full = full_face_areas(2 * self.model.half_np[bodies])
        new_cap = 2.0 * patch[bodies]
        new_cap = np.where(new_cap >= full.max(axis=(1, 2)), np.inf, new_cap)
        area_cap[bodies] = new_cap
        self.clock.face_area[bodies] = np.minimum(full, new_cap[:, None, None])
        old = self.clock.dt
        self.clock.dt_crit = self._critical_step()
        first = self.simulations[0]
        if self.options.dt is not None:
            if self.options.dt > self.clock.dt_crit:
                raise SimulationError(
                    f"at t = {first.t:.4f} s block(s) {bodies.tolist()} made a contact patch "
                    f"larger than assumed: the critical step is now {self.clock.dt_crit:.3g} s, "
                    f"below solver.dt = {self.options.dt:.3g} s; leave solver.dt out (automatic) "
                    f"or lower it")
            return
        new = float(self.options.safety * self.clock.dt_crit)
        if new < old:
            self._set_dt(new, {"t": first.t, "step": first.step_count,
                               "blocks": bodies.tolist(),
                               "new_area_cap_m2": [float(x) for x in new_cap]})

    # ------------------------------------------------------------------------------------
    def advance(self, n_steps: int, loads: list, on_chunk: Callable[[int], None] | None = None
                ) -> None:
        """Advance every active scene by n_steps steps, scene g with ``loads[g]`` (a LoadFn;
        ignored for a frozen scene).  A lone scene's failure raises (InstabilityError,
        CapacityError, SimulationError; the state is then that of the failing step); a scene
        among others is frozen with its failure in ``simulations[g].failure``."""
        done_total = 0
        while done_total < n_steps and self.control.active.any():
            k = min(n_steps - done_total, self.control.loads.shape[0])
            done = self._launch(k, loads)
            done_total += done
            status = self.control.status.copy()
            for g in np.flatnonzero(status & STOP):
                self._fail(g, self.simulations[g]._instability())
            for g in np.flatnonzero(status & REBUILD):
                if self.control.active[g]:
                    try:
                        self.simulations[g].rebuild()
                    except CapacityError as err:
                        self._fail(g, err)
            if self._hyperbolic:  # each scene against its own law's limit
                for g in np.flatnonzero(self.control.active):
                    limit = self._closure_limits[g]
                    err = None if limit is None else \
                        self.simulations[g]._closure_error(limit)
                    if err is not None:
                        self._fail(g, err)
            self._check_caps()
            if on_chunk is not None:
                on_chunk(done)

    def _patches_over_caps(self) -> bool:
        """On a device: whether any live pair's patch may exceed its bodies' area cap, counted
        on the device (dem.engine.device.patches_over_caps) so that the patches' areas of every
        scene (most of the bytes a chunk end brings back) are copied only when one may.  The
        margin (CAP_CHECK_MARGIN) is far above the round-off between the device's sum of a
        patch's point areas and the host's: where it says no, _check_caps would find none."""
        from dem.engine.device import patches_over_caps

        if self._cap_dev is None:
            real = ti.f32 if ti_runtime.real_dtype() == np.float32 else ti.f64
            self._cap_dev = ti.ndarray(real, shape=(self.model.n_bodies,))
        self._cap_dev.from_numpy(np.ascontiguousarray(self.clock.area_cap,
                                                      dtype=ti_runtime.real_dtype()))
        m, _, c, ctl = self.containers()
        return patches_over_caps(self.n_pair_slots(), self._cap_dev, 1.0 - CAP_CHECK_MARGIN, m, c,
                                 ctl, self.batched) > 0

    def n_pair_slots(self) -> int:
        """The pair slots the kernels loop over: a lone scene's pairs, else up to the last
        slot in use."""
        sp = self.contacts.scene_pairs
        if not self.batched:
            return int(sp[0])
        P = self.contacts.capacity
        used = [g * P + int(n) for g, n in enumerate(sp) if n > 0]
        return max(used, default=0)

    def _launch(self, k: int, loads: list) -> int:
        # step n's time counted from the last change of dt, as sim.t: the same loads for a
        # step however the run is cut into launches (frames, the parallel kernel)
        ctl = self.control
        for g, sim in enumerate(self.simulations):
            if not ctl.active[g]:
                continue
            grav, a = loads[g](sim.clock.times(sim.step_count, k))
            ctl.loads[:k, g, 0] = grav
            ctl.loads[:k, g, 1] = a
        k, probes = self._plan_probes(k)
        ctl.status[...] = 0
        ctl.bad_body[...] = 0
        ctl.deepest_step[...] = -1
        ctl.steps_done[...] = 0
        if self._warped and self._overlap_wanted() != self._overlap:
            self._choose_launch()  # coherence.set_overlap_reuse switched the overlap reuse
        n_slots = self.n_pair_slots()
        self.n_chunks += 1
        self._to_device()
        if self.mode == "serial":
            self._advance(k, n_slots, self.dt)
        else:
            for s in range(k):  # no read-back between steps: a stopped chunk's launches idle
                self._advance(s, n_slots, self.dt)
        self._from_device()
        done = int(ctl.steps_done[0])
        if probes:
            self._take_probes(probes, done)
        for g, sim in enumerate(self.simulations):
            if not ctl.active[g]:
                continue
            if ctl.deepest_step[g] >= 0:  # the time of that step's start, as sim.t counts it
                steps = sim.step_count + int(ctl.deepest_step[g]) - sim.clock.step_anchor
                sim._deepest_time = sim.clock.t_anchor + steps * self.dt
            sim.step_count += done
        return done

    def _plan_probes(self, k: int) -> tuple[int, dict]:
        """Before a launch of k steps: each active scene's probed steps among them
        (Simulation.set_probe: ``probe.plan``) into control.probe_slot, the i-th of a scene in
        slot i, at most Q (probe_buf's slots) a scene: the launch is shortened to the step of
        the last one that fits.  Returns (k, {g: [s, ...]}), s the steps of the launch (0 = its
        first) after which scene g's probed bodies are copied, ascending (slot = index)."""
        ctl = self.control
        ctl.probe_slot[:k] = -1
        slots = ctl.probe_buf.shape[0]
        planned = {}
        for g, sim in enumerate(self.simulations):
            if sim.probe is None or not ctl.active[g]:
                continue
            steps = [c - sim.step_count - 1 for c in
                     sim.probe.plan(sim.clock, sim.step_count, k)]
            if len(steps) > slots:
                k = steps[slots - 1] + 1
            planned[g] = steps
        planned = {g: [s for s in steps if s < k] for g, steps in planned.items()}
        planned = {g: steps for g, steps in planned.items() if steps}
        for g, steps in planned.items():
            ctl.probe_slot[steps, g] = np.arange(len(steps))
        return k, planned

    def _take_probes(self, probes: dict, done: int) -> None:
        """After a launch that did ``done`` steps: each probed step it reached, handed to its
        scene's ``probe.take(step, t, rows)`` in order (rows: [bodies, 13] pos, quat, vel, omega
        of the probed bodies, as Simulation.set_probe listed them).  A scene that failed in the
        launch gets none of its last step (the failing one: its state is not a result)."""
        if self.on_device:
            self._dev["control"].pull(["probe_buf"])
        buf = self.control.probe_buf
        status = self.control.status
        for g, steps in probes.items():
            sim = self.simulations[g]
            reached = done - 1 if status[g] & STOP else done
            n = len(sim.probe.bodies)
            for slot, s in enumerate(steps):
                if s < reached:
                    step = sim.step_count + s + 1
                    sim.probe.take(step, sim.clock.time(step), buf[slot, g, :n].copy())

    # ------------------------------------------------------------------------------------
    def containers(self) -> tuple:
        """The argpacks of (Model, State, Contacts, Control), as the kernels take them (the
        device's arrays for an engine on a device)."""
        if self.on_device:
            d = self._dev
            return (d["model"].args, d["state"].args, d["contacts"].args, d["control"].args)
        return (self.model.args, self.state.args, self.contacts.args, self.control.args)

    # -- an engine on a device (dem.engine.device) ------------------------------------------
    def _device_init(self) -> None:
        """Device arrays of every container, filled from the host's."""
        if not self.on_device:
            return
        from dem.engine.device import DeviceArrays, HistoryScratch

        self._dev = {name: DeviceArrays(box) for name, box in (
            ("model", self.model), ("state", self.state), ("contacts", self.contacts),
            ("control", self.control))}
        for d in self._dev.values():
            d.push()
        real = ti.f32 if ti_runtime.real_dtype() == np.float32 else ti.f64
        self._scratch = HistoryScratch(self.contacts.capacity, real)
        self._fields = {"state": State.field_names(), "contacts": Contacts.field_names()}
        self._stale = {"state": set(), "contacts": set()}   # fields whose device copy is newer
        self._dirty = {"state": set(), "contacts": set()}   # fields the host may have written

    # Contacts fields that only the host writes between launches (the broad phase's index
    # arrays: the stepping kernels read them, install_pairs writes on the device the values the
    # host wrote on its own copy): current on the host after any launch, never copied back
    HOST_KEPT = {"state": frozenset(),
                 "contacts": frozenset({"pairs", "adj_ptr", "adj", "scene_pairs"})}
    # Contacts fields that install_pairs writes on the device from the device's history (a
    # rebuild): stale on the host after it
    INSTALLED = ("code", "npts", "loc", "shear", "patch_shape")

    def host(self, name: str, write: bool = True, fields=None) -> None:
        """Make the host's ``name`` ("state" or "contacts") current before the host reads it,
        and, with ``write``, copy it to the device before the next launch (the host may write
        it).  ``fields``: only these fields of it (names of the container's FIELDS; None: all).
        A no-op on the CPU without device arrays.

        Per field: a field is *stale* where the kernels wrote it since the host last copied it
        (every field but :attr:`HOST_KEPT` after a launch; :attr:`INSTALLED` after a rebuild's
        install): only the stale fields asked for are copied back (one copy per field, of every
        scene of the engine), once.  ``write`` marks the fields asked for *dirty* (whether the
        host then writes them or not, and whether they were stale or not: a field the host
        writes whole without reading it still goes to the device); the dirty fields are copied
        to the device before the next launch (or install) and are never stale meanwhile, so a
        copy back never overwrites what the host wrote.  ``sim.state`` / ``sim.contacts`` ask for
        every field with ``write`` (a writer gets what it always got); the read-only accessors
        (Simulation.read_state / read_contacts) ask for their fields without it."""
        if not self.on_device:
            return
        names = self._fields[name] if fields is None else tuple(fields)
        unknown = set(names) - set(self._fields[name])
        if unknown:
            raise KeyError(f"{name} has no field(s) {sorted(unknown)}")
        stale = self._stale[name]
        pull = [f for f in names if f in stale]
        if pull:
            self._dev[name].pull(pull)
            stale.difference_update(pull)
        if write:
            self._dirty[name].update(names)

    def _push_dirty(self, name: str) -> None:
        dirty = self._dirty[name]
        if dirty:
            self._dev[name].push([f for f in self._fields[name] if f in dirty])
            dirty.clear()

    # Control fields only the kernels write and the host reads on demand (Engine._take_probes)
    CONTROL_KERNEL_ONLY = ("probe_buf",)

    def _to_device(self) -> None:
        if not self.on_device:
            return
        self._dev["control"].push([f for f in self._dev["control"].dev
                                   if f not in self.CONTROL_KERNEL_ONLY])
        for name in ("state", "contacts"):
            self._push_dirty(name)

    def _from_device(self) -> None:
        if not self.on_device:
            return
        host_written = ("loads", "probe_slot", "probe_body")
        self._dev["control"].pull([f for f in self._dev["control"].dev
                                   if f not in host_written + self.CONTROL_KERNEL_ONLY])
        for name in ("state", "contacts"):  # nothing is dirty: _to_device pushed it
            self._stale[name] = set(self._fields[name]) - self.HOST_KEPT[name]

    def transfer_stats(self) -> dict:
        """The host <-> device traffic since construction (benchmarks/batch_speed.py ``run``):
        ``host_to_device`` / ``device_to_host``: ``copies`` (one per field moved), ``bytes``,
        ``seconds`` (the host's wall time in them), in all and ``by_container`` (model, state,
        contacts, control; each with ``fields``: the bytes of each field moved);
        ``install_pairs``: the rebuilds installed on the device (``calls``; ``bytes``: the
        host's index arrays handed to each, which a GPU copies in, and back after the kernel);
        ``chunks``: the chunks launched (each ends with the control's pull).  On the CPU without
        device arrays every count but ``chunks`` is 0."""
        ways = {"host_to_device": "push", "device_to_host": "pull"}
        out = {}
        for key, way in ways.items():
            by = {name: {**d.counts[way], "fields": dict(d.counts[way]["fields"])}
                  for name, d in getattr(self, "_dev", {}).items()}
            out[key] = {"copies": sum(v["copies"] for v in by.values()),
                        "bytes": sum(v["bytes"] for v in by.values()),
                        "seconds": sum(v["seconds"] for v in by.values()),
                        "by_container": by}
        out["install_pairs"] = dict(self._installs)
        out["chunks"] = self.n_chunks
        return out

    def install_pairs(self, g: int, lists, has_history: bool) -> None:
        """Scene g's new pair lists (containers.pair_lists) into the device's contacts
        (dem.engine.device.install_pairs: the history carried on the device)."""
        from dem.engine.device import install_pairs

        # what the host wrote since goes to the device first
        self._push_dirty("contacts")
        self._push_dirty("state")
        src = lists.src if lists.src is not None else np.zeros(0, dtype=np.int32)
        src_full = np.full(self.contacts.capacity, -1, dtype=np.int32)
        src_full[: len(src)] = src
        sc = self._scratch
        _, st, c, _ = self.containers()
        self._installs["calls"] += 1
        self._installs["bytes"] += (lists.pairs.nbytes + lists.adj_ptr.nbytes + lists.adj.nbytes
                                    + src_full.nbytes)
        install_pairs(g, lists.n, int(has_history), lists.pairs, lists.adj_ptr, lists.adj,
                      src_full, self._dev["model"].args, st, c, sc.code, sc.npts, sc.loc,
                      sc.shear)
        self._stale["contacts"].update(self.INSTALLED)  # the history, moved on the device

    def _warm_up(self) -> None:
        """Compile every kernel (or load it from Taichi's offline cache) with zero work, and
        record the stepping kernel's launch (dem.engine.launch: later launches skip Taichi's
        per-call argument handling unless ``fast_launch`` is False)."""
        # the kernels' compile-time variants (dem.engine.step): the imperfect faces' code only
        # for scenes that have some, each pair's normal law only for scenes with a hyperbolic
        # pair; a perfect, linear scene runs the perfect model's code (bit for bit, at its speed)
        self._warped = bool(self.model.imperfect.any())
        self._hyperbolic = any(sim.model.closure_limit() is not None
                               for sim in self.simulations)
        # the pair's no-tension rule of the normal dashpots only for scenes with a pair that
        # has it (material.normal_damping: pair or stiffness)
        self._pair_damping = any(sim.model.pair_damping() for sim in self.simulations)
        self._choose_launch()
        m, st, c, _ = self.containers()
        depth = ti_nd_real(1)
        stepk.probe_contacts(0, 0, depth, depth, m, st, c, self._warped, self.batched)
        stepk.elastic_energy(0, 0, m, c, self._hyperbolic, self.batched)

    def _overlap_wanted(self) -> bool:
        """Whether the overlap reuse variant should run: a warped scene whose overlap reuse
        tolerance (coherence.set_overlap_reuse, read from the contacts) is > 0."""
        return self._warped and any(coherence.overlap_reuse_tolerance(sim._contacts) > 0.0
                                    for sim in self.simulations)

    def _choose_launch(self) -> None:
        """Record the stepping kernel's launch for the compile-time variants (warped,
        hyperbolic, overlap, batched, pair_damping; dem.engine.step.advance_serial).  ``overlap`` follows
        coherence.set_overlap_reuse, which may be called after construction: _launch checks it
        before each launch of a warped scene and records a new launch when it changed."""
        self._overlap = self._overlap_wanted()
        variants = (self._warped, self._hyperbolic, self._overlap, self.batched,
                    self._pair_damping)
        if self.mode == "serial":
            kernel, scalars = stepk.advance_serial, (0, 0, float(self.dt))
        else:  # "step -2": the recording launch does nothing (steps_done is 0, not -2 or -1)
            kernel, scalars = stepk.advance_parallel, (-2, 0, float(self.dt))
            variants = variants + (self.on_device,)  # atomic sums on a device
        if self.fast_launch:
            self._advance = CachedLaunch(kernel, scalars, *self.containers(), *variants)
        else:
            kernel(*scalars, *self.containers(), *variants)
            self._advance = lambda *sc: kernel(*sc, *self.containers(), *variants)


class FieldView:
    """Named read-only views of some fields of a container (Simulation.read_state /
    read_contacts): ``view.pos`` is the container's ``pos`` array, not writeable."""

    def __init__(self, box, names):
        for name in names:
            a = getattr(box, name).view()
            a.flags.writeable = False
            setattr(self, name, a)


class Simulation:
    """One scene of an :class:`Engine`: the run loop's handle on it.

    ``Simulation(scene, joints, options, gravity)`` builds an engine of that one scene (the
    common case); an engine of several scenes makes one per scene (``engine.simulations``).
    Either way its state, contacts and control are that scene's (dem.engine.containers:
    slices of the engine's arrays), its clock (t, step_count) its own.

    Reading and writing the arrays: ``sim.state`` / ``sim.contacts`` are the containers
    themselves, to read and write; on a device (dem.engine.device) each use copies every field
    the kernels changed to the host and every field back to the device before the next launch.
    What only reads asks for its fields with ``sim.read_state("pos", "vel")`` /
    ``sim.read_contacts("wrench")``: read-only views of those fields, copied to the host only
    where stale, never back (Engine.host).  On the CPU without device arrays both are the
    host's arrays, nothing is copied.  The run loop's reads (frames, instruments, settling,
    energies, the summary) use the read-only accessors."""

    def __init__(self, scene: Scene, joints: JointLaw, options: StepOptions,
                 gravity=(0.0, 0.0, -9.81), fast_launch: bool = True):
        Engine([scene], [joints], options, [gravity], fast_launch, lone=self)

    def _bind(self, engine: Engine, g: int, scene: Scene, model: Model, joints, gravity
              ) -> None:
        self.engine = engine
        self.scene_index = g
        self.scene = scene
        self.options = engine.options
        self.joints = joints
        self.n_blocks = scene.n_blocks
        self.gravity0 = np.array(gravity, dtype=float)
        self.failure: Exception | None = None
        em = engine.model
        self._b0, self._b1 = (int(x) for x in em.scene_bodies[g])
        self.model = model
        self._movable = ~model.fixed_np
        self._movable[model.table] = False
        if engine.batched:
            self._state = engine.state.region(self._b0, self._b1)
            self._contacts = engine.contacts.region(g, self._b0, self._b1)
            self.control = engine.control.region(g)
            self.clock = Clock()
            self._slot0 = g * engine.contacts.capacity
        else:
            self._state, self._contacts, self.control = \
                engine.state, engine.contacts, engine.control
            self.clock = engine.clock
            self._slot0 = 0
        self.step_count = 0
        self._deepest_time = 0.0
        self.n_rebuilds = 0
        self.energy_initial = 0.0
        self.probe = None

    # ------------------------------------------------------------------------------------
    @property
    def state(self) -> State:
        """This scene's State, to read and write (on a device: every field copied to the host
        where the kernels changed it, and every field back before the next launch: the caller
        may write it).  To read only: :meth:`read_state`."""
        self.engine.host("state")
        return self._state

    @property
    def contacts(self) -> Contacts:
        """This scene's Contacts, to read and write (on a device: as :attr:`state`).  To read
        only: :meth:`read_contacts`."""
        self.engine.host("contacts")
        return self._contacts

    def set_probe(self, probe) -> None:
        """Copy some bodies' state at chosen steps inside a launch, without ending it (an
        instrument's samples: dem.run.record).  ``probe`` (None: none) has ``bodies`` (indices
        within this scene, at most PROBES_PER_SCENE), ``plan(clock, step, k)`` (the step counts
        in step + 1 ... step + k after which to copy, ascending, from this scene's Clock; called
        before each launch: it must not change the probe, as a launch may stop early) and
        ``take(step, t, rows)`` (called after the launch for each planned step it reached, in
        order; rows [bodies, 13]: pos, quat, vel, omega, as the state at that step count)."""
        ctl = self.engine.control
        ctl.probe_body[self.scene_index] = -1
        self.probe = None
        if probe is None:
            return
        bodies = np.asarray(probe.bodies, dtype=int).reshape(-1)
        if len(bodies) > PROBES_PER_SCENE or (bodies < 0).any() or \
                (bodies >= self._b1 - self._b0).any():
            raise InputError(f"a probe takes at most {PROBES_PER_SCENE} bodies of the scene "
                             f"(0 ... {self._b1 - self._b0 - 1}); got {bodies.tolist()}")
        ctl.probe_body[self.scene_index, :len(bodies)] = self._b0 + bodies
        self.probe = probe

    def read_state(self, *fields: str) -> FieldView:
        """This scene's State fields ``fields`` (names of State.FIELDS; none given: all) to read
        only, as attributes of a :class:`FieldView` (read-only views of the arrays, no copy: a
        write raises; a field not asked for is not there).  On a device only the fields asked
        for are copied to the host, and only where the kernels changed them since (for every
        scene of the engine at once: the batch-mates' reads after it copy nothing), and nothing
        goes back to the device.  Valid until the next advance."""
        names = fields or State.field_names()
        self.engine.host("state", write=False, fields=names)
        return FieldView(self._state, names)

    def read_contacts(self, *fields: str) -> FieldView:
        """This scene's Contacts fields ``fields`` (none given: all) to read only, as
        :meth:`read_state`; the view also has ``n_pairs``.  The broad phase's index arrays
        (pairs, adj_ptr, adj, scene_pairs: Engine.HOST_KEPT) are current on the host and never
        copied."""
        names = fields or Contacts.field_names()
        self.engine.host("contacts", write=False, fields=names)
        view = FieldView(self._contacts, names)
        view.n_pairs = self._contacts.n_pairs
        return view

    def active_contact_points(self) -> dict[str, np.ndarray]:
        """Contacts.active_points of this scene, read only (:meth:`read_contacts`)."""
        return Contacts.active_points(self.read_contacts(*Contacts.POINT_FIELDS))

    @property
    def t(self) -> float:
        return self.clock.time(self.step_count)

    skin = property(lambda self: self.engine.skin, doc="neighbour-list skin (m)")
    mode = property(lambda self: self.engine.mode, doc="the stepping kernel: serial / parallel")
    compile_seconds = property(lambda self: self.engine.compile_seconds)
    dt_changes = property(lambda self: self.engine.dt_changes,
                          lambda self, v: setattr(self.engine, "dt_changes", v),
                          doc="the changes of the (engine's) time step")

    @property
    def dt(self) -> float:
        """time step in use (s): the engine's"""
        return self.engine.clock.dt

    @dt.setter
    def dt(self, value: float) -> None:
        if self.engine.batched:
            # (a restart point's dt, set after its anchors) this scene's clock at its present
            # step in that dt, then the engine's step from here on (the smaller of the two)
            value = float(value)
            if value != self.engine.clock.dt:  # the same step: the anchors stand as saved
                t = self.clock.t_anchor + (self.step_count - self.clock.step_anchor) * value
                self.clock.anchor(t, self.step_count)
                self.clock.dt = self.engine.clock.dt
                self.engine.adopt_dt(value)
        else:
            self.engine.clock.dt = value

    @property
    def dt_crit(self) -> float:
        """critical time step with the present area caps (s), the engine's"""
        return self.engine.clock.dt_crit

    @dt_crit.setter
    def dt_crit(self, value: float) -> None:
        if not self.engine.batched:  # several scenes: the engine's, recomputed from the caps
            self.engine.clock.dt_crit = value

    # the clock's anchors under the names Simulation always had (restart points save them so)
    def _clock_field(name: str, doc: str):  # a helper of the class body, deleted below
        return property(lambda self: getattr(self.clock, name),
                        lambda self, v: setattr(self.clock, name, v), doc=doc)

    _t_anchor = _clock_field("t_anchor", "time at the last change of dt (s)")
    _step_anchor = _clock_field("step_anchor", "step count at the last change of dt")
    del _clock_field

    def _caps_field(name: str, doc: str):  # a helper of the class body, deleted below
        def get(self):
            a = getattr(self.engine.clock, name)
            return a[self._b0:self._b1] if self.engine.batched else a

        def put(self, v):
            if self.engine.batched:
                getattr(self.engine.clock, name)[self._b0:self._b1] = v
            else:
                setattr(self.engine.clock, name, v)
        return property(get, put, doc=doc)

    area_cap = _caps_field("area_cap", "per body, the capped contact area (m^2, inf: none)")
    _face_area = _caps_field("face_area", "per body and face, the areas in the bound (m^2)")
    del _caps_field

    # ------------------------------------------------------------------------------------
    def advance(self, n_steps: int, loads: LoadFn, on_chunk: Callable[[int], None] | None = None
                ) -> None:
        """Advance n_steps steps.  Raises InstabilityError / CapacityError on failure (the state
        is then that of the failing step).  A scene of an engine of several scenes advances
        through the engine's hub (dem.run.batched), with the others."""
        if not self.engine.batched:
            self.engine.advance(n_steps, [loads], on_chunk)
            return
        if self.engine.hub is None:
            raise RuntimeError("a scene of an engine of several scenes advances with the others: "
                               "Engine.advance, or the engine's hub (dem.run.batched)")
        self.engine.hub.advance(self.scene_index, n_steps, loads)
        if self.failure is not None:
            raise self.failure
        if on_chunk is not None:
            on_chunk(n_steps)

    def rebuild(self) -> None:
        """Broad phase of this scene: new neighbour list, history carried over for pairs that
        stay."""
        self.engine.host("state", write=False, fields=("pos", "rot", "quat"))
        st = self._state
        m = self.model
        pairs = candidate_pairs(st.pos, st.rot, m.half_np, m.radius_np, m.fixed_np, m.table,
                                self.skin)
        c = self._contacts
        if len(pairs) > c.capacity:
            counts = np.bincount(pairs.ravel(), minlength=m.n_bodies)[: self.n_blocks]
            worst = int(np.argmax(counts))
            raise CapacityError(
                f"neighbour list overflow at step {self.step_count} (t = {self.t:.4f} s): "
                f"{len(pairs)} candidate pairs > capacity {c.capacity} (block {worst} has "
                f"{counts[worst]} neighbours); raise solver.max_pairs_per_block "
                f"(now {self.options.max_pairs_per_block}) or lower solver.skin ({self.skin:.3g} m)")
        n_old = c.n_pairs
        old_pairs = c.pairs[:n_old].copy() if n_old else None
        if self.engine.on_device:
            # the host keeps the index arrays (only it writes them); the history stays on the
            # device (dem.engine.device.install_pairs)
            lists = pair_lists(pairs, m.n_bodies, c.capacity, old_pairs)
            c.pairs[...] = lists.pairs
            c.adj_ptr[...] = lists.adj_ptr
            c.adj[...] = lists.adj
            c.n_pairs = lists.n
            self.engine.install_pairs(self.scene_index, lists, n_old > 0)
        else:
            history = c.read_history() if n_old else None
            c.write_pairs(pairs, m.n_bodies, history, old_pairs)
        c.ref_pos[...] = st.pos
        c.ref_quat[...] = st.quat
        self.n_rebuilds += 1

    def check_initial_overlaps(self, tolerance: float) -> np.ndarray:
        """Raise if two bodies overlap by more than ``tolerance`` at the start; returns each
        body's largest contact patch area (m^2) at the start."""
        c = self._contacts  # its pairs (written by the host)
        patch = np.zeros(self.model.n_bodies)
        n = c.n_pairs
        if n == 0:
            return patch
        depth = ti_nd_real(c.capacity)
        area = ti_nd_real(c.capacity)
        e = self.engine
        m, st, ca, _ = e.containers()
        stepk.probe_contacts(self._slot0, self._slot0 + n, depth, area, m, st, ca, e._warped,
                             e.batched)
        d = depth[:n]
        worst = int(np.argmax(d))
        if d[worst] > tolerance:
            i, j = c.pairs[worst]
            name = lambda b: "the table" if b == self.model.table else f"block {b}"  # noqa: E731
            raise InputError(
                f"{name(i)} and {name(j)} overlap by {d[worst] * 1e3:.3f} mm at the start "
                f"(tolerance solver.overlap_tolerance = {tolerance * 1e3:.3f} mm); "
                f"{int((d > tolerance).sum())} pair(s) overlap in all")
        pairs = c.pairs[:n]
        for side in (0, 1):
            np.maximum.at(patch, pairs[:, side], area[:n])
        return patch

    def _closure_error(self, closure_limit: float) -> SimulationError | None:
        """The hyperbolic law: the error to stop with when a joint closed beyond the closure
        the step is made for (d_lim = closure_limit x d_max; dem.engine.laws: past it the law is
        linearised, stable but no longer the hyperbolic law), else None."""
        deepest = float(self.control.deepest[0])
        if deepest > closure_limit:
            return SimulationError(
                f"a joint closed by {deepest:.4g} m by t = {self.t:.5f} s, beyond "
                f"{closure_limit:.4g} m (material.closure_limit x max_closure), the "
                f"largest closure the time step is made for: the hyperbolic law's tangent "
                f"stiffness grows without bound as the closure nears max_closure; raise "
                f"material.closure_limit (a shorter step) or check max_closure and the loads")
        return None

    def unbalanced_force_ratio(self, gravity, base_accel=(0.0, 0.0, 0.0)) -> float:
        """Mean unbalanced-force ratio (the static-convergence measure of 3DEC / UDEC / PFC):
        sum over movable blocks of |F_i| + |T_i| / r_i over the sum of their weights m_i |g|,
        where F_i, T_i are the net force and torque of the last step's contact wrenches plus
        m_i (gravity - base_accel) (m/s^2, table frame), before any local damping, r_i the
        bounding radius.  Zero in static equilibrium; -.  Computed on the host from
        Contacts.wrench, so the kernels are untouched."""
        m, c = self.model, self.read_contacts("pairs", "wrench")
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
        """Cundall local damping coefficient (of this scene) from the next step on (0: none)."""
        self.control.local_damping[0] = alpha

    def save_point(self) -> dict:
        """Copies of everything that evolves: State, Contacts (neighbour list, shear history),
        the energy sums.  :meth:`restore_point` puts them back in place (the arrays the kernels
        hold do not move); time and step count go on."""
        return {"state": {k: a.copy() for k, a in self._read_all("state").arrays().items()},
                "contacts": {k: a.copy()
                             for k, a in self._read_all("contacts").arrays().items()},
                "energy": self.control.energy_sums.copy()}

    def restore_point(self, point: dict) -> None:
        for k, a in point["state"].items():
            getattr(self.state, k)[...] = a
        for k, a in point["contacts"].items():
            getattr(self.contacts, k)[...] = a
        self.control.energy_sums[...] = point["energy"]

    # what evolves on the host beside the containers' arrays: the clock, the time step and the
    # area caps behind it, counters, the energy at t = 0 (saved by snapshot)
    EVOLVING = ("step_count", "_t_anchor", "_step_anchor", "dt", "dt_crit", "n_rebuilds",
                "_deepest_time", "energy_initial", "area_cap", "_face_area")

    # written before every launch, never read after it: not saved (a restart point then fits
    # an engine with another chunk length, e.g. one on a device)
    TRANSIENT = {("control", "loads")}

    def snapshot(self) -> dict[str, np.ndarray]:
        """Everything that evolves, as named arrays (an npz file's content): every array of
        State, Contacts and Control (this scene's), the pair count, :attr:`EVOLVING`,
        ``dt_changes`` and the kernel in use.  :meth:`restore` on a Simulation built from the
        same scene and options goes on bit for bit as this one would (tests/test_resume.py),
        alone or as a scene of an engine of several.  The Model is static, rebuilt from the
        scene, never saved."""
        boxes = (("state", self._read_all("state")), ("contacts", self._read_all("contacts")),
                 ("control", self.control))
        out = {f"{name}.{k}": a.copy() for name, box in boxes
               for k, a in box.arrays().items() if (name, k) not in self.TRANSIENT}
        out["contacts.n_pairs"] = np.array(self._contacts.n_pairs)
        out.update({f"sim.{k}": np.array(getattr(self, k)) for k in self.EVOLVING})
        out["sim.dt_changes"] = np.array(json.dumps(self.dt_changes))
        out["sim.mode"] = np.array(self.mode)
        return out

    def restore(self, snap) -> None:
        """Put a :meth:`snapshot` back (the arrays in place: the cached launches hold them).
        Raises ValueError, naming the entry, where it does not fit this simulation (another
        kernel, precision, scene size or pair capacity); nothing is changed then.  A scene of
        an engine of several keeps the engine's shared control fields (skin, ...) and takes
        the smaller of its snapshot's time step and the engine's."""
        if str(snap["sim.mode"]) != self.mode:
            raise ValueError(f"the snapshot was taken with the {snap['sim.mode']} kernel, this "
                             f"simulation runs the {self.mode} one")
        for name, box in self._boxes():
            for k, a in box.arrays().items():
                if (name, k) in self.TRANSIENT:
                    continue
                key = f"{name}.{k}"
                if key not in snap:
                    raise ValueError(f"the snapshot has no {key}")
                b = snap[key]
                if b.shape != a.shape or b.dtype != a.dtype:
                    raise ValueError(f"{key}: {b.dtype} {b.shape} in the snapshot, {a.dtype} "
                                     f"{a.shape} in this simulation")
        shared = Control.SHARED if self.engine.batched else ()
        for name, box in self._boxes():
            for k, a in box.arrays().items():
                if (name == "control" and k in shared) or (name, k) in self.TRANSIENT:
                    continue
                a[...] = snap[f"{name}.{k}"]
        self.contacts.n_pairs = int(snap["contacts.n_pairs"])
        for k in self.EVOLVING:
            v = np.asarray(snap[f"sim.{k}"])
            setattr(self, k, v.copy() if v.ndim else v.item())
        if not self.engine.batched:
            self.dt_changes = json.loads(str(snap["sim.dt_changes"]))

    def _read_all(self, name: str):
        """The container ``name`` ("state" or "contacts") itself, every field current on the
        host, to read only (copied, never written: nothing goes back to the device)."""
        self.engine.host(name, write=False)
        return self._state if name == "state" else self._contacts

    def _boxes(self) -> tuple:
        return (("state", self.state), ("contacts", self.contacts), ("control", self.control))

    def deepest_penetration(self) -> tuple[float, float]:
        """(depth in m, time in s) of the deepest penetration of any contact point at any step
        since t = 0 (kept by the kernel every step: dem.engine.step.deepest_stage)."""
        return float(self.control.deepest[0]), self._deepest_time

    def containers(self) -> tuple:
        """The argpacks of the engine's (Model, State, Contacts, Control), as the kernels take
        them (every scene of the engine)."""
        return self.engine.containers()

    def _instability(self) -> InstabilityError:
        b = int(self.control.bad_body[0])
        st = self.read_state("pos", "vel")
        v = st.vel[b]
        x = st.pos[b]
        what = "became NaN/inf" if self.control.status[0] & NONFINITE else (
            f"moves faster than solver.max_speed = {self.options.max_speed} m/s")
        return InstabilityError(
            f"block {b} {what} at step {self.step_count} (t = {self.t:.5f} s): position "
            f"{np.array2string(x, precision=4)} m, velocity {np.array2string(v, precision=3)} m/s;"
            f" dt = {self.dt:.3g} s (critical {self.dt_crit:.3g} s)", self.step_count, b)

    # ------------------------------------------------------------------------------------
    def kinetic_energy(self) -> float:
        st, m = self.read_state("vel", "omega", "angmom"), self.model
        v = st.vel
        w = st.omega
        L = st.angmom
        movable = ~m.fixed_np
        return float(0.5 * (m.mass_np[movable] * (v[movable] ** 2).sum(1)).sum()
                     + 0.5 * (w[movable] * L[movable]).sum())

    def elastic_energy(self) -> float:
        n = self._contacts.n_pairs
        if n == 0:
            return 0.0
        e = self.engine
        m, _, c, _ = e.containers()
        return float(stepk.elastic_energy(self._slot0, self._slot0 + n, m, c, e._hyperbolic,
                                          e.batched))

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

