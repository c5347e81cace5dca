"""The host's time of a batched device run, per chunk and per step, by stage: what a GPU would
wait for between its kernels.

    python benchmarks/host_share.py --ks 16,64 --steps 600 --repeats 3
    python benchmarks/host_share.py --ks 16 --steps 300 --repeats 1 --phases shaking
    python benchmarks/host_share.py --summarise runs.jsonl    # the medians of saved runs
    python benchmarks/host_share.py --launch --ks 16,64       # one stepping launch's Python
    python benchmarks/host_share.py --clock cpu ...           # the thread's CPU time, not wall

The runs: K realisations of Model II shaken along y (benchmarks/batch_speed.py ``run``: the same
cases, ``case_of``) through dem.run.batched.run_cases_in_one_engine, as ``dem ensemble --batch``
runs them, with the engine's device arrays on the CPU (``device_arrays=True``: the host code a
GPU run executes, dem.engine.device and dem.engine.residency), on one Taichi thread, for
``--steps`` steps each (--max-steps), wall-clock checkpoints off.  Two phases:

  settling   the run as it starts: every scene settles (local damping, a look every 200 steps,
             the rebuilds of the blocks seating); ``batch_speed.py run`` measures this phase
  shaking    the load phase from step 0: the benchmark sets dem.run.settle.MAX_TIME to 0, so
             the shake starts from the built pose (as batch_speed.py ``cpu`` / ``cuda`` and the
             H100 kernel profile step it: the blocks seat while shaken, many rebuilds), with
             the frames every 0.02 s and the 500 Hz instruments (the probes) of the load phase

How the host's time is measured.  The host functions of a run are wrapped (in this process
only: the library is not changed) with a clock that charges each call's wall time to its stage,
less the time of the wrapped calls inside it (exclusive times; a stack); the run loop
(drive_together) is one, so every moment of the run between the engine's construction and the
loop's end is some stage's.  Every kernel launch in Taichi's C++ (``launch_kernel`` of Taichi's
program object: the stepping kernel's, the other kernels', the copies' from_numpy / to_numpy)
is the stage ``device work``: here the kernel runs inside it, on a GPU it queues the kernel (a
copy waits for the device).  The host's time is the sum of the other stages (the run loop's
time less ``device work``, less a run's start and end, below), less the clock's own cost
(measured: a wrapped empty call, times the wrapped calls).  So the Python of every launch stays
the host's: the stepping kernel's cached launch (dem/engine/launch.py: on a device a fresh
launch context a step, its 4 argpacks and 56 ndarray slots set) is ``step launch``, the other
kernels' argument handling is each ``kernel NAME``.  What this leaves out of the host's time,
and a GPU would add: the launches' own C++ and driver time (``device_launches_per_step`` /
``_per_chunk`` count them) and the waits of the copies for the device.  ``--clock cpu``: the
stages read the CPU time of the process's thread instead of the wall (the kernels run on
Taichi's worker thread, so ``device work`` is then ~0, and the host's stages no longer count
the waits of a machine shared with other processes: the figure to compare two versions on such
a machine).  ``--launch``: the Python of one stepping launch, and its parts, apart from a run.

What a GPU waits for.  On CUDA a stepping launch only queues its kernels: Taichi 1.7.4's
launcher (taichi/runtime/cuda/kernel_launcher.cpp) copies the argument buffer asynchronously
and waits for the device only where a host array is an argument or the kernel returns a value,
neither of which the cached launch has (dem/engine/launch.py), so the host prepares the next
launch while the GPU runs the earlier ones.  A chunk's launches then cost the GPU nothing as
long as the host's time of a launch (its Python, ``launch_ms_per_step`` here, and its C++ and
driver time, not measured here) stays under the kernels' time of its steps; the host's time
between the chunks' launches (``between_launches_ms_per_step``: the loads, the copies, the
probes, the run loop) is what the GPU waits for where it falls in the *window* from a chunk's
end (``from_device``: the diagnostics' copy waits for the device) to the next chunk's first
stepping launch (``window_ms_per_step``: the host's stages in that window, the clock's cost
out; ``window_stage_ms_per_chunk``: by stage); the host's work after a chunk's launches and before its end (the next chunk's loads,
dem.engine.launcher.Launcher.write_loads) runs while the GPU still has that chunk's kernels
queued.  ``waited_share`` is the window's time against the H100's kernels, an estimate as the
other.

Stages (a stage is the time of these calls, less the wrapped calls inside them):

  loads            the scenes' load functions (each scene's loading at the chunk's step times)
  clocks           Clock.times, Simulation.count_steps
  launch           Launcher.launch: the loads into control.loads, the diagnostics reset, the
                   variants' check, the pair slots, the steps counted
  chunk loop       Launcher.advance: the status read, failures, rebuild and closure loops
  probes plan      Launcher.plan_probes (LaunchProbe.plan: the samples and frames in launches)
  probes take      Launcher.take_probes (LaunchProbe.take: the samples' and frames' rows
                   copied, the next ones booked)
  probes record    Launcher.flush_probes (LaunchProbe.flush: the last chunk's samples and
                   frames recorded, once the next chunk's launches are queued)
  to_device        DeviceResidency.to_device (ChunkCopies.push_chunk, changed Control fields,
                   dirty State / Contacts fields)
  from_device      DeviceResidency.from_device (ChunkCopies.pull_diagnostics), pull_probes
  rebuild poses    DeviceResidency.host_scenes (the rebuilding scenes' poses gathered, copied)
  broad phase      dem.engine.broadphase.candidate_pairs (cKDTree and the boxes' test)
  install          DeviceResidency.write_pairs (pair_lists, install_pairs)
  rebuild          Simulation.rebuild, the rest (capacity check, reference poses)
  caps check       StepSize.check_caps (the caps' count on the device)
  host reads       DeviceResidency.host (the fields a frame, a look, an energy reads)
  frames           Recording.start / after_advance / frame_at_stop (frames, listeners)
  settling looks   dem.run.settle.settle_steps between its advances (speeds, the
                   unbalanced-force ratio, the energy report)
  run loop         dem.run.batched.drive_together (requests, resumes), Engine.advance
  run_case_steps   each point's run (dem.run.loop.run_case_steps, in dem.run.batched's body)
                   between its advances (progress, checkpoints, stop rule); a run's start (up to its first request: building, the first
                   frame, settling's set-up) and end (its summary and files) are once a run,
                   not a chunk's work: "run start" / "run end" (the point's record and its
                   summary.json's batch stamp included), printed apart, not in the host's time
  step launch      the stepping kernel's launches (dem.engine.launch.CachedLaunch), their Python
  kernel NAME      the other kernels the host launches, their Python, each apart (AUX_KERNELS:
                   unpack_chunk, pack_diagnostics, install_pairs, gather_scene_rows,
                   patches_over_caps, gather_probe_rows, probe_contacts, elastic_energy)

Per (phase, K) the medians over ``--repeats`` runs (each a fresh engine; its construction left
out): the host's ms per chunk and per step, each stage's, and the implied host share of a step
against the H100's kernels: ``H100_KERNEL_STEP_MS`` (0.135 ms of kernels per step of 64 Model II
scenes, results/batched-engine/README.md, kernel profile) at K = 64.  That share is an
*estimate from this CPU's Python speed*: the GPU machine's host CPU runs the same Python at its
own speed (a 16-core Xeon; not measured here).  A digest of every point's frames and
instruments (batch_speed.digest) is printed: a change that keeps the outputs keeps it.
Prints one JSON line per run and per (phase, K) (``--json FILE`` appends them).
"""

