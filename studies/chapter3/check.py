"""Chapter 3 unchanged: the frozen set's calibration tilts re-run on the engine that runs the
prediction, compared realisation by realisation with the committed calibration (the
prediction's criterion "Chapter 3: the calibrated results unchanged within 5 %").

    python -m studies chapter3-check                     # run (resumable), then compare
    python -m studies chapter3-check --compare-only      # compare what has run
    python -m studies chapter3-check --seeds 2 --specimens ip-small-5x5 ip-small-5x15

What it runs.  For the frozen candidate (``candidate:`` of studies/calibration/frozen.yaml, whose
``imperfections:`` must equal that candidate's entry in studies/calibration/candidates.yaml), every
calibration specimen (studies.calibration.specimens.specimens) with the first N of the
calibration's seeds (default N = 1: seed 0), through studies.calibration.points.run_point: the same case,
the same quasi-static tilt, the same ``dem ensemble`` child with one thread.  The committed record
of a point goes to ``<out>/<candidate>/<specimen>/ensemble.json`` (default out
results/prediction/chapter3-check), its raw runs under ``--runs`` (default
results/prediction/runs/chapter3-check, git-ignored).  A finished point is skipped on a rerun.

What it compares.  Realisation k of a specimen is the same wall with the same bed unevenness
(the ensemble's seed k) in the calibration and here, so a change of the engine's results shows
in every realisation: the check compares lambda = tan(collapse angle) (dimensionless) of each
re-run seed with the calibration's value of that seed,

    d = |lambda_now - lambda_calibrated| / lambda_calibrated,

and passes when every compared realisation has d <= 5 % (:data:`TOLERANCE`), fails when one
has more, and is pending while a specimen has not finished.  The mechanisms are listed beside
(same / differs), not judged: the criterion is about the calibrated numbers.  ``same_case``
says whether the re-run case is the calibration's (their fingerprints with the calibration's N;
a case file or builder changed since then reads False).  The record, ``<out>/check.json``, names
the commit that ran and the engine's results revision; the prediction report reads it.

Other imperfections on top (:func:`run_points`, :func:`compare` with ``patches``): a specimen's
patch (imperfection fields, e.g. the as-built ``head_gap``) is added to the frozen candidate's
parameters of that specimen's case, and the re-run is compared with the calibration seed by seed
in the same way (studies.as_built.chapter3).  Without patches the cases, fingerprints and
records are the check's own.
"""

from __future__ import annotations

import sys
import time
from pathlib import Path
from types import SimpleNamespace

import typer
import yaml

from dem.engine import RESULTS_REVISION
from studies.calibration import points as cal_points
from studies.calibration import specimens as cal_specimens
from studies.kit import cli, provenance
from studies.kit import study as kit
from studies.kit.provenance import rel
from studies.kit.records import read_json
from studies.prediction.protocol import CHAPTER3_CHECK
from studies.kit.provenance import ROOT

DEFAULT_FROZEN = ROOT / "studies" / "calibration" / "frozen.yaml"
DEFAULT_CALIBRATION = ROOT / "results" / "calibration"
CHECK_DIR, CHECK_FILE = CHAPTER3_CHECK.split("/")  # under the prediction's --out
DEFAULT_OUT = ROOT / "results" / "prediction" / CHECK_DIR
DEFAULT_RUNS = ROOT / "results" / "prediction" / "runs" / CHECK_DIR
TOLERANCE = 0.05  # relative, on lambda: the criterion "unchanged within 5 %"


class CheckInputError(ValueError):
    """A bad input of the check, naming the file or option."""


def frozen_candidate(frozen_path: Path, candidates: dict) -> tuple[str, dict]:
    """(name, parameters) of the frozen set, checked against the candidates file."""
    try:
        data = yaml.safe_load(Path(frozen_path).read_text()) or {}
    except OSError as err:
        raise CheckInputError(f"{frozen_path}: {err}") from err
    name, params = data.get("candidate"), data.get("imperfections")
    if not name or not isinstance(params, dict):
        raise CheckInputError(f"{frozen_path}: needs 'candidate' and 'imperfections'")
    if name not in candidates:
        raise CheckInputError(f"{frozen_path}: candidate {name!r} is not in the candidates file "
                              f"({list(candidates)})")
    if candidates[name] != params:
        raise CheckInputError(f"{frozen_path}: imperfections {params} differ from candidate "
                              f"{name!r}'s {candidates[name]} in the candidates file")
    return name, params


def _by_seed(data: dict | None) -> dict[int, dict]:
    return {int(r["seed"]): r for r in (data or {}).get("realisations") or []
            if r.get("status") == "ok" and r.get("lambda") is not None}


