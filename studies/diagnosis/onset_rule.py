"""The onset rule: does one number per run, the table's acceleration times the quiet branch's
amplification, say which runs started rocking from rest?

Every from-rest run of the diagnosis ended on one of two branches (``postprocess.verdicts.
response_branch``: rocking, or the quiet quasi-static one).  The rule tried here treats the quiet
branch as a linear single-degree-of-freedom mode on a moving base, with the natural frequency
f_n that E1 read from the same candidate's quiet run at 2.0 Hz (studies/diagnosis/e1.py), and
says a run leaves rest when the mode's response reaches a fixed capacity:

    rocking  <=>  A T(f; f_n, zeta) >= a0                                           (1)

A (m/s2) is the table's peak acceleration (2 pi f)^2 x its displacement amplitude, f (Hz) the
drive's frequency, a0 (m/s2) one capacity for every run, zeta the mode's damping ratio.  Three
amplifications T of the steady response to u_g = X sin(w t), r = f / f_n (Chopra, Dynamics of
Structures, 4th ed., Sections 3.2 and 3.6):

* ``relative`` (what E1 measured: ds, the top's displacement relative to the table, over the
  table's; E1 inverted its zeta = 0 form r^2 / |1 - r^2|):
  T = r^2 / sqrt((1 - r^2)^2 + (2 zeta r)^2).  A T is the amplitude of the top's acceleration
  relative to the table (w^2 u for a response at f).
* ``deformation``: R_d = T_relative / r^2 = 1 / sqrt((1 - r^2)^2 + (2 zeta r)^2).  A R_d is the
  pseudo-acceleration w_n^2 u, the spring force per unit mass: the equivalent static
  acceleration, the one a static capacity (a tilt, an uplift moment) is compared with.
* ``absolute``: TR = sqrt(1 + (2 zeta r)^2) / sqrt((1 - r^2)^2 + (2 zeta r)^2), the top's
  absolute acceleration over the table's.

``relative`` is the default because it is E1's measured quantity; the other two are reported
beside it.  Below resonance (every quiet run here: r = 0.2-0.9) R_d and TR are 1-5 and nearly
flat in f, while T_relative grows as r^2: the definitions differ in how much frequency, rather
than acceleration, decides.

For a fixed zeta the best a0 is a one-dimensional cut (:func:`best_threshold`): the scores
s_i = A_i T_i sorted, every cut between two neighbours tried, the one that classifies the most
runs kept; the optimal cuts form an interval, reported whole with its geometric middle as a0.
zeta is scanned (:func:`fit`); it is identifiable only if few values reach the best count.
Independently, a quiet run's ds amplification and phase give both f_n and zeta of the mode
(:func:`sdof_from_response`, exact for the damped mode): E1's runs read that way
(:func:`damped_table`) give a rule with a0 its only free parameter (:func:`analyse_damped`).
Two reference rules set the scale of a count: "never rocks" and A >= a0 alone (T = 1).

Records read (committed, no run): results/diagnosis/<key>/points.json of the keys in
``FIT_KEYS`` (the fit) and ``CHECK_KEYS`` (first-prediction joints under other starts, roof
friction, 12 mm and 50 cycles: predicted with the fitted rule, not used to fit it), and
results/diagnosis/e1/summary.json (f_n per candidate and model).  Output:
results/diagnosis/onset-rule.json and onset-rule.png (``python -m studies diagnosis
onset-rule``).
"""

from __future__ import annotations

import math
from pathlib import Path

import numpy as np

from postprocess.verdicts import response_branch
from studies.kit import study as kit
from studies.kit.records import read_json

