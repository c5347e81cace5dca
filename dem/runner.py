"""Run one case: build the scene, step it, record frames, write the output directory.

Output directory (contract of ../shared/DESIGN.md):
    summary.json   name, n_blocks, dt, steps, sim_time (s), wall_seconds, compile_seconds,
                   status ("ok" | "failed" | "interrupted"), error, energy balance, loading ...
    frames.npz     t [T] (s), pos [T,N,3] (m, table frame), quat [T,N,4] (w,x,y,z),
                   base_disp [T,3] (m), vel [T,N,3] (m/s), omega [T,N,3] (rad/s, table
                   frame); tilt runs add tilt_angle [T] (deg)
    instruments.npz  virtual instruments sampled every run.instrument_interval (dem.instruments)
    case.json      the validated case with every default filled in (Case.model_validate_json)

Nothing is lost on failure: frames.npz and summary.json are written (atomically, through
dem.output.atomic: temp file in the same directory, fsync, rename) when the run ends for any reason,
and every ``CHECKPOINT_SECONDS`` of wall-clock time.  Ends and what they leave (docs/failures.md):

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

import json
import math
import time
from dataclasses import dataclass, field
from pathlib import Path

import numpy as np

from dem.output import atomic
from dem.case import Case
from dem.collapse import CollapseDetector
from dem.instruments import InstrumentRecorder, thesis_instruments
from dem.loading import Record, Shake, Tilt, loading_from_case
from dem.scene import Scene, scene_from_case

CHECKPOINT_SECONDS = 30.0


class OutputError(OSError):
    """An output file could not be written (disk full, I/O error, read-only file system)."""


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


class FrameRecorder:
    """Frames in memory, flushed to ``frames.npz`` atomically."""

    def __init__(self, out_dir: Path | None):
        self.out_dir = out_dir
        self.cols: dict[str, list] = {k: [] for k in ("t", "pos", "quat", "vel", "omega",
                                                       "base_disp")}
        self.extra: dict[str, list] = {}

    def add(self, t, pos, quat, vel, omega, base_disp, **extra) -> None:
        self.cols["t"].append(float(t))
        self.cols["pos"].append(np.array(pos))
        self.cols["quat"].append(np.array(quat))
        self.cols["vel"].append(np.array(vel))
        self.cols["omega"].append(np.array(omega))
        self.cols["base_disp"].append(np.array(base_disp, dtype=float).reshape(3))
        for k, v in extra.items():
            self.extra.setdefault(k, []).append(v)

    def arrays(self) -> dict[str, np.ndarray]:
        out = {k: np.asarray(v) for k, v in self.cols.items()}
        out.update({k: np.asarray(v) for k, v in self.extra.items()})
        return out

    def write(self) -> None:
        if self.out_dir is None or not self.cols["t"]:
            return
        _save_npz(self.out_dir / "frames.npz", self.arrays())


def _save_npz(path: Path, arrays: dict) -> None:
    atomic.save_npz(path, arrays)


def _snapshot(path: Path, scene: Scene, rec: FrameRecorder, title: str) -> None:
    """final.png: the last frame coloured by displacement from the start."""
    from dem.output.snapshot import snapshot_png

    pos, quat = rec.cols["pos"], rec.cols["quat"]
    disp = np.linalg.norm(pos[-1] - pos[0], axis=1)
    snapshot_png(path, scene, pos[-1], quat[-1], scalars=disp, scalar_name="displacement (m)",
                 title=title)


class _Progress:
    """A rich progress bar over simulated time (steps/s and ETA), or nothing."""

    def __init__(self, enabled: bool, duration: float, name: str):
        self.bar = None
        if not enabled:
            return
        from rich.progress import (BarColumn, Progress, TextColumn, TimeElapsedColumn,
                                   TimeRemainingColumn)
        self.bar = Progress(
            TextColumn("[bold]{task.description}"), BarColumn(),
            TextColumn("t = {task.completed:.3f} / {task.total:.3f} s"),
            TextColumn("{task.fields[rate]:>10} steps/s"), TimeElapsedColumn(),
            TextColumn("ETA"), TimeRemainingColumn(), transient=False)
        self.task = self.bar.add_task(name, total=duration, rate="-")
        self.bar.start()

    def update(self, t: float, steps_per_s: float) -> None:
        if self.bar is not None:
            self.bar.update(self.task, completed=t, rate=f"{steps_per_s:,.0f}")

    def close(self) -> None:
        if self.bar is not None:
            self.bar.stop()


def simulate(case: Case, out_dir: str | Path | None = None, progress: bool = False,
             max_steps: int | None = None, scene: Scene | None = None) -> RunResult:
    """Run a validated case.  Writes ``summary.json`` and ``frames.npz`` into out_dir if given.

    Raises dem.engine.InputError (bad scene/settings) before anything is written,
    SimulationError when the run fails, KeyboardInterrupt (dem.signals.Interrupted for SIGTERM /
    SIGHUP) when stopped, :class:`OutputError` when an output file cannot be written; in all but
    the first the frames recorded so far are written first (where the disk allows).
    ``scene``: the scene of the case, already built and checked (dem.validate), else built here.
    """
    from dem.engine import Simulation, SimulationError

    wall0 = time.perf_counter()
    out = Path(out_dir) if out_dir is not None else None
    scene = scene if scene is not None else scene_from_case(case)
    loading = loading_from_case(case)
    sim = Simulation(scene, case.material, case.solver, gravity=loading.g0)
    if out is not None:
        out.mkdir(parents=True, exist_ok=True)
        # the validated case (all defaults filled in): post-processing rebuilds the scene from it
        try:
            atomic.write_text(out / "case.json", case.model_dump_json(indent=1))
        except OSError as err:
            raise OutputError(err.errno, f"cannot write {out / 'case.json'}: "
                                         f"{err.strerror or err}") from None
    n = scene.n_blocks
    dt = sim.dt
    t_end = case.run.duration
    step_limit = int(max_steps) if max_steps is not None else None
    rec = FrameRecorder(out)
    summary = {
        "name": case.name,
        "n_blocks": n,
        "dt": dt,
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
    }

    detector = None
    if isinstance(loading, Tilt) and case.loading.collapse.enabled:
        cs = case.loading.collapse
        detector = CollapseDetector(scene.position.copy(), scene.quat.copy(),
                                    0.5 * np.linalg.norm(scene.size, axis=1), cs.onset_speed,
                                    cs.confirm, cs.after, cs.stop)

    instruments = None
    choice = case.run.instruments
    if choice == "auto":
        boxy = {"L1", "L2", "T1", "T2"} <= set(scene.group_names)
        choice = "thesis" if boxy and isinstance(loading, (Shake, Record)) else "none"
    if choice == "thesis":
        if isinstance(loading, Shake):
            d = np.abs(loading.direction)
        elif isinstance(loading, Record):
            d = np.abs(loading.acc).max(axis=0)
            d = np.where(d >= 0.3 * d.max(), d, 0.0)  # the axes the record really moves
        else:
            d = np.array([0.0, 1.0, 0.0])
        axis = "xy" if d[0] > 1e-9 and d[1] > 1e-9 else ("x" if d[0] > d[1] else "y")
        instruments = InstrumentRecorder(thesis_instruments(scene, axis), scene)

    def sample_instruments():
        st = sim.state
        tt = np.array([sim.t])
        instruments.sample(sim.t, st.pos, st.quat, st.vel, st.omega, loading.base_disp(tt)[0],
                           loading.base_vel(tt)[0])

    vtk = None
    if out is not None and case.run.vtk:
        from dem.output.vtk import VtkSeries
        vtk = VtkSeries(out, scene, write_contacts=case.run.contacts)

    def record():
        st = sim.state
        t = sim.t
        extra = {}
        if isinstance(loading, Tilt):
            extra["tilt_angle"] = float(loading.angle(t)[0])
        base = loading.base_disp(np.array([t]))[0]
        if vtk is not None and len(rec.cols["t"]) % case.run.vtk_every == 0:
            vtk.add_frame(t, st.pos[:n], st.quat[:n], st.vel[:n], base,
                          contacts=sim.contacts.active_points() if case.run.contacts else None)
        rec.add(t, st.pos[:n], st.quat[:n], st.vel[:n], st.omega[:n], base, **extra)

    write_errors: dict[str, str] = {}

    def guarded(name: str, fn, *args) -> bool:
        """Run one write; an OSError is recorded (the file is not there, or is the previous
        checkpoint's: atomic writes) instead of stopping the other writes."""
        try:
            fn(*args)
            return True
        except OSError as err:
            write_errors[name] = f"{err.strerror or err} (errno {err.errno})" if err.errno \
                else str(err)
            return False

    def finish(status: str, error: str | None = None):
        summary["status"] = status
        summary["error"] = error
        summary["steps"] = sim.step_count
        summary["sim_time"] = sim.t
        summary["wall_seconds"] = time.perf_counter() - wall0
        run_s = summary["wall_seconds"] - summary["compile_seconds"]
        summary["brick_steps_per_second"] = n * sim.step_count / run_s if run_s > 0 else None
        summary["neighbour_rebuilds"] = sim.n_rebuilds
        summary["dt"] = sim.dt
        summary["dt_changes"] = sim.dt_changes
        summary["n_pairs"] = sim.contacts.n_pairs
        summary["n_contact_points"] = int(sim.contacts.npts[: sim.contacts.n_pairs].sum())
        summary["energy"] = sim.energy_report()
        summary["max_penetration_m"], summary["max_penetration_time_s"] = \
            sim.deepest_penetration()
        if detector is not None and rec.cols["t"]:
            from postprocess.tilt import tilt_results

            c = rec.cols
            summary.update(tilt_results(case, scene, np.asarray(c["t"]),
                                        np.asarray(rec.extra["tilt_angle"]), np.asarray(c["pos"]),
                                        np.asarray(c["quat"]), np.asarray(c["vel"]),
                                        np.asarray(c["omega"])))
        if instruments is not None:
            summary["instruments"] = {"file": "instruments.npz",
                                      "interval_s": case.run.instrument_interval,
                                      "names": [i.name for i in instruments.instruments]}
        if out is not None:
            guarded("frames.npz", rec.write)
            if instruments is not None and instruments.rows["t"]:
                guarded("instruments.npz", _save_npz, out / "instruments.npz",
                        instruments.arrays())
            if vtk is not None:
                guarded("vtk/scene.pvd", vtk.close)
                summary["vtk_frames"] = vtk.n_frames
                summary["vtk_bytes"] = vtk.bytes_written
            if case.run.snapshot and rec.cols["t"] and not write_errors:
                guarded("final.png", _snapshot, out / "final.png", scene, rec, case.name)
            if write_errors:
                summary["status"] = "failed"
                summary["error"] = "output: " + "; ".join(f"{k}: {v}" for k, v in
                                                          write_errors.items()) + \
                    (f" (after: {status}: {error})" if error else "")
                summary["write_errors"] = write_errors
            if not guarded("summary.json", atomic.write_json, out / "summary.json", summary):
                # a checkpoint's 'running' must not survive: remove it (frees its blocks), then
                # try a minimal summary
                import contextlib

                with contextlib.suppress(OSError):
                    (out / "summary.json").unlink()
                small = {k: summary.get(k) for k in ("name", "n_blocks", "dt", "steps",
                                                     "sim_time", "status", "error")}
                small["write_errors"] = write_errors
                small["status"] = "failed"
                guarded("summary.json (minimal)", atomic.write_json, out / "summary.json", small)
            if write_errors:
                first = next(iter(write_errors))
                raise OutputError(
                    None, f"cannot write the output in {out}: {first}: {write_errors[first]}"
                    + ("; summary.json says failed" if (out / "summary.json").is_file()
                       else "; no summary.json could be written"))

    def record_last():
        """The state where the run stopped, so frames.npz ends at summary's sim_time."""
        if not rec.cols["t"] or sim.t > rec.cols["t"][-1]:
            record()

    bar = _Progress(progress, t_end, case.name)
    last_flush = time.perf_counter()
    run0 = time.perf_counter()
    try:
        record()
        if instruments is not None:
            sample_instruments()
        # frames and instrument samples at the first step at or after each multiple of their
        # interval (time-based, so a change of dt during the run keeps the schedule)
        next_frame = case.run.output_interval
        next_inst = case.run.instrument_interval

        def steps_to(t_target):
            return max(1, int(math.ceil((t_target - sim.t) / sim.dt - 1e-9)))

        def next_multiple(interval):
            return (math.floor(sim.t / interval + 1e-9) + 1) * interval

        while sim.t < t_end - 1e-12 * t_end and (step_limit is None or sim.step_count < step_limit):
            k = steps_to(min(next_frame, t_end))
            if instruments is not None:
                k = min(k, steps_to(next_inst))
            if step_limit is not None:
                k = min(k, step_limit - sim.step_count)
            sim.advance(k, loading)
            if instruments is not None and sim.t >= next_inst - 1e-9 * sim.dt:
                sample_instruments()
                next_inst = next_multiple(case.run.instrument_interval)
            last = sim.t >= t_end - 1e-12 * t_end or (step_limit is not None
                                                       and sim.step_count >= step_limit)
            if sim.t >= next_frame - 1e-9 * sim.dt or last:
                next_frame = next_multiple(case.run.output_interval)
                record()
                st = sim.state
                if detector is not None and detector.update(
                        sim.t, rec.extra["tilt_angle"][-1], st.pos[:n], st.quat[:n], st.vel[:n],
                        st.omega[:n]):
                    break
            now = time.perf_counter()
            bar.update(sim.t, sim.step_count / max(now - run0, 1e-9))
            if out is not None and now - last_flush > CHECKPOINT_SECONDS:
                summary["steps"], summary["sim_time"] = sim.step_count, sim.t
                rec.write()
                atomic.write_json(out / "summary.json", summary)
                last_flush = now
    except SimulationError as err:
        bar.close()
        guarded("last frame", record_last)
        finish("failed", str(err))
        raise
    except KeyboardInterrupt as err:
        from dem.signals import signal_name

        bar.close()
        guarded("last frame", record_last)
        sig = signal_name(err)
        finish("interrupted", f"stopped by {sig}" + (" (Ctrl-C)" if sig == "SIGINT" else ""))
        raise
    except OSError as err:  # a checkpoint or a VTK frame could not be written
        bar.close()
        write_errors["checkpoint (frames.npz, summary.json or a VTK frame)"] = \
            f"{err.strerror or err} (errno {err.errno})"
        finish("failed", None)
        raise OutputError(err.errno, str(err)) from None  # finish raises first if it can
    bar.close()
    finish("ok")
    arrays = rec.arrays()
    extra = {k: v for k, v in arrays.items()
             if k not in ("t", "pos", "quat", "vel", "omega", "base_disp")}
    return RunResult(arrays["t"], arrays["pos"], arrays["quat"], arrays["vel"],
                     arrays["base_disp"], summary, extra, scene)


def result_line(summary: dict, arrays: dict | None = None) -> str:
    """The last line of every run: status and the main result of its loading type."""
    status = summary.get("status")
    parts = [f"result: {status}"]
    if summary.get("error"):
        parts.append(str(summary["error"]).splitlines()[0])
    kind = (summary.get("loading") or {}).get("type")
    if kind == "tilt":
        col = summary.get("collapse") or {}
        if col.get("detected"):
            mech = summary.get("mechanism") or {}
            label = mech.get("mechanism") or mech.get("kind")
            parts.append(f"collapse at {col['angle_deg']:.2f} deg, load factor "
                         f"{col['load_factor']:.3f}" + (f", mechanism {label}" if label else ""))
        elif col:
            parts.append(f"no collapse up to {col.get('last_angle_deg', 0.0):.2f} deg")
    if arrays is not None and len(arrays.get("t", [])) and kind != "tilt":
        pos = np.asarray(arrays["pos"])
        disp = float(np.linalg.norm(pos - pos[0], axis=2).max()) if pos.size else 0.0
        ld = summary.get("loading") or {}
        if kind in ("shake", "record"):
            parts.append(f"peak table acceleration {ld.get('peak_acceleration_m_s2', 0.0):.3g} "
                         f"m/s2, largest block displacement relative to the table "
                         f"{disp * 1e3:.3g} mm (amplification: dem post)")
        else:
            parts.append(f"largest block displacement {disp * 1e3:.3g} mm")
    parts.append(f"t = {summary.get('sim_time', 0.0):.4g} s")
    return "; ".join(parts)


def run_case_file(path: str | Path, out: str | Path, progress: bool = True, force: bool = False,
                  max_blocks: int | None = None) -> int:
    """CLI body of ``dem run``: returns the exit code (0 ok, 1 run failed or stopped, 2 bad
    input; docs/failures.md).  SIGTERM and SIGHUP stop the run like Ctrl-C (dem.signals)."""
    import typer

    from dem.signals import signal_name, stop_on_signals

    with stop_on_signals():
        try:
            return _run_case_file(path, out, progress, force, max_blocks)
        except KeyboardInterrupt as err:  # before the output directory was claimed
            typer.echo(f"interrupted by {signal_name(err)} before the run started; nothing "
                       f"written", err=True)
            return 1


def _run_case_file(path, out, progress, force, max_blocks) -> int:
    import typer

    from dem.engine import InputError, SimulationError
    from dem.rundir import RunDirError, claim
    from dem.signals import signal_name
    from dem.validate import load_and_check

    def err(msg):
        typer.echo(msg, err=True)

    checked = load_and_check(path, err, max_blocks)
    if checked is None:
        return 2
    case = checked.case
    try:
        rd = claim(out, case.model_dump_json(indent=1), force=force)
    except RunDirError as e:
        err(f"error: {e}")
        return 2
    out = Path(out)
    try:
        res = simulate(case, out, progress=progress, scene=checked.scene)
    except (InputError, ValueError) as e:
        rd.abandon()
        err(f"error: {path}: {e}")
        return 2
    except SimulationError as e:
        err(f"run failed: {e}\nframes written so far are in {out}/frames.npz")
        err(_summary_result(out))
        return 1
    except OSError as e:  # OutputError, or a write while the run was being set up
        msg = e.strerror or str(e)
        if not isinstance(e, OutputError):
            msg = f"cannot write the output in {out}: {msg} (errno {e.errno})"
        err(f"error: {msg}")
        return 1
    except KeyboardInterrupt as e:
        if (out / "summary.json").is_file():
            err(f"interrupted by {signal_name(e)}; summary.json says 'interrupted', frames so "
                f"far are in {out}/frames.npz")
            err(_summary_result(out))
        else:
            rd.abandon()
            err(f"interrupted by {signal_name(e)} before the first step; nothing written")
        return 1
    finally:
        rd.release()
    s = res.summary
    typer.echo(
        f"{s['name']}: {s['n_blocks']} blocks, {s['steps']} steps of {s['dt']:.3g} s, "
        f"t = {s['sim_time']:.3f} s in {s['wall_seconds']:.1f} s wall "
        f"({s['compile_seconds']:.1f} s compile, {s['brick_steps_per_second']:.3g} brick-steps/s); "
        f"output in {out}")
    typer.echo(result_line(s, {"t": res.t, "pos": res.pos}))
    return 0


def _summary_result(out: Path) -> str:
    """result_line of a run directory that ended early (from its summary.json and frames)."""
    try:
        s = json.loads((out / "summary.json").read_text())
    except (OSError, ValueError):
        return "result: failed (no summary.json)"
    arrays = None
    try:
        with np.load(out / "frames.npz") as fr:
            arrays = {"t": fr["t"], "pos": fr["pos"]}
    except (OSError, ValueError, KeyError):
        pass
    return result_line(s, arrays)
