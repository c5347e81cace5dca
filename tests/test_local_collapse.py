"""Local collapse and the survival verdict (postprocess.survival).

Closed forms first (the toppling angle of a rigid brick, atan(b / h); its height), then built
scenes run in the engine: a top corner brick knocked off, a top course sliding out, a whole
facade overturning.
"""

import numpy as np
import pytest
from scipy.spatial.transform import Rotation

from dem import quaternion
from dem.builders import Wing, build_facade
from postprocess.survival import (COLLAPSE_SHARE, count_verdicts, cycle_counter, survival,
                                  toppled, vertical_extent)

SMALL = np.array([0.105, 0.05, 0.035])  # small brick, m (thesis Chapter 3)


def _q(rotvec):
    return quaternion.from_rotation(Rotation.from_rotvec(np.atleast_2d(rotvec)))


@pytest.mark.parametrize("axis, b", [(0, SMALL[1]), (1, SMALL[0])])
def test_toppling_angle_is_atan_b_over_h(axis, b):
    """A brick on its bed turned about a horizontal body axis topples past atan(b / h), b the
    bed's side across the axis, h its height: 55.0 deg about the long axis, 71.6 deg about the
    short one."""
    crit = np.arctan(b / SMALL[2])
    e = np.eye(3)[axis]
    q0 = _q([0.0, 0.0, 0.0])
    for theta, expected in ((crit - 1e-6, False), (crit + 1e-6, True), (-crit - 1e-6, True),
                            (0.5 * crit, False), (np.pi, True)):
        assert toppled(SMALL[None], q0, _q(theta * e))[0] == expected, theta
    # the same for a brick laid on its side (its bed is then the L x H face, height W)
    side = Rotation.from_rotvec([np.pi / 2, 0.0, 0.0])
    q0s = quaternion.from_rotation(side).reshape(1, 4)
    h = vertical_extent(SMALL[None], q0s)[0]
    assert h == pytest.approx(SMALL[1])
    crit_side = np.arctan(SMALL[2] / SMALL[1])  # turned about the long axis
    for theta, expected in ((crit_side - 1e-6, False), (crit_side + 1e-6, True)):
        q = quaternion.from_rotation(Rotation.from_rotvec([theta, 0, 0]) * side).reshape(1, 4)
        assert toppled(SMALL[None], q0s, q)[0] == expected


def test_cycle_counter_counts_from_one_and_stops_after_the_shaking():
    class Motion:
        frequency, t_end = 2.0, 5.0  # 10 cycles

    class Loading:
        motion = Motion()

    cyc = cycle_counter(Loading())
    assert [cyc(t) for t in (0.0, 0.49, 0.51, 4.99, 5.0, 5.1)] == [1, 1, 2, 10, 10, None]
    assert cycle_counter(None)(1.0) is None


def _run(scene, duration, every=0.01):
    from dem.case import parse_case
    from dem.engine import Simulation
    from dem.run.build import joint_law, step_options
    from tests.engine_helpers import constant_loads, record

    case = parse_case({"name": "t", "scene": {"blocks": [{"size": [0.1, 0.1, 0.1],
                                                          "position": [0, 0, 0.05], "mass": 1.0}]},
                       "material": {"friction": 0.81}, "run": {"duration": duration}})
    sim = Simulation(scene, joint_law(case.material), step_options(case.solver))
    t, pos, quat, _ = record(sim, constant_loads(), duration, every)
    return t, pos, quat


def _facade_with_wings():
    """A small-brick facade 3 bricks long, 4 courses, with 1-brick wings on both sides (groups
    facade, wing-left, wing-right), on the table."""
    return build_facade("small", 3, 4, left=Wing(1, "strong"), right=Wing(1, "strong"))


def _top(scene, group):
    g = scene.group_names.index(group)
    sel = scene.group == g
    return sel & (scene.course == scene.course[sel].max())


