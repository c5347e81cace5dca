"""Verdicts on an analysed run or ensemble, one implementation each (so that a study and a
command cannot judge the same numbers differently), for the studies, ``dem sweep`` and ``dem ensemble`` alike.

* **Ensemble bands.**  The statistics of a quantity over the realisations are
  postprocess.ensemble.statistics (n, median, 10 % and 90 % quantiles); :func:`band_text` writes
  one as ``median (q10 - q90)`` and :func:`band_verdict` judges it against a reference value:
  pass when the median lies within the tolerance of the reference (``tol_abs``:
  |median - ref| <= tol_abs; ``factor``: ref / factor <= median <= ref x factor) AND the
  reference lies inside the band [q10, q90]; both are needed, so that a close median from a
  scatter that does not contain the reference does not pass.
* **Characteristic frequency with its edge rules** (:func:`characteristic`): the peak of an
  amplification curve {f (Hz): amplification (-)} by postprocess.sweep.effective_range (thesis
  Section 4.3: the frequency of the peak amplification; interior, at least three points, clear
  of the median); a peak at the lowest or highest frequency of the sweep is no characteristic
  frequency ("no resonance found in the range", ``peak_at_edge``), and a peak at the last
  finished frequency before frequencies still to run is "pending", not an edge.
* **Is the response rocking?** (:func:`is_rocking`): a top displacement amplification ds (-) is
  rocking, not drift or a sliding ratchet, when (1) ds oscillates at the excitation frequency f:
  its dominant frequency is f within DOMINANT_REL_TOL and its first harmonic's amplitude ratio
  A1 >= H1_SHARE_MIN x ds; (2) the accelerometer sees it: the amplification of the absolute
  displacement da equals that of table + ds, |1 + A1 exp(-i 2 pi f lag)| (:func:`da_expected`,
  lag (s) of ds behind the table), within max(DA_REL_TOL x expected, DA_ABS_TOL); (3) the
  facade's centre moves relative to its corners: dsr >= DSR_SHARE_MIN x ds.  The thresholds are
  this harness' choices (the thesis gives none), not thesis values.

Survival (standing / local collapse / collapse) is postprocess.survival's.
"""

from __future__ import annotations

import math

import numpy as np

from postprocess.sweep import effective_range

# rocking, not drift or a sliding ratchet (the harness' thresholds):
H1_SHARE_MIN = 0.5    # the first harmonic at f carries >= half of the ds peak-to-peak
DA_REL_TOL = 0.25     # da agrees with the table + ds phasor sum within 25 % (or DA_ABS_TOL)
DA_ABS_TOL = 0.1
DSR_SHARE_MIN = 0.2   # the facade centre moves relative to its corners (a rigid slide reads 0)
DOMINANT_REL_TOL = 0.05  # the dominant frequency of ds is f within 5 %
#: comparisons of a median or quantile with a reference allow this much rounding (-, Hz or s)
COMPARE_SLACK = 1e-12


def fmt(x, spec=".3g"):
    return format(x, spec) if finite(x) else "-"


def band_text(st: dict | None, spec=".3g") -> str:
    if not st or not st.get("n"):
        return "-"
    return f"{fmt(st['median'], spec)} ({fmt(st['q10'], spec)} - {fmt(st['q90'], spec)})"


def finite(x) -> bool:
    return isinstance(x, (int, float)) and not isinstance(x, bool) and math.isfinite(x)