RESULTS = kit.results_dir("diagnosis")
KINDS = ("relative", "deformation", "absolute")
#: the damping ratios scanned, 0-1 (critical); E1's quiet runs read as a damped mode give
#: 0.13-0.33 per model (median; :func:`damped_table`)
ZETAS = tuple(float(z) for z in np.round(np.arange(0.0, 1.005, 0.01), 2))
#: the definitions drawn in onset-rule.png: E1's measured one and the static-capacity one
PLOTTED = ("relative", "deformation")
#: E1's candidate for the first prediction's own joints (results/diagnosis/e1/summary.json)
BASELINE = "first prediction (kn 5e9, planar 0.1 mm)"
#: the from-rest grids the rule is fitted to: key -> (E1 candidate per variant; None: the
#: variant's own name is E1's candidate)
FIT_KEYS = {"e4": BASELINE, "e5": BASELINE, "e1-model-ii-y": None, "e1-model-i-y": None,
            "e1-model-ii-x": None, "e1-model-iii-y": None, "e1-threshold": None,
            "e1-band": None, "e1-band-model-i-y": None}
#: from-rest runs of the first prediction's joints that the fit does not see
CHECK_KEYS = {"e3": BASELINE, "e6": BASELINE, "corners-model-i-y": BASELINE,
              "corners-model-ii-y": BASELINE, "survival-model-i-y": BASELINE,
              "survival-model-ii-x": BASELINE}
E4_SWEEP = "model-ii-y"


def transmissibility(f, fn, zeta, kind: str = "relative"):
    """The steady amplification of a base-excited linear oscillator (module docstring; Chopra
    3.2, 3.6) at drive frequency ``f`` (Hz) for natural frequency ``fn`` (Hz) and damping ratio
    ``zeta`` (-); arrays broadcast.  ``kind``: relative | deformation | absolute.  At zeta = 0
    the resonance r = 1 is infinite."""
    if kind not in KINDS:
        raise ValueError(f"kind must be one of {KINDS}, not {kind!r}")
    zeta = np.asarray(zeta, float)
    if np.any(zeta < 0):
        raise ValueError(f"zeta must be >= 0, not {zeta}")
    r = np.asarray(f, float) / np.asarray(fn, float)
    with np.errstate(divide="ignore"):
        inv = 1.0 / np.sqrt((1.0 - r ** 2) ** 2 + (2.0 * zeta * r) ** 2)
    if kind == "relative":
        return r ** 2 * inv
    if kind == "deformation":
        return inv
    return np.sqrt(1.0 + (2.0 * zeta * r) ** 2) * inv


def sdof_from_response(amplification: float, phase_deg: float, f: float) -> tuple[float, float]:
    """(f_n in Hz, zeta) of the linear oscillator whose relative-displacement response at ``f``
    has this amplification (> 0) and lag behind the table (0 <= phase < 180 deg).  The complex
    transfer H = r^2 / (1 - r^2 + 2 i zeta r) gives 1 / H = 1 / r^2 - 1 + 2 i zeta / r, so

        r^2 = 1 / (1 + cos(phase) / amplification),   zeta = r sin(phase) / (2 amplification)

    (phase 0: E1's undamped f_n = f sqrt((1 + A) / A))."""
    if not amplification > 0 or not 0.0 <= phase_deg < 180.0:
        raise ValueError("need amplification > 0 and 0 <= phase_deg < 180")
    ph = math.radians(phase_deg)
    denom = 1.0 + math.cos(ph) / amplification
    if denom <= 0:
        raise ValueError("this amplification and phase fit no oscillator below its resonance "
                         "or above it")
    r = math.sqrt(1.0 / denom)
    return f / r, r * math.sin(ph) / (2.0 * amplification)


