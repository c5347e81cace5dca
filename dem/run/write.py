"""Write phase: the output directory of a run (contract of ../shared/DESIGN.md).

    summary.json   name, n_blocks, dt, steps, sim_time (s), wall_seconds, compile_seconds,
                   status ("ok" | "failed" | "interrupted"), error, energy balance, loading ...
    frames.npz     t [T] (s), pos [T,N,3] (m, table frame), quat [T,N,4] (w,x,y,z),
                   base_disp [T,3] (m), vel [T,N,3] (m/s), omega [T,N,3] (rad/s, table
                   frame); tilt runs add tilt_angle [T] (deg)
    instruments.npz  virtual instruments sampled every run.instrument_interval (dem.instruments)
    case.json      the validated case with every default filled in (Case.model_validate_json)
    vtk/, final.png

Nothing is lost on failure: frames.npz and summary.json are written (atomically, through
dem.output.atomic: temp file in the same directory, fsync, rename) when the run ends for any
reason, and at checkpoints, every ``CHECKPOINT_SECONDS`` of wall-clock time, or less often where
the checkpoints of the runs that share a process would take more than ``CHECKPOINT_SHARE`` of
its time (:class:`CheckpointPace`: the K runs of a batch each rewrite their files).  Ends and
what they leave (docs/failures.md):

* ok / failed (SimulationError) / interrupted (SIGINT, SIGTERM, SIGHUP: dem.signals): every file
  written, summary.json says which, with the error;
* a write that fails (ENOSPC, EIO, read-only file system): :class:`OutputError`; the files already
  written stay whole (atomic writes), the one that failed is not there (or is the previous
  checkpoint's), summary.json says ``failed`` with ``write_errors`` if it could still be written,
  else it is removed (a checkpoint's ``running`` would be a lie);
* a stop before the first step (bad input found by the engine, a signal while it compiles):
  nothing is written, ``dem run`` removes the directory it claimed.
"""

from __future__ import annotations

import contextlib
import time
from pathlib import Path
from typing import Callable

import numpy as np

from dem.case import Case
from dem.engine import RESULTS_REVISION
from dem.output import atomic
from dem.run.record import Recording
from dem.run.resume import remove_restart, write_restart
from dem.scene import Scene
from dem.units import INSTRUMENTS_UNITS, npz_units, summary_units

CHECKPOINT_SECONDS = 30.0
# the most of a process's wall time its runs' checkpoints may take together (CheckpointPace): a
# lone run's take 0.3-0.7 % at the end of a 50-cycle Model II run (frames.npz and restart.npz,
# 90-210 ms every 30 s: benchmarks/checkpoint_cost.py), K runs of a batch K times that
CHECKPOINT_SHARE = 0.02


from dem.output.atomic import OutputError  # noqa: E402,F401 - one class for every command


def write_case(out: Path, case: Case) -> None:
    """case.json: the validated case (all defaults filled in); post-processing rebuilds the
    scene from it."""
    try:
        atomic.write_text(out / "case.json", case.model_dump_json(indent=1))
    except OSError as err:
        raise OutputError(err.errno, f"cannot write {out / 'case.json'}: "
                                     f"{err.strerror or err}") from None


def initial_summary(case: Case, scene: Scene, loading, sim) -> dict:
    return {
        "name": case.name,
        "n_blocks": scene.n_blocks,
        "dt": sim.dt,
        "dt_critical": sim.dt_crit,
        "steps": 0,
        "sim_time": 0.0,
        "wall_seconds": 0.0,
        "compile_seconds": sim.compile_seconds,
        "status": "running",
        "error": None,
        "mode": sim.mode,
        "skin": sim.skin,
        "loading": loading.describe(),
        "material": case.material.model_dump(),
        "output_interval": case.run.output_interval,
        "results_revision": RESULTS_REVISION,
    }


def imperfection_record(out: Path | None, case: Case, scene: Scene) -> dict:
    """summary.json's ``imperfections`` (seed, parameters, what was drawn), and the realisation in
    full to imperfections.npz (per block: size, position as built, face_offset [6, 4], arris; the
    scene can be rebuilt from the case and the seed, this file shows it without rebuilding)."""
    from dem.imperfections import realised_summary
    from dem.run.build import (as_built_record, imperfection_params, scene_from_case,
                               size_reference)

    nominal = scene_from_case(case, check=False, imperfect=False).size
    record = realised_summary(scene, imperfection_params(case), size_reference(case),
                              as_built_record(case))
    if out is not None:
        atomic.save_npz(out / "imperfections.npz", {
            "seed": np.array(case.imperfections.seed), "size": scene.size,
            "nominal_size": nominal, "position": scene.position,
            "face_offset": scene.face_offset, "arris": scene.arris})
    return record