def band_verdict(stats: dict | None, thesis: float | None, tol_abs: float | None = None,
                 factor: float | None = None) -> dict:
    """pass / fail / pending of a numeric criterion judged two ways: the median within the
    tolerance of the thesis value (``tol_abs``: |median - thesis| <= tol_abs; ``factor``:
    thesis / factor <= median <= thesis x factor) AND the thesis value inside the 10-90 % band
    [q10, q90] of the realisations.  pending without data."""
    if thesis is None:
        return {"status": "n/a", "why": "no thesis value"}
    if not stats or not stats.get("n"):
        return {"status": "pending", "why": "no realisation finished"}
    med, q10, q90 = stats["median"], stats["q10"], stats["q90"]
    if tol_abs is not None:
        by_median = abs(med - thesis) <= tol_abs + COMPARE_SLACK
        tol = f"+-{tol_abs:g}"
    else:
        by_median = thesis / factor - COMPARE_SLACK <= med <= thesis * factor + COMPARE_SLACK
        tol = f"x/{factor:g}"
    in_band = q10 - COMPARE_SLACK <= thesis <= q90 + COMPARE_SLACK
    ok = by_median and in_band
    return {"status": "pass" if ok else "fail", "by_median": by_median, "in_band": in_band,
            "thesis_value": thesis, "median": med, "band": [q10, q90], "tolerance": tol,
            "why": f"median {med:.3g}, 10-90 % [{q10:.3g}, {q90:.3g}]: " + (
                "both agree with the thesis" if ok else "; ".join(
                w for w, bad in ((f"median {med:.3g} outside thesis {thesis:g} {tol}",
                                  not by_median),
                                 (f"thesis {thesis:g} outside the 10-90 % band "
                                  f"[{q10:.3g}, {q90:.3g}]", not in_band)) if bad))}


def characteristic(freqs, curve: dict, unrun=()) -> dict:
    """Characteristic frequency and effective range of an amplification curve {f: amplification}
    by postprocess.sweep.effective_range; at an edge of the sweep the frequency is null with the
    reason "peak at the edge of the sweep: no resonance found in the range".  ``unrun``: the
    frequencies of the sweep with no finished run yet; a peak at the last finished frequency
    before them is not at the edge of the sweep, and reads "pending" instead."""
    fs = [f for f in freqs if finite(curve.get(f))]
    er = effective_range(fs, [curve[f] for f in fs])
    if not fs:
        er["characteristic_frequency_note"] = "no surviving realisation with an analysed response"
    if er.get("characteristic_frequency_hz") is None and fs:
        k = int(np.argmax([curve[f] for f in fs]))
        beyond = [f for f in unrun if (f < fs[k] if k == 0 else f > fs[k])]
        if len(fs) >= 3 and k in (0, len(fs) - 1) and beyond:
            er["characteristic_frequency_note"] = (
                f"pending: the peak so far is at {fs[k]:g} Hz, and {len(beyond)} frequencies "
                f"beyond it have not run")
        elif len(fs) >= 3 and k in (0, len(fs) - 1):
            er["characteristic_frequency_note"] = (
                f"peak at the edge of the sweep ({fs[k]:g} Hz, the "
                f"{'lowest' if k == 0 else 'highest'} frequency): no resonance found in the range")
            er["peak_at_edge"] = True
    return er


def da_expected(row: dict) -> float | None:
    """The amplification of the absolute top displacement da that an oscillation of ds at f
    implies: |1 + A1 exp(-i 2 pi f lag)|, A1 the first-harmonic amplitude ratio of ds (relative
    to the table) and lag its lag behind the table (s).  The absolute motion is table + ds, so
    a response lagging by ~150 deg reads da < 1 while it rocks (results/shake, 4.0 m/s2:
    2.8 Hz, A1 1.56, lag 0.146 s: 0.906 expected, 0.910 measured)."""
    h1, lag = row.get("h1_ds"), (row.get("lag_s") or {}).get("ds")
    if not (finite(h1) and finite(lag)):
        return None
    th = 2 * math.pi * row["frequency_hz"] * lag
    return float(abs(1 + h1 * complex(math.cos(th), -math.sin(th))))


