"""Calibration of the imperfection parameters on the Chapter 3 tilting tests (issue 13, step 1).

    python -m studies calibration --out results/calibration          # run, then report
    python -m studies calibration --out results/calibration --report # report only
    python -m studies calibration --out results/calibration \\
        --candidates perfect bed-0.1-planar --specimens ip-small-5x5 --realisations 20

What it runs.  The calibration specimens are the small-brick tilt specimens of cases/tilt/
(in-plane/small-*.yaml, out-of-plane/small-*.yaml; the large-brick walls are held out), each
turned into a quasi-static tilt by studies.tilt.study (``quasi_static_case`` then
``study_settings``: the converged lambda of issue 11, frames every 0.02 s, no VTK), with the
``imperfections:`` section of one candidate of studies/calibration/candidates.yaml.  Friction and
joint stiffness are the case files' (measured / physical) values, never parameters.  Every
(candidate, specimen) point is one ``dem ensemble`` of N realisations, seeds 0 .. N-1 (fixed in
advance; a perfect candidate is deterministic and runs one realisation), one worker, one Taichi
thread (DEM_THREADS=1), in a child process of its own.

Where things go.  The raw runs (frames.npz, summary.json per seed) go under ``--runs`` (default
``<out>/runs/``, git-ignored by ``results/*/runs/``); the committed record of a point is
``<out>/<candidate>/<specimen>/ensemble.json``: the ensemble's own ensemble.json plus a
``calibration`` block (fingerprint of the case, seeds, per-realisation extras read from the
runs: overturning mass fraction, crack angle, engine seconds; the CPU seconds of the child
processes, accumulated over resumed sessions).  ``<out>/summary.json`` and ``<out>/README.md``
score every candidate (:func:`score_candidate`) against the targets of issue 13 step 1 that
../shared/REFERENCE.md supports (listed in :data:`TARGETS`, each with its strength).

Resumable.  A point whose committed ensemble.json holds all N realisations finished, for the
same case (fingerprint) and step cap, is skipped without starting anything; an unfinished point
is handed to ``dem ensemble`` again, which keeps every realisation already finished in its run
directory.  SIGTERM / SIGINT stop the running ensemble cleanly (its finished realisations stay),
record the point as pending and write the report.  A point that is not finished shows as pending
in the report, never as a number.

Units: lambda = a/g = tan(tilt angle at collapse), dimensionless; lengths in m; times in s.
"""

from __future__ import annotations

import argparse
import hashlib
import json
import sys
import time
from pathlib import Path

import numpy as np
import yaml

from dem.builders.bricks import brick
from dem.case import Case, load_case
from dem.engine import RESULTS_REVISION
from studies.kit import child as dem_child
from studies.kit import session
from studies.kit.provenance import rel, repo_rel, source_state
from studies.kit.records import read_json
from studies.calibration.select import is_perfect, select, selection_lines
from studies.tilt.study import quasi_static_case, study_settings

ROOT = Path(__file__).resolve().parents[2]
TILT = ROOT / "cases" / "tilt"
CANDIDATES_FILE = ROOT / "studies" / "calibration" / "candidates.yaml"
DEFAULT_REALISATIONS = 20
INVARIANT_SLIDING_TOL = 0.03  # relative: the L/H = 3 wall slides at lambda = mu within 3 %
SEQUENCE_TOL = 0.05  # overturning mass fraction: a drop smaller than this is noise, not a reversal
PARAM_KEYS = ("bed_unevenness", "face_shape", "size_scatter", "arris")
MECH_RANK = {"sliding": 0, "mixed": 1, "overturning": 2}

# ---- thesis targets (../shared/REFERENCE.md, Chapter 3; thesis Sections 3.4-3.5) -----------------
#: the L = 5, s/h = 1.5 in-plane series: L/H -> the mechanism the tests showed (Fig 3.12 / 3.13 text)
THESIS_IN_PLANE_MECHANISM = {3.0: "pure sliding", 2.14: "sliding, leeward first column overturns",
                             1.0: "two columns overturn plus sliding (mixed)",
                             0.75: "overturning dominant (three columns)",
                             0.6: "pure overturning above the main crack"}
#: FaMIVE limit analysis (Section 3.4.2, s/h = 1.5, L = 5): MODEL values, not test values
FAMIVE = {3.0: 0.67, 2.14: 0.67, 1.0: 0.65, 0.75: 0.56}
#: out-of-plane mechanisms by corner connection (Fig 3.14 text): test observations
THESIS_OOP_MECHANISM = {"strong-strong": ("B2", "G")}
#: the held-out walls (issue 13 step 1): the thesis' L/H = 2.5 large-brick walls, whose test
#: lambdas are the only ones its text gives (Section 3.3.3; REFERENCE.md), specimen -> lambda.
#: Never used to choose the set; run with the frozen set after the freeze (``--held-out``).
HELD_OUT = {"ip-large-stretcher-flat-5x6": 0.48, "ip-large-english-5x6": 0.45,
            "ip-large-stretcher-on-edge-5x4": 0.36}
