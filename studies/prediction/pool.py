"""Run chosen (seed, frequency) points of a prediction sweep in a local process pool, without
dask: for a borrowed many-core machine where dask is not installed.

    python -m studies point-pool --out results/prediction --sweep model-ii-y \\
        --points 0:3.2,9:3.6,9:3.2 --workers 16

Each point is built exactly as ``dem sweep --realisations 1 --seed S --frequencies F`` builds
it from the study's case file (studies.prediction.plan.sweep_case: the sweep's case with the frozen
set, written to ``<runs>/<sweep>.yaml`` the same way; dem.run.sweep.realisation_cases, then
sweep_cases at the plan's cycles), and is run by the same task body (dem.batch.run_one: one
Taichi thread, the point's analysis, postprocess.sweep.analyze_point) into the directory dem sweep
uses, ``<runs>/<sweep>/seed-<S>/f<F>Hz/``.  So a finished point's directory, or just its
``summary.json``, ``case.json``, ``analysis.json`` and ``truncated-rows.json`` copied back to the
study's runs directory, is taken by the next ``python -m studies prediction`` call as finished
(dem_cli.commands.sweep.finished_point: same case.json, status ok, same results revision) and
merged into points.json; nothing of points.json is written here.  A point already finished in
its directory is skipped.

Each point runs in a fresh process (spawn; :func:`each_in_own_process`), so a point's memory
and Taichi runtime end with it.  After a run, its analyses over the first N cycles
(studies.prediction.protocol.TRUNCATED_CYCLES) go to ``truncated-rows.json`` beside it, from which the
study's cycles checks take them (the raw run stays on that machine).  ``--list`` prints the
``<runs>``-relative paths of the finished points' JSON files (to pack them).  Exit 0 every
point ok, 1 one failed or was cut short.

A point cut short (SIGTERM, e.g. the ``timeout`` of a device call: the workers are terminated
with this process, none is left holding its directory) keeps its last restart point
(dem.run.resume, every 30 s after settling); the same command on the same machine resumes it.
"""

from __future__ import annotations

import json
import multiprocessing as mp
import sys
import time
from pathlib import Path
from types import SimpleNamespace

import typer

from studies.kit import cli
from studies.kit.records import read_json
from studies.prediction.cycles import POOL_TRUNCATED, truncated_row
from studies.prediction.plan import sweep_case, sweep_cycles
from studies.prediction.protocol import PredictionInputError, ROOT, TRUNCATED_CYCLES
from studies.prediction.run import write_run_case

RECEIPT = ("summary.json", "case.json", "analysis.json", POOL_TRUNCATED)


def parse_points(text: str) -> list[tuple[int, float]]:
    """``S:F,S:F,...`` -> [(seed, frequency in Hz)]."""
    out = []
    for item in text.split(","):
        if not item.strip():
            continue
        try:
            s, f = item.split(":")
            out.append((int(s), float(f)))
        except ValueError:
            raise PredictionInputError(f"--points: expected SEED:FREQUENCY, got {item!r}")
    if not out:
        raise PredictionInputError("--points: empty")
    return out


def point_cases(out: Path, runs: Path, name: str, plan: dict, points) -> list[tuple]:
    """(seed, frequency, point name, Case, directory) of each point, as dem sweep builds them
    from the study's case file (module docstring)."""
    from dem.case import load_case
    from dem.run.sweep import realisation_cases, sweep_cases

    sweep = plan["sweeps"].get(name)
    if sweep is None:
        raise PredictionInputError(f"--sweep {name}: not in {out}/plan.json")
    loaded = load_case(write_run_case(runs, name,
                                         sweep_case(name, plan["frozen"]["parameters"])))
    cycles = sweep_cycles(plan, name)
    res = []
    for s, f in points:
        if s not in plan["seeds"]:
            raise PredictionInputError(f"--points: seed {s} not among the plan's {plan['seeds']}")
        if not any(abs(f - g) < 1e-9 for g in sweep["frequencies_hz"]):
            raise PredictionInputError(f"--points: {f:g} Hz not in {name}'s frequencies "
                                          f"{sweep['frequencies_hz']}")
        ((rname, rcase),) = realisation_cases(loaded, 1, s)
        ((pname, pcase),) = sweep_cases(rcase, [f], cycles)
        res.append((s, f, pname, pcase, Path(runs) / name / rname / pname))
    return res


