"""Run K cases in one engine: the points of a sweep or the realisations of an ensemble
side by side in one dem.engine.simulation.Engine, each written into its own run directory exactly as a lone
run (dem.run.loop.run_case) writes it.

    records = run_cases_in_one_engine([(name, case), ...], [out_dir, ...], max_steps=None)

How it runs.  Each point's run is the run loop as a generator
(dem.run.loop.run_case_steps, dem.run.steps): it yields a request "advance my scene by n steps
under my loads" and goes on when that is done.  One loop (:func:`drive_together`) drives the K
generators over one engine: it runs each point up to its next request, then advances the whole
engine by the smallest request of those waiting (``engine.advance(m, loads)``: each scene with
its own loads), and resumes in turn (in index order: the run is deterministic) each point whose
request is complete, or whose scene failed: that point gets its failure (``sims[g].failure``)
raised at its request, its run loop writes the failed run as a lone run does, and its
batch-mates go on.  A point that ended (finished or failed) is deactivated
(``engine.deactivate(g)``: its bodies stop, it costs ~0).  No threads: Taichi and a CUDA context
see one thread, as in a lone run.

Stopping.  dem.signals' handlers run in the main thread, where everything runs.  The stop
signals are held (dem.signals.deferred) while the loop runs, so that a stop never cuts the
bookkeeping of requests in half: a point sees a stop at its run loop's next look
(dem.signals.raise_if_stopped) and the loop between two advances of the engine; then every
point gets dem.signals.Interrupted raised at its request, in turn, so each run ends
``interrupted`` with its last frame and its restart point (the one of its last checkpoint, as a
lone run), and the KeyboardInterrupt is raised again in the caller.  A point that stops by
itself (a KeyboardInterrupt out of its run) stops the whole batch the same way.

Resuming works per point: a point whose directory holds a usable restart point goes on from it
(run_case(resume=True) restores its Simulation), the others start fresh.

Each point's summary.json gains ``batch``: ``n_scenes`` (K), ``index`` (g, from 0), ``dt_s``
(the engine's time step, the smallest critical step of its scenes times the safety factor, s)
and ``arch`` (Taichi's arch: cpu or cuda).
"""

from __future__ import annotations

import json
import os
import threading
import time
import traceback
from pathlib import Path
from typing import Callable, Sequence

import numpy as np

from dem.case import Case

ARCHS = ("cpu", "cuda")

BATCH_NOTE = ("this run shared one engine and one process with n_scenes - 1 others: its "
              "wall_seconds (from the batch's start), cpu_seconds (the process's) and "
              "brick_steps_per_second (its own brick-steps over that wall time) are the "
              "batch's, not a lone run's; engine_seconds: the engine's construction (compile "
              "included), counted in wall_seconds")


class BatchInputError(ValueError):
    """Cases that cannot share one engine, or a bad --batch / --arch; the message names the
    field or option."""


class CudaUnavailable(BatchInputError):
    """--arch cuda where Taichi finds no CUDA device (or the engine cannot run on one): exit
    code 2, like a bad option (nothing ran)."""


# ---------------------------------------------------------------------------------------------
# checks and Taichi's arch
# ---------------------------------------------------------------------------------------------
def check_arch(arch: str) -> None:
    """Raise BatchInputError for an arch that is not cpu / cuda, CudaUnavailable for cuda on a
    machine where Taichi finds no CUDA driver (without starting Taichi: cheap, for a command to
    refuse before any worker starts)."""
    if arch not in ARCHS:
        raise BatchInputError(f"--arch must be one of {', '.join(ARCHS)}, got '{arch}'")
    if arch == "cuda" and not cuda_present():
        raise CudaUnavailable("--arch cuda: CUDA was asked for and is not available (Taichi "
                              "finds no CUDA driver on this machine); use --arch cpu")


