"""The run loop: build, (settle), load, record, stop, write.

The load phase advances the engine in time (constant-rate tilt, shake, record) or, for a
quasi-static tilt, angle by angle to the loss of equilibrium (dem.run.quasi_static).

    res = run_case(case, "runs/wall")            # writes the output directory, returns frames

``analyses``: functions ``f(case, scene, frames, summary) -> dict`` that read the finished run
(frames: the arrays of frames.npz) and return keys merged into summary.json before it is written
(e.g. ``postprocess.tilt.tilt_mechanism``, handed in by the ``dem run`` command): the run loop
itself never imports the analysis.  One that raises is recorded in summary.json
``analysis_errors``; the run's files are written all the same.
"""

from __future__ import annotations

import json
import time
from dataclasses import dataclass, field
from pathlib import Path
from typing import Callable, Sequence

import numpy as np

from dem.case import Case
from dem.loading import HeldTilt
from dem.run.build import build, joint_summary
from dem.run.progress import Progress
from dem.run import resume as resume_mod
from dem.run.quasi_static import QuasiStaticTilt
from dem.run.record import FRAME_KEYS, FRAMES_A_REQUEST, Recording
from dem.run.settle import settle_steps
from dem.run.steps import Advance, Steps, drive
from dem.run.stop import StopRule
from dem.run.table_start import apply_table_start
from dem.rundir import clear
from dem.run.write import (CheckpointPace, OutputError, RunWriter, engine_results,
                           imperfection_record, initial_summary, write_case)
from dem.scene import Scene
from dem.signals import raise_if_stopped

Analysis = Callable[[Case, Scene, dict, dict], dict]


def _restart_point(case: Case, out: Path, why_not: str | None, max_steps: int | None
                   ) -> tuple[dict | None, str | None]:
    """(restart.npz's arrays, None) if ``out`` holds a restart point this run can go on from,
    else (None, why not: None where there was none) with the directory cleared of the earlier
    attempt (dem.run.resume).  Called before anything of this run is written."""
    if not (out / resume_mod.RESTART_FILE).exists():
        return None, None  # the claim cleared any earlier attempt
    if why_not is not None:
        arrays, reason = None, f"this run cannot resume: {why_not}"
    else:
        arrays, reason = resume_mod.load_restart(out, case)
        if arrays is not None and json.loads(str(arrays["summary"])).get("step_limit") != \
                max_steps:
            arrays, reason = None, "the step limit (--max-steps) differs from the checkpoint's"
    if arrays is None:
        clear(out)
    return arrays, reason


@dataclass
class RunResult:
    t: np.ndarray
    pos: np.ndarray
    quat: np.ndarray
    vel: np.ndarray
    base_disp: np.ndarray
    summary: dict
    extra: dict = field(default_factory=dict)
    scene: Scene | None = None


def run_case(case: Case, out_dir: str | Path | None = None, progress: bool = False,
             max_steps: int | None = None, scene: Scene | None = None,
             analyses: Sequence[Analysis] = (), resume: bool = False, sim=None) -> RunResult:
    """Run a validated case.  Writes the output directory (dem.run.write) if ``out_dir`` given.
    :func:`run_case_steps` with its scene advancing alone (dem.run.steps.drive); the arguments
    and what is raised are its."""
    return drive(run_case_steps(case, out_dir, progress, max_steps, scene, analyses, resume,
                                sim))