def engine_results(sim, n_blocks: int, wall0: float, compile_seconds: float) -> dict:
    """The engine's figures at the end of a run (steps, time, speed, contacts, energy)."""
    out = {"steps": sim.step_count, "sim_time": sim.t,
           "wall_seconds": time.perf_counter() - wall0}
    run_s = out["wall_seconds"] - compile_seconds
    out["brick_steps_per_second"] = n_blocks * sim.step_count / run_s if run_s > 0 else None
    out["neighbour_rebuilds"] = sim.n_rebuilds
    out["dt"] = sim.dt
    out["dt_changes"] = sim.dt_changes
    c = sim.read_contacts("npts")
    out["n_pairs"] = c.n_pairs
    out["n_contact_points"] = int(c.npts[: c.n_pairs].sum())
    out["energy"] = sim.energy_report()
    out["max_penetration_m"], out["max_penetration_time_s"] = sim.deepest_penetration()
    joints = sim.joints
    if getattr(joints, "normal_law", "linear") == "hyperbolic":
        # the hyperbolic law: how far the deepest joint closed, as a fraction of d_max, and
        # whether it went past the closure the law holds to (a capped law then ran on its
        # tangent there; docs/engine.md 4.2).  The deepest contact point of any pair, so a
        # pair given another law (material.pairs) may set it
        frac = out["max_penetration_m"] / joints.max_closure
        out["hyperbolic_closure"] = {
            "deepest_closure_fraction": frac,
            "closure_limit": joints.closure_limit,
            "beyond_closure_limit": bool(frac > joints.closure_limit),
            "law_beyond_it": joints.beyond_closure_limit}
    return out


def _snapshot(path: Path, scene: Scene, frames, case: Case) -> None:
    """final.png: the last frame coloured by displacement from the start; a tilt run's table
    drawn at its last angle (the frames are in the table frame)."""
    from dem.loading import AXES
    from dem.output.snapshot import snapshot_png

    pos, quat = frames.cols["pos"], frames.cols["quat"]
    disp = np.linalg.norm(pos[-1] - pos[0], axis=1)
    title, tilt = case.name, None
    if frames.extra.get("tilt_angle"):
        ax = case.loading.axis
        tilt = (float(frames.extra["tilt_angle"][-1]), AXES[ax] if isinstance(ax, str) else ax)
        title = f"{case.name}: table at {tilt[0]:.2f} deg"
    snapshot_png(path, scene, pos[-1], quat[-1], scalars=disp, scalar_name="displacement (m)",
                 title=title, tilt=tilt)


class CheckpointPace:
    """When the runs of one process checkpoint.  A run (its :class:`RunWriter`) checkpoints
    CHECKPOINT_SECONDS after its last checkpoint, and no sooner than the last checkpoint of
    every run of the pace took together, divided by CHECKPOINT_SHARE: the stepping stops while a
    run writes, and in a batch (dem.run.batched: one engine, one pace) it stops for every
    point's.  At 64 Model II points near a 50-cycle run's end a round takes ~6 s (0.09 s a
    point, benchmarks/checkpoint_cost.py), 18 % of 30 s, so the points checkpoint every ~5
    minutes instead; a lone run's round takes under 2 % of 30 s, so it keeps its 30 s.  The
    price: a batch killed (SIGKILL) loses up to that interval.  ``clock``: the wall clock (s),
    a parameter for the tests."""

    def __init__(self, clock: Callable[[], float] = time.perf_counter):
        self.clock = clock
        self.took: dict[int, float] = {}  # id(writer) -> its last checkpoint's seconds

    def interval(self) -> float:
        """The wall seconds a run waits from its last checkpoint to its next."""
        return max(CHECKPOINT_SECONDS, sum(self.took.values()) / CHECKPOINT_SHARE)

    def record(self, writer, seconds: float) -> None:
        self.took[id(writer)] = seconds

    def leave(self, writer) -> None:
        """A run that ended checkpoints no more."""
        self.took.pop(id(writer), None)


