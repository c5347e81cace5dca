"""Motion of blocks from their recorded poses (frames.npz: t [T], pos [T,N,3], vel [T,N,3],
quat [T,N,4] (w, x, y, z), table frame): positions of body points, translations and rotations
since the first frame, angular velocities and the true kinetic energy.  Quaternions go through
dem.quaternion (the package's one convention).

Kinetic energy of blocks relative to the table (:func:`kinetic_energy_blocks`; next to eq 4-4 in
the shake analysis, postprocess.signal_analysis.kinetic_energy_eq44): sum 1/2 m |v|^2 +
1/2 w.I.w, v recorded, w from successive orientations (:func:`angular_velocity`).  For a rigid
facade rocking about its base the true value is about a third of eq 4-4 (the bricks below the
centre move less), plus the rotational part.
"""

from __future__ import annotations

import numpy as np

from dem import quaternion


def point_histories(pos, quat, blocks, points) -> np.ndarray:
    """Positions [T,n,3] of body-frame ``points`` [n,3] of ``blocks`` over the frames."""
    q = quat[:, blocks]
    R = quaternion.rotation(q)
    T, n = q.shape[:2]
    r = R.apply(np.tile(np.asarray(points, float), (T, 1))).reshape(T, n, 3)
    return pos[:, blocks] + r


def angular_velocity(t: np.ndarray, quat: np.ndarray) -> np.ndarray:
    """omega [T,n,3] (rad/s, table frame) from orientations quat [T,n,4] (w,x,y,z): rotation
    vector of R(t_(k+1)) R(t_(k-1))^-1 over t_(k+1) - t_(k-1) (one-sided at the ends)."""
    T, n = quat.shape[:2]
    R = quaternion.rotation(quat)
    lo = np.clip(np.arange(T) - 1, 0, T - 1)
    hi = np.clip(np.arange(T) + 1, 0, T - 1)
    idx = np.arange(T * n).reshape(T, n)
    dR = R[idx[hi].ravel()] * R[idx[lo].ravel()].inv()
    dt = (t[hi] - t[lo])[:, None, None]
    return dR.as_rotvec().reshape(T, n, 3) / np.where(dt > 0, dt, np.inf)


def kinetic_energy_blocks(t, vel, quat, scene, blocks) -> np.ndarray:
    """True kinetic energy (J) of ``blocks`` relative to the table: translation + rotation."""
    blocks = np.asarray(blocks, dtype=int)
    if blocks.size == 0:
        return np.zeros(len(t))
    v = vel[:, blocks]
    m = scene.mass[blocks]
    e_t = 0.5 * np.einsum("n,tni->t", m, v * v)
    w = angular_velocity(t, quat[:, blocks])
    R = quaternion.rotation(quat[:, blocks])
    w_body = R.inv().apply(w.reshape(-1, 3)).reshape(w.shape)
    inertia = scene.inertia()[blocks]
    e_r = 0.5 * np.einsum("ni,tni->t", inertia, w_body * w_body)
    return e_t + e_r


def brick_motion(pos, quat, e, axis):
    """Translation along e [T,N] (m) and rotation about ``axis`` [T,N] (rad) from frame 0: the
    rotation vector of R_i(t) R_i(0)^-1 projected on ``axis``."""
    T, N = pos.shape[:2]
    s = (pos - pos[:1]) @ e
    R = quaternion.rotation(quat)
    R0 = quaternion.rotation(np.broadcast_to(quat[:1], quat.shape))
    theta = (R * R0.inv()).as_rotvec().reshape(T, N, 3) @ axis
    return s, theta