import argparse
import json
import os
import shutil
import sys
import tempfile
import time
from collections import defaultdict
from pathlib import Path

import numpy as np
from batch_speed import case_of, digest, emit  # benchmarks/ is first on sys.path

ROOT = Path(__file__).resolve().parents[1]
sys.path.insert(0, str(ROOT))

# the H100's kernels of one step of 64 Model II scenes (results/batched-engine/README.md, "Where
# a GPU step goes": Taichi's kernel profiler, the pair loop, body loop and serial tasks)
H100_KERNEL_STEP_MS = 0.135
# the target: the host's share of a step at K = 64 below this fraction of the GPU step
TARGET_SHARE = 0.10

# a run's start (build, first frame, settling's set-up) and end (its summary and files written):
# once a run, not a chunk's or a frame's work; reported apart, not in the host's time
ONE_OFF = ("run start", "run end")
# the window a GPU waits for the host (module docstring): it opens where a chunk's end waits for
# the device (the diagnostics' copy) and closes at the next chunk's first stepping launch
WINDOW_OPENS, WINDOW_CLOSES = "from_device", "step launch"
_WINDOW_MARK = ("window",)  # a key of a mark of StageClock.seconds that no stage has
# the kernels the host launches beside the stepping kernel (dem.engine.device, dem.engine.step)
AUX_KERNELS = ("unpack_chunk", "pack_diagnostics", "install_pairs", "gather_scene_rows",
               "patches_over_caps", "gather_probe_rows", "probe_contacts", "elastic_energy")
