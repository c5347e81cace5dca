"""``dem ensemble CASE.yaml --out DIR --realisations N [--seed S] [--workers K | --scheduler ADDR]``
runs N realisations of a case with imperfections (docs/imperfections.md), seeds S, S + 1, ...
(S defaults to the case's ``imperfections.seed``), through the batch machinery of ``dem sweep``
(dem.batch: a local dask cluster, or an existing one with ``--scheduler``).

* each realisation runs into DIR/seed-<seed>/ (the case with that seed, named
  <case>-seed<seed>); a tilt run gets its mechanism (dem_cli.commands.run.RUN_ANALYSES), a shaking
  run the sweep's analysis (analysis.json);
* DIR/ensemble.json holds every realisation's scalar results (lambda, mechanism,
  amplifications, lags, excited bricks, survived) and their statistics (median, 10 % and 90 %
  quantiles, mean, standard deviation, counts of mechanisms and failures: postprocess.ensemble);
  it is written when the ensemble starts and again as each realisation lands, so an interrupted
  ensemble keeps what finished; DIR/lambda.png shows the distribution of lambda;
* a rerun into the same DIR skips the realisations whose directory holds a finished run of the
  same case (summary.json status "ok", case.json equal), so a long study runs in pieces;
* a failed realisation is reported and loses none of the others; a realisation whose worker
  dies is computed again by dask on another worker (a task lost with its worker is
  rescheduled), and failing that it is reported failed and a rerun computes it;
* ``--batch K``: on a GPU (``--arch cuda``) the realisations run K to an engine
  (dem.run.batched, as ``dem sweep --batch``); on the CPU one to an engine, as without it.

Exit code: 0 all realisations ok, 1 one failed, 2 bad input (dem_cli.commands.exit_codes).
"""

from __future__ import annotations

import json
from pathlib import Path

from dem_cli.commands.exit_codes import ExitCode, exit_code_for
from dem_cli.commands.sweep import (batching, check_counts, finished_run, mark_stopped_runs,
                                points_ok, resume_notes, say, workers_text)
from dem.run.sweep import EnsembleInputError, realisation_cases
from postprocess.ensemble import aggregate, plot_lambda, realisation_scalars


def finished_realisation(case, out_dir: Path, shake: bool,
                         max_steps: int | None = None) -> dict | None:
    """The record of a realisation whose directory holds a finished run of ``case``
    (dem_cli.commands.sweep.finished_run), else None."""
    summ = finished_run(case, out_dir, max_steps)
    if summ is None:
        return None
    rec = {"name": out_dir.name, "status": "ok", "out_dir": str(out_dir), "summary": summ,
           "reused": True}
    if shake:
        from postprocess.sweep import analyze_point, compact

        try:
            rec["post"] = compact(json.loads((out_dir / "analysis.json").read_text()))
        except (OSError, ValueError):
            rec["post"] = analyze_point(case, None, out_dir)
    return rec


def scalar_text(sc: dict) -> str:
    """One realisation's headline results as text (not a dict repr with 17
    digits): 'lambda 0.4512 (24.28 deg), mechanism overturning, ds amplification 1.23,
    standing'."""
    parts = []
    if sc.get("lambda") is not None:
        parts.append(f"lambda {sc['lambda']:.4f}" + (f" ({sc['angle_deg']:.2f} deg)"
                                                     if sc.get("angle_deg") is not None else ""))
    elif "lambda" in sc:
        parts.append("no collapse")
    if sc.get("mechanism"):
        parts.append(f"mechanism {sc['mechanism']}")
    if sc.get("amplification_ds") is not None:
        parts.append(f"ds amplification {sc['amplification_ds']:.3g}")
    if "survived" in sc and "lambda" not in sc:
        parts.append("standing" if sc["survived"] else "collapsed")
    return ", ".join(parts)


def counts_text(counts: dict) -> str:
    """Mechanism counts as text, most frequent first: '7 x overturning, 1 x sliding' (not a
    Python dict)."""
    if not counts:
        return "none"
    return ", ".join(f"{n} x {name}" for name, n in sorted(counts.items(),
                                                           key=lambda kv: (-kv[1], kv[0])))


def write_ensemble(out: Path, meta: dict, names: list[str], records: dict, plots: bool) -> dict:
    from dem.output.atomic import write_json

    rows = []
    for n in names:
        rec = records.get(n) or {"status": "pending"}
        row = {"name": n, "seed": meta["seeds"][names.index(n)], **realisation_scalars(rec)}
        if rec.get("status") == "failed":
            row["error"] = rec.get("error")
        if rec.get("reused"):
            row["reused"] = True
        rows.append(row)
    data = {**meta, "realisations": rows, "aggregate": aggregate(rows)}
    write_json(out / "ensemble.json", data, indent=1, strict=True)
    if plots:
        plot_lambda(rows, out / "lambda.png", meta["case"])
    return data


