"""``dem run CASE.yaml --out DIR``: check the case, claim DIR, run the case (dem.run), plot the lean
of a tilt run (lean.png, postprocess.tilt.plot_lean, as ``dem post`` does), print the result
line.  The analyses a run gets in its summary.json (the mechanism of a tilt) are chosen
here (``RUN_ANALYSES``), so the run loop never imports the analysis.  Exit codes:
dem_cli.commands.exit_codes; what each failure prints and keeps: docs/failures.md.
"""

from __future__ import annotations

import json
from pathlib import Path

import numpy as np

from dem_cli.commands.exit_codes import ExitCode, exit_code_for
from dem.run import OutputError, run_case
from postprocess.decisive import decisive_numbers
from postprocess.lone_block import reference_limit
from postprocess.survival import survival_analysis
from postprocess.tilt import plot_lean, tilt_mechanism

# read the finished run, merged into summary.json (reference: the closed form of lone blocks;
# survival: standing / local collapse / collapse of a shaking run, every brick)
RUN_ANALYSES = (tilt_mechanism, reference_limit, survival_analysis)


def result_line(summary: dict, arrays: dict | None = None) -> str:
    """The last line of every run: status and the main result of its loading type."""
    status = summary.get("status")
    parts = [f"result: {status}"]
    if summary.get("error"):
        parts.append(str(summary["error"]).splitlines()[0])
    kind = (summary.get("loading") or {}).get("type")
    if kind == "tilt":
        col = summary.get("collapse") or {}
        if col.get("detected") and col.get("load_factor") is None:  # dem.collapse
            parts.append("collapse detected, onset not resolved: "
                         + str(col.get("onset_note") or "no lambda"))
        elif col.get("detected"):
            mech = summary.get("mechanism") or {}
            label = mech.get("mechanism") or mech.get("kind")
            n_col = (mech.get("collapsed") or {}).get("n_blocks", col.get("n_moved"))
            parts.append(f"load factor {col['load_factor']:.3f} at {col['angle_deg']:.2f} deg"
                         + (f", mechanism {label}" if label else "")
                         + (f", {n_col} of {summary.get('n_blocks', '?')} blocks collapsed"
                            if n_col is not None else ""))
        elif col:
            parts.append(f"no collapse up to {col.get('last_angle_deg', 0.0):.2f} deg")
        parts.extend(decisive_numbers(summary))  # closed form, elastic offset
    if arrays is not None and len(arrays.get("t", [])) and kind != "tilt":
        pos = np.asarray(arrays["pos"])
        disp = float(np.linalg.norm(pos - pos[0], axis=2).max()) if pos.size else 0.0
        ld = summary.get("loading") or {}
        if kind in ("shake", "record", "stepped_shake", "sweep", "noise"):
            parts.append(f"peak table acceleration {ld.get('peak_acceleration_m_s2', 0.0):.3g} "
                         f"m/s2, largest block displacement relative to the table "
                         f"{disp * 1e3:.3g} mm ("
                         + ("f_n, zeta" if kind in ("sweep", "noise") else "amplification")
                         + ": dem post)")
        else:
            parts.append(f"largest block displacement {disp * 1e3:.3g} mm")
    parts.append(f"t = {summary.get('sim_time', 0.0):.4g} s")
    return "; ".join(parts)


def run_case_file(path: str | Path, out: str | Path, progress: bool = True, force: bool = False,
                  max_blocks: int | None = None, resume: bool = False) -> int:
    """Body of ``dem run``: returns the exit code (0 ok, 1 run failed or stopped, 2 bad
    input; docs/failures.md).  SIGTERM and SIGHUP stop the run like Ctrl-C (dem.signals)."""
    import typer

    from dem.signals import signal_name, stop_on_signals

    with stop_on_signals():
        try:
            return _run_case_file(path, out, progress, force, max_blocks, resume)
        except KeyboardInterrupt as err:  # before the output directory was claimed
            typer.echo(f"interrupted by {signal_name(err)} before the run started; nothing "
                       f"written", err=True)
            return exit_code_for(err)


