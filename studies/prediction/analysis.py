"""The numbers of one sweep from its points.json: survival, amplification curves and bands,
characteristic frequency (postprocess.verdicts), inside / outside the thesis' range, excited
portion, the rocking check (postprocess.verdicts.is_rocking).
"""

from __future__ import annotations

import numpy as np

from postprocess.ensemble import statistics
from postprocess.shake_signals import LOWPASS_SENSITIVITY_HZ
from postprocess.verdicts import characteristic, finite, is_rocking
from studies.prediction.points import sweep_finished
from studies.prediction.protocol import FRONT_BACK, LEFT_OUT, ROW_QUANTITIES, THESIS


# ---- analysis of one sweep ----------------------------------------------------------------------
def survived(row: dict) -> bool | None:
    """True: the run finished, was analysed and its standing check passed (postprocess.shake: the
    centre moved less than its thickness relative to the table); False: collapse suspected, the
    check missing, or the analysis failed (counted against survival: a run that cannot be
    analysed is not a standing model); None: not run / run failed (pending)."""
    if row.get("run_status") != "ok":
        return None
    if row.get("analysis_status") != "ok":
        return False
    # None: an analysis without the standing check (older sweep.json): not confirmed standing
    return row.get("collapse_suspected") is False


def per_seed_mean(rows, seeds, freqs_in, key) -> list:
    """Per seed, the mean of ``key(row)`` over its surviving rows at the frequencies freqs_in;
    None for a seed with one of those frequencies not yet finished (pending or failed run: an
    unfinished sweep's seed does not enter the statistics with a part of the range).  Rows a
    cycles check left out (LEFT_OUT: no raw run here) are skipped, on both of its sides alike."""
    out = []
    for s in seeds:
        mine = [r for r in rows if r["seed"] == s and r["frequency_hz"] in freqs_in]
        if len(mine) < len(freqs_in) or any(survived(r) is None and
                                            r.get("run_status") != LEFT_OUT for r in mine):
            out.append(None)
            continue
        v = [key(r) for r in mine if survived(r)]
        v = [x for x in v if finite(x)]
        out.append(float(np.mean(v)) if v else None)
    return out


def amp_of(q: str):
    """Row -> its amplification of quantity q (None where absent)."""
    return lambda r: (r.get("amplification") or {}).get(q)


def ratio_of(front: str, back: str):
    """Row -> amplification of ``front`` over that of ``back`` (None unless both are finite and
    the back one > 0)."""
    def key(r):
        a = r.get("amplification") or {}
        f, b = a.get(front), a.get(back)
        return f / b if finite(f) and finite(b) and b > 0 else None
    return key


def acceleration_inside(rows, seeds, freqs_in) -> dict:
    """The centre accelerometer's amplification inside (per-seed means over the surviving rows
    at the frequencies ``freqs_in`` (Hz), then median and 10-90 % over the seeds): unfiltered
    ``a``, ``a_lp`` (the assumed instrument low-pass at LOWPASS_HZ) and ``cutoff_sensitivity``
    ("raw" and one key per LOWPASS_SENSITIVITY_HZ cutoff, Hz, from the rows' ``a_lowpass``).
    Not a criterion: the thesis gives no filter, and the answer depends on the cutoff."""
    def low(k):
        return lambda r: (r.get("a_lowpass") or {}).get(k)

    keys = ["raw"] + [f"{c:g}" for c in LOWPASS_SENSITIVITY_HZ]
    return {"a": statistics(per_seed_mean(rows, seeds, freqs_in, amp_of("a"))),
            "a_lp": statistics(per_seed_mean(rows, seeds, freqs_in, amp_of("a_lp"))),
            "cutoff_sensitivity": {k: statistics(per_seed_mean(rows, seeds, freqs_in, low(k)))
                                   for k in keys}}


def front_back_inside(rows, seeds, freqs_in) -> dict:
    """Per ratio of FRONT_BACK ("da": da_front / da, "a_lp": a_front_lp / a_lp): the front and
    back amplifications and their ratio (per row, then per-seed means over the surviving rows
    at ``freqs_in`` (Hz), then median and 10-90 % over the seeds)."""
    return {label: {"front": statistics(per_seed_mean(rows, seeds, freqs_in, amp_of(fr))),
                    "back": statistics(per_seed_mean(rows, seeds, freqs_in, amp_of(bk))),
                    "ratio": statistics(per_seed_mean(rows, seeds, freqs_in, ratio_of(fr, bk)))}
            for label, (fr, bk) in FRONT_BACK.items()}


