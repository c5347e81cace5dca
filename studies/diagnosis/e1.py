"""E1: are the joints too stiff at low stress?  The low-branch frequency fingerprint.

Hypothesis: the DEM's box models are stiffer than the laboratory's, and unevenly so between
models; a joint law that is right at 1-7 kPa would move each model's natural frequency to the
thesis' and, with it, the ratios between models.

The fingerprint.  On the quiet (quasi-static) branch a model responds like a linear oscillator
on a moving base (studies/resonance: Chopra, Dynamics of Structures, Section 3.6, zeta ~ 0):
the ds amplification (peak-to-peak displacement relative to the table over the table's) is

    A = r^2 / |1 - r^2|,   r = f / f_n,

so one run at f on the quiet branch (phase of ds behind the table under 90 deg: r < 1) gives
f_n = f sqrt((1 + A) / A); a run lagging by 90 deg or more (above a linear resonance, or on the
rocking branch: the phase cannot tell them apart) gives none, and is counted.  Each candidate runs
Models II y, I y, II x and III y at FREQUENCY = 2.0 Hz (below every thesis f_c), 10 cycles,
seeds 0-2; the fingerprint is the three ratios of the median f_n: I y / II y, II x / II y,
III y / II y, against the thesis' characteristic frequencies 2.0 / 2.8, 2.8 / 2.8, 2.4 / 2.8
(Chapter 4: 0.71, 1.0, 0.86).  A candidate passes if all three lie within RATIO_TOLERANCE of the
thesis' (and, checked separately, Chapter 3's tilt results stay within 5 %).

A uniform change of a linear joint's kn (ks = 0.4 kn follows) scales every model's stiffness
alike, so f_n by sqrt(kn'/kn) and the ratios not at all, if the joints stay closed: the
kn candidates test that scaling (and put f_n where the thesis' f_c is); only a change that acts
unevenly between models (stress-dependent stiffness, joint geometry) can move the ratios.

Candidates (CANDIDATES: a patch of the first prediction's case each; the baseline is the first
prediction's own rows at 2.0 Hz, kn = 5e9 Pa/m, planar 0.1 mm beds): linear kn 1e9 and 2e8
Pa/m; planar beds of 0.2 and 0.3 mm; twisted (bilinear) faces of 0.1 mm; and the stress-dependent
joint: the hyperbolic closure law p = kn0 d / (1 - d/d_max) (docs/engine.md 4.2) with
d_max = 0.05, 0.1, 0.2 mm (the issue's values).  No literature kn0 could be read (docs/engine.md
4.2), so kn0 = 1e8 Pa/m, the project's illustrative value, chosen before any run: its tangent
kt(p) = kn0 (1 + p / (kn0 d_max))^2 is 1.4-5.8e8 (d_max 0.05 mm), 1.2-2.9e8 (0.1 mm) and 1.1-1.8e8
Pa/m (0.2 mm) between the 1 kPa under a top course and the 7 kPa at a base: a joint 4.0, 2.4 and
1.65 x stiffer at the base than at the top, around the kn 2e8 candidate's stiffness.  ks is that
candidate's 8e7 Pa/m (0.4 x 2e8), so the kn 2e8 candidate is the control: the two differ in the
normal law only.  closure_limit 0.8 (the step for kt = 25 kn0 = 2.5e9 Pa/m) with
beyond_closure_limit: tangent (a capped law): the patches that carry a wall on an edge or a
corner close past 0.8 d_max (the pilot, results/diagnosis/e1-pilot) and go on at kt(0.8 d_max),
where the beds (p(0.8 d_max) = 4 kn0 d_max = 20-80 kPa) stay on the hyperbolic law.  A fourth,
added once those three had run seed 0, takes the family to its stress-dependent end: half closed
at 1 kPa (kn0 2e7 Pa/m, d_max 0.05 mm: kt 8e7 at 1 kPa, 1.3e9 at 7 kPa), capped at 0.9 d_max.
"""

from __future__ import annotations

import math
from pathlib import Path

import numpy as np

from dem.output.plotting import agg_pyplot
from postprocess.verdicts import response_branch
from studies.diagnosis.grid import Grid, RESULTS, Variant, baseline_rows, judged
from studies.kit import study as kit
from studies.kit.records import read_json

