"""Energies of the two-body rocking model: kinetic and potential energy of one state
(:func:`energy`) and of the recorded samples at once (:func:`energy_arrays`, for the outputs).

Both are measured in the base frame from the position at rest; the work of the base-acceleration
inertia forces is not included.  Conventions: :mod:`dem.rocking.params`.
"""

from __future__ import annotations

import math

import numpy as np

from dem.rocking.equations import terms
from dem.rocking.maximal import points
from dem.rocking.params import RockingParams
from dem.rocking.patterns import geometry


def energy(P: RockingParams, mode: tuple, y) -> tuple[float, float]:
    """Kinetic and potential energy (J) in the base frame: (KE, V).

    V = g (m1 z_G1 + m2 z_G2) + N z_p, measured from the position at rest.  The work of the
    base-acceleration inertia forces is not included (so E = KE + V is conserved only when
    a = 0 and mu N = 0 and impacts are elastic).
    """
    b, c, tau, sig = mode
    th1, phi, w1, wphi = (float(v) for v in y)
    th2, w2 = th1 + phi, w1 + wphi
    s1, s2 = geometry(P, b, c)
    M11, M12, M22, *_ = terms(P, s1, s2, sig, th1, th2, w1, w2, 0.0)
    KE = 0.5 * (M11 * w1 * w1 + 2.0 * M12 * w1 * w2 + M22 * w2 * w2)
    pts = points(P, s1, s2, th1, th2)
    Lp, gp = P.load_geom[(s2, sig)]
    zp = pts["Q"][1] + Lp * math.cos(th2 + gp)
    V = P.gravity * (P.m1 * (pts["G1"][1] - P.h1 / 2) + P.m2 * (pts["G2"][1] - P.h1 - P.h2 / 2))
    V += P.top_load * (zp - P.height)
    return KE, V


def energy_arrays(P: RockingParams, th1, th2, w1, w2, b, c, sig):
    """Vectorised :func:`energy`: (KE, V) arrays (J) for samples with modes (b, c, sigma)."""
    th1, th2, w1, w2 = (np.asarray(v, dtype=float) for v in (th1, th2, w1, w2))
    b, c, sig = (np.asarray(v, dtype=int) for v in (b, c, sig))
    s1 = np.where(b != 0, b, np.where(c != 0, c, 1))
    s2 = np.where(c != 0, c, s1)
    same = s2 == s1
    L1 = np.where(same, P.h1, 2.0 * P.R1)
    psiQ = np.where(same, th1, th1 - s1 * P.al1)
    psi1 = th1 - s1 * P.al1
    psi2 = th2 - s2 * P.al2
    Lp = np.empty_like(th1)
    gp = np.empty_like(th1)
    for (s2v, sv), (L, gg) in P.load_geom.items():
        m = (s2 == s2v) & (sig == sv)
        Lp[m], gp[m] = L, gg
    mN = P.mN
    M11 = P.IO1 + (P.m2 + mN) * L1 * L1
    M12 = P.m2 * L1 * P.R2 * np.cos(psiQ - psi2) + mN * L1 * Lp * np.cos(psiQ - th2 - gp)
    M22 = P.IO2 + mN * Lp * Lp
    KE = 0.5 * (M11 * w1 * w1 + 2.0 * M12 * w1 * w2 + M22 * w2 * w2)
    zG1 = P.R1 * np.cos(psi1)
    zQ = L1 * np.cos(psiQ)
    zG2 = zQ + P.R2 * np.cos(psi2)
    zp = zQ + Lp * np.cos(th2 + gp)
    V = P.gravity * (P.m1 * (zG1 - P.h1 / 2) + P.m2 * (zG2 - P.h1 - P.h2 / 2))
    V = V + P.top_load * (zp - P.height)
    return KE, V
