"""Frequency sweeps of one shaking case (thesis Section 4.3: amplification curves, characteristic
frequency, effective range, lag times; Figs 4.19, 4.30 - 4.33, 4.43, Tables 4.2, 4.3).

``dem sweep CASE.yaml --out DIR --frequencies 1.8,2.0 --range 2.2:3.6:0.2`` runs the case once per
frequency, each run independent (dem.batch.run_batch: a local dask cluster sized to the cores with
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
  again into their cleared directories.  SIGTERM / SIGHUP stop a sweep like Ctrl-C.

Aggregation (:func:`aggregate`):
  amplification curve per quantity (ds, dsr, da, dar, a, ar, vs, vsr, va, var ...);
  characteristic frequency = frequency of the peak amplification (of ds, as Fig 4.43; per
  quantity too) if the curve has a clear peak, else null with the reason.  A clear peak is
  (1) interior: not at the lowest or highest valid frequency (at an edge the curve may go on
  rising outside the range: the elastic box models rise as f^2 up to the last point), and
  (2) standing out of the curve: at least ``PEAK_MIN_RATIO`` = 1.1 times the median
  amplification (a flat or noisy curve, where nothing responds more at one frequency than at the
  others, has its maximum within a few % of its median); it needs at least 3 valid points;
  effective range, the thesis' "two groups" (Section 4.3.1.2: "the frequencies are clearly divided
  into two groups ... with a clear gap in values of amplifications between them"): the ds
  amplifications of the valid points, sorted, are split at the largest ratio between neighbours;
  if that ratio is at least ``GAP_MIN`` = 1.5 (Model III's 3.5 vs 2.0 is 1.75, Model II's ~2.0 vs
  < 0.5 is > 4) the high group is the effective group, else (no clear gap) the points with
  amplification >= peak / sqrt(2) (half power).  The effective range is the run of consecutive
  frequencies of that group around the characteristic frequency, [f_low, f_high];
  lag times: per point (ds and dsr, s and deg) and their means inside and outside the effective
  range (the thesis' 0.13 s effective / 0.03 s ineffective for Model II y).
"""

from __future__ import annotations

from dem.output.atomic import savefig as _atomic_savefig

import json
import math
import os
import sys
from pathlib import Path

import numpy as np

GAP_MIN = 1.5
PEAK_MIN_RATIO = 1.1
DEFAULT_MARGIN = 1.0
MAIN_QUANTITY = "ds"


class SweepInputError(ValueError):
    """Bad sweep input (exit code 2); the message names the option or field."""


# ---------------------------------------------------------------------------------------------
# building the runs
# ---------------------------------------------------------------------------------------------
def parse_frequencies(frequencies: str | None = None, rng: str | None = None) -> list[float]:
    """Frequencies (Hz, sorted, unique) from "1.8,2.0,2.4" and/or "start:stop:step" (inclusive)."""
    out: list[float] = []
    if frequencies:
        for tok in frequencies.split(","):
            tok = tok.strip()
            if not tok:
                continue
            try:
                out.append(float(tok))
            except ValueError:
                raise SweepInputError(f"--frequencies: '{tok}' is not a number (Hz)") from None
    if rng:
        parts = rng.split(":")
        try:
            start, stop, step = (float(p) for p in parts)
        except ValueError:
            raise SweepInputError(f"--range: '{rng}' is not start:stop:step (Hz)") from None
        if not (step > 0) or stop < start:
            raise SweepInputError(f"--range: '{rng}' needs step > 0 and stop >= start")
        n = int(math.floor((stop - start) / step + 1e-6)) + 1
        out += [round(start + k * step, 9) for k in range(n)]
    if not out:
        raise SweepInputError("give the frequencies: --frequencies 1.8,2.0 and/or "
                              "--range 1.8:3.6:0.2")
    bad = [f for f in out if not (f > 0) or not math.isfinite(f)]
    if bad:
        raise SweepInputError(f"frequencies must be > 0 Hz, got {bad[0]}")
    return sorted({round(f, 9) for f in out})


def point_name(f: float) -> str:
    return f"f{f:.3f}Hz"


