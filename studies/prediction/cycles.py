"""The cycles check (protocol step 3: fewer cycles must not change the answer) and the cut it
justifies (``--cut-cycles``).
"""

from __future__ import annotations

import sys
import time
from pathlib import Path

from studies.kit.provenance import rel, source_state
from studies.kit.records import locked, read_json
from studies.prediction.analysis import analyse_sweep
from studies.prediction.points import point_key, points_path, row_from_point, sweep_finished
from studies.prediction.protocol import (CYCLES_REL_FLOOR, CYCLES_RULE, FULL_SWEEP, LEFT_OUT,
                                         NO_RAW_RUN, PredictionInputError, SURVIVAL_MIN,
                                         TRUNCATED_CYCLES)


# ---- the cycles check (protocol step 3: fewer cycles must not change the answer) --------------
def truncated_row(seed: int, f: float, run_dir: Path, cycles: float) -> dict:
    """The row (:func:`row_from_point`) of one finished run analysed over its first ``cycles``
    cycles only (postprocess.shake.analyze_run(cycles=...): as if it had shaken that many; the
    run's first cycles do not depend on how many follow, module docstring); an analysis that
    fails gives a failed row naming the error."""
    from postprocess.shake import analyze_run
    from postprocess.sweep import compact

    try:
        p = {"frequency_hz": f, "status": "ok", **compact(analyze_run(run_dir, cycles=cycles))}
    except Exception as err:  # noqa: BLE001 - reported in the row, like dem sweep's post hook
        p = {"frequency_hz": f, "status": "failed", "analysis_status": "failed",
             "error": f"analysis: {type(err).__name__}: {err}"}
    return row_from_point(seed, p)


def has_raw_run(run_dir: Path) -> bool:
    """Whether a finished point's raw run (its frames.npz) is on this machine: a point finished
    in an earlier checkout, or run elsewhere (studies.prediction.pool) and merged from its
    summary / case / analysis.json, has only its committed row."""
    return (Path(run_dir) / "frames.npz").is_file()


def truncated_points(data: dict, sweep_dir: Path, cycles: float,
                     stored: dict | None = None) -> tuple[dict, dict, list]:
    """Both sides of a cycles check of the sweep ``data`` (its committed points.json), on the
    finished rows whose first ``cycles`` cycles were analysed when they finished (``stored``:
    {(seed, frequency): row}, :func:`stored_truncated`) or can be now from their raw runs in
    ``sweep_dir`` (``seed-<k>/<point>/``, :func:`has_raw_run`): (full, short, left_out).  A
    finished row with neither is marked LEFT_OUT on both sides (named in ``left_out`` as
    [seed, frequency]), so that the full and the short answer come from the same runs;
    unfinished rows stay as they are."""
    from dem.run.sweep import point_name

    stored = stored or {}
    full, short, left_out = [], [], []
    for r in data.get("rows") or []:
        d = Path(sweep_dir) / f"seed-{r['seed']}" / point_name(r["frequency_hz"])
        k = point_key(r["seed"], r["frequency_hz"])
        if r.get("run_status") != "ok":
            full.append(dict(r))
            short.append(dict(r))
        elif k in stored or has_raw_run(d):
            full.append(r)
            short.append(stored[k] if k in stored else
                         truncated_row(r["seed"], r["frequency_hz"], d, cycles))
        else:
            left_out.append([r["seed"], r["frequency_hz"]])
            gone = {"seed": r["seed"], "frequency_hz": r["frequency_hz"],
                    "run_status": LEFT_OUT, "analysis_status": None, "note": NO_RAW_RUN}
            full.append(gone)
            short.append(dict(gone))
    return ({"prediction": data["prediction"], "rows": full},
            {"prediction": {**data["prediction"], "cycles": cycles}, "rows": short}, left_out)


def median_agrees(full: dict | None, short: dict | None) -> dict:
    """Medians of two statistics agree when |short - full| <= max(q90 - q10 of full,
    CYCLES_REL_FLOOR x |full median|) (the floor: a band of zero width, one realisation)."""
    if not (full and full.get("n") and short and short.get("n")):
        return {"same": None, "full": (full or {}).get("median"),
                "short": (short or {}).get("median"), "why": "no data"}
    tol = max(full["q90"] - full["q10"], CYCLES_REL_FLOOR * abs(full["median"]))
    d = short["median"] - full["median"]
    return {"same": abs(d) <= tol + 1e-12, "full": full["median"], "short": short["median"],
            "full_band": [full["q10"], full["q90"]], "short_band": [short["q10"], short["q90"]],
            "difference": d, "tolerance": tol}


