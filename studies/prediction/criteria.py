"""The success criteria (protocol step 4) and the false-success checks (step 5), each pass / fail /
pending.
"""

from __future__ import annotations

import math

from postprocess.verdicts import band_verdict, DA_REL_TOL, DSR_SHARE_MIN, fmt, H1_SHARE_MIN
from studies.prediction.protocol import (AMP_FACTOR, AMP_RATIO_MIN, COURSES_TOL, DEFAULT_CYCLES,
                                         EXCITATION_CHECK, EXCITED_REL_TOL, FC_TOL_HZ, LAG_TOL_S,
                                         MEASURED_FRICTION, ORDER, SURVIVAL_MIN, THESIS)


# ---- criteria (protocol step 4) and false-success checks (step 5) -----------------------------
def fc_verdict(sw: dict, thesis_fc: float | None) -> dict:
    """Characteristic frequency: the median curve's peak within FC_TOL_HZ of the thesis and the
    thesis value inside the band of the per-seed characteristic frequencies; a null prediction
    (peak at the edge, no clear peak) fails with its reason; fewer than half the seeds with a
    characteristic frequency fails."""
    if sw.get("status") == "pending" and not sw.get("n_run"):
        return {"status": "pending", "why": "not run"}
    if thesis_fc is None:
        return {"status": "n/a", "why": "the thesis gives no characteristic frequency"}
    fc = sw.get("characteristic_frequency_hz")
    if fc is None:
        return {"status": "fail",
                "why": f"no characteristic frequency: {sw.get('characteristic_frequency_note')}"}
    n_null = sw.get("realisations_without_characteristic_frequency", 0)
    if n_null * 2 > len(sw.get("seeds") or []):
        return {"status": "fail", "why": f"{n_null} of {len(sw['seeds'])} realisations have no "
                                         f"characteristic frequency", "median_curve_fc": fc}
    band = dict(sw.get("characteristic_frequency_band") or {})
    band["median"] = fc  # judged on the peak of the median curve
    return band_verdict(band, thesis_fc, tol_abs=FC_TOL_HZ)


def survival_verdict(sw: dict, min_rate: float = SURVIVAL_MIN) -> dict:
    """At least ``min_rate`` of the realisations survive at every frequency."""
    r = (sw.get("survival") or {}).get("min_rate")
    if r is None:
        return {"status": "pending", "why": "no realisation finished"}
    ok = r >= min_rate - 1e-12
    return {"status": "pass" if ok else "fail", "min_rate": r, "threshold": min_rate,
            "why": f"lowest survival over the frequencies {r:.0%} "
                   f"({'>=' if ok else '<'} {min_rate:.0%}) in {fmt(sw.get('cycles'), 'g')} cycles"}