def cuda_present() -> bool:
    """Whether Taichi is built with CUDA and finds the driver.  The driver library is looked for
    first (ctypes: no Taichi, no message where there is none); where it loads, Taichi's
    is_arch_supported decides, with the process's stderr (file descriptor 2: Taichi's C++
    warnings go there, not through Python's sys.stderr) kept off the terminal meanwhile."""
    import ctypes
    import os

    for name in ("libcuda.so.1", "libcuda.so", "nvcuda.dll", "libcuda.dylib"):
        try:
            ctypes.CDLL(name)
            break
        except OSError:
            continue
    else:
        return False
    import sys

    import taichi as ti
    from taichi.lang.misc import is_arch_supported

    sys.stderr.flush()
    saved = os.dup(2)
    try:
        with open(os.devnull, "w") as null:
            os.dup2(null.fileno(), 2)
            return bool(is_arch_supported(ti.cuda))
    finally:
        os.dup2(saved, 2)
        os.close(saved)


def init_taichi(arch: str, threads: int | None, precision: str = "f64") -> None:
    """Start Taichi on ``arch`` (dem.ti_runtime.init).  ti.init(arch=ti.cuda) falls back to the
    CPU silently where CUDA is absent, so the arch in use is checked after the start:
    CudaUnavailable if cuda was asked for and Taichi runs on the CPU."""
    import inspect

    from dem import ti_runtime

    check_arch(arch)
    if "arch" in inspect.signature(ti_runtime.init).parameters:
        try:
            ti_runtime.init(threads=threads, precision=precision, arch=arch)
        except RuntimeError as err:  # no CUDA after all, or Taichi already started on the CPU
            if arch == "cuda" and running_arch() != "cuda":
                raise CudaUnavailable(f"--arch cuda: CUDA was asked for and is not available "
                                      f"({err}); use --arch cpu") from None
            raise
    elif arch == "cuda":
        raise CudaUnavailable("--arch cuda: this engine cannot start Taichi on CUDA "
                              "(dem.ti_runtime.init takes no arch); use --arch cpu")
    else:
        ti_runtime.init(threads=threads, precision=precision)
    if arch == "cuda" and running_arch() != "cuda":
        raise CudaUnavailable("--arch cuda: CUDA was asked for and is not available (Taichi "
                              f"started on {running_arch()}); use --arch cpu")


def running_arch() -> str:
    """The arch Taichi runs on: "cuda", or "cpu" for the host archs (x64, arm64)."""
    import taichi as ti
    from taichi.lang import impl

    arch = impl.current_cfg().arch
    return "cuda" if arch == ti.cuda else ("cpu" if arch in (ti.x64, ti.arm64) else str(arch))


def solver_difference(cases: Sequence[Case]) -> str | None:
    """None if every case has the first one's ``solver:`` section, else a sentence naming the
    first field that differs (one engine steps every scene with the same solver options)."""
    first = cases[0].solver.model_dump()
    for case in cases[1:]:
        other = case.solver.model_dump()
        for key in first:
            if first[key] != other.get(key):
                return (f"solver.{key} differs between the cases of one batch ({cases[0].name}: "
                        f"{first[key]!r}, {case.name}: {other.get(key)!r}): one engine steps "
                        f"every scene with the same solver options; run them in separate batches")
    return None


# ---------------------------------------------------------------------------------------------
# which runs share an engine
# ---------------------------------------------------------------------------------------------
def engine_groups(n_cases: int, batch: int, arch: str = "cpu",
                  device_arrays: bool = False) -> list[list[int]]:
    """The cases' indices 0..n_cases-1 by engine, for ``--batch`` ``batch`` (K, >= 1) on
    ``arch``; each group is one task, one engine.  ``device_arrays``: the CPU runs as a proxy
    of a GPU batch (``DEM_DEVICE_ARRAYS`` = 1: the engines keep their arrays as on a device),
    grouped as on a GPU.

    On a GPU: K to an engine in order, the last group smaller (the GPU's throughput grows with
    K: one launch steps every scene).  On the CPU: one run to an engine, whatever K.  A worker
    is one thread, and an engine of K scenes on one thread steps them one after the other with
    the serial kernel's batched variant (each scene's slice of the engine's arrays, its pair
    slots, the frozen-scene tests), which costs more per scene-step than K lone engines
    stepping the same scenes: x 1.10, 1.13 and 1.24 at K = 2, 4 and 8 (the shaken 142-block
    wall; benchmarks/RESULTS.md "Batching on the CPU"); and one engine for K runs leaves the
    other workers idle where there are fewer engines than workers.  A run alone is also the
    run that does not depend on its batch-mates (the shared step, the smallest of theirs).
    The batched engine on the CPU stays for a library user (run_cases_in_one_engine) and as
    the CPU check of the GPU's batch path (tests, benchmarks/batch_speed.py ``run``)."""
    if batch < 1:
        raise BatchInputError(f"--batch must be >= 1, got {batch}")
    if arch not in ARCHS:
        raise BatchInputError(f"--arch must be one of {', '.join(ARCHS)}, got '{arch}'")
    size = batch if arch != "cpu" or device_arrays else 1
    return [list(range(k, min(k + size, n_cases))) for k in range(0, n_cases, size)]