HELD_OUT_DIR = "held-out"  # <out>/held-out/<specimen>/ensemble.json
TARGETS = [
    {"id": "sliding-invariant", "kind": "invariant", "strength": "strong",
     "text": "the L/H = 3 wall (ip-small-5x5) slides at lambda = mu = 0.81 within 3 % (median, "
             "modal mechanism sliding): a rigid block sliding on Coulomb joints; any imperfection "
             "that moves it is not a physical one"},
    {"id": "mechanism-sequence", "kind": "invariant", "strength": "strong (qualitative)",
     "text": "the in-plane mechanism against L/H (L = 5, s/h = 1.5: L/H = 3, 2.14, 1, 0.75, 0.6) "
             "goes from sliding to overturning: modal mechanism and median overturning mass "
             "fraction do not fall as L/H falls; L/H = 3 slides, L/H = 0.6 overturns (tests, "
             "Fig 3.12 / 3.13 text)"},
    {"id": "no-wings-lowest", "kind": "invariant", "strength": "n/a for small bricks",
     "text": "out-of-plane walls without wings have the lowest lambda (Section 3.5): no small-brick "
             "wall without wings is among cases/tilt, so it cannot be checked here"},
    {"id": "in-plane-mechanisms", "kind": "thesis", "strength": "moderate (qualitative)",
     "text": "per L/H, the mechanism observed in the tests (Fig 3.12 / 3.13 text): 3 sliding; "
             "2.14 sliding (with the leeward column overturning: sliding or mixed with < 50 % "
             "overturning mass); 1 mixed; 0.75 overturning dominant (> 50 % overturning mass); 0.6 "
             "overturning"},
    {"id": "stagger-trend", "kind": "thesis", "strength": "weak (a trend read off Fig 3.11, no "
     "numbers)", "text": "lambda rises with the stagger s/h (9 x 15 walls, s/h = 0.28 < 1 < 1.5; "
                         "Section 3.3.3)"},
    {"id": "oop-mechanisms", "kind": "thesis", "strength": "moderate (qualitative)",
     "text": "strong-strong corners: B2, G (B2 with a dominant arch) on long facades (Fig 3.14 text)"},
    {"id": "famive", "kind": "thesis", "strength": "weak: MODEL values",
     "text": "FaMIVE limit analysis (Section 3.4.2): 0.67 (L/H = 3 and 2.14, sliding), 0.65 (L/H "
             "= 1), 0.56 (L/H = 0.75).  These are not test values: the test values are only in "
             "the missing Fig 3.13(b), of which the text says 'good agreement ... when L/H > 0.8' "
             "(walls of both brick sizes together).  The thesis says FaMIVE's sliding minimum "
             "'coincides with a friction coefficient of 0.66', not the measured 0.81, so at L/H "
             "= 3 it contradicts the sliding invariant (lambda = mu = 0.81).  Shown, not scored."},
]


# ---- specimens and candidates -------------------------------------------------------------------
def _l_over_h(case: Case) -> float | None:
    """L/H of a builder wall or facade laid flat: length x brick length / (courses x brick
    height), dimensionless; None for anything else."""
    spec = case.scene.wall or case.scene.facade
    if spec is None or getattr(spec, "laying", "flat") != "flat":
        return None
    b = brick(spec.brick)
    return round(spec.length * b.length / (spec.courses * b.height), 2)


def _cost_order() -> dict[str, float]:
    """Seconds of the perfect quasi-static run of each specimen (results/tilt/results.json), the
    key that orders the specimens cheapest first; empty when that file is not there."""
    path = ROOT / "results" / "tilt" / "results.json"
    try:
        rows = json.loads(path.read_text())
    except (OSError, ValueError):
        return {}
    return {r["name"].removeprefix("qs-"): float(r.get("wall_seconds") or 0.0)
            for r in rows if r.get("name", "").startswith("qs-") and r.get("status") == "ok"}


def specimens() -> dict[str, dict]:
    """The calibration specimens: name ("ip-small-5x5", "oop-small-...") -> {path, kind
    ("in-plane" / "out-of-plane"), l_over_h}.  Order: the L = 5 in-plane series first (the
    invariants, which decide whether a candidate is admissible at all), then the others; each
    group cheapest first."""
    found = {}
    for kind, prefix in (("in-plane", "ip"), ("out-of-plane", "oop")):
        for f in sorted((TILT / kind).glob("small-*.yaml")):
            case = load_case(f)
            found[f"{prefix}-{f.stem}"] = {"path": f, "kind": kind, "l_over_h": _l_over_h(case)}
    cost = _cost_order()
    order = sorted(found, key=lambda n: (not n.startswith("ip-small-5x"),
                                         cost.get(n, float("inf")), n))
    return {n: found[n] for n in order}


def held_out_specimens() -> dict[str, dict]:
    """The held-out large-brick walls (:data:`HELD_OUT`) as :func:`specimens` gives the others,
    plus ``thesis_lambda``; ``l_over_h`` is the thesis' 2.5 (the case files' walls are 2.53)."""
    return {name: {"path": TILT / "in-plane" / (name.removeprefix("ip-") + ".yaml"),
                   "kind": "in-plane", "l_over_h": 2.5, "thesis_lambda": lam}
            for name, lam in HELD_OUT.items()}