def sweep_cases(case, frequencies, cycles: float | None = None, margin: float = DEFAULT_MARGIN):
    """(name, Case) per frequency (module docstring); raises SweepInputError naming the field."""
    from pydantic import ValidationError

    from dem.case import Case, ShakeLoading

    if not isinstance(case.loading, ShakeLoading):
        raise SweepInputError(f"loading.type: a sweep needs a 'shake' loading, got "
                              f"'{case.loading.type}'")
    if cycles is not None and not (cycles > 0):
        raise SweepInputError(f"--cycles must be > 0, got {cycles}")
    if not (margin >= 0):
        raise SweepInputError(f"--margin must be >= 0 s, got {margin}")
    out = []
    for f in frequencies:
        data = case.model_dump()
        ld = data["loading"]
        ld["frequency"] = float(f)
        if cycles is not None:
            ld["cycles"] = float(cycles)
        data["run"]["duration"] = ld["cycles"] / f + margin
        data["name"] = f"{case.name}-{point_name(f)}"
        try:
            out.append((point_name(f), Case.model_validate(data)))
        except ValidationError as err:
            raise SweepInputError(f"{point_name(f)}: {err}") from None
    return out


# ---------------------------------------------------------------------------------------------
# per point (runs on the worker)
# ---------------------------------------------------------------------------------------------
def compact(analysis: dict) -> dict:
    """The small per-point record kept in sweep.json (from an analysis.json dict)."""
    ax = analysis.get("axes", {}).get(analysis.get("primary_axis"), {})
    q = ax.get("quantities", {})
    main = q.get(MAIN_QUANTITY, {})
    portion = ax.get("excited_portion") or {}
    return {
        "analysis_status": "ok",
        "note": analysis.get("error"),
        "amplification": analysis.get("amplification", {}),
        "lag": analysis.get("lag", {}),
        "h1_amplitude_ratio": {k: v.get("h1_amplitude_ratio") for k, v in q.items()},
        "dominant_frequency_hz": main.get("dominant_frequency_hz"),
        "single_peak": main.get("single_peak"),
        "steady_state": analysis.get("steady_state"),
        "unit_drift_per_m": analysis.get("unit_drift_per_m"),
        "mechanism": analysis.get("mechanism"),
        "excited": {k: portion.get(k) for k in ("n_excited", "n_upper", "n_lower", "mass_kg",
                                                  "excited_courses_from_top")} if portion else None,
        "loop_energy_J": (ax.get("hysteresis") or {}).get("loop_energy_J_mean"),
        "kinetic_energy": ax.get("kinetic_energy"),
        "other_axes": {k: v.get("amplification") for k, v in analysis.get("axes", {}).items()
                       if k != analysis.get("primary_axis")},
    }


def analyze_point(case, res, out_dir) -> dict:
    """dem.batch ``post`` hook: analyse the run directory on the worker, return :func:`compact`.
    An analysis that raises is reported (analysis_status "failed"), never fatal."""
    import traceback

    from postprocess.shake import analyze_run

    try:
        return compact(analyze_run(out_dir))
    except Exception as err:  # noqa: BLE001
        return {"analysis_status": "failed", "error": f"{type(err).__name__}: {err}",
                "traceback": traceback.format_exc()}


def finished_point(case, out_dir: Path) -> dict | None:
    """The record of a point whose directory already holds a finished run of ``case`` (same
    case.json, summary.json status ok), else None."""
    try:
        summ = json.loads((out_dir / "summary.json").read_text())
        same = json.loads((out_dir / "case.json").read_text()) == \
            json.loads(case.model_dump_json())
    except (OSError, ValueError):
        return None
    if not same or summ.get("status") != "ok":
        return None
    try:
        post = compact(json.loads((out_dir / "analysis.json").read_text()))
    except (OSError, ValueError):
        post = analyze_point(case, None, out_dir)
    return {"name": out_dir.name, "status": "ok", "out_dir": str(out_dir), "summary": summ,
            "post": post, "reused": True}