def _child(task, item, conn) -> None:
    """Body of one point's process: ``task(item)`` sent back through ``conn`` as ("ok", result)
    or ("error", traceback)."""
    import traceback

    try:
        msg = ("ok", task(item))
    except BaseException:                           # noqa: BLE001 - reported to the parent
        msg = ("error", traceback.format_exc(limit=8))
    conn.send(msg)
    conn.close()


def each_in_own_process(task, items, n: int, on_result, failed, grace_s: float = 30.0) -> None:
    """``task(item)`` for every item, each in a fresh spawned process, at most ``n`` at once,
    in order; ``on_result(result)`` in this process as each ends (``failed(item, message)``
    stands in for the result of one that raised or died).

    On a KeyboardInterrupt here (Ctrl-C, or SIGTERM inside dem.signals.stop_on_signals) the
    processes in flight get SIGTERM (each point's run stops cleanly and keeps its restart
    point), are waited for up to ``grace_s`` seconds, then killed, and the interrupt goes on
    up.  Not multiprocessing.Pool: its terminate() waits for ever for the task queue's lock,
    which an idle worker holds while it waits for work (CPython pool._help_stuff_finish); a
    pool has idle workers as soon as some points have finished and fewer remain than workers,
    and so a stopped device call hung until it was killed, before it could pack the points it
    had finished."""
    from multiprocessing.connection import wait

    ctx = mp.get_context("spawn")
    queue = list(items)
    running = {}                                    # reader connection -> (process, item)
    try:
        while queue or running:
            while queue and len(running) < n:
                item = queue.pop(0)
                reader, writer = ctx.Pipe(duplex=False)
                proc = ctx.Process(target=_child, args=(task, item, writer), daemon=False)
                proc.start()
                writer.close()                      # the child holds the only writer now
                running[reader] = (proc, item)
            for reader in wait(list(running)):
                proc, item = running.pop(reader)
                try:
                    kind, value = reader.recv()
                except EOFError:                    # died without a word (killed, crashed)
                    kind, value = "error", "the point's process ended without a result"
                reader.close()
                proc.join()
                if kind == "ok":
                    on_result(value)
                else:
                    if proc.exitcode:
                        value += f" (exit code {proc.exitcode})"
                    on_result(failed(item, value))
    except BaseException:
        procs = [p for p, _ in running.values()]
        for p in procs:
            p.terminate()
        deadline = time.monotonic() + grace_s
        for p in procs:
            p.join(max(0.0, deadline - time.monotonic()))
            if p.is_alive():
                p.kill()
                p.join()
        raise


def _task(args) -> dict:
    """One point in its own process (dem.batch.run_one with the sweep's analysis), then the
    analyses of its first N cycles for each N of ``ns`` (studies.prediction.cycles.record_truncated
    takes them from ``truncated-rows.json``: the raw run does not travel back)."""
    pname, case_json, out_dir, max_steps, seed, f, ns = args
    from dem.batch import run_one
    from dem.output.atomic import write_json
    from postprocess.sweep import analyze_point

    rec = run_one(pname, case_json, out_dir, 1, max_steps, analyze_point)
    if rec["status"] == "ok" and ns:
        write_json(Path(out_dir) / POOL_TRUNCATED,
                   {f"{n:g}": truncated_row(seed, f, Path(out_dir), n) for n in ns}, indent=1)
    s = rec.get("summary") or {}
    return {"out_dir": out_dir, "status": rec["status"], "error": rec.get("error"),
            "steps": s.get("steps"), "wall_seconds": s.get("wall_seconds", rec.get("wall_seconds")),
            "amplification_ds": ((rec.get("post") or {}).get("amplification") or {}).get("ds")}


