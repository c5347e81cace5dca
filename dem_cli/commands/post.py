"""``dem post DIR``: (re)build the analysis of what DIR holds (:func:`directory_kind`):

* a run (``case.json``): a shake run through postprocess.shake, a tilt run through
  postprocess.tilt, a stepped shake through postprocess.stepped, a sweep or a noise through
  postprocess.identification (identification.json, identification.png);
* a sweep (``sweep.json``, or point directories of a shake case): every point re-analysed,
  postprocess.sweep re-aggregates;
* an ensemble (``ensemble.json`` of ``dem ensemble``): every realisation's results re-read (a
  shaking realisation re-analysed), the statistics re-aggregated (postprocess.ensemble) and
  ensemble.json / lambda.png rewritten;
* an ensemble of sweeps (``dem sweep --realisations``): every realisation's sweep re-analysed,
  ensemble.json and amplification_band.png re-aggregated
  (dem_cli.commands.sweep.aggregate_sweep_realisations);
* a two-body rocking run: nothing to do (``dem rocking`` writes its analysis);
* anything else: one line saying what DIR is, exit 2.

The exit code: dem_cli.commands.exit_codes.
"""

from __future__ import annotations

import json
from pathlib import Path

from dem_cli.commands.exit_codes import ExitCode, exit_code_for
from dem_cli.commands.sweep import say
from dem.run.sweep import SweepInputError
from postprocess.sweep import characteristic_text, finite, is_sweep_dir, post_sweep


def run_state(path: Path) -> str | None:
    """A run directory that is not a finished run, in words (docs/interrupted-runs.md), or None
    for a finished one (summary.json 'ok' or 'failed'):

    * a live process holds run.lock: "running, pid N, t = x s" (t: the simulated time of its
      last checkpoint, "before its first checkpoint" without summary.json);
    * summary.json 'running' and no holder: killed (SIGKILL, power loss) at its last
      checkpoint;
    * 'interrupted': stopped by a signal at t = x s;
    * no summary.json and no holder: it never started, or was killed before its first
      checkpoint."""
    from dem.rundir import lock_holder

    summ = _read_json(path / "summary.json")
    pid = lock_holder(path)
    t = (summ or {}).get("sim_time")
    at = f"t = {float(t):.4g} s" if isinstance(t, (int, float)) else None
    if pid is not None:
        who = f"pid {pid}" if pid else "pid unknown"
        return f"running, {who}, " + (f"{at} at its last checkpoint" if at and summ else
                                       "before its first checkpoint")
    if summ is None:
        return ("never started, or was killed before its first checkpoint (no summary.json, "
                "no process holds it)")
    status = summ.get("status")
    if status == "running":
        return (f"killed (SIGKILL, power loss): no process holds it; its last checkpoint is at "
                f"{at or 't = 0 s'}")
    if status == "interrupted":
        return f"{summ.get('error') or 'interrupted'} at {at or 't = 0 s'}"
    return None


def _read_json(path: Path) -> dict | None:
    try:
        data = json.loads(path.read_text())
    except (OSError, ValueError):
        return None
    return data if isinstance(data, dict) else None


def _loading_type(run_dir: Path) -> str | None:
    """The loading type written in a run directory's case.json (None: unreadable)."""
    data = _read_json(run_dir / "case.json") or {}
    ld = data.get("loading")
    return ld.get("type") if isinstance(ld, dict) else None


def directory_kind(path: Path) -> str:
    """What a directory holds: "rocking", "run", "ensemble", "sweep-ensemble", "sweep",
    "runs" (run directories of a case that is not shaken: not a sweep), or "unknown"."""
    path = Path(path)
    if (path / "rocking.npz").is_file() and not (path / "frames.npz").is_file():
        return "rocking"
    if (path / "case.json").is_file():
        return "run"
    ens = _read_json(path / "ensemble.json")
    if ens is not None and ens.get("kind") in ("ensemble", "sweep-ensemble"):
        return ens["kind"]
    if (path / "sweep.json").is_file():
        return "sweep"
    if is_sweep_dir(path):
        runs = [d for d in sorted(path.iterdir()) if d.is_dir() and (d / "case.json").is_file()]
        return "sweep" if all(_loading_type(d) == "shake" for d in runs) else "runs"
    return "unknown"