def _point_from_record(f: float, case, rec: dict, out_root: Path) -> dict:
    ld = case.loading
    p = {"name": point_name(f), "frequency_hz": f, "amplitude_m": ld.displacement_amplitude,
         "peak_acceleration_m_s2": ld.displacement_amplitude * (2 * math.pi * f) ** 2,
         "cycles": ld.cycles, "duration_s": case.run.duration, "dir": point_name(f),
         "status": rec.get("status", "pending")}
    if rec.get("status") == "failed":
        p["error"] = rec.get("error")
    summ = rec.get("summary") or {}
    for k in ("sim_time", "steps", "wall_seconds"):
        if k in summ:
            p[k] = summ[k]
    post = rec.get("post")
    if post is not None:
        if post.get("analysis_status") == "failed":
            p["status"] = "failed"
            p["error"] = "analysis: " + post.get("error", "")
        p.update({k: v for k, v in post.items() if k != "traceback"})
    return p


# ---------------------------------------------------------------------------------------------
# aggregation
# ---------------------------------------------------------------------------------------------
def _finite(x) -> bool:
    return x is not None and isinstance(x, (int, float)) and math.isfinite(x)


def effective_range(freqs, amps) -> dict:
    """Characteristic frequency and effective range (rule in the module docstring)."""
    f = np.asarray(freqs, float)
    a = np.asarray(amps, float)
    if len(f) == 0:
        return {"characteristic_frequency_hz": None, "note": "no valid point"}
    order = np.argsort(f)
    f, a = f[order], a[order]
    k = int(np.argmax(a))
    out = {"characteristic_frequency_hz": float(f[k]), "peak_amplification": float(a[k]),
           "max_amplification_at_hz": float(f[k])}
    reason = None
    if len(f) < 3:
        reason = f"{len(f)} valid point(s): a peak needs at least 3"
    elif k in (0, len(f) - 1):
        reason = (f"no clear peak: the largest amplification ({a[k]:.3g}) is at the "
                  f"{'lowest' if k == 0 else 'highest'} frequency of the range ({f[k]:g} Hz); "
                  f"the curve may go on {'rising below' if k == 0 else 'rising above'} it")
    elif not a[k] >= PEAK_MIN_RATIO * float(np.median(a)):
        reason = (f"no clear peak: the largest amplification ({a[k]:.3g} at {f[k]:g} Hz) is less "
                  f"than {PEAK_MIN_RATIO} x the median ({float(np.median(a)):.3g})")
    if reason is not None:
        out.update({"characteristic_frequency_hz": None, "characteristic_frequency_note": reason,
                    "effective_range_hz": None, "rule": None,
                    "note": "no effective range without a characteristic frequency"})
        return out
    desc = np.sort(a)[::-1]
    with np.errstate(divide="ignore", invalid="ignore"):
        ratios = desc[:-1] / desc[1:]
    ratios = np.where(np.isfinite(ratios), ratios, np.inf)
    i = int(np.argmax(ratios))
    gap = float(ratios[i])
    if gap >= GAP_MIN:
        high = a >= desc[i]
        rule = (f"two groups: largest gap between sorted amplifications, ratio {gap:.2f} >= "
                f"{GAP_MIN}")
    else:
        high = a >= a[k] / math.sqrt(2.0)
        rule = f"no clear gap (largest ratio {gap:.2f} < {GAP_MIN}): amplification >= peak / sqrt 2"
    lo = hi = k
    while lo - 1 >= 0 and high[lo - 1]:
        lo -= 1
    while hi + 1 < len(f) and high[hi + 1]:
        hi += 1
    out.update({"effective_range_hz": [float(f[lo]), float(f[hi])], "rule": rule,
                "gap_ratio": gap, "effective_frequencies_hz": f[lo:hi + 1].tolist()})
    return out


def aggregate(points: list[dict]) -> dict:
    """Curves, characteristic frequency, effective range and lag times from the point records."""
    ok = [p for p in points if p.get("status") == "ok"
          and _finite((p.get("amplification") or {}).get(MAIN_QUANTITY))]
    ok.sort(key=lambda p: p["frequency_hz"])
    names = sorted({n for p in ok for n in (p.get("amplification") or {})})
    curves = {n: [[p["frequency_hz"], p["amplification"][n]] for p in ok
                  if _finite(p["amplification"].get(n))] for n in names}
    per_q = {n: effective_range([c[0] for c in cv], [c[1] for c in cv])
             .get("characteristic_frequency_hz") for n, cv in curves.items()}
    er = effective_range([p["frequency_hz"] for p in ok],
                         [p["amplification"][MAIN_QUANTITY] for p in ok])
    inside = set(er.get("effective_frequencies_hz") or [])
    lags = {}
    for q in ("ds", "dsr"):
        rows = [[p["frequency_hz"], (p.get("lag") or {}).get(q, {}).get("s"),
                 (p.get("lag") or {}).get(q, {}).get("deg")] for p in ok]
        rows = [r for r in rows if _finite(r[1])]
        if not rows:
            continue
        ins = [r[1] for r in rows if r[0] in inside]
        outs = [r[1] for r in rows if r[0] not in inside]
        lags[q] = {"per_point": rows,
                   "mean_effective_s": float(np.mean(ins)) if ins and inside else None,
                   "mean_ineffective_s": float(np.mean(outs)) if outs and inside else None}
    return {"quantity": MAIN_QUANTITY, "n_valid": len(ok), **er,
            "characteristic_frequency_per_quantity_hz": per_q, "curves": curves, "lag": lags}