FREQUENCY = 2.0
SEEDS = (0, 1, 2)
CYCLES = 10.0
RATIO_TOLERANCE = 0.1
THESIS_FC = {"model-ii-y": 2.8, "model-i-y": 2.0, "model-ii-x": 2.8, "model-iii-y": 2.4}
REFERENCE = "model-ii-y"
SWEEPS = tuple(THESIS_FC)

CANDIDATES = (
    Variant("kn-1e9", "linear kn 1e9 Pa/m (ks 0.4 kn)", {"material": {"normal_stiffness": 1e9}}),
    Variant("kn-2e8", "linear kn 2e8 Pa/m (ks 0.4 kn)", {"material": {"normal_stiffness": 2e8}}),
    Variant("planar-0.2", "planar beds, 0.2 mm unevenness",
            {"imperfections": {"bed_unevenness": 0.0002}}),
    Variant("planar-0.3", "planar beds, 0.3 mm unevenness",
            {"imperfections": {"bed_unevenness": 0.0003}}),
    Variant("twisted", "twisted (bilinear) faces, 0.1 mm",
            {"imperfections": {"face_shape": "bilinear"}}),
    *(Variant(f"hyperbolic-{dm:g}", f"hyperbolic joint, kn0 1e8 Pa/m, d_max {dm:g} mm "
              "(ks 8e7 Pa/m, capped at 0.8 d_max)",
              {"material": {"normal_law": "hyperbolic", "normal_stiffness": 1e8,
                            "max_closure": dm * 1e-3, "closure_limit": 0.8,
                            "beyond_closure_limit": "tangent", "shear_stiffness": 8e7}})
      for dm in (0.05, 0.1, 0.2)),
    # added after the three above had run seed 0 (II x / II y moved towards 1.0 as d_max fell,
    # I / II did not move): the most stress-dependent law of the family, half closed at the
    # top course's 1 kPa (kn0 d_max = 1 kPa; kt 8e7 Pa/m at 1 kPa, 1.3e9 at 7 kPa, 16 x), its
    # cap at 0.9 d_max (p = 9 kPa) so that the beds stay on the law
    Variant("hyperbolic-1kPa", "hyperbolic joint half closed at 1 kPa: kn0 2e7 Pa/m, d_max "
            "0.05 mm (ks 8e7 Pa/m, capped at 0.9 d_max)",
            {"material": {"normal_law": "hyperbolic", "normal_stiffness": 2e7,
                          "max_closure": 5e-5, "closure_limit": 0.9,
                          "beyond_closure_limit": "tangent", "shear_stiffness": 8e7}}),
)

GRIDS = tuple(Grid(key=f"e1-{s}", title=f"E1 fingerprint run: {s} at {FREQUENCY:g} Hz",
                   hypothesis="the joints are too stiff at low stress", sweep=s,
                   variants=CANDIDATES, frequencies=(FREQUENCY,), seeds=SEEDS, cycles=CYCLES)
              for s in SWEEPS)
OUT = RESULTS / "e1"


def natural_frequency(row: dict) -> float | None:
    """f_n (Hz) of one run on the quiet branch from its ds amplification A (module docstring:
    phase under 90 deg, r < 1); None without them, and for a run whose ds lags the table by
    90 deg or more: above a linear resonance and on the rocking branch the phase reads the same
    (postprocess.verdicts.response_branch), and a rocking block is no linear oscillator, so
    such a run gives no f_n (``fingerprint_of`` counts it)."""
    b = response_branch(row)
    a, ph, f = b["ds"], b["phase_deg"], row["frequency_hz"]
    if a is None or ph is None or not a > 0.0 or ph >= 90.0:
        return None
    return f * math.sqrt((1.0 + a) / a)