def post_command(path) -> int:
    """Body of ``dem post DIR``; returns the exit code."""
    path = Path(path)
    if not path.is_dir():
        say(f"error: {path}: not a directory")
        return ExitCode.BAD_INPUT
    from postprocess.shake_signals import ShakeAnalysisError

    try:
        kind = directory_kind(path)
        if kind == "rocking":
            say(f"{path}: a two-body rocking run; its analysis is written by `dem rocking`")
            return ExitCode.OK
        if kind == "ensemble":
            return post_ensemble(path)
        if kind == "sweep-ensemble":
            return post_sweep_ensemble(path)
        if kind == "sweep":
            data, n_failed = post_sweep(path)
            agg = data["aggregate"]
            say(f"{path}/sweep.json: {len(data['points'])} points, {n_failed} failed; "
                f"{characteristic_text(agg)}")
            return ExitCode.RUN_FAILED if n_failed else ExitCode.OK
        if kind == "runs":
            names = [d.name for d in sorted(path.iterdir()) if (d / "case.json").is_file()]
            say(f"error: {path}: holds {len(names)} run directories ({', '.join(names[:3])}"
                f"{', ...' if len(names) > 3 else ''}) but no sweep.json nor ensemble.json, and "
                f"they are not all shake runs: not a sweep; run `dem post` on each")
            return ExitCode.BAD_INPUT
        if kind == "unknown":
            say(f"error: {path}: not a run (no case.json), a sweep (no sweep.json) nor an "
                f"ensemble (no ensemble.json)")
            return ExitCode.BAD_INPUT
        return post_run(path)
    except (ShakeAnalysisError, SweepInputError) as err:
        say(f"error: {err}")
        return exit_code_for(err)
    except OSError as err:  # an analysis file that cannot be written (full disk ...)
        say(f"error: cannot write the analysis in {path}: {err.strerror or err}"
            + (f" (errno {err.errno})" if err.errno else ""))
        return ExitCode.RUN_FAILED
    except Exception as err:  # noqa: BLE001 - one line, never a traceback
        say(f"error: {path}: the analysis failed: {type(err).__name__}: {err}")
        return ExitCode.RUN_FAILED


def post_run(path: Path) -> int:
    """One run directory (shake or tilt)."""
    from dem.case import ShakeLoading, TiltLoading
    from postprocess.shake import analyze_run
    from postprocess.shake_signals import load_run
    from postprocess.tilt import analyze_tilt_run, plot_lean

    state = run_state(path)
    if not (path / "summary.json").is_file():
        say(f"error: {path}: not a finished run: {state}; nothing to analyse yet")
        return ExitCode.BAD_INPUT
    if state is not None:
        say(f"warning: {path}: the run is not finished: {state}; analysing the frames recorded "
            f"so far" + ("" if state.startswith("running") else
                         " (dem run --resume goes on from its last checkpoint where it can: "
                         "docs/interrupted-runs.md)"))
    case, _ = load_run(path)
    if isinstance(case.loading, ShakeLoading):
        res = analyze_run(path)
        say(f"{path}/analysis.json: amplification "
            + ", ".join(f"{k} {v:.3g}" for k, v in res.get("amplification", {}).items()
                        if finite(v)) + (f"; {res['error']}" if res.get("error") else ""))
        for w in res.get("warnings") or []:
            say(f"warning: {w}")
    elif isinstance(case.loading, TiltLoading):
        res = analyze_tilt_run(path)
        mech = res["mechanism"] or {}
        col = res["collapse"]
        lam = (f" (load factor {col['load_factor']:.3f} at {col['angle_deg']:.2f} deg)"
               if col.get("detected") and col.get("load_factor") is not None else
               " (onset not resolved)" if col.get("detected") else "")
        n_col = (mech.get("collapsed") or {}).get("n_blocks")
        if not col.get("detected") and state is not None:
            # a tilt cut short says nothing about collapse: the table never reached the angle
            # the case asked for
            last = col.get("last_angle_deg")
            say(f"{path}/analysis.json: no collapse up to "
                + (f"{last:.2f} deg" if isinstance(last, (int, float)) else "the stop")
                + f", but the run did not finish ({state}): not a result; the table was to turn "
                  f"to {case.loading.max_angle:g} deg")
        else:
            say(f"{path}/analysis.json: collapse {col['detected']}{lam}, mechanism "
                f"{mech.get('mechanism') or mech.get('kind')}"
                + (f", {n_col} blocks collapsed" if n_col is not None else ""))
        say(f"{plot_lean(path, col)}: lean against the table angle")
    elif case.loading.type == "stepped_shake":   # postprocess.stepped
        from postprocess.stepped import analyze_stepped_run, steps_line

        res = analyze_stepped_run(path)
        say(f"{path}/stepped.json: {steps_line(res)}")
        for w in res.get("warnings") or []:
            say(f"warning: {w}")
    elif case.loading.type in ("sweep", "noise"):   # postprocess.identification
        from postprocess.identification import analyze_identification_run, identification_line

        res = analyze_identification_run(path)
        say(f"{path}/identification.json: {identification_line(res)}")
        for w in res.get("warnings") or []:
            say(f"warning: {w}")
    else:
        say(f"{path}: loading '{case.loading.type}': no analysis defined")
    return ExitCode.OK