def cycles_verdict(full: dict, short: dict, freqs) -> dict:
    """Does analysing fewer cycles change the answer?  ``full`` / ``short``: analyse_sweep of the
    same runs over all / the first N cycles; freqs: the sweep's frequencies (Hz).  The rule:
    CYCLES_RULE ((2): :func:`median_agrees`).  Returns the three comparisons, ``changed`` (the
    names of those that differ) and ``unchanged`` (None when one could not be judged)."""
    fs = sorted(freqs)
    a, b = full.get("characteristic_frequency_hz"), short.get("characteristic_frequency_hz")
    if a is None or b is None:
        same_fc = a is None and b is None
    else:
        same_fc = abs(fs.index(a) - fs.index(b)) <= 1
    out = {"characteristic_frequency": {"full": a, "short": b, "same": same_fc,
                                        "full_note": full.get("characteristic_frequency_note"),
                                        "short_note": short.get("characteristic_frequency_note")}}
    io_f = (full.get("inside_outside") or {}).get("thesis_range") or {}
    io_s = (short.get("inside_outside") or {}).get("thesis_range") or {}
    for key in ("amplification_ds_inside", "amplification_ds_outside"):
        out[key] = median_agrees(io_f.get(key), io_s.get(key))
    rf = (full.get("survival") or {}).get("min_rate")
    rs = (short.get("survival") or {}).get("min_rate")
    ok_f = None if rf is None else rf >= SURVIVAL_MIN - 1e-12
    ok_s = None if rs is None else rs >= SURVIVAL_MIN - 1e-12
    out["survival"] = {"full": rf, "short": rs, "full_pass": ok_f, "short_pass": ok_s,
                       "same": ok_f == ok_s if None not in (ok_f, ok_s) else None}
    items = {k: v["same"] for k, v in out.items()}
    changed = [k for k, v in items.items() if v is False]
    out["changed"] = changed
    out["unchanged"] = None if not changed and None in items.values() else not changed
    return out


def truncated_path(out: Path, name: str) -> Path:
    return Path(out) / name / "truncated.json"


def stored_truncated(out: Path, name: str, fp: str, cycles: float) -> dict:
    """{(seed, frequency): row} of the committed truncated.json for ``cycles`` cycles (none
    when it was made for another fingerprint)."""
    data = read_json(truncated_path(out, name)) or {}
    if data.get("fingerprint") != fp:
        return {}
    return {point_key(r["seed"], r["frequency_hz"]): r
            for r in (data.get("rows") or {}).get(f"{cycles:g}", [])}


POOL_TRUNCATED = "truncated-rows.json"   # a point_pool run's analyses of its first N cycles


def record_truncated(out: Path, runs: Path, name: str, fp: str, log=print) -> int:
    """Analyse every finished point of the sweep's points.json over its first N cycles, for each
    N of TRUNCATED_CYCLES below the sweep's cycles, while its raw run is here (or take the
    analyses a point_pool machine made, ``<point>/truncated-rows.json``), and merge them into the
    committed ``<out>/<sweep>/truncated.json`` (under the lock of points.json).  So the cycles
    check (:func:`cycles_check`) does not depend on raw runs surviving from session to session
    (a new checkout loses them; a pooled point never had them here).  ~0.6 s per analysis.
    Returns the number of points added."""
    from dem.output.atomic import write_json
    from dem.run.sweep import point_name

    data = read_json(points_path(out, name))
    if not data or (data.get("prediction") or {}).get("fingerprint") != fp:
        return 0
    ns = [n for n in TRUNCATED_CYCLES if 2 <= n < data["prediction"]["cycles"]]
    if not ns:
        return 0
    have = stored_truncated(out, name, fp, ns[0])
    new: dict[str, list] = {f"{n:g}": [] for n in ns}
    for r in data.get("rows") or []:
        k = point_key(r["seed"], r["frequency_hz"])
        if r.get("run_status") != "ok" or k in have:
            continue
        d = Path(runs) / name / f"seed-{r['seed']}" / point_name(r["frequency_hz"])
        pooled = read_json(d / POOL_TRUNCATED)
        if pooled is not None and all(f"{n:g}" in pooled for n in ns):
            for n in ns:
                new[f"{n:g}"].append(pooled[f"{n:g}"])
        elif has_raw_run(d):
            for n in ns:
                new[f"{n:g}"].append(truncated_row(r["seed"], r["frequency_hz"], d, n))
    added = len(new[f"{ns[0]:g}"])
    if not added:
        return 0
    dest = truncated_path(out, name)
    with locked(points_path(out, name)):
        old = read_json(dest) or {}
        rows = (old.get("rows") or {}) if old.get("fingerprint") == fp else {}
        for n, lst in new.items():
            mine = {point_key(x["seed"], x["frequency_hz"]): x for x in rows.get(n, [])}
            mine.update({point_key(x["seed"], x["frequency_hz"]): x for x in lst})
            rows[n] = [mine[k] for k in sorted(mine)]
        write_json(dest, {"kind": "prediction-truncated-rows", "sweep": name,
                          "fingerprint": fp, "cycles": ns, "rows": rows,
                          "what": "each finished point's analysis over its first N cycles "
                                  "(postprocess.shake.analyze_run(cycles=N)), made while its "
                                  "raw run existed: the input of the cycles checks"},
                   indent=1)
    log(f"    {name}: first {', '.join(f'{n:g}' for n in ns)} cycles of {added} finished "
        f"point(s) analysed -> {rel(dest)}")
    return added