def _run_case_file(path, out, progress, force, max_blocks, resume=False) -> int:
    import typer

    from dem.engine import SimulationError
    from dem.rundir import RunDirError, claim
    from dem.signals import signal_name
    from dem.validate import load_and_check

    def err(msg):
        typer.echo(msg, err=True)

    checked = load_and_check(path, err, max_blocks)
    if checked is None:
        return ExitCode.BAD_INPUT
    case = checked.case
    before = _previous_status(Path(out)) if resume else None
    try:
        rd = claim(out, case.model_dump_json(indent=1), force=force, resume=resume)
    except RunDirError as e:
        err(f"error: {e}")
        return exit_code_for(e)
    out = Path(out)
    if resume:
        err(_resume_line(out, case, before))
    try:
        res = run_case(case, out, progress=progress, scene=checked.scene, analyses=RUN_ANALYSES,
                       resume=resume)
    except ValueError as e:  # InputError: bad input the engine found before the first step
        rd.abandon()
        err(f"error: {path}: {e}")
        return exit_code_for(e)
    except SimulationError as e:
        err(f"run failed: {e}\nframes written so far are in {out}/frames.npz")
        err(_summary_result(out))
        return exit_code_for(e)
    except OSError as e:  # OutputError, or a write while the run was being set up
        msg = e.strerror or str(e)
        if not isinstance(e, OutputError):
            msg = f"cannot write the output in {out}: {msg}" + (f" (errno {e.errno})"
                                                                 if e.errno else "")
        err(f"error: {msg}")
        return exit_code_for(e)
    except KeyboardInterrupt as e:
        if (out / "summary.json").is_file():
            err(f"interrupted by {signal_name(e)}; summary.json says 'interrupted', frames so "
                f"far are in {out}/frames.npz")
            err(_summary_result(out))
        else:
            rd.abandon()
            err(f"interrupted by {signal_name(e)} before the first step; nothing written")
        return exit_code_for(e)
    finally:
        rd.release()
    s = res.summary
    refused = (s.get("resume") or {}).get("refused") if resume and not s.get("resumed") else None
    if refused and (out / "summary.json").is_file():
        err(f"resume: could not go on from the checkpoint after all ({refused}); the run "
            f"started over from t = 0")
    if case.loading.type == "tilt":
        _plot_lean(out, err)
    typer.echo(
        f"{s['name']}: {s['n_blocks']} blocks, {s['steps']} steps of {s['dt']:.3g} s, "
        f"t = {s['sim_time']:.3f} s in {s['wall_seconds']:.1f} s wall "
        f"({s['compile_seconds']:.1f} s compile, {s['brick_steps_per_second']:.3g} brick-steps/s); "
        f"output in {out}")
    typer.echo(result_line(s, {"t": res.t, "pos": res.pos}))
    return ExitCode.OK


def _previous_status(out: Path) -> str | None:
    """summary.json's status in OUT before the claim (which may clear it), for the resume
    message."""
    try:
        return json.loads((out / "summary.json").read_text()).get("status")
    except (OSError, ValueError, AttributeError):
        return None


def _resume_line(out: Path, case, before: str | None) -> str:
    """One line on what --resume does (dem.run.resume.resume_outlook)."""
    from dem.rundir import RESTART_FILE

    if not (out / RESTART_FILE).is_file():
        why = (f"the run in {out} finished ('{before}')" if before in ("ok", "failed") else
               f"no restart point ({RESTART_FILE}) in {out}")
        return f"cannot resume: {why}; starting over from t = 0"
    from dem.run.resume import resume_outlook

    return resume_outlook(out, case)


def _plot_lean(out: Path, err) -> None:
    """lean.png of a finished tilt run (postprocess.tilt.plot_lean, what ``dem post`` also
    writes); a plot that cannot be made is reported, not fatal: the run's results are written."""
    try:
        plot_lean(out)
    except Exception as e:  # noqa: BLE001 - the run is done; say why the plot is missing
        err(f"warning: lean.png not written: {e}")


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
