"""The quasi-static tilt and the rigid-joint option against rigid-block
statics: a block slides at atan(mu) and tips at atan(b/h); a small wall's lambda agrees with a
constant-rate run ten times slower than the default.

Tolerances: with ``normal_stiffness: rigid`` the elastic offset of a block's tipping load factor
is at most 0.5 % (dem/compliance.py), 0.09 deg at atan(1/2); the bisection brackets the limit to
``quasi_static.resolution`` (0.05 deg) and the tolerance on the unbalanced-force ratio (1e-4)
lets an angle ~0.006 deg above a sliding limit pass as equilibrium: 0.2 deg holds all three.
"""

from __future__ import annotations

import math

import numpy as np
import pytest

from dem.case import parse_case
from dem.compliance import elastic_offset
from dem.run import run_case
from dem.run.build import joint_law, step_options


def _block_case(size, mu, start, collapse=None, **qs):
    return parse_case({
        "name": "qs-block",
        "scene": {"blocks": [{"size": size, "position": [0, 0, size[2] / 2],
                              "density": 2000.0}]},
        "material": {"friction": mu, "normal_stiffness": "rigid"},
        "loading": {"type": "tilt", "axis": "x", "method": "quasi_static", "start_angle": start,
                    "quasi_static": {"max_relax_time": 0.3, **qs},
                    **({"collapse": collapse} if collapse else {})},
        "run": {"duration": 20.0, "vtk": False, "snapshot": False},
    })


def test_a_block_slides_at_atan_mu():
    res = run_case(_block_case([0.2, 0.2, 0.1], 0.5, 24.0))
    col = res.summary["collapse"]
    assert col["detected"] and col["method"] == "quasi_static"
    assert col["angle_deg"] == pytest.approx(math.degrees(math.atan(0.5)), abs=0.2)
    assert col["failed_angle_deg"] - col["angle_deg"] <= 0.05 + 1e-12
    # the dynamic continuation (1 s at the first failing increment, 27 deg) moved it
    assert col["n_moved"] == 1 and col["dynamic_max_motion_m"] >= 0.005
    assert col["dynamic_turns"] == 0  # 4 cm in that second: no further turn


def test_a_collapse_that_creeps_keeps_the_table_turning_until_the_mechanism_shows():
    """A block whose sliding limit atan(mu) = 26.5 deg lies just below the first failing
    increment (27 deg): there it accelerates at g (sin 27 - mu cos 27) = 0.096 m/s2 and slides
    about 1.2 cm in the continuation's first 0.5 s (collapse.after), less than collapse.stop
    (3 cm): too little to show a mechanism.  The table then turns on by the increment (28 deg:
    0.29 m/s2) until the block has slid collapse.stop.  lambda is the search's, unchanged."""
    mu = math.tan(math.radians(26.5))
    res = run_case(_block_case([0.2, 0.2, 0.1], mu, 26.0, collapse={"after": 0.5}))
    col = res.summary["collapse"]
    assert col["detected"]
    # the search's bracket lies below the first failing increment (with max_relax_time 0.3 s
    # the REST_MOTION rule passes a creep of < 0.5 mm: here 26.75 deg)
    assert 26.5 - 0.05 <= col["angle_deg"] < 27.0
    assert col["dynamic_angle_deg"] == 27.0
    assert col["dynamic_turns"] == 1 and col["dynamic_end_angle_deg"] == 28.0
    assert col["dynamic_max_motion_m"] >= 0.03


def test_a_block_tips_at_atan_b_over_h_with_rigid_joints():
    res = run_case(_block_case([0.1, 0.1, 0.2], 0.8, 24.0))
    col = res.summary["collapse"]
    joints = res.summary["joints"]
    assert joints["elastic_offset"]["block"]["relative"] == pytest.approx(0.005, rel=1e-6)
    assert joints["normal_stiffness_Pa_m"] > 1e11  # far above the default 5e9
    assert col["detected"]
    assert col["angle_deg"] == pytest.approx(math.degrees(math.atan(0.5)), abs=0.2)


