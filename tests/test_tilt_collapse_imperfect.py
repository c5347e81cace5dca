"""Tilt collapse on imperfect scenes: the detector measures from the settled
pose, a re-seating on warped beds is not a collapse, and an onset that cannot be resolved says
so instead of reading lambda = 0.

The user's column (cases/tilt/column-3-uneven.yaml: 3 bricks 0.105 x 0.05 x 0.035 m, 0.336 kg,
friction 0.81, bed_unevenness 0.3 mm, seed 14) settles, snaps through its free play at
1.4-2.1 deg (its top moves ~4.3 mm, motion measure 9.5 mm), then stands until it overturns near
the rigid limit atan(0.05 / 0.105) = 25.5 deg.  Before the fix the constant-rate tilt read
lambda 0 (confirmed at frame 0: the reference was the pose before settling) and the
quasi-static tilt 0.043 (a relaxation that moved 5.03 mm taken for the loss of equilibrium).
"""

from pathlib import Path

import numpy as np
import pytest
import yaml

from dem.case import parse_case
from dem.collapse import REST_TIME, CollapseDetector
from postprocess.ensemble import aggregate, realisation_scalars

ROOT = Path(__file__).resolve().parents[1]
IDENT = np.array([1.0, 0.0, 0.0, 0.0])
RATE = 2.0  # deg/s


def _feed(det, t, x, v, n=1):
    """One frame: block 0 at x (m) along x with speed v (m/s), the others at rest."""
    pos = np.zeros((n, 3))
    vel = np.zeros((n, 3))
    pos[0, 0], vel[0, 0] = x, v
    return det.update(t, RATE * t, pos, np.tile(IDENT, (n, 1)), vel, np.zeros((n, 3)))


def _reseat_then_collapse(t):
    """A block that slips 9 mm between 1.0 and 1.3 s (a re-seating: constant speed 30 mm/s,
    then at rest), and from 12 s on slides off with a = 0.5 m/s2 (the collapse)."""
    x, v = 0.0, 0.0
    if 1.0 < t <= 1.3:
        x, v = 0.03 * (t - 1.0), 0.03
    elif t > 1.3:
        x = 0.009
    if t > 12.0:
        x, v = 0.009 + 0.25 * (t - 12.0) ** 2, 0.5 * (t - 12.0)
    return x, v


def test_a_reseating_is_not_a_collapse_and_the_onset_is_read_after_it():
    det = CollapseDetector(None, None, np.full(1, 0.05))
    for k in range(1400):
        t = 0.01 * k
        if _feed(det, t, *_reseat_then_collapse(t)):
            break
    res = det.result()
    assert res["detected"] and res["onset_resolved"]
    # the block is at rest until 12 s; the first frame at >= 1 mm/s is 12.01 s (a = 0.5 m/s2
    # gives 5 mm/s there), so the onset frame is 12.00 s, angle 24.0 deg
    assert res["onset_time_s"] == pytest.approx(12.0)
    assert res["load_factor"] == pytest.approx(np.tan(np.radians(RATE * 12.0)))
    assert res["onset_bracket_deg"] == pytest.approx([24.0, 24.02])
    (rs,) = res["reseats"]
    assert rs["candidate_time_s"] == pytest.approx(1.17, abs=0.011)  # 5 mm at 30 mm/s
    # at rest from 1.31 s on; the new equilibrium is accepted REST_TIME later
    assert rs["rest_time_s"] == pytest.approx(1.31 + REST_TIME, abs=0.011)
    assert res["reference_time_s"] == rs["rest_time_s"]


def test_the_reference_is_the_first_frame_fed_not_the_built_pose():
    """A scene that settled 4-6 mm away from its built pose (the column's bricks 2 and 3) and
    then stands: no collapse."""
    built = np.zeros((3, 3))
    settled = built + [[0.0, 0.0, -0.001], [0.0, 0.004, -0.001], [0.0, 0.0056, -0.001]]
    from dem.case.loadings import CollapseSpec
    from dem.run.build import scene_from_case

    case = parse_case(_column(rate=2.0))
    scene = scene_from_case(case)
    det = CollapseDetector.for_scene(scene, CollapseSpec())
    zero = np.zeros((3, 3))
    for k in range(100):
        assert not det.update(0.01 * k, 0.02 * k, settled, np.tile(IDENT, (3, 1)), zero, zero)
    assert not det.result()["detected"]
    # the old reference (the built pose) would have read 5.6 mm >= confirm at frame 0
    assert np.abs(settled - built).sum(axis=1).max() >= 5e-3


