"""``dem sweep CASE.yaml --out DIR --frequencies 1.8,2.0 --range 2.2:3.6:0.2`` runs the case once
per frequency (the cases: dem.run.sweep), each run independent (dem.batch.run_batch: a local dask cluster sized to the cores with
Taichi capped at one thread per worker, or an existing cluster with ``--scheduler``):

* constant peak acceleration if the case gives ``loading.peak_acceleration`` (the amplitude
  follows, A = a_p / (2 pi f)^2: the thesis' Models II and III), else constant amplitude (Model I
  group 1 / 4);
* ``cycles`` from the case or ``--cycles``; run.duration = cycles / f + ``margin`` (default 1 s,
  as in the case files: free motion after the shaking);
* each run writes DIR/f<frequency>Hz/ (summary.json, frames.npz, instruments.npz, ...); its
  analysis (postprocess.shake.analyze_run: analysis.json and PNGs) runs on the worker, and only a
  compact record travels back;
* DIR/sweep.json is written when the sweep starts (every point "pending") and rewritten as each
  point lands, so an interrupted sweep keeps what finished; ``dem post DIR`` rebuilds it from the
  run directories;
* a rerun into the same DIR skips every point whose directory holds a finished run of the same
  point case (summary.json status "ok", case.json equal): it is read back (its analysis.json, or
  analysed again if that is missing), not recomputed; the others (killed, failed, changed) run
  again into their cleared directories.  SIGTERM / SIGHUP stop a sweep like Ctrl-C;
* ``--batch K``: with ``--arch cuda`` the points run K to an engine (dem.run.batched: K scenes
  in one Taichi engine, one kernel launch for all, each point written as a lone run; dask
  spreads the engines over the workers); on the CPU one point to an engine, as without it
  (dem.run.batched.engine_groups: an engine of K on one core is slower per scene-step);
  ``--arch cuda`` runs the engines on a CUDA GPU (an error, before anything runs, where Taichi
  finds none).

The exit code: dem_cli.commands.exit_codes.
"""

from __future__ import annotations

import contextlib
import json
import os
import sys
from pathlib import Path

from dem_cli.commands.exit_codes import ExitCode, exit_code_for
from dem.engine import RESULTS_REVISION
from dem.run.sweep import DEFAULT_MARGIN, SweepInputError, parse_frequencies, sweep_cases
from postprocess.sweep import (MAIN_QUANTITY, analyze_point, characteristic_text, compact,
                               finite, point_record, sweep_meta, write_sweep)
from dem.case.identity import same_case


def say(msg: str) -> None:
    """Progress and errors of a command go to stderr."""
    print(msg, file=sys.stderr, flush=True)


def finished_run(case, out_dir: Path, max_steps: int | None = None) -> dict | None:
    """summary.json of ``out_dir`` if it holds a finished run that a rerun of ``case`` would
    repeat: the same case.json, status ok, the same step cap ``max_steps`` (a smoke run is never
    taken for a full one) and the same engine results revision (dem.engine.RESULTS_REVISION: a
    run an engine with different physics finished is not mixed in); else None."""
    try:
        summ = json.loads((out_dir / "summary.json").read_text())
        same = same_case(json.loads((out_dir / "case.json").read_text()), case)
    except (OSError, ValueError):
        return None
    if not same or summ.get("status") != "ok" or summ.get("step_limit") != max_steps \
            or summ.get("results_revision") != RESULTS_REVISION:
        return None
    return summ


def finished_point(case, out_dir: Path, max_steps: int | None = None) -> dict | None:
    """The record of a point whose directory already holds a finished run of ``case``
    (:func:`finished_run`), else None."""
    summ = finished_run(case, out_dir, max_steps)
    if summ is None:
        return None
    try:
        post = compact(json.loads((out_dir / "analysis.json").read_text()))
    except (OSError, ValueError):
        post = analyze_point(case, None, out_dir)
    return {"name": out_dir.name, "status": "ok", "out_dir": str(out_dir), "summary": summ,
            "post": post, "reused": True}


