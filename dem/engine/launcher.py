"""Launching the stepping kernels: which kernel and which compile-time variant, chunks of steps,
the probes inside a chunk, and what the host does between two chunks.

A *chunk* is the steps run between two looks of the host (at most control.loads' S rows: the
residency's ``CHUNK_STEPS``, dem.engine.residency): the loads of its steps are written
into control.loads (one row a step and scene), the serial kernel runs them in one launch (the
parallel kernel in one launch a step, with no read-back between them), and the chunk ends early
after a step that raised a status bit of any scene (STOP: a scene failed; REBUILD: a scene's
neighbour list must be rebuilt).  On a device (the residency's ``device_stepper``) the
stepping kernel runs several steps a launch (dem.engine.step_device), each followed by the
rebuild of the lists that asked for one (dem.engine.broadphase_device): a rebuild ends the
chunk only where the new list does not fit.  Between chunks the host rebuilds the neighbour
lists asked for, freezes failed scenes, checks the hyperbolic closures and the area caps
(dem.engine.stepsize).  Where an advance goes on past a chunk, the next chunk's loads are
written once the chunk's launches are queued, before its end is read back
(:meth:`Launcher.write_loads`), and so are the last chunk's probed samples and frames
recorded (:meth:`Launcher.flush_probes`): on a device the GPU still runs the chunk meanwhile,
and a GPU waits for the host only from a chunk's end to the next chunk's first launch
(benchmarks/host_share.py).

The kernels' compile-time variants are one value, :class:`KernelVariants`, chosen in one place
(:meth:`KernelVariants.of`); docs/engine.md lists the reachable ones.
"""

from __future__ import annotations

import dataclasses
import os
from typing import Callable

import numpy as np

from dem import ti_runtime
from dem.engine import coherence
from dem.engine import step as stepk
from dem.engine.containers import REBUILD, STOP
from dem.engine.errors import CapacityError
from dem.engine.launch import CachedLaunch

# auto mode: the parallel kernel from this many bodies on, by the threads Taichi runs (measured,
# benchmarks/RESULTS.md "Thread scaling by scene size", with the cached launch): a parallel step pays ~30-100 us of
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


def kernel_mode(requested: str, on_device: bool, n_bodies: int) -> str:
    """The stepping kernel, "serial" or "parallel": solver.mode where it names one; on a device
    always the parallel one (the serial kernel would run on one GPU thread); auto: the parallel
    kernel from :func:`parallel_min_bodies` on."""
    if on_device:
        return "parallel"
    if requested == "auto":
        threads = ti_runtime.settings()["threads"] or os.cpu_count() or 1
        return "parallel" if n_bodies >= parallel_min_bodies(threads) else "serial"
    return requested


@dataclasses.dataclass(frozen=True)
class KernelVariants:
    """The compile-time flags of the kernels (dem.engine.step: each combination is its own
    compiled kernel).

    warped       the imperfect faces' narrow phase (a scene with imperfect faces)
    hyperbolic   each pair's normal law (a scene with a hyperbolic pair); else the linear law
    overlap      the overlap reuse of warped faces (coherence.set_overlap_reuse > 0; warped only)
    batched      several scenes in the arrays (their pair slots and bodies by scene); on a
                 device always (one scene too): its pair slots' test reads the pair counts
                 there, which the device's broad phase changes within a chunk
    pair_damping the pair's no-tension rule of the normal dashpots (material.normal_damping:
                 pair or stiffness)
    atomic_sums  the parallel kernel's sums as atomics (on a device); the serial kernel has none
    device_steps an engine on a device with its broad phase there: the steps a launch of
                 dem.engine.step_device.advance_device (batched, atomic sums); 0: the kernels
                 of dem.engine.step (the host's broad phase between chunks)

    A perfect, linear, lone scene runs the perfect model's code (bit for bit, at its speed)."""

    warped: bool
    hyperbolic: bool
    overlap: bool
    batched: bool
    pair_damping: bool
    atomic_sums: bool
    device_steps: int = 0

    @classmethod
    def of(cls, model, models, contacts, mode: str, on_device: bool,
           device_steps: int = 0) -> "KernelVariants":
        """The variants of an engine of the scenes of ``models`` (one Model each; ``model``:
        the engine's, all of them), their Contacts ``contacts`` (one region each: the overlap
        reuse tolerance is kept there), the kernel ``mode``, whether it runs on a device and
        the steps a launch of the device's kernel (0: none)."""
        warped = bool(model.imperfect.any())
        return cls(warped=warped,
                   hyperbolic=any(m.closure_limit() is not None for m in models),
                   overlap=overlap_wanted(warped, contacts),
                   batched=len(models) > 1 or on_device,
                   pair_damping=any(m.pair_damping() for m in models),
                   atomic_sums=mode == "parallel" and on_device,
                   device_steps=device_steps if on_device else 0)

    def stepping(self, mode: str) -> tuple:
        """The flags the stepping kernel of ``mode`` takes, in its order (the device's:
        dem.engine.step_device.DeviceStepper.launch's)."""
        if self.device_steps:
            return (self.device_steps, self.warped, self.hyperbolic, self.overlap,
                    self.pair_damping)
        flags = (self.warped, self.hyperbolic, self.overlap, self.batched, self.pair_damping)
        return flags + (self.atomic_sums,) if mode == "parallel" else flags


