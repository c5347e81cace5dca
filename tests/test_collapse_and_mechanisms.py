"""Collapse detection and mechanism identification on planted block motions."""

import numpy as np
import pytest
from scipy.spatial.transform import Rotation

from dem import quaternion
from dem.builders import Wing, build_facade, build_wall
from dem.collapse import CollapseDetector
from dem.loading import Tilt
from postprocess.mechanisms import crack_shape, in_plane_mechanism, out_of_plane_mechanism

IDENT = np.array([1.0, 0.0, 0.0, 0.0])


def _quats(rotvecs):
    return quaternion.from_rotation(Rotation.from_rotvec(rotvecs))


def test_tilt_angle_schedule_with_steps_and_holds():
    tilt = Tilt([0, 0, -9.81], "y", 2.0, 10.0, step_deg=1.0, hold_s=1.5)
    # each step: 0.5 s turning at 2 deg/s, then 1.5 s held
    t = np.array([0.25, 0.5, 1.9, 2.25, 100.0])
    assert np.allclose(tilt.angle(t), [0.5, 1.0, 1.0, 1.5, 10.0])
    assert np.allclose(tilt.load_direction, [1, 0, 0])  # about +y the load points to +x
    smooth = Tilt([0, 0, -9.81], "y", 2.0, 40.0, start_angle_deg=20.0, start_time_s=1.0)
    assert np.allclose(smooth.angle([0.0, 0.5, 1.0, 2.0]), [0.0, 10.0, 20.0, 22.0])


def test_detector_reads_the_onset_not_the_visible_collapse():
    n = 3
    pos0, quat0 = np.zeros((n, 3)), np.tile(IDENT, (n, 1))
    det = CollapseDetector(pos0, quat0, np.full(n, 0.05), onset_speed=1e-3, confirm=5e-3,
                           after=0.2, stop=0.03)
    zero = np.zeros((n, 3))
    stopped_at = None
    for k in range(200):
        t = 0.01 * k
        pos, vel = pos0.copy(), zero.copy()
        pos[2, 0] = 1e-5  # elastic creep-free resting block
        if 0.2 < t < 0.3:  # block 1 slips 2 mm early on and stops: not the collapse
            pos[1, 0], vel[1, 0] = 0.02 * (t - 0.2), 0.02
        elif t >= 0.3:
            pos[1, 0] = 0.002
        if t > 1.0:  # block 1 starts to accelerate at t = 1 s (angle 10 deg), a = 2 m/s2
            pos[1, 0] = 0.002 + (t - 1.0) ** 2
            vel[1, 0] = 2.0 * (t - 1.0)
        if det.update(t, 10.0 * t, pos, quat0, vel, zero):
            stopped_at = t
            break
    res = det.result()
    assert res["detected"] and res["first_moving_blocks"] == [1]
    # onset read while the block was still slower than 1 mm/s (0.0005 s after it started here,
    # i.e. at the last frame before 1 s + 1 frame), although 5 mm of motion came at 1.06 s, and
    # not at the early slip
    assert 0.99 <= res["onset_time_s"] <= 1.0 + 1e-9
    assert res["load_factor"] == pytest.approx(np.tan(np.radians(10.0 * res["onset_time_s"])))
    assert res["confirm_time_s"] >= 1.05  # 5 mm since the start: 2 mm slip + 3 mm after 1 s
    assert stopped_at is not None and stopped_at <= res["confirm_time_s"] + 0.2 + 1e-9


def test_detector_ignores_a_small_slip_that_stops():
    pos0, quat0 = np.zeros((1, 3)), np.tile(IDENT, (1, 1))
    det = CollapseDetector(pos0, quat0, np.full(1, 0.05))
    for k in range(100):
        pos = np.array([[min(0.002, 0.001 * k), 0.0, 0.0]])  # slips 2 mm and stops
        vel = np.array([[0.1 if k < 2 else 0.0, 0.0, 0.0]])
        assert not det.update(0.01 * k, float(k), pos, quat0, vel, np.zeros((1, 3)))
    assert not det.result()["detected"]


def _planted_wall():
    scene = build_wall("small", length=5, courses=7)
    pos0, quat0 = scene.position.copy(), scene.quat.copy()
    # the portion above a stepped crack that starts at the leeward (+x) bottom brick and rises
    # towards the windward side at the bond angle: tan(alpha) = s/h = 1.5 from the vertical
    x_lee = (pos0[:, 0] + 0.5 * scene.size[:, 0]).max()
    h = 0.035
    edge = pos0[:, 0] - 0.5 * scene.size[:, 0]
    moving = edge >= x_lee - 0.105 - scene.course * h * 1.5 - 1e-9
    return scene, pos0, quat0, moving


def test_planted_sliding_portion_is_sliding_with_bond_angle_crack():
    scene, pos0, quat0, moving = _planted_wall()
    pos = pos0.copy()
    pos[moving, 0] += 0.02  # rigid translation along the load
    res = in_plane_mechanism(scene, pos0, quat0, pos, quat0, moving, [1, 0, 0], [0, 1, 0],
                             stagger=0.0525, course_height=0.035)
    assert res["mechanism"] == "sliding"
    assert res["crack"]["rises_towards_windward"]
    assert res["crack"]["angle_from_vertical_deg"] == pytest.approx(56.3, abs=4.0)