def run_sweep(case_path, out, frequencies: str | None = None, rng: str | None = None,
              cycles: float | None = None, margin: float = DEFAULT_MARGIN,
              scheduler: str | None = None, workers: int | None = None,
              max_steps: int | None = None, realisations: int | None = None,
              seed: int | None = None, case=None, reraise_interrupt: bool = False,
              drain_file: Path | None = None, batch: int | None = None,
              arch: str = "cpu", max_points: int | None = None) -> int:
    """Body of ``dem sweep``; returns the exit code (0 all ok, 1 a point failed, 2 bad input).

    ``realisations``: the sweep runs once per realisation of the case's imperfections (seeds
    ``seed``, ``seed`` + 1, ...: dem.run.sweep.realisation_cases), each a whole sweep in
    OUT/seed-<seed>/ (resumable like any sweep), then OUT/ensemble.json and
    amplification_band.png gather the amplification curves (median, 10-90 %:
    postprocess.ensemble).  ``case``: the loaded case (else read from case_path).
    ``drain_file``: once this file exists no new point starts; the points in flight finish
    (dem.batch, "Draining"), the exit code is 1 and, with realisations, the loop stops too.
    None: no draining (the caller clears a leftover file: dem.batch.clear_drain_file).
    ``batch``: the points K to an engine; ``arch``: "cpu" or "cuda" (dem.batch.run_batch)."""
    from dem.batch import Drained, drain_file_check, run_batch
    from dem.case import CaseError, load_case

    out = Path(out)
    if realisations is not None or seed is not None:
        return run_sweep_realisations(case_path, out, frequencies, rng, cycles, margin,
                                      scheduler, workers, max_steps, realisations, seed,
                                      drain_file, batch, arch, max_points)
    try:
        case = load_case(case_path) if case is None else case
        freqs = parse_frequencies(frequencies, rng, max_points)
        if rng:
            own = parse_frequencies(None, rng, max_points)
            say(f"--range {rng}: {len(own)} frequencies, {own[0]:g} - {own[-1]:g} Hz")
        cases = sweep_cases(case, freqs, cycles, margin)
        check_counts(workers, max_steps, SweepInputError)
        batch_options = batching(batch, arch, scheduler)
    except CaseError as err:
        say(f"error: {err}")
        return exit_code_for(err)
    except ValueError as err:  # SweepInputError, SceneError, BatchInputError
        say(f"error: {case_path}: {err}")
        return exit_code_for(err)
    if not points_ok(cases, case_path, "point"):
        return ExitCode.BAD_INPUT
    if out.exists() and not out.is_dir():
        say(f"error: --out {out}: exists and is not a directory")
        return ExitCode.BAD_INPUT
    if (out / "case.json").is_file():
        say(f"error: --out {out}: holds a single run (case.json), not a sweep; choose another "
             f"directory")
        return ExitCode.BAD_INPUT
    try:
        out.mkdir(parents=True, exist_ok=True)
    except OSError as err:
        say(f"error: --out {out}: cannot create it ({err.strerror or err})")
        return ExitCode.BAD_INPUT
    meta = sweep_meta(case, freqs, cycles, margin, case_path)
    by_name = {n: (f, c) for f, (n, c) in zip(freqs, cases)}
    points = {n: point_record(f, c, {"status": "pending"}, out)
              for n, (f, c) in by_name.items()}
    reused = {}
    for n, (f, c) in by_name.items():
        rec = finished_point(c, out / n, max_steps)
        if rec is not None:
            reused[n] = rec
            points[n] = point_record(f, c, rec, out)
            points[n]["reused"] = True
    if reused:
        say(f"{len(reused)} point(s) already finished in {out}, kept: "
             + ", ".join(f"{by_name[n][0]:g} Hz" for n in reused))
    todo = [(n, c) for n, c in cases if n not in reused]
    notes = resume_notes(out, [n for n, _ in todo])
    if notes:
        say(f"{len(notes)} point(s) resume from their last checkpoint (what ran after it is "
            f"computed again): {', '.join(notes)}")
    write_sweep(out, meta, list(points.values()), plots=False)
    n_done = [0]

    def on_done(rec: dict) -> None:
        n_done[0] += 1 if rec["name"] not in reused else 0
        f, c = by_name[rec["name"]]
        p = point_record(f, c, rec, out)
        points[rec["name"]] = p
        head = f"[{n_done[0]}/{len(todo)}] {f:g} Hz"
        if p["status"] == "failed":
            say(f"{head}: FAILED: {p.get('error')}")
        else:
            A = (p.get("amplification") or {}).get(MAIN_QUANTITY)
            a_txt = f"amplification {MAIN_QUANTITY} = {A:.3g}" if finite(A) else \
                f"no amplification ({p.get('note') or 'no steady state'})"
            resumed = ((rec.get("summary") or {}).get("resumed") or [{}])[0].get("sim_time")
            went_on = f", resumed at t = {resumed:.2f} s" if resumed is not None else ""
            say(f"{head}: ok, {a_txt} ({p.get('wall_seconds', 0):.1f} s wall{went_on})")
        write_sweep(out, meta, list(points.values()), plots=False)

    where = workers_text(scheduler, workers, batch, arch)
    say(f"sweep {case.name}: {len(cases)} frequencies {freqs} Hz ({len(todo)} to run), {where}")
    from dem.signals import signal_name, stop_on_signals

    try:
        with stop_on_signals():
            records = run_batch(todo, out, scheduler=scheduler, n_workers=workers,
                                max_steps=max_steps, post=analyze_point, on_done=on_done,
                                drain=None if drain_file is None else
                                drain_file_check(drain_file), **batch_options) if todo else []
    except Drained as err:
        say(f"drained ({drain_file} exists): the points in flight finished; "
            f"{len(err.not_started)} not started: "
            + ", ".join(f"{by_name[n][0]:g} Hz" for n in err.not_started)
            + f"; {out}/sweep.json holds the finished ones (a rerun of the same command runs "
              f"the others)")
        if reraise_interrupt:       # --realisations: the loop over realisations stops too
            raise
        return ExitCode.RUN_FAILED
    except KeyboardInterrupt as err:
        stopped = mark_stopped_runs(out, [n for n, _ in todo], signal_name(err))
        say(f"interrupted by {signal_name(err)}; finished points are in {out}/sweep.json (a rerun"
            f" of the same command keeps them and runs the others)"
            + (f"; stopped: {', '.join(stopped)} (a rerun resumes each from that checkpoint)"
               if stopped else ""))
        if reraise_interrupt:       # --realisations: the loop over realisations stops too
            raise
        return exit_code_for(err)
    for rec in records:  # records the callback may not have seen (should not happen)
        if rec is not None and points[rec["name"]]["status"] == "pending":
            on_done(rec)
    data = write_sweep(out, meta, [points[n] for n, _ in cases])
    agg = data["aggregate"]
    say(f"{characteristic_text(agg)}; {out}/sweep.json")
    if data["failed"]:
        say(f"{len(data['failed'])} of {len(cases)} points failed: "
             + ", ".join(f"{x['frequency_hz']:g} Hz" for x in data["failed"]))
        return ExitCode.RUN_FAILED
    return ExitCode.OK