def run_ensemble(case_path, out, realisations: int, seed: int | None = None,
                 scheduler: str | None = None, workers: int | None = None,
                 max_steps: int | None = None, drain_file: Path | None = None,
                 batch: int | None = None, arch: str = "cpu") -> int:
    """Body of ``dem ensemble``; returns the exit code.  ``drain_file``: once it exists no new
    realisation starts and those in flight finish (dem.batch, "Draining"); exit code 1.
    ``batch``: the realisations K to an engine; ``arch``: "cpu" or "cuda" (dem.batch)."""
    from dem.batch import Drained, drain_file_check, run_batch
    from dem.case import CaseError, ShakeLoading, load_case
    from dem_cli.commands.run import RUN_ANALYSES
    from postprocess.sweep import analyze_point

    out = Path(out)
    try:
        case = load_case(case_path)
        cases = realisation_cases(case, realisations, seed)
        check_counts(workers, max_steps, EnsembleInputError)
        batch_options = batching(batch, arch, scheduler)
    except CaseError as err:
        say(f"error: {err}")
        return exit_code_for(err)
    except ValueError as err:
        say(f"error: {case_path}: {err}")
        return exit_code_for(err)
    if not points_ok(cases, case_path, "realisation"):  # each as dem check, before any runs
        return ExitCode.BAD_INPUT
    if out.exists() and not out.is_dir():
        say(f"error: --out {out}: exists and is not a directory")
        return ExitCode.BAD_INPUT
    if (out / "case.json").is_file():
        say(f"error: --out {out}: holds a single run (case.json), not an ensemble")
        return ExitCode.BAD_INPUT
    try:
        out.mkdir(parents=True, exist_ok=True)
    except OSError as err:
        say(f"error: --out {out}: cannot create it ({err.strerror or err})")
        return ExitCode.BAD_INPUT
    if not case.imperfections.any():
        say("warning: the case has no imperfections: every realisation is the same perfect "
            "model")
    shake = isinstance(case.loading, ShakeLoading)
    names = [n for n, _ in cases]
    meta = {"kind": "ensemble", "case": case.name, "source": str(case_path),
            "imperfections": case.imperfections.model_dump(),
            "seeds": [c.imperfections.seed for _, c in cases]}
    records: dict = {}
    for n, c in cases:
        rec = finished_realisation(c, out / n, shake, max_steps)
        if rec is not None:
            records[n] = rec
    if records:
        say(f"{len(records)} realisation(s) already finished in {out}, kept")
    todo = [(n, c) for n, c in cases if n not in records]
    notes = resume_notes(out, [n for n, _ in todo])
    if notes:
        say(f"{len(notes)} realisation(s) resume from their last checkpoint (what ran after it "
            f"is computed again): {', '.join(notes)}")
    write_ensemble(out, meta, names, records, plots=False)
    n_done = [0]

    def on_done(rec: dict) -> None:
        n_done[0] += 1
        records[rec["name"]] = rec
        sc = realisation_scalars(rec)
        head = f"[{n_done[0]}/{len(todo)}] {rec['name']}"
        if rec.get("status") == "failed":
            say(f"{head}: FAILED: {rec.get('error')}")
        else:
            say(f"{head}: ok" + (f": {scalar_text(sc)}" if scalar_text(sc) else ""))
        write_ensemble(out, meta, names, records, plots=False)

    where = workers_text(scheduler, workers, batch, arch)
    say(f"ensemble {case.name}: {len(cases)} realisations, seeds {meta['seeds'][0]}.."
        f"{meta['seeds'][-1]} ({len(todo)} to run), {where}")
    from dem.signals import signal_name, stop_on_signals

    try:
        with stop_on_signals():
            if todo:
                run_batch(todo, out, scheduler=scheduler, n_workers=workers, max_steps=max_steps,
                          post=analyze_point if shake else None, on_done=on_done,
                          analyses=() if shake else RUN_ANALYSES,
                          drain=None if drain_file is None else drain_file_check(drain_file),
                          **batch_options)
    except Drained as err:
        say(f"drained ({drain_file} exists): the realisations in flight finished; "
            f"{len(err.not_started)} not started ({', '.join(err.not_started)}); finished ones "
            f"are in {out}/ensemble.json (a rerun of the same command keeps them)")
        return ExitCode.RUN_FAILED
    except KeyboardInterrupt as err:
        stopped = mark_stopped_runs(out, [n for n, _ in todo], signal_name(err))
        say(f"interrupted by {signal_name(err)}; finished realisations are in "
            f"{out}/ensemble.json (a rerun of the same command keeps them)"
            + (f"; stopped: {', '.join(stopped)} (a rerun resumes each from that checkpoint)"
               if stopped else ""))
        return exit_code_for(err)
    data = write_ensemble(out, meta, names, records, plots=True)
    agg = data["aggregate"]
    lam = agg["statistics"].get("lambda")
    if lam and lam["n"]:
        say(f"lambda: median {lam['median']:.4f}, 10-90 % {lam['q10']:.4f} - {lam['q90']:.4f} "
            f"({lam['n']} realisations); mechanisms: {counts_text(agg['mechanisms'])}")
    say(f"{agg['n_ok']} of {agg['n_realisations']} realisations ok; {out}/ensemble.json")
    return ExitCode.RUN_FAILED if agg["n_failed"] else ExitCode.OK
