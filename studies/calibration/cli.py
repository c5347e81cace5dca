"""``python -m studies calibration``: the command line of the calibration (the protocol:
studies/calibration/__init__.py).
"""

from __future__ import annotations

import argparse
import sys
import time
from pathlib import Path

from studies import calibration
from studies.calibration.points import run_point
from studies.calibration.report import report
from studies.calibration.specimens import (CANDIDATES_FILE, DEFAULT_REALISATIONS, HELD_OUT_DIR,
                                           held_out_specimens, load_candidates, ROOT, specimens)
from studies.kit import session
from studies.kit.provenance import repo_rel


# ---- command line -------------------------------------------------------------------------------
def _command(args) -> str:
    """The command that regenerates the study, as run from the checkout that holds --out (the
    session's --stop-at and --runs left out: they do not change the results)."""
    return session.command("calibration", out=repo_rel(args.out),
                           candidates=args.candidates or None, specimens=args.specimens or None,
                           realisations=(args.realisations, DEFAULT_REALISATIONS),
                           max_steps=args.max_steps)


def main(argv=None) -> int:
    ap = argparse.ArgumentParser(description=calibration.__doc__, formatter_class=argparse.RawTextHelpFormatter)
    ap.add_argument("--out", type=Path, default=ROOT / "results" / "calibration")
    ap.add_argument("--runs", type=Path, default=None,
                    help="raw runs (frames.npz ...; default <out>/runs, git-ignored)")
    ap.add_argument("--candidates", nargs="*", default=None, help="names (default: all, in the "
                    "file's order)")
    ap.add_argument("--candidates-file", type=Path, default=CANDIDATES_FILE)
    ap.add_argument("--specimens", nargs="*", default=None, help="names (default: all, "
                    "cheapest first)")
    ap.add_argument("--realisations", type=int, default=DEFAULT_REALISATIONS)
    ap.add_argument("--max-steps", type=int, default=None,
                    help="cap the steps of each run (smoke; such points never count as the "
                         "real ones: the cap is part of their fingerprint)")
    ap.add_argument("--stop-at", default=None,
                    help="UTC time HH:MM after which no new point is started")
    ap.add_argument("--report", action="store_true", help="only rebuild the report")
    ap.add_argument("--held-out", action="store_true",
                    help="after the freeze: run the held-out large-brick walls (HELD_OUT) with "
                         "the committed frozen set (--frozen) into <out>/held-out/")
    ap.add_argument("--frozen", type=Path, default=ROOT / "studies" / "calibration" / "frozen.yaml",
                    help="the frozen set for --held-out (must be committed under cases/)")
    ap.add_argument("--freeze", action="store_true",
                    help="rebuild the report, then write the choice of SELECTION.md "
                         "(studies.calibration.select) to --frozen; refused (exit 2) while "
                         "the choice is undecided.  Commit the file and the report together.")
    args = ap.parse_args(argv)
    if args.realisations < 1:
        ap.error("--realisations must be >= 1")
    if args.held_out:
        return _main_held_out(ap, args)
    if args.freeze:
        return _main_freeze(ap, args)
    all_c, all_s = load_candidates(args.candidates_file), specimens()
    for what, chosen, known in (("candidate", args.candidates, all_c),
                                ("specimen", args.specimens, all_s)):
        bad = [x for x in chosen or [] if x not in known]
        if bad:
            ap.error(f"unknown {what}(s) {bad}; known: {list(known)}")
    cands = {c: all_c[c] for c in (args.candidates or all_c)}
    specs = {s: all_s[s] for s in all_s if args.specimens is None or s in args.specimens}
    out, runs = session.begin(args.out, args.runs)
    command = _command(args)
    if not args.report:
        for c, params in cands.items():
            for s, spec in specs.items():
                if session.should_stop(stop_at=args.stop_at,
                                       log=lambda m: print(m, flush=True)):
                    break
                state = run_point(out, runs, c, params, s, spec, args.realisations,
                                  args.max_steps, log=lambda m: print(m, flush=True))
                if state != "skipped":
                    report(out, all_c, all_s, args.realisations, command)
    report(out, all_c, all_s, args.realisations, command)
    return 0


def _main_freeze(ap, args) -> int:
    """--freeze: the report from the committed points, then the decided choice to --frozen."""
    from studies.calibration.select import FreezeRefused, freeze

    if args.candidates or args.specimens:
        ap.error("--freeze applies SELECTION.md to every candidate and specimen: no "
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


def _main_held_out(ap, args) -> int:
    """--held-out: the large-brick walls with the frozen set (refused, exit 2, before the
    freeze: studies.prediction.plan.load_frozen)."""
    from studies.prediction.plan import load_frozen
    from studies.prediction.protocol import PredictionInputError

    if args.candidates:
        ap.error("--held-out runs the frozen set, not --candidates")
    try:
        frozen = load_frozen(args.frozen)
    except PredictionInputError as err:
        ap.error(str(err))
    all_s = held_out_specimens()
    bad = [x for x in args.specimens or [] if x not in all_s]
    if bad:
        ap.error(f"unknown held-out specimen(s) {bad}; known: {list(all_s)}")
    record = {"frozen": {"file": frozen["path"], "commit": frozen["commit"],
                         "sha256": frozen["sha256"]}}
    out, runs = session.begin(args.out, args.runs)
    for s, spec in all_s.items():
        if args.specimens and s not in args.specimens:
            continue
        if session.should_stop(stop_at=args.stop_at,
                               log=lambda m: print(m, flush=True)):
            break
        run_point(out, runs, HELD_OUT_DIR, frozen["parameters"], s, spec, args.realisations,
                  args.max_steps, log=lambda m: print(m, flush=True), record=record)
    report(out, load_candidates(args.candidates_file), specimens(), args.realisations,
           _command(args))
    return 0


if __name__ == "__main__":
    sys.exit(main())