def best_threshold(scores, rocked) -> dict:
    """The cut a0 on ``scores`` that classifies the most runs by ``score >= a0 <=> rocked``.
    Every cut between two neighbouring distinct scores (and below / above all) is tried; the
    cuts with the best count form an interval (lo, hi] of scores (the first such interval when
    the best count is reached in several places; lo = 0 and hi = inf at the ends).  a0 is its
    geometric middle (its finite end when one end is open).  Returns {a0, lo, hi, correct, n,
    ties} (ties: how many separate intervals reach the best count); the rule at any a0 in
    (lo, hi] classifies the runs alike."""
    s = np.asarray(scores, float)
    y = np.asarray(rocked, bool)
    if s.shape != y.shape or s.ndim != 1 or not s.size:
        raise ValueError("scores and rocked must be equal-length 1-D and not empty")
    if not np.all(np.isfinite(s)) or np.any(s < 0):
        raise ValueError("scores must be finite and >= 0")
    u = np.unique(s)
    cuts = np.concatenate(([0.0], u, [np.inf]))     # a0 = cuts[k]: rock iff s >= cuts[k]
    # correct(k) = rocking runs with s >= cuts[k] + quiet runs with s < cuts[k]
    correct = np.array([np.sum(y & (s >= c)) + np.sum(~y & (s < c)) for c in cuts])
    best = int(correct.max())
    hits = np.flatnonzero(correct == best)
    runs = np.split(hits, np.flatnonzero(np.diff(hits) > 1) + 1)
    first = runs[0]
    # the cuts cuts[first[0]] ... cuts[first[-1]] all score best: a0 anywhere in
    # (the score below cuts[first[0]], cuts[first[-1]]]
    k0, k1 = int(first[0]), int(first[-1])
    lo = float(cuts[k0 - 1]) if k0 >= 1 else 0.0
    hi = float(cuts[k1])
    if 0.0 < lo and np.isfinite(hi):
        a0 = math.sqrt(lo * hi)
    elif np.isfinite(hi):
        a0 = hi                                  # (0, hi]: hi itself is a best cut
    else:
        a0 = float(np.nextafter(lo, np.inf))     # (lo, inf): just above the top score
    return {"a0": a0, "lo": lo, "hi": hi, "correct": best, "n": int(s.size),
            "ties": len(runs)}


def confusion(scores, rocked, a0: float) -> dict:
    """Counts of (observed, predicted) for the rule score >= a0."""
    s = np.asarray(scores, float)
    y = np.asarray(rocked, bool)
    p = s >= a0
    return {"rocking_predicted_rocking": int(np.sum(y & p)),
            "rocking_predicted_quiet": int(np.sum(y & ~p)),
            "quiet_predicted_rocking": int(np.sum(~y & p)),
            "quiet_predicted_quiet": int(np.sum(~y & ~p))}


def fit(f, accel, fn, rocked, zetas=ZETAS, kind: str = "relative") -> dict:
    """Rule (1) fitted to outcomes: per zeta of ``zetas`` the best cut (:func:`best_threshold`)
    of the scores A T(f; f_n, zeta); the zeta with the most correct runs (the smallest such
    zeta when several tie) and the range of zeta that reaches that count.  Arrays: ``f`` (Hz),
    ``accel`` (m/s2), ``fn`` (Hz), ``rocked`` (bool), equal length."""
    f, accel, fn = (np.asarray(x, float) for x in (f, accel, fn))
    per = []
    for z in zetas:
        s = accel * transmissibility(f, fn, z, kind)
        if not np.all(np.isfinite(s)):
            per.append({"zeta": float(z), "correct": None})
            continue
        per.append({"zeta": float(z), **best_threshold(s, rocked)})
    ok = [p for p in per if p["correct"] is not None]
    if not ok:
        raise ValueError("no zeta gives finite scores (a run at its f_n with zeta = 0?)")
    best = max(p["correct"] for p in ok)
    at = [p for p in ok if p["correct"] == best]
    return {"kind": kind, "best": at[0], "zeta_range": [at[0]["zeta"], at[-1]["zeta"]],
            "zetas_at_best": len(at), "per_zeta": per}


# --- the committed records ------------------------------------------------------------------

def _rows(data: dict):
    """(variant or level name, row) of a grid's or E4's points.json."""
    groups = data.get("variants") or data.get("levels") or {}
    for name, rec in groups.items():
        for r in rec.get("rows", []):
            yield name, r


def fn_table(e1_summary: dict) -> dict:
    """{candidate: {sweep: {"median": f_n, "by_seed": {seed: f_n}}}} from E1's summary."""
    out = {}
    for cand, rec in (e1_summary.get("candidates") or {}).items():
        out[cand] = {s: {"median": p.get("median_fn_hz"),
                         "by_seed": {int(k): v for k, v in (p.get("fn_hz_by_seed") or {}).items()}}
                     for s, p in (rec.get("sweeps") or {}).items()}
    return out