def plot_sweep(path, points: list[dict], agg: dict, title: str = "") -> None:
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    fig, (ax, ax2) = plt.subplots(2, 1, figsize=(8, 8), sharex=True)
    for n, cv in agg["curves"].items():
        if cv:
            c = np.array(cv)
            ax.plot(c[:, 0], c[:, 1], "o-" if n == MAIN_QUANTITY else ".--",
                    lw=2 if n == MAIN_QUANTITY else 1, label=n)
    er = agg.get("effective_range_hz")
    if agg.get("characteristic_frequency_hz") is None:
        ax.text(0.02, 0.95, "characteristic frequency: none\n"
                + str(agg.get("characteristic_frequency_note") or agg.get("note") or ""),
                transform=ax.transAxes, va="top", fontsize=8, wrap=True,
                bbox={"facecolor": "white", "alpha": 0.8, "edgecolor": "tab:red"})
    for a in (ax, ax2):
        if er:
            a.axvspan(er[0] - 0.02, er[1] + 0.02, color="tab:green", alpha=0.1)
        if agg.get("characteristic_frequency_hz"):
            a.axvline(agg["characteristic_frequency_hz"], color="tab:red", lw=0.8, ls=":")
        a.grid(alpha=0.3)
    for p in points:
        if p.get("status") == "failed":
            ax.axvline(p["frequency_hz"], color="k", lw=0.6, ls="--")
    ax.set_ylabel("amplification")
    ax.legend(fontsize=7, ncol=4)
    ax.set_title(title + "\n(green: effective range; red: characteristic f; black dashed: failed)")
    for q, mk in (("ds", "o-"), ("dsr", "s--")):
        rows = agg.get("lag", {}).get(q, {}).get("per_point")
        if rows:
            r = np.array(rows, float)
            ax2.plot(r[:, 0], r[:, 1], mk, label=f"lag of {q} (s)")
    ax2.set_ylabel("lag time (s)")
    ax2.set_xlabel("frequency (Hz)")
    ax2.legend(fontsize=8)
    fig.tight_layout()
    _atomic_savefig(fig, path, dpi=110)
    plt.close(fig)


def write_sweep(out: Path, meta: dict, points: list[dict], plots: bool = True) -> dict:
    from dem.output.atomic import write_json

    agg = aggregate(points)
    failed = [{"name": p["name"], "frequency_hz": p["frequency_hz"], "error": p.get("error")}
              for p in points if p.get("status") == "failed"]
    data = {**meta, "points": points, "failed": failed, "aggregate": agg}
    write_json(out / "sweep.json", data, indent=1, strict=True)
    if plots and agg["n_valid"]:
        plot_sweep(out / "sweep.png", points, agg, meta.get("case", ""))
    return data


def characteristic_text(agg: dict) -> str:
    """The printed summary of a sweep's characteristic frequency and effective range."""
    fc = agg.get("characteristic_frequency_hz")
    if fc is None:
        return ("characteristic frequency: none ("
                + str(agg.get("characteristic_frequency_note") or agg.get("note")) + ")")
    return (f"characteristic frequency {fc:g} Hz (amplification {agg.get('peak_amplification'):.3g})"
            f", effective range {agg.get('effective_range_hz')} Hz")