DEVICE_KERNELS = 6  # the first of AUX_KERNELS are dem.engine.device's, the rest dem.engine.step's
# the warm-up run of each phase (not timed): every kernel of a run loaded, rebuilds included
WARM_K, WARM_STEPS = 4, 600
STAGE_ORDER = ("step launch", "loads", "clocks", "launch", "chunk loop", "probes plan",
               "probes take", "probes record", "to_device", "from_device", "rebuild poses",
               "broad phase", "install", "rebuild", "caps check", "host reads", "frames",
               "settling looks", "run loop", "run_case_steps") + \
    tuple(f"kernel {k}" for k in AUX_KERNELS)


# the clocks a StageClock reads: the wall (what a GPU waits for), or the CPU time of the
# calling thread (what the host's Python costs, less the waits of a machine shared with others)
CLOCKS = {"wall": time.perf_counter, "cpu": time.thread_time}


class StageClock:
    """Exclusive time per stage: a call's time less that of the wrapped calls inside it (a
    stack of [stage, start]); ``now``: the clock read (CLOCKS)."""

    def __init__(self, now=time.perf_counter):
        self.now = now
        self.stack: list[list] = []
        self.seconds: dict[str, float] = defaultdict(float)
        self.calls: dict[str, int] = defaultdict(int)
        # the host's time in the window a GPU waits (module docstring): from a chunk's end
        # (WINDOW_OPENS) to the next stepping launch (WINDOW_CLOSES), and its wrapped calls
        self.window_open = False
        self.window_s = 0.0
        self.window_calls = 0
        self.window_by_stage: dict[str, float] = defaultdict(float)  # the window's, by stage

    def _charge(self, stage: str, seconds: float) -> None:
        self.seconds[stage] += seconds
        if self.window_open and stage not in ONE_OFF and stage != "device work":
            self.window_s += seconds
            self.window_by_stage[stage] += seconds

    def enter(self, stage: str) -> None:
        t = self.now()
        if self.stack:
            top = self.stack[-1]
            self._charge(top[0], t - top[1])
            if top[0] in ONE_OFF:  # a run's start or end: everything inside is charged to it
                stage = top[0]
        if stage == WINDOW_OPENS:
            self.window_open = True
        elif stage == WINDOW_CLOSES:
            self.window_open = False
        self.window_calls += self.window_open
        self.stack.append([stage, t])
        self.calls[stage] += 1

    def leave(self) -> None:
        t = self.now()
        stage, t0 = self.stack.pop()
        self._charge(stage, t - t0)
        if self.stack:
            self.stack[-1][1] = t

    def timed(self, fn, stage: str):
        """``fn`` with its calls charged to ``stage``."""
        def wrapped(*args, **kwargs):
            self.enter(stage)
            try:
                return fn(*args, **kwargs)
            finally:
                self.leave()
        wrapped.__wrapped__ = fn
        return wrapped

    def timed_steps(self, gen_fn, stage: str, ends: bool = False):
        """A generator function (a steppable run or phase, dem.run.steps) whose work between
        its yields is charged to ``stage`` (what it yields, and what is sent or thrown into
        it, passed through).  ``ends``: its start (up to its first request) and its end (after
        its last) are charged to ONE_OFF's stages with everything inside them, apart from the
        per-chunk and per-frame work between (the end is known once it has come: that
        segment's times are moved there)."""
        def wrapped(*args, **kwargs):
            return (yield from self.timed_generator(gen_fn(*args, **kwargs), stage, ends))
        return wrapped

    def timed_generator(self, it, stage: str, ends: bool = False):
        """The generator ``it`` as :meth:`timed_steps` times a generator function's."""
        err = None
        first = True
        while True:
            mark = None
            if ends and not first:  # the stages' times and the window's, as they were
                mark = dict(self.seconds)
                mark[_WINDOW_MARK] = (self.window_s, self.window_calls,
                                      dict(self.window_by_stage))
            self.enter("run start" if ends and first else stage)
            try:
                req = it.send(None) if err is None else it.throw(err)
            except BaseException as exc:  # noqa: BLE001 - the run's end, passed on
                self.leave()
                if mark is not None:
                    self.to_end(mark)
                if isinstance(exc, StopIteration):
                    return exc.value
                raise
            self.leave()
            first = False
            try:
                yield req
            except BaseException as exc:  # noqa: BLE001 - thrown on into the run
                err = exc
            else:
                err = None

    def to_end(self, mark: dict) -> None:
        """Every stage's time since ``mark`` (a copy of :attr:`seconds`) moved to "run end",
        and out of the window's (a run's end is once a run, as its start)."""
        for name in list(self.seconds):
            if name != "run end":
                extra = self.seconds[name] - mark.get(name, 0.0)
                self.seconds[name] -= extra
                self.seconds["run end"] += extra
        self.window_s, self.window_calls, by_stage = mark[_WINDOW_MARK]
        self.window_by_stage = defaultdict(float, by_stage)

    def overhead_s(self, n: int = 20000) -> float:
        """The clock's own cost of one wrapped call (s), measured on an empty function."""
        probe = StageClock(self.now)
        f = probe.timed(lambda: None, "x")
        probe.enter("outer")
        t0 = self.now()
        for _ in range(n):
            f()
        dt = self.now() - t0
        probe.leave()
        t0 = self.now()
        for _ in range(n):
            (lambda: None)()
        return max(0.0, (dt - (self.now() - t0)) / n)


