"""Every committed record of a study still resumes: the fingerprint a finished point recorded is
the one the study's code computes for that point today, so the point counts as finished and is
never run again.  Nothing runs: each point's case is rebuilt from the study's plan and hashed.

The studies with fingerprinted records: the calibration (results/calibration/<candidate>/
<specimen>/ensemble.json, its held-out points and the quasi-static validation's rates, all
through studies.calibration.points), the Chapter 3 check (the same points under
results/prediction/chapter3-check), the first prediction (results/prediction/<sweep>/
points.json) and the diagnosis (results/diagnosis/<key>/points.json: E2's specimens, E4's
levels, every grid's variants)."""

import json
from pathlib import Path

import pytest

ROOT = Path(__file__).resolve().parents[1]
RESULTS = ROOT / "results"


def _calibration_points():
    return sorted(p for p in RESULTS.rglob("ensemble.json")
                  if "fingerprint" in (json.loads(p.read_text()).get("calibration") or {}))


def _reported_stale(point: Path) -> bool:
    """Whether the committed calibration summary already reports ``point`` as stale (made by an
    earlier engine revision: pending, to run again by design)."""
    rel = point.relative_to(RESULTS / "calibration").parts
    if len(rel) != 3:
        return False
    summary = json.loads((RESULTS / "calibration" / "summary.json").read_text())
    return bool(((summary.get("points") or {}).get(rel[0]) or {}).get(rel[1], {}).get("stale"))


def test_every_calibration_point_keeps_its_fingerprint():
    """The calibration's, held-out, quasi-static and Chapter 3 check points: recomputed from
    the recorded specimen case, parameters, rate, N and step cap."""
    from studies.calibration.specimens import fingerprint, specimen_case

    points = _calibration_points()
    kinds = {"calibration": 0, "held-out": 0, "qs-validation": 0, "chapter3-check": 0}
    for path in points:
        cal = json.loads(path.read_text())["calibration"]
        rate = cal.get("rate_deg_per_s")
        name = f"cal-{cal['candidate']}-{cal['specimen']}" + ("" if rate is None
                                                                else f"-rate-{rate:g}")
        case = specimen_case(ROOT / cal["specimen_case"], cal["parameters"], name, rate)
        now = fingerprint(case, cal["n_realisations"], cal["max_steps"])
        if now != cal["fingerprint"]:
            assert _reported_stale(path), f"{path.relative_to(ROOT)} would run again"
            continue
        parts = path.relative_to(RESULTS).parts
        kind = ("chapter3-check" if "chapter3-check" in parts else "held-out" if "held-out" in
                parts else "qs-validation" if "qs-validation" in parts else "calibration")
        kinds[kind] += 1
    assert all(kinds.values()), kinds


def test_every_prediction_sweep_keeps_its_fingerprint():
    from studies.prediction import plan as P

    root = RESULTS / "prediction"
    plan = json.loads((root / "plan.json").read_text())
    checked = 0
    for name, sweep in plan["sweeps"].items():
        path = root / name / "points.json"
        if not path.exists():
            continue
        stored = json.loads(path.read_text())["prediction"]["fingerprint"]
        case = P.sweep_case(name, plan["frozen"]["parameters"])
        assert stored == P.fingerprint(case, sweep["frequencies_hz"], plan["seeds"],
                                       P.sweep_cycles(plan, name), plan["max_steps"]), name
        checked += 1
    assert checked == len(list(root.glob("*/points.json")))


def _diagnosis_records():
    return sorted((RESULTS / "diagnosis").glob("*/points.json"))


@pytest.fixture(scope="module")
def frozen_parameters():
    from studies.prediction.plan import load_frozen
    from studies.prediction.protocol import DEFAULT_FROZEN

    return load_frozen(DEFAULT_FROZEN)["parameters"]


def test_every_diagnosis_record_keeps_its_fingerprint(frozen_parameters):
    """Each results/diagnosis/<key>/points.json belongs to E2, E4 or a grid of the study, and
    each point recorded in it (specimen, level, variant) has today's fingerprint."""
    from studies.diagnosis import e2, e4, grid as G
    from studies.diagnosis.e1 import GRIDS as E1_GRIDS
    from studies.diagnosis.experiments import GRIDS

    grids = {**GRIDS, **{g.key: g for g in E1_GRIDS}}
    checked = {}
    for path in _diagnosis_records():
        key, data = path.parent.name, json.loads(path.read_text())
        if key == "e2":
            now = {n: e2.fingerprint(e2.specimen_case(r["sweep"], r["seed"], frozen_parameters))
                   for n, r in data["specimens"].items()}
            recs = data["specimens"]
        elif key == "e4":
            now = {n: e4.fingerprint(e4.level_case(frozen_parameters,
                                                   r["peak_acceleration_m_s2"]))
                   for n, r in data["levels"].items()}
            recs = data["levels"]
        else:
            assert key in grids, f"{path.relative_to(ROOT)}: no grid of the study writes it"
            grid = grids[key]
            variants = {v.name: v for v in grid.variants}
            recs = data["variants"]
            assert set(recs) <= set(variants), key
            now = {n: G.fingerprint(grid, G.variant_case(grid, variants[n], frozen_parameters))
                   for n in recs}
        for name, rec in recs.items():
            assert rec["fingerprint"] == now[name], f"{key}/{name} would run again"
        checked[key] = len(recs)
    assert {"e2", "e4"} <= set(checked) and len(checked) == len(_diagnosis_records())
    assert all(checked.values()), checked


def test_every_as_built_record_keeps_its_fingerprint(frozen_parameters):
    """Each results/as-built/<key>/points.json belongs to a grid, the identification runs or
    the kick-start of the as-built study, and each point recorded in it has today's
    fingerprint."""
    from studies.as_built import identification as ident
    from studies.as_built import kick_start as kick
    from studies.as_built.grids import GRIDS
    from studies.diagnosis import grid as G
    from studies.prediction.plan import load_frozen
    from studies.prediction.protocol import DEFAULT_FROZEN

    paths = sorted((RESULTS / "as-built").glob("*/points.json"))
    for path in paths:
        key, data = path.parent.name, json.loads(path.read_text())
        if key == ident.KEY:
            now = {p.name: p.fingerprint for p in ident.points(load_frozen(DEFAULT_FROZEN))}
            recs = data["points"]
        elif key == kick.KEY:
            now = {p.name: p.fingerprint for p in kick.points(load_frozen(DEFAULT_FROZEN))}
            recs = data["points"]
        else:
            assert key in GRIDS, f"{path.relative_to(ROOT)}: no grid of the study writes it"
            grid = GRIDS[key]
            variants = {v.name: v for v in grid.variants}
            recs = data["variants"]
            now = {n: G.fingerprint(grid, G.variant_case(grid, variants[n], frozen_parameters))
                   for n in recs}
        assert recs, key
        for name, rec in recs.items():
            assert rec["fingerprint"] == now[name], f"{key}/{name} would run again"
