"""The invariants and thesis checks of the calibration on the finished points, and a candidate's
score.
"""

from __future__ import annotations

import numpy as np

from studies.calibration.points import point_finished
from studies.calibration.specimens import (FAMIVE, INVARIANT_SLIDING_TOL, MECH_RANK, SEQUENCE_TOL,
                                           THESIS_IN_PLANE_MECHANISM, THESIS_OOP_MECHANISM)


# ---- scoring ------------------------------------------------------------------------------------
def point_summary(data: dict | None) -> dict:
    """The numbers the report shows for one point; {"status": "pending", ...} unless finished,
    with no lambda then."""
    if not data or "calibration" not in data:
        return {"status": "pending", "n_ok": 0, "n_realisations": None}
    cal, agg = data["calibration"], data.get("aggregate") or {}
    out = {"status": "finished" if point_finished(data) else "pending",
           "n_ok": agg.get("n_ok", 0), "n_realisations": cal.get("n_realisations"),
           "n_failed": agg.get("n_failed", 0), "cpu_seconds": cal.get("cpu_seconds"),
           "deterministic": cal.get("deterministic", False), "l_over_h": cal.get("l_over_h"),
           "kind": cal.get("kind"), "friction": cal.get("friction"),
           "smoke": cal.get("max_steps") is not None,
           "commit": (cal.get("source") or {}).get("commit"),
           "dirty": (cal.get("source") or {}).get("dirty")}
    if out["status"] != "finished":
        return out
    lam = (agg.get("statistics") or {}).get("lambda") or {}
    rows = [r for r in data.get("realisations") or [] if r.get("status") == "ok"]
    ex = cal.get("extras") or {}
    otf = [ex.get(r["name"], {}).get("overturning_mass_fraction") for r in rows]
    otf = [x for x in otf if x is not None]
    eng = [ex.get(r["name"], {}).get("engine_seconds") for r in rows]
    eng = [x for x in eng if x is not None]
    mechs = agg.get("mechanisms") or {}
    out.update({
        "lambda_median": lam.get("median"), "lambda_q10": lam.get("q10"),
        "lambda_q90": lam.get("q90"), "n_lambda": lam.get("n", 0),
        "no_collapse": sum(1 for r in rows if r.get("lambda") is None),
        "mechanisms": mechs,
        "modal_mechanism": max(mechs, key=lambda k: (mechs[k], k)) if mechs else None,
        "overturning_fraction_median": float(np.median(otf)) if otf else None,
        # a collapse of one block alone (a lone brick creeping or tipping out of the wall), not
        # a wall mechanism: flagged, still counted in the statistics
        "lone_block": [[r["name"], r.get("lambda")] for r in rows
                       if ex.get(r["name"], {}).get("n_moving") == 1],
        "engine_seconds_per_realisation": float(np.mean(eng)) if eng else None})
    return out


def summary_finished(p: dict | None) -> bool:
    return bool(p) and p.get("status") == "finished"


def check_sliding(points: dict, tol: float = INVARIANT_SLIDING_TOL) -> dict:
    """Invariant: the L/H = 3 in-plane wall slides at lambda = mu within ``tol`` (relative):
    pass when its median lambda is within tol of its friction and its modal mechanism is
    sliding.  ``points``: specimen -> point_summary."""
    cand = [n for n, p in points.items() if p.get("kind") == "in-plane"
            and p.get("l_over_h") is not None and abs(p["l_over_h"] - 3.0) < 0.01]
    if not cand:
        return {"status": "n/a", "why": "no L/H = 3 in-plane specimen"}
    name = cand[0]
    p = points[name]
    if not summary_finished(p):
        return {"status": "pending", "specimen": name}
    mu, med = p["friction"], p.get("lambda_median")
    if med is None:
        return {"status": "fail", "specimen": name, "why": "no collapse"}
    err = med / mu - 1.0
    ok = abs(err) <= tol and p.get("modal_mechanism") == "sliding"
    return {"status": "pass" if ok else "fail", "specimen": name, "mu": mu, "median": med,
            "relative_error": err, "tolerance": tol, "modal_mechanism": p.get("modal_mechanism"),
            "band": [p.get("lambda_q10"), p.get("lambda_q90")]}