class Patches:
    """Attributes set for a run and put back after it."""

    def __init__(self):
        self.saved: list[tuple] = []

    def set(self, owner, name: str, value) -> None:
        self.saved.append((owner, name, owner.__dict__.get(name, _ABSENT)
                           if isinstance(owner, type) else getattr(owner, name)))
        setattr(owner, name, value)

    def undo(self) -> None:
        for owner, name, old in reversed(self.saved):
            if old is _ABSENT:
                delattr(owner, name)
            else:
                setattr(owner, name, old)
        self.saved.clear()


_ABSENT = object()


def instrument(clock: StageClock) -> Patches:
    """Wrap the host functions of a batched run with ``clock`` (module docstring's stages)."""
    import dem.engine.device as device
    import dem.engine.simulation as simulation
    import dem.engine.step as stepk
    import dem.run.batched as batched
    import dem.run.loop as loop
    from dem.engine.launcher import Launcher
    from dem.engine.residency import DeviceResidency
    from dem.engine.simulation import Engine, Simulation
    from dem.engine.stepsize import StepSize
    from dem.engine.timestep import Clock
    from dem.run.record import Recording
    from taichi.lang import impl

    p = Patches()
    methods = [
        (Launcher, "advance", "chunk loop"), (Launcher, "launch", "launch"),
        (Launcher, "plan_probes", "probes plan"), (Launcher, "take_probes", "probes take"),
        (Launcher, "flush_probes", "probes record"),
        (DeviceResidency, "to_device", "to_device"),
        (DeviceResidency, "from_device", "from_device"),
        (DeviceResidency, "pull_probes", "from_device"),
        (DeviceResidency, "host_scenes", "rebuild poses"),
        (DeviceResidency, "write_pairs", "install"), (DeviceResidency, "host", "host reads"),
        (Simulation, "rebuild", "rebuild"), (Simulation, "count_steps", "clocks"),
        (Clock, "times", "clocks"), (StepSize, "check_caps", "caps check"),
        (Recording, "start", "frames"), (Recording, "after_advance", "frames"),
        (Recording, "frame_at_stop", "frames"),
    ]
    for owner, name, stage in methods:
        p.set(owner, name, clock.timed(getattr(owner, name), stage))
    p.set(simulation, "candidate_pairs", clock.timed(simulation.candidate_pairs, "broad phase"))
    for name in AUX_KERNELS[:DEVICE_KERNELS]:
        p.set(device, name, clock.timed(getattr(device, name), f"kernel {name}"))
    for name in AUX_KERNELS[DEVICE_KERNELS:]:
        p.set(stepk, name, clock.timed(getattr(stepk, name), f"kernel {name}"))
    p.set(loop, "settle_steps", clock.timed_steps(loop.settle_steps, "settling looks"))
    drive_together = batched.drive_together

    def drive_timed(engine, bodies):  # each point's whole run, its start and end apart
        bodies = [clock.timed_generator(b, "run_case_steps", ends=True) for b in bodies]
        return clock.timed(drive_together, "run loop")(engine, bodies)
    p.set(batched, "drive_together", drive_timed)

    # every kernel's launch in Taichi's C++ (the stepping kernel's, the others', the copies'
    # from_numpy / to_numpy): the stage "device work", apart from the Python around it
    runtime = impl.get_runtime()
    p.set(runtime, "prog", DeviceWork(runtime.prog, clock))

    record_launch = Launcher.record_launch

    def record_and_time(self):  # the stepping kernel's launches (their Python): "step launch"
        record_launch(self)
        self.kernel = clock.timed(self.kernel, "step launch")
    p.set(Launcher, "record_launch", record_and_time)

    advance = Engine.advance

    def advance_timing_loads(self, n_steps, loads, on_chunk=None):
        loads = [None if f is None else clock.timed(f, "loads") for f in loads]
        clock.enter("run loop")
        try:
            return advance(self, n_steps, loads, on_chunk)
        finally:
            clock.leave()
    p.set(Engine, "advance", advance_timing_loads)
    return p


