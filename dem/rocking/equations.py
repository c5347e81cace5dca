"""Equations of motion of two stacked rigid blocks rocking on a rigid base (thesis Chapter 5).

Accelerations and reactions of every contact mode (:func:`evaluate`), the same equations as a fast
right-hand side for the integrator (:func:`make_rhs`), and the force on a co-moving top load
(:func:`top_contact_force`).  Conventions: :mod:`dem.rocking.params`; modes and pivot geometry:
:mod:`dem.rocking.patterns`; derivation in ``docs/rocking_model.md``.

Lagrangian (pivot geometry s1, s2 = +-1)
-----------------------------------------
psi1 = theta1 - s1 alpha1                       (direction of G1 seen from the base pivot)
Q - P1 = L1 (sin psiQ, cos psiQ), psiQ = theta1 + delta,
         (L1, delta) = (H1, 0) if s2 = s1 else (2 R1, -s1 alpha1)
psi2 = theta2 - s2 alpha2                       (direction of G2 seen from Part 2's pivot Q)
p - Q = Lp (sin psip, cos psip), psip = theta2 + gamma_p   (load point p of the top load N)

    M11 = I_O1 + m2 L1^2,  M22 = I_O2,  M12 = m2 L1 R2 cos(psiQ - psi2),  k = m2 L1 R2 sin(psiQ - psi2)
    M11 th1'' + M12 th2'' + k th2'^2 = Q1
    M12 th1'' + M22 th2'' - k th1'^2 = Q2
    Q1 = g (m1 R1 sin psi1 + m2 L1 sin psiQ) + N L1 sin psiQ - a (m1 R1 cos psi1 + m2 L1 cos psiQ)
         + F L1 cos psiQ
    Q2 = g m2 R2 sin psi2 + N Lp sin psip - a m2 R2 cos psi2 + F Lp cos psip

with R_i = sqrt(T^2 + H_i^2)/2, alpha_i = atan(T/H_i), I_Oi = m_i (T^2 + H_i^2)/3, a(t) the base
acceleration (+x), F the horizontal friction force on the load point, x_p' = L1 cos psiQ th1' +
Lp cos psip th2'.

Top contact (``top_contact``, docs/rocking_model.md section 3b)
* ``sliding`` (the thesis): N is a dead load fixed in space, F = -tau mu N (or the stick reaction).
* ``co-moving``: the top load is a point mass m_N = N / g moving with the load point p (the beam
  translates with the raised top corner it bears on, as the cap beam of a rocking frame, Makris &
  Vassiliou 2013); no friction (F = 0).  Its kinetic energy 1/2 m_N |v_p|^2 and its inertia force
  -m_N a at p add, with m_N = N/g (kg):

      M11 += m_N L1^2,  M22 += m_N Lp^2,  M12 += m_N L1 Lp cos(psiQ - psip),
      k += m_N L1 Lp sin(psiQ - psip),
      Q1 -= a m_N L1 cos psiQ,  Q2 -= a m_N Lp cos psip

  (its weight N at p is already in Q1, Q2).  When the beam passes from one top corner to the other
  (theta2 = 0) the rising corner strikes it: an impact (dem.rocking.impacts).

Locked contacts are constraints with Lagrange multipliers; the multiplier of a lock, taken in the
pivot geometry +-1, is T times the normal force at the opposite corner.  For a single block this is
Housner's (1963) equation I_O th'' = -m g R sin(alpha - th) - m a R cos(alpha - th) (theta > 0).
Units: SI (m, kg, s, N, rad).
"""

from __future__ import annotations

import math

from dem.rocking.params import RockingParams
from dem.rocking.patterns import flow_kind, geometry