def imputed_ratio(fns: dict, sweep: str, ref: str = E4_SWEEP) -> float | None:
    """The median over E1's candidates of f_n(sweep) / f_n(ref), where both were measured: the
    stand-in for a candidate whose ``sweep`` rocked at 2.0 Hz on every seed (no f_n)."""
    vals = [c[sweep]["median"] / c[ref]["median"] for c in fns.values()
            if (c.get(sweep) or {}).get("median") and (c.get(ref) or {}).get("median")]
    return float(np.median(vals)) if vals else None


def outcomes(keys: dict, fns: dict, results: Path = RESULTS) -> list[dict]:
    """One record per finished from-rest run of the grids ``keys`` (key -> E1 candidate or None
    for the variant's own name): where it ran, what it did and the f_n E1 gives its candidate
    and model (``fn_source``: median | imputed; seed-wise f_n beside it)."""
    out = []
    for key, cand_of in keys.items():
        data = kit.records(results / key)
        sweep = data.get("sweep") or (E4_SWEEP if key == "e4" else None)
        for name, r in _rows(data):
            if r.get("run_status") != "ok" or not r.get("amplitude_m"):
                continue
            b = response_branch(r)
            if b["branch"] is None:
                continue
            cand = cand_of or name
            rec = (fns.get(cand) or {}).get(sweep) or {}
            fn, src = rec.get("median"), "median"
            if fn is None:
                ratio = imputed_ratio(fns, sweep)
                ref = ((fns.get(cand) or {}).get(E4_SWEEP) or {}).get("median")
                fn, src = (ratio * ref, "imputed") if ratio and ref else (None, None)
            if fn is None:
                continue
            f = float(r["frequency_hz"])
            out.append({"experiment": key, "variant": name, "candidate": cand, "sweep": sweep,
                        "seed": int(r["seed"]), "frequency_hz": f,
                        "table_acceleration_m_s2": (2 * math.pi * f) ** 2 * r["amplitude_m"],
                        "rocked": b["branch"] == "rocking", "ds": b["ds"],
                        "phase_deg": b["phase_deg"], "fn_hz": fn, "fn_source": src,
                        "fn_seed_hz": (rec.get("by_seed") or {}).get(int(r["seed"])) or fn,
                        "zeta": rec.get("zeta")})
    return out


def e1_quiet_rows(results: Path = RESULTS) -> dict:
    """{(candidate, sweep): [rows]} of E1's 2.0 Hz runs: the e1-model-* grids' rows per
    candidate, and the first prediction's own rows of seeds 0-2 at 2.0 Hz (E1's baseline,
    results/prediction/<sweep>/points.json)."""
    out = {}
    for key in [k for k in FIT_KEYS if k.startswith("e1-model-")]:
        data = kit.records(results / key)
        for name, r in _rows(data):
            out.setdefault((name, data["sweep"]), []).append(r)
    for sweep in sorted({s for _c, s in out}):
        data = kit.records(results.parent / "prediction" / sweep)
        out[(BASELINE, sweep)] = [r for r in data.get("rows", [])
                                  if r.get("run_status") == "ok" and r["seed"] in (0, 1, 2)
                                  and abs(r["frequency_hz"] - 2.0) < 1e-9]
    return out


def damped_table(results: Path = RESULTS) -> dict:
    """E1's quiet 2.0 Hz runs read as a damped mode (:func:`sdof_from_response`: amplification
    and phase give f_n and zeta together): {candidate: {sweep: {"median": f_n, "zeta": zeta,
    "by_seed": {seed: f_n}, "runs": n}}}, medians over the quiet seeds; a (candidate, sweep)
    with no quiet run is left out (``outcomes`` imputes its f_n; its zeta is then the sweep's
    median over the other candidates, :func:`sweep_zeta`)."""
    out = {}
    for (cand, sweep), rows in e1_quiet_rows(results).items():
        got = {}
        for r in rows:
            b = response_branch(r)
            if b["branch"] != "quasi-static":
                continue
            try:
                got[int(r["seed"])] = sdof_from_response(b["ds"], b["phase_deg"],
                                                         r["frequency_hz"])
            except ValueError:
                continue
        if got:
            out.setdefault(cand, {})[sweep] = {
                "median": float(np.median([v[0] for v in got.values()])),
                "zeta": float(np.median([v[1] for v in got.values()])),
                "by_seed": {k: v[0] for k, v in got.items()}, "runs": len(got)}
    return out