def realisation_record(run_dir: Path, shake: bool) -> dict:
    """The record of one realisation directory (as dem.batch makes it: status, summary.json, a
    shaking run's compact analysis, re-analysed here), for postprocess.ensemble."""
    from postprocess.sweep import compact

    summ = _read_json(run_dir / "summary.json")
    rec = {"name": run_dir.name, "out_dir": str(run_dir)}
    if summ is None:
        return {**rec, "status": "failed",
                "error": f"{run_dir / 'summary.json'}: missing or unreadable"}
    if summ.get("status") != "ok":
        return {**rec, "status": "failed", "summary": summ,
                "error": summ.get("error") or f"run status {summ.get('status')!r}"}
    rec.update(status="ok", summary=summ)
    if shake:
        from postprocess.shake import analyze_run

        try:
            rec["post"] = compact(analyze_run(run_dir))
        except Exception as err:  # noqa: BLE001 - one realisation's analysis, reported
            rec["post"] = {"analysis_status": "failed", "error": f"{type(err).__name__}: {err}"}
    return rec


def post_ensemble(path: Path) -> int:
    """Re-read every realisation of a ``dem ensemble`` directory, re-aggregate ensemble.json
    (postprocess.ensemble through dem_cli.commands.ensemble.write_ensemble) and lambda.png."""
    from dem_cli.commands.ensemble import write_ensemble

    old = _read_json(path / "ensemble.json") or {}
    rows = old.get("realisations") or []
    names = [r["name"] for r in rows if isinstance(r, dict) and "name" in r]
    if not names or len(names) != len(old.get("seeds") or []):
        say(f"error: {path}/ensemble.json: no realisations listed (or their seeds do not match "
            f"them); rerun `dem ensemble` into {path}")
        return ExitCode.BAD_INPUT
    shake = any(_loading_type(path / n) == "shake" for n in names)
    records = {n: realisation_record(path / n, shake) for n in names if (path / n).is_dir()}
    meta = {k: v for k, v in old.items() if k not in ("realisations", "aggregate")}
    data = write_ensemble(path, meta, names, records, plots=True)
    agg = data["aggregate"]
    lam = agg["statistics"].get("lambda")
    lam_txt = (f"; lambda median {lam['median']:.4f}, 10-90 % {lam['q10']:.4f} - "
               f"{lam['q90']:.4f}" if lam and lam["n"] else "")
    say(f"{path}/ensemble.json: {agg['n_ok']} of {agg['n_realisations']} realisations ok, "
        f"{agg['n_failed']} failed, {agg['n_pending']} not run{lam_txt}")
    return ExitCode.RUN_FAILED if agg["n_failed"] else ExitCode.OK


def post_sweep_ensemble(path: Path) -> int:
    """``dem sweep --realisations`` directory: every realisation's sweep re-analysed."""
    old = _read_json(path / "ensemble.json") or {}
    names = [r["name"] for r in old.get("realisations") or [] if isinstance(r, dict)
             and "name" in r]
    n_failed = 0
    for n in names:
        d = path / n
        if not (d / "sweep.json").is_file():
            say(f"{d}: no sweep.json (not run)")
            n_failed += 1
            continue
        data, failed = post_sweep(d)
        n_failed += failed
        say(f"{d}/sweep.json: {len(data['points'])} points, {failed} failed; "
            f"{characteristic_text(data['aggregate'])}")
    from dem_cli.commands.sweep import aggregate_sweep_realisations

    seeds = [r.get("seed") for r in old.get("realisations") or [] if isinstance(r, dict)
             and "name" in r]
    meta = {"case": old.get("case"), "source": old.get("source"),
            "imperfections": old.get("imperfections")}
    result = aggregate_sweep_realisations(path, meta, list(zip(names, seeds)))
    fc = result["characteristic_frequency_hz"]
    fc_txt = (f"; characteristic frequency median {fc['median']:.3g} Hz over {fc['n']}"
              if fc.get("n") else "")
    say(f"{path}/ensemble.json: {len(names)} realisations re-aggregated{fc_txt}")
    return ExitCode.RUN_FAILED if n_failed else ExitCode.OK
