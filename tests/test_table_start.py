"""How the table starts (dem.table_motion, dem.run.table_start).

``start: lab``: the table is at rest before t = 0 and moves as u = A sin(w t) after, so every
block starts with the velocity -A w relative to it.  A Coulomb block of friction mu on the table
then slips until friction has brought it to the table's velocity, and sticks if A w^2 < mu g.
Relative to the table (x, v = dx/dt) while it slips backwards (v < 0):

    dv/dt = -a_table(t) + mu g = A w^2 sin(w t) + mu g,   v(0) = -A w
    v(t)  = -A w cos(w t) + mu g t,     x(t) = -A sin(w t) + mu g t^2 / 2

It sticks at the first root t* of A w cos(w t*) = mu g t*, having slipped x(t*).  The test
checks that closed form against scipy's solve_ivp of the same one-degree-of-freedom model, then
the DEM against both (1 %: the DEM's block is elastic on its contact, with a shear give of
m a / (ks area) = 4 * 1.6 / (2e9 * 0.04) = 0.08 um, 1e-4 of the 1.3 mm slip; frames every
50 us read the stick time to 0.25 % of its 21 ms).

``start: ramp``: the amplitude rises smoothly, so a squat block below its sliding and tipping
thresholds moves with the table (its give on the contact is 0.08 um; below 1 um).
"""

from __future__ import annotations

import math

import numpy as np
import pytest
from scipy.integrate import solve_ivp
from scipy.optimize import brentq

from dem.case import parse_case
from dem.table_motion import SineMotion

G = 9.81
F, A, MU = 2.0, 0.01, 0.6     # Hz, m, -: A w^2 = 1.58 m/s2 < mu g = 5.9 m/s2 (sticks)
W = 2 * np.pi * F
BLOCK = {"size": [0.2, 0.2, 0.1], "position": [0, 0, 0.05], "mass": 4.0}


def _case(loading: dict, duration: float, interval: float, mu: float = MU):
    return parse_case({
        "name": "block-table-start", "scene": {"blocks": [BLOCK]},
        "material": {"friction": mu},
        "loading": {"type": "shake", "direction": [1, 0, 0], "frequency": F, **loading},
        "run": {"duration": duration, "output_interval": interval, "vtk": False,
                "snapshot": False}})


def _coulomb_lab_start():
    """(stick time s, slip m): the closed form of the module docstring, and solve_ivp's."""
    t_star = brentq(lambda t: A * W * np.cos(W * t) - MU * G * t, 1e-9, 0.25 / F)
    x_star = -A * np.sin(W * t_star) + 0.5 * MU * G * t_star**2

    def rhs(t, y):  # y = (x, v) relative to the table, slipping backwards (v < 0)
        return [y[1], A * W**2 * np.sin(W * t) + MU * G]

    def stuck(t, y):
        return y[1]
    stuck.terminal, stuck.direction = True, 1
    sol = solve_ivp(rhs, (0.0, 0.25 / F), [0.0, -A * W], events=stuck, rtol=1e-10, atol=1e-13)
    return (t_star, x_star), (float(sol.t_events[0][0]), float(sol.y_events[0][0][0]))


def test_closed_form_of_the_lab_start_matches_an_independent_integration():
    (t_c, x_c), (t_i, x_i) = _coulomb_lab_start()
    assert t_i == pytest.approx(t_c, rel=1e-7)
    assert x_i == pytest.approx(x_c, rel=1e-7)
    assert A * W**2 < MU * G          # it stays stuck once stuck