def _meta(case, frequencies, cycles, margin, source) -> dict:
    ld = case.loading
    mode = "peak_acceleration" if ld.peak_acceleration is not None else "amplitude"
    return {"kind": "sweep", "case": case.name, "source": str(source),
            "direction": list(ld.direction), "constant": mode,
            "peak_acceleration_m_s2": ld.peak_acceleration, "amplitude_m": ld.amplitude,
            "cycles": cycles if cycles is not None else ld.cycles, "margin_s": margin,
            "frequencies_hz": list(frequencies),
            "definitions": {
                "characteristic_frequency": "frequency of the peak amplification of "
                                            + MAIN_QUANTITY + " if the peak is clear: interior "
                                            "(not at the first or last valid frequency) and >= "
                                            f"{PEAK_MIN_RATIO} x the median amplification; "
                                            "else null with characteristic_frequency_note",
                "effective_range": "sorted amplifications split at the largest neighbour ratio if "
                                   f">= {GAP_MIN} (the thesis' two groups), else >= peak/sqrt(2); "
                                   "consecutive frequencies around the characteristic one",
                "point analysis": "postprocess.shake (analysis.json in each point directory)"}}


# ---------------------------------------------------------------------------------------------
# commands
# ---------------------------------------------------------------------------------------------
def _say(msg: str) -> None:
    print(msg, file=sys.stderr, flush=True)


def run_sweep(case_path, out, frequencies: str | None = None, rng: str | None = None,
              cycles: float | None = None, margin: float = DEFAULT_MARGIN,
              scheduler: str | None = None, workers: int | None = None,
              max_steps: int | None = None) -> int:
    """CLI body of ``dem sweep``; returns the exit code (0 all ok, 1 a point failed, 2 bad
    input)."""
    from dem.batch import run_batch
    from dem.case import CaseError, load_case
    from dem.scene import scene_from_case

    out = Path(out)
    try:
        case = load_case(case_path)
        freqs = parse_frequencies(frequencies, rng)
        cases = sweep_cases(case, freqs, cycles, margin)
        scene_from_case(cases[0][1])  # overlaps, floating blocks: before any worker starts
        if workers is not None and workers < 1:
            raise SweepInputError(f"--workers must be >= 1, got {workers}")
        if max_steps is not None and max_steps < 1:
            raise SweepInputError(f"--max-steps must be >= 1, got {max_steps}")
    except CaseError as err:
        _say(f"error: {err}")
        return 2
    except (SweepInputError, ValueError) as err:
        _say(f"error: {case_path}: {err}")
        return 2
    if out.exists() and not out.is_dir():
        _say(f"error: --out {out}: exists and is not a directory")
        return 2
    if (out / "case.json").is_file():
        _say(f"error: --out {out}: holds a single run (case.json), not a sweep; choose another "
             f"directory")
        return 2
    try:
        out.mkdir(parents=True, exist_ok=True)
    except OSError as err:
        _say(f"error: --out {out}: cannot create it ({err.strerror or err})")
        return 2
    meta = _meta(case, freqs, cycles, margin, case_path)
    by_name = {n: (f, c) for f, (n, c) in zip(freqs, cases)}
    points = {n: _point_from_record(f, c, {"status": "pending"}, out)
              for n, (f, c) in by_name.items()}
    reused = {}
    for n, (f, c) in by_name.items():
        rec = finished_point(c, out / n)
        if rec is not None:
            reused[n] = rec
            points[n] = _point_from_record(f, c, rec, out)
            points[n]["reused"] = True
    if reused:
        _say(f"{len(reused)} point(s) already finished in {out}, kept: "
             + ", ".join(f"{by_name[n][0]:g} Hz" for n in reused))
    todo = [(n, c) for n, c in cases if n not in reused]
    write_sweep(out, meta, list(points.values()), plots=False)
    n_done = [0]

    def on_done(rec: dict) -> None:
        n_done[0] += 1 if rec["name"] not in reused else 0
        f, c = by_name[rec["name"]]
        p = _point_from_record(f, c, rec, out)
        points[rec["name"]] = p
        head = f"[{n_done[0]}/{len(todo)}] {f:g} Hz"
        if p["status"] == "failed":
            _say(f"{head}: FAILED: {p.get('error')}")
        else:
            A = (p.get("amplification") or {}).get(MAIN_QUANTITY)
            a_txt = f"amplification {MAIN_QUANTITY} = {A:.3g}" if _finite(A) else \
                f"no amplification ({p.get('note') or 'no steady state'})"
            _say(f"{head}: ok, {a_txt} ({p.get('wall_seconds', 0):.1f} s wall)")
        write_sweep(out, meta, list(points.values()), plots=False)

    where = f"scheduler {scheduler}" if scheduler else \
        f"local cluster, {workers or os.cpu_count()} workers"
    _say(f"sweep {case.name}: {len(cases)} frequencies {freqs} Hz ({len(todo)} to run), {where}")
    # run_batch sets DEM_THREADS=1 in this (client) process for its workers to inherit; put it
    # back afterwards, or a later Taichi initialisation in this process would clash
    threads_env = os.environ.get("DEM_THREADS")
    from dem.signals import signal_name, stop_on_signals

    try:
        with stop_on_signals():
            records = run_batch(todo, out, scheduler=scheduler, n_workers=workers,
                                max_steps=max_steps, post=analyze_point,
                                on_done=on_done) if todo else []
    except KeyboardInterrupt as err:
        _say(f"interrupted by {signal_name(err)}; finished points are in {out}/sweep.json (a rerun"
             f" of the same command keeps them and runs the others)")
        return 1
    finally:
        if threads_env is None:
            os.environ.pop("DEM_THREADS", None)
        else:
            os.environ["DEM_THREADS"] = threads_env
    for rec in records:  # records the callback may not have seen (should not happen)
        if rec is not None and points[rec["name"]]["status"] == "pending":
            on_done(rec)
    data = write_sweep(out, meta, [points[n] for n, _ in cases])
    agg = data["aggregate"]
    _say(f"{characteristic_text(agg)}; {out}/sweep.json")
    if data["failed"]:
        _say(f"{len(data['failed'])} of {len(cases)} points failed: "
             + ", ".join(f"{x['frequency_hz']:g} Hz" for x in data["failed"]))
        return 1
    return 0