def run_case_steps(case: Case, out_dir: str | Path | None = None, progress: bool = False,
                   max_steps: int | None = None, scene: Scene | None = None,
                   analyses: Sequence[Analysis] = (), resume: bool = False, sim=None,
                   pace: CheckpointPace | None = None) -> Steps:
    """Run a validated case, steppable (dem.run.steps): yields each advance of its scene
    (``Advance``), returns the :class:`RunResult`.  Writes the output directory
    (dem.run.write) if ``out_dir`` given.

    ``resume``: ``out_dir`` may hold an unfinished run of this case with a restart point
    (dem.run.resume); go on from it, else clear the directory and start over (summary.json
    ``resume.refused`` says why).  The caller holds the directory (dem.rundir.claim with
    ``resume=True``, which kept those files).

    Raises dem.engine.InputError (bad scene/settings) before anything is written,
    SimulationError when the run fails, KeyboardInterrupt (dem.signals.Interrupted for SIGTERM /
    SIGHUP) when stopped, :class:`OutputError` when an output file cannot be written; in all but
    the first the frames recorded so far are written first (where the disk allows).
    ``scene``: the scene of the case, already built and checked (dem.validate), else built here.
    ``sim``: the case's engine already made (one scene of a batch: dem.run.batched), else made
    here (dem.run.build.build).  ``pace``: when it checkpoints, shared with the other points of
    a batch (dem.run.write.CheckpointPace; its own where None).
    """
    from dem.engine import SimulationError

    wall0 = time.perf_counter()
    out = Path(out_dir) if out_dir is not None else None
    built = build(case, scene, sim)                                   # build
    scene, loading, sim = built.scene, built.loading, built.sim
    raise_if_stopped()  # a stop signal Taichi swallowed while starting: nothing written yet
    stop = StopRule(case, scene, loading, max_steps)                  # stop
    why_not = resume_mod.unresumable_reason(case, loading, stop) if out is not None else \
        "no output directory"
    restart, refused = None, None
    if out is not None:
        out.mkdir(parents=True, exist_ok=True)
        if resume:                                                    # resume
            restart, refused = _restart_point(case, out, why_not, max_steps)
        write_case(out, case)
    recording = Recording(case, scene, loading, sim, out)             # record
    recording.listeners.append(stop.listen)
    writer = RunWriter(out, case, scene, recording, pace)             # write
    summary = None
    if restart is not None:
        summary, refused = resume_mod.apply_restart(restart, sim, recording)
        restart = None
        if summary is None:  # nothing was changed: start over in a cleared directory
            clear(out)
            write_case(out, case)
    fresh = summary is None  # else: settled and recording already, go on from the restart
    if fresh:
        summary = initial_summary(case, scene, loading, sim)
        summary["step_limit"] = max_steps  # a smoke run capped by --max-steps is not finished
        summary["joints"] = joint_summary(case, scene, sim.joints)
        if case.imperfections.any():
            summary["imperfections"] = imperfection_record(out, case, scene)
        summary["machine"] = resume_mod.machine()  # the CPU (results differ in the last bits)
        summary["resume"] = {"restart_points": why_not is None, "why_not": why_not,
                             "refused": refused}
    else:
        wall0 -= summary["wall_seconds"]  # wall and compile seconds count every process
        summary["compile_seconds"] += sim.compile_seconds
        summary.setdefault("resumed", []).append({
            "step": sim.step_count, "sim_time": sim.t,
            "wall_seconds_before": summary["wall_seconds"], "machine": resume_mod.machine()})
    if why_not is None:
        writer.restart = lambda: resume_mod.restart_arrays(case, sim, recording, summary)

    def finish(status: str, error: str | None = None) -> None:
        summary["status"], summary["error"] = status, error
        summary.update(engine_results(sim, scene.n_blocks, wall0, summary["compile_seconds"]))
        summary.update(stop.results())
        if analyses and recording.frames.n_frames:
            arrays = recording.frames.arrays()
            for analyse in analyses:
                try:
                    summary.update(analyse(case, scene, arrays, summary))
                except Exception as err:  # noqa: BLE001 - an analysis never loses the run
                    summary.setdefault("analysis_errors", {})[analyse.__name__] = \
                        f"{type(err).__name__}: {err}"
        writer.finish(summary, status, error)

    held = isinstance(loading, HeldTilt)  # the bar follows its table angle (dem.run.progress)
    bar = Progress(progress, case.loading.max_angle, case.name, "deg", "table angle") if held \
        else Progress(progress, stop.t_end, case.name)
    run0 = time.perf_counter()

    def progressed(*args) -> None:
        raise_if_stopped()  # one swallowed by Taichi's compiler (dem.signals)
        bar.update(float(args[0]) if held and args else sim.t,
                   sim.step_count / max(time.perf_counter() - run0, 1e-9))
        writer.checkpoint(summary, sim, time.perf_counter() - wall0)

    try:
        if fresh and case.imperfections.any():                        # settle
            from dem.run.settle import MAX_TIME

            settling_bar = Progress(progress, MAX_TIME, f"{case.name} settling")
            try:
                summary["settling"] = yield from settle_steps(
                    sim, loading, case.solver.local_damping, max_steps,
                    on_look=lambda: (raise_if_stopped(), settling_bar.update(
                        sim.t, sim.step_count / max(time.perf_counter() - run0, 1e-9))))
            finally:
                settling_bar.close()
        if fresh:
            started = apply_table_start(sim, loading)  # lab start: the impulse, once
            if started is not None:
                summary["table_start"] = started
            recording.start()
        if isinstance(loading, HeldTilt):                             # load: quasi-static
            search = QuasiStaticTilt(case, scene, loading, sim, recording, progressed,
                                     max_steps)
            summary["collapse"] = yield from search.run()
        else:                                                         # load: in time
            # several frames a request where no frame listener may stop the run (the collapse
            # detector of a tilt): the engine may then take them inside its launches
            frames = FRAMES_A_REQUEST if stop.detector is None else 1
            while not stop.at_end(sim):
                yield Advance(sim, stop.limit_steps(sim, recording.steps_to_next(stop.t_end,
                                                                                 frames)),
                              loading)
                if recording.after_advance(last=stop.at_end(sim)) and stop.collapse_stop:
                    break
                progressed()
    except SimulationError as err:
        bar.close()
        writer.guarded("last frame", recording.frame_at_stop)
        finish("failed", str(err))
        raise
    except KeyboardInterrupt as err:
        from dem.signals import signal_name

        bar.close()
        writer.guarded("last frame", recording.frame_at_stop)
        sig = signal_name(err)
        finish("interrupted", f"stopped by {sig}" + (" (Ctrl-C)" if sig == "SIGINT" else ""))
        raise
    except OSError as err:  # a checkpoint or a VTK frame could not be written
        bar.close()
        writer.write_errors["checkpoint (frames.npz, restart.npz, summary.json or a VTK frame)"] = \
            f"{err.strerror or err}" + (f" (errno {err.errno})" if err.errno else "")
        finish("failed", None)
        raise OutputError(err.errno, err.strerror or str(err)) from None  # finish raises first if it can
    bar.close()
    finish("ok")
    arrays = recording.frames.arrays()
    extra = {k: v for k, v in arrays.items() if k not in FRAME_KEYS}
    return RunResult(arrays["t"], arrays["pos"], arrays["quat"], arrays["vel"],
                     arrays["base_disp"], summary, extra, scene)
