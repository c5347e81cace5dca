"""Run one case: build the scene, step it, record frames, write the output directory.

Output directory (contract of ../shared/DESIGN.md):
    summary.json   name, n_blocks, dt, steps, sim_time (s), wall_seconds, compile_seconds,
                   status ("ok" | "failed" | "interrupted"), error, energy balance, loading ...
    frames.npz     t [T] (s), pos [T,N,3] (m, table frame), quat [T,N,4] (w,x,y,z),
                   base_disp [T,3] (m), vel [T,N,3] (m/s), omega [T,N,3] (rad/s, table
                   frame); tilt runs add tilt_angle [T] (deg)
    instruments.npz  virtual instruments sampled every run.instrument_interval (dem.instruments)
    case.json      the validated case with every default filled in (Case.model_validate_json)

Nothing is lost on failure: frames.npz and summary.json are written (atomically, temp file +
rename) when the run ends for any reason, and every ``CHECKPOINT_SECONDS`` of wall-clock time.
"""

from __future__ import annotations

import json
import math
import os
import time
from dataclasses import dataclass, field
from pathlib import Path

import numpy as np

from dem.case import Case, CaseError, load_case
from dem.collapse import CollapseDetector
from dem.instruments import InstrumentRecorder, thesis_instruments
from dem.loading import Record, Shake, Tilt, loading_from_case
from dem.scene import Scene, scene_from_case

CHECKPOINT_SECONDS = 30.0


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
    """np.savez_compressed through a temporary file, so the file is always whole."""
    tmp = path.with_name(path.stem + ".tmp.npz")
    np.savez_compressed(tmp, **arrays)
    os.replace(tmp, path)


def _write_json(path: Path, data: dict) -> None:
    tmp = path.with_suffix(".tmp")
    tmp.write_text(json.dumps(data, indent=2, default=_json_default))
    os.replace(tmp, path)


def _json_default(o):
    if isinstance(o, (np.floating, np.integer)):
        return o.item()
    if isinstance(o, np.ndarray):
        return o.tolist()
    raise TypeError(type(o).__name__)


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
             max_steps: int | None = None) -> RunResult:
    """Run a validated case.  Writes ``summary.json`` and ``frames.npz`` into out_dir if given.

    Raises dem.engine.InputError (bad scene/settings) before stepping, SimulationError when the
    run fails; in both the frames recorded so far are written first.
    """
    from dem.engine import Simulation, SimulationError

    wall0 = time.perf_counter()
    out = Path(out_dir) if out_dir is not None else None
    if out is not None:
        out.mkdir(parents=True, exist_ok=True)
        # the validated case (all defaults filled in): post-processing rebuilds the scene from it
        (out / "case.json").write_text(case.model_dump_json(indent=1))
    scene = scene_from_case(case)
    loading = loading_from_case(case)
    sim = Simulation(scene, case.material, case.solver, gravity=loading.g0)
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

    deepest = {"depth": 0.0, "t": 0.0}

    def record():
        st = sim.state
        t = sim.t
        d = sim.contacts.max_depth()
        if d > deepest["depth"]:
            deepest.update(depth=d, t=t)
        extra = {}
        if isinstance(loading, Tilt):
            extra["tilt_angle"] = float(loading.angle(t)[0])
        base = loading.base_disp(np.array([t]))[0]
        if vtk is not None and len(rec.cols["t"]) % case.run.vtk_every == 0:
            vtk.add_frame(t, st.pos[:n], st.quat[:n], st.vel[:n], base,
                          contacts=sim.contacts.active_points() if case.run.contacts else None)
        rec.add(t, st.pos[:n], st.quat[:n], st.vel[:n], st.omega[:n], base, **extra)

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
        summary["max_penetration_m"] = deepest["depth"]
        summary["max_penetration_time_s"] = deepest["t"]
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
            rec.write()
            if instruments is not None and instruments.rows["t"]:
                _save_npz(out / "instruments.npz", instruments.arrays())
            if vtk is not None:
                vtk.close()
                summary["vtk_frames"] = vtk.n_frames
                summary["vtk_bytes"] = vtk.bytes_written
            if case.run.snapshot and rec.cols["t"]:
                _snapshot(out / "final.png", scene, rec, case.name)
            _write_json(out / "summary.json", summary)

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
                _write_json(out / "summary.json", summary)
                last_flush = now
    except SimulationError as err:
        record()
        finish("failed", str(err))
        bar.close()
        raise
    except KeyboardInterrupt:
        finish("interrupted", "interrupted by the user")
        bar.close()
        raise
    bar.close()
    finish("ok")
    arrays = rec.arrays()
    extra = {k: v for k, v in arrays.items()
             if k not in ("t", "pos", "quat", "vel", "omega", "base_disp")}
    return RunResult(arrays["t"], arrays["pos"], arrays["quat"], arrays["vel"],
                     arrays["base_disp"], summary, extra, scene)


def run_case_file(path: str | Path, out: str | Path, progress: bool = True) -> int:
    """CLI body of ``dem run``: returns the exit code (0 ok, 1 run failed, 2 bad input)."""
    import typer

    from dem.engine import InputError, SimulationError

    try:
        case = load_case(path)
    except CaseError as err:
        typer.echo(f"error: {err}", err=True)  # the message starts with path:line:
        return 2
    try:
        res = simulate(case, out, progress=progress)
    except (InputError, ValueError) as err:
        typer.echo(f"error: {path}: {err}", err=True)
        return 2
    except SimulationError as err:
        typer.echo(f"run failed: {err}\nframes written so far are in {out}/frames.npz", err=True)
        return 1
    except KeyboardInterrupt:
        typer.echo(f"interrupted; frames written so far are in {out}/frames.npz", err=True)
        return 1
    s = res.summary
    typer.echo(
        f"{s['name']}: {s['n_blocks']} blocks, {s['steps']} steps of {s['dt']:.3g} s, "
        f"t = {s['sim_time']:.3f} s in {s['wall_seconds']:.1f} s wall "
        f"({s['compile_seconds']:.1f} s compile, {s['brick_steps_per_second']:.3g} brick-steps/s); "
        f"output in {out}")
    return 0