# ---------------------------------------------------------------------------------------------
# one loop over the points' generators
# ---------------------------------------------------------------------------------------------
def drive_together(engine, bodies: Sequence) -> list:
    """Drive the points' generators ``bodies[g]`` (steppable runs, dem.run.steps: each yields
    Advance requests of scene g of ``engine`` and returns its result) to their ends over the
    one engine (module docstring); returns each one's result, or the exception it raised.
    Raises the KeyboardInterrupt that stopped the batch once every point has ended."""
    import contextlib
    import signal

    from dem.signals import Interrupted, deferred, raise_if_stopped, signal_name, stop_on_signals

    n = len(bodies)
    signatures: dict = {}  # the points' load functions' signatures (shared_loads)
    results: list = [None] * n
    request: list = [None] * n  # [steps left, loads] of a waiting point; None: ended
    stop: list[BaseException] = []  # the KeyboardInterrupt that stops the batch

    def resume(g: int, err: BaseException | None = None) -> None:
        """Run point g up to its next request (or its end), ``err`` raised at its request."""
        try:
            req = bodies[g].send(None) if err is None else bodies[g].throw(err)
        except StopIteration as done:
            results[g] = done.value
        except BaseException as exc:  # noqa: BLE001 - reported as the point's result
            results[g] = exc
            if isinstance(exc, KeyboardInterrupt) and not stop:
                stop.append(exc)  # a stop seen by one point stops the batch
        else:
            request[g] = [int(req.n_steps), req.loads]
            return
        request[g] = None
        try:
            engine.deactivate(g)
        except Exception as exc:  # noqa: BLE001 - the others must still run
            if not isinstance(results[g], BaseException):
                results[g] = exc

    def look_at_signals() -> None:
        try:
            raise_if_stopped()
        except KeyboardInterrupt as err:
            if not stop:
                stop.append(err)

    def step(live: list[int]) -> None:
        """Every live point waits: advance the engine by the smallest request and resume, in
        index order, each point whose request is done (or failed; all of them when stopping)."""
        if stop:
            for g in live:  # stopping: every waiting point ends its run (interrupted)
                resume(g, Interrupted(signal_name(stop[0])))
            return
        m = min(request[g][0] for g in live)
        loads = shared_loads(engine, [request[g][1] if request[g] is not None else None
                                      for g in range(n)], signatures)
        try:
            engine.advance(m, loads)
        except Exception as err:  # noqa: BLE001 - the engine itself failed: every live point
            for g in live:
                resume(g, err)
            return
        sims = engine.simulations
        for g in live:
            failure = getattr(sims[g], "failure", None)
            if failure is not None:
                resume(g, failure)
                continue
            request[g][0] -= m
            if request[g][0] <= 0:
                resume(g)

    main = threading.current_thread() is threading.main_thread()
    install = main and signal.getsignal(signal.SIGINT) is signal.default_int_handler
    with stop_on_signals() if install else contextlib.nullcontext():
        try:
            with deferred():
                for g in range(n):  # each in turn: it runs up to its first request or its end
                    resume(g)
                while True:
                    live = [g for g in range(n) if request[g] is not None]
                    if not live:
                        break
                    look_at_signals()
                    step(live)
        except KeyboardInterrupt as err:  # held during the run, raised at its end
            if not stop:
                stop.append(err)
    if stop:
        raise stop[0]
    return results