def mark_stopped_runs(out: Path, names, signame: str) -> list[str]:
    """After a sweep or an ensemble is stopped by a signal: each run directory OUT/<name> whose
    summary.json still says 'running' and that no process holds any more (its worker went with
    the local cluster, before its run could write 'interrupted') is marked 'interrupted' and its
    stale run.lock removed, so that it reads as what it is (docs/interrupted-runs.md).  Returns
    one text per run: its name and the checkpoint time a rerun resumes it from."""
    from dem.output.atomic import write_json
    from dem.rundir import LOCK, RESTART_FILE, lock_holder

    texts = []
    for name in names:
        d = Path(out) / name
        try:
            summ = json.loads((d / "summary.json").read_text())
        except (OSError, ValueError):
            summ = None
        if lock_holder(d) is not None:
            continue  # still running (a worker of an external cluster): not ours to mark
        if isinstance(summ, dict) and summ.get("status") == "running":
            summ["status"] = "interrupted"
            summ["error"] = (f"stopped by {signame} (its worker ended with the sweep or "
                             f"ensemble)")
            try:
                write_json(d / "summary.json", summ, indent=1, strict=True)
            except (OSError, ValueError):
                continue
        if (d / LOCK).is_file():
            with contextlib.suppress(OSError):
                (d / LOCK).unlink()
        if isinstance(summ, dict) and summ.get("status") in ("running", "interrupted"):
            t = summ.get("sim_time")
            texts.append(f"{name} at t = {float(t or 0.0):.3g} s" if (d / RESTART_FILE).is_file()
                         else f"{name} (no restart point: starts over)")
    return texts