def is_rocking(row: dict) -> dict:
    """Step 5: is the row's ds amplification rocking, not drift or a sliding ratchet?  Rocking
    when (1) ds is at the excitation frequency: its dominant frequency is f within
    DOMINANT_REL_TOL and its first harmonic carries >= H1_SHARE_MIN of the peak-to-peak
    amplification (a drift or a ratchet puts its peak-to-peak into a slow or stepwise motion);
    (2) the accelerometer agrees: da (double-integrated absolute acceleration, slow wander
    removed) is the phasor sum :func:`da_expected` within DA_REL_TOL (or DA_ABS_TOL); and
    (3) the centre moves relative to its corners: dsr >= DSR_SHARE_MIN x ds (a rigid slide of
    the whole top reads dsr ~ 0).  Thresholds are this harness' choices, not thesis values.
    Returns {rocking: bool | None, why}."""
    amp = row.get("amplification") or {}
    ds, da, dsr = amp.get("ds"), amp.get("da"), amp.get("dsr")
    if not finite(ds) or ds <= 0:
        return {"rocking": None, "why": "no ds amplification"}
    f, fd, h1 = row["frequency_hz"], row.get("dominant_frequency_hz"), row.get("h1_ds")
    why = []
    if not (finite(fd) and abs(fd - f) <= DOMINANT_REL_TOL * f):
        why.append(f"dominant frequency of ds {fmt(fd)} Hz, not {f:g}")
    if not (finite(h1) and h1 >= H1_SHARE_MIN * ds):
        why.append(f"first harmonic {fmt(h1)} < {H1_SHARE_MIN} x ds amplification {ds:.3g}: "
                   f"drift or ratchet")
    exp = da_expected(row)
    if not (finite(da) and exp is not None
            and abs(da - exp) <= max(DA_REL_TOL * exp, DA_ABS_TOL)):
        why.append(f"da amplification {fmt(da)} against {fmt(exp)} from ds at f: the "
                   f"accelerometer does not see the ds oscillation")
    if not (finite(dsr) and dsr >= DSR_SHARE_MIN * ds):
        why.append(f"dsr amplification {fmt(dsr)} < {DSR_SHARE_MIN} x ds: a rigid slide, "
                   f"not rocking")
    return {"rocking": not why, "why": "; ".join(why) or "rocking"}


# ---- which branch of the response ---------------------------------------------------------------
#: A shaken box model of the DEM answers on one of two branches (results/prediction, FINDINGS):
#: the quasi-static branch moves nearly with the table (ds amplification 0.04-0.35, ds lag phase
#: 7-13 deg) and the rocking branch rocks past resonance (ds 3.3-3.5, phase 127-147 deg).  The
#: split is physical, not fitted: a driven oscillator's phase passes 90 deg at resonance, and an
#: amplification of 1 is a response as large as the input's.  A run meeting one and not the other
#: is "between" (a run caught in its transient, or a third kind of response).
BRANCH_AMPLIFICATION = 1.0   # - (ds peak-to-peak over the table's)
BRANCH_PHASE_DEG = 90.0      # deg (360 f lag of ds behind the table)


def response_branch(row: dict) -> dict:
    """The branch of one analysed shake run: ``rocking`` when its ds amplification >=
    BRANCH_AMPLIFICATION and the phase of ds behind the table 360 f lag_s >= BRANCH_PHASE_DEG,
    ``quasi-static`` when both are below, ``between`` otherwise, None without a ds amplification
    or lag.  ``row``: {frequency_hz, amplification: {ds}, lag_s: {ds}} (a study's point row).
    Returns {branch, ds, phase_deg}."""
    ds = (row.get("amplification") or {}).get("ds")
    lag = (row.get("lag_s") or {}).get("ds")
    f = row.get("frequency_hz")
    if not (finite(ds) and finite(lag) and finite(f)):
        return {"branch": None, "ds": ds if finite(ds) else None, "phase_deg": None}
    phase = 360.0 * f * lag
    big, late = ds >= BRANCH_AMPLIFICATION, phase >= BRANCH_PHASE_DEG
    branch = "rocking" if big and late else ("quasi-static" if not (big or late) else "between")
    return {"branch": branch, "ds": float(ds), "phase_deg": float(phase)}
