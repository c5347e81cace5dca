"""Analysis of a frequency sweep: per-point records, the aggregate (amplification curves,
characteristic frequency, effective range, lag times: thesis Section 4.3, Figs 4.19, 4.30 - 4.33,
4.43, Tables 4.2, 4.3), sweep.json and sweep.png.  The runs themselves: dem.run.sweep and the
``dem sweep`` command (dem_cli.commands.sweep).

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
  range (the thesis' 0.13 s effective / 0.03 s ineffective for Model II y);
  survival: each point's verdict, standing / local collapse / collapse, from
  every brick of its frames (postprocess.survival, kept in the point record as ``survival``),
  gathered by frequency with the count of each verdict (:func:`survival_by_point`).
"""

from __future__ import annotations

import json
import math
from pathlib import Path

import numpy as np

from dem.output.atomic import savefig as _atomic_savefig
from dem.output.plotting import agg_pyplot
from dem.run.sweep import DEFAULT_MARGIN, SweepInputError, point_name

GAP_MIN = 1.5
PEAK_MIN_RATIO = 1.1
MAIN_QUANTITY = "ds"


# ---------------------------------------------------------------------------------------------
# per point
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
        "collapse_suspected": ax.get("collapse_suspected"),
        "kinetic_energy": ax.get("kinetic_energy"),
        "other_axes": {k: v.get("amplification") for k, v in analysis.get("axes", {}).items()
                       if k != analysis.get("primary_axis")},
        "a_lowpass": (ax.get("a_lowpass_sensitivity") or {}).get("amplification"),
    }


def analyze_point(case, res, out_dir) -> dict:
    """dem.batch ``post`` hook: analyse the run directory on the worker, return :func:`compact`.
    An analysis that raises is reported (analysis_status "failed"), never fatal."""
    import traceback

    from postprocess.shake import analyze_run

    try:
        out = compact(analyze_run(out_dir))
    except Exception as err:  # noqa: BLE001
        return {"analysis_status": "failed", "error": f"{type(err).__name__}: {err}",
                "traceback": traceback.format_exc()}
    out["survival"] = point_survival(case, res)
    return out


def run_dir_survival(run_dir) -> dict | None:
    """:func:`point_survival` of a finished run directory (``dem post`` of a sweep)."""
    from postprocess.survival import compact as compact_survival, survival_of_run

    try:
        return compact_survival(survival_of_run(run_dir))
    except Exception as err:  # noqa: BLE001 - the amplifications stand without it
        return {"verdict": None, "error": f"{type(err).__name__}: {err}"}


def point_survival(case, res) -> dict | None:
    """The survival verdict of a point (postprocess.survival: standing, local collapse or
    collapse, with its fallen bricks by wall, corner, course, time and cycle) from the run's
    frames, or None where the run handed back none; an error is recorded, never fatal."""
    from dem.loading import loading_from_case
    from postprocess.survival import compact as compact_survival, survival

    if res is None or getattr(res, "scene", None) is None or not len(res.t):
        return None
    try:
        return compact_survival(survival(res.scene, res.t, res.pos, res.quat,
                                         loading_from_case(case)))
    except Exception as err:  # noqa: BLE001 - the amplifications stand without it
        return {"verdict": None, "error": f"{type(err).__name__}: {err}"}


def point_record(f: float, case, rec: dict, out_root: Path) -> dict:
    ld = case.loading
    p = {"name": point_name(f), "frequency_hz": f, "amplitude_m": ld.displacement_amplitude,
         "peak_acceleration_m_s2": ld.displacement_amplitude * (2 * math.pi * f) ** 2,
         "cycles": ld.cycles, "duration_s": case.run.duration, "dir": point_name(f),
         "status": rec.get("status", "pending")}
    if rec.get("status") == "failed":
        p["error"] = rec.get("error")
    summ = rec.get("summary") or {}
    for k in ("sim_time", "steps", "wall_seconds", "machine"):
        if k in summ:
            p[k] = summ[k]
    if summ.get("resumed"):  # the machines of the later processes of a resumed run
        p["resumed_on"] = [r.get("machine") for r in summ["resumed"]]
    post = rec.get("post")
    if post is not None:
        # the analysis' own error must not replace the marked one below (or the run's)
        p.update({k: v for k, v in post.items() if k not in ("traceback", "error")})
        if post.get("analysis_status") == "failed":
            p["status"] = "failed"
            p["error"] = "analysis: " + (post.get("error") or "")
    return p