def resume_notes(out: Path, names) -> list[str]:
    """Before a rerun: the runs among ``names`` that will go on from a checkpoint
    (OUT/<name>/restart.npz, summary.json not 'ok'), each with its time, so that a rerun says
    where each resumes (a checkpoint is up to dem.run.write.CHECKPOINT_SECONDS old: what ran
    after it is computed again)."""
    from dem.rundir import RESTART_FILE

    notes = []
    for name in names:
        d = Path(out) / name
        if not (d / RESTART_FILE).is_file():
            continue
        try:
            summ = json.loads((d / "summary.json").read_text())
        except (OSError, ValueError):
            continue
        if summ.get("status") in ("running", "interrupted"):
            notes.append(f"{name} from t = {float(summ.get('sim_time') or 0.0):.3g} s")
    return notes


def points_ok(cases, case_path, what: str) -> bool:
    """Every point (realisation) checked as ``dem check`` checks a case (dem.validate.
    check_points: scene, time step, loading against the step and the run), before anything
    runs or is written; each warning and error printed naming its point.  False: bad input."""
    from dem.validate import check_points

    warnings, errors = check_points(cases, case_path)
    for line in warnings:
        say(f"warning: {what} {line}")
    for line in errors:
        say(f"error: {what} {line}")
    if errors:
        bad = len({line.split(":", 1)[0] for line in errors})
        say(f"error: {bad} of {len(cases)} {what}s cannot run as given; nothing was run")
    return not errors


def check_counts(workers: int | None, max_steps: int | None, error: type[ValueError]) -> None:
    """Raise ``error`` (a ValueError: exit code 2) naming the option when --workers or
    --max-steps is given and below 1 (dem sweep and dem ensemble alike)."""
    for option, value in (("--workers", workers), ("--max-steps", max_steps)):
        if value is not None and value < 1:
            raise error(f"{option} must be >= 1, got {value}")


def batching(batch: int | None, arch: str, scheduler: str | None = None) -> dict:
    """run_batch's keywords for ``--batch`` and ``--arch`` (none where both are the defaults,
    so that the default path is today's); raises BatchInputError (a ValueError: exit code 2)
    for --batch < 1, an unknown arch, or cuda where Taichi finds no CUDA device (checked here,
    before any worker starts: dem.run.batched.check_arch)."""
    from dem.run.batched import BatchInputError, check_arch

    if batch is not None and batch < 1:
        raise BatchInputError(f"--batch must be >= 1, got {batch}")
    check_arch(arch)
    if scheduler is not None:  # before anything is written (dask would wait 30 s, then fail)
        from dem.batch import check_scheduler

        check_scheduler(scheduler)
    return {} if batch is None and arch == "cpu" else {"batch": batch, "arch": arch}


def workers_text(scheduler: str | None, workers: int | None, batch: int | None,
                 arch: str) -> str:
    """Where the runs go, for the start line of dem sweep / dem ensemble."""
    if scheduler:
        where = f"scheduler {scheduler}"
    else:
        n = workers or (1 if arch == "cuda" else os.cpu_count())
        where = f"local cluster, {n} worker{'s' if n != 1 else ''}"
    if batch is not None:
        where += (f", {batch} to an engine" if arch != "cpu" else
                  f", --batch {batch} ignored on the CPU: one run to an engine")
    return where + (f", on {arch}" if arch != "cpu" else "")


