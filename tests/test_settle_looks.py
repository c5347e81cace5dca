"""The settle phase's looks (dem.run.settle): the unbalanced-force ratio, the one look quantity
that copies the contacts' wrenches back from a device, is computed only where it can decide
(every block below REST_SPEED), and the summary still reports the last look's ratio."""

from __future__ import annotations

import numpy as np

from dem.case import Case
from dem.run.build import build
from dem.run.settle import REST_SPEED, TOLERANCE, settle

WALL = {"name": "settling-wall", "scene": {"wall": {"brick": "small", "length": 3, "courses": 4}},
        "material": {"friction": 0.81},
        "imperfections": {"bed_unevenness": 1e-4, "face_shape": "planar", "seed": 0},
        "loading": {"type": "none"}, "run": {"duration": 0.01}}


def _settled(max_steps):
    built = build(Case.model_validate(WALL))
    calls = []
    ratio = built.sim.unbalanced_force_ratio
    built.sim.unbalanced_force_ratio = lambda g: calls.append(built.sim.step_count) or ratio(g)
    out = settle(built.sim, built.loading, 0.0, max_steps=max_steps)
    g0 = built.loading.gravity(np.array([0.0]))[0]
    return out, calls, ratio(g0), built.sim


def test_a_look_at_moving_blocks_skips_the_ratio_and_the_summary_has_the_last_one():
    out, calls, now, sim = _settled(400)  # cut while the blocks still fall onto their beds
    assert not out["at_rest"] and out["final_speed_m_s"] >= REST_SPEED
    assert calls == [sim.step_count]  # none at the two moving looks; once, after, for the summary
    assert out["final_unbalanced_force_ratio"] == now > TOLERANCE


def test_a_wall_that_comes_to_rest_is_judged_by_its_ratio_at_the_calm_looks():
    out, calls, now, sim = _settled(None)
    assert out["at_rest"] and out["final_speed_m_s"] < REST_SPEED
    assert out["final_unbalanced_force_ratio"] == now < TOLERANCE
    assert len(calls) >= 3 and calls[-1] == sim.step_count  # at least the three calm looks
    assert len(calls) < out["steps"] // 200  # and not at the looks where blocks still moved
