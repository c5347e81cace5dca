"""``python -m studies prediction``: the command line of the prediction study (the protocol:
studies/prediction/__init__.py).
"""

from __future__ import annotations

import sys
from pathlib import Path
from types import SimpleNamespace

import typer

from studies import prediction
from studies.kit import cli, session
from studies.kit.provenance import rel
from studies.kit.records import read_json
from studies.prediction.cycles import cut_record, cycles_check, verdict_text
from studies.prediction.plan import load_frozen, make_plan, sweep_names, write_plan
from studies.prediction.points import points_path
from studies.prediction.protocol import (DEFAULT_CYCLES, DEFAULT_FROZEN, DEFAULT_REALISATIONS,
                                         FULL_SWEEP, ORDER, PredictionInputError, ROOT)
from studies.prediction.report import report
from studies.prediction.run import run_sweep_point


def command_line(args) -> str:
    cmd = ["python -m studies prediction", "--frozen", rel(Path(args.frozen)),
           "--out", rel(Path(args.out))]
    if args.realisations != DEFAULT_REALISATIONS:
        cmd += ["--realisations", str(args.realisations)]
    if args.cycles != DEFAULT_CYCLES:
        cmd += ["--cycles", f"{args.cycles:g}"]
    if args.max_steps is not None:
        cmd += ["--max-steps", str(args.max_steps)]
    if args.cycles_check is not None:
        cmd += ["--cycles-check", f"{args.cycles_check:g}"]
    return " ".join(cmd)


def subset(text: str | None, kind, flag: str) -> list | None:
    """A comma-separated --seeds / --frequencies value as a list (None: all of the plan's)."""
    if text is None:
        return None
    try:
        vals = [kind(x) for x in text.split(",") if x.strip()]
    except ValueError:
        raise PredictionInputError(f"{flag}: expected comma-separated numbers, got {text!r}")
    if not vals:
        raise PredictionInputError(f"{flag}: empty")
    return vals


app = cli.study_app()


@app.command(help=cli.text(prediction.__doc__))
def prediction_command(
        frozen: Path = typer.Option(DEFAULT_FROZEN),
        out: Path = typer.Option(ROOT / "results" / "prediction"),
        runs: Path = typer.Option(None, help="raw runs (default <out>/runs, git-ignored)"),
        only: str = typer.Option(None, help=cli.text(f"comma-separated sweeps of {list(ORDER)}")),
        realisations: int = typer.Option(DEFAULT_REALISATIONS),
        cycles: float = typer.Option(DEFAULT_CYCLES),
        workers: int = typer.Option(None),
        max_steps: int = typer.Option(None, help="cap every run (smoke tests)"),
        report_only: bool = typer.Option(False, "--report", help="only rebuild the report"),
        cycles_check: float = typer.Option(
            None, metavar="N",
            help="no runs: re-analyse the finished runs of the sweeps (--only) over their first "
                 "N cycles, compare with the full cycles, then report"),
        cut_cycles: float = typer.Option(
            None, metavar="N",
            help=f"run the sweeps of --only (not {FULL_SWEEP}, not yet planned) at N cycles; "
                 f"only once {FULL_SWEEP} finished in full and its cycles-check-N.json says the "
                 f"answer is unchanged"),
        seeds: str = typer.Option(None, metavar="S,S,...",
                                  help="run only these of the plan's seeds (share a sweep "
                                       "between processes or machines; the plan does not "
                                       "change)"),
        frequencies: str = typer.Option(None, metavar="F,F,...",
                                        help="run only these of each sweep's frequencies (Hz; "
                                             "as --seeds)"),
        drain_file: Path = typer.Option(
            None, help="once this file exists no new run starts, the runs in flight finish, "
                       "then the report is written (default <runs>/DRAIN); SIGTERM instead "
                       "stops at once: the runs in flight resume from their last restart point "
                       "on the next call")) -> int:
    args = SimpleNamespace(frozen=frozen, out=out, runs=runs, only=only,
                           realisations=realisations, cycles=cycles, workers=workers,
                           max_steps=max_steps, report=report_only, cycles_check=cycles_check,
                           cut_cycles=cut_cycles, seeds=seeds, frequencies=frequencies,
                           drain_file=drain_file)
    return _prediction(args)


def main(argv=None) -> int:
    """``python -m studies prediction ARGV``; returns the exit code (0 ok, 1 a run failed or
    was stopped, 2 bad input)."""
    return cli.run(app, argv, "prediction")


def _prediction(args) -> int:
    try:
        only_seeds = subset(args.seeds, int, "--seeds")
        only_freqs = subset(args.frequencies, float, "--frequencies")
        frozen = load_frozen(args.frozen)
        names = sweep_names(args.only)
        if not args.report and args.cycles_check is None:
            new = make_plan(frozen, names, args.realisations, args.cycles, args.max_steps)
            if args.cut_cycles is not None:
                if FULL_SWEEP in names:
                    raise PredictionInputError(f"--cut-cycles: {FULL_SWEEP} runs in full (issue "
                                               f"13 step 3); leave it out of --only")
                cut = cut_record(args.out, read_json(Path(args.out) / "plan.json"), args.cut_cycles)
                for n in names:
                    new["sweeps"][n].update(cycles=args.cut_cycles, cut=cut)
            plan = write_plan(args.out, new)
        else:
            plan = read_json(Path(args.out) / "plan.json")
            if plan is not None and plan["frozen"]["commit"] != frozen["commit"]:
                raise PredictionInputError(
                    f"{args.out}/plan.json: made with frozen commit {plan['frozen']['commit']}, "
                    f"{args.frozen} is now at {frozen['commit']}")
        if plan is not None and only_seeds is not None and \
                not set(only_seeds) <= set(plan["seeds"]):
            raise PredictionInputError(f"--seeds {args.seeds}: not among the plan's seeds "
                                       f"{plan['seeds']}")
        if plan is not None and only_freqs is not None:
            known = [f for n in names for f in plan["sweeps"].get(n, {}).get("frequencies_hz", [])]
            bad = [f for f in only_freqs if not any(abs(f - g) < 1e-9 for g in known)]
            if bad:
                raise PredictionInputError(f"--frequencies: {bad} Hz not in the plan of "
                                           f"{', '.join(names)}")
        if args.cycles_check is not None:
            runs = args.runs or Path(args.out) / "runs"
            have = [n for n in names if points_path(args.out, n).is_file()]
            if not have:
                raise PredictionInputError(
                    f"--cycles-check: no {points_path(args.out, names[0]).name} of "
                    f"{', '.join(names)} under {args.out}: nothing to check")
            for n in have:
                v = cycles_check(args.out, runs, n, args.cycles_check)["verdict"]
                print(f"{n}: {args.cycles_check:g} cycles: {verdict_text(v)}", file=sys.stderr)
    except PredictionInputError as err:
        print(f"error: {err}", file=sys.stderr)
        return 2
    states = []
    if not args.report and args.cycles_check is None:
        runs = args.runs or Path(args.out) / "runs"
        drain = session.start(runs, args.drain_file)
        for n in names:
            if session.should_stop(drain):
                break
            states.append(run_sweep_point(args.out, runs, n, plan, args.workers,
                                          drain_file=drain, only_seeds=only_seeds,
                                          only_freqs=only_freqs))
    report(args.out, frozen, command_line(args), args.runs)
    print(f"{args.out}/summary.json, {args.out}/README.md", file=sys.stderr)
    return 0 if all(s in ("skipped", "finished") for s in states) else 1



if __name__ == "__main__":
    sys.exit(main())
