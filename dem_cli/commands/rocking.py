"""``dem rocking CASE.yaml --out DIR``: load a two-body case, run the model, write its outputs,
print the result line.  The model-level run and writers are dem.rocking.runner; the outputs are
listed there.  Exit codes (dem_cli.commands.exit_codes): 0 ok (also when the wall collapses: that is
a result), 1 the integration failed (what was computed is written, the message says where and
why), 2 bad input.
"""

from __future__ import annotations

import time
from pathlib import Path

from dem_cli.commands.exit_codes import ExitCode, exit_code_for
from dem.rocking.runner import run_rocking_case, write_outputs
from dem.rocking.schema import RockingCaseError, load_rocking_case, rocking_plausibility


def load_checked(path, err=print, overrides: dict | None = None):
    """The case at ``path``, checked (schema, then plausibility: warnings printed), or None
    after printing why (exit 2): ``dem check`` and ``dem rocking`` say the same."""
    try:
        case = load_rocking_case(path, overrides)
    except RockingCaseError as e:
        err(f"error: {e}")
        return None
    warnings, errors = rocking_plausibility(case, path)
    for w in warnings:
        err(f"warning: {w}")
    for e in errors:
        err(f"error: {e}")
    return None if errors else case


def rocking_command(path, out, plots: bool = True, force: bool = False, echo=print,
                    err=print) -> ExitCode:
    """Body of ``dem rocking`` (and ``dem run`` of a two-body case): the case is checked before
    --out is claimed (dem.rundir), so bad input leaves no empty --out behind."""
    from dem.rundir import RunDirError, claim

    case = load_checked(path, err)
    if case is None:
        return ExitCode.BAD_INPUT
    try:
        rd = claim(out, None, force=force, rerun_marker="rocking.npz")
    except RunDirError as e:
        err(f"error: {e}")
        return exit_code_for(e)
    code = ExitCode.RUN_FAILED
    try:
        code = run_rocking_case_file(path, out, plots=plots, echo=echo, err=err, case=case)
        return code
    finally:
        if code == ExitCode.BAD_INPUT:
            rd.abandon()  # refused by the model before anything was written: no empty --out
        else:
            rd.release()


def run_rocking_case_file(path, out, plots: bool = True, echo=print, err=print,
                          overrides: dict | None = None, case=None) -> ExitCode:
    """Load (unless ``case``: already loaded and checked), run, write; returns the exit code
    (0 ok, 1 run failed, 2 bad input)."""
    t0 = time.perf_counter()
    case = case if case is not None else load_checked(path, err, overrides)
    if case is None:
        return ExitCode.BAD_INPUT
    try:
        P, exc, res, failure = run_rocking_case(case)
    except ValueError as e:  # parameters the model refuses (should have been caught by the schema)
        err(f"error: {path}: {e}")
        return exit_code_for(e)
    out = Path(out)
    try:
        summary = write_outputs(out, case, P, exc, res, time.perf_counter() - t0, plots=plots)
    except OSError as e:  # dem.output.atomic.OutputError: a full disk ...
        err(f"error: {e.strerror or e}")
        return exit_code_for(e)
    if failure is not None:
        err(f"error: {case.name}: the integration failed: {failure}\n"
            f"(results up to t = {summary['sim_time']:.6g} s written to {out})")
        return exit_code_for(failure)
    if summary["status"] == "failed":
        err(f"error: {case.name}: run failed: {summary['message']} (results up to t = "
            f"{summary['sim_time']:.6g} s written to {out}; summary.json says failed)")
        return ExitCode.RUN_FAILED
    amp = summary["response"]["amplitude_steady"]
    amp_txt = (f", steady amplitude +{1e3 * amp['positive_mean_m']:.2f} / "
               f"{1e3 * amp['negative_mean_m']:.2f} mm") if amp else ""
    echo(f"{case.name}: {res.status} in {summary['wall_seconds']:.2f} s, "
         f"{summary['sim_time']:.3g} s simulated, {len(res.events)} events, most frequent "
         f"pattern {summary['most_frequent_pattern_by_occurrences']}{amp_txt} -> {out}")
    if res.status == "collapsed":
        echo(f"  {res.message}")
    return ExitCode.OK