def run_sweep_realisations(case_path, out: Path, frequencies, rng, cycles, margin, scheduler,
                           workers, max_steps, realisations, seed, drain_file=None,
                           batch=None, arch="cpu", max_points=None) -> int:
    """``dem sweep --realisations N``: one sweep per realisation, then their statistics."""
    from dem.batch import Drained
    from dem.case import CaseError, load_case
    from dem.run.sweep import realisation_cases

    try:
        case = load_case(case_path)
        freqs = parse_frequencies(frequencies, rng, max_points)
        cases = realisation_cases(case, 1 if realisations is None else realisations, seed)
        points = [(f"{name} {n}", p) for name, c in cases
                  for n, p in sweep_cases(c, freqs, cycles, margin)]
    except CaseError as err:
        say(f"error: {err}")
        return exit_code_for(err)
    except ValueError as err:
        say(f"error: {case_path}: {err}")
        return exit_code_for(err)
    if not points_ok(points, case_path, "point"):
        return ExitCode.BAD_INPUT
    from dem.signals import signal_name, stop_on_signals

    codes = []
    try:
        with stop_on_signals():     # a signal between two realisations stops the loop as well
            for name, c in cases:
                say(f"realisation {name} ({len(codes) + 1} of {len(cases)})")
                code = run_sweep(case_path, out / name, frequencies, rng, cycles, margin,
                                 scheduler, workers, max_steps, case=c, reraise_interrupt=True,
                                 drain_file=drain_file, batch=batch, arch=arch,
                                 max_points=max_points)
                if code == ExitCode.BAD_INPUT:
                    return code
                codes.append(code)
    except Drained:
        left = [name for name, _ in cases][len(codes) + 1:]
        if left:
            say(f"drained: realisation(s) {', '.join(left)} not started")
        return ExitCode.RUN_FAILED
    except KeyboardInterrupt as err:
        left = [name for name, _ in cases][len(codes):]
        say(f"stopped by {signal_name(err)}: realisation(s) {', '.join(left)} not finished; a "
            f"rerun of the same command keeps every finished point")
        return exit_code_for(err)
    aggregate_sweep_realisations(
        out, {"case": case.name, "source": str(case_path),
              "imperfections": case.imperfections.model_dump()},
        [(name, c.imperfections.seed) for name, c in cases])
    say(f"{len(cases)} realisations; {out}/ensemble.json, {out}/amplification_band.png")
    return ExitCode.RUN_FAILED if any(c != ExitCode.OK for c in codes) else ExitCode.OK


def aggregate_sweep_realisations(out: Path, meta: dict, names_seeds: list[tuple[str, int]]
                                 ) -> dict:
    """OUT/ensemble.json and amplification_band.png of ``dem sweep --realisations`` from each
    realisation's OUT/<name>/sweep.json (also ``dem post OUT``): per frequency, the statistics
    of the amplification and lag of MAIN_QUANTITY over the realisations; the characteristic
    frequencies' statistics.  ``meta``: case, source, imperfections."""
    from dem.output.atomic import write_json
    from postprocess.ensemble import plot_amplification_band, statistics

    curves: dict[float, list] = {}
    lags: dict[float, list] = {}
    per_seed = []
    for name, seed in names_seeds:
        try:
            data = json.loads((out / name / "sweep.json").read_text())
        except (OSError, ValueError):
            per_seed.append({"name": name, "seed": seed, "status": "missing"})
            continue
        agg = data.get("aggregate") or {}
        per_seed.append({"name": name, "seed": seed,
                         "characteristic_frequency_hz": agg.get("characteristic_frequency_hz"),
                         "failed_points": len(data.get("failed") or [])})
        for p in data.get("points", []):
            if p.get("status") != "ok":
                continue
            f = p["frequency_hz"]
            curves.setdefault(f, []).append((p.get("amplification") or {}).get(MAIN_QUANTITY))
            lag = (p.get("lag") or {}).get(MAIN_QUANTITY)
            lags.setdefault(f, []).append(lag.get("s") if isinstance(lag, dict) else lag)
    fcs = [r.get("characteristic_frequency_hz") for r in per_seed]
    result = {"kind": "sweep-ensemble", "case": meta["case"], "source": meta["source"],
              "quantity": MAIN_QUANTITY, "imperfections": meta["imperfections"],
              "realisations": per_seed,
              "amplification": {f"{f:g}": statistics(v) for f, v in sorted(curves.items())},
              "lag_s": {f"{f:g}": statistics(v) for f, v in sorted(lags.items())},
              "characteristic_frequency_hz": statistics(fcs),
              "realisations_without_characteristic_frequency":
                  sum(1 for x in fcs if x is None)}
    write_json(out / "ensemble.json", result, indent=1, strict=True)
    plot_amplification_band(curves, out / "amplification_band.png", MAIN_QUANTITY,
                            f"{meta['case']}: {len(names_seeds)} realisations")
    return result