def sweep_zeta(table: dict) -> dict:
    """{sweep: {median, min, max, candidates}} of the damped table's zeta over candidates."""
    per = {}
    for c in table.values():
        for sweep, rec in c.items():
            per.setdefault(sweep, []).append(rec["zeta"])
    return {s: {"median": float(np.median(z)), "min": float(min(z)), "max": float(max(z)),
                "candidates": len(z)} for s, z in per.items()}


def _arrays(rows: list[dict], seedwise: bool = False):
    return (np.array([o["frequency_hz"] for o in rows]),
            np.array([o["table_acceleration_m_s2"] for o in rows]),
            np.array([o["fn_seed_hz" if seedwise else "fn_hz"] for o in rows]),
            np.array([o["rocked"] for o in rows]))


def _misses(rows, scores, a0):
    out = []
    for o, s in zip(rows, scores):
        if (s >= a0) != o["rocked"]:
            out.append({k: o[k] for k in ("experiment", "variant", "sweep", "seed",
                                          "frequency_hz", "rocked", "ds", "fn_hz",
                                          "fn_source")}
                       | {"table_acceleration_m_s2": round(o["table_acceleration_m_s2"], 3),
                          "score_over_a0": float(s / a0)})
    return out


def _result(kind, zeta, a0, interval, fit_rows, check_rows, fn_label, seedwise, zetas=None):
    """Confusion, misses and the check runs' prediction of the rule at (zeta, a0); ``zeta`` a
    number, or None for each run's own ``zeta``."""
    def scores(rows):
        f, a, fn, _y = _arrays(rows, seedwise)
        z = zeta if zeta is not None else np.array([o["zeta"] for o in rows])
        return a * transmissibility(f, fn, z, kind)

    s = scores(fit_rows)
    y = np.array([o["rocked"] for o in fit_rows])
    res = {"kind": kind, "fn": fn_label, "zeta": zeta if zeta is not None else "per run (E1)",
           "a0_m_s2": a0, "a0_interval_m_s2": interval, "correct": int(np.sum((s >= a0) == y)),
           "n": len(fit_rows), "confusion": confusion(s, y, a0),
           "missed": _misses(fit_rows, s, a0)}
    if zetas is not None:
        res |= zetas
    sc = scores(check_rows)
    yc = np.array([o["rocked"] for o in check_rows])
    res["check"] = {"n": len(check_rows), "correct": int(np.sum((sc >= a0) == yc)),
                    "confusion": confusion(sc, yc, a0), "missed": _misses(check_rows, sc, a0)}
    return res


def analyse(fit_rows: list[dict], check_rows: list[dict], kind: str, seedwise=False) -> dict:
    """Rule (1) with one T definition fitted over zeta and a0 (:func:`fit`): its confusion
    table, the runs it misses and its prediction of the check runs."""
    fr = fit(*_arrays(fit_rows, seedwise), kind=kind)
    b = fr["best"]
    return _result(kind, b["zeta"], b["a0"], [b["lo"], b["hi"]], fit_rows, check_rows,
                   "E1 per seed (undamped reading)" if seedwise
                   else "E1 median over seeds (undamped reading)", seedwise,
                   {"zeta_range_at_best": fr["zeta_range"],
                    "correct_by_zeta": {p["zeta"]: p["correct"] for p in fr["per_zeta"]}})


def analyse_damped(fit_rows: list[dict], check_rows: list[dict], kind: str) -> dict:
    """Rule (1) with f_n and zeta both read from E1's runs as a damped mode (each run's own
    ``zeta``): only a0 is fitted."""
    f, a, fn, y = _arrays(fit_rows)
    z = np.array([o["zeta"] for o in fit_rows])
    b = best_threshold(a * transmissibility(f, fn, z, kind), y)
    return _result(kind, None, b["a0"], [b["lo"], b["hi"]], fit_rows, check_rows,
                   "E1 read as a damped mode (median f_n and zeta over quiet seeds)", False)


