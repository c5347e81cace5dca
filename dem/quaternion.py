"""The package's one quaternion convention and its bridge to scipy.

Every orientation in the package (Scene.quat, the engine's State.quat, frames.npz ``quat``) is a
unit quaternion (w, x, y, z), scalar first, rotating body coordinates into the table frame.
scipy's :class:`~scipy.spatial.transform.Rotation` reads and writes that order with
``scalar_first=True`` (scipy >= 1.14), so no code reorders components by hand.
"""

from __future__ import annotations

import numpy as np
from scipy.spatial.transform import Rotation


def rotation(quat) -> Rotation:
    """Rotation(s) of quaternions [..., 4] (w, x, y, z), flattened to one stack [M]."""
    q = np.asarray(quat, dtype=np.float64)
    return Rotation.from_quat(q.reshape(-1, 4), scalar_first=True)


def matrices(quat) -> np.ndarray:
    """Body -> table rotation matrices [..., 3, 3] of quaternions [..., 4] (w, x, y, z)."""
    q = np.asarray(quat, dtype=np.float64)
    return rotation(q).as_matrix().reshape(q.shape[:-1] + (3, 3))


def from_rotation(rot: Rotation) -> np.ndarray:
    """Quaternions [M, 4] (w, x, y, z) of a Rotation stack (a single one gives [1, 4])."""
    return np.atleast_2d(rot.as_quat(scalar_first=True))


def from_euler_xyz(angles_deg) -> np.ndarray:
    """Quaternions [M, 4] (w, x, y, z) of intrinsic XYZ Euler angles [M, 3] (degrees)."""
    return from_rotation(Rotation.from_euler("XYZ", np.atleast_2d(angles_deg), degrees=True))