def criteria(summary: dict, chapter3: dict | None = None) -> list[dict]:
    """The success criteria's rows for every sweep in ``summary`` (sweep -> analyse_sweep);
    ``chapter3``: the record of studies.chapter3.check (its check.json) for the last row,
    pending without one."""
    rows = []

    def add(sweep, quantity, thesis_text, v):
        sw = summary.get(sweep) or {}
        if sw.get("status") == "pending" and sw.get("n_run") and v["status"] in ("pass", "fail"):
            # no verdict before a sweep's last run: the partial one is shown as "so far"
            v = {**v, "status": "pending", "so_far": v["status"],
                 "why": f"unfinished ({sw['n_run']} of {sw.get('n_expected')} runs), so far "
                        f"{v['status']}: {v['why']}"}
        rows.append({"sweep": sweep, "quantity": quantity, **v, "thesis": thesis_text})

    for name in ORDER:
        sw, th = summary.get(name) or {"status": "pending"}, THESIS.get(name, {})
        pend = {"status": "pending", "why": "not run"} if sw.get("status") == "pending" and \
            not sw.get("n_run") else None
        if th.get("fc") is not None:
            add(name, "characteristic frequency (Hz)", f"{th['fc']:g} +-{FC_TOL_HZ:g}",
                pend or fc_verdict(sw, th["fc"]))
        elif name == "model-ii-xy":
            fc, edge = sw.get("characteristic_frequency_hz"), sw.get("peak_at_edge")
            v = pend or ({"status": "pass" if edge and sw.get("frequencies_hz") and
                          (sw.get("characteristic_frequency_note") or "").find("highest") >= 0
                          else "fail", "why": f"DEM: {fc if fc is not None else 'none'} "
                          f"({sw.get('characteristic_frequency_note') or ''})"})
            add(name, "response grows up to 3.6 Hz", th.get("fc_note", ""), v)
        io = (sw.get("inside_outside") or {}).get("thesis_range") or {}
        if th.get("amp_in") is not None:
            add(name, "ds amplification inside the thesis range", f"~{th['amp_in']:g} (x/1.5)",
                pend or band_verdict(io.get("amplification_ds_inside"), th["amp_in"],
                                     factor=AMP_FACTOR))
        if name == "model-ii-y":
            st = io.get("ratio_inside_outside")
            if pend or not st or not st.get("n"):
                v = pend or {"status": "pending", "why": "no realisation finished"}
            else:
                ok = st["median"] > AMP_RATIO_MIN and st["q10"] > AMP_RATIO_MIN
                v = {"status": "pass" if ok else "fail", "median": st["median"],
                     "band": [st["q10"], st["q90"]],
                     "why": f"median {st['median']:.3g}, 10 % quantile {st['q10']:.3g} "
                            f"(need > {AMP_RATIO_MIN:g})"}
            add(name, "ds amplification inside / outside", f"~2 / < 0.5: > {AMP_RATIO_MIN:g}", v)
        if th.get("lag_in") is not None:
            add(name, "lag inside the thesis range (s)", f"{th['lag_in']:g} +-{LAG_TOL_S:g}",
                pend or band_verdict(io.get("lag_ds_inside_s"), th["lag_in"], tol_abs=LAG_TOL_S))
        if th.get("excited") is not None:
            add(name, f"excited bricks at {th['fc']:g} Hz", f"{th['excited']} +-20 %",
                pend or band_verdict(sw.get("excited_bricks"), th["excited"],
                                     tol_abs=EXCITED_REL_TOL * th["excited"]))
        if th.get("excited") is not None:
            up, lo = sw.get("excited_upper") or {}, sw.get("excited_lower") or {}
            if pend or not up.get("n"):
                v = pend or {"status": "pending", "why": "no realisation finished"}
            else:
                ok = up["median"] > 0 and lo["median"] > 0
                v = {"status": "pass" if ok else "fail",
                     "why": f"median upper {up['median']:g} + lower {lo['median']:g} bricks"}
            add(name, f"excited portion in two parts at {th['fc']:g} Hz",
                "upper part + stepped lower part", v)
        if th.get("courses") is not None:
            add(name, f"excited courses from the top at {th['fc']:g} Hz", f"{th['courses']} +-1",
                pend or band_verdict(sw.get("excited_courses"), th["courses"],
                                     tol_abs=COURSES_TOL))
        add(name, "survival (no overturning in the cycles)", ">= 80 % at every frequency",
            pend or survival_verdict(sw))
    ii, iii = summary.get("model-ii-y") or {}, summary.get("model-iii-y") or {}
    f2, f3 = ii.get("characteristic_frequency_hz"), iii.get("characteristic_frequency_hz")
    if ii.get("status") == "finished" and iii.get("status") == "finished":
        def fc(x):
            return f"{x:g} Hz" if x is not None else "none (no characteristic frequency)"
        v = {"status": "pass" if (f2 is not None and f3 is not None and f3 < f2) else "fail",
             "why": f"III {fc(f3)}, II {fc(f2)}"}
    else:
        v = {"status": "pending", "why": "needs both sweeps finished"}
    add("model-iii-y vs model-ii-y", "III below II (y)", "2.4 < 2.8", v)
    if chapter3 and chapter3.get("verdict"):
        src = chapter3.get("source") or {}
        v = {**chapter3["verdict"], "why": chapter3["verdict"]["why"] + (
            f"; seeds {chapter3.get('seeds')} re-run at commit {str(src.get('commit'))[:7]}"
            f"{' (dirty tree)' if src.get('dirty') else ''}, engine results revision "
            f"{chapter3.get('engine_results_revision')} (studies.chapter3.check)")}
    else:
        v = {"status": "pending", "why": "not checked yet: python -m studies chapter3-check "
                                         "re-runs the frozen set's tilts on this engine"}
    add("chapter 3", "calibrated tilt results unchanged within 5 %", "results/calibration", v)
    return rows