def plot(fit_rows: list[dict], check_rows: list[dict], results: list[dict], path: Path) -> None:
    """One column per fitted definition of T.  Top: A / a0 against f for the (model, f_n) groups
    run at more than one frequency (E4, E5, the band runs, the 12 mm check), with each group's
    boundary 1 / T(f): a run on or above its own line is predicted to rock.  Bottom: every run's
    score A T / a0 (rocking predicted at >= 1).  Filled: rocking, open: quiet; squares: the
    check runs (not fitted); seeds offset by 0.03 Hz."""
    from dem.output.plotting import agg_pyplot

    plt = agg_pyplot()
    fig, axes = plt.subplots(2, len(results), figsize=(6.0 * len(results) + 2.4, 9.0),
                             squeeze=False)
    rows = [(o, "o") for o in fit_rows] + [(o, "s") for o in check_rows]
    key = lambda o: (o["sweep"], round(o["fn_hz"], 2))   # noqa: E731
    freqs = {}
    for o, _m in rows:
        freqs.setdefault(key(o), set()).add(round(o["frequency_hz"], 3))
    swept = sorted(g for g, fs in freqs.items() if len(fs) > 1)
    cmap = plt.get_cmap("tab10")
    color = {g: cmap(i % 10) for i, g in enumerate(swept)}
    model_color = {"model-ii-y": "C0", "model-i-y": "C1", "model-ii-x": "C2",
                   "model-iii-y": "C3"}
    ff = np.linspace(1.6, 4.6, 200)
    for j, result in enumerate(results):
        kind, z, a0 = result["kind"], result["zeta"], result["a0_m_s2"]
        top, bottom = axes[0][j], axes[1][j]
        for g in swept:
            top.plot(ff, 1.0 / transmissibility(ff, g[1], z, kind), "-", lw=1.0,
                     color=color[g], label=f"{g[0]}, f_n {g[1]:.2f} Hz")
        for o, m in rows:
            x = o["frequency_hz"] + 0.03 * (o["seed"] - 1)
            if key(o) in color:
                c = color[key(o)]
                top.plot(x, o["table_acceleration_m_s2"] / a0, m, ms=5, color=c,
                         mfc=c if o["rocked"] else "none")
            c = model_color.get(o["sweep"], "k")
            score = o["table_acceleration_m_s2"] * transmissibility(
                o["frequency_hz"], o["fn_hz"], z, kind) / a0
            bottom.plot(x, score, m, ms=5, color=c, mfc=c if o["rocked"] else "none")
        bottom.axhline(1.0, color="k", lw=0.8)
        ys = [o["table_acceleration_m_s2"] / a0 for o, _m in rows if key(o) in color]
        top.set_ylim(min(ys) / 1.6, max(ys) * 1.6)
        top.set_yscale("log")
        bottom.set_yscale("log")
        for ax in (top, bottom):
            ax.set_xlim(1.6, 4.0)
            ax.set_xlabel("drive frequency f (Hz)")
        top.set_ylabel("A / a0")
        bottom.set_ylabel("A T(f) / a0")
        top.set_title(f"T {kind}, zeta {z:g}, a0 {a0:.3g} m/s2: {result['correct']} of "
                      f"{result['n']} fitted runs, {result['check']['correct']} of "
                      f"{result['check']['n']} check runs right", fontsize=8)
    axes[0][-1].legend(fontsize=6, loc="center left", bbox_to_anchor=(1.0, 0.5))
    for s_, c in model_color.items():
        axes[1][-1].plot([], [], "o", color=c, label=s_)
    axes[1][-1].plot([], [], "ko", label="rocking (filled)")
    axes[1][-1].plot([], [], "ko", mfc="none", label="quiet (open)")
    axes[1][-1].plot([], [], "ks", mfc="none", label="check run (not fitted)")
    axes[1][-1].legend(fontsize=6, loc="center left", bbox_to_anchor=(1.0, 0.5))
    fig.suptitle("onset rule A T(f) >= a0 on the diagnosis' from-rest runs (top: runs swept in "
                 "f, lines 1 / T(f); bottom: every run's score, line at 1)", fontsize=9)
    fig.tight_layout()
    fig.savefig(path, dpi=100)
    plt.close(fig)