# ---------------------------------------------------------------------------------------------
# the loads of scenes that share a loading
# ---------------------------------------------------------------------------------------------
class SharedLoads:
    """One load function (dem.run.steps.LoadFn) of several scenes of ``engine`` (the
    realisations of an ensemble each hold an equal loading), evaluated for all of them in one
    call a chunk instead of one call a scene (~15 us of numpy calls each, 1 ms a chunk at 64
    scenes: the host's time between two launches of a device's chunk).

    ``of(g)`` is scene g's load function.  The engine asks for scene g's loads at its steps'
    times (Launcher.write_loads: ``sim.clock.times(sim.step_count + ahead, k)``, ``ahead`` > 0
    for the next chunk's, written while a chunk runs); the first such call of a chunk computes
    every active scene's times the same way, at the same ``ahead`` (read from the call's first
    time; Clock.times_of) and ``fn`` of them all, in one array; each scene's call whose times
    are those, byte for byte, gets its rows, any other call ``fn`` of its own times.  A load
    function is a function of each time alone (the engine relies on it: a step's loads are the
    same however the run is cut into launches, dem.engine.launcher.Launcher.write_loads), so
    the rows are what ``fn`` gives for the scene alone, bit for bit
    (tests/test_shared_loads.py)."""

    def __init__(self, engine, scenes: list[int], fn):
        self.engine, self.scenes, self.fn = engine, scenes, fn
        self.rows: dict = {}  # g -> (times, gravity, base acceleration) of the last chunk

    def of(self, g: int):
        return lambda t: self.loads(g, t)

    def loads(self, g: int, t):
        row = self.rows.get(g)
        if row is None or not _same_times(row[0], t):
            self._fill(len(t), self._ahead(g, t))
            row = self.rows.get(g)
            if row is None or not _same_times(row[0], t):
                return self.fn(t)
        return row[1], row[2]

    def _ahead(self, g: int, t) -> int:
        """The steps from scene g's step count to the first of the times ``t`` it asks for (0:
        this chunk's; a wrong guess only costs the fallback above)."""
        sim = self.engine.simulations[g]
        dt = sim.clock.dt
        if len(t) == 0 or not dt > 0.0:
            return 0
        return int(round((float(t[0]) - sim.clock.time(sim.step_count)) / dt))

    def _fill(self, k: int, ahead: int = 0) -> None:
        from dem.engine.timestep import Clock

        sims = self.engine.simulations
        live = [g for g in self.scenes if self.engine.active(g)]
        self.rows = {}
        if not live or k <= 0:
            return
        t = Clock.times_of([sims[g].clock for g in live],
                           [sims[g].step_count + ahead for g in live], k)
        grav, acc = self.fn(t.reshape(-1))
        grav = np.asarray(grav).reshape(len(live), k, -1)
        acc = np.asarray(acc).reshape(len(live), k, -1)
        self.rows = {g: (t[i], grav[i], acc[i]) for i, g in enumerate(live)}


def _same_times(a, b) -> bool:
    """The same times, byte for byte."""
    b = np.asarray(b)
    return a.shape == b.shape and a.dtype == b.dtype and a.tobytes() == b.tobytes()


def shared_loads(engine, loads: list, signatures: dict) -> list:
    """``loads`` (each scene's load function, None for a scene that does not step) with the
    functions that are equal (the same object, or objects of one class whose pickled states
    are equal: the loadings of an ensemble's realisations) replaced by one
    :class:`SharedLoads` of their scenes.  ``signatures``: a memo of each function's signature
    (id -> (function, signature)), kept by the caller across advances, used for the functions
    that say they never change (``immutable``: dem.loading.Loading); any other's state is read
    at every advance (a quasi-static tilt's loading is turned between advances)."""
    import pickle

    groups: dict = {}
    for g, fn in enumerate(loads):
        if fn is None:
            continue
        known = signatures.get(id(fn))
        if known is None or known[0] is not fn or not getattr(fn, "immutable", False):
            try:
                sig = (type(fn), pickle.dumps(fn))
            except Exception:  # noqa: BLE001 - a closure, a lambda: only itself
                sig = ("object", id(fn))
            known = signatures[id(fn)] = (fn, sig)
        groups.setdefault(known[1], []).append(g)
    out = list(loads)
    for scenes in groups.values():
        if len(scenes) > 1:
            shared = SharedLoads(engine, scenes, loads[scenes[0]])
            for g in scenes:
                out[g] = shared.of(g)
    return out