def test_motion_of_each_start_is_continuous_where_it_should_be():
    """u, v, a are each other's derivatives for every start; lab and table-frame share u and a,
    with v jumping 0 -> A w at t = 0; the ramp is continuous from rest (u = v = a = 0 at 0)
    into the held sine."""
    t = np.linspace(-0.05, 2.3, 470001)
    h = t[1] - t[0]
    for start, ramp in (("table-frame", None), ("lab", None), ("ramp", 2.0)):
        m = SineMotion(A, F, 4, start, ramp)
        u, v, a = m.displacement(t), m.velocity(t), m.acceleration(t)
        inside = (t > 2 * h) & (t < m.t_end - 2 * h)
        # central differences: error h^2 / 6 u''' ~ 1e-9 of A w
        assert np.abs(np.gradient(u, t) - v)[inside].max() < 1e-6 * A * W, start
        assert np.abs(np.gradient(v, t) - a)[inside].max() < 1e-6 * A * W**2, start
        assert u[t < 0].max() == 0.0 and v[t < 0].max() == 0.0
    lab = SineMotion(A, F, 4, "lab")
    assert lab.velocity_jump == pytest.approx(A * W)
    assert SineMotion(A, F, 4).velocity_jump == 0.0
    ramp = SineMotion(A, F, 4, "ramp", 2.0)
    assert ramp.velocity_jump == 0.0
    assert float(ramp.velocity(0.0)) == 0.0 and float(ramp.acceleration(0.0)) == 0.0
    t_r = ramp.t_ramp
    for q in ("displacement", "velocity", "acceleration"):
        held = getattr(SineMotion(A, F, 4), q)(np.array([t_r, 1.5]))
        np.testing.assert_allclose(getattr(ramp, q)(np.array([t_r, 1.5])), held,
                                   atol=1e-12, err_msg=q)
    # the ramp's acceleration extrema (breakpoints) are where the jerk is zero
    for tb in ramp.breakpoints(0.0, t_r):
        if tb < t_r:
            d = 1e-6
            a0, a1, a2 = ramp.acceleration(np.array([tb - d, tb, tb + d]))
            assert (a1 - a0) * (a2 - a1) <= 1e-18


def test_a_block_on_a_lab_start_slips_then_sticks_as_the_coulomb_block():
    from dem.run import run_case

    res = run_case(_case({"amplitude": A, "cycles": 2, "start": "lab"}, 0.06, 5e-5))
    assert res.summary["status"] == "ok"
    assert res.summary["table_start"]["relative_velocity_m_s"][0] == pytest.approx(-A * W)
    t, x = res.t, res.pos[:, 0, 0] - res.pos[0, 0, 0]
    v = res.vel[:, 0, 0]
    assert v[0] == pytest.approx(-A * W, rel=1e-12)     # the impulse, at the first frame
    (t_c, x_c), _ = _coulomb_lab_start()
    t_stick = t[np.argmax(v >= -1e-4)]                   # 1e-4 m/s: 1e-3 of A w
    assert t_stick == pytest.approx(t_c, rel=0.01)
    assert x[-1] == pytest.approx(x_c, rel=0.01)         # stuck since: the slip stays
    # the table's record: u = A sin(w t) from 0 (the lab table starts where it stood)
    np.testing.assert_allclose(res.base_disp[:, 0], A * np.sin(W * t), atol=1e-15)
    # the energy balance counts the impulse's kinetic energy as supplied
    e = res.summary["energy"]
    assert abs(e["residual"]) < 0.01 * e["initial"]


def test_a_ramp_start_leaves_a_squat_block_moving_with_the_table():
    """b/h = 2, mu = 0.8: sliding at mu g = 7.8 m/s2, tipping at g b/h = 19.6 m/s2, both far
    above the peak 1.5 m/s2 (the ramp adds at most 15 / (8 pi n_r) = 0.6 / n_r of it)."""
    from dem.run import run_case

    res = run_case(_case({"peak_acceleration": 1.5, "cycles": 2, "start": "ramp",
                          "ramp_cycles": 1}, 1.0, 0.002, mu=0.8))
    assert res.summary["status"] == "ok" and "table_start" not in res.summary
    rel = np.linalg.norm(res.pos[:, 0] - res.pos[0, 0], axis=1)
    assert rel.max() < 1e-6
    m = SineMotion(1.5 / W**2, F, 2, "ramp", 1)
    np.testing.assert_allclose(res.base_disp[:, 0], m.displacement(res.t), atol=1e-15)


@pytest.mark.parametrize("loading,message", [
    ({"amplitude": A, "start": "ramp"}, "ramp_cycles: start: ramp needs ramp_cycles"),
    ({"amplitude": A, "start": "lab", "ramp_cycles": 2}, "ramp_cycles: only with start: ramp"),
    ({"amplitude": A, "cycles": 3, "start": "ramp", "ramp_cycles": 4},
     "ramp_cycles: 4 is more than cycles = 3"),
    ({"amplitude": A, "start": "sudden"}, "loading.start: Input should be"),
])
def test_dem_check_names_a_bad_start_field(tmp_path, loading, message):
    import yaml
    from typer.testing import CliRunner

    from dem_cli.app import app

    case = _case({"amplitude": A}, 0.1, 0.01).model_dump()
    case["loading"] = {"type": "shake", "direction": [1, 0, 0], "frequency": F, **loading}
    path = tmp_path / "case.yaml"
    path.write_text(yaml.safe_dump(case))
    r = CliRunner().invoke(app, ["check", str(path)])
    assert r.exit_code == 2, r.output
    assert f"{path}:" in r.output and message in r.output, r.output