def _l5_series(points: dict) -> list[tuple[float, str]]:
    """The in-plane L = 5 series (ip-small-5xN) as (L/H, specimen), L/H descending."""
    out = [(p["l_over_h"], n) for n, p in points.items()
           if n.startswith("ip-small-5x") and p.get("l_over_h") is not None]
    return sorted(out, reverse=True)


def check_sequence(points: dict, tol: float = SEQUENCE_TOL) -> dict:
    """Invariant: along the L = 5 in-plane series, as L/H falls the modal mechanism's rank
    (sliding < mixed < overturning) never falls, the median overturning mass fraction never
    falls by more than ``tol``, the highest L/H slides and the lowest overturns."""
    series = _l5_series(points)
    if len(series) < 2:
        return {"status": "n/a", "why": "fewer than two L = 5 in-plane specimens"}
    pend = [n for _, n in series if not summary_finished(points[n])]
    if pend:
        return {"status": "pending", "waiting_for": pend}
    rows = [{"l_over_h": lh, "specimen": n, "modal": points[n].get("modal_mechanism"),
             "overturning_fraction": points[n].get("overturning_fraction_median")}
            for lh, n in series]
    problems = []
    for a, b in zip(rows, rows[1:]):
        ra, rb = MECH_RANK.get(a["modal"], -1), MECH_RANK.get(b["modal"], -1)
        if rb < ra:
            problems.append(f"L/H {b['l_over_h']}: {b['modal']} after {a['modal']} at "
                            f"L/H {a['l_over_h']}")
        fa, fb = a["overturning_fraction"], b["overturning_fraction"]
        if fa is not None and fb is not None and fb < fa - tol:
            problems.append(f"L/H {b['l_over_h']}: overturning fraction {fb:.2f} < {fa:.2f} "
                            f"at L/H {a['l_over_h']}")
    if rows[0]["modal"] != "sliding":
        problems.append(f"L/H {rows[0]['l_over_h']} does not slide ({rows[0]['modal']})")
    if rows[-1]["modal"] != "overturning":
        problems.append(f"L/H {rows[-1]['l_over_h']} does not overturn ({rows[-1]['modal']})")
    return {"status": "fail" if problems else "pass", "series": rows, "problems": problems}


def check_no_wings_lowest(points: dict) -> dict:
    """Invariant: an out-of-plane wall without wings has the lowest median lambda of the
    out-of-plane specimens; n/a when no such specimen is among them."""
    oop = {n: p for n, p in points.items() if p.get("kind") == "out-of-plane"}
    bare = [n for n in oop if "no-wings" in n]
    if not bare:
        return {"status": "n/a", "why": "no small-brick out-of-plane wall without wings in "
                                        "cases/tilt (only strong-strong facades)"}
    if any(not summary_finished(p) for p in oop.values()):
        return {"status": "pending"}
    med = {n: p.get("lambda_median") for n, p in oop.items()}
    low = max(med[n] for n in bare)
    others = [v for n, v in med.items() if n not in bare]
    ok = all(v is not None and low is not None and low < v for v in others)
    return {"status": "pass" if ok else "fail", "medians": med}


def _expected_in_plane(lh: float, p: dict) -> bool | None:
    """Whether a finished in-plane L = 5 point shows the tests' mechanism at its L/H."""
    m, f = p.get("modal_mechanism"), p.get("overturning_fraction_median")
    key = min(THESIS_IN_PLANE_MECHANISM, key=lambda k: abs(k - lh))
    if abs(key - lh) > 0.02:
        return None
    if key == 3.0:
        return m == "sliding"
    if key == 2.14:
        return m == "sliding" or (m == "mixed" and f is not None and f < 0.5)
    if key == 1.0:
        return m == "mixed"
    if key == 0.75:
        return m == "overturning" or (m == "mixed" and f is not None and f > 0.5)
    return m == "overturning"