def fingerprint_of(rows_by_sweep: dict) -> dict:
    """Per sweep the seeds' f_n and their median; the ratios to REFERENCE's median and whether
    each lies within RATIO_TOLERANCE of the thesis' f_c ratio."""
    per = {}
    for s, rows in rows_by_sweep.items():
        ok = [r for r in rows
              if r.get("run_status") == "ok" and abs(r["frequency_hz"] - FREQUENCY) < 1e-9]
        fn = {int(r["seed"]): natural_frequency(r) for r in ok}
        vals = [v for v in fn.values() if v is not None]
        per[s] = {"fn_hz_by_seed": fn, "median_fn_hz": float(np.median(vals)) if vals else None,
                  "runs": len(ok),
                  "rocking": sum(response_branch(r)["branch"] == "rocking" for r in ok)}
    ref = (per.get(REFERENCE) or {}).get("median_fn_hz")
    ratios = {}
    for s in SWEEPS:
        if s == REFERENCE:
            continue
        m = (per.get(s) or {}).get("median_fn_hz")
        want = THESIS_FC[s] / THESIS_FC[REFERENCE]
        got = m / ref if (m and ref) else None
        ratios[f"{s} / {REFERENCE}"] = {
            "dem": got, "thesis": want,
            "within": None if got is None else abs(got - want) <= RATIO_TOLERANCE}
    known = [r["within"] for r in ratios.values()]
    # one ratio outside fails the candidate whatever the others; all must be in to pass
    verdict = ("fails" if False in known else "pending" if None in known else "passes")
    return {"sweeps": per, "ratios": ratios, "fingerprint": verdict}


CORNER_PAIR = ("model-i-y", "model-ii-y")   # the same box but for the four corner masses


def corner_motion_of(rows_by_sweep: dict) -> dict:
    """What the corner masses do to the corner bricks (the thesis' account of Model I, lines
    752-776 and 923-929: its corner bricks "slide and rotate separately", and Model II's masses
    were added "to constrain individual brick movements"): per model of CORNER_PAIR the median
    over seeds of the two instrumented corner bricks' (penultimate course, postprocess.excited)
    mean first-harmonic twist about z (deg) and mean peak-to-peak ds (m), and Model I's over
    Model II's.  Runs without the record (rows collected before it existed, whose run directory
    is gone) are left out."""
    per = {}
    for s in CORNER_PAIR:
        runs = [judged(r) for r in rows_by_sweep.get(s) or []
                if r.get("run_status") == "ok" and abs(r["frequency_hz"] - FREQUENCY) < 1e-9]
        tw = [j["corner_twist_deg"] for j in runs if j["corner_twist_deg"] is not None]
        pp = [j["corner_pp_m"] for j in runs if j["corner_pp_m"] is not None]
        per[s] = {"runs": len(tw),
                  "median_twist_h1_deg": float(np.median(tw)) if tw else None,
                  "median_pp_corner_m": float(np.median(pp)) if pp else None}
    a, b = (per[s] for s in CORNER_PAIR)
    ratio = {k: (a[k] / b[k] if a[k] and b[k] else None)
             for k in ("median_twist_h1_deg", "median_pp_corner_m")}
    return {"models": per, f"{CORNER_PAIR[0]} / {CORNER_PAIR[1]}": ratio}


def plot(table: dict, path: Path) -> None:
    plt = agg_pyplot()

    names = list(table)
    keys = [k for k in next(iter(table.values()))["ratios"]]
    fig, ax = plt.subplots(figsize=(9.0, 3.8))
    x = np.arange(len(keys))
    w = 0.8 / (len(names) + 1)
    for i, k in enumerate(keys):
        t = table[names[0]]["ratios"][k]["thesis"]
        ax.fill_between([i - 0.45, i + 0.45], t - RATIO_TOLERANCE, t + RATIO_TOLERANCE,
                        color="0.85", lw=0)
        ax.plot([i - 0.45, i + 0.45], [t, t], "k-", lw=1)
    for j, n in enumerate(names):
        vals = [table[n]["ratios"][k]["dem"] for k in keys]
        ax.bar(x - 0.4 + (j + 0.5) * w, [v if v is not None else 0.0 for v in vals], w,
               label=n)
    ax.set_xticks(x, [k.replace(" / ", "\n/ ") for k in keys], fontsize=7)
    ax.set_ylabel("ratio of natural frequencies")
    ax.set_title(f"E1 fingerprint at {FREQUENCY:g} Hz: thesis' f_c ratio (line) +- "
                 f"{RATIO_TOLERANCE:g} (grey); no bar: that model rocks at "
                 f"{FREQUENCY:g} Hz (no f_n)", fontsize=8)
    ax.legend(fontsize=6, loc="center left", bbox_to_anchor=(1.0, 0.5))
    fig.tight_layout()
    fig.savefig(path, dpi=120)
    plt.close(fig)


