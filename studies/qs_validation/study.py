"""Slow constant-rate tilts against the calibration's quasi-static lambda (is the
calibration's lambda the rate -> 0 value?).

    python -m studies qs-validation --out results/calibration/qs-validation   # run, report
    python -m studies qs-validation --out results/calibration/qs-validation --report
    python -m studies qs-validation --out results/calibration/qs-validation \\
        --specimens ip-small-9x15-s10 --candidate bed-0.1-planar --realisations 2

Why.  The calibration (studies.calibration) reads lambda from the quasi-static search
(dem.run.quasi_static: increments relaxed with local damping, bisection of the first that
fails).  That search was checked against the rate -> 0 limit of constant-rate tilts on two walls
only (the perfect 5 x 7 wall and the 5 x 9 facade without wings; benchmarks/speed_error.md,
"Quasi-static tilt").  On the perfect 9 x 15 wall with s = 10 mm it read 0.5408, +6.0 % above
the runaway of a 1 deg/s tilt (0.5104; speed_error.md, "Quasi-static tilt of imperfect walls":
the 0.5 deg/s "collapse" there was a 9.8 mm slip that stopped).  This study repeats that check
on every calibration specimen.

What it runs.  For each specimen (studies.calibration.specimens.specimens) and each rate of ``--rates``
(default 2, 1, 0.5 deg/s): the calibration's own case of that specimen and candidate
(studies.calibration.specimens.specimen_case with ``rate``: friction, stiffness, imperfections and output
settings unchanged), tilted from 0 deg at that constant rate, its collapse read at the runaway
(studies.calibration.specimens.RUNAWAY_COLLAPSE: confirmed at 20 mm of motion instead of the case files'
5 mm, so that a slip that stops after a few mm is not the collapse), one ``dem ensemble`` of N
realisations (``--realisations``; seeds 0 .. N-1; a perfect candidate runs one), resumable
exactly as the calibration's points (studies.calibration.points.run_point):
``<out>/rate-<r>/<candidate>/<specimen>/ensemble.json``, raw runs under ``<out>/runs/``.

What it reports (``<out>/README.md``, ``<out>/summary.json``), per specimen and seed: lambda at
each rate (the detector's onset: the last frame at which the blocks that go on to move 20 mm
were at rest; dem/collapse.py), lambda0 extrapolated to a vanishing rate through the three
rates r, 2r, 4r (the three slowest finished; studies.tilt.study.rate_extrapolation:
lambda = lambda0 - c r^p), and the calibration's quasi-static lambda of the same candidate and
seed (its committed point), with QS / lambda0 - 1 and QS / lambda(slowest) - 1.  A constant-rate
tilt reads low by its rate (the onset comes early on a wall that leans faster as it tilts
faster), so the rate -> 0 value is the reference.  The verdict (:func:`rate_limit`,
:func:`compare`):

* ``ok`` / ``flag``: lambda0 exists and the quasi-static lambda lies within / more than
  :data:`FLAG_TOLERANCE` (3 %, the tolerance of the issue's sliding invariant) from it.
* ``unconfirmed``: the three rates are monotone but do not converge: the fitted
  lambda0 - lambda(slowest) = D1 / (2^p - 1) would reach further beyond the slowest rate than the
  three rates span (|lambda(r) - lambda(4r)|, i.e. p < 1/2), so lambda0 is an extrapolation, not a
  measurement, and is not given.  The trend still bounds it: the rate -> 0 value lies beyond the
  slowest rate on the side the trend goes.  A quasi-static lambda on that side (or within 3 % of
  the slowest rate) is consistent with it, but not confirmed; on the other side by more than 3 %
  it is flagged.  A slower rate (``--rates ... 0.25``, added to the specimens concerned) is the
  way to confirm it: the extrapolation uses the three slowest rates finished.
* without a monotone trio: ``ok`` / ``flag`` against the slowest rate.

Units: lambda = tan(tilt angle), dimensionless; rates in deg/s.
"""

from __future__ import annotations