def load_candidates(path: Path = CANDIDATES_FILE) -> dict[str, dict]:
    """Candidate imperfection sets, in the file's order: name -> {bed_unevenness (m), face_shape,
    size_scatter ([m, m, m]), arris (m)}.  Exits 2 (ValueError) on an unknown or missing key."""
    data = yaml.safe_load(Path(path).read_text()) or {}
    out = {}
    for name, params in data.items():
        params = dict(params or {})
        extra = set(params) - set(PARAM_KEYS)
        if extra:
            raise ValueError(f"{path}: candidate {name}: unknown keys {sorted(extra)} (friction "
                             f"and stiffness are not calibration parameters)")
        out[str(name)] = params
    return out


#: the collapse detector of a constant-rate tilt compared with the quasi-static lambda
#: (dem/collapse.py): confirmed at 20 mm of motion, so that a slip that stops after a few mm does
#: not count (the perfect 9 x 15 s = 10 mm wall at 0.5 deg/s slipped ~10 mm at 26.9 deg and
#: stopped; the case files' 5 mm read that slip as the collapse), lambda at the onset of the
#: motion that reaches it (the last frame its blocks were at rest), run on to 40 mm or 0.5 s.
#: The quasi-static search likewise fails an angle only when its relaxation does not come to rest.
RUNAWAY_COLLAPSE = {"confirm": 0.02, "after": 0.5, "stop": 0.04}


def specimen_case(specimen_path: Path, params: dict, name: str,
                  rate: float | None = None) -> Case:
    """The case of one (candidate, specimen) point: the specimen's case file on a quasi-static
    tilt and with the study's output settings (studies.tilt.study: ``quasi_static_case``,
    ``study_settings``), plus ``imperfections:`` = the candidate (seed 0: the ensemble sets each
    realisation's).  Everything else, friction and joint stiffness included, is the case file's.
    ``rate`` (deg/s): a constant-rate tilt from 0 deg at that rate instead of the quasi-static
    one (studies.qs_validation.study), read at the runaway (:data:`RUNAWAY_COLLAPSE`)."""
    base = load_case(specimen_path)
    if rate is None:
        base = quasi_static_case(base, name)
    else:
        data = base.model_dump()
        data["name"] = name
        data["loading"].update({"method": "constant_rate", "rate": float(rate),
                                "start_angle": 0.0, "start_time": 0.0})
        data["loading"]["collapse"].update(RUNAWAY_COLLAPSE)
        base = Case.model_validate(data)
    case = study_settings(base, name)
    data = case.model_dump()
    data["imperfections"] = {**data["imperfections"], **params, "seed": 0}
    return Case.model_validate(data)


def realisations_for(params: dict, requested: int) -> int:
    """N for a point: the requested number, 1 for a perfect candidate (every seed is the same)."""
    return 1 if is_perfect(params) else requested


def fingerprint(case: Case, n: int, max_steps: int | None) -> str:
    """What a finished point must match to be reused: the case, N, the step cap, the engine's
    results revision (dem.engine.RESULTS_REVISION)."""
    h = hashlib.sha256(case.model_dump_json().encode())
    h.update(f"|{n}|{max_steps}|{RESULTS_REVISION}".encode())
    return h.hexdigest()[:16]


# ---- running one point --------------------------------------------------------------------------
def _realisation_extras(run_dir: Path) -> dict:
    """Per-realisation numbers the ensemble's scalars leave out, from its summary.json."""
    try:
        s = json.loads((run_dir / "summary.json").read_text())
    except (OSError, ValueError):
        return {}
    m = s.get("mechanism") if isinstance(s.get("mechanism"), dict) else {}
    col = s.get("collapse") or {}
    out = {"engine_seconds": s.get("wall_seconds"), "compile_seconds": s.get("compile_seconds"),
           "steps": s.get("steps"), "sim_time_s": s.get("sim_time"), "n_blocks": s.get("n_blocks"),
           "relaxations": col.get("relaxations"), "n_moved": col.get("n_moved"),
           "overturning_mass_fraction": m.get("overturning_mass_fraction"),
           "crack_angle_deg": m.get("crack_angle_deg"),
           "collapsed_blocks": (m.get("collapsed") or {}).get("n_blocks"),
           "n_moving": m.get("n_moving")}
    return {k: v for k, v in out.items() if v is not None}


def point_path(out: Path, candidate: str, specimen: str) -> Path:
    return Path(out) / candidate / specimen / "ensemble.json"


def point_finished(data: dict | None, fp: str | None = None) -> bool:
    """A committed point is finished when every one of its N realisations finished ok (and, if
    given, its fingerprint is ``fp``)."""
    if not data or "calibration" not in data:
        return False
    cal = data["calibration"]
    if fp is not None and cal.get("fingerprint") != fp:
        return False
    agg = data.get("aggregate") or {}
    return bool(cal.get("finished")) and agg.get("n_ok") == cal.get("n_realisations")