app = cli.study_app()


@app.command(help=cli.text(__doc__))
def point_pool(
        out: Path = typer.Option(ROOT / "results" / "prediction",
                                 help="the study's folder (its plan.json)"),
        runs: Path = typer.Option(None, help="raw runs (default <out>/runs)"),
        sweep: str = typer.Option(...),
        points: str = typer.Option(..., metavar="S:F,S:F,..."),
        workers: int = typer.Option(None, help="processes (default: one per core)"),
        list_: bool = typer.Option(False, "--list", help="print the finished points' JSON files "
                                                          "(RECEIPT) and exit")) -> int:
    return _pool(SimpleNamespace(out=out, runs=runs, sweep=sweep, points=points,
                                 workers=workers, list=list_))


def main(argv=None) -> int:
    """``python -m studies point-pool ARGV``; returns the exit code (0 every point ok, 1 one
    failed or was cut short, 2 bad input)."""
    return cli.run(app, argv, "point-pool")


def _pool(args) -> int:
    from dem_cli.commands.sweep import finished_run

    runs = args.runs or Path(args.out) / "runs"
    try:
        plan = read_json(Path(args.out) / "plan.json")
        if plan is None:
            raise PredictionInputError(f"{args.out}/plan.json: missing or unreadable")
        pts = point_cases(args.out, runs, args.sweep, plan, parse_points(args.points))
        if args.workers is not None and args.workers < 1:
            raise PredictionInputError(f"--workers must be >= 1, got {args.workers}")
    except PredictionInputError as err:
        print(f"error: {err}", file=sys.stderr)
        return 2
    cap = plan["max_steps"]          # the plan's step cap (smoke plans), as the study runs it
    ns = [n for n in TRUNCATED_CYCLES if 2 <= n < sweep_cycles(plan, args.sweep)]
    if args.list:                    # only points whose receipt is complete (_task's last write)
        for *_, pcase, d in pts:
            if (finished_run(pcase, d, cap) is not None and (d / "analysis.json").is_file()
                    and (not ns or (d / POOL_TRUNCATED).is_file())):
                print("\n".join(str((d / f).relative_to(runs)) for f in RECEIPT
                                if (d / f).is_file()))
        return 0
    todo = [(pname, pcase.model_dump_json(), str(d), cap, s, f, ns)
            for s, f, pname, pcase, d in pts if finished_run(pcase, d, cap) is None]
    n = min(len(todo), args.workers or mp.cpu_count()) if todo else 0
    print(f"{args.sweep}: {len(pts)} points, {len(pts) - len(todo)} finished before, "
          f"{len(todo)} to run on {n} processes", file=sys.stderr, flush=True)
    bad = 0
    t0 = time.perf_counter()
    if todo:
        from dem.signals import stop_on_signals

        def report(r):
            nonlocal bad
            bad += r["status"] != "ok"
            print(f"[{time.perf_counter() - t0:6.0f} s] {json.dumps(r)}", file=sys.stderr,
                  flush=True)

        try:
            # a stop signal (the `timeout` of a device call: SIGTERM) terminates the points in
            # flight: none is left running (and holding its directory) after this process; each
            # keeps its last restart point, and the same command resumes it
            with stop_on_signals():
                each_in_own_process(_task, todo, n, report,
                                    failed=lambda item, err: {"out_dir": item[2],
                                                              "status": "error", "error": err})
        except KeyboardInterrupt as err:
            from dem.signals import signal_name

            print(f"[{time.perf_counter() - t0:6.0f} s] stopped by {signal_name(err)}: the "
                  f"points in flight keep their restart points (dem.run.resume); the same "
                  f"command resumes them", file=sys.stderr, flush=True)
            return 1
    return 1 if bad else 0


if __name__ == "__main__":
    sys.exit(main())
