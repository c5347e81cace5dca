"""The instruments' samples (dem.instruments.InstrumentRecorder) are computed in batches when
they are read: the rows must be those of one sample at a time, bit for bit, however the samples
are grouped, with the table's motion given as values or as the loading's functions."""

import numpy as np

from dem import quaternion
from dem.instruments import Instrument, InstrumentRecorder, cross
from dem.loading import Shake
from dem.scene import blocks_to_scene
from dem.case import BlockSpec


def _scene_and_instruments(n_blocks=4):
    blocks = [BlockSpec(size=[0.2, 0.1, 0.05], position=[0.3 * b, 0.0, 0.025], mass=2.0)
              for b in range(n_blocks)]
    scene = blocks_to_scene(blocks)
    rng = np.random.default_rng(1)
    instruments = [Instrument(f"i{k}", k % n_blocks, rng.uniform(-0.1, 0.1, 3),
                              np.array([0.0, 1.0, 0.0]), "transducer") for k in range(6)]
    return scene, instruments


def _states(m, n, seed=2):
    """m random states of n blocks: pos, unit quat, vel, omega; rising times."""
    rng = np.random.default_rng(seed)
    q = rng.normal(size=(m, n, 4))
    q /= np.linalg.norm(q, axis=-1, keepdims=True)
    t = np.cumsum(rng.uniform(1e-3, 3e-3, m))
    return t, rng.normal(size=(m, n, 3)), q, rng.normal(size=(m, n, 3)), rng.normal(size=(m, n, 3))


def _one_at_a_time(rec, t, pos, quat, vel, omega, loading):
    """The rows as one sample's arithmetic gives them (the recorder's definition: the point
    x = pos + R p, v = vel + omega x R p, the table's motion at t; the acceleration the
    difference quotient of the absolute velocity with the sample before)."""
    out = {k: [] for k in ("disp", "vel", "acc", "table_disp", "table_acc")}
    last = None
    for k in range(len(t)):
        R = quaternion.matrices(quat[k])
        r = np.einsum("nij,nj->ni", R, rec.points)
        x = pos[k] + r
        v = vel[k] + np.cross(omega[k], r)
        tv = loading.base_vel(np.array([t[k]]))[0]
        v_abs = v + tv
        if last is None:
            acc, tacc = np.zeros_like(v), np.zeros(3)
        else:
            acc, tacc = (v_abs - last[1]) / (t[k] - last[0]), (tv - last[2]) / (t[k] - last[0])
        last = (t[k], v_abs, tv)
        out["disp"].append(x - rec.x0)
        out["vel"].append(v)
        out["acc"].append(acc)
        out["table_disp"].append(loading.base_disp(np.array([t[k]]))[0])
        out["table_acc"].append(tacc)
    return {k: np.asarray(v) for k, v in out.items()}


def test_samples_in_batches_are_one_sample_at_a_time_bit_for_bit():
    scene, instruments = _scene_and_instruments()
    loading = Shake([0, 0, -9.81], [0, 1, 0], 2.8, 0.02, 3)
    m = 37
    t, pos, quat, vel, omega = _states(m, len(instruments))
    want = _one_at_a_time(InstrumentRecorder(instruments, scene), t, pos, quat, vel, omega,
                          loading)
    for groups in ([1] * m, [m], [5, 1, 20, 11]):  # rows read after each group of samples
        rec = InstrumentRecorder(instruments, scene)
        k = 0
        for size in groups:
            for j in range(k, k + size):
                given = j % 2 == 0  # the table's motion as values, or as the loading's functions
                rec.sample_blocks(t[j], pos[j], quat[j], vel[j], omega[j],
                                  loading.base_disp(np.array([t[j]]))[0] if given
                                  else loading.base_disp,
                                  loading.base_vel(np.array([t[j]]))[0] if given
                                  else loading.base_vel)
            k += size
            assert len(rec.rows["t"]) == k
        got = rec.arrays()
        assert np.array_equal(got["t"], t)
        for key, value in want.items():
            assert np.array_equal(got[key], value), (groups, key)


def test_the_last_sample_is_kept_across_a_restart_point():
    """A recorder restored from another's rows and last sample (dem.run.resume) goes on as that
    one does: the next sample's acceleration differences the restored last one."""
    scene, instruments = _scene_and_instruments()
    loading = Shake([0, 0, -9.81], [0, 1, 0], 2.8, 0.02, 3)
    t, pos, quat, vel, omega = _states(6, len(instruments), seed=3)
    a = InstrumentRecorder(instruments, scene)
    b = InstrumentRecorder(instruments, scene)
    for j in range(6):
        a.sample_blocks(t[j], pos[j], quat[j], vel[j], omega[j], loading.base_disp,
                        loading.base_vel)
        if j == 2:  # b takes a's state here, as apply_restart does from restart.npz
            for key in a.rows:
                b.rows[key] = list(np.asarray(a.rows[key]))
            b.last = tuple(np.copy(x) for x in a.last)
        elif j > 2:
            b.sample_blocks(t[j], pos[j], quat[j], vel[j], omega[j], loading.base_disp,
                            loading.base_vel)
    for key in a.rows:
        assert np.array_equal(np.asarray(a.rows[key]), np.asarray(b.rows[key])), key


def test_cross_is_numpys_bit_for_bit():
    rng = np.random.default_rng(4)
    a, b = rng.normal(size=(50, 7, 3)) * 10.0 ** rng.integers(-8, 8, (50, 7, 1)), \
        rng.normal(size=(50, 7, 3))
    assert np.array_equal(cross(a, b), np.cross(a, b))
