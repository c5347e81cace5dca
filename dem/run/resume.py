"""Resume a run from its last checkpoint (``restart.npz``).

A run whose loading goes on in time (shake, record, constant-rate tilt without the collapse
detector) and writes no VTK series can resume: at every checkpoint (dem.run.write, every
``CHECKPOINT_SECONDS`` of wall-clock time or, for the points of a large batch, as paced by
``CheckpointPace``; always between two frames) it writes OUT/restart.npz,
after frames.npz and before summary.json:

* ``sim.*``, ``state.*``, ``contacts.*``, ``control.*``: the engine's evolving arrays and clock
  (:meth:`dem.engine.simulation.Simulation.snapshot`);
* ``rec.*``: the recording's schedule (next frame, next instrument sample), the number of frames
  that frames.npz then held, the instrument samples so far and the last one's velocities;
* ``summary``: what summary.json then said (the settling record among it), ``case``: the case,
  ``format`` and ``results_revision``.

``dem run --resume`` and every point of a sweep (dem.batch) whose directory holds a run of the
same case that did not finish (summary.json ``running`` or ``interrupted``: killed, cut by a
time limit, stopped by a signal) and a usable restart.npz go on from that checkpoint instead of
starting over: the frames recorded after it are dropped and made again, and the run is, bit for
bit, the one an uninterrupted process would have made on the same machine (tests/test_resume.py).
Not usable, and the run starts over from t = 0 after clearing the directory (:func:`load_restart`
says why): another results revision, format or case, another kernel (serial / parallel) or
precision or scene size, a file that cannot be read, a frames.npz shorter than the checkpoint.

summary.json of a resumed run lists each resumption in ``resumed`` (step, sim_time, the wall
seconds before it and the machine's CPU) and counts ``wall_seconds`` and ``compile_seconds``
over all its processes.  A run that ends ``ok`` removes its restart.npz.  On another machine the
run goes on with that machine's rounding: each segment is a valid simulation, but the whole is not
bit-identical to an uninterrupted run there (the resumed list names the machines).
"""

from __future__ import annotations

import contextlib
import json
import platform
from pathlib import Path

import numpy as np

from dem.engine import RESULTS_REVISION
from dem.loading import HeldTilt
from dem.output.atomic import save_npz
from dem.rundir import RESTART_FILE  # the file's name is kept where claim() needs it
from dem.case.identity import same_case

FORMAT = 1
RESUMABLE_STATUS = ("running", "interrupted")


def unresumable_reason(case, loading, stop) -> str | None:
    """Why a run of ``case`` cannot write restart points (None: it can)."""
    if isinstance(loading, HeldTilt):
        return "a quasi-static tilt (its search is not a loop in time)"
    if stop.detector is not None:
        return "a tilt with the collapse detector (its state is not saved)"
    if case.run.vtk:
        return "run.vtk (the VTK series is not saved)"
    return None


def machine() -> str:
    """The CPU model (/proc/cpuinfo), else platform.processor(), else the architecture."""
    with contextlib.suppress(OSError):
        for line in Path("/proc/cpuinfo").read_text().splitlines():
            if line.startswith("model name"):
                return line.split(":", 1)[1].strip()
    return platform.processor() or platform.machine()


def restart_arrays(case, sim, recording, summary: dict) -> dict[str, np.ndarray]:
    """The content of restart.npz at this moment (module docstring)."""
    out = sim.snapshot()
    out["format"] = np.array(FORMAT)
    out["results_revision"] = np.array(RESULTS_REVISION)
    out["case"] = np.array(case.model_dump_json())
    out["summary"] = np.array(json.dumps(summary))
    out["rec.next_frame"] = np.array(recording.next_frame)
    out["rec.next_sample"] = np.array(recording.next_sample)
    out["rec.n_frames"] = np.array(recording.frames.n_frames)
    ins = recording.instruments
    if ins is not None:
        out.update({f"rec.instruments.{k}": np.asarray(v) for k, v in ins.rows.items()})
        if ins.last is not None:
            out["rec.last.t"] = np.array(ins.last[0])
            out["rec.last.v_abs"] = np.asarray(ins.last[1])
            out["rec.last.table_vel"] = np.asarray(ins.last[2])
    return out