import sys
from pathlib import Path
from types import SimpleNamespace

import numpy as np
import typer

from studies.calibration import points as cal_points
from studies.calibration import report as cal_report
from studies.calibration import specimens as cal_specimens
from studies.kit import cli, session, study as kit
from studies.kit.provenance import repo_rel
from studies.kit.records import read_json
from studies.tilt.study import rate_extrapolation

RATES = (2.0, 1.0, 0.5)  # deg/s: r, 2r, 4r for the extrapolation; 2 deg/s is the case files'
FLAG_TOLERANCE = 0.03
VERDICT_TEXT = {"ok": "ok", "flag": "**> 3 %**", "unconfirmed": "unconfirmed (bound only)"}
DEFAULT_OUT = cal_specimens.ROOT / "results" / "calibration" / "qs-validation"


def rate_dir(out: Path, rate: float) -> Path:
    return Path(out) / f"rate-{rate:g}"


def _lambdas(data: dict | None) -> dict[str, float | None]:
    """seed name -> lambda of a finished point's ok realisations ({} unless finished)."""
    if not cal_points.point_finished(data):
        return {}
    return {r["name"]: r.get("lambda") for r in data.get("realisations") or []
            if r.get("status") == "ok"}


def rate_limit(pts) -> tuple[float | None, str]:
    """(lambda0, how): the rate -> 0 value from ``pts`` [(rate, lambda), ...] sorted slowest
    first, and "extrapolated", "not converging" (monotone, but the extrapolation would go
    further beyond the slowest rate than the three rates span: p < 1/2) or "not monotone"
    (fewer than three doubling rates, or differences that do not shrink with one sign)."""
    lam0 = rate_extrapolation(pts)
    if lam0 is None:
        return None, "not monotone"
    if abs(lam0 - pts[0][1]) > abs(pts[0][1] - pts[2][1]):
        return None, "not converging"
    return lam0, "extrapolated"


def compare(qs: dict, by_rate: dict[float, dict]) -> list[dict]:
    """One row per realisation present in the quasi-static point and at every rate:
    ``qs``: seed name -> lambda; ``by_rate``: rate -> (seed name -> lambda).  ``verdict``: ok,
    flag or unconfirmed (module docstring); ``flag`` is verdict == "flag"."""
    rows = []
    for seed, lam_qs in sorted(qs.items()):
        lams = {r: by_rate[r].get(seed) for r in by_rate}
        if lam_qs is None or any(v is None for v in lams.values()) or not lams:
            continue
        pts = sorted((r, v) for r, v in lams.items())
        lam0, how = rate_limit(pts)
        slowest = pts[0][1]
        vs_slowest = lam_qs / slowest - 1
        if lam0 is not None:
            verdict = "flag" if abs(lam_qs / lam0 - 1) > FLAG_TOLERANCE else "ok"
        elif how == "not converging":
            side = np.sign(slowest - pts[2][1])      # where the rate -> 0 value lies
            verdict = "flag" if side * vs_slowest < -FLAG_TOLERANCE else "unconfirmed"
        else:
            verdict = "flag" if abs(vs_slowest) > FLAG_TOLERANCE else "ok"
        rows.append({"seed": seed, "qs": lam_qs, "rates": {f"{r:g}": v for r, v in pts},
                     "lambda0": lam0, "rate_limit": how,
                     "qs_vs_lambda0": None if lam0 is None else lam_qs / lam0 - 1,
                     "qs_vs_slowest": vs_slowest, "verdict": verdict,
                     "flag": verdict == "flag"})
    return rows


def rates_on_disk(out: Path) -> list[float]:
    """The rates that have a directory under ``out`` (rate-<r>)."""
    found = []
    for d in Path(out).glob("rate-*"):
        try:
            found.append(float(d.name[len("rate-"):]))
        except ValueError:
            continue
    return found