def report(results: Path = RESULTS, log=print) -> dict:
    """onset-rule.json and onset-rule.png from the committed records."""
    from dem.output.atomic import write_json

    fns = fn_table(read_json(results / "e1" / "summary.json") or {})
    fit_rows = outcomes(FIT_KEYS, fns, results)
    check_rows = outcomes(CHECK_KEYS, fns, results)
    fits = {k: analyse(fit_rows, check_rows, k) for k in KINDS}
    seedwise = analyse(fit_rows, check_rows, "relative", seedwise=True)
    _f, a, _fn, y = _arrays(fit_rows)
    alone = best_threshold(a, y)
    reference = {"never rocks": {"correct": int(np.sum(~y)), "n": int(y.size)},
                 "A >= a0 alone (T = 1)": {"a0_m_s2": alone["a0"], "correct": alone["correct"],
                                           "n": alone["n"]}}
    damped = damped_table(results)
    zeta_of = sweep_zeta(damped)
    d_fit, d_check = (outcomes(k, damped, results) for k in (FIT_KEYS, CHECK_KEYS))
    for o in d_fit + d_check:
        if o["zeta"] is None:
            o["zeta"] = zeta_of[o["sweep"]]["median"]
    damped_fits = {k: analyse_damped(d_fit, d_check, k) for k in KINDS}
    out = {"rule": "rocking from rest iff A T(f; f_n, zeta) >= a0",
           "definitions": {"relative": "r^2 / sqrt((1 - r^2)^2 + (2 zeta r)^2): ds relative "
                                       "to the table over the table's, E1's measured quantity",
                           "deformation": "1 / sqrt((1 - r^2)^2 + (2 zeta r)^2): "
                                          "pseudo-acceleration over A",
                           "absolute": "absolute acceleration of the mode over A"},
           "fn_source": "results/diagnosis/e1/summary.json (median over seeds 0-2 of the "
                        "candidate on the model; 'imputed': Model III y rocked at 2.0 Hz on "
                        "every seed, f_n = II y's x the median III y / II y ratio of the "
                        "other candidates)",
           "imputed_ratio_iii_over_ii": imputed_ratio(fns, "model-iii-y"),
           "fit_experiments": list(FIT_KEYS), "check_experiments": list(CHECK_KEYS),
           "runs": {"fit": len(fit_rows), "fit_rocking": sum(o["rocked"] for o in fit_rows),
                    "fit_imputed_fn": sum(o["fn_source"] == "imputed" for o in fit_rows),
                    "check": len(check_rows),
                    "check_rocking": sum(o["rocked"] for o in check_rows)},
           "e1_as_damped_mode": {"zeta_by_model": zeta_of,
                                 "table": damped, "fits": damped_fits},
           "reference_rules": reference,
           "fits": fits, "relative_with_seedwise_fn": seedwise,
           "outcomes": fit_rows, "check_outcomes": check_rows,
           "command": "python -m studies diagnosis onset-rule"}
    write_json(results / "onset-rule.json", out, indent=1)
    plot(fit_rows, check_rows, [fits[k] for k in PLOTTED], results / "onset-rule.png")
    for k, r in damped_fits.items():
        log(f"onset rule, T {k}, f_n and zeta from E1 as a damped mode: a0 "
            f"{r['a0_m_s2']:.3g} m/s2: {r['correct']} of {r['n']} correct, check "
            f"{r['check']['correct']} of {r['check']['n']}")
    for k, r in list(fits.items()) + [("relative, f_n per seed", seedwise)]:
        log(f"onset rule, T {k}: zeta {r['zeta']:g} (best over {r['zeta_range_at_best']}), "
            f"a0 {r['a0_m_s2']:.3g} m/s2 ({r['a0_interval_m_s2'][0]:.3g}-"
            f"{r['a0_interval_m_s2'][1]:.3g}): {r['correct']} of {r['n']} correct, "
            f"check {r['check']['correct']} of {r['check']['n']}")
    return out
