"""``dem post DIR``: (re)build the analysis of a run directory (shake: postprocess.shake; tilt:
postprocess.tilt) or of a sweep directory (postprocess.sweep); a two-body rocking run is analysed
by ``dem rocking`` itself.  The exit code: dem.commands.exit_codes.
"""

from __future__ import annotations

import json
from pathlib import Path

from dem.commands.exit_codes import ExitCode, exit_code_for
from dem.commands.sweep import say
from dem.run.sweep import SweepInputError
from postprocess.sweep import characteristic_text, finite, is_sweep_dir, post_sweep


def _locked(path: Path) -> bool:
    """Whether a live run holds DIR/run.lock (dem.rundir)."""
    import fcntl

    lock = path / "run.lock"
    if not lock.is_file():
        return False
    with open(lock, "rb") as fh:
        try:
            fcntl.flock(fh.fileno(), fcntl.LOCK_EX | fcntl.LOCK_NB)
        except BlockingIOError:
            return True
        fcntl.flock(fh.fileno(), fcntl.LOCK_UN)
    return False


def post_command(path) -> int:
    """Body of ``dem post DIR``; returns the exit code."""
    from dem.case import ShakeLoading, TiltLoading
    from postprocess.shake import analyze_run
    from postprocess.shake_signals import ShakeAnalysisError, load_run
    from postprocess.tilt import analyze_tilt_run, plot_lean

    path = Path(path)
    if not path.is_dir():
        say(f"error: {path}: not a directory")
        return ExitCode.BAD_INPUT
    try:
        if (path / "rocking.npz").is_file() and not (path / "frames.npz").is_file():
            say(f"{path}: a two-body rocking run; its analysis is written by `dem rocking`")
            return ExitCode.OK
        if is_sweep_dir(path):
            data, n_failed = post_sweep(path)
            agg = data["aggregate"]
            say(f"{path}/sweep.json: {len(data['points'])} points, {n_failed} failed; "
                 f"{characteristic_text(agg)}")
            return ExitCode.RUN_FAILED if n_failed else ExitCode.OK
        if not (path / "case.json").is_file():
            say(f"error: {path}: not a run directory (no case.json) nor a sweep (no sweep.json)")
            return ExitCode.BAD_INPUT
        if not (path / "summary.json").is_file():
            say(f"error: {path}: not a run: no summary.json (the run never started, or was "
                 f"killed before its first checkpoint)")
            return ExitCode.BAD_INPUT
        try:
            status = json.loads((path / "summary.json").read_text()).get("status")
        except ValueError:
            status = None
        if status == "running" and not _locked(path):
            say(f"warning: {path}: summary.json says 'running' but no process holds the run: it "
                 f"was killed (SIGKILL, power loss); analysing the frames of its last checkpoint")
        case, _ = load_run(path)
        if isinstance(case.loading, ShakeLoading):
            res = analyze_run(path)
            say(f"{path}/analysis.json: amplification "
                 + ", ".join(f"{k} {v:.3g}" for k, v in res.get("amplification", {}).items()
                             if finite(v)) + (f"; {res['error']}" if res.get("error") else ""))
        elif isinstance(case.loading, TiltLoading):
            res = analyze_tilt_run(path)
            mech = res["mechanism"] or {}
            col = res["collapse"]
            lam = (f" (load factor {col['load_factor']:.3f} at {col['angle_deg']:.2f} deg)"
                   if col.get("detected") else "")
            n_col = (mech.get("collapsed") or {}).get("n_blocks")
            say(f"{path}/analysis.json: collapse {col['detected']}{lam}, mechanism "
                 f"{mech.get('mechanism') or mech.get('kind')}"
                 + (f", {n_col} blocks collapsed" if n_col is not None else ""))
            say(f"{plot_lean(path, col)}: lean against the table angle")
        else:
            say(f"{path}: loading '{case.loading.type}': no analysis defined")
        return ExitCode.OK
    except (ShakeAnalysisError, SweepInputError) as err:
        say(f"error: {err}")
        return exit_code_for(err)