def deepest_closures(variant: Variant, before: dict) -> dict:
    """A capped hyperbolic candidate's deepest closure per run, over d_max ({sweep: {seed:
    x}}): read from each run's summary.json (``max_penetration_m``, the deepest contact point
    of the run); a run whose directory is gone keeps the value ``before`` recorded.  Above
    the closure_limit a joint ran on the cap's tangent, not on the hyperbolic law."""
    mat = variant.patch.get("material") or {}
    if mat.get("normal_law") != "hyperbolic":
        return {}
    out = {}
    for g in GRIDS:
        got = dict((before.get(g.sweep) or {}))
        for seed in SEEDS:
            summ = read_json(g.runs / variant.name / f"seed-{seed}" / f"f{FREQUENCY:.3f}Hz"
                             / "summary.json") or {}
            if summ.get("status") == "ok" and summ.get("max_penetration_m") is not None:
                got[str(seed)] = summ["max_penetration_m"] / mat["max_closure"]
        if got:
            out[g.sweep] = got
    return out


def report(log=print) -> dict:
    """summary.json and fingerprint.png: the baseline's and each candidate's fingerprint."""
    from dem.output.atomic import write_json

    before = (read_json(OUT / "summary.json") or {}).get("candidates") or {}
    table = {"first prediction (kn 5e9, planar 0.1 mm)": fingerprint_of(
        {g.sweep: baseline_rows(g) for g in GRIDS})}
    for v in CANDIDATES:
        rows = {}
        for g in GRIDS:
            data = kit.records(g.out)
            rows[g.sweep] = ((data.get("variants") or {}).get(v.name) or {}).get("rows", [])
        table[v.name] = {"label": v.label, **fingerprint_of(rows),
                         "corner_motion": corner_motion_of(rows)}
        deep = deepest_closures(v, (before.get(v.name) or {}).get("deepest_closure_over_dmax")
                                or {})
        if deep:
            table[v.name]["deepest_closure_over_dmax"] = deep
    cpu = sum((read_json(g.out / "cpu.json") or {}).get(g.key, 0.0) for g in GRIDS)
    summary = {"experiment": "E1", "frequency_hz": FREQUENCY, "seeds": list(SEEDS),
               "cycles": CYCLES, "ratio_tolerance": RATIO_TOLERANCE,
               "thesis_fc_hz": THESIS_FC, "candidates": table, "cpu_seconds": cpu,
               "command": "python -m studies diagnosis grid " + " ".join(g.key for g in GRIDS)
               + " && python -m studies diagnosis e1"}
    OUT.mkdir(parents=True, exist_ok=True)
    write_json(OUT / "summary.json", summary, indent=1)
    plot(table, OUT / "fingerprint.png")
    for n, t in table.items():
        fns = ", ".join(f"{s} {p['median_fn_hz']:.2f}" for s, p in t["sweeps"].items()
                        if p["median_fn_hz"])
        rats = ", ".join(f"{r['dem']:.2f}" if r["dem"] else "-" for r in t["ratios"].values())
        cm = t.get("corner_motion")
        corners = ""
        if cm:
            r = cm[f"{CORNER_PAIR[0]} / {CORNER_PAIR[1]}"]
            tw = [cm["models"][s]["median_twist_h1_deg"] for s in CORNER_PAIR]
            if None not in tw:
                corners = (f"; corner twist I y {tw[0]:.2f} / II y {tw[1]:.2f} deg "
                           f"(x {r['median_twist_h1_deg']:.2f}), corner ds x "
                           f"{r['median_pp_corner_m']:.2f}")
        log(f"E1 {n}: f_n (Hz) {fns or '-'}; ratios {rats} -> {t['fingerprint']}{corners}")
    return summary