def check_in_plane_mechanisms(points: dict) -> dict:
    """Thesis (tests): the mechanism at each L/H of the L = 5 series (THESIS_IN_PLANE_MECHANISM)."""
    rows, status = [], "pass"
    for lh, n in _l5_series(points):
        p = points[n]
        if not summary_finished(p):
            rows.append({"specimen": n, "l_over_h": lh, "status": "pending"})
            status = "pending" if status == "pass" else status
            continue
        ok = _expected_in_plane(lh, p)
        if ok is None:
            continue
        rows.append({"specimen": n, "l_over_h": lh, "modal": p.get("modal_mechanism"),
                     "overturning_fraction": p.get("overturning_fraction_median"),
                     "thesis": THESIS_IN_PLANE_MECHANISM.get(round(lh, 2)),
                     "status": "pass" if ok else "fail"})
        if not ok:
            status = "fail"
    return {"status": status if rows else "n/a", "rows": rows}


def check_stagger_trend(points: dict) -> dict:
    """Thesis (tests, weak): lambda rises with s/h on the 9 x 15 walls (s = 10, 35, 52.5 mm)."""
    names = [n for n in points if n.startswith("ip-small-9x15-s")]
    if len(names) < 2:
        return {"status": "n/a", "why": "fewer than two 9 x 15 walls"}
    names.sort(key=lambda n: float(n.rsplit("-s", 1)[1]))
    if any(not summary_finished(points[n]) for n in names):
        return {"status": "pending"}
    med = [points[n].get("lambda_median") for n in names]
    ok = all(a is not None and b is not None and b > a for a, b in zip(med, med[1:]))
    return {"status": "pass" if ok else "fail", "specimens": names, "medians": med}


def check_oop_mechanisms(points: dict) -> dict:
    """Thesis (tests): strong-strong corners give B2, or G on a long facade."""
    rows, status = [], "n/a"
    for n, p in points.items():
        if p.get("kind") != "out-of-plane":
            continue
        key = next((k for k in THESIS_OOP_MECHANISM if n.endswith(k)), None)
        if key is None:
            continue
        if not summary_finished(p):
            rows.append({"specimen": n, "status": "pending"})
            status = "pending" if status in ("n/a", "pass") else status
            continue
        ok = p.get("modal_mechanism") in THESIS_OOP_MECHANISM[key]
        rows.append({"specimen": n, "modal": p.get("modal_mechanism"),
                     "mechanisms": p.get("mechanisms"),
                     "thesis": "/".join(THESIS_OOP_MECHANISM[key]),
                     "status": "pass" if ok else "fail"})
        status = "fail" if not ok else ("pass" if status == "n/a" else status)
    return {"status": status, "rows": rows}


def famive_comparison(points: dict) -> list[dict]:
    """DEM median against the FaMIVE (limit-analysis MODEL) values of the L = 5 series: the
    relative difference and whether the value lies in the 10-90 % band; shown, not scored."""
    rows = []
    for lh, n in _l5_series(points):
        key = min(FAMIVE, key=lambda k: abs(k - lh))
        if abs(key - lh) > 0.02:
            continue
        p = points[n]
        row = {"specimen": n, "l_over_h": lh, "famive": FAMIVE[key]}
        if summary_finished(p) and p.get("lambda_median") is not None:
            row.update({"median": p["lambda_median"],
                        "relative_difference": p["lambda_median"] / FAMIVE[key] - 1.0,
                        "in_band": None if p.get("deterministic") else
                        p["lambda_q10"] <= FAMIVE[key] <= p["lambda_q90"]})
        else:
            row["status"] = "pending"
        rows.append(row)
    return rows


def score_candidate(points: dict) -> dict:
    """Every check of a candidate's points (specimen -> point_summary).  ``invariants_pass`` is
    True only when every applicable invariant passes, None while one is pending."""
    inv = {"sliding-invariant": check_sliding(points),
           "mechanism-sequence": check_sequence(points),
           "no-wings-lowest": check_no_wings_lowest(points)}
    st = [c["status"] for c in inv.values() if c["status"] != "n/a"]
    overall = False if "fail" in st else (None if "pending" in st else True)
    return {"invariants": inv, "invariants_pass": overall,
            "thesis": {"in-plane-mechanisms": check_in_plane_mechanisms(points),
                       "stagger-trend": check_stagger_trend(points),
                       "oop-mechanisms": check_oop_mechanisms(points)},
            "famive": famive_comparison(points)}