def terms(P: RockingParams, s1: int, s2: int, sig: int, th1: float, th2: float,
          w1: float, w2: float, a: float) -> tuple:
    """Mass matrix, velocity terms and generalised forces (without friction) of geometry (s1, s2).

    Returns (M11, M12, M22, k, Q1, Q2, J1, J2, beta): see the module docstring.  J = dx_p/dq is
    the Jacobian of the load point's horizontal position, beta = L1 sin psiQ th1'^2 + Lp sin psip
    th2'^2 so that x_p'' = J q'' - beta.
    """
    if s2 == s1:
        L1 = P.h1
        psiQ = th1
    else:
        L1 = 2.0 * P.R1
        psiQ = th1 - s1 * P.al1
    psi1 = th1 - s1 * P.al1
    psi2 = th2 - s2 * P.al2
    Lp, gp = P.load_geom[(s2, sig)]
    psip = th2 + gp
    sQ, cQ = math.sin(psiQ), math.cos(psiQ)
    sn1, cs1 = math.sin(psi1), math.cos(psi1)
    sn2, cs2 = math.sin(psi2), math.cos(psi2)
    sp, cp = math.sin(psip), math.cos(psip)
    d = psiQ - psi2
    m1, m2, R1, R2, g, N, mN = P.m1, P.m2, P.R1, P.R2, P.gravity, P.top_load, P.mN
    dp = psiQ - psip
    M11 = P.IO1 + (m2 + mN) * L1 * L1
    M22 = P.IO2 + mN * Lp * Lp
    M12 = m2 * L1 * R2 * math.cos(d) + mN * L1 * Lp * math.cos(dp)
    k = m2 * L1 * R2 * math.sin(d) + mN * L1 * Lp * math.sin(dp)
    Q1 = g * (m1 * R1 * sn1 + m2 * L1 * sQ) + N * L1 * sQ - a * (m1 * R1 * cs1 + (m2 + mN) * L1 * cQ)
    Q2 = g * m2 * R2 * sn2 + N * Lp * sp - a * (m2 * R2 * cs2 + mN * Lp * cp)
    J1 = L1 * cQ
    J2 = Lp * cp
    beta = L1 * sQ * w1 * w1 + Lp * sp * w2 * w2
    return M11, M12, M22, k, Q1, Q2, J1, J2, beta


def _solve2(M11, M12, M22, r1, r2):
    det = M11 * M22 - M12 * M12
    return (M22 * r1 - M12 * r2) / det, (M11 * r2 - M12 * r1) / det


class Eval:
    """Accelerations and reactions of one mode at one state (see :func:`evaluate`)."""

    __slots__ = ("dd1", "dd2", "F", "xd", "xdd", "iface", "base")

    def __init__(self, dd1, dd2, F, xd, xdd, iface=None, base=None):
        self.dd1, self.dd2, self.F, self.xd, self.xdd = dd1, dd2, F, xd, xdd
        self.iface = iface  # (f_plus, f_minus): normal forces at the interface corners, N
        self.base = base    # (f_plus, f_minus): normal forces at the base corners (flat base), N