class DeviceWork:
    """Stands in for Taichi's program object (as dem.engine.launch's recorder does): its
    ``launch_kernel`` (Taichi's C++ launch: here the kernel runs in it, on a GPU it queues the
    kernel, and a copy's waits for the device) charged to the stage "device work"."""

    def __init__(self, prog, clock: StageClock):
        self._prog = prog
        self._launch = clock.timed(prog.launch_kernel, "device work")

    def __getattr__(self, name):
        return getattr(self._prog, name)

    def launch_kernel(self, compiled, ctx):
        return self._launch(compiled, ctx)


def launch_parts(k: int, n: int = 3000) -> dict:
    """The Python of one cached launch of the stepping kernel (dem.engine.launch.CachedLaunch)
    of an engine of k Model II scenes on the device path, its C++ launch stubbed (us, medians
    of 5 x ``n`` calls): the whole, and its parts: a fresh launch context, the argpacks, the
    ndarray slots (the counts with them); and the whole after a 64 MB memory sweep each (the
    median of 300: the caches emptied, as a kernel running on the CPU between two launches
    empties them and a kernel on a GPU does not)."""
    from batch_speed import build

    engine, _ = build(k, "parallel", True)
    launch = engine.launcher.kernel
    if not launch.device_arrays:
        raise SystemExit("the stepping kernel's launch is not cached with device arrays here")

    def per_call_us(f) -> float:
        times = []
        for _ in range(5):
            t0 = time.perf_counter()
            for _ in range(n):
                f()
            times.append((time.perf_counter() - t0) / n)
        return 1e6 * float(np.median(times))

    class NoLaunch:
        def launch_kernel(self, compiled, ctx):
            pass

    # a kernel's memory traffic between two launches, as in a run on the CPU: a sweep of 64 MB
    # (more than this machine's caches) before each timed launch
    sweep = np.ones(8 * 1024 * 1024)

    def after_sweep_us(m: int = 300) -> float:
        times = []
        for _ in range(m):
            sweep.sum()
            t0 = time.perf_counter()
            launch(-2, 0, 1e-5)
            times.append(time.perf_counter() - t0)
        return 1e6 * float(np.median(times))

    real, launch.prog = launch.prog, NoLaunch()
    try:
        whole = per_call_us(lambda: launch(-2, 0, 1e-5))
        swept = after_sweep_us()
    finally:
        launch.prog = real
    ctx = launch.t_kernel.make_launch_context()

    def packs():
        for slot, pack in launch.argpacks:
            ctx.set_arg_argpack(slot, pack)

    def arrays():
        for slot, arr in launch.device_arrays:
            ctx.set_arg_ndarray(slot, arr)

    return {"launch": True, "K": k, "python_per_launch_us": whole,
            "python_per_launch_after_64MB_sweep_us": swept,
            "make_launch_context_us": per_call_us(launch.t_kernel.make_launch_context),
            "argpacks": len(launch.argpacks), "argpacks_us": per_call_us(packs),
            "ndarray_slots": len(launch.device_arrays), "ndarray_slots_us": per_call_us(arrays)}


