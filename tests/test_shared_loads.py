"""The loads of scenes that share a loading, computed for all of them in one call
(dem.run.batched.SharedLoads): each scene's rows are its loading's at its own times, bit for
bit, and the many clocks' times (Clock.times_of) are each clock's."""

from types import SimpleNamespace

import numpy as np
import pytest

from dem.engine.timestep import Clock
from dem.loading import HeldTilt, Record, Shake, Tilt
from dem.run.batched import SharedLoads, shared_loads
from dem.run.settle import RestLoads


def _clocks(n, dt=1.4447534739140497e-05, seed=0):
    rng = np.random.default_rng(seed)
    clocks, steps = [], []
    for i in range(n):
        c = Clock()
        c.dt = dt
        c.anchor(float(rng.uniform(-0.5, 3.0)), int(rng.integers(0, 50000)))
        clocks.append(c)
        steps.append(c.step_anchor + int(rng.integers(0, 200000)))
    return clocks, steps


def test_times_of_many_clocks_are_each_clocks_times():
    clocks, steps = _clocks(9)
    for k in (1, 7, 256):
        t = Clock.times_of(clocks, steps, k)
        for i, c in enumerate(clocks):
            assert t[i].tobytes() == c.times(steps[i], k).tobytes()


def _engine(clocks, steps, active):
    sims = [SimpleNamespace(clock=c, step_count=s) for c, s in zip(clocks, steps)]
    return SimpleNamespace(simulations=sims, active=lambda g: bool(active[g]))


LOADINGS = [
    Shake([0, 0, -9.81], [0, 1, 0], 2.8, 0.0049, 3),
    Shake([0, 0, -9.81], [1, 0, 0], 2.0, 0.01, 4, "ramp", 1.0),
    Shake([0, 0, -9.81], [1, 1, 0], 3.0, 0.01, 5, "lab"),
    Tilt([0, 0, -9.81], "y", 2.0, 30.0),
    Record([0, 0, -9.81], np.linspace(0.0, 2.0, 41), np.random.default_rng(3).normal(size=(41, 3))),
    RestLoads([0.0, 0.0, -9.81]),
]


@pytest.mark.parametrize("loading", LOADINGS, ids=lambda x: type(x).__name__)
def test_shared_loads_are_each_scenes_alone_bit_for_bit(loading):
    clocks, steps = _clocks(6, seed=1)
    active = [1, 1, 0, 1, 1, 1]
    shared = SharedLoads(_engine(clocks, steps, active), list(range(6)), loading)
    for k in (256, 13, 1):
        for g in range(6):
            if not active[g]:
                continue
            t = clocks[g].times(steps[g], k)
            got, want = shared.of(g)(t), loading(t)
            for a, b in zip(got, want):
                assert np.asarray(a).tobytes() == np.asarray(b).tobytes()
    # times that are not the clock's (another caller): the loading's own at those times
    t = np.linspace(0.1, 0.2, 5)
    for a, b in zip(shared.of(0)(t), loading(t)):
        assert np.asarray(a).tobytes() == np.asarray(b).tobytes()


def test_equal_loadings_are_shared_and_others_kept():
    clocks, steps = _clocks(4, seed=2)
    engine = _engine(clocks, steps, [1, 1, 1, 1])
    a = Shake([0, 0, -9.81], [0, 1, 0], 2.8, 0.0049, 3)
    b = Shake([0, 0, -9.81], [0, 1, 0], 2.8, 0.0049, 3)   # equal to a: another point's
    c = Shake([0, 0, -9.81], [0, 1, 0], 2.9, 0.0049, 3)   # another frequency
    closure = lambda t: (np.zeros((len(t), 3)), np.zeros((len(t), 3)))  # noqa: E731
    out = shared_loads(engine, [a, b, c, closure, None], {})
    assert out[2] is c and out[3] is closure and out[4] is None
    assert out[0] is not a and out[1] is not b
    t = clocks[1].times(steps[1], 64)
    for x, y in zip(out[1](t), b(t)):
        assert x.tobytes() == y.tobytes()
    # two settling scenes with the same gravity share, with another gravity not
    rest = [RestLoads([0, 0, -9.81]), RestLoads([0, 0, -9.81]), RestLoads([0, -1.0, -9.7])]
    out = shared_loads(engine, rest, {})
    assert out[0] is not rest[0] and out[1] is not rest[1] and out[2] is rest[2]


def test_a_loading_turned_between_advances_is_shared_only_while_equal():
    """A quasi-static tilt's loading changes between advances (HeldTilt.turn): two scenes whose
    tilts were equal at one advance and differ at the next get each its own loads then."""
    clocks, steps = _clocks(2, seed=5)
    engine = _engine(clocks, steps, [1, 1])
    a, b = (HeldTilt([0, 0, -9.81], "y", 40.0) for _ in range(2))
    memo = {}
    out = shared_loads(engine, [a, b], memo)
    assert out[0] is not a and out[1] is not b  # equal: shared
    b.turn(0.0, 12.0, 0.0)  # b is turned, a is not
    out = shared_loads(engine, [a, b], memo)
    assert out[0] is a and out[1] is b
    t = clocks[1].times(steps[1], 16)
    assert not np.array_equal(out[1](t)[0], a(t)[0])


def test_the_next_chunks_times_are_shared_in_one_call_too():
    """The launcher asks for the next chunk's loads while a chunk runs (its steps' times
    ``ahead`` steps on, dem.engine.launcher.Launcher.write_loads): the first scene's call
    computes every scene's at that offset in one call of the loading, and each scene gets its
    own rows, bit for bit."""
    clocks, steps = _clocks(5, seed=4)
    loading = LOADINGS[0]
    lengths = []

    def counted(t):
        lengths.append(len(t))
        return loading(t)

    shared = SharedLoads(_engine(clocks, steps, [1] * 5), list(range(5)), counted)
    k = 64
    for ahead in (0, 37, 37 + 64):
        lengths.clear()
        for g in range(5):
            t = clocks[g].times(steps[g] + ahead, k)
            for a, b in zip(shared.of(g)(t), loading(t)):
                assert np.asarray(a).tobytes() == np.asarray(b).tobytes()
        assert lengths == [5 * k]  # one call for the five scenes