def is_sweep_dir(path: Path) -> bool:
    path = Path(path)
    return (path / "sweep.json").is_file() or (
        not (path / "case.json").is_file()
        and any((d / "case.json").is_file() for d in path.iterdir() if d.is_dir()))


def post_sweep(path) -> tuple[dict, int]:
    """Re-analyse every point directory of a sweep and rewrite sweep.json / sweep.png.
    Returns (sweep data, number of failed points)."""
    from postprocess.shake import analyze_run, load_run

    path = Path(path)
    old = {}
    if (path / "sweep.json").is_file():
        old = json.loads((path / "sweep.json").read_text())
    dirs = [path / p["dir"] for p in old.get("points", [])] or \
        sorted(d for d in path.iterdir() if d.is_dir() and (d / "case.json").is_file())
    planned = {p["dir"]: p for p in old.get("points", [])}
    points, case0 = [], None
    for d in dirs:
        prev = planned.get(d.name, {})
        if not (d / "case.json").is_file():
            err = prev.get("error") or f"{d}: no case.json (the run never started)"
            points.append({**prev, "status": "failed", "error": err})
            continue
        case, _ = load_run(d)
        case0 = case0 or case
        f = case.loading.frequency
        sp = d / "summary.json"
        summ = json.loads(sp.read_text()) if sp.is_file() else {}
        status = summ.get("status")
        if status == "ok":
            try:
                rec = {"status": "ok", "summary": summ, "post": compact(analyze_run(d))}
            except Exception as err:  # noqa: BLE001 - reported as a failed point
                rec = {"status": "ok", "summary": summ,
                       "post": {"analysis_status": "failed",
                                "error": f"{type(err).__name__}: {err}"}}
        else:
            rec = {"status": "failed", "summary": summ,
                   "error": summ.get("error") or prev.get("error")
                   or f"{d / 'summary.json'}: run status {status!r}"}
        p = _point_from_record(f, case, rec, path)
        p["dir"] = d.name
        points.append(p)
    if case0 is None:
        raise SweepInputError(f"{path}: no run directory with a case.json")
    meta = {k: v for k, v in old.items() if k not in ("points", "failed", "aggregate")} or \
        _meta(case0, [p["frequency_hz"] for p in points if "frequency_hz" in p], None,
              DEFAULT_MARGIN, "(rebuilt by dem post)")
    data = write_sweep(path, meta, points)
    return data, len(data["failed"])


