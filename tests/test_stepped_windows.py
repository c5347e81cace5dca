"""Does the branch hold through a long step?  postprocess.stepped.step_windows judges a step
window by window (ds amplification, lag, postprocess.verdicts.response_branch),
step_and_cycle places a time in a step, postprocess.survival.fallen_parts says what fell; the
kick-start study (studies/as_built/kick_start.py) reads its verdicts from them.

The windows are checked on a response built by hand on a kick-start's table motion: ds is a
sinusoid at the step's frequency, 2 x the table's amplitude and 150 deg behind it for the first
10 cycles of the test step (the rocking branch), 0.1 x and 10 deg behind after (the quiet
branch).  Sampled every 1 ms at 2.8 Hz, a sampled peak misses the true one by at most
(2 pi f dt)^2 / 8 = 4e-5 of it: the amplifications are checked to 1e-3; the fitted phase of a
pure sinusoid is exact to rounding (checked to 0.01 deg).
"""

from __future__ import annotations

import numpy as np
import pytest

from dem.table_motion import SteppedSineMotion
from postprocess.shake_signals import ShakeSignals

F = 2.8                               # Hz
W = 2 * np.pi * F
KICK, TEST = (2.0, 2.3), (20.0, 1.53)  # cycles, m/s2
SWITCH = 10                           # the response leaves the branch after this test cycle


@pytest.fixture(scope="module")
def kicked():
    motion = SteppedSineMotion([(F, KICK[0]), (F, TEST[0])], peak_acceleration=TEST[1],
                               levels=[("peak_acceleration", KICK[1]), None])
    steps = motion.steps_run()
    t = np.arange(0.0, motion.t_end + 0.5, 1e-3)
    u = motion.displacement(t)
    st = steps[1]
    tau = t - st["t_start_s"]
    phase = W * tau + st["start_phase_rad"]
    rocking = tau < SWITCH / F - 1e-9   # (a sample at the switch, to rounding, is quiet)
    amp, lag = np.where(rocking, 2.0, 0.1), np.radians(np.where(rocking, 150.0, 10.0))
    ds = np.where(tau >= 0.0, amp * st["amplitude_m"] * np.sin(phase - lag), 0.0)
    sig = ShakeSignals(t=t, f=F, t_end=motion.t_end, direction=np.array([0.0, 1.0, 0.0]),
                       axis="y", excitation={"displacement": u, "velocity": motion.velocity(t),
                                             "acceleration": motion.acceleration(t)},
                       ds_centre=ds)
    return sig, steps


def test_windows_of_a_step_follow_the_branch_it_is_on(kicked):
    from postprocess.stepped import step_windows

    sig, steps = kicked
    wins = step_windows(sig, steps[1], 5)
    assert [(w["first_cycle"], w["last_cycle"]) for w in wins] == [(1, 5), (6, 10), (11, 15),
                                                                    (16, 20)]
    assert [w["branch"] for w in wins] == ["rocking", "rocking", "quasi-static", "quasi-static"]
    for w, (ds, ph) in zip(wins, [(2.0, 150.0)] * 2 + [(0.1, 10.0)] * 2):
        assert w["ds"] == pytest.approx(ds, rel=1e-3)
        assert w["phase_deg"] == pytest.approx(ph, abs=0.01)
        assert w["lag_s"] == pytest.approx(ph / (360.0 * F), abs=0.01 / (360 * F))
        assert w["t1_s"] - w["t0_s"] == pytest.approx(5 / F)
    assert wins[0]["t0_s"] == pytest.approx(steps[1]["t_start_s"])


def test_the_last_window_is_the_last_whole_cycles_when_the_count_is_not_a_multiple(kicked):
    from postprocess.stepped import step_windows

    sig, steps = kicked
    wins = step_windows(sig, steps[1], 6)
    assert [(w["first_cycle"], w["last_cycle"]) for w in wins] == [(1, 6), (7, 12), (13, 18),
                                                                    (15, 20)]
    assert wins[0]["branch"] == "rocking" and wins[-1]["branch"] == "quasi-static"
    assert wins[-1]["ds"] == pytest.approx(0.1, rel=1e-3)
    # a record that ends before one window of the step: no window
    short = ShakeSignals(**{**sig.__dict__, "t": sig.t[sig.t < steps[1]["t_start_s"] + 3 / F]})
    assert step_windows(short, steps[1], 6) == []
    with pytest.raises(ValueError, match="width"):
        step_windows(sig, steps[1], 0)


def test_a_time_is_placed_in_its_step_and_cycle(kicked):
    from postprocess.stepped import step_and_cycle

    _, steps = kicked
    t1 = steps[1]["t_start_s"]
    assert step_and_cycle(steps, 0.0) == {"step": 0, "cycle": 1}
    assert step_and_cycle(steps, t1 - 1e-6) == {"step": 0, "cycle": 3}   # the kick's 2.25
    assert step_and_cycle(steps, t1 + 10.5 / F) == {"step": 1, "cycle": 11}
    assert step_and_cycle(steps, steps[1]["t_end_s"] + 0.1) is None
    assert step_and_cycle(steps, None) is None


@pytest.mark.parametrize("by_wall,parts", [
    ({}, "standing"),
    ({"roof-mass": {"n_fallen": 2}}, "roof only"),
    ({"roof-mass": {"n_fallen": 1}, "corner-mass": {"n_fallen": 1}}, "roof only"),
    ({"roof-mass": {"n_fallen": 1}, "L1": {"n_fallen": 1}}, "bricks fallen"),
    ({"T2": {"n_fallen": 3}}, "bricks fallen"),
])
def test_what_fell_is_the_roof_or_bricks(by_wall, parts):
    from postprocess.survival import fallen_parts

    n = sum(w["n_fallen"] for w in by_wall.values())
    assert fallen_parts({"n_fallen": n, "by_wall": by_wall}) == parts