# ---------------------------------------------------------------------------------------------
# the batch
# ---------------------------------------------------------------------------------------------
def run_cases_in_one_engine(cases: Sequence[tuple[str, Case]], out_dirs: Sequence[str | Path],
                            max_steps: int | None = None, analyses: Sequence = (),
                            resume: bool = True, arch: str = "cpu",
                            post: Callable | None = None, threads: int | None = None,
                            device_arrays: bool | None = None,
                            on_engine: Callable | None = None) -> list[dict]:
    """Run the (name, case) pairs in one engine (module docstring), each into its own
    ``out_dirs[g]``; returns one record per case, in order, as dem.batch's task body returns it:
    ``{"name", "status": "ok", "out_dir", "summary"[, "post"]}`` or ``{"name", "status":
    "failed", "out_dir", "error", "traceback", "wall_seconds"}``.

    ``analyses``: handed to each run_case; ``post(case, RunResult, out_dir) -> dict`` after a
    point's successful run (in its thread); ``resume``: a point directory that holds an
    unfinished run of the same case with a restart point goes on from it (dem.rundir.claim and
    run_case with resume=True), else it is cleared.  ``arch``: Taichi's arch, "cpu" or "cuda"
    (CudaUnavailable where CUDA is absent); ``threads``: Taichi's CPU threads (None: DEM_THREADS
    or all cores).  ``device_arrays``: keep the engine's arrays as on a device
    (dem.engine.device) on the CPU too; None: where Taichi runs on a GPU, or on the CPU where the
    environment variable ``DEM_DEVICE_ARRAYS`` is 1 (a CPU proxy of a GPU batch's host traffic:
    benchmarks/batch_speed.py ``run``).  ``on_engine(engine)``: called once the engine is made
    (its counters: Engine.transfer_stats).  Raises BatchInputError before anything runs when
    the cases' ``solver:`` sections differ (naming the field), KeyboardInterrupt when stopped
    (every point written first)."""
    from dem.rundir import claim
    from dem.run.build import case_joint_law, scene_from_case, step_options
    from dem.loading import loading_from_case

    cases = list(cases)
    out_dirs = [str(d) for d in out_dirs]
    if len(out_dirs) != len(cases):
        raise BatchInputError(f"{len(cases)} cases but {len(out_dirs)} output directories")
    if not cases:
        return []
    why = solver_difference([c for _, c in cases])
    if why is not None:
        raise BatchInputError(why)
    t0 = time.perf_counter()
    options = step_options(cases[0][1].solver)
    init_taichi(arch, threads if threads is not None else options.threads, options.precision)

    records: list[dict | None] = [None] * len(cases)

    def failed(g: int, err: BaseException, tb: str | None = None) -> dict:
        return {"name": cases[g][0], "status": "failed", "out_dir": out_dirs[g],
                "error": f"{type(err).__name__}: {err}",
                "traceback": tb if tb is not None else "".join(
                    traceback.format_exception(type(err), err, err.__traceback__)),
                "wall_seconds": time.perf_counter() - t0}

    # each point's directory (a lock against a second batch writing into it), scene and loading;
    # a point whose scene cannot be built fails alone
    held, scenes, joints, gravity, members = [], [], [], [], []
    try:
        for g, (name, case) in enumerate(cases):
            try:
                held.append(claim(out_dirs[g], case.model_dump_json(indent=1), force=True,
                                  what="point", resume=resume))
                scene = scene_from_case(case)
                scenes.append(scene)
                joints.append(case_joint_law(case, scene))
                gravity.append(loading_from_case(case).g0)
                members.append(g)
            except Exception as err:  # noqa: BLE001 - a failed point is reported, never fatal
                records[g] = failed(g, err)
        if members:
            if device_arrays is None and os.environ.get("DEM_DEVICE_ARRAYS") == "1":
                device_arrays = True
            _run_members(cases, out_dirs, members, scenes, joints, gravity, options, records,
                         failed, max_steps, analyses, resume, arch, post, t0, device_arrays,
                         on_engine)
    finally:
        for rd in held:
            rd.release()
    return records