def run_point(out: Path, runs: Path, candidate: str, params: dict, specimen: str,
              spec: dict, realisations: int, max_steps: int | None = None,
              log=print, record: dict | None = None, rate: float | None = None) -> str:
    """Run (or skip) one point; returns "skipped" (already finished), "finished", "pending"
    (interrupted or a realisation failed) or "failed" (dem ensemble refused the case).
    ``record``: more fields for the point's ``calibration`` block (the held-out points: the
    frozen set's file and commit).  ``rate``: a constant-rate tilt (:func:`specimen_case`)."""
    name = f"cal-{candidate}-{specimen}" + ("" if rate is None else f"-rate-{rate:g}")
    case = specimen_case(spec["path"], params, name, rate)
    n = realisations_for(params, realisations)
    fp = fingerprint(case, n, max_steps)
    dest = point_path(out, candidate, specimen)
    old = read_json(dest)
    if point_finished(old, fp):
        return "skipped"
    ens_dir = Path(runs) / candidate / specimen
    case_file = Path(runs) / candidate / f"{specimen}.yaml"
    case_file.parent.mkdir(parents=True, exist_ok=True)
    case_file.write_text(yaml.safe_dump(case.model_dump(mode="json"), sort_keys=False))
    cmd = ["ensemble", str(case_file), "--out", str(ens_dir), "--realisations", str(n),
           "--seed", "0", "--workers", "1"]
    if max_steps is not None:
        cmd += ["--max-steps", str(max_steps)]
    log(f"[{time.strftime('%H:%M:%S', time.gmtime())} UTC] {candidate} / {specimen}: {n} realisation(s) ...")
    rc, cpu, wall = dem_child.run_dem(cmd, log)
    data = read_json(ens_dir / "ensemble.json")
    if data is None:
        log(f"    dem ensemble exit {rc}: no ensemble.json")
        return "failed"
    prev = (old or {}).get("calibration") or {}
    same = prev.get("fingerprint") == fp
    rows = data.get("realisations") or []
    extras = {r["name"]: _realisation_extras(ens_dir / r["name"]) for r in rows
              if r.get("status") == "ok"}
    finished = (data.get("aggregate") or {}).get("n_ok") == n
    data["source"] = rel(case_file)
    data["calibration"] = {
        "candidate": candidate, "specimen": specimen, "specimen_case": rel(spec["path"]),
        "kind": spec["kind"], "l_over_h": spec["l_over_h"],
        "parameters": params, "friction": case.material.friction,
        "normal_stiffness_pa_per_m": case.material.normal_stiffness,
        "n_realisations": n, "seeds": list(range(n)), "max_steps": max_steps,
        "deterministic": is_perfect(params), "fingerprint": fp, "finished": finished,
        "cpu_seconds": (prev.get("cpu_seconds", 0.0) if same else 0.0) + cpu,
        "wall_seconds": (prev.get("wall_seconds", 0.0) if same else 0.0) + wall,
        "sessions": (prev.get("sessions", 0) if same else 0) + 1,
        "exit_code": rc, "source": source_state(checkout=True), "extras": extras, **(record or {})}
    from dem.output.atomic import write_json

    dest.parent.mkdir(parents=True, exist_ok=True)
    write_json(dest, data, indent=1)
    state = "finished" if finished else "pending"
    log(f"    -> {state}: {cpu:.0f} CPU-s, {wall:.0f} s this call")
    return state


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


def _finished(p: dict | None) -> bool:
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
    if not _finished(p):
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
    pend = [n for _, n in series if not _finished(points[n])]
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
    if any(not _finished(p) for p in oop.values()):
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
        if not _finished(p):
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
    if any(not _finished(points[n]) for n in names):
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
        if not _finished(p):
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
        if _finished(p) and p.get("lambda_median") is not None:
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


# ---- report -------------------------------------------------------------------------------------
def collect(out: Path, candidates: dict, specs: dict, n: int | None = None) -> dict:
    """candidate -> specimen -> point_summary, from the committed point files.  With ``n``
    (the study's N), a point whose fingerprint is not this code's for that case (an earlier
    RESULTS_REVISION, another case; smoke points capped by --max-steps excepted) is reported
    as pending, ``stale``: its numbers are not this engine's."""
    res: dict = {}
    for c, params in candidates.items():
        res[c] = {}
        for s in specs:
            data = read_json(point_path(out, c, s))
            p = point_summary(data)
            cal = (data or {}).get("calibration") or {}
            if n is not None and cal and cal.get("max_steps") is None:
                case = specimen_case(specs[s]["path"], params, f"cal-{c}-{s}")
                if cal.get("fingerprint") != fingerprint(case, realisations_for(params, n), None):
                    p = {"status": "pending", "stale": True, "n_ok": 0,
                         "n_realisations": cal.get("n_realisations")}
            res[c][s] = {"l_over_h": specs[s]["l_over_h"], "kind": specs[s]["kind"],
                         **{k: v for k, v in p.items()
                            if v is not None or k not in ("l_over_h", "kind")}}
    return res