def compare_point(calibrated: dict | None, rerun: dict | None, seeds: list[int],
                  tol: float = TOLERANCE) -> dict:
    """One specimen: per seed, lambda calibrated / now, d and the mechanisms; status pass (every
    seed within ``tol``), fail (one beyond) or pending (the calibration or the re-run lacks a
    seed)."""
    old, new = _by_seed(calibrated), _by_seed(rerun)
    rows, missing = [], []
    for s in seeds:
        if s not in old or s not in new:
            missing.append(s)
            continue
        a, b = float(old[s]["lambda"]), float(new[s]["lambda"])
        d = abs(b - a) / abs(a)
        rows.append({"seed": s, "lambda_calibrated": a, "lambda_now": b, "rel_diff": d,
                     "within": d <= tol + 1e-12, "mechanism_calibrated": old[s].get("mechanism"),
                     "mechanism_now": new[s].get("mechanism"),
                     "same_mechanism": old[s].get("mechanism") == new[s].get("mechanism")})
    status = "fail" if any(not r["within"] for r in rows) else (
        "pending" if missing else "pass")
    return {"status": status, "seeds_missing": missing, "rows": rows,
            "max_rel_diff": max((r["rel_diff"] for r in rows), default=None)}


def verdict(points: dict[str, dict], tol: float = TOLERANCE,
            n_specimens: int | None = None) -> dict:
    """The criterion over every specimen's :func:`compare_point`; with ``n_specimens`` (the
    calibration's count) a check of fewer specimens passes nothing: pending at best."""
    if not points:
        return {"status": "pending", "why": "no specimen compared"}
    bad = [n for n, p in points.items() if p["status"] == "fail"]
    pend = [n for n, p in points.items() if p["status"] == "pending"]
    rows = [(n, r) for n, p in points.items() for r in p["rows"]]
    worst = max(rows, key=lambda x: x[1]["rel_diff"], default=None)
    n_mech = sum(r["same_mechanism"] for _, r in rows)
    partial = n_specimens is not None and len(points) < n_specimens
    status = "fail" if bad else ("pending" if pend or partial else "pass")
    why = (f"{len(rows)} realisation(s) of {len(points)} specimen(s) re-run: largest |d lambda| / "
           f"lambda {worst[1]['rel_diff']:.2%} ({worst[0]}, seed {worst[1]['seed']}; "
           f"tolerance {tol:.0%}); same mechanism in {n_mech} of {len(rows)}"
           if worst else "nothing compared yet")
    if bad:
        why += f"; beyond the tolerance: {bad}"
    if pend:
        why += f"; not finished: {pend}"
    if partial:
        why += f"; only {len(points)} of the calibration's {n_specimens} specimens"
    return {"status": status, "why": why}


def case_params(params: dict, patch: dict | None) -> dict:
    """The imperfections of one specimen's re-run: the candidate's ``params`` with ``patch``'s
    fields (imperfection fields of the case schema, dem/case/imperfections.py) added; a patch
    may not replace a candidate's own parameter (the check would no longer be of that set)."""
    patch = patch or {}
    clash = sorted(set(patch) & set(params))
    if clash:
        raise CheckInputError(f"patch: {clash} would replace the candidate's own parameters")
    return {**params, **patch}


def run_points(out: Path, runs: Path, candidate: str, params: dict, specs: dict,
               n_seeds: int, max_steps: int | None = None, patches: dict | None = None,
               stop_at: str | None = None, study=None, log=print) -> list[str]:
    """Run (resumable) each specimen of ``specs`` with the calibration's seeds 0 .. n_seeds-1
    and ``params`` plus the specimen's patch (``patches``: specimen -> fields, none by default)
    through studies.calibration.points.Ensembles, records under ``out``, raw runs under
    ``runs``; ``stop_at``: UTC HH:MM after which no point starts; ``study``: an Ensembles of
    n_seeds to plan on (default a new one).  Returns each point's state."""
    study = study if study is not None else cal_points.Ensembles(n_seeds, max_steps)
    for s, spec in specs.items():
        study.add(out, runs, candidate, case_params(params, (patches or {}).get(s)), s, spec)
    return [state for _, state in kit.run(study, stop_at, log=log)]


