"""E7: were the thesis' targets measured in another frame?

Hypothesis: the thesis' acceleration amplifications (a ~2 inside Model II y's effective range,
< 0.5 outside, thesis line 1017; ds = da at 1.9 Hz, line 1059) are relative to the table, and the
first prediction compared them with absolute ones (a of a body the table carries reads 1).  If so,
reading the DEM in the thesis' frame should move it towards the thesis.

The relative acceleration of a response is the second derivative of its displacement relative
to the table, so for a response at the excitation frequency f (every prediction run: single FFT
peak at f, results/prediction/FINDINGS.md) its amplification equals the first-harmonic amplitude
ratio of ds:

    a_rel(t) = d2/dt2 [D sin(w t - phi)] = -w^2 D sin(w t - phi),  a_table = -w^2 A sin(w t)
    => |a_rel| / |a_table| = D / A = h1_ds                                            (exact)

(higher harmonics of ds, from impacts, weigh n^2 in a_rel and raise its peak-to-peak: h1_ds is
the first-harmonic estimate, a lower bound of the peak-to-peak ratio.)  So the first prediction's
committed rows (results/prediction/<sweep>/points.json, field h1_ds) already hold the relative
acceleration amplification of every one of its 400 runs: no rerun needed.  The runs analysed
with today's shake analysis also record a_rel directly (postprocess/shake.py: relative_to_table);
results/shake's sweeps with perfect joints were compared by ``python -m studies diagnosis relative
results/shake`` (docs/table_protocols.md).

Output: results/diagnosis/e7/summary.json and the table in results/diagnosis/README.md.
"""

from __future__ import annotations

import numpy as np

from studies.kit import study as kit

PREDICTION = kit.results_dir("prediction")
OUT = kit.results_dir("diagnosis", "e7")
#: thesis (REFERENCE.md, Chapter 4 results): effective range and the amplification of a inside /
#: outside it, where the thesis gives them
THESIS = {"model-ii-y": {"range_hz": (2.4, 3.2), "inside": 2.0, "outside_max": 0.5},
          "model-ii-x": {"range_hz": (2.4, 2.8), "inside": None, "outside_max": None},
          "model-i-y": {"range_hz": (1.8, 2.5), "inside": None, "outside_max": None},
          "model-i-x": {"range_hz": None, "inside": None, "outside_max": None},
          "model-iii-y": {"range_hz": (2.4, 2.5), "inside": 3.5, "outside_max": 2.0}}


def sweep_table(name: str) -> list[dict]:
    """Per frequency of one prediction sweep: runs, median (10-90 %) h1_ds (= relative a,
    first harmonic), median absolute a amplification through the assumed 20 Hz low-pass."""
    rows = [r for r in kit.records(PREDICTION / name).get("rows", [])
            if r.get("analysis_status") == "ok"]
    out = []
    for f in sorted({r["frequency_hz"] for r in rows}):
        at = [r for r in rows if r["frequency_hz"] == f]
        h1 = np.array([r["h1_ds"] for r in at if r.get("h1_ds") is not None], float)
        a = np.array([(r.get("amplification") or {}).get("a_lp") for r in at
                      if (r.get("amplification") or {}).get("a_lp") is not None], float)
        out.append({"frequency_hz": f, "runs": len(at),
                    "a_rel_h1": float(np.median(h1)) if h1.size else None,
                    "a_rel_h1_q10": float(np.quantile(h1, 0.1)) if h1.size else None,
                    "a_rel_h1_q90": float(np.quantile(h1, 0.9)) if h1.size else None,
                    "a_abs_lp": float(np.median(a)) if a.size else None})
    return out


def report(log=print) -> dict:
    from dem.output.atomic import write_json

    summary = {"experiment": "E7",
               "hypothesis": "the thesis' accelerations are relative to the table",
               "method": "relative a amplification = first-harmonic ratio of ds (exact for a "
                         "response at f); the first prediction's committed rows",
               "sweeps": {}}
    for name, th in THESIS.items():
        table = sweep_table(name)
        if not table:
            continue
        rng = th["range_hz"]
        inside = [t["a_rel_h1"] for t in table if rng and rng[0] - 1e-9 <= t["frequency_hz"]
                  <= rng[1] + 1e-9]
        summary["sweeps"][name] = {
            "thesis": th, "points": table,
            "a_rel_inside_max": max(inside) if inside else None,
            "a_rel_all_max": max(t["a_rel_h1"] for t in table if t["a_rel_h1"] is not None)}
        s = summary["sweeps"][name]
        log(f"E7 {name}: relative a (first harmonic) "
            f"{min(t['a_rel_h1'] for t in table):.3f}-{s['a_rel_all_max']:.3f} over the sweep"
            + (f", at most {s['a_rel_inside_max']:.3f} inside the thesis' range "
               f"(thesis ~{th['inside']:g})" if th["inside"] and inside else ""))
    OUT.mkdir(parents=True, exist_ok=True)
    write_json(OUT / "summary.json", summary, indent=1)
    return summary