def held_out_summary(out: Path) -> dict:
    """specimen -> the held-out point's point_summary with the thesis' lambda, the frozen set it
    ran with (file, commit), the median's relative difference from the thesis and whether the
    thesis value lies in the 10-90 % band (pending points: no numbers)."""
    res = {}
    for s, spec in held_out_specimens().items():
        data = read_json(point_path(out, HELD_OUT_DIR, s))
        p = {**point_summary(data), "l_over_h": spec["l_over_h"],
             "thesis_lambda": spec["thesis_lambda"],
             "frozen": ((data or {}).get("calibration") or {}).get("frozen")}
        if _finished(p) and p.get("lambda_median") is not None:
            lam = spec["thesis_lambda"]
            p["relative_difference"] = p["lambda_median"] / lam - 1.0
            p["thesis_in_band"] = bool(p["lambda_q10"] <= lam <= p["lambda_q90"])
        res[s] = p
    return res


def held_out_lines(held: dict) -> list[str]:
    """The report's section on the held-out large-brick walls."""
    L = ["## Held out: the large-brick walls (L/H = 2.5)", ""]
    if not any(p.get("n_ok") for p in held.values()):
        return L + ["Their test lambdas (0.48 stretcher flat, 0.45 English, 0.36 stretcher on "
                    "edge; Section 3.3.3) are the only ones the text gives; they are not used "
                    "to choose the set.  After the freeze they are predicted with the frozen set "
                    "unchanged: `python -m studies calibration --out "
                    "results/calibration --held-out` (not run yet).", ""]
    frozen = {json.dumps(p["frozen"], sort_keys=True) for p in held.values() if p.get("frozen")}
    L += ["Predicted with the frozen set unchanged (its lengths in metres, not scaled to the "
          "larger brick): " + "; ".join(f"`{f}`" for f in sorted(frozen)) + ".", "",
          "| specimen | L/H | thesis lambda | done | median lambda | 10-90 % | thesis in band | "
          "median vs thesis | mechanisms |", "|---|---|---|---|---|---|---|---|---|"]
    for s, p in held.items():
        done = f"{p.get('n_ok', 0)}/{p.get('n_realisations') or '-'}"
        if _finished(p) and p.get("lambda_median") is not None:
            mech = ", ".join(f"{k} {v}" for k, v in (p.get("mechanisms") or {}).items()) or "-"
            L.append(f"| {s} | {fmt_fixed(p['l_over_h'], 2)} | {p['thesis_lambda']} | {done} | "
                     f"{fmt_fixed(p['lambda_median'], 4)} | {fmt_fixed(p['lambda_q10'], 4)} - "
                     f"{fmt_fixed(p['lambda_q90'], 4)} | {'yes' if p['thesis_in_band'] else 'no'} | "
                     f"{100 * p['relative_difference']:+.0f} % | {mech} |")
        else:
            L.append(f"| {s} | {fmt_fixed(p['l_over_h'], 2)} | {p['thesis_lambda']} | {done} | "
                     "pending | pending | - | - | pending |")
    return L + [""]


def _estimate(points: dict, specs: dict, candidates: dict, n: int) -> dict:
    """CPU seconds per realisation of each specimen and the whole grid's estimate (n
    realisations per imperfect point, one per perfect one).

    Measured: the mean over a specimen's finished imperfect points (their own CPU, settling and
    process start included).  Where a specimen has none yet: its perfect point's CPU times the
    median ratio imperfect / perfect over the specimens that have both (imperfect runs settle
    first and step the warped-face kernels).  None while no perfect point is finished."""
    def per_real(ps):
        vals = [p["cpu_seconds"] / max(p["n_realisations"], 1) for p in ps
                if p.get("cpu_seconds")]
        return float(np.mean(vals)) if vals else None

    perfect = [c for c in candidates if is_perfect(candidates[c])]
    imperfect = [c for c in candidates if not is_perfect(candidates[c])]
    meas = {s: per_real([points[c][s] for c in imperfect if _finished(points[c][s])])
            for s in specs}
    base = {s: per_real([points[c][s] for c in perfect if _finished(points[c][s])])
            for s in specs}
    ratios = [meas[s] / base[s] for s in specs if meas[s] and base[s]]
    ratio = float(np.median(ratios)) if ratios else None
    per, how = {}, {}
    for s in specs:
        if meas[s] is not None:
            per[s], how[s] = meas[s], "measured"
        elif base[s] is not None and ratio is not None:
            per[s], how[s] = base[s] * ratio, f"perfect x {ratio:.2f}"
        else:
            per[s], how[s] = None, "unknown"
    known = all(v is not None for v in per.values())
    total = sum(v * n * len(imperfect) + (base[s] or v) * len(perfect)
                for s, v in per.items()) if known else None
    done = sum(p.get("cpu_seconds") or 0.0 for c in points for p in points[c].values()
               if _finished(p))
    return {"cpu_seconds_per_realisation": per, "how": how, "imperfect_over_perfect": ratio,
            "grid_cpu_seconds": total, "finished_cpu_seconds": done,
            "basis": "per specimen: its finished imperfect points' CPU per realisation, else its "
                     "perfect point's times the median imperfect / perfect ratio; x (N x "
                     "imperfect candidates) + the perfect points"}


def fmt_fixed(x, nd=3) -> str:
    """x with nd decimals, '-' for None (the report's lambdas)."""
    return "-" if x is None else f"{x:.{nd}f}"