def false_success_checks(plan: dict | None, summary: dict) -> list[dict]:
    """The false-success checks (protocol step 5) as explicit rows, each pass / fail / pending
    with what was checked."""
    rows = []
    sweeps = (plan or {}).get("sweeps") or {}
    frozen = (plan or {}).get("frozen") or {}
    # 1. one parameter set and one seed list for everything
    per = [(n, (summary.get(n) or {}).get("frozen_commit")) for n in sweeps]
    commits = {c for _, c in per if c}
    seeds = {tuple((summary.get(n) or {}).get("seeds") or ()) for n in sweeps
             if (summary.get(n) or {}).get("seeds")}
    ok = len(commits) <= 1 and commits <= {frozen.get("commit")} and len(seeds) <= 1 and \
        (not seeds or seeds == {tuple(plan["seeds"])})
    rows.append({"check": "no per-model or per-frequency parameters or seeds",
                 "status": ("pass" if ok else "fail") if plan else "pending",
                 "why": f"every sweep ran the frozen set of commit {frozen.get('commit')} "
                        f"({frozen.get('path')}) with seeds {plan['seeds'] if plan else '-'}"
                 if ok else f"sweeps disagree: commits {sorted(commits)}, seeds {sorted(seeds)}"})
    # 2. friction unchanged
    fr = {n: s.get("friction") for n, s in sweeps.items()}
    bad = {n: f for n, f in fr.items() if f != MEASURED_FRICTION}
    rows.append({"check": "friction unchanged (measured 0.81)",
                 "status": ("fail" if bad else "pass") if sweeps else "pending",
                 "why": f"not {MEASURED_FRICTION}: {bad}" if bad else
                 f"every case: friction {MEASURED_FRICTION} (case files, not parameters)"})
    # 3. excitation as in the thesis
    bad = {n: s.get("peak_acceleration_m_s2") for n, s in sweeps.items()
           if n in THESIS and s.get("peak_acceleration_m_s2") != THESIS[n]["peak_acc"]}
    cyc = (plan or {}).get("cycles")
    cuts = {n: s["cut"] for n, s in sweeps.items() if s.get("cut")}
    unjustified = {n: s["cycles"] for n, s in sweeps.items()
                   if "cycles" in s and s["cycles"] != cyc and not s.get("cut")}
    rows.append({"check": EXCITATION_CHECK,
                 "status": ("fail" if bad or cyc != DEFAULT_CYCLES or plan.get("max_steps")
                            or unjustified else "pass") if plan else "pending",
                 "why": "; ".join(filter(None, [
                     f"peak accelerations differ: {bad}" if bad else
                     "peak accelerations 1.53 (y) / 1.71 (x) / 1.08 (diagonal) / 1.23 (III) m/s2",
                     f"{cyc:g} cycles, not {DEFAULT_CYCLES}" if plan and cyc != DEFAULT_CYCLES
                     else None,
                     f"cycles cut without a cycles check: {unjustified}" if unjustified else None,
                     "cut: " + ", ".join(f"{n} {c['cycles']:g} cycles ({c['justified_by']}: "
                                         f"{c['verdict']})" for n, c in cuts.items())
                     if cuts else None,
                     f"runs capped at {plan['max_steps']} steps (smoke)" if plan and
                     plan.get("max_steps") else None]))})
    # 4. an edge peak is not a characteristic frequency
    edge = [n for n in sweeps if (summary.get(n) or {}).get("peak_at_edge")]
    leak = [n for n in edge if (summary.get(n) or {}).get("characteristic_frequency_hz")
            is not None]
    ran = [n for n in sweeps if (summary.get(n) or {}).get("n_run")]
    rows.append({"check": "a peak at the edge of a sweep is not a characteristic frequency",
                 "status": "fail" if leak else ("pass" if ran else "pending"),
                 "why": (f"edge peaks reported as null: {edge}" if edge else
                         "no sweep peaked at an edge") if not leak else f"numbers at {leak}"})
    # 5. rocking, not drift or a sliding ratchet (da, dsr), where an amplification is compared:
    # the DEM's effective range where it found one, else the thesis' (its characteristic
    # frequency alone where the thesis gives no range), else the whole sweep
    bad, scopes, pend = [], [], False
    for n in sweeps:
        sw = summary.get(n) or {}
        if sw.get("status") != "finished":
            pend = True
        rr = sw.get("rocking_rows") or {}
        if not rr.get("n"):
            continue
        rng, where = sw.get("effective_range_hz"), "DEM range"
        if not rng:   # analyse_sweep's thesis range (its fc alone where it gives no range)
            rng = ((sw.get("inside_outside") or {}).get("thesis_range") or {}).get("range_hz")
            where = "thesis range"
        if not rng:
            rng, where = [-math.inf, math.inf], "whole sweep"
        for r in rr.get("not_rocking", []):
            if rng[0] - 1e-9 <= r["frequency_hz"] <= rng[1] + 1e-9:
                bad.append(f"{n} {r['frequency_hz']:g} Hz seed {r['seed']}: {r['why']}")
        scopes.append(f"{n} ({where}; {rr['rocking']} of {rr['n']} runs rock over the sweep)")
    rows.append({"check": "amplification is rocking, not drift or a sliding ratchet (da, dsr)",
                 "status": "fail" if bad else ("pending" if pend or not scopes else "pass"),
                 "why": "; ".join(bad[:5]) if bad else
                 f"every surviving run where the amplification is compared rocks: ds at f (first "
                 f"harmonic >= {H1_SHARE_MIN} of the peak-to-peak), da = table + ds phasor within "
                 f"{DA_REL_TOL:.0%}, dsr >= {DSR_SHARE_MIN} ds; " + ", ".join(scopes)})
    # 6. collapses are not a match
    bad = []
    for n in sweeps:
        sw = summary.get(n) or {}
        rng = sw.get("effective_range_hz")
        for f, v in ((sw.get("survival") or {}).get("per_frequency") or {}).items():
            if rng and rng[0] - 1e-9 <= float(f) <= rng[1] + 1e-9 and v["rate"] is not None \
                    and v["rate"] < SURVIVAL_MIN:
                bad.append(f"{n} {f} Hz: {v['survived']}/{v['n']} survive")
    rows.append({"check": "a match by collapsing facades is not a match",
                 "status": "fail" if bad else ("pending" if pend or not sweeps else "pass"),
                 "why": "; ".join(bad) if bad else
                 "amplifications use surviving realisations only; no frequency of a DEM "
                 f"effective range has survival below {SURVIVAL_MIN:.0%}"})
    return rows