def evaluate(P: RockingParams, mode: tuple, y, a: float, want_forces: bool = True) -> Eval:
    """Accelerations (rad/s2), friction F (N), load-point velocity and acceleration, lock forces.

    ``mode = (b, c, tau, sigma)``; ``y = (theta1, phi, omega1, omega_phi)``; ``a`` base
    acceleration (m/s2).  Lock forces are the normal forces at the two corners of a flat contact
    (>= 0 while the lock is valid).
    """
    b, c, tau, sig = mode
    th1, phi, w1, wphi = y[0], y[1], y[2], y[3]
    th2 = th1 + phi
    w2 = w1 + wphi
    kind = flow_kind(b, c, tau)
    s1, s2 = geometry(P, b, c)
    T = P.thickness
    F = -tau * P.Fmax
    M11, M12, M22, k, Q1, Q2, J1, J2, beta = terms(P, s1, s2, sig, th1, th2, w1, w2, a)
    iface = base = None
    if kind == "free":
        dd1, dd2 = _solve2(M11, M12, M22, Q1 + F * J1 - k * w2 * w2, Q2 + F * J2 + k * w1 * w1)
    elif kind == "free_stick":
        a1, a2 = _solve2(M11, M12, M22, Q1 - k * w2 * w2, Q2 + k * w1 * w1)
        f1, f2 = _solve2(M11, M12, M22, J1, J2)
        F = (beta - (J1 * a1 + J2 * a2)) / (J1 * f1 + J2 * f2)
        dd1, dd2 = a1 + F * f1, a2 + F * f2
    elif kind in ("p3", "p3_stuck"):
        if kind == "p3":
            dd1 = dd2 = (Q1 + Q2 + F * (J1 + J2)) / (M11 + 2.0 * M12 + M22)
        else:
            F = -(Q1 + Q2) / (J1 + J2)
            dd1 = dd2 = 0.0
        if want_forces and not P.locked:
            lam = []
            for s2p in (1, -1):
                t_ = terms(P, s1, s2p, sig, th1, th2, w1, w2, a)
                lam.append((t_[1] + t_[2]) * dd1 - t_[3] * w1 * w1 - t_[5] - F * t_[7])
            iface = (-lam[1] / T, lam[0] / T)
    elif kind in ("p4", "p4_stuck"):
        dd1 = 0.0
        if kind == "p4":
            dd2 = (Q2 + F * J2) / M22
        else:
            F = -Q2 / J2
            dd2 = 0.0
        if want_forces:
            lam = []
            for s1p in (1, -1):
                t_ = terms(P, s1p, c, sig, th1, th2, w1, w2, a)
                lam.append(t_[1] * dd2 + t_[3] * w2 * w2 - t_[4] - F * t_[6])
            base = (-lam[1] / T, lam[0] / T)
    else:  # rest: nothing moves; reactions are statically indeterminate (not needed)
        dd1 = dd2 = 0.0
        F = 0.0
    xd = J1 * w1 + J2 * w2
    xdd = J1 * dd1 + J2 * dd2 - beta
    return Eval(dd1, dd2, F, xd, xdd, iface, base)


def top_contact_force(P: RockingParams, mode: tuple, y, a: float) -> tuple[float, float]:
    """Force (H, V) in N that Part 2 exerts on a co-moving beam at the load point p.

    The beam (mass m_N = N/g, no rotation) follows p, so in the table's frame
        H = m_N (x_p'' + a),   V = m_N (g + z_p''),
    x_p = x_Q + Lp sin psip, z_p = L1 cos psiQ + Lp cos psip, hence
        x_p'' = L1 (cos psiQ th1'' - sin psiQ th1'^2) + Lp (cos psip th2'' - sin psip th2'^2),
        z_p'' = -L1 (sin psiQ th1'' + cos psiQ th1'^2) - Lp (sin psip th2'' + cos psip th2'^2).
    Without slip the beam needs a friction coefficient of at least abs(H) / V (V > 0 while it
    bears): the test of whether a stick-slip top contact would ever slip.
    """
    b, c, tau, sig = mode
    th1, phi, w1, wphi = y
    th2, w2 = th1 + phi, w1 + wphi
    e = evaluate(P, mode, y, a, want_forces=False)
    s1, s2 = geometry(P, b, c)
    if s2 == s1:
        L1, psiQ = P.h1, th1
    else:
        L1, psiQ = 2.0 * P.R1, th1 - s1 * P.al1
    Lp, gp = P.load_geom[(s2, sig)]
    psip = th2 + gp
    sQ, cQ, sp, cp = math.sin(psiQ), math.cos(psiQ), math.sin(psip), math.cos(psip)
    xdd = L1 * (cQ * e.dd1 - sQ * w1 * w1) + Lp * (cp * e.dd2 - sp * w2 * w2)
    zdd = -L1 * (sQ * e.dd1 + cQ * w1 * w1) - Lp * (sp * e.dd2 + cp * w2 * w2)
    mN = P.top_load / P.gravity
    return mN * (xdd + a), mN * (P.gravity + zdd)


