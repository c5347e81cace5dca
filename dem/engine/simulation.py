"""Engine: the scenes of one engine, composed of its parts; Simulation: one scene of an engine,
the object the run loop drives.

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

An engine's parts, one job each (docs/engine.md, "The engine's parts"):

  dem.engine.assembly   the containers (Model, State, Contacts, Control) of the scenes
  dem.engine.stepsize   the time step: the critical step, area caps, restart points' dt
  dem.engine.launcher   the kernel and its variants, chunks of steps, probes, chunk ends
  dem.engine.residency  where the arrays live (host, device) and which copy is current
  this module           Engine (the parts, composed) and Simulation (one scene's view)

Time is kept as an integer step count (t = step * dt) so that long runs do not accumulate
rounding in t.
"""

from __future__ import annotations

import json
import time
from typing import Callable

import numpy as np

from dem import ti_runtime
from dem.engine import step as stepk
from dem.engine.assembly import assemble
from dem.engine.broadphase import candidate_pairs
from dem.engine.containers import NONFINITE, Contacts, Control, Model, State
from dem.engine.launcher import Launcher, kernel_mode
from dem.engine.options import JointLaw, StepOptions
from dem.engine.errors import CapacityError, InputError, InstabilityError, SimulationError
from dem.engine.residency import residency_kind
from dem.engine.stepsize import StepSize
from dem.engine.timestep import Clock
from dem.scene import Scene

# loads(t [K]) -> (gravity [K,3], base acceleration [K,3]), both in the table frame, m/s^2
LoadFn = Callable[[np.ndarray], tuple[np.ndarray, np.ndarray]]