def one_run(k: int, steps: int, phase: str, out_root: Path, clock_name: str = "wall") -> dict:
    """One batched run of realisations 0..k-1 in ``phase`` (module docstring); its stages."""
    import dem.run.settle
    import dem.run.write
    from dem.run.batched import run_cases_in_one_engine

    dem.run.write.CHECKPOINT_SECONDS = float("inf")  # counts per step, not per wall second
    max_time = dem.run.settle.MAX_TIME
    if phase == "shaking":
        dem.run.settle.MAX_TIME = 0.0  # the load phase from step 0 (module docstring)
    cases = [(f"seed{s}", case_of(s)) for s in range(k)]
    dirs = [out_root / f"{phase}-K{k}" / name for name, _ in cases]
    clock = StageClock(CLOCKS[clock_name])
    held: dict = {}

    def on_engine(engine) -> None:  # the construction is left out
        held["engine"] = engine
        held["chunks0"] = engine.n_chunks
        held["launches0"] = engine.launcher.n_launches
        clock.seconds.clear()
        clock.calls.clear()
        clock.window_open, clock.window_s, clock.window_calls = False, 0.0, 0
        clock.window_by_stage.clear()
        held["t"] = clock.now()

    patches = instrument(clock)
    try:
        records = run_cases_in_one_engine(cases, dirs, max_steps=steps, resume=False,
                                          threads=1, device_arrays=True, on_engine=on_engine)
        t1 = clock.now()
    finally:
        patches.undo()
        dem.run.settle.MAX_TIME = max_time
    if "engine" not in held:
        raise SystemExit(f"K={k}: no engine was built: "
                         f"{[(r.get('status'), r.get('error')) for r in records]}")
    engine = held["engine"]
    wall = t1 - held["t"]
    chunks = engine.n_chunks - held["chunks0"]
    summaries = [r.get("summary") or {} for r in records]
    seconds = dict(clock.seconds)
    calls = dict(clock.calls)
    kernel = seconds.pop("device work", 0.0)
    kernel_calls = calls.pop("device work", 0)
    wrapped = sum(calls.values()) + kernel_calls
    return {"phase": phase, "K": k, "steps": steps, "clock": clock_name, "chunks": chunks,
            "wall_s": wall,
            "device_s": kernel, "device_launches": kernel_calls, "wrapped_calls": wrapped,
            "stage_s": seconds, "stage_calls": calls,
            "window_s": clock.window_s, "window_calls": clock.window_calls,
            "window_stage_s": dict(clock.window_by_stage),
            "rebuilds": sum(s.n_rebuilds for s in engine.simulations),
            "steps_per_launch": engine.launcher.variants.device_steps,
            "stepping_launches": engine.launcher.n_launches - held["launches0"],
            "status": sorted({r["status"] for r in records}),
            "steps_done": sorted({s.get("steps") for s in summaries}, key=str),
            "digests": [digest(d) for d in dirs]}