def write_restart(out: Path, arrays: dict[str, np.ndarray]) -> None:
    """OUT/restart.npz, atomically, uncompressed (it is rewritten at every checkpoint)."""
    save_npz(Path(out) / RESTART_FILE, arrays, compressed=False)


def remove_restart(out: Path | None) -> None:
    if out is not None:
        with contextlib.suppress(FileNotFoundError):
            (Path(out) / RESTART_FILE).unlink()


def load_restart(out: Path, case) -> tuple[dict | None, str]:
    """(restart.npz's arrays, "") if ``out`` holds a run of ``case`` that can go on from it, else
    (None, why not).  The engine-side fit (kernel, precision, sizes) is checked by
    :func:`apply_restart`."""
    out = Path(out)
    path = out / RESTART_FILE
    if not path.is_file():
        return None, f"no {RESTART_FILE}"
    try:
        status = json.loads((out / "summary.json").read_text()).get("status")
    except (OSError, ValueError) as err:
        return None, f"summary.json unreadable ({err})"
    if status not in RESUMABLE_STATUS:
        return None, f"summary.json says '{status}'"
    try:
        with np.load(path, allow_pickle=False) as z:
            arrays = {k: z[k] for k in z.files}
    except (OSError, ValueError, EOFError) as err:
        return None, f"{RESTART_FILE} unreadable ({err})"
    if int(arrays.get("format", -1)) != FORMAT:
        return None, f"{RESTART_FILE} format {arrays.get('format')}, this code reads {FORMAT}"
    if int(arrays.get("results_revision", -1)) != RESULTS_REVISION:
        return None, (f"{RESTART_FILE} from results revision {arrays.get('results_revision')}, "
                      f"this engine is {RESULTS_REVISION}")
    if not same_case(json.loads(str(arrays["case"])), case):
        return None, f"{RESTART_FILE} is of another case"
    return arrays, ""


def apply_restart(arrays: dict, sim, recording) -> tuple[dict | None, str]:
    """Put the engine and the recording back to the checkpoint; returns (the summary saved with
    it, "") or (None, why not), having changed nothing in the latter case."""
    n = int(arrays["rec.n_frames"])
    try:
        with np.load(recording.frames.out_dir / "frames.npz", allow_pickle=False) as z:
            frames = {k: z[k] for k in z.files}
    except (OSError, ValueError, EOFError) as err:
        return None, f"frames.npz unreadable ({err})"
    if len(frames.get("t", ())) < n:
        return None, f"frames.npz holds {len(frames.get('t', ()))} frames, the checkpoint {n}"
    ins = recording.instruments
    if (ins is None) != ("rec.instruments.t" not in arrays):
        return None, "the instruments differ from the checkpoint's"
    try:
        sim.restore(arrays)
    except (ValueError, KeyError) as err:
        return None, str(err)
    fr = recording.frames
    frames.pop("units", None)  # written by FrameRecorder.write from the keys (dem.units)
    for k, v in frames.items():
        (fr.cols if k in fr.cols else fr.extra)[k] = list(v[:n])
    if ins is not None:
        for k in ins.rows:
            ins.rows[k] = list(arrays[f"rec.instruments.{k}"])
        ins.last = (float(arrays["rec.last.t"]), arrays["rec.last.v_abs"].copy(),
                     arrays["rec.last.table_vel"].copy()) if "rec.last.t" in arrays else None
    recording.next_frame = float(arrays["rec.next_frame"])
    recording.next_sample = float(arrays["rec.next_sample"])
    return json.loads(str(arrays["summary"])), ""


def resume_outlook(out: Path, case) -> str:
    """What ``dem run --resume`` will do with ``out`` (claimed, before the run starts), in one
    line: "resuming from t = ... s (step ..., checkpoint of ...)" or "cannot resume: why;
    starting over from t = 0" (so that --resume never says nothing).  The run loop has
    the last word (dem.run.loop: an engine that does not fit the checkpoint); the command
    reports a late refusal after the run from summary.json ``resume.refused``."""
    arrays, why = load_restart(out, case)
    if arrays is None:
        return f"cannot resume: {why}; starting over from t = 0"
    s = json.loads(str(arrays["summary"]))
    return (f"resuming from t = {float(s.get('sim_time', 0.0)):.6g} s (step "
            f"{int(s.get('steps', 0))}, the last checkpoint in {out})")