class Engine:
    """The containers of ``len(scenes)`` scenes side by side and the kernels that step them.

    scenes   : the scenes (dem.scene.Scene), in order; scene g's bodies are rows
               model.scene_bodies[g] of every body array
    joints   : one JointLaw per scene (or one for all)
    options  : the StepOptions of every scene (one time step, one kernel, one skin)
    gravity  : per scene, the gravity at rest (m/s^2, table frame), or one 3-vector for all
    views    : the Simulation objects to bind, one per scene (Simulation's own constructor);
               None: new ones
    device_arrays : keep the arrays on the device (dem.engine.residency); None: where Taichi
               runs on a GPU (dem.ti_runtime.init(arch="cuda")); True on the CPU runs the device
               path in host memory (its tests)
    device_broad_phase : with device arrays, rebuild a scene's neighbour list on the device
               between two steps of a chunk (dem.engine.broadphase_device; default); False: on
               the host between chunks, as the CPU path does (dem.engine.broadphase; the same
               lists: tests/test_broadphase_device.py).  Ignored without device arrays.
    steps_per_launch : with the device's broad phase, the steps a launch of its stepping
               kernel (dem.engine.step_device.steps_per_launch: None, DEM_STEPS_PER_LAUNCH or
               by arch); the same trajectories for every value.

    Its parts: ``residency`` (where the arrays live), ``launcher`` (kernel, variants, chunks),
    ``step_size`` (the time step); the containers ``model``, ``state``, ``contacts``,
    ``control`` (dem.engine.assembly); ``simulations``, one view per scene.
    """

    def __init__(self, scenes: list[Scene], joints, options: StepOptions, gravity=None,
                 fast_launch: bool = True, views: "list[Simulation] | None" = None,
                 device_arrays: bool | None = None, device_broad_phase: bool = True,
                 steps_per_launch: int | None = None):
        # Taichi is started by the process's entry point (dem.run.build, dem.batch,
        # dem.run.batched: arch, threads, precision); for a library user who did not, this
        # starts it with the options' settings, and otherwise checks that they agree
        ti_runtime.init(threads=options.threads, precision=options.precision)
        # on a GPU always (numpy arguments would be copied at every launch, and a reused launch
        # context of copied arrays crashed Taichi 1.7.4); on the CPU where asked (its tests)
        self.on_device = (ti_runtime.settings()["arch"] == "cuda" or bool(device_arrays))
        kind = residency_kind(self.on_device)
        box = assemble(scenes, joints, gravity, options, kind.CHUNK_STEPS, kind.PROBE_SLOTS,
                       kind.probe_bodies)
        G = box.n_scenes
        self.n_scenes = G
        self.options = options
        self.model, self.state, self.contacts, self.control = \
            box.model, box.state, box.contacts, box.control
        self.skin = box.skin
        self.mode = kernel_mode(options.mode, self.on_device, self.model.n_bodies)
        self.step_size = StepSize(box.models, box.joints, self.model, options)
        sims = []
        for g in range(G):
            sim = views[g] if views is not None else Simulation.__new__(Simulation)
            sim._bind(self, g, box.scenes[g], box.models[g], box.joints[g], box.gravity[g])
            sims.append(sim)
        self.simulations = sims
        self.residency = kind(self.model, self.state, self.contacts, self.control,
                              device_broad_phase)
        self.launcher = Launcher(self, fast_launch, steps_per_launch)
        t0 = time.perf_counter()
        self.launcher.warm_up()
        self.compile_seconds = time.perf_counter() - t0
        patch = np.zeros(self.model.n_bodies)
        for g, sim in enumerate(sims):
            try:
                sim.rebuild()
                b0, b1 = self.model.scene_bodies[g]
                patch[b0:b1] = sim.check_initial_overlaps(options.overlap_tolerance)
            except (InputError, CapacityError) as err:
                self.fail(g, err)
        if not self.control.active.any():
            return  # every scene failed (a lone Simulation raises its failure): no step
        self.step_size.start(patch)
        for sim in sims:
            sim.clock.dt = self.clock.dt
            sim.energy_initial = sim.mechanical_energy()

    # ------------------------------------------------------------------------------------
    @property
    def dt(self) -> float:
        return self.step_size.clock.dt

    @property
    def clock(self) -> Clock:
        """The engine's clock: dt, dt_crit and the area caps (dem.engine.stepsize)."""
        return self.step_size.clock

    variants = property(lambda self: self.launcher.variants,
                        doc="the kernels' compile-time variants (launcher.KernelVariants)")
    n_chunks = property(lambda self: self.launcher.n_chunks, doc="chunks launched")

    def active(self, g: int) -> bool:
        return bool(self.control.active[g])

    def deactivate(self, g: int) -> None:
        """Freeze scene g (its run finished or failed): its bodies and pairs are skipped."""
        self.control.active[g] = 0

    def fail(self, g: int, err: Exception) -> None:
        """Scene g failed: it is frozen and keeps its failure (``simulations[g].failure``,
        raised by its Simulation.advance); the others go on."""
        self.simulations[g].failure = err
        self.deactivate(g)

    def adopt_dt(self, dt: float) -> None:
        """A scene restored from a restart point taken with ``dt``: the engine takes the smaller
        of the two steps (several scenes share one)."""
        self.step_size.adopt_dt(dt, self.simulations)

    def advance(self, n_steps: int, loads: list, on_chunk: Callable[[int], None] | None = None
                ) -> None:
        """Advance every active scene by n_steps steps, scene g with ``loads[g]`` (a LoadFn;
        ignored for a frozen scene).  A scene that fails (InstabilityError, CapacityError,
        SimulationError) is frozen in the state of its failing step, with its failure in
        ``simulations[g].failure``; the others go on (Simulation.advance raises it)."""
        self.launcher.advance(n_steps, loads, on_chunk)

    def n_pair_slots(self) -> int:
        """The pair slots the kernels loop over (Launcher.n_pair_slots)."""
        return self.launcher.n_pair_slots()

    # -- where the arrays live (dem.engine.residency) -----------------------------------------
    def containers(self) -> tuple:
        """The argpacks of (Model, State, Contacts, Control), as the kernels take them (the
        device's arrays for an engine on a device)."""
        return self.residency.containers()

    def host(self, name: str, write: bool = True, fields=None) -> None:
        """Make the host's ``name`` ("state" or "contacts") current before the host reads it,
        and, with ``write``, copy it to the device before the next launch
        (dem.engine.residency.DeviceResidency.host; nothing to do on the host alone)."""
        self.residency.host(name, write, fields)

    def host_scenes(self, name: str, fields, scenes) -> None:
        """Make the host's rows of the scenes ``scenes`` of ``fields`` (per-body fields of
        ``name``) current, to read them, and only those rows
        (dem.engine.residency.DeviceResidency.host_scenes; nothing to do on the host alone)."""
        self.residency.host_scenes(name, fields, scenes)

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
        counts = self.residency.transfer_counts()
        out = {}
        for key, way in ways.items():
            by = {name: {**c[way], "fields": dict(c[way]["fields"])}
                  for name, c in counts.items()}
            out[key] = {"copies": sum(v["copies"] for v in by.values()),
                        "bytes": sum(v["bytes"] for v in by.values()),
                        "seconds": sum(v["seconds"] for v in by.values()),
                        "by_container": by}
        out["install_pairs"] = self.residency.install_counts()
        out["chunks"] = self.n_chunks
        return out


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

    # the State fields the broad phase reads (rebuild): of its own scene only
    BROAD_PHASE_READS = ("pos", "rot", "quat")

    def __init__(self, scene: Scene, joints: JointLaw, options: StepOptions,
                 gravity=(0.0, 0.0, -9.81), fast_launch: bool = True):
        """An engine of this one scene; raises what the scene failed with while the engine
        was made (an overlap, a neighbour-list overflow, a fixed step above the bound)."""
        Engine([scene], [joints], options, [gravity], fast_launch, views=[self])
        if self.failure is not None:
            raise self.failure

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
        # this scene's slices of the engine's containers (the whole arrays for an engine of one)
        self._state = engine.state.region(self._b0, self._b1)
        self._contacts = engine.contacts.region(g, self._b0, self._b1)
        self.control = engine.control.region(g)
        self.clock = Clock()  # this scene's t (its anchors); dt is the engine's
        self._slot0 = g * engine.contacts.capacity
        self.dt_changes: list[dict] = []  # the changes of the time step (StepSize.set_dt)
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
    def contacts_on_host(self) -> Contacts:
        """This scene's Contacts as the host holds them, nothing copied: current only where
        Engine.host made them so (the broad phase's index arrays always are)."""
        return self._contacts

    def count_steps(self, done: int, deepest_step: int, dt: float) -> None:
        """After a launch that did ``done`` steps of ``dt``: the step count goes on; where the
        deepest penetration since t = 0 was reached in it (``deepest_step`` >= 0, the step of
        the launch), its time (the start of that step, as :attr:`t` counts it)."""
        if deepest_step >= 0:
            steps = self.step_count + deepest_step - self.clock.step_anchor
            self._deepest_time = self.clock.t_anchor + steps * dt
        self.step_count += done

    @property
    def contacts(self) -> Contacts:
        """This scene's Contacts, to read and write (on a device: as :attr:`state`).  To read
        only: :meth:`read_contacts`."""
        self.engine.host("contacts")
        return self._contacts

    @property
    def probe_capacity(self) -> int:
        """The most bodies a probe of this scene may list (control.probe_body's J: the
        residency's probe_bodies, dem.engine.residency)."""
        return int(self.engine.control.probe_body.shape[1])

    @property
    def frames_in_launches(self) -> bool:
        """Whether a run should take its frames inside the launches (a probe of every body,
        dem.run.record) rather than end its advance at each: on a device, where a chunk end
        costs a synchronisation and the host's per-chunk work, and the probe holds every body
        of the scene; on the host a chunk end costs nothing."""
        return self.engine.on_device and self.probe_capacity >= self._b1 - self._b0

    def set_probe(self, probe) -> None:
        """Copy some bodies' state at chosen steps inside a launch, without ending it (an
        instrument's samples, a device's frames: dem.run.record).  ``probe`` (None: none) has
        ``bodies`` (indices within this scene, at most :attr:`probe_capacity`), ``plan(clock,
        step, k)`` (the step counts in step + 1 ... step + k after which to copy, ascending,
        from this scene's Clock; called before each launch: it must not change the probe, as a
        launch may stop early) and ``take(step, t, rows)`` (called after the launch for each
        planned step it reached, in order; rows [bodies, 13]: pos, quat, vel, omega, as the
        state at that step count); optionally ``rows(step)``, the number of its first bodies
        that a planned step needs (take then gets those rows only), and ``flush()``, called
        once the next chunk's launches are queued and at an advance's end (take may keep its
        rows, copies, until then: Launcher.flush_probes)."""
        ctl = self.engine.control
        ctl.probe_body[self.scene_index] = -1
        self.probe = None
        if probe is None:
            return
        bodies = np.asarray(probe.bodies, dtype=int).reshape(-1)
        if len(bodies) > self.probe_capacity or (bodies < 0).any() or \
                (bodies >= self._b1 - self._b0).any():
            raise InputError(f"a probe takes at most {self.probe_capacity} bodies of the scene "
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
        :meth:`read_state`; the view also has ``n_pairs``.  The pair counts are current on the
        host after every launch; the index arrays (pairs, adj_ptr, adj) are copied only where
        the device's broad phase rewrote them (DeviceResidency.LISTS)."""
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
    @property
    def dt(self) -> float:
        """time step in use (s): the engine's"""
        return self.engine.clock.dt

    @dt.setter
    def dt(self, value: float) -> None:
        """A restart point's dt, set after its anchors (which count t in that step): the engine
        takes the smaller of it and its own (StepSize.adopt_dt: the other scenes are
        re-anchored, this one keeps its anchors); where the engine's is the smaller, this
        scene's clock is re-anchored at its present step, as at any change of dt."""
        value = float(value)
        step_size = self.engine.step_size
        self.clock.dt = value
        if value < step_size.dt:
            step_size.adopt_dt(value, [s for s in self.engine.simulations if s is not self])
        elif value > step_size.dt:
            self.clock.anchor(self.t, self.step_count)
        self.clock.dt = step_size.dt

    @property
    def dt_crit(self) -> float:
        """critical time step with the present area caps (s), the engine's"""
        return self.engine.clock.dt_crit

    @dt_crit.setter
    def dt_crit(self, value: float) -> None:
        """A restart point's dt_crit: the engine's is the smallest of its scenes' (the caps
        only rise, so a scene's saved one is at most the engine's at its start)."""
        clock = self.engine.clock
        clock.dt_crit = min(clock.dt_crit, float(value))

    # the clock's anchors under the names Simulation always had (restart points save them so)
    def _clock_field(name: str, doc: str):  # a helper of the class body, deleted below
        return property(lambda self: getattr(self.clock, name),
                        lambda self, v: setattr(self.clock, name, v), doc=doc)

    _t_anchor = _clock_field("t_anchor", "time at the last change of dt (s)")
    _step_anchor = _clock_field("step_anchor", "step count at the last change of dt")
    del _clock_field

    def _caps_field(name: str, doc: str):  # a helper of the class body, deleted below
        def get(self):  # this scene's rows of the engine's array (a view)
            return getattr(self.engine.clock, name)[self._b0:self._b1]

        def put(self, v):
            getattr(self.engine.clock, name)[self._b0:self._b1] = v
        return property(get, put, doc=doc)

    area_cap = _caps_field("area_cap", "per body, the capped contact area (m^2, inf: none)")
    _face_area = _caps_field("face_area", "per body and face, the areas in the bound (m^2)")
    del _caps_field

    # ------------------------------------------------------------------------------------
    def advance(self, n_steps: int, loads: LoadFn, on_chunk: Callable[[int], None] | None = None
                ) -> None:
        """Advance n_steps steps.  Raises InstabilityError / CapacityError / SimulationError on
        failure (the state is then that of the failing step).  Only while the other scenes of
        its engine are frozen (a lone scene: always): scenes that share an engine advance
        together, Engine.advance (the runs of a batch: dem.run.batched.drive_together)."""
        e = self.engine
        if self.failure is None:
            others = [g for g in np.flatnonzero(e.control.active) if g != self.scene_index]
            if others:
                raise RuntimeError("a scene of an engine with other active scenes advances "
                                   "with the others: Engine.advance, or the runs' one loop "
                                   "(dem.run.batched.drive_together)")
            e.advance(n_steps, [loads if g == self.scene_index else None
                                for g in range(e.n_scenes)], on_chunk)
        if self.failure is not None:
            raise self.failure

    def rebuild(self) -> None:
        """Broad phase of this scene: new neighbour list, history carried over for pairs that
        stay."""
        self.engine.host_scenes("state", self.BROAD_PHASE_READS, [self.scene_index])
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
        # the history carried over where it lives (dem.engine.residency)
        self.engine.residency.write_pairs(self.scene_index, c, pairs, m.n_bodies)
        c.ref_pos[...] = st.pos
        c.ref_quat[...] = st.quat
        self.n_rebuilds += 1

    def check_initial_overlaps(self, tolerance: float) -> np.ndarray:
        """Raise if two bodies overlap by more than ``tolerance`` at the start; returns each
        body's largest contact patch area (m^2) at the start."""
        self.engine.host("contacts", write=False, fields=("pairs",))
        c = self._contacts
        patch = np.zeros(self.model.n_bodies)
        n = c.n_pairs
        if n == 0:
            return patch
        depth = ti_nd_real(c.capacity)
        area = ti_nd_real(c.capacity)
        e = self.engine
        m, st, ca, _ = e.containers()
        stepk.probe_contacts(self._slot0, self._slot0 + n, depth, area, m, st, ca,
                             e.variants.warped, e.variants.batched)
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

    def closure_error(self, closure_limit: float) -> SimulationError | None:
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
        for name, box in self._boxes():  # the control's shared fields stay the engine's
            for k, a in box.arrays().items():
                if (name == "control" and k in Control.SHARED) or (name, k) in self.TRANSIENT:
                    continue
                a[...] = snap[f"{name}.{k}"]
        self.contacts.n_pairs = int(snap["contacts.n_pairs"])
        for k in self.EVOLVING:
            v = np.asarray(snap[f"sim.{k}"])
            setattr(self, k, v.copy() if v.ndim else v.item())
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

    def instability_error(self) -> InstabilityError:
        """The error of this scene's failing step (its status bits: NaN or too fast)."""
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
        return float(stepk.elastic_energy(self._slot0, self._slot0 + n, m, c,
                                          e.variants.hyperbolic, e.variants.batched))

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