def compare(out: Path, calibration: Path, candidate: str, specs: dict, seeds: list[int],
            params: dict, tol: float = TOLERANCE, patches: dict | None = None) -> dict:
    """check.json's content from the committed calibration and the re-run points; with
    ``patches`` (specimen -> extra imperfection fields, :func:`case_params`) each specimen's
    re-run case is the patched one, and its entry names its patch."""
    points = {}
    for s, spec in specs.items():
        calib = read_json(cal_points.point_path(calibration, candidate, s))
        rerun = read_json(cal_points.point_path(out, candidate, s))
        p = compare_point(calib, rerun, seeds, tol)
        if patches is not None:
            p["patch"] = patches.get(s) or {}
        case = cal_specimens.specimen_case(
            spec["path"], params if patches is None else case_params(params, patches.get(s)),
            f"cal-{candidate}-{s}")
        n_cal = ((calib or {}).get("calibration") or {}).get("n_realisations")
        p["same_case"] = (None if n_cal is None else
                          cal_specimens.fingerprint(case, n_cal, None) ==
                          (calib or {}).get("calibration", {}).get("fingerprint"))
        p["cpu_seconds"] = ((rerun or {}).get("calibration") or {}).get("cpu_seconds")
        p["source"] = ((rerun or {}).get("calibration") or {}).get("source")
        points[s] = p
    return {"kind": "chapter3-check", "candidate": candidate, "parameters": params,
            "calibration": rel(calibration), "seeds": seeds, "tolerance": tol,
            "engine_results_revision": RESULTS_REVISION, "source": provenance.source_state(),
            "cpu_seconds": sum(p["cpu_seconds"] or 0.0 for p in points.values()),
            "specimens": points,
            "verdict": verdict(points, tol, len(cal_specimens.specimens()))}


app = cli.study_app()


@app.command(help=cli.text(__doc__))
def chapter3_check(
        ctx: typer.Context,
        frozen: Path = typer.Option(DEFAULT_FROZEN),
        calibration: Path = typer.Option(DEFAULT_CALIBRATION,
                                         help="the committed calibration study (its "
                                              "<candidate>/<specimen>/ensemble.json)"),
        out: Path = typer.Option(DEFAULT_OUT),
        runs: Path = typer.Option(DEFAULT_RUNS, help="raw runs (git-ignored)"),
        seeds: int = typer.Option(1, metavar="N", help="re-run the calibration's seeds 0 .. N-1 "
                                                       "of each specimen"),
        specimens: list[str] = typer.Option(None, help="names (default: all)"),
        candidates_file: Path = typer.Option(cal_specimens.CANDIDATES_FILE),
        max_steps: int = typer.Option(None, help="cap each run (smoke: a capped point is not "
                                                 "the calibration's case)"),
        compare_only: bool = typer.Option(False, "--compare-only", help="run nothing")) -> int:
    return _check(SimpleNamespace(frozen=frozen, calibration=calibration, out=out, runs=runs,
                                  seeds=seeds, specimens=specimens,
                                  candidates_file=candidates_file, max_steps=max_steps,
                                  compare_only=compare_only), ctx.obj["argv"])


def main(argv=None) -> int:
    """``python -m studies chapter3-check ARGV``; returns the exit code (0 ok, 1 a run failed
    or was stopped, 2 bad input)."""
    return cli.run(app, argv, "chapter3-check", lists=("--specimens",))


def _check(args, argv: list[str]) -> int:
    try:
        if args.seeds < 1:
            raise CheckInputError("--seeds must be >= 1")
        candidate, params = frozen_candidate(args.frozen, cal_specimens.load_candidates(
            args.candidates_file))
        all_s = cal_specimens.specimens()
        bad = [s for s in args.specimens or [] if s not in all_s]
        if bad:
            raise CheckInputError(f"--specimens: unknown {bad}; known: {list(all_s)}")
    except (CheckInputError, ValueError) as err:
        print(f"error: {err}", file=sys.stderr)
        return 2
    specs = {s: v for s, v in all_s.items() if args.specimens is None or s in args.specimens}
    seeds = list(range(args.seeds))
    states = []
    if not args.compare_only:
        states = run_points(args.out, args.runs, candidate, params, specs, args.seeds,
                            args.max_steps, log=lambda m: print(m, flush=True))
    from dem.output.atomic import write_json

    args.out.mkdir(parents=True, exist_ok=True)
    data = compare(args.out, args.calibration, candidate, specs, seeds, params)
    data["command"] = "python -m studies chapter3-check " + " ".join(argv)
    data["written"] = time.strftime("%Y-%m-%d %H:%M UTC", time.gmtime())
    write_json(args.out / CHECK_FILE, data, indent=1)
    v = data["verdict"]
    print(f"Chapter 3 unchanged within {TOLERANCE:.0%}: {v['status']}: {v['why']}\n"
          f"{args.out / CHECK_FILE}", file=sys.stderr)
    return 0 if all(s in ("skipped", "finished") for s in states) else 1


if __name__ == "__main__":
    sys.exit(main())