def _run_members(cases, out_dirs, members, scenes, joints, gravity, options, records, failed,
                 max_steps, analyses, resume, arch, post, t0, device_arrays=None,
                 on_engine=None) -> None:
    """The engine of the points ``members`` (indices into cases) and their runs."""
    from dem.engine.simulation import Engine
    from dem.run.loop import run_case_steps
    from dem.run.write import CheckpointPace

    t1 = time.perf_counter()
    try:
        engine = Engine(scenes, joints, options, gravity=gravity, device_arrays=device_arrays)
    except Exception as err:  # noqa: BLE001 - the engine could not be made: every point fails
        for g in members:
            records[g] = failed(g, err)
        return
    engine_seconds = time.perf_counter() - t1
    if on_engine is not None:
        on_engine(engine)
    sims = engine.simulations
    k = len(members)

    def stamp(i: int, summary: dict | None, before: float) -> None:
        """summary.json's ``batch`` (module docstring), in the file and in ``summary``; the
        run's wall_seconds also count ``before`` (s: the batch's start, its engine's
        construction and the batch-mates' turns before this point's run began), as a lone
        run's count its engine's construction."""
        from dem.output import atomic
        from dem.units import summary_units

        g = members[i]
        path = Path(out_dirs[g]) / "summary.json"
        try:
            data = json.loads(path.read_text())
        except (OSError, ValueError):
            return  # nothing written (a stop before the first step): nothing to stamp
        batch = {"n_scenes": k, "index": i, "dt_s": float(engine.dt), "arch": running_arch(),
                 "engine_seconds": engine_seconds,
                 "note": BATCH_NOTE}
        new = {"batch": batch}
        if isinstance(data.get("wall_seconds"), (int, float)):
            new["wall_seconds"] = data["wall_seconds"] + before
            run_s = new["wall_seconds"] - float(data.get("compile_seconds") or 0.0)
            if isinstance(data.get("steps"), int) and "brick_steps_per_second" in data:
                new["brick_steps_per_second"] = (data["n_blocks"] * data["steps"] / run_s
                                                 if run_s > 0 else None)
        data.update(new)
        data["units"] = summary_units(data)
        if summary is not None:
            summary.update(new)
            summary["units"] = data["units"]
        try:
            atomic.write_json(path, data)
        except OSError:
            pass  # the run's own write errors are in summary.json already

    pace = CheckpointPace()  # the engine stops for every point's checkpoint: one pace

    def body(i: int):
        """Point i's run, steppable (dem.run.steps); returns its record."""
        g = members[i]
        name, case = cases[g]
        t1 = time.perf_counter()
        before = t1 - t0
        failure = getattr(sims[i], "failure", None)
        if failure is not None:  # the scene failed while the engine was made
            return failed(g, failure)
        try:
            res = yield from run_case_steps(case, out_dirs[g], progress=False,
                                            max_steps=max_steps, scene=scenes[i],
                                            analyses=analyses, resume=resume, sim=sims[i],
                                            pace=pace)
            stamp(i, res.summary, before)
            record = {"name": name, "status": "ok", "out_dir": out_dirs[g],
                      "summary": res.summary}
            if post is not None:
                record["post"] = post(case, res, out_dirs[g])
            return record
        except Exception as err:  # noqa: BLE001 - a failed point is reported, never fatal
            stamp(i, None, before)
            rec = failed(g, err, traceback.format_exc())
            rec["wall_seconds"] = time.perf_counter() - t1 + before
            return rec
        except BaseException:
            stamp(i, None, before)
            raise

    results = drive_together(engine, [body(i) for i in range(k)])
    for i, res in enumerate(results):
        records[members[i]] = res if isinstance(res, dict) else failed(members[i], res)