def summarise(runs: list[dict], clock_cost_s: float) -> dict:
    """The medians over the repeats of one (phase, K)."""
    first = runs[0]
    k, steps = first["K"], first["steps"]

    def med(values):
        return float(np.median(values))

    host = [sum(v for s, v in r["stage_s"].items() if s not in ONE_OFF)
            - r["wrapped_calls"] * clock_cost_s for r in runs]
    # after the run loop: the points' records, their directories' locks released (once a run)
    after = [r["wall_s"] - r["device_s"] - sum(r["stage_s"].values()) for r in runs]
    stages = {s: med([r["stage_s"].get(s, 0.0) for r in runs]) for s in STAGE_ORDER}
    other = sorted(set().union(*(r["stage_s"] for r in runs)) - set(STAGE_ORDER) - set(ONE_OFF))
    stages.update({s: med([r["stage_s"].get(s, 0.0) for r in runs]) for s in other})
    chunks = med([r["chunks"] for r in runs])
    host_s = med(host)
    step_ms = 1e3 * host_s / steps
    rec = {"summary": True, "phase": first["phase"], "K": k, "steps": steps,
           "clock": first.get("clock", "wall"),
           "repeats": len(runs), "chunks": chunks, "rebuilds": med([r["rebuilds"] for r in runs]),
           "wall_s": med([r["wall_s"] for r in runs]), "device_s": med([r["device_s"] for r in runs]),
           "host_s": host_s, "host_s_each": host, "clock_cost_us": 1e6 * clock_cost_s,
           "host_ms_per_chunk": 1e3 * host_s / chunks, "host_ms_per_step": step_ms,
           "device_ms_per_step_here": 1e3 * med([r["device_s"] for r in runs]) / steps,
           "device_launches_per_step": med([r["device_launches"] for r in runs]) / steps,
           "device_launches_per_chunk": med([r["device_launches"] for r in runs]) / chunks,
           "steps_per_launch": first.get("steps_per_launch"),
           "stepping_launches_per_step": med([r.get("stepping_launches", 0) for r in runs])
           / steps,
           "one_off_s_per_run": {**{s: med([r["stage_s"].get(s, 0.0) for r in runs])
                                    for s in ONE_OFF}, "after the run loop": med(after)},
           "stage_ms_per_step": {s: 1e3 * v / steps for s, v in stages.items()},
           "stage_ms_per_chunk": {s: 1e3 * v / chunks for s, v in stages.items()},
           "stage_calls_per_chunk": {s: med([r["stage_calls"].get(s, 0) for r in runs]) / chunks
                                     for s in stages},
           "digests_equal_across_repeats": all(r["digests"] == first["digests"] for r in runs),
           "digests": first["digests"]}
    # the stepping launches' Python (their wrappers' clock cost out) and the rest of the
    # host's time: the work between a chunk's last launch and the next chunk's first
    launch_s = med([r["stage_s"].get("step launch", 0.0)
                    - r["stage_calls"].get("step launch", 0) * clock_cost_s for r in runs])
    rec["launch_ms_per_step"] = 1e3 * launch_s / steps
    rec["between_launches_ms_per_step"] = step_ms - rec["launch_ms_per_step"]
    # the host's time from a chunk's end to the next chunk's first launch (the window)
    window_s = med([r.get("window_s", 0.0) - r.get("window_calls", 0) * clock_cost_s
                    for r in runs])
    rec["window_ms_per_step"] = 1e3 * window_s / steps
    # the window's time by stage, ms a chunk (the clock's cost not taken out: a few calls each)
    in_window = set().union(*(r.get("window_stage_s", {}) for r in runs))
    rec["window_stage_ms_per_chunk"] = {
        st: 1e3 * med([r.get("window_stage_s", {}).get(st, 0.0) for r in runs]) / chunks
        for st in sorted(in_window)}
    if k == 64:
        host_step = step_ms
        window = rec["window_ms_per_step"]
        rec["h100_estimate"] = {
            "kernel_step_ms": H100_KERNEL_STEP_MS, "host_ms_per_step": host_step,
            "host_share_of_gpu_step": host_step / H100_KERNEL_STEP_MS,
            "launch_ms_per_step": rec["launch_ms_per_step"],
            "between_launches_ms_per_step": rec["between_launches_ms_per_step"],
            "window_ms_per_step": window,
            "waited_share_of_gpu_step": window / H100_KERNEL_STEP_MS,
            "target_share": TARGET_SHARE,
            "note": "an estimate from this CPU's Python speed (the host's ms per step here, "
                    "the launches' own C++ and driver time not included) against the H100's "
                    "kernel time of a step; waited: the host's time in the window from a "
                    "chunk's end to the next chunk's first launch only, what a GPU waits for "
                    "where the stepping launches queue asynchronously and their host time a "
                    "step stays under the kernels' (module docstring)"}
    return rec


def print_table(rec: dict) -> None:
    print(f"\n{rec['phase']}, K = {rec['K']} ({rec['clock']} clock): {rec['steps']} steps, "
          f"{rec['chunks']:.0f} chunks, {rec.get('steps_per_launch')} steps a launch "
          f"({rec.get('stepping_launches_per_step', 0):.3f} stepping launches a step), "
          f"{rec['rebuilds']:.0f} rebuilds; median of {rec['repeats']}: wall {rec['wall_s']:.2f}"
          f" s, device work {rec['device_s']:.2f} s, host {rec['host_s']:.3f} s = "
          f"{rec['host_ms_per_chunk']:.3f} ms/chunk, {rec['host_ms_per_step']:.4f} ms/step "
          f"({rec['device_launches_per_chunk']:.1f} launches/chunk); left out: "
          + ", ".join(f"{k} {v:.2f} s" for k, v in rec["one_off_s_per_run"].items()))
    print(f"  {'stage':<16} {'ms/step':>9} {'ms/chunk':>9} {'calls/chunk':>11}")
    for s, v in sorted(rec["stage_ms_per_step"].items(), key=lambda sv: -sv[1]):
        print(f"  {s:<16} {v:9.4f} {rec['stage_ms_per_chunk'][s]:9.4f} "
              f"{rec['stage_calls_per_chunk'][s]:11.1f}")
    if "h100_estimate" in rec:
        h = rec["h100_estimate"]
        print(f"  H100 estimate: host {h['host_ms_per_step']:.4f} ms/step against "
              f"{h['kernel_step_ms']} ms of kernels: host share {100 * h['host_share_of_gpu_step']:.0f} %"
              f" (target < {100 * h['target_share']:.0f} %; from this CPU's Python speed)")
        print(f"  of which the stepping launches' Python {h['launch_ms_per_step']:.4f} ms/step "
              f"(queued on a GPU while earlier kernels run) and the rest "
              f"{h['between_launches_ms_per_step']:.4f} ms/step, "
              f"{h['window_ms_per_step']:.4f} ms/step of it from a chunk's end to the next "
              f"chunk's first launch: what a GPU waits for, "
              f"{100 * h['waited_share_of_gpu_step']:.0f} % of its step")
    if rec.get("window_stage_ms_per_chunk"):
        print("  the window by stage, ms a chunk: " + ", ".join(
            f"{st} {v:.2f}" for st, v in sorted(rec["window_stage_ms_per_chunk"].items(),
                                                 key=lambda sv: -sv[1]) if v >= 0.005))
    print(f"  digests: {rec['digests']} (equal across repeats: "
          f"{rec['digests_equal_across_repeats']})", flush=True)