def overlap_wanted(warped: bool, contacts) -> bool:
    """Whether the overlap reuse variant should run: a warped scene whose overlap reuse
    tolerance (coherence.set_overlap_reuse, read from its contacts) is > 0."""
    return warped and any(coherence.overlap_reuse_tolerance(c) > 0.0 for c in contacts)


class Launcher:
    """The chunks of one engine (``engine``: dem.engine.simulation.Engine, read for its
    containers, residency, step size, scenes and control)."""

    def __init__(self, engine, fast_launch: bool = True, steps_per_launch: int | None = None):
        self.engine = engine
        self.fast_launch = fast_launch
        self.steps_per_launch = steps_per_launch  # the device's kernel (Engine)
        self.n_chunks = 0  # chunks launched (one launch, or k of the parallel kernel)
        self.n_launches = 0  # stepping kernel launches
        self.variants: KernelVariants | None = None
        # the stepping kernel's launch: kernel(step, n_slots, dt); the device's,
        # kernel(first step, chunk's steps, dt)
        self.kernel = None
        # the device's stepping kernel and broad phase (dem.engine.step_device.DeviceStepper);
        # None: the host's broad phase between chunks (dem.engine.residency)
        self.stepper = None
        # the loads written into control.loads ahead, while the last chunk's launches ran:
        # scene -> (its clock's key at the chunk they are for, their rows, the load function)
        self.ahead: dict = {}

    # ------------------------------------------------------------------------------------
    def warm_up(self) -> None:
        """Compile every kernel (or load it from Taichi's offline cache) with zero work, and
        record the stepping kernel's launch (dem.engine.launch: later launches skip Taichi's
        per-call argument handling unless ``fast_launch`` is False)."""
        from dem.engine.step_device import steps_per_launch

        e = self.engine
        self.stepper = e.residency.device_stepper()
        steps = steps_per_launch(self.steps_per_launch) if self.stepper is not None else 0
        self.variants = KernelVariants.of(e.model, [s.model for s in e.simulations],
                                          [s.contacts_on_host for s in e.simulations], e.mode,
                                          e.on_device, steps)
        self.record_launch()
        v = self.variants
        m, st, c, _ = e.containers()
        depth = np.zeros(1, dtype=ti_runtime.real_dtype())
        stepk.probe_contacts(0, 0, depth, depth, m, st, c, v.warped, v.batched)
        stepk.elastic_energy(0, 0, m, c, v.hyperbolic, v.batched)

    def record_launch(self) -> None:
        """Record the stepping kernel's launch for :attr:`variants`
        (dem.engine.step.advance_serial / advance_parallel, or the device's
        dem.engine.step_device.advance_device)."""
        e = self.engine
        if self.variants.device_steps:
            self.kernel = self.stepper.launch(*self.variants.stepping(e.mode))
            return
        if e.mode == "serial":
            kernel, scalars = stepk.advance_serial, (0, 0, float(e.dt))
        else:  # "step -2": the recording launch does nothing (steps_done is 0, not -2 or -1)
            kernel, scalars = stepk.advance_parallel, (-2, 0, float(e.dt))
        flags = self.variants.stepping(e.mode)
        if self.fast_launch:
            self.kernel = CachedLaunch(kernel, scalars, *e.containers(), *flags)
        else:
            kernel(*scalars, *e.containers(), *flags)
            self.kernel = lambda *sc: kernel(*sc, *e.containers(), *flags)

    # ------------------------------------------------------------------------------------
    def advance(self, n_steps: int, loads: list, on_chunk: Callable[[int], None] | None = None
                ) -> None:
        """Advance every active scene by n_steps steps, scene g with ``loads[g]`` (a LoadFn;
        ignored for a frozen scene), chunk by chunk (module docstring); a scene's failure goes to
        ``engine.fail``."""
        self.ahead = {}  # rows written ahead belong to one advance (its load functions)
        try:
            self._chunks(n_steps, loads, on_chunk)
        finally:  # the last chunk's probes (and a stopped advance's) before the caller looks
            self.flush_probes()

    def _chunks(self, n_steps: int, loads: list, on_chunk) -> None:
        """:meth:`advance`'s chunks, each followed by what the host checks at a chunk's end."""
        e = self.engine
        ctl = e.control
        done_total = 0
        while done_total < n_steps and ctl.active.any():
            k = min(n_steps - done_total, ctl.loads.shape[0])
            done = self.launch(k, loads, n_steps - done_total)
            done_total += done
            status = ctl.status.copy()
            for g in np.flatnonzero(status & STOP):
                e.fail(g, e.simulations[g].instability_error())
            rebuilding = [int(g) for g in np.flatnonzero(status & REBUILD) if ctl.active[g]]
            if rebuilding:  # their poses to the host in one copy a field (a device's)
                e.host_scenes("state", e.simulations[0].BROAD_PHASE_READS, rebuilding)
            for g in np.flatnonzero(status & REBUILD):
                if ctl.active[g]:
                    try:
                        e.simulations[g].rebuild()
                    except CapacityError as err:
                        e.fail(g, err)
            if self.variants.hyperbolic:  # each scene against its own law's limit
                for g in np.flatnonzero(ctl.active):
                    limit = e.step_size.closure_limits[g]
                    err = None if limit is None else \
                        e.simulations[g].closure_error(limit)
                    if err is not None:
                        e.fail(g, err)
            e.step_size.check_caps(e)
            if on_chunk is not None:
                on_chunk(done)

    def n_pair_slots(self) -> int:
        """The pair slots the kernels loop over: up to the last slot in use (one scene: its
        pairs); where the lists are the device's, every slot (a list may grow within a chunk:
        the kernels' slot test reads the counts there)."""
        e = self.engine
        sp = e.contacts.scene_pairs
        P = e.contacts.capacity
        if e.residency.lists_on_device:
            return len(sp) * P
        used = [g * P + int(n) for g, n in enumerate(sp) if n > 0]
        return max(used, default=0)

    @staticmethod
    def _clock_key(sim, ahead: int = 0) -> tuple:
        """What the times of a chunk's steps depend on (dem.engine.timestep.Clock.times): the
        step count ``ahead`` steps on, the clock's anchor and dt."""
        c = sim.clock
        return (sim.step_count + ahead, c.t_anchor, c.step_anchor, c.dt)

    def write_loads(self, k: int, loads: list, ahead: int = 0) -> None:
        """Each active scene's loads of the k steps from its step count + ``ahead`` into
        control.loads (step n's time counted from the last change of dt, as sim.t: the same
        loads for a step however the run is cut into launches).  ``ahead`` > 0: the next
        chunk's, written while this chunk's launches run (:meth:`launch`), kept in
        :attr:`ahead` with the clock's key they assume; a chunk whose scene's key and load
        function are those finds its rows written (a load function is a function of time
        alone, dem.run.steps)."""
        e = self.engine
        ctl = e.control
        for g, sim in enumerate(e.simulations):
            if not ctl.active[g]:
                continue
            if not ahead:
                got = self.ahead.get(g)
                if got is not None and got[0] == self._clock_key(sim) and got[1] >= k \
                        and got[2] is loads[g]:
                    continue
            grav, a = loads[g](sim.clock.times(sim.step_count + ahead, k))
            ctl.loads[:k, g, 0] = grav
            ctl.loads[:k, g, 1] = a
            if ahead:
                self.ahead[g] = (self._clock_key(sim, ahead), k, loads[g])
        if not ahead:
            self.ahead = {}

    def launch(self, k: int, loads: list, left: int | None = None) -> int:
        """One chunk of up to k steps; returns the steps done.  ``left``: the steps of the
        advance left before this chunk (Launcher.advance); where more are left than it does,
        the next chunk's loads are written while its launches run (:meth:`write_loads`: on a
        device, the host's part of a chunk's end that the GPU does not wait for)."""
        e = self.engine
        ctl = e.control
        self.write_loads(k, loads)
        k, probes = self.plan_probes(k)
        ctl.status[...] = 0
        ctl.bad_body[...] = 0
        ctl.deepest_step[...] = -1
        ctl.steps_done[...] = 0
        v = self.variants
        if v.warped and overlap_wanted(v.warped, [s.contacts_on_host for s in e.simulations]) \
                != v.overlap:
            # coherence.set_overlap_reuse switched the overlap reuse
            self.variants = dataclasses.replace(v, overlap=not v.overlap)
            self.record_launch()
        n_slots = self.n_pair_slots()
        self.n_chunks += 1
        e.residency.to_device(k)
        dt = e.dt
        if e.mode == "serial":
            self.kernel(k, n_slots, dt)
            self.n_launches += 1
        elif self.variants.device_steps:
            # U steps a launch, each then the lists of the scenes that must rebuild; no
            # read-back between launches (a stopped chunk's launches idle)
            U = self.variants.device_steps
            for s in range(0, k, U):
                self.kernel(s, k, dt)
            self.n_launches += -(-k // U)
        else:
            for s in range(k):  # no read-back between steps: a stopped chunk's launches idle
                self.kernel(s, n_slots, dt)
            self.n_launches += k
        if left is not None and left > k:  # the next chunk's loads while these steps run
            self.write_loads(min(left - k, ctl.loads.shape[0]), loads, ahead=k)
        self.flush_probes()  # the last chunk's samples and frames, while these steps run
        e.residency.from_device()
        done = int(ctl.steps_done[0])
        if probes:
            self.take_probes(probes, done)
        for g, sim in enumerate(e.simulations):
            if ctl.active[g]:
                sim.count_steps(done, int(ctl.deepest_step[g]), dt)
        rebuilt = e.residency.rebuilds()
        if rebuilt is not None:
            for g in np.flatnonzero(rebuilt):
                e.simulations[g].n_rebuilds += int(rebuilt[g])
        return done

    def plan_probes(self, k: int) -> tuple[int, dict]:
        """Before a launch of k steps: each active scene's probed steps among them
        (Simulation.set_probe: ``probe.plan``) into control.probe_slot, the i-th of a scene in
        slot i, at most Q (probe_buf's slots) a scene: the launch is shortened to the step of
        the last one that fits.  Returns (k, {g: [s, ...]}), s the steps of the launch (0 = its
        first) after which scene g's probed bodies are copied, ascending (slot = index)."""
        e = self.engine
        ctl = e.control
        ctl.probe_slot[:k] = -1
        slots = ctl.probe_buf.shape[0]
        planned = {}
        for g, sim in enumerate(e.simulations):
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

    def take_probes(self, probes: dict, done: int) -> None:
        """After a launch that did ``done`` steps: each probed step it reached, handed to its
        scene's ``probe.take(step, t, rows)`` in order (rows: [n, 13] pos, quat, vel, omega of
        the first n probed bodies, as Simulation.set_probe listed them: all of them, or the
        ``probe.rows(step)`` first where the probe says a step needs fewer).  A scene that
        failed in the launch gets none of its last step (the failing one: its state is not a
        result).  Only the slots and rows handed over come back from a device.  The rows are
        copies and t is the step's time now (a later change of dt moves the clock's anchor),
        so a probe may keep them and record them at its ``flush()`` (:meth:`flush_probes`)."""
        e = self.engine
        status = e.control.status
        taken = []  # (scene, slot, step, rows)
        for g, steps in probes.items():
            sim = e.simulations[g]
            reached = done - 1 if status[g] & STOP else done
            rows_of = getattr(sim.probe, "rows", None)
            for slot, s in enumerate(steps):
                if s < reached:
                    step = sim.step_count + s + 1
                    n = len(sim.probe.bodies) if rows_of is None else rows_of(step)
                    taken.append((g, slot, step, n))
        if not taken:
            return
        rows = [0] * (max(t[1] for t in taken) + 1)  # of each slot: the most a scene needs
        for _, slot, _, n in taken:
            rows[slot] = max(rows[slot], n)
        e.residency.pull_probes(rows)
        buf = e.control.probe_buf
        for g, slot, step, n in taken:
            sim = e.simulations[g]
            sim.probe.take(step, sim.clock.time(step), buf[slot, g, :n].copy())

    def flush_probes(self) -> None:
        """Each probe's ``flush()``, where it has one: what it took at the last chunk's end
        and kept (a LaunchProbe's samples and frames, dem.run.record).  Called once the next
        chunk's launches are queued (:meth:`launch`: on a device the recording's Python then
        runs while the GPU steps, not in the time the GPU waits for the host) and at an
        advance's end, stopped or not, so a caller of :meth:`advance` finds every probed step
        recorded."""
        for sim in self.engine.simulations:
            flush = getattr(sim.probe, "flush", None)
            if flush is not None:
                flush()