def report(out: Path, candidates: dict, specs: dict, n: int, command: str) -> dict:
    """Write <out>/summary.json and <out>/README.md from the committed point files."""
    from dem.output.atomic import write_json

    points = collect(out, candidates, specs, n)
    scores = {c: score_candidate(points[c]) for c in candidates}
    selection = select(candidates, points, scores)
    cpu = sum(p.get("cpu_seconds") or 0.0 for c in points for p in points[c].values())
    est = _estimate(points, specs, candidates, n)
    held = held_out_summary(out)
    summary = {"kind": "calibration", "issue": 13, "step": 1, "command": command,
               "realisations": n, "seeds": f"0..{n - 1} (perfect: 0 only, deterministic)",
               "candidates": candidates, "specimens": {s: {"case": rel(v["path"]),
                   "kind": v["kind"], "l_over_h": v["l_over_h"]}
                   for s, v in specs.items()},
               "targets": TARGETS, "points": points, "scores": scores,
               "selection": selection, "cpu_seconds_so_far": cpu, "estimate": est,
               "held_out": held}
    write_json(out / "summary.json", summary, indent=1)

    L = ["# Calibration on the Chapter 3 tilting tests (issue 13, step 1)", "",
         f"Generated by `{command}` (resumable: finished points are skipped, unfinished "
         "ensembles keep their finished realisations); `--report` rebuilds this page and "
         "summary.json from the committed point files "
         "`<candidate>/<specimen>/ensemble.json`.", "",
         "Each point: the small-brick tilt specimen of cases/tilt on a quasi-static tilt "
         "(studies/tilt/study.py `quasi_static_case`, `study_settings`) with the candidate's "
         "`imperfections:` (studies/calibration/candidates.yaml, where each magnitude comes from), "
         f"N = {n} realisations with seeds 0..{n - 1} (the perfect candidate is deterministic: "
         "one run), friction 0.81 and joint stiffness as in the case files.  lambda = tan(tilt "
         "angle at collapse), the median and 10-90 % band over the realisations; mechanisms: "
         "counts over the realisations (postprocess/mechanisms.py).  A point not finished shows "
         "as pending.  CPU: user + system seconds of the point's `dem ensemble` process tree "
         "(one worker, one Taichi thread), summed over the sessions that ran it.  Every point "
         f"ran on the engine's results revision {RESULTS_REVISION} (dem.engine.RESULTS_REVISION, "
         "part of the resume fingerprint: a point of another revision is run again).", "",
         "How the frozen set will be chosen from these points was fixed before the grid "
         "finished: [SELECTION.md](SELECTION.md).  Points of earlier revisions were withdrawn; "
         "what they showed and why: [HISTORY.md](HISTORY.md).", ""]
    L += ["## Targets (../shared/REFERENCE.md) and their strength", "",
          "| target | kind | strength | what |", "|---|---|---|---|"]
    for t in TARGETS:
        L.append(f"| {t['id']} | {t['kind']} | {t['strength']} | {t['text']} |")
    L += [""] + selection_lines(selection) + held_out_lines(held)
    for c, params in candidates.items():
        pts, sc = points[c], scores[c]
        L += [f"## {c}", "", "`" + json.dumps(params) + "`", "",
              "| specimen | L/H | done | median lambda | vs perfect | 10-90 % | mechanisms | "
              "median overturning fraction | CPU s | CPU s / realisation |",
              "|---|---|---|---|---|---|---|---|---|---|"]
        for s in specs:
            p = pts[s]
            done = f"{p.get('n_ok', 0)}/{p.get('n_realisations') or '-'}"
            cpu_s = p.get("cpu_seconds")
            per = (cpu_s / p["n_realisations"]) if cpu_s and p.get("n_realisations") else None
            if _finished(p):
                band = f"{fmt_fixed(p.get('lambda_q10'), 4)} - {fmt_fixed(p.get('lambda_q90'), 4)}"
                mech = [f"{k} {v}" for k, v in (p.get("mechanisms") or {}).items()]
                if p.get("no_collapse"):
                    mech.append(f"no collapse {p['no_collapse']}")
                if p.get("lone_block"):
                    mech.append("one block alone: " + ", ".join(
                        f"{n} at {fmt_fixed(lam, 3)}" for n, lam in p["lone_block"]))
                mech = ", ".join(mech) or "-"
                if p.get("smoke"):
                    done += " (smoke: steps capped)"
                ref = points.get("perfect", {}).get(s, {})
                vs = (f"{100 * (p['lambda_median'] / ref['lambda_median'] - 1):+.1f} %"
                      if c != "perfect" and _finished(ref) and ref.get("lambda_median")
                      and p.get("lambda_median") is not None else "-")
                L.append(f"| {s} | {fmt_fixed(p.get('l_over_h'), 2)} | {done} | "
                         f"{fmt_fixed(p.get('lambda_median'), 4)} | {vs} | {band} | {mech} | "
                         f"{fmt_fixed(p.get('overturning_fraction_median'), 2)} | "
                         f"{fmt_fixed(cpu_s, 0)} | {fmt_fixed(per, 0)} |")
            elif p.get("stale"):
                L.append(f"| {s} | {fmt_fixed(p.get('l_over_h'), 2)} | - | pending (the committed "
                         "point is of an earlier revision or case: not shown, see HISTORY.md) | "
                         "- | pending | pending | pending | - | - |")
            else:
                L.append(f"| {s} | {fmt_fixed(p.get('l_over_h'), 2)} | {done} | pending | - | "
                         f"pending | pending | pending | {fmt_fixed(cpu_s, 0)} | - |")
        L += ["", "| check | kind | status | detail |", "|---|---|---|---|"]
        for k, v in sc["invariants"].items():
            L.append(f"| {k} | invariant | {v['status']} | {_detail(k, v)} |")
        for k, v in sc["thesis"].items():
            L.append(f"| {k} | thesis | {v['status']} | {_detail(k, v)} |")
        fam = "; ".join(
            f"L/H {r['l_over_h']}: FaMIVE {r['famive']}, DEM "
            + (f"{r['median']:.3f} ({100 * r['relative_difference']:+.0f} %, "
               + ("deterministic" if r["in_band"] is None else
                  f"{'in' if r['in_band'] else 'outside'} the band") + ")"
               if "median" in r else "pending")
            for r in sc["famive"])
        L += [f"| famive | thesis, MODEL values, not scored | - | {fam or '-'} |", ""]
    commits = sorted({(p.get("commit"), p.get("dirty")) for c in points
                      for p in points[c].values() if p.get("commit")})
    L += ["## Code", "", "The points were computed by commit(s) " + (", ".join(
        f"{c[:7]}" + (" (with uncommitted changes in dem/, postprocess/, studies/ or cases/)" if d else "")
        for c, d in commits) or "-") + " (each point file's `calibration.source`).", ""]
    L += ["## CPU", "",
          f"CPU so far: {cpu:.0f} s ({cpu / 3600:.2f} h) over the finished and partial points."]
    per = est["cpu_seconds_per_realisation"]
    L += ["", "| specimen | CPU s per imperfect realisation | from |", "|---|---|---|"]
    L += [f"| {s} | {fmt_fixed(v, 0)} | {est['how'][s]} |" for s, v in per.items()]
    g = est["grid_cpu_seconds"]
    L += ["", "Estimated CPU of the whole grid (" + f"{len(candidates)} candidates x "
          f"{len(specs)} specimens, N = {n}): "
          + (f"{g:.0f} s = {g / 3600:.1f} h, of which {est['finished_cpu_seconds']:.0f} s "
             "are done" if g else "not yet (a specimen has no finished point)")
          + f"; {est['basis']}.", ""]
    (out / "README.md").write_text("\n".join(L) + "\n")
    return summary