def main() -> int:
    ap = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    ap.add_argument("--ks", default="16,64")
    ap.add_argument("--steps", type=int, default=600)
    ap.add_argument("--repeats", type=int, default=3)
    ap.add_argument("--phases", default="settling,shaking")
    ap.add_argument("--json", default=None)
    ap.add_argument("--clock", choices=sorted(CLOCKS), default="wall",
                    help="the stages' clock: wall (default), or cpu: the CPU time of the "
                         "process's thread (less the machine's other load; wall_s is then that "
                         "clock's too)")
    ap.add_argument("--steps-per-launch", type=int, default=None,
                    help="the device's stepping kernel's steps a launch (DEM_STEPS_PER_LAUNCH; "
                         "default: dem.engine.step_device's, 1 on the CPU)")
    ap.add_argument("--launch", action="store_true",
                    help="no runs: the Python of one cached launch of the stepping kernel and "
                         "its parts, for each K (launch_parts)")
    ap.add_argument("--summarise", default=None, metavar="FILE",
                    help="no runs: the medians of the runs' JSON lines in FILE (an earlier "
                         "--json), by phase and K")
    args = ap.parse_args()
    if args.summarise:
        runs = [json.loads(line) for line in Path(args.summarise).read_text().splitlines()
                if line.strip()]
        runs = [r for r in runs if not r.get("summary")]
        costs = {name: StageClock(now).overhead_s() for name, now in CLOCKS.items()}
        for key in dict.fromkeys((r["phase"], r["K"]) for r in runs):
            clock_cost = costs[next(r.get("clock", "wall") for r in runs
                                    if (r["phase"], r["K"]) == key)]
            rec = summarise([r for r in runs if (r["phase"], r["K"]) == key], clock_cost)
            emit(rec, args.json)
            print_table(rec)
        return 0
    if args.steps_per_launch is not None:
        os.environ["DEM_STEPS_PER_LAUNCH"] = str(args.steps_per_launch)
    phases = args.phases.split(",")
    bad = set(phases) - {"settling", "shaking"}
    if bad:
        ap.error(f"--phases: unknown {sorted(bad)} (settling, shaking)")
    from dem import ti_runtime

    ti_runtime.init(threads=1, arch="cpu")  # before the runs: instrument() wraps its program
    if args.launch:
        for k in [int(x) for x in args.ks.split(",")]:
            emit(launch_parts(k), args.json)
        return 0
    root = Path(tempfile.mkdtemp(prefix="host-share-"))
    clock_cost = StageClock(CLOCKS[args.clock]).overhead_s()
    try:
        for phase in phases:  # Taichi's kernels loaded (offline cache) before any timing
            one_run(WARM_K, WARM_STEPS, phase, root, args.clock)
        for k in [int(x) for x in args.ks.split(",")]:
            for phase in phases:
                runs = []
                for _ in range(args.repeats):
                    run = one_run(k, args.steps, phase, root, args.clock)
                    emit(run, args.json)
                    runs.append(run)
                rec = summarise(runs, clock_cost)
                emit(rec, args.json)
                print_table(rec)
    finally:
        shutil.rmtree(root, ignore_errors=True)
    return 0


if __name__ == "__main__":
    sys.exit(main())