def test_an_onset_in_the_first_frame_interval_is_unresolved_not_lambda_zero():
    """At 2000 deg/s and 0.01 s a frame the table turns 20 deg a frame: a block at rest at
    frame 0 and sliding at frame 1 has its onset somewhere in 0-20 deg."""
    det = CollapseDetector(None, None, np.full(1, 0.05))
    for k in range(30):
        t = 0.01 * k
        x, v = (0.0, 0.0) if k == 0 else (0.004 * k * k, 0.8 * k)
        pos = np.array([[x, 0.0, 0.0]])
        if det.update(t, 2000.0 * t, pos, IDENT[None], np.array([[v, 0, 0]]), np.zeros((1, 3))):
            break
    res = det.result()
    assert res["detected"] and not res["onset_resolved"]
    assert res["load_factor"] is None and res["angle_deg"] is None
    assert "first frame" in res["onset_note"]
    assert res["onset_bracket_deg"] == pytest.approx([0.0, 20.0])


def test_the_ensemble_leaves_an_unresolved_onset_out_of_lambda():
    def rec(lam, resolved=True):
        col = {"detected": True, "load_factor": lam if resolved else None,
               "angle_deg": 25.0 if resolved else None, "onset_resolved": resolved,
               "onset_note": None if resolved else "unresolved"}
        return {"status": "ok", "summary": {"collapse": col}}

    rows = [{"seed": s, **realisation_scalars(r)} for s, r in
            enumerate([rec(0.47), rec(0.48), rec(None, resolved=False)])]
    agg = aggregate(rows)
    assert agg["statistics"]["lambda"]["n"] == 2
    assert agg["statistics"]["lambda"]["mean"] == pytest.approx(0.475)
    assert agg["n_onset_unresolved"] == 1 and agg["onset_unresolved_seeds"] == [2]


def _column(**loading):
    data = yaml.safe_load((ROOT / "cases/tilt/column-3-uneven.yaml").read_text())
    data["loading"] = {"type": "tilt", "axis": "x", **loading}
    return data


def test_the_uneven_column_reseats_without_collapsing(tmp_path):
    """The user's column tilted at 2 deg/s up to 4 deg: it settles, re-seats at ~2 deg and is
    standing at 4 deg (the rigid column overturns at 25.5 deg)."""
    from dem.run.loop import run_case

    data = _column(rate=2.0, max_angle=40.0)
    data["run"] = {"duration": 2.0, "output_interval": 0.01, "vtk": False}
    res = run_case(parse_case(data))
    col = res.summary["collapse"]
    assert not col["detected"], col
    assert len(col["reseats"]) >= 1
    assert 1.0 <= col["reseats"][0]["candidate_angle_deg"] <= 3.0
    assert res.summary["settling"]["at_rest"]


def test_the_uneven_column_quasi_static_stands_past_its_reseating(tmp_path):
    """Quasi-static, 0 to 4 deg by 1 deg: every angle is in equilibrium (one of them after a
    re-seating of more than collapse.confirm), not lambda = tan(2.44 deg) = 0.043."""
    from dem.run.loop import run_case

    data = _column(method="quasi_static", max_angle=4.0)
    data["run"] = {"duration": 20.0, "output_interval": 0.01, "vtk": False}
    res = run_case(parse_case(data))
    col = res.summary["collapse"]
    assert not col["detected"], col
    assert col["note"] == "max_angle reached in equilibrium"
    assert [a["equilibrium"] for a in col["angles"]] == [True] * len(col["angles"])
    assert any(a["why"] == "re-seated" for a in col["angles"])