def _detail(key: str, v: dict) -> str:
    s = v.get("status")
    if s == "n/a":
        return v.get("why", "")
    if s == "pending":
        w = v.get("waiting_for") or [r["specimen"] for r in v.get("rows", [])
                                     if r.get("status") == "pending"] or v.get("specimen")
        return f"waiting for {w}" if w else ""
    if key == "sliding-invariant":
        return (f"{v['specimen']}: median {fmt_fixed(v.get('median'), 4)} vs mu {v.get('mu')} "
                f"({100 * v['relative_error']:+.1f} %, tolerance 3 %), band "
                f"{fmt_fixed(v['band'][0], 4)} - {fmt_fixed(v['band'][1], 4)}, modal "
                f"{v.get('modal_mechanism')}" if "relative_error" in v else v.get("why", ""))
    if key == "mechanism-sequence":
        seq = ", ".join(f"{r['l_over_h']}: {r['modal']} ({fmt_fixed(r['overturning_fraction'], 2)})"
                        for r in v["series"])
        return seq + ("; " + "; ".join(v["problems"]) if v["problems"] else "")
    if key in ("in-plane-mechanisms", "oop-mechanisms"):
        return "; ".join(f"{r['specimen']}: {r.get('modal', 'pending')} ({r['status']})"
                         for r in v["rows"])
    if key == "stagger-trend":
        return ", ".join(f"{n}: {fmt_fixed(m, 4)}" for n, m in zip(v["specimens"], v["medians"]))
    return json.dumps(v)


# ---- command line -------------------------------------------------------------------------------
def _command(args) -> str:
    """The command that regenerates the study, as run from the checkout that holds --out (the
    session's --stop-at and --runs left out: they do not change the results)."""
    return session.command("calibration", out=repo_rel(args.out),
                           candidates=args.candidates or None, specimens=args.specimens or None,
                           realisations=(args.realisations, DEFAULT_REALISATIONS),
                           max_steps=args.max_steps)