def collect(out: Path, calibration: Path, candidate: str, specs: dict, rates) -> dict:
    """specimen -> {"rows": compare(...), "pending_rates": [rates not finished], "cpu_seconds"}.
    ``rates`` are required of every specimen; a further rate found under ``out`` (a slower tilt
    run for some specimens) is used where its point exists, pending where it is unfinished."""
    res = {}
    extra = sorted(set(rates_on_disk(out)) - set(rates))
    for s in specs:
        qs = _lambdas(read_json(cal_points.point_path(calibration, candidate, s)))
        by_rate, pending, cpu = {}, [], 0.0
        for r in list(rates) + extra:
            data = read_json(cal_points.point_path(rate_dir(out, r), candidate, s))
            if data is None and r in extra:
                continue
            cpu += ((data or {}).get("calibration") or {}).get("cpu_seconds") or 0.0
            lams = _lambdas(data)
            if lams:
                by_rate[r] = lams
            else:
                pending.append(r)
        res[s] = {"rows": compare(qs, by_rate) if not pending and qs else [],
                  "pending_rates": pending, "quasi_static_finished": bool(qs),
                  "cpu_seconds": cpu}
    return res


def report(out: Path, calibration: Path, candidate: str, specs: dict, rates, command: str
           ) -> dict:
    from dem.output.atomic import write_json

    res = collect(out, calibration, candidate, specs, rates)
    rates = sorted(set(rates) | {float(r) for v in res.values() for row in v["rows"]
                                 for r in row["rates"]})
    summary = {"kind": "quasi-static validation", "issue": 13, "command": command,
               "candidate": candidate, "rates_deg_per_s": list(rates),
               "flag_tolerance": FLAG_TOLERANCE, "specimens": res}
    write_json(Path(out) / "summary.json", summary, indent=1)
    rs = [f"{r:g}" for r in sorted(rates)]
    L = ["# Quasi-static lambda against slow constant-rate tilts (issue 13, step 1)", "",
         f"Generated by `{command}`; the method, the reference and the flag: the docstring of "
         "studies/qs_validation/study.py.  Candidate: " + f"`{candidate}`; quasi-static lambda: "
         "its committed calibration point (results/calibration).  lambda at a rate: the "
         "onset of the motion that reaches 20 mm (an arrested slip does not count).  "
         "lambda0: extrapolated to a vanishing rate "
         "(lambda = lambda0 - c r^p through the three slowest rates); not given when the rates "
         "do not converge (the flag: the module docstring).", "",
         "| specimen | seed | " + " | ".join(f"{r} deg/s" for r in rs)
         + " | lambda0 | quasi-static | QS vs lambda0 | QS vs slowest | flag | CPU s |",
         "|---|---|" + "---|" * len(rs) + "---|---|---|---|---|---|"]
    for s, v in res.items():
        if not v["rows"]:
            why = ("quasi-static point pending" if not v["quasi_static_finished"] else
                   f"pending at {v['pending_rates']} deg/s")
            L.append(f"| {s} | - | " + " | ".join("-" for _ in rs)
                     + f" | - | - | - | - | {why} | {v['cpu_seconds']:.0f} |")
            continue
        for row in v["rows"]:
            pct = (lambda x: "-" if x is None else f"{100 * x:+.1f} %")
            L.append(f"| {s} | {row['seed']} | "
                     + " | ".join(cal_report.fmt_fixed(row["rates"].get(r), 4) for r in rs)
                     + " | " + (cal_report.fmt_fixed(row["lambda0"], 4) if row["lambda0"] is not None
                                else row["rate_limit"])
                     + f" | {row['qs']:.4f} | "
                     f"{pct(row['qs_vs_lambda0'])} | {pct(row['qs_vs_slowest'])} | "
                     f"{VERDICT_TEXT[row['verdict']]} | {v['cpu_seconds']:.0f} |")
    by = {k: sorted({s for s, v in res.items() for r in v["rows"] if r["verdict"] == k})
          for k in VERDICT_TEXT}
    done = [s for s, v in res.items() if v["rows"]]
    L += ["", f"Compared: {len(done)} of {len(res)} specimens.  Flagged (quasi-static lambda "
          f"more than {100 * FLAG_TOLERANCE:.0f} % from the rate -> 0 value): "
          + (", ".join(by["flag"]) or "none") + ".  Unconfirmed (the rates do not converge; "
          "the quasi-static lambda lies on the side the trend goes): "
          + (", ".join(by["unconfirmed"]) or "none") + ".", ""]
    (Path(out) / "README.md").write_text("\n".join(L) + "\n")
    return summary