def test_a_top_corner_brick_knocked_off_is_a_local_collapse():
    scene = _facade_with_wings()
    top = np.flatnonzero(_top(scene, "facade"))
    corner = int(top[np.argmin(scene.position[top, 0])])  # the left end: touches the left wing
    scene.velocity[corner] = [0.0, -1.5, 0.3]  # knocked out of the facade (front is -y)
    t, pos, quat = _run(scene, 0.6)
    res = survival(scene, t, pos, quat)
    assert res["verdict"] == "local collapse"
    assert [b["block"] for b in res["fallen"]] == [corner]
    b = res["fallen"][0]
    assert b["wall"] == "facade" and b["corner"] == "wing-left"
    assert b["course"] == int(scene.course.max())
    # it fell off a wall 4 courses high: the drop by its own height (35 mm) comes after about
    # sqrt(2 h / g) with the upward kick, within the run
    assert 0.05 < b["time_s"] < 0.6
    assert res["by_wall"]["facade"]["n_at_corners"] == 1


def test_a_top_course_sliding_out_is_a_local_collapse_of_that_course():
    scene = _facade_with_wings()
    top = _top(scene, "facade")
    scene.velocity[top] = [0.0, -1.2, 0.0]  # the whole top course slides out of the facade
    t, pos, quat = _run(scene, 0.6)
    res = survival(scene, t, pos, quat)
    assert res["verdict"] == "local collapse"
    fallen = {b["block"] for b in res["fallen"]}
    assert fallen == set(np.flatnonzero(top).tolist())
    assert res["by_wall"]["facade"]["courses"] == [int(scene.course.max())]
    assert res["by_wall"]["facade"]["share"] < COLLAPSE_SHARE


def test_a_whole_facade_overturning_is_a_collapse():
    """The facade (no wings) turned about its front bottom edge at omega = 6 rad/s: as a rigid
    body it needs omega^2 > 2 g dz / ((H^2 + t^2) / 3) = 11.5 (rad/s)^2 to pass over the edge
    (H = 0.14 m, t = 0.05 m, dz = sqrt((H/2)^2 + (t/2)^2) - H/2 = 4.3 mm); 36 is three times
    that, so it overturns whatever its dry joints do."""
    scene = build_facade("small", 3, 4)
    pivot = np.array([0.0, -0.025, 0.0])
    w = np.array([-6.0, 0.0, 0.0])  # the top moves to -y
    scene.angular_velocity[:] = w
    scene.velocity[:] = np.cross(w, scene.position - pivot)
    t, pos, quat = _run(scene, 0.8)
    res = survival(scene, t, pos, quat)
    assert res["verdict"] == "collapse"
    assert res["by_wall"]["facade"]["share"] >= COLLAPSE_SHARE
    assert count_verdicts([res["verdict"], "standing", None]) == {
        "standing": 1, "local collapse": 0, "collapse": 1}


def test_a_wall_at_rest_is_standing():
    scene = _facade_with_wings()
    t, pos, quat = _run(scene, 0.2)
    res = survival(scene, t, pos, quat)
    assert res["verdict"] == "standing" and res["n_fallen"] == 0 and res["fallen"] == []


def test_sweeps_and_ensembles_count_the_verdicts():
    from postprocess.ensemble import aggregate, realisation_scalars
    from postprocess.sweep import survival_by_point

    def surv(verdict, n, cycle):
        return {"verdict": verdict, "n_fallen": n, "first_fall_cycle": cycle}

    points = [{"frequency_hz": 2.5, "status": "ok", "survival": surv("local collapse", 2, 16)},
              {"frequency_hz": 1.8, "status": "ok", "survival": surv("standing", 0, None)},
              {"frequency_hz": 3.0, "status": "failed"},
              {"frequency_hz": 3.5, "status": "ok"}]  # analysed before the verdict existed: none
    agg = survival_by_point(points)
    assert agg["per_point"] == [[1.8, "standing", 0, None], [2.5, "local collapse", 2, 16]]
    assert agg["counts"] == {"standing": 1, "local collapse": 1, "collapse": 0}
    assert survival_by_point(points[2:]) is None

    recs = [{"status": "ok", "post": {"analysis_status": "ok", "collapse_suspected": False,
                                      "survival": surv(v, n, None)}}
            for v, n in (("standing", 0), ("local collapse", 3), ("collapse", 40))]
    rows = [{"seed": k, **realisation_scalars(r)} for k, r in enumerate(recs)]
    # the centre check said standing for all three; the bricks say otherwise
    assert [r["survived"] for r in rows] == [True, False, False]
    out = aggregate(rows)
    assert out["survival"] == {"standing": 1, "local collapse": 1, "collapse": 1}
    assert out["survived"] == 1 and out["collapsed"] == 2