def analyse_sweep(name: str, data: dict | None) -> dict:
    """The numbers of one sweep (module docstring) from its points.json; {"status": "pending"}
    without one."""
    if not data or "prediction" not in data:
        return {"status": "pending", "sweep": name}
    pred, rows = data["prediction"], data.get("rows") or []
    seeds, freqs = pred["seeds"], pred["frequencies_hz"]
    thesis = THESIS.get(name, {})
    out = {"sweep": name, "status": "finished" if sweep_finished(data) else "pending",
           "n_rows": len(rows), "n_run": sum(1 for r in rows if r.get("run_status") == "ok"),
           "n_expected": len(seeds) * len(freqs), "seeds": seeds, "frequencies_hz": freqs,
           "cycles": pred["cycles"], "max_steps": pred["max_steps"],
           "smoke": pred["max_steps"] is not None, "cpu_seconds": pred.get("cpu_seconds"),
           "code": pred.get("source"), "friction": pred.get("friction"),
           "peak_acceleration_m_s2": pred.get("peak_acceleration_m_s2"),
           "frozen_commit": (pred.get("frozen") or {}).get("commit")}
    # survival per frequency
    surv = {}
    for f in freqs:
        s = [survived(r) for r in rows if r["frequency_hz"] == f]
        known = [x for x in s if x is not None]
        surv[f"{f:g}"] = {"n": len(known), "survived": int(sum(known)),
                          "rate": (sum(known) / len(known)) if known else None}
    rates = [v["rate"] for v in surv.values() if v["rate"] is not None]
    out["survival"] = {"per_frequency": surv, "min_rate": min(rates) if rates else None,
                       "overall_rate": (sum(v["survived"] for v in surv.values())
                                        / max(1, sum(v["n"] for v in surv.values())))
                       if rates else None}
    # amplification curves: median and band over the surviving realisations
    curves = {}
    for q in ROW_QUANTITIES:
        curves[q] = {f"{f:g}": statistics((r.get("amplification") or {}).get(q) for r in rows
                                          if r["frequency_hz"] == f and survived(r))
                     for f in freqs}
    out["amplification_curves"] = curves
    # front / back ratio per frequency (the thesis: constant over frequency)
    out["front_back_curves"] = {
        label: {f"{f:g}": statistics(ratio_of(fr, bk)(r) for r in rows
                                     if r["frequency_hz"] == f and survived(r)) for f in freqs}
        for label, (fr, bk) in FRONT_BACK.items()}
    med = {f: curves["ds"][f"{f:g}"]["median"] for f in freqs}
    unrun = [f for f in freqs if not any(r["frequency_hz"] == f and r.get("run_status") == "ok"
                                         for r in rows)]
    er = characteristic(freqs, med, unrun)
    out["characteristic_frequency_hz"] = er.get("characteristic_frequency_hz")
    out["characteristic_frequency_note"] = er.get("characteristic_frequency_note")
    out["peak_at_edge"] = bool(er.get("peak_at_edge"))
    out["effective_range_hz"] = er.get("effective_range_hz")
    out["effective_range_rule"] = er.get("rule")
    # per-seed characteristic frequencies (the band)
    fcs = []
    for s in seeds:
        c = {r["frequency_hz"]: (r.get("amplification") or {}).get("ds") for r in rows
             if r["seed"] == s and survived(r)}
        fcs.append(characteristic(freqs, c).get("characteristic_frequency_hz"))
    out["characteristic_frequency_per_seed_hz"] = fcs
    out["characteristic_frequency_band"] = statistics(fcs)
    out["realisations_without_characteristic_frequency"] = sum(1 for x in fcs if x is None)
    # inside / outside: the thesis' range (the same frequencies as the tests, as the criteria
    # compare),
    # and the DEM's own effective range where it found one
    def split(rng):
        if not rng:
            return None, None
        ins = [f for f in freqs if rng[0] - 1e-9 <= f <= rng[1] + 1e-9]
        return ins, [f for f in freqs if f not in ins]

    ranges = {"thesis_range": thesis.get("range") or ([thesis["fc"]] * 2 if thesis.get("fc")
                                                       else None),
              "dem_range": out["effective_range_hz"]}
    out["inside_outside"] = {}
    for label, rng in ranges.items():
        ins, outs = split(rng)
        if not ins:
            out["inside_outside"][label] = {"range_hz": rng, "note": "no range"}
            continue
        a_in = per_seed_mean(rows, seeds, ins, lambda r: (r.get("amplification") or {})
                              .get("ds"))
        a_out = per_seed_mean(rows, seeds, outs, lambda r: (r.get("amplification") or {})
                               .get("ds"))
        ratio = [i / o if finite(i) and finite(o) and o > 0 else None
                 for i, o in zip(a_in, a_out)]
        lag_in = per_seed_mean(rows, seeds, ins, lambda r: (r.get("lag_s") or {}).get("ds"))
        lag_out = per_seed_mean(rows, seeds, outs, lambda r: (r.get("lag_s") or {}).get("ds"))
        out["inside_outside"][label] = {
            "range_hz": rng, "inside_hz": ins, "outside_hz": outs,
            "amplification_ds_inside": statistics(a_in),
            "amplification_ds_outside": statistics(a_out),
            "ratio_inside_outside": statistics(ratio),
            "lag_ds_inside_s": statistics(lag_in), "lag_ds_outside_s": statistics(lag_out),
            "acceleration_inside": acceleration_inside(rows, seeds, ins),
            "front_back_inside": front_back_inside(rows, seeds, ins)}
    # excited portion at the thesis' characteristic frequency (else the DEM's)
    f_exc = thesis.get("fc") or out["characteristic_frequency_hz"]
    ex_rows = [r for r in rows if f_exc is not None and abs(r["frequency_hz"] - f_exc) < 1e-9
               and survived(r)]
    out["excited_at_hz"] = f_exc
    out["excited_bricks"] = statistics((r.get("excited") or {}).get("n_excited")
                                       for r in ex_rows)
    out["excited_courses"] = statistics((r.get("excited") or {}).get("excited_courses_from_top")
                                        for r in ex_rows)
    for part in ("upper", "lower"):
        out[f"excited_{part}"] = statistics((r.get("excited") or {}).get(f"n_{part}")
                                            for r in ex_rows)
    # rocking, not drift (step 5), at the frequencies inside the thesis' / DEM's range
    chk = [{"seed": r["seed"], "frequency_hz": r["frequency_hz"], **is_rocking(r)}
           for r in rows if survived(r)]
    out["rocking_rows"] = {"n": len([c for c in chk if c["rocking"] is not None]),
                           "rocking": sum(1 for c in chk if c["rocking"]),
                           "not_rocking": [c for c in chk if c["rocking"] is False][:20]}
    return out