def post_tilt(run_dir) -> dict:
    """Collapse and mechanism of a tilt run, recomputed from frames.npz and case.json
    (postprocess.tilt.tilt_results, the same function the run loop uses); written to
    analysis.json."""
    from dem.output.atomic import write_json
    from postprocess.block_kinematics import angular_velocity
    from postprocess.shake import ShakeAnalysisError, load_run
    from postprocess.tilt import tilt_results

    run_dir = Path(run_dir)
    case, scene = load_run(run_dir)
    path = run_dir / "frames.npz"
    if not path.is_file():
        raise ShakeAnalysisError(f"{path}: missing")
    fr = np.load(path)
    if "tilt_angle" not in fr.files:
        raise ShakeAnalysisError(f"{path}: no tilt_angle array (not a tilt run?)")
    vel = fr["vel"] if "vel" in fr.files else np.gradient(fr["pos"], fr["t"], axis=0)
    omega = fr["omega"] if "omega" in fr.files else angular_velocity(fr["t"], fr["quat"])
    res = tilt_results(case, scene, fr["t"], fr["tilt_angle"], fr["pos"], fr["quat"], vel, omega)
    out = {"kind": "tilt", "case": case.name, "collapse": res["collapse"],
           "mechanism": res.get("mechanism")}
    write_json(run_dir / "analysis.json", out, indent=1, strict=True)
    return out


def _locked(path: Path) -> bool:
    """Whether a live run holds DIR/run.lock (dem.rundir)."""
    import fcntl

    lock = path / "run.lock"
    if not lock.is_file():
        return False
    with open(lock, "rb") as fh:
        try:
            fcntl.flock(fh.fileno(), fcntl.LOCK_EX | fcntl.LOCK_NB)
        except BlockingIOError:
            return True
        fcntl.flock(fh.fileno(), fcntl.LOCK_UN)
    return False


def post_command(path) -> int:
    """CLI body of ``dem post DIR``; returns the exit code."""
    from dem.case import ShakeLoading, TiltLoading
    from postprocess.shake import ShakeAnalysisError, analyze_run, load_run

    path = Path(path)
    if not path.is_dir():
        _say(f"error: {path}: not a directory")
        return 2
    try:
        if (path / "rocking.npz").is_file() and not (path / "frames.npz").is_file():
            _say(f"{path}: a two-body rocking run; its analysis is written by `dem rocking`")
            return 0
        if is_sweep_dir(path):
            data, n_failed = post_sweep(path)
            agg = data["aggregate"]
            _say(f"{path}/sweep.json: {len(data['points'])} points, {n_failed} failed; "
                 f"{characteristic_text(agg)}")
            return 1 if n_failed else 0
        if not (path / "case.json").is_file():
            _say(f"error: {path}: not a run directory (no case.json) nor a sweep (no sweep.json)")
            return 2
        if not (path / "summary.json").is_file():
            _say(f"error: {path}: not a run: no summary.json (the run never started, or was "
                 f"killed before its first checkpoint)")
            return 2
        try:
            status = json.loads((path / "summary.json").read_text()).get("status")
        except ValueError:
            status = None
        if status == "running" and not _locked(path):
            _say(f"warning: {path}: summary.json says 'running' but no process holds the run: it "
                 f"was killed (SIGKILL, power loss); analysing the frames of its last checkpoint")
        case, _ = load_run(path)
        if isinstance(case.loading, ShakeLoading):
            res = analyze_run(path)
            _say(f"{path}/analysis.json: amplification "
                 + ", ".join(f"{k} {v:.3g}" for k, v in res.get("amplification", {}).items()
                             if _finite(v)) + (f"; {res['error']}" if res.get("error") else ""))
        elif isinstance(case.loading, TiltLoading):
            res = post_tilt(path)
            mech = res["mechanism"] or {}
            _say(f"{path}/analysis.json: collapse {res['collapse']['detected']}, mechanism "
                 f"{mech.get('mechanism') or mech.get('kind')}")
        else:
            _say(f"{path}: loading '{case.loading.type}': no analysis defined")
        return 0
    except (ShakeAnalysisError, SweepInputError) as err:
        _say(f"error: {err}")
        return 2
