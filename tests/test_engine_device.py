"""The engine's device path (issue 35 item 3: dem.engine.device), run on the CPU: Taichi's own
arrays (ti.ndarray) instead of numpy's, data moved only where the host needs it, neighbour-list
rebuilds installed by a kernel with the shear history carried on the device.  The kernels'
arithmetic is the same as the numpy path's, so a scene must follow the same trajectory to
round-off (tests/engine_helpers.py's bounds), lone and batched, with both kernels, through
rebuilds; a GPU runs this same code (the benchmark: benchmarks/batch_speed.py)."""

from __future__ import annotations

import numpy as np
import pytest

from dem.engine.simulation import DEVICE_CHUNK, Engine
from tests.engine_helpers import ROUND_OFF_POS_M, ROUND_OFF_QUAT
from tests.test_engine_batch import JOINTS, assert_same, options, shake, wall


@pytest.mark.parametrize("mode", ["serial", "parallel"])
def test_device_arrays_follow_the_numpy_path(mode):
    loads = [shake(4.0, 7.0), shake(6.0, 8.0, axis=1)]
    opts = options(mode=mode)
    host = Engine([wall() for _ in loads], JOINTS, opts)
    dev = Engine([wall() for _ in loads], JOINTS, opts, device_arrays=True)
    assert dev.on_device and not host.on_device
    steps = 5 * DEVICE_CHUNK + 17  # chunks of DEVICE_CHUNK steps, and a short one
    for _ in range(3):  # the host reads the states between advances (a frame), as a run does
        host.advance(steps, loads)
        dev.advance(steps, loads)
        for a, b in zip(dev.simulations, host.simulations):
            assert np.abs(a.state.pos - b.state.pos).max() <= ROUND_OFF_POS_M
            assert np.abs(a.state.quat - b.state.quat).max() <= ROUND_OFF_QUAT
    for a, b in zip(dev.simulations, host.simulations):
        assert_same(a, b)
        assert np.array_equal(a.contacts.npts, b.contacts.npts)
        assert np.abs(a.contacts.shear - b.contacts.shear).max() <= 1e-15
    assert max(s.n_rebuilds for s in dev.simulations) > 2  # rebuilds installed by the kernel


def test_host_writes_reach_the_device():
    """A velocity set by the host (a lab start, a restart point) is what the kernels step."""
    opts = options()
    dev = Engine([wall()], JOINTS, opts, device_arrays=True)
    host = Engine([wall()], JOINTS, opts)
    for e in (dev, host):
        e.simulations[0].state.vel[:-1, 0] += 0.05
        e.advance(300, [shake(3.0, 1.0)])
    assert_same(dev.simulations[0], host.simulations[0])
    assert np.abs(dev.simulations[0].state.vel[:-1, 0]).max() > 0.01