def test_the_elastic_offset_matches_docs_engine_section_5():
    """2000 kg/m^3, b/h = 1/3: 0.020 at kn = 5e9 and 0.0033 at 1e12 (docs/engine.md)."""
    from dem.scene import Scene

    s = Scene(size=[[0.1, 0.1, 0.3]], position=[[0, 0, 0.15]], quat=[[1, 0, 0, 0]],
              mass=[2000 * 0.003], fixed=[False], velocity=[[0, 0, 0]],
              angular_velocity=[[0, 0, 0]], group=[0], course=[-1])
    for kn, absolute in ((5e9, 0.020), (1e12, 0.0034)):
        rel = elastic_offset(s, kn)["block"]["relative"]
        assert rel / 3 == pytest.approx(absolute, rel=0.03)


def test_save_and_restore_give_the_same_trajectory():
    """restore_point puts back everything that evolves: the same steps from it give the same
    state, bit for bit (the bisection relies on it)."""
    from dem.builders import build_wall
    from dem.case import Material, SolverSpec
    from dem.engine import Simulation

    sim = Simulation(build_wall("small", length=2, courses=2), joint_law(Material(friction=0.6)),
                     step_options(SolverSpec(mode="serial")))
    g = np.array([0.0, 2.0, -9.6])
    loads = lambda t: (np.tile(g, (len(t), 1)), np.zeros((len(t), 3)))  # noqa: E731
    sim.advance(300, loads)
    point = sim.save_point()
    sim.advance(500, loads)
    first = {k: a.copy() for k, a in sim.state.arrays().items()}
    energy = sim.control.energy()
    sim.restore_point(point)
    sim.advance(500, loads)
    for k, a in sim.state.arrays().items():
        assert np.array_equal(a, first[k]), k
    assert sim.control.energy() == energy


@pytest.mark.slow
def test_a_small_wall_agrees_with_a_tilt_ten_times_slower():
    """3 x 3 small-brick wall (test_tilt_run's): the quasi-static lambda within 1 % of a
    constant-rate run at 0.2 deg/s (a tenth of the default rate)."""
    base = {
        "name": "tilt-3x3",
        "scene": {"wall": {"brick": "small", "length": 3, "courses": 3}},
        "material": {"friction": 0.81, "base_friction": 1.5},
        "run": {"duration": 40.0, "output_interval": 0.01, "vtk": False, "snapshot": False},
    }
    qs = parse_case({**base, "loading": {"type": "tilt", "axis": "y", "method": "quasi_static",
                                          "start_angle": 30.0, "max_angle": 45.0}})
    slow = parse_case({**base, "loading": {"type": "tilt", "axis": "y", "rate": 0.2,
                                            "start_angle": 35.0, "start_time": 0.5,
                                            "max_angle": 45.0, "collapse": {"after": 0.2}}})
    lam_qs = run_case(qs).summary["collapse"]["load_factor"]
    lam_slow = run_case(slow).summary["collapse"]["load_factor"]
    assert lam_qs == pytest.approx(lam_slow, rel=0.01)


def test_dem_post_of_a_quasi_static_run_keeps_its_collapse(tmp_path):
    """The search is not in the frames, so dem post keeps the run's collapse (lambda, bracket)
    and re-reads the mechanism from frames.npz."""
    import json

    from typer.testing import CliRunner

    from dem_cli.app import app
    from dem_cli.commands.run import RUN_ANALYSES

    run_case(_block_case([0.2, 0.2, 0.1], 0.5, 25.0), tmp_path, analyses=RUN_ANALYSES)
    ran = json.loads((tmp_path / "summary.json").read_text())
    r = CliRunner().invoke(app, ["post", str(tmp_path)])
    assert r.exit_code == 0, r.output
    post = json.loads((tmp_path / "analysis.json").read_text())
    assert post["collapse"]["load_factor"] == ran["collapse"]["load_factor"]
    assert post["collapse"]["method"] == "quasi_static"
    assert post["mechanism"] == ran["mechanism"]
