"""Resting walls do not creep; hard cases stay finite and never create energy.

Energy check: kinetic + elastic - initial <= work of gravity + work of the base (+ 0.1 % of the
gravity work for the explicit scheme's residual, measured at about 1e-5 of it on the resting
wall).  Interpenetration check: no contact point deeper than 1 mm (static joints compress by
about 1 um at the default stiffness).
"""

import numpy as np
import pytest

from engine_helpers import (ROUND_OFF_POS_M, ROUND_OFF_QUAT, constant_loads, make_sim,
                            rotation_angle, stretcher_wall)

BRICK = [0.105, 0.05, 0.035]
M_BRICK = 0.336


def _run_checked(sim, duration, every=0.01):
    """Advance, checking finiteness and the deepest contact along the way."""
    loads = constant_loads()
    deepest = 0.0
    n = max(1, int(round(every / sim.dt)))
    while sim.t < duration:
        sim.advance(n, loads)
        c = sim.contacts
        if c.n_pairs:
            mask = np.arange(c.depth.shape[1])[None, :] < c.npts[: c.n_pairs, None]
            deepest = max(deepest, float(c.depth[: c.n_pairs][mask].max(initial=0.0)))
        assert np.isfinite(sim.state.pos).all() and np.isfinite(sim.state.vel).all()
    return deepest


def _assert_energy_bounded(sim):
    e = sim.energy_report()
    assert e["gain"] <= 1e-3 * abs(e["work_gravity"]) + 1e-12, e


@pytest.mark.stability
def test_resting_stretcher_wall_does_not_creep():
    """9 x 15 stretcher bond, half bricks at the ends, small bricks, mu 0.81, 10 s at rest."""
    blocks = stretcher_wall(9, 15)
    assert len(blocks) == 142
    sim = make_sim(blocks, friction=0.81)
    loads = constant_loads()
    p0 = sim.state.pos[:142].copy()
    sim.advance(int(round(1.0 / sim.dt)), loads)  # elastic settling (~15 um at the top)
    p1 = sim.state.pos[:142].copy()
    sim.advance(int(round(9.0 / sim.dt)), loads)
    p10 = sim.state.pos[:142].copy()
    assert np.abs(p1 - p0).max() < 5e-5  # settling is elastic and small
    assert np.abs(p10[:, :2] - p0[:, :2]).max() < 1e-6  # no horizontal drift at all
    assert np.abs(p10 - p1).max() < 1e-6  # no creep after settling
    _assert_energy_bounded(sim)
    assert sim.kinetic_energy() < 1e-9


def test_column_of_twenty_bricks_stands():
    blocks = [{"size": BRICK, "position": [0.003 * (-1) ** k, 0, (k + 0.5) * 0.035],
               "mass": M_BRICK} for k in range(20)]
    sim = make_sim(blocks, friction=0.81)
    p0 = sim.state.pos[:20].copy()
    deepest = _run_checked(sim, 1.0)
    assert np.abs(sim.state.pos[:20] - p0).max() < 1e-4
    assert deepest < 1e-3
    _assert_energy_bounded(sim)


def test_half_supported_end_brick_tips_over():
    """A brick overhanging its support by 60 % of its length tips off and lands on the table."""
    support = {"size": BRICK, "position": [0, 0, 0.0175], "mass": M_BRICK}
    top = {"size": BRICK, "position": [0.6 * 0.105, 0, 0.0525], "mass": M_BRICK}
    sim = make_sim([support, top], friction=0.81)
    deepest = _run_checked(sim, 1.0)
    # it tipped off (turned by more than 30 deg) and came down (it may end leaning on the support)
    assert rotation_angle(sim.state.quat[1], np.array([1.0, 0, 0, 0])) > np.radians(30)
    assert sim.state.pos[1, 2] < 0.0525 - 0.005
    assert deepest < 1e-3
    _assert_energy_bounded(sim)


def test_brick_dropped_on_wall():
    blocks = stretcher_wall(5, 5)
    drop = {"size": BRICK, "position": [0.25, 0.0, 5 * 0.035 + 0.15], "rotation": [10, 20, 5],
            "mass": M_BRICK}
    sim = make_sim(blocks + [drop], friction=0.81)
    deepest = _run_checked(sim, 0.8)
    assert deepest < 1e-3
    _assert_energy_bounded(sim)
    e = sim.energy_report()
    # the impact dissipated energy (damping and friction), it did not all bounce back
    assert e["dissipated_normal_damping"] + e["dissipated_friction"] > 0.1 * M_BRICK * 9.81 * 0.15


def test_serial_and_parallel_kernels_agree_to_round_off():
    """Both kernels sum contact forces per body in the same order (no atomics): through a
    landing impact they agree to round-off (the bounds and what was measured:
    engine_helpers.ROUND_OFF_*)."""
    blocks = stretcher_wall(4, 4)
    drop = {"size": BRICK, "position": [0.2, 0.0, 4 * 0.035 + 0.03], "rotation": [5, 10, 0],
            "mass": M_BRICK}  # lowest corner ~3 mm above the wall: it lands within the run
    runs = []
    for mode in ("serial", "parallel"):
        sim = make_sim(blocks + [drop], friction=0.81, solver={"mode": mode})
        start = sim.state.pos.copy()
        sim.advance(2500, constant_loads())
        runs.append((sim.state.pos.copy(), sim.state.quat.copy()))
    assert np.abs(runs[0][0] - start).max() > 1e-3  # the dropped brick moved
    assert np.abs(runs[0][0] - runs[1][0]).max() <= ROUND_OFF_POS_M
    assert np.abs(runs[0][1] - runs[1][1]).max() <= ROUND_OFF_QUAT


def test_light_plank_landing_flat_lifts_its_area_cap_and_shortens_the_step():
    """A light plank (0.4 x 0.04 x 0.01 m, 96 g) among bricks: its faces are capped at a brick's
    face in the critical-step bound (dem.engine.timestep.face_area_caps), so it does not set dt
    while it touches things on small patches.  Dropped flat on the table, its patch exceeds the
    cap: the cap is lifted, dt shrinks, and the run stays sound."""
    bricks = [{"size": BRICK, "position": [0.3 + 0.12 * k, 0, 0.0175], "mass": M_BRICK}
              for k in range(10)]
    plank = {"size": [0.4, 0.04, 0.01], "position": [0, 0, 0.01], "density": 600}
    sim = make_sim(bricks + [plank], friction=0.81)
    assert np.isfinite(sim.area_cap[10]) and not np.isfinite(sim.area_cap[:10]).any()
    dt0 = sim.dt
    _run_checked(sim, 0.2)
    assert len(sim.dt_changes) == 1 and sim.dt_changes[0]["blocks"] == [10]
    assert sim.dt < dt0
    assert sim.dt == pytest.approx(sim.options.safety * sim.dt_crit)
    _assert_energy_bounded(sim)
