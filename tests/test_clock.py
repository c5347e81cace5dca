"""dem.engine.timestep.Clock: t = t_anchor + (step - step_anchor) dt, continuous across a change
of dt, and the same for a launch's steps (times) as for one step (time)."""

import numpy as np

from dem.engine.timestep import Clock


def test_time_is_continuous_across_a_change_of_dt():
    c = Clock()
    c.dt = 1e-5
    t_before = c.time(1000)  # 1000 steps of 1e-5 s
    assert t_before == 1000 * 1e-5
    c.anchor(c.time(1000), 1000)
    c.dt = 4e-6
    assert c.time(1000) == t_before  # the change does not move t
    # 250 steps of the new dt later: 1e-3 s more (to the rounding of one product and one sum)
    assert abs(c.time(1250) - (t_before + 1e-3)) <= 4 * np.finfo(float).eps * c.time(1250)


def test_times_of_a_launch_equal_time_of_each_step():
    c = Clock()
    c.dt = 3.7e-6
    c.anchor(0.25, 17)
    ts = c.times(40, 5)
    assert np.array_equal(ts, [c.time(40 + k) for k in range(5)])