# ---------------------------------------------------------------------------------------------
# aggregation
# ---------------------------------------------------------------------------------------------
def finite(x) -> bool:
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
          and finite((p.get("amplification") or {}).get(MAIN_QUANTITY))]
    ok.sort(key=lambda p: p["frequency_hz"])
    names = sorted({n for p in ok for n in (p.get("amplification") or {})})
    curves = {n: [[p["frequency_hz"], p["amplification"][n]] for p in ok
                  if finite(p["amplification"].get(n))] for n in names}
    per_q = {n: effective_range([c[0] for c in cv], [c[1] for c in cv])
             .get("characteristic_frequency_hz") for n, cv in curves.items()}
    er = effective_range([p["frequency_hz"] for p in ok],
                         [p["amplification"][MAIN_QUANTITY] for p in ok])
    inside = set(er.get("effective_frequencies_hz") or [])
    lags = {}
    for q in ("ds", "dsr"):
        rows = [[p["frequency_hz"], (p.get("lag") or {}).get(q, {}).get("s"),
                 (p.get("lag") or {}).get(q, {}).get("deg")] for p in ok]
        rows = [r for r in rows if finite(r[1])]
        if not rows:
            continue
        ins = [r[1] for r in rows if r[0] in inside]
        outs = [r[1] for r in rows if r[0] not in inside]
        lags[q] = {"per_point": rows,
                   "mean_effective_s": float(np.mean(ins)) if ins and inside else None,
                   "mean_ineffective_s": float(np.mean(outs)) if outs and inside else None}
    out = {"quantity": MAIN_QUANTITY, "n_valid": len(ok), **er,
           "characteristic_frequency_per_quantity_hz": per_q, "curves": curves, "lag": lags}
    surv = survival_by_point(points)
    if surv is not None:
        out["survival"] = surv
    return out


def survival_by_point(points: list[dict]) -> dict | None:
    """The survival verdicts of the finished points (postprocess.survival), by frequency:
    [f, verdict, fallen bricks, cycle of the first fall], and the count of each verdict; None
    when no point has one (a sweep analysed before the points recorded it)."""
    from postprocess.survival import count_verdicts

    rows = sorted([p["frequency_hz"], p["survival"]["verdict"], p["survival"].get("n_fallen"),
                   p["survival"].get("first_fall_cycle")] for p in points
                  if p.get("status") == "ok" and (p.get("survival") or {}).get("verdict"))
    if not rows:
        return None
    return {"per_point": rows, "counts": count_verdicts(r[1] for r in rows),
            "columns": ["frequency_hz", "verdict", "n_fallen", "first_fall_cycle"]}


def plot_sweep(path, points: list[dict], agg: dict, title: str = "") -> None:
    plt = agg_pyplot()

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


def sweep_meta(case, frequencies, cycles, margin, source) -> dict:
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
                rec["post"]["survival"] = run_dir_survival(d)
            except Exception as err:  # noqa: BLE001 - reported as a failed point
                rec = {"status": "ok", "summary": summ,
                       "post": {"analysis_status": "failed",
                                "error": f"{type(err).__name__}: {err}"}}
        else:
            rec = {"status": "failed", "summary": summ,
                   "error": summ.get("error") or prev.get("error")
                   or f"{d / 'summary.json'}: run status {status!r}"}
        p = point_record(f, case, rec, path)
        p["dir"] = d.name
        points.append(p)
    if case0 is None:
        raise SweepInputError(f"{path}: no run directory with a case.json")
    meta = {k: v for k, v in old.items() if k not in ("points", "failed", "aggregate")} or \
        sweep_meta(case0, [p["frequency_hz"] for p in points if "frequency_hz" in p], None,
              DEFAULT_MARGIN, "(rebuilt by dem post)")
    data = write_sweep(path, meta, points)
    return data, len(data["failed"])