def _command(args) -> str:
    """The command that regenerates the validation (--stop-at and --runs left out)."""
    return session.command("qs-validation", out=repo_rel(args.out),
                           candidate=(args.candidate, "perfect"),
                           specimens=args.specimens or None,
                           rates=(list(args.rates), list(RATES)),
                           realisations=(args.realisations, 1), max_steps=args.max_steps)


app = cli.study_app()
LISTS = ("--specimens", "--rates")   # options that take several values: --rates 2 1 0.5


@app.command(help=cli.text(__doc__))
def qs_validation(
        out: Path = typer.Option(DEFAULT_OUT),
        calibration: Path = typer.Option(cal_specimens.ROOT / "results" / "calibration",
                                         help="the calibration study's --out (its committed "
                                              "quasi-static points)"),
        runs: Path = typer.Option(None, help="raw runs (default <out>/runs)"),
        candidate: str = typer.Option("perfect", help="a candidate of "
                                      "studies/calibration/candidates.yaml (default perfect)"),
        specimens: list[str] = typer.Option(None, help="names (default: every calibration "
                                            "specimen, cheapest first)"),
        rates: list[float] = typer.Option(list(RATES), help="deg/s; three doubling rates give "
                                          "lambda0 (default 2 1 0.5)"),
        realisations: int = typer.Option(1, help="seeds 0 .. N-1 of an imperfect candidate (a "
                                         "perfect one runs one)"),
        max_steps: int = typer.Option(None, help="cap the steps (smoke)"),
        stop_at: str = typer.Option(None, help="UTC HH:MM after which no new run starts"),
        report_only: bool = typer.Option(False, "--report", help="only rebuild the report")
        ) -> int:
    return _qs_validation(SimpleNamespace(
        out=out, calibration=calibration, runs=runs, candidate=candidate, specimens=specimens,
        rates=rates, realisations=realisations, max_steps=max_steps, stop_at=stop_at,
        report=report_only))


def main(argv=None) -> int:
    """``python -m studies qs-validation ARGV``; returns the exit code (0 ok, 2 bad options)."""
    return cli.run(app, argv, "qs-validation", lists=LISTS)


def _qs_validation(args) -> int:
    cands, all_s = cal_specimens.load_candidates(), cal_specimens.specimens()
    if args.candidate not in cands:
        cli.usage_error(f"--candidate: unknown {args.candidate!r}; known: {list(cands)}")
    bad = [x for x in args.specimens or [] if x not in all_s]
    if bad:
        cli.usage_error(f"--specimens: unknown {bad}; known: {list(all_s)}")
    if not args.rates or any(not np.isfinite(r) or r <= 0 for r in args.rates):
        cli.usage_error("--rates: positive deg/s values")
    if args.realisations < 1:
        cli.usage_error("--realisations must be >= 1")
    specs = {s: all_s[s] for s in all_s if args.specimens is None or s in args.specimens}
    params = cands[args.candidate]
    out, runs = session.begin(args.out, args.runs)
    command = _command(args)
    if not args.report:
        study = cal_points.Ensembles(args.realisations, args.max_steps)
        for s, spec in specs.items():
            for r in sorted(args.rates, reverse=True):        # the fast rate first: cheapest
                study.add(rate_dir(out, r), runs / f"rate-{r:g}", args.candidate, params, s,
                          spec, record={"rate_deg_per_s": r}, rate=r)
        kit.run(study, args.stop_at, log=lambda m: print(m, flush=True))
    report(out, args.calibration, args.candidate, all_s, args.rates, command)
    return 0


if __name__ == "__main__":
    sys.exit(main())