def cycles_check(out: Path, runs: Path, name: str, cycles: float) -> dict:
    """Compare the finished runs of a sweep over their first ``cycles`` cycles (the kept
    analyses of truncated.json, after :func:`record_truncated` has added those of the raw runs
    here; else analysed now from a raw run; no simulation) with the full cycles
    (:func:`cycles_verdict`) and write ``<out>/<sweep>/cycles-check-<N>.json`` (committed, like
    points.json); returns it.
    PredictionInputError without the sweep's points.json or with ``cycles`` not in
    [2, the sweep's cycles)."""
    from dem.output.atomic import write_json

    data = read_json(points_path(out, name))
    if not data or "prediction" not in data:
        raise PredictionInputError(f"{points_path(out, name)}: missing: run the sweep first")
    full_cycles = data["prediction"]["cycles"]
    if not 2 <= cycles < full_cycles:
        raise PredictionInputError(f"--cycles-check {cycles:g}: must lie in [2, {full_cycles:g}) "
                                   f"(the sweep ran {full_cycles:g} cycles; cycle 1 is dropped)")
    fp = data["prediction"].get("fingerprint")
    record_truncated(out, runs, name, fp, log=lambda m: print(m, file=sys.stderr))
    stored = stored_truncated(out, name, fp, cycles)
    full, short, left_out = truncated_points(data, Path(runs) / name, cycles, stored)
    full_sw, short_sw = analyse_sweep(name, full), analyse_sweep(name, short)
    res = {"kind": "prediction-cycles-check", "sweep": name, "cycles": cycles,
           "full_cycles": full_cycles, "sweep_finished": sweep_finished(data),
           "n_runs": full_sw["n_run"],
           "n_runs_sweep": sum(1 for r in data.get("rows") or [] if r.get("run_status") == "ok"),
           "left_out_no_raw_run": left_out, "rows": short["rows"],
           "verdict": cycles_verdict(full_sw, short_sw, data["prediction"]["frequencies_hz"]),
           "rule": CYCLES_RULE,
           "source": source_state()}
    write_json(cycles_check_path(out, name, cycles), res, indent=1)
    return res


def verdict_text(v: dict) -> str:
    """One line for a :func:`cycles_verdict`."""
    return {True: "unchanged", False: "CHANGED: " + ", ".join(v["changed"]),
            None: "not judged (no data)"}[v["unchanged"]]


def cycles_check_path(out: Path, name: str, cycles: float) -> Path:
    return Path(out) / name / f"cycles-check-{cycles:g}.json"




def cut_record(out: Path, plan: dict | None, cycles: float) -> dict:
    """The justification of running sweeps other than FULL_SWEEP at ``cycles`` < the plan's
    (protocol step 3: Model II y in full first, and a cut shown not to change the answer):
    FULL_SWEEP finished at the plan's cycles, and its committed
    ``cycles-check-<N>.json``, made from the finished sweep, says the answer is unchanged
    (:func:`cycles_verdict`).  PredictionInputError naming what is missing otherwise."""
    if plan is None:
        raise PredictionInputError(f"--cut-cycles: {out}/plan.json missing: {FULL_SWEEP} runs "
                                   f"in full first")
    if not 2 <= cycles < plan["cycles"]:
        raise PredictionInputError(f"--cut-cycles {cycles:g}: must lie in [2, {plan['cycles']:g})"
                                   f" (the plan's cycles)")
    full = read_json(points_path(out, FULL_SWEEP))
    if not sweep_finished(full) or full["prediction"]["cycles"] != plan["cycles"]:
        raise PredictionInputError(f"--cut-cycles: {FULL_SWEEP} has not finished at the plan's "
                                   f"{plan['cycles']:g} cycles ({points_path(out, FULL_SWEEP)}):"
                                   f" no cut before it")
    path = cycles_check_path(out, FULL_SWEEP, cycles)
    chk = read_json(path)
    if not chk or not chk.get("sweep_finished"):
        raise PredictionInputError(f"--cut-cycles: {path} missing or made before {FULL_SWEEP} "
                                   f"finished: run --cycles-check {cycles:g} --only {FULL_SWEEP}")
    v = chk["verdict"]
    if v.get("unchanged") is not True:
        raise PredictionInputError(f"--cut-cycles {cycles:g}: {path} says the answer "
                                   f"{verdict_text(v)}: no cut")
    return {"cycles": cycles, "full_cycles": plan["cycles"], "justified_by": rel(path),
            "verdict": verdict_text(v),
            "decided_utc": time.strftime("%Y-%m-%dT%H:%M:%SZ", time.gmtime())}