class RunWriter:
    """Writes the output directory (or nothing when ``out`` is None) and keeps the list of
    writes that failed.  ``pace``: when it checkpoints, shared by the runs of a batch (its own
    where None)."""

    def __init__(self, out: Path | None, case: Case, scene: Scene, recording: Recording,
                 pace: CheckpointPace | None = None):
        self.out = out
        self.pace = pace if pace is not None else CheckpointPace()
        self.case = case
        self.scene = scene
        self.recording = recording
        self.write_errors: dict[str, str] = {}
        self.last_flush = self.pace.clock()
        # () -> restart.npz's arrays, for a run that can resume (set by dem.run.loop.run_case)
        self.restart: Callable[[], dict] | None = None
        self.cpu0 = time.process_time()  # summary.json cpu_seconds: see cpu_seconds()
        self.cpu_before: float | None = None

    def cpu_seconds(self, summary: dict) -> float:
        """summary.json ``cpu_seconds`` (s): CPU time of the process, every thread, since this
        writer was set up (after the build: the kernels' compile is not in it), plus what a
        resumed run's checkpoint had counted (the summary it restored)."""
        if self.cpu_before is None:
            self.cpu_before = float(summary.get("cpu_seconds") or 0.0)
        return self.cpu_before + time.process_time() - self.cpu0

    def guarded(self, name: str, fn, *args) -> bool:
        """Run one write; an OSError is recorded (the file is not there, or is the previous
        checkpoint's: atomic writes) instead of stopping the other writes."""
        try:
            fn(*args)
            return True
        except OSError as err:
            self.write_errors[name] = f"{err.strerror or err} (errno {err.errno})" \
                if err.errno else str(err)
            return False

    def checkpoint(self, summary: dict, sim, wall_seconds: float) -> None:
        """frames.npz, restart.npz (a run that can resume: ``restart`` set, dem.run.resume) and
        summary.json, in that order, once the pace's interval has passed since the last
        (:class:`CheckpointPace`); called between frames only."""
        now = self.pace.clock()
        if self.out is None or now - self.last_flush <= self.pace.interval():
            return
        summary["steps"], summary["sim_time"] = sim.step_count, sim.t
        summary["wall_seconds"] = wall_seconds
        summary["cpu_seconds"] = self.cpu_seconds(summary)
        self.recording.frames.write()
        if self.restart is not None:
            write_restart(self.out, self.restart())
        atomic.write_json(self.out / "summary.json", summary)
        self.pace.record(self, self.pace.clock() - now)
        self.last_flush = now

    def finish(self, summary: dict, status: str, error: str | None) -> None:
        """Every output file at the end of a run; raises OutputError if one could not be
        written (after writing all the others)."""
        out, rec, case = self.out, self.recording, self.case
        self.pace.leave(self)
        summary["cpu_seconds"] = self.cpu_seconds(summary)
        if rec.instruments is not None:
            summary["instruments"] = {"file": "instruments.npz",
                                      "interval_s": case.run.instrument_interval,
                                      "names": [i.name for i in rec.instruments.instruments]}
        if out is None:
            return
        self.guarded("frames.npz", rec.frames.write)
        if rec.instruments is not None and rec.instruments.rows["t"]:
            arrays = rec.instruments.arrays()
            arrays["units"] = npz_units(arrays, INSTRUMENTS_UNITS)  # (key, unit) rows
            self.guarded("instruments.npz", atomic.save_npz, out / "instruments.npz", arrays)
        if rec.vtk is not None:
            self.guarded("vtk/scene.pvd", rec.vtk.close)
            summary["vtk_frames"] = rec.vtk.n_frames
            summary["vtk_bytes"] = rec.vtk.bytes_written
        if case.run.snapshot and rec.frames.n_frames and not self.write_errors:
            self.guarded("final.png", _snapshot, out / "final.png", self.scene, rec.frames,
                         case)
        errors = self.write_errors
        if errors:
            summary["status"] = "failed"
            summary["error"] = "output: " + "; ".join(f"{k}: {v}" for k, v in errors.items()) + \
                (f" (after: {status}: {error})" if error else "")
            summary["write_errors"] = errors
        summary["units"] = summary_units(summary)  # {path: unit} of every number (dem.units)
        if not self.guarded("summary.json", atomic.write_json, out / "summary.json", summary):
            # a checkpoint's 'running' must not survive: remove it (frees its blocks), then
            # try a minimal summary
            with contextlib.suppress(OSError):
                (out / "summary.json").unlink()
            small = {k: summary.get(k) for k in ("name", "n_blocks", "dt", "steps", "sim_time",
                                                 "status", "error")}
            small["write_errors"] = errors
            small["status"] = "failed"
            self.guarded("summary.json (minimal)", atomic.write_json, out / "summary.json", small)
        if summary["status"] != "interrupted":
            remove_restart(out)  # finished or failed: nothing to go on from
        if errors:
            first = next(iter(errors))
            raise OutputError(
                None, f"cannot write the output in {out}: {first}: {errors[first]}"
                + ("; summary.json says failed" if (out / "summary.json").is_file()
                   else "; no summary.json could be written"))
