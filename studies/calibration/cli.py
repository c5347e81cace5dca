"""``python -m studies calibration``: the command line of the calibration (the protocol:
studies/calibration/__init__.py).
"""

from __future__ import annotations

import sys
import time
from pathlib import Path
from types import SimpleNamespace

import typer

from studies import calibration
from studies.calibration.points import Ensembles
from studies.calibration.report import report
from studies.calibration.specimens import (CANDIDATES_FILE, DEFAULT_REALISATIONS, HELD_OUT_DIR,
                                           held_out_specimens, load_candidates, ROOT, specimens)
from studies.kit import cli, session, study as kit
from studies.kit.provenance import repo_rel


# ---- command line -------------------------------------------------------------------------------
def _command(args) -> str:
    """The command that regenerates the study, as run from the checkout that holds --out (the
    session's --stop-at and --runs left out: they do not change the results)."""
    return session.command("calibration", out=repo_rel(args.out),
                           candidates=args.candidates or None, specimens=args.specimens or None,
                           realisations=(args.realisations, DEFAULT_REALISATIONS),
                           max_steps=args.max_steps)


app = cli.study_app()
LISTS = ("--candidates", "--specimens")   # options that take several values: --specimens a b


@app.command(help=cli.text(calibration.__doc__))
def calibration_command(
        out: Path = typer.Option(ROOT / "results" / "calibration"),
        runs: Path = typer.Option(None, help="raw runs (frames.npz ...; default <out>/runs, "
                                             "git-ignored)"),
        candidates: list[str] = typer.Option(None, help="names (default: all, in the file's "
                                                        "order)"),
        candidates_file: Path = typer.Option(CANDIDATES_FILE),
        specimens: list[str] = typer.Option(None, help="names (default: all, cheapest first)"),
        realisations: int = typer.Option(DEFAULT_REALISATIONS),
        max_steps: int = typer.Option(None, help="cap the steps of each run (smoke; such points "
                                                 "never count as the real ones: the cap is part "
                                                 "of their fingerprint)"),
        stop_at: str = typer.Option(None, help="UTC time HH:MM after which no new point is "
                                               "started"),
        report_only: bool = typer.Option(False, "--report", help="only rebuild the report"),
        held_out: bool = typer.Option(False, "--held-out",
                                      help="after the freeze: run the held-out large-brick walls "
                                           "(HELD_OUT) with the committed frozen set (--frozen) "
                                           "into <out>/held-out/"),
        frozen: Path = typer.Option(ROOT / "studies" / "calibration" / "frozen.yaml",
                                    help="the frozen set for --held-out (must be committed under "
                                         "cases/)"),
        freeze: bool = typer.Option(False, "--freeze",
                                    help="rebuild the report, then write the choice of "
                                         "SELECTION.md (studies.calibration.select) to --frozen; "
                                         "refused (exit 2) while the choice is undecided.  Commit "
                                         "the file and the report together.")) -> int:
    return _calibration(SimpleNamespace(
        out=out, runs=runs, candidates=candidates, candidates_file=candidates_file,
        specimens=specimens, realisations=realisations, max_steps=max_steps, stop_at=stop_at,
        report=report_only, held_out=held_out, frozen=frozen, freeze=freeze))


def main(argv=None) -> int:
    """``python -m studies calibration ARGV``; returns the exit code (0 ok, 2 bad options or a
    refused --freeze / --held-out)."""
    return cli.run(app, argv, "calibration", lists=LISTS)


def _calibration(args) -> int:
    if args.realisations < 1:
        cli.usage_error("--realisations must be >= 1")
    if args.held_out:
        return _main_held_out(args)
    if args.freeze:
        return _main_freeze(args)
    all_c, all_s = load_candidates(args.candidates_file), specimens()
    for what, chosen, known in (("candidate", args.candidates, all_c),
                                ("specimen", args.specimens, all_s)):
        bad = [x for x in chosen or [] if x not in known]
        if bad:
            cli.usage_error(f"unknown {what}(s) {bad}; known: {list(known)}")
    cands = {c: all_c[c] for c in (args.candidates or all_c)}
    specs = {s: all_s[s] for s in all_s if args.specimens is None or s in args.specimens}
    out, runs = session.begin(args.out, args.runs)
    command = _command(args)
    if not args.report:
        study = Ensembles(args.realisations, args.max_steps, after=lambda p, state: (
            state != "skipped" and report(out, all_c, all_s, args.realisations, command)))
        for c, params in cands.items():
            for s, spec in specs.items():
                study.add(out, runs, c, params, s, spec)
        kit.run(study, args.stop_at, log=lambda m: print(m, flush=True))
    report(out, all_c, all_s, args.realisations, command)
    return 0


def _main_freeze(args) -> int:
    """--freeze: the report from the committed points, then the decided choice to --frozen."""
    from studies.calibration.select import FreezeRefused, freeze

    if args.candidates or args.specimens:
        cli.usage_error("--freeze applies SELECTION.md to every candidate and specimen: no "
                        "--candidates / --specimens")
    all_c = load_candidates(args.candidates_file)
    args.out.mkdir(parents=True, exist_ok=True)
    summary = report(args.out, all_c, specimens(), args.realisations, _command(args))
    sel = summary["selection"]
    try:
        written = freeze(sel, all_c, args.frozen, time.strftime("%Y-%m-%d", time.gmtime()))
    except FreezeRefused as err:
        print(f"calibration: {err}", file=sys.stderr)
        return 2
    print(f"{'froze' if written else 'already frozen:'} {sel['chosen']} -> {args.frozen} "
          f"({sel['why']}); commit it with {args.out}/README.md and summary.json")
    return 0


def _main_held_out(args) -> int:
    """--held-out: the large-brick walls with the frozen set (refused, exit 2, before the
    freeze: studies.prediction.plan.load_frozen)."""
    from studies.prediction.plan import load_frozen
    from studies.prediction.protocol import PredictionInputError

    if args.candidates:
        cli.usage_error("--held-out runs the frozen set, not --candidates")
    try:
        frozen = load_frozen(args.frozen)
    except PredictionInputError as err:
        cli.usage_error(str(err))
    all_s = held_out_specimens()
    bad = [x for x in args.specimens or [] if x not in all_s]
    if bad:
        cli.usage_error(f"unknown held-out specimen(s) {bad}; known: {list(all_s)}")
    record = {"frozen": {"file": frozen["path"], "commit": frozen["commit"],
                         "sha256": frozen["sha256"]}}
    out, runs = session.begin(args.out, args.runs)
    study = Ensembles(args.realisations, args.max_steps)
    for s, spec in all_s.items():
        if not args.specimens or s in args.specimens:
            study.add(out, runs, HELD_OUT_DIR, frozen["parameters"], s, spec, record=record)
    kit.run(study, args.stop_at, log=lambda m: print(m, flush=True))
    report(out, load_candidates(args.candidates_file), specimens(), args.realisations,
           _command(args))
    return 0


if __name__ == "__main__":
    sys.exit(main())