def main(argv=None) -> int:
    ap = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawTextHelpFormatter)
    ap.add_argument("--out", type=Path, default=ROOT / "results" / "calibration")
    ap.add_argument("--runs", type=Path, default=None,
                    help="raw runs (frames.npz ...; default <out>/runs, git-ignored)")
    ap.add_argument("--candidates", nargs="*", default=None, help="names (default: all, in the "
                    "file's order)")
    ap.add_argument("--candidates-file", type=Path, default=CANDIDATES_FILE)
    ap.add_argument("--specimens", nargs="*", default=None, help="names (default: all, "
                    "cheapest first)")
    ap.add_argument("--realisations", type=int, default=DEFAULT_REALISATIONS)
    ap.add_argument("--max-steps", type=int, default=None,
                    help="cap the steps of each run (smoke; such points never count as the "
                         "real ones: the cap is part of their fingerprint)")
    ap.add_argument("--stop-at", default=None,
                    help="UTC time HH:MM after which no new point is started")
    ap.add_argument("--report", action="store_true", help="only rebuild the report")
    ap.add_argument("--held-out", action="store_true",
                    help="after the freeze: run the held-out large-brick walls (HELD_OUT) with "
                         "the committed frozen set (--frozen) into <out>/held-out/")
    ap.add_argument("--frozen", type=Path, default=ROOT / "studies" / "calibration" / "frozen.yaml",
                    help="the frozen set for --held-out (must be committed under cases/)")
    ap.add_argument("--freeze", action="store_true",
                    help="rebuild the report, then write the choice of SELECTION.md "
                         "(studies.calibration.select) to --frozen; refused (exit 2) while "
                         "the choice is undecided.  Commit the file and the report together.")
    args = ap.parse_args(argv)
    if args.realisations < 1:
        ap.error("--realisations must be >= 1")
    if args.held_out:
        return _main_held_out(ap, args)
    if args.freeze:
        return _main_freeze(ap, args)
    all_c, all_s = load_candidates(args.candidates_file), specimens()
    for what, chosen, known in (("candidate", args.candidates, all_c),
                                ("specimen", args.specimens, all_s)):
        bad = [x for x in chosen or [] if x not in known]
        if bad:
            ap.error(f"unknown {what}(s) {bad}; known: {list(known)}")
    cands = {c: all_c[c] for c in (args.candidates or all_c)}
    specs = {s: all_s[s] for s in all_s if args.specimens is None or s in args.specimens}
    out = args.out
    runs = args.runs or out / "runs"
    out.mkdir(parents=True, exist_ok=True)
    command = _command(args)
    dem_child.install_signal_handlers()
    if not args.report:
        for c, params in cands.items():
            for s, spec in specs.items():
                if session.should_stop(stop_at=args.stop_at,
                                       log=lambda m: print(m, flush=True)):
                    break
                state = run_point(out, runs, c, params, s, spec, args.realisations,
                                  args.max_steps, log=lambda m: print(m, flush=True))
                if state != "skipped":
                    report(out, all_c, all_s, args.realisations, command)
    report(out, all_c, all_s, args.realisations, command)
    return 0


def _main_freeze(ap, args) -> int:
    """--freeze: the report from the committed points, then the decided choice to --frozen."""
    from studies.calibration.select import FreezeRefused, freeze

    if args.candidates or args.specimens:
        ap.error("--freeze applies SELECTION.md to every candidate and specimen: no "
                 "--candidates / --specimens")
    all_c = load_candidates(args.candidates_file)
    args.out.mkdir(parents=True, exist_ok=True)
    summary = report(args.out, all_c, specimens(), args.realisations, _command(args))
    sel = summary["selection"]
    try:
        written = freeze(sel, all_c, args.frozen, time.strftime("%Y-%m-%d", time.gmtime()))
    except FreezeRefused as err:
        print(f"calibration_study: {err}", file=sys.stderr)
        return 2
    print(f"{'froze' if written else 'already frozen:'} {sel['chosen']} -> {args.frozen} "
          f"({sel['why']}); commit it with {args.out}/README.md and summary.json")
    return 0


def _main_held_out(ap, args) -> int:
    """--held-out: the large-brick walls with the frozen set (refused, exit 2, before the
    freeze: studies.prediction.plan.load_frozen)."""
    from studies.prediction.plan import load_frozen
    from studies.prediction.protocol import PredictionInputError

    if args.candidates:
        ap.error("--held-out runs the frozen set, not --candidates")
    try:
        frozen = load_frozen(args.frozen)
    except PredictionInputError as err:
        ap.error(str(err))
    all_s = held_out_specimens()
    bad = [x for x in args.specimens or [] if x not in all_s]
    if bad:
        ap.error(f"unknown held-out specimen(s) {bad}; known: {list(all_s)}")
    record = {"frozen": {"file": frozen["path"], "commit": frozen["commit"],
                         "sha256": frozen["sha256"]}}
    out, runs = args.out, args.runs or args.out / "runs"
    out.mkdir(parents=True, exist_ok=True)
    dem_child.install_signal_handlers()
    for s, spec in all_s.items():
        if args.specimens and s not in args.specimens:
            continue
        if session.should_stop(stop_at=args.stop_at,
                               log=lambda m: print(m, flush=True)):
            break
        run_point(out, runs, HELD_OUT_DIR, frozen["parameters"], s, spec, args.realisations,
                  args.max_steps, log=lambda m: print(m, flush=True), record=record)
    report(out, load_candidates(args.candidates_file), specimens(), args.realisations,
           _command(args))
    return 0


if __name__ == "__main__":
    sys.exit(main())