def make_rhs(P: RockingParams, mode: tuple, acc):
    """Fast right-hand side y' = f(t, y) of the flow modes (same equations as :func:`evaluate`).

    ``acc(t)`` is the base acceleration.  y = (theta1, phi, omega1, omega_phi).
    """
    b, c, tau, sig = mode
    kind = flow_kind(b, c, tau)
    s1, s2 = geometry(P, b, c)
    F = -tau * P.Fmax
    m1, m2, R1, R2, g, N = P.m1, P.m2, P.R1, P.R2, P.gravity, P.top_load
    sin, cos = math.sin, math.cos
    if s2 == s1:
        L1, dl = P.h1, 0.0
    else:
        L1, dl = 2.0 * P.R1, -s1 * P.al1
    a1, a2 = s1 * P.al1, s2 * P.al2
    Lp, gp = P.load_geom[(s2, sig)]
    mN = P.mN
    M11 = P.IO1 + (m2 + mN) * L1 * L1
    M22 = P.IO2 + mN * Lp * Lp
    mLR = m2 * L1 * R2
    nLL = mN * L1 * Lp                 # co-moving beam: coupling through cos(psiQ - psip)
    g1, gQ, g2 = g * m1 * R1, g * m2 * L1 + N * L1, g * m2 * R2
    NLp, FLp, FL1 = N * Lp, F * Lp, F * L1
    mR1, mL1, mR2 = m1 * R1, (m2 + mN) * L1, m2 * R2
    nLp = mN * Lp                      # inertia force of the beam at p: lever Lp cos psip

    if kind == "free":
        def rhs(t, y):
            th1 = y[0]
            th2 = th1 + y[1]
            w1 = y[2]
            w2 = w1 + y[3]
            a = acc(t)
            psiQ = th1 + dl
            psi1 = th1 - a1
            psi2 = th2 - a2
            psip = th2 + gp
            sQ, cQ = sin(psiQ), cos(psiQ)
            d = psiQ - psi2
            dp = psiQ - psip
            cp = cos(psip)
            M12 = mLR * cos(d) + nLL * cos(dp)
            k = mLR * sin(d) + nLL * sin(dp)
            r1 = (g1 * sin(psi1) + gQ * sQ - a * (mR1 * cos(psi1) + mL1 * cQ) + FL1 * cQ
                  - k * w2 * w2)
            r2 = (g2 * sin(psi2) + NLp * sin(psip) - a * (mR2 * cos(psi2) + nLp * cp) + FLp * cp
                  + k * w1 * w1)
            det = M11 * M22 - M12 * M12
            dd1 = (M22 * r1 - M12 * r2) / det
            dd2 = (M11 * r2 - M12 * r1) / det
            return [w1, y[3], dd1, dd2 - dd1]
    elif kind == "p3":
        def rhs(t, y):
            th = y[0]
            a = acc(t)
            psiQ = th + dl
            psi1 = th - a1
            psi2 = th - a2
            psip = th + gp
            sQ, cQ = sin(psiQ), cos(psiQ)
            cp = cos(psip)
            M12 = mLR * cos(psiQ - psi2) + nLL * cos(psiQ - psip)
            r = (g1 * sin(psi1) + gQ * sQ - a * (mR1 * cos(psi1) + mL1 * cQ) + FL1 * cQ
                 + g2 * sin(psi2) + NLp * sin(psip) - a * (mR2 * cos(psi2) + nLp * cp) + FLp * cp)
            return [y[2], 0.0, r / (M11 + 2.0 * M12 + M22), 0.0]
    elif kind == "p4":
        def rhs(t, y):
            th2 = y[0] + y[1]
            a = acc(t)
            psi2 = th2 - a2
            psip = th2 + gp
            cp = cos(psip)
            r2 = g2 * sin(psi2) + NLp * sin(psip) - a * (mR2 * cos(psi2) + nLp * cp) + FLp * cp
            dd2 = r2 / M22
            return [0.0, y[3], 0.0, dd2]
    else:
        def rhs(t, y):
            e = evaluate(P, mode, y, acc(t), want_forces=False)
            return [y[2], y[3], e.dd1, e.dd2 - e.dd1]
    return rhs
