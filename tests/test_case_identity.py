"""A case's identity across schema changes (dem.case.identity): a field added later at the
value that reproduces the old behaviour leaves recorded runs valid."""

import json

from dem.case import parse_case
from dem.case.identity import LATER_FIELDS, identity_json, same_case

BLOCK = {"name": "b", "scene": {"blocks": [{"size": [0.2, 0.2, 0.1],
                                            "position": [0.0, 0.0, 0.05], "mass": 4.0}]},
         "material": {"friction": 0.5}, "run": {"duration": 0.1}}


def test_the_recorded_e4_fingerprints_still_match():
    """results/diagnosis/e4/points.json was written before solver.overlap_reuse existed: its
    levels' fingerprints are those of the study's cases today (else E4 would run again)."""
    from pathlib import Path

    from studies.diagnosis import e4

    points = json.loads((Path(__file__).parents[1] / "results/diagnosis/e4/points.json")
                        .read_text())
    frozen = e4.load_frozen(e4.DEFAULT_FROZEN)
    checked = 0
    for accel in e4.ACCELERATIONS:
        rec = points["levels"].get(e4.level_name(accel))
        if rec is None:
            continue
        assert rec["fingerprint"] == e4.fingerprint(e4.level_case(frozen["parameters"], accel))
        checked += 1
    assert checked >= 2


def test_a_later_field_at_its_neutral_value_is_left_out():
    case = parse_case(BLOCK)
    assert ("solver", "overlap_reuse") in LATER_FIELDS
    assert "overlap_reuse" not in json.loads(identity_json(case))["solver"]
    on = parse_case({**BLOCK, "solver": {"overlap_reuse": 1e-7}})
    assert json.loads(identity_json(on))["solver"]["overlap_reuse"] == 1e-7
    assert identity_json(on) != identity_json(case)


def test_a_case_json_written_before_the_field_is_the_same_case():
    case = parse_case(BLOCK)
    old = json.loads(case.model_dump_json())
    del old["solver"]["overlap_reuse"]
    assert same_case(old, case)
    assert not same_case(old, parse_case({**BLOCK, "solver": {"overlap_reuse": 1e-7}}))
    other = json.loads(case.model_dump_json())
    other["material"]["friction"] = 0.6
    assert not same_case(other, case)


def test_the_recorded_prediction_fingerprints_still_match():
    """Each sweep of results/prediction (recorded before solver.overlap_reuse existed) keeps the
    fingerprint its plan gives today: the prediction is not run again."""
    from pathlib import Path

    from studies.prediction import plan as P

    root = Path(__file__).parents[1] / "results/prediction"
    plan = json.loads((root / "plan.json").read_text())
    checked = 0
    for name, sweep in plan["sweeps"].items():
        points = root / name / "points.json"
        if not points.exists():
            continue
        stored = (json.loads(points.read_text()).get("prediction") or {}).get("fingerprint")
        case = P.sweep_case(name, plan["frozen"]["parameters"])
        assert stored == P.fingerprint(case, sweep["frequencies_hz"], plan["seeds"],
                                       P.sweep_cycles(plan, name), plan["max_steps"]), name
        checked += 1
    assert checked >= 5