def test_planted_overturning_portion_is_overturning():
    scene, pos0, quat0, moving = _planted_wall()
    toe = np.array([pos0[:, 0].max() + 0.0525, 0.0, 0.0])
    theta = 0.08  # rad, about +y: the top moves towards +x (leeward)
    rot = Rotation.from_rotvec([0.0, theta, 0.0])
    pos, quat = pos0.copy(), quat0.copy()
    pos[moving] = toe + rot.apply(pos0[moving] - toe)
    quat[moving] = _quats(np.tile([0.0, theta, 0.0], (moving.sum(), 1)))
    res = in_plane_mechanism(scene, pos0, quat0, pos, quat, moving, [1, 0, 0], [0, 1, 0])
    assert res["mechanism"] == "overturning"
    assert res["overturning_mass_fraction"] > 0.8


def test_planted_mixed_portion_is_mixed():
    scene, pos0, quat0, moving = _planted_wall()
    pos, quat = pos0.copy(), quat0.copy()
    lee = moving & (pos0[:, 0] > pos0[:, 0].max() - 0.06)  # the leeward column overturns
    pos[moving, 0] += 0.02
    quat[lee] = _quats(np.tile([0.0, 0.2, 0.0], (lee.sum(), 1)))
    res = in_plane_mechanism(scene, pos0, quat0, pos, quat, moving, [1, 0, 0], [0, 1, 0])
    assert res["mechanism"] == "mixed"
    assert res["overturning_columns"] == 1


def _facade(left, right):
    return build_facade("large", 5, 9, left=Wing(3, left), right=Wing(3, right))


def _turning(scene, rule, theta=0.02):
    """Quaternions with the bricks selected by rule(group, x, course) turned by theta about +x
    (the overturning axis of a facade loaded towards -y: its top moves outwards)."""
    names = scene.group_names
    g = np.array([names[i] for i in scene.group])
    sel = rule(g, scene.position[:, 0], scene.course)
    quat = np.tile(IDENT, (scene.n_blocks, 1))
    quat[sel] = _quats(np.tile([theta, 0.0, 0.0], (sel.sum(), 1)))
    return quat


def test_out_of_plane_a_b1_d_b2_g_from_planted_patterns():
    sc = _facade("poor", "poor")
    fac_x = sc.position[sc.group == sc.group_names.index("facade"), 0]
    x0, x1 = fac_x.min(), fac_x.max()
    u = lambda x: (x - x0) / (x1 - x0)  # noqa: E731  0 at the left corner, 1 at the right
    cases = {
        "A": lambda g, x, c: (g == "facade") & (c >= 6),
        "B1": lambda g, x, c: ((g == "facade") & (c >= 5)) | ((g == "wing-right") & (c >= 5)
                                                              & (x > x1 - 0.2)),
        "D": lambda g, x, c: ((g == "facade") & (c >= 2 + 6 * (1 - u(x)))) | (
            (g == "wing-left") & (c >= 7)),
        "B2": lambda g, x, c: ((g == "facade") & (c >= 6)) | ((g != "facade") & (c >= 7)),
        "G": lambda g, x, c: ((g == "facade") & (c >= 8 - 7 * np.sin(np.pi * np.clip(u(x), 0, 1))))
        | ((g != "facade") & (c >= 8)),
    }
    quat0 = np.tile(IDENT, (sc.n_blocks, 1))
    for expected, rule in cases.items():
        res = out_of_plane_mechanism(sc, sc.position, quat0, sc.position, _turning(sc, rule),
                                     [0.0, -1.0, 0.0])
        assert res["mechanism"] == expected, (expected, res)
    res = out_of_plane_mechanism(sc, sc.position, quat0, sc.position, _turning(sc, cases["A"]),
                                 [0.0, -1.0, 0.0])
    assert res["collapsed_courses"] == 3 and res["crack_shape"] == "horizontal"
    # bricks turning the other way (wings tilting inwards) do not join the collapse
    q = _turning(sc, cases["A"])
    wing = np.array([sc.group_names[i].startswith("wing") for i in sc.group])
    q[wing] = _quats(np.tile([-0.005, 0.0, 0.0], (wing.sum(), 1)))
    assert out_of_plane_mechanism(sc, sc.position, quat0, sc.position, q,
                                  [0.0, -1.0, 0.0])["mechanism"] == "A"


@pytest.mark.parametrize("depth, shape", [
    ([9, 9, 9, 9, 9], "horizontal"), ([8, 9, 9, 9, 8], "horizontal"),
    # the diagonal cracks of results/tilt (poor-good, poor-strong large facades): D
    ([9, 9, 9, 8, 5], "diagonal"), ([9, 9, 9, 8, 6], "diagonal"), ([2, 4, 6, 8, 9], "diagonal"),
    # symmetric arches (the perfect 10 x 21 and 5 x 9 strong-strong facades): G
    ([8, 12, 14, 15, 15, 15, 15, 14, 12, 8], "arch"), ([6, 8, 9, 8, 6], "arch"),
    # an asymmetric arch (bed-0.1-planar 10 x 21, seed 0): its ends differ by 6 courses, its
    # deepest columns lie 8 below the deeper end: not a crack from one edge to the other
    ([2, 12, 14, 15, 15, 16, 16, 14, 12, 8], "arch"),
])
def test_crack_shape_tells_a_diagonal_from_an_asymmetric_arch(depth, shape):
    assert crack_shape(depth) == shape
    assert crack_shape(depth[::-1]) == shape          # mirror image, same shape
