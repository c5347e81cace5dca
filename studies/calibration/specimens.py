"""The calibration's specimens (the small-brick tilts of cases/tilt), the candidates
(studies/calibration/candidates.yaml), the thesis targets, and the case of one point.
"""

from __future__ import annotations

import json
from pathlib import Path

import yaml

from dem.builders.bricks import brick
from dem.case import Case, load_case
from studies.calibration.select import is_perfect
from studies.kit.study import fingerprint as kit_fingerprint
from studies.tilt.study import quasi_static_case, study_settings
from studies.kit.provenance import ROOT

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
#: the held-out walls: the thesis' L/H = 2.5 large-brick walls, whose test
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
    results revision (dem.engine.RESULTS_REVISION), in the form its records were written with."""
    return kit_fingerprint(case, n, max_steps, form="bars")