def test_a_default_shake_writes_its_case_as_before():
    """case.json of a default shake has no start keys (shipped runs stay byte for byte)."""
    case = _case({"amplitude": A}, 0.1, 0.01)
    assert "start" not in case.loading.model_dump()
    assert "ramp_cycles" not in case.model_dump_json()
    lab = _case({"amplitude": A, "start": "lab"}, 0.1, 0.01)
    assert lab.loading.model_dump()["start"] == "lab"
    assert type(lab).model_validate_json(lab.model_dump_json()).loading.start == "lab"


def test_a_resumed_lab_start_run_does_not_take_the_impulse_again(tmp_path, monkeypatch):
    """Stopped after its third checkpoint and resumed, a lab-start run is the run never
    stopped, bit for bit (the impulse belongs to t = 0, not to the resumption)."""
    import dem.run.write
    from dem.run import run_case
    from dem.run.write import RunWriter

    case = _case({"amplitude": A, "cycles": 2, "start": "lab"}, 0.03, 0.002)
    whole = run_case(case, tmp_path / "whole")
    monkeypatch.setattr(dem.run.write, "CHECKPOINT_SECONDS", -1.0)   # one at every frame
    monkeypatch.setattr(dem.run.write, "CHECKPOINT_SHARE", math.inf)
    calls, original = [0], RunWriter.checkpoint

    def checkpoint(self, *args):
        calls[0] += 1
        if calls[0] > 3:
            raise KeyboardInterrupt
        original(self, *args)

    monkeypatch.setattr(RunWriter, "checkpoint", checkpoint)
    with pytest.raises(KeyboardInterrupt):
        run_case(case, tmp_path / "cut")
    monkeypatch.setattr(RunWriter, "checkpoint", original)
    again = run_case(case, tmp_path / "cut", resume=True)
    assert again.summary.get("resumed"), again.summary.get("resume")
    np.testing.assert_array_equal(again.vel, whole.vel)
    np.testing.assert_array_equal(again.pos, whole.pos)
    assert again.summary["table_start"] == whole.summary["table_start"]


@pytest.mark.parametrize("start,ramp", [("table-frame", None), ("lab", None), ("ramp", 1.0)])
def test_instruments_record_the_tables_own_motion_for_each_start(start, ramp):
    """instruments.npz's table record is the start's table motion: table_disp = u(t_k),
    table_vel = v(t_k) (recorded for the lab and ramp starts) and table_acc = the mean of a
    over the sample interval, (v(t_k) - v(t_k-1)) / dt_sample, exactly."""
    from dem.case import BlockSpec
    from dem.instruments import Instrument, InstrumentRecorder
    from dem.loading import Shake
    from dem.scene import blocks_to_scene

    scene = blocks_to_scene([BlockSpec(**BLOCK)])
    loading = Shake([0, 0, -G], [1, 0, 0], F, A, 2, start, ramp)
    rec = InstrumentRecorder([Instrument("a", 0, np.zeros(3), np.array([1.0, 0, 0]),
                                         "accelerometer")], scene,
                             table_velocity=loading.records_table_velocity())
    t = np.arange(0.0, 0.5, 0.002)
    zero = np.zeros((2, 3))
    quat = np.vstack([scene.quat, [[1.0, 0, 0, 0]]])
    pos = np.vstack([scene.position, zero[:1]])
    for tk in t:
        rec.sample(tk, pos, quat, zero, zero, loading.base_disp(np.array([tk]))[0],
                   loading.base_vel(np.array([tk]))[0])
    out = rec.arrays()
    m = SineMotion(A, F, 2, start, ramp)
    np.testing.assert_allclose(out["table_disp"][:, 0], m.displacement(t), atol=1e-15)
    np.testing.assert_allclose(out["table_acc"][1:, 0], np.diff(m.velocity(t)) / 0.002,
                               rtol=1e-9, atol=1e-12)
    assert ("table_vel" in out) == (start != "table-frame")
    if start != "table-frame":
        np.testing.assert_allclose(out["table_vel"][:, 0], m.velocity(t), atol=1e-15)
    if start == "lab":   # the table starts from rest: v(0-) = 0, v(0) = A w
        assert float(m.velocity(-1e-9)) == 0.0 and out["table_vel"][0, 0] == pytest.approx(A * W)
