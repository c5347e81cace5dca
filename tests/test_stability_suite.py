"""Stability suite of hard cases: run with ``pytest -m stability`` (about 7 min on the
2-core machine).

Every case must finish without NaN (the engine stops a run on NaN or runaway speed), without
energy beyond what the loads supplied (kinetic + elastic - initial - work of gravity and of the
table <= 1e-3 of the work supplied; the measured residual of the scheme on steady contacts is
~1e-5 of it), without blocks passing through each other (deepest contact penetration < 2 mm; a
small brick is 35 mm thick, static joints close by ~1 um; where bricks fall onto others (drops,
collapses) the bound is a quarter of the brick thickness, IMPACT below, see
test_bricks_dropped_from_height) and without blocks sinking into the table.  A case that cannot satisfy this must fail loudly (an InstabilityError naming the block),
never finish with garbage.
"""

import numpy as np
import pytest

from dem import quaternion
from dem.case import parse_case
from dem.run import run_case

pytestmark = pytest.mark.stability

BRICK = [0.105, 0.05, 0.035]
M = 0.336
IMPACT = 0.25 * 0.035  # penetration bound where bricks fall onto others (measured 2.7-3.8 mm)


def _run(case_dict, max_penetration=2e-3):
    case_dict.setdefault("run", {})
    case_dict["run"].setdefault("vtk", False)
    case_dict["run"].setdefault("snapshot", False)
    res = run_case(parse_case(case_dict))
    s = res.summary
    e = s["energy"]
    supplied = abs(e["work_gravity"]) + abs(e["work_base"])
    assert s["status"] == "ok"
    assert e["gain"] <= 1e-3 * supplied + 1e-9, e
    assert s["max_penetration_m"] < max_penetration, s["max_penetration_m"]
    # nothing below the table: lowest corner of every block
    q = res.quat[-1]
    R = quaternion.matrices(q)
    half = 0.5 * res.scene.size
    zmin = res.pos[-1, :, 2] - np.einsum("nk,nk->n", np.abs(R[:, 2, :]), half)
    assert zmin.min() > -max_penetration
    return res


def test_slender_column_of_30_bricks_leaning():
    """A 1.05 m column of bricks each shifted 1.5 mm further to +x: it leans and may fall."""
    blocks = [{"size": BRICK, "position": [0.0015 * k, 0, (k + 0.5) * 0.035], "mass": M}
              for k in range(30)]
    _run({"name": "column-30", "scene": {"blocks": blocks}, "material": {"friction": 0.81},
          "run": {"duration": 2.0, "output_interval": 0.01}})


def test_half_supported_end_brick_tips_and_falls():
    blocks = [{"size": BRICK, "position": [0, 0, 0.0175], "mass": M},
              {"size": BRICK, "position": [0.6 * 0.105, 0, 0.0525], "mass": M}]
    res = _run({"name": "end-brick", "scene": {"blocks": blocks}, "material": {"friction": 0.81},
                "run": {"duration": 1.5, "output_interval": 0.01}})
    # It tips about the support's edge until its far end meets the table: tilted by
    # asin(35 / 63) = 33.7 deg with its centre 8.8 mm lower (or more, if it slides off the edge)
    w = abs(res.quat[-1, 1, 0])
    assert np.degrees(2 * np.arccos(min(w, 1.0))) > 30.0
    assert res.pos[-1, 1, 2] < 0.0525 - 0.008


def test_wall_collapsing_into_a_debris_pile():
    """A 9 x 15 wall (0.525 m) thrown over by a 0.3 s table pulse of 5 m/s2 out of plane (its
    overturning threshold is ~0.14 g): it falls flat onto the level table and comes to rest.
    (A table tilted past the friction angle, as tried first, gives no pile: the bricks tumble
    down the incline for ever.)"""
    res = _run({"name": "debris", "scene": {"wall": {"brick": "small", "length": 9,
                                                      "courses": 15}},
                "material": {"friction": 0.81},
                "loading": {"type": "record", "time": [0.0, 0.3, 0.31], "ay": [5.0, 5.0, 0.0]},
                "run": {"duration": 2.0, "output_interval": 0.01}}, max_penetration=IMPACT)
    assert res.pos[-1, :, 2].max() < 0.1  # every brick down (measured: under 0.03 m)
    assert np.linalg.norm(res.vel[-1], axis=1).max() < 0.01  # the pile is at rest (1e-5 m/s)


def test_high_friction_wall_tilted_to_60_degrees():
    res = _run({"name": "mu-1.2-tilt-60", "scene": {"wall": {"brick": "small", "length": 5,
                                                              "courses": 7}},
                "material": {"friction": 1.2, "base_friction": 1.5},
                "loading": {"type": "tilt", "axis": "y", "rate": 20.0, "max_angle": 60.0,
                            "collapse": {"enabled": False}},
                "run": {"duration": 4.0, "output_interval": 0.01}}, max_penetration=IMPACT)
    assert np.abs(res.pos[-1] - res.pos[0]).max() > 0.05  # it collapsed


def test_very_stiff_joints_brick_dropped_on_wall():
    blocks = [{"size": BRICK, "position": [0.0, 0.0, 0.25], "rotation": [15, 25, 5], "mass": M}]
    _run({"name": "stiff", "scene": {"blocks": blocks, "wall": {"brick": "small", "length": 3,
                                                                  "courses": 3},
                                     "allow_floating": True},
          "material": {"friction": 0.81, "normal_stiffness": 1e11},
          "run": {"duration": 0.6, "output_interval": 0.01}})


def test_bricks_dropped_from_height():
    """Ten bricks dropped from 0.3 - 1 m with random orientations (impacts up to 4.5 m/s).
    A corner landing first closes a patch whose area grows like d^2, so the penetration reaches
    d ~ (2 m v^2 / (kn c))^(1/4) ~ 6 mm at kn = 5e9 Pa/m (c ~ 2): the bound here is a quarter of
    the 35 mm brick thickness, far from passing through (measured: 2.7 mm)."""
    rng = np.random.default_rng(7)
    blocks = [{"size": BRICK, "position": [0.03 * rng.standard_normal(), 0.03 *
                                           rng.standard_normal(), 0.3 + 0.08 * k],
               "rotation": rng.uniform(-60, 60, 3).tolist(), "mass": M} for k in range(10)]
    _run({"name": "drop", "scene": {"blocks": blocks, "allow_floating": True},
          "material": {"friction": 0.81}, "run": {"duration": 1.5, "output_interval": 0.01}},
         max_penetration=IMPACT)


def test_model_iii_at_resonance():
    """Model III at its characteristic frequency (2.4 Hz) with twice the test's acceleration."""
    _run({"name": "m3-resonance", "scene": {"box_model": {"model": "III"}},
          "material": {"friction": 0.81},
          "loading": {"type": "shake", "direction": [0, 1, 0], "frequency": 2.4,
                      "peak_acceleration": 2.46, "cycles": 5},
          "run": {"duration": 2.0, "output_interval": 0.02}})
