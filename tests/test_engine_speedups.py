"""Invariants behind the engine's fast paths: a fast path must give the
result of the general code bit for bit or to round-off, never an approximation of it."""

import numpy as np
import taichi as ti
from scipy.spatial.transform import Rotation

from dem import ti_runtime
from dem.engine import step
from dem.engine.mathutil import TINY_ANGLE, quat_to_mat

nd = ti.types.ndarray


@ti.kernel
def _sin_cos(x: nd(dtype=ti.f64, ndim=1), out: nd(dtype=ti.f64, ndim=2)):
    for i in range(x.shape[0]):
        out[i, 0] = ti.sin(x[i])
        out[i, 1] = ti.cos(x[i])


@ti.kernel
def _free_rotation(q: nd(dtype=ti.math.vec4, ndim=1), L: nd(dtype=ti.math.vec3, ndim=1),
                   inv_I: nd(dtype=ti.math.vec3, ndim=1), dt: ti.f64,
                   out: nd(dtype=ti.math.vec4, ndim=1)):
    for i in range(q.shape[0]):
        q1, _ = step.free_rotation(q[i], quat_to_mat(q[i]), L[i], inv_I[i], dt)
        out[i] = q1


def test_sin_and_cos_below_tiny_angle_are_exactly_x_and_one():
    """free_rotation skips the libm calls below TINY_ANGLE and takes sin x = x, cos x = 1:
    that must be what Taichi's sin and cos return there, bit for bit."""
    ti_runtime.init()
    rng = np.random.default_rng(1)
    x = np.concatenate([
        rng.uniform(-TINY_ANGLE, TINY_ANGLE, 100_000),
        np.exp(rng.uniform(np.log(1e-300), np.log(TINY_ANGLE), 100_000)),
        [0.0, -0.0, 5e-324, np.nextafter(TINY_ANGLE, 0.0), -np.nextafter(TINY_ANGLE, 0.0)]])
    out = np.zeros((len(x), 2))
    _sin_cos(x, out)
    assert np.array_equal(out[:, 0], x)
    assert np.all(out[:, 1] == 1.0)


def test_free_rotation_is_the_exact_splitting():
    """X(dt/2) Y(dt/2) Z(dt) Y(dt/2) X(dt/2), each an exact rotation about a body axis, from
    1e-12 rad per factor (libm skipped) to 0.5 rad: the same composition done by scipy."""
    ti_runtime.init()
    rng = np.random.default_rng(2)
    n, dt = 3000, 1e-3
    q = rng.normal(size=(n, 4))
    q /= np.linalg.norm(q, axis=1)[:, None]
    inv_I = rng.uniform(0.5, 2.0, (n, 3))
    L = rng.normal(size=(n, 3)) * np.exp(rng.uniform(np.log(1e-9), np.log(300.0), n))[:, None]
    out = np.zeros((n, 4))
    _free_rotation(q, L, inv_I, dt, out)
    worst = 0.0
    for i in range(n):
        R = Rotation.from_quat(q[i], scalar_first=True)
        for k, frac in zip((0, 1, 2, 1, 0), (0.5, 0.5, 1.0, 0.5, 0.5)):
            phi = frac * dt * (R.as_matrix()[:, k] @ L[i]) * inv_I[i, k]
            R = R * Rotation.from_rotvec(phi * np.eye(3)[k])
        ref = R.as_quat(scalar_first=True)
        worst = max(worst, min(np.abs(out[i] - ref).max(), np.abs(out[i] + ref).max()))
    assert worst < 1e-14
