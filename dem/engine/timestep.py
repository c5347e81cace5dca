"""Critical time step of the explicit scheme.

For a mass-spring pair, symplectic Euler is stable for dt < 2 / omega, omega = sqrt(k / m); a
viscous ratio zeta lowers that to (2 / omega)(sqrt(1 + zeta^2) - zeta).  For a box we bound the
highest frequency by assuming every face of the block fully in contact with joints of stiffness
kn (normal) and ks (shear) per unit area, against a neighbour of equal mass (factor 2 on k/m):

  translation along x:  k_x = 2 [kn A_x + ks (A_y + A_z)]        A_x = l_y l_z, ...
  rotation about x:     k_rx = 2 [kn l_x (l_y^3 + l_z^3)/12       (bending of faces _|_ z and _|_ y)
                              + ks A_x (l_y^2 + l_z^2)/12          (torsion of faces _|_ x)
                              + ks (A_z l_z^2 + A_y l_y^2)/4]      (shear of faces _|_ y, z)
  omega^2 = 2 max(k_x / m, ..., k_rx / I_x, ...)

(and likewise for y, z), which covers thin blocks whose rotation about the long axis is the
fastest mode.  dt_crit = min over movable blocks; the default step is ``safety * dt_crit``.
"""

from __future__ import annotations

import numpy as np


def critical_time_step(size: np.ndarray, mass: np.ndarray, inertia: np.ndarray,
                       movable: np.ndarray, kn: float, ks: float, zeta: float) -> float:
    """Critical time step (s) of the scene; size [N,3] full edges (m), inertia [N,3] (kg m^2)."""
    size = np.asarray(size, dtype=float)[movable]
    if len(size) == 0:
        return np.inf
    m = np.asarray(mass, dtype=float)[movable]
    inertia = np.asarray(inertia, dtype=float)[movable]
    omega2 = np.zeros(len(size))
    for a in range(3):
        b, c = (a + 1) % 3, (a + 2) % 3
        la, lb, lc = size[:, a], size[:, b], size[:, c]
        Aa, Ab, Ac = lb * lc, la * lc, la * lb
        k_t = 2.0 * (kn * Aa + ks * (Ab + Ac))
        k_r = 2.0 * (kn * la * (lb**3 + lc**3) / 12.0 + ks * Aa * (lb**2 + lc**2) / 12.0
                     + ks * (Ac * lc**2 + Ab * lb**2) / 4.0)
        omega2 = np.maximum(omega2, 2.0 * np.maximum(k_t / m, k_r / inertia[:, a]))
    omega = np.sqrt(omega2.max())
    return float(2.0 / omega * (np.sqrt(1.0 + zeta**2) - zeta))
