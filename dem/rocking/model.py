"""Equations of motion of two stacked rigid blocks rocking on a rigid base (thesis Chapter 5).

Geometry and conventions (derivation in ``docs/rocking_model.md``)
-------------------------------------------------------------------
Plane x-z, z up, x along the loading direction.  Part 1 (lower: thickness T, height H1, mass m1)
stands on the rigid base, Part 2 (upper: T, H2, m2) stands on Part 1.  Generalised coordinates are
the **absolute** angles theta1, theta2 (rad) of each part from the vertical, positive when the part's
top moves towards +x.  The integrator's state is ``y = (theta1, phi, omega1, omega_phi)`` with the
relative angle ``phi = theta2 - theta1`` (so that a joint that has just opened starts at exactly 0).

Contact modes (one per contact, no sliding, no flight - the thesis' assumptions):

* base contact ``b``: +1 = Part 1 rocks on its +x bottom corner (theta1 > 0), -1 on its -x corner,
  0 = Part 1 flat on the base (theta1 = omega1 = 0, the contact carries a moment);
* interface ``c``: +1 = Part 2 rocks on the +x top corner of Part 1 (phi > 0), -1, 0 = flat;
* top friction ``tau``: +1 / -1 = the load point of Part 2 slides towards +x / -x under the beam,
  friction F = -tau mu N; 0 = it sticks (|F| <= mu N, F from the constraint x_p' = 0);
* ``sigma`` = sign of theta2: which top corner of Part 2 is raised and carries the beam load N.

Patterns: (b, c) = (+,+) 1A, (-,-) 1B, (+,-) 2A, (-,+) 2B, (+,0) 3A, (-,0) 3B; not in the thesis:
(0,+) 4A / (0,-) 4B = Part 1 resting flat, Part 2 rocking on it; (0,0) "rest".

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
  (theta2 = 0) the rising corner strikes it: an impact (dem.rocking.impacts).  Locked contacts are constraints with Lagrange multipliers; the multiplier of a
lock, taken in the pivot geometry +-1, is T times the normal force at the opposite corner.
For a single block this is Housner's (1963) equation I_O th'' = -m g R sin(alpha - th) - m a R
cos(alpha - th) (theta > 0).  Units: SI (m, kg, s, N, rad).
"""

from __future__ import annotations

import math
from dataclasses import dataclass, field

import numpy as np

PATTERNS = ("rest", "1A", "1B", "2A", "2B", "3A", "3B", "4A", "4B")


def pattern_name(b: int, c: int) -> str:
    """Pattern label of the contact modes (b, c); see the module docstring."""
    if b == 0 and c == 0:
        return "rest"
    if c == 0:
        return "3A" if b > 0 else "3B"
    if b == 0:
        return "4A" if c > 0 else "4B"
    if b == c:
        return "1A" if b > 0 else "1B"
    return "2A" if b > 0 else "2B"


def flow_kind(b: int, c: int, tau: int) -> str:
    """Which set of equations governs the mode (b, c, tau)."""
    if b != 0 and c != 0:
        return "free" if tau else "free_stick"
    if b != 0:
        return "p3" if tau else "p3_stuck"
    if c != 0:
        return "p4" if tau else "p4_stuck"
    return "rest"


STATIONARY = ("rest", "p3_stuck", "p4_stuck")


@dataclass(frozen=True)
class RockingParams:
    """Physical parameters of the two-block model (SI units).

    thickness T (m, both parts), h1/m1 lower part (m, kg), h2/m2 upper part, top_load N (N,
    vertical, on the top of Part 2), top_friction mu (-): the beams exert a horizontal friction of
    magnitude up to mu N on the load point; gravity g (m/s2); load_point "corner" (N acts on the
    raised top corner of Part 2, as in the thesis' equations of motion 5-9..5-14) or "centre" (on
    the middle of the top face, as in its uplift criterion 5-3); locked: the interface never opens
    (the two parts are one block, Pattern 3 only); top_contact "sliding" (the thesis: N fixed in
    space, friction up to mu N) or "co-moving" (N is a point mass N/g moving with the load point,
    no friction; ``mN`` its mass, kg).
    """

    thickness: float
    h1: float
    m1: float
    h2: float
    m2: float
    top_load: float = 0.0
    top_friction: float = 0.0
    gravity: float = 9.81
    load_point: str = "corner"
    locked: bool = False
    top_contact: str = "sliding"

    R1: float = field(init=False)
    R2: float = field(init=False)
    al1: float = field(init=False)
    al2: float = field(init=False)
    Ic1: float = field(init=False)
    Ic2: float = field(init=False)
    IO1: float = field(init=False)
    IO2: float = field(init=False)
    Fmax: float = field(init=False)
    mN: float = field(init=False)
    load_geom: dict = field(init=False, repr=False, compare=False)

    def __post_init__(self) -> None:
        for name in ("thickness", "h1", "m1", "h2", "m2"):
            v = getattr(self, name)
            if not (v > 0 and math.isfinite(v)):
                raise ValueError(f"{name} must be > 0, got {v}")
        for name in ("top_load", "top_friction", "gravity"):
            v = getattr(self, name)
            if not (v >= 0 and math.isfinite(v)):
                raise ValueError(f"{name} must be >= 0, got {v}")
        if self.load_point not in ("corner", "centre"):
            raise ValueError(f"load_point must be 'corner' or 'centre', got {self.load_point!r}")
        if self.top_contact not in ("sliding", "co-moving"):
            raise ValueError(f"top_contact must be 'sliding' or 'co-moving', got {self.top_contact!r}")
        if self.top_contact == "co-moving" and self.top_load > 0 and not self.gravity > 0:
            raise ValueError("a co-moving top load N needs gravity > 0 (its mass is N / g)")
        T = self.thickness
        s = object.__setattr__
        s(self, "R1", 0.5 * math.hypot(T, self.h1))
        s(self, "R2", 0.5 * math.hypot(T, self.h2))
        s(self, "al1", math.atan2(T, self.h1))
        s(self, "al2", math.atan2(T, self.h2))
        s(self, "Ic1", self.m1 * (T * T + self.h1 ** 2) / 12.0)
        s(self, "Ic2", self.m2 * (T * T + self.h2 ** 2) / 12.0)
        s(self, "IO1", self.m1 * (T * T + self.h1 ** 2) / 3.0)
        s(self, "IO2", self.m2 * (T * T + self.h2 ** 2) / 3.0)
        comoving = self.top_contact == "co-moving"
        s(self, "Fmax", 0.0 if comoving else self.top_friction * self.top_load)
        s(self, "mN", self.top_load / self.gravity if comoving and self.top_load > 0 else 0.0)
        geom = {}
        for s2 in (1, -1):
            for sig in (1, -1):
                if self.load_point == "corner":
                    u = -(sig + s2) * T / 2.0
                else:
                    u = -s2 * T / 2.0
                geom[(s2, sig)] = (math.hypot(u, self.h2), math.atan2(u, self.h2))
        s(self, "load_geom", geom)

    # convenience -------------------------------------------------------------------------
    @property
    def mass(self) -> float:
        return self.m1 + self.m2

    @property
    def height(self) -> float:
        return self.h1 + self.h2

    @property
    def comoving(self) -> bool:
        """True when the top load is a mass moving with the top (top_contact co-moving, N > 0)."""
        return self.mN > 0.0

    @property
    def ndof(self) -> int:
        """Velocities in maximal coordinates: two planar bodies, plus the beam's (x, z) if co-moving."""
        return 8 if self.comoving else 6

    @property
    def friction(self) -> bool:
        """True when the top friction can act (mu N > 0)."""
        return self.Fmax > 0.0

    def scales(self) -> dict:
        """Scales for tolerances: angular acceleration, angular velocity, force."""
        hmin = min(self.h1, self.h2, self.thickness)
        g = self.gravity if self.gravity > 0 else 9.81
        return {
            "acc": g / hmin,
            "vel": math.sqrt(g / hmin),
            "force": self.mass * g + self.top_load,
            "length": self.height,
        }


def geometry(P: RockingParams, b: int, c: int) -> tuple[int, int]:
    """Pivot geometry (s1, s2) used for the mode (b, c); flat contacts use a reference side."""
    s1 = b if b != 0 else (c if c != 0 else 1)
    s2 = c if c != 0 else s1
    return s1, s2


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


# ------------------------------------------------------------------------------------------
# energy and kinematics
# ------------------------------------------------------------------------------------------
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


def _rot(th: float, u: float, w: float) -> np.ndarray:
    return np.array([u * math.cos(th) + w * math.sin(th), -u * math.sin(th) + w * math.cos(th)])


def points(P: RockingParams, s1: int, s2: int, th1: float, th2: float) -> dict:
    """World positions (x, z) of the centres, corners and pivots for geometry (s1, s2).

    Keys: P1 (base pivot), Q (Part 2's pivot), G1, G2, B+ / B- (Part 1 bottom corners),
    C+ / C- (Part 1 top corners), D+ / D- (Part 2 bottom corners), E+ / E- (Part 2 top corners).
    """
    T, h1, h2 = P.thickness, P.h1, P.h2
    P1 = np.array([s1 * T / 2.0, 0.0])

    def on1(u, w):
        return P1 + _rot(th1, u - s1 * T / 2.0, w)

    Q = on1(s2 * T / 2.0, h1)

    def on2(u, w):
        return Q + _rot(th2, u - s2 * T / 2.0, w)

    out = {"P1": P1, "Q": Q, "G1": on1(0.0, h1 / 2), "G2": on2(0.0, h2 / 2)}
    for sgn, key in ((1, "+"), (-1, "-")):
        out["B" + key] = on1(sgn * T / 2, 0.0)
        out["C" + key] = on1(sgn * T / 2, h1)
        out["D" + key] = on2(sgn * T / 2, 0.0)
        out["E" + key] = on2(sgn * T / 2, h2)
        # load point p when sigma = sgn: the raised top corner (u = -sigma T/2) or the top centre
        out["p" + key] = on2(-sgn * T / 2 if P.load_point == "corner" else 0.0, h2)
    return out


def perp(r: np.ndarray) -> np.ndarray:
    """d r / d theta for a body-fixed vector r under rotation theta (top towards +x)."""
    return np.array([r[1], -r[0]])


def maximal_velocity(P: RockingParams, s1: int, s2: int, th1, th2, w1, w2, sig: int = 1) -> np.ndarray:
    """Planar body velocities (x_G1', z_G1', w1, x_G2', z_G2', w2) from the generalised ones;
    with a co-moving top load also the beam's (x', z'), that of Part 2's point at p (sigma = sig)."""
    p = points(P, s1, s2, th1, th2)
    vG1 = w1 * perp(p["G1"] - p["P1"])
    vQ = w1 * perp(p["Q"] - p["P1"])
    vG2 = vQ + w2 * perp(p["G2"] - p["Q"])
    v = [vG1[0], vG1[1], w1, vG2[0], vG2[1], w2]
    if P.comoving:
        vp = vQ + w2 * perp(p["p" + ("+" if sig > 0 else "-")] - p["Q"])
        v += [vp[0], vp[1]]
    return np.array(v)


def mass6(P: RockingParams) -> np.ndarray:
    """Mass matrix in maximal coordinates (6 x 6; 8 x 8 with the co-moving beam, a point mass)."""
    d = [P.m1, P.m1, P.Ic1, P.m2, P.m2, P.Ic2]
    if P.comoving:
        d += [P.mN, P.mN]
    return np.diag(d)


def _point_rows(X: np.ndarray, G: np.ndarray, body: int, n: int = 6) -> tuple[np.ndarray, np.ndarray]:
    """Rows giving the (x, z) velocity of the material point at X of body 0/1 (n-vector each)."""
    rx = np.zeros(n)
    rz = np.zeros(n)
    o = 3 * body
    r = X - G
    rx[o:o + 3] = (1.0, 0.0, r[1])
    rz[o:o + 3] = (0.0, 1.0, -r[0])
    return rx, rz


def contact_rows(P: RockingParams, s1: int, s2: int, th1: float, th2: float) -> tuple[dict, dict]:
    """Velocity rows of every possible contact point, and the velocity-product terms.

    Keys ``base_x+``, ``base_z+`` (velocity of Part 1's material point at its bottom corner B+),
    ``if_x+``, ``if_z+`` (velocity of Part 2's bottom corner D+ relative to Part 1's material
    point at the same place), ``if_n+`` (the latter along Part 1's top normal n1 = (sin th1,
    cos th1)); the same with ``-``.  A pivot is a hinge (x and z rows at its corner); a flat
    contact is a hinge at the + corner plus the normal row at the - corner.  A positive impulse
    along a z (base) or n (interface) row pushes the bodies apart.

    The second dict holds, for each row, the function w -> (d row/dt) . v (centripetal terms)
    needed at acceleration level: a_X = a_G + w' perp(X - G) - w^2 (X - G).
    """
    p = points(P, s1, s2, th1, th2)
    n1 = np.array([math.sin(th1), math.cos(th1)])
    rows, cent = {}, {}
    nd = P.ndof

    for key in ("+", "-"):
        if P.comoving:
            # beam on the load point p(sigma = key): beam velocity - velocity of Part 2's point at p
            X = p["p" + key]
            px, pz = _point_rows(X, p["G2"], 1, nd)
            ex, ez = np.zeros(nd), np.zeros(nd)
            ex[6], ez[7] = 1.0, 1.0
            rows["beam_x" + key], rows["beam_z" + key] = ex - px, ez - pz
            rp = X - p["G2"]
            cent["beam_x" + key] = lambda v, r=rp: v[5] ** 2 * r[0]
            cent["beam_z" + key] = lambda v, r=rp: v[5] ** 2 * r[1]
        B = p["B" + key]
        bx, bz = _point_rows(B, p["G1"], 0, nd)
        rows["base_x" + key], rows["base_z" + key] = bx, bz
        rB = B - p["G1"]
        cent["base_x" + key] = lambda v, r=rB: -v[2] ** 2 * r[0]
        cent["base_z" + key] = lambda v, r=rB: -v[2] ** 2 * r[1]
        X = p["D" + key]
        ax2, az2 = _point_rows(X, p["G2"], 1, nd)
        ax1, az1 = _point_rows(X, p["G1"], 0, nd)
        rows["if_x" + key], rows["if_z" + key] = ax2 - ax1, az2 - az1
        rows["if_n" + key] = n1[0] * (ax2 - ax1) + n1[1] * (az2 - az1)
        r2, r1 = X - p["G2"], X - p["G1"]

        def _c(v, r2=r2, r1=r1):
            return -v[5] ** 2 * r2 + v[2] ** 2 * r1

        def _cn(v, r2=r2, r1=r1, X=X):
            # d/dt[(v2 - v1) . n1] = (a2 - a1) . n1 + (v2 - v1) . n1', n1' = w1 (cos th1, -sin th1)
            rel_v = (v[3:5] + v[5] * perp(r2)) - (v[0:2] + v[2] * perp(r1))
            dn = v[2] * np.array([math.cos(th1), -math.sin(th1)])
            return float(_c(v) @ n1 + rel_v @ dn)

        cent["if_x" + key] = lambda v, f=_c: f(v)[0]
        cent["if_z" + key] = lambda v, f=_c: f(v)[1]
        cent["if_n" + key] = _cn
    return rows, cent


def mode_row_keys(b: int, c: int, sig: int = 1, comoving: bool = False) -> list[str]:
    """Constraint rows of the contact modes (b, c) in maximal coordinates; with a co-moving top
    load the beam is held (x and z) at the load point of sigma = sig."""
    keys = []
    if comoving:
        k = "+" if sig > 0 else "-"
        keys += ["beam_x" + k, "beam_z" + k]
    if b != 0:
        k = "+" if b > 0 else "-"
        keys += ["base_x" + k, "base_z" + k]
    else:
        keys += ["base_x+", "base_z+", "base_z-"]
    if c != 0:
        k = "+" if c > 0 else "-"
        keys += ["if_x" + k, "if_z" + k]
    else:
        keys += ["if_x+", "if_z+", "if_n-"]
    return keys


def constrained_acc_maximal(P: RockingParams, mode: tuple, y, a: float, F: float) -> np.ndarray:
    """Accelerations from Newton-Euler in maximal coordinates with contact constraints (KKT).

    Independent of the Lagrangian closed forms; the tests use it to check them.  Bodies are free
    planar rigid bodies (x_G, z_G, theta); the contact modes (b, c) of ``mode`` are holonomic
    constraints (see :func:`contact_rows`) differentiated twice; gravity, the inertia force
    -m a, the top load N (vertical, on the load point) and the friction F (horizontal, on the
    load point) act.  Returns (x_G1'', z_G1'', w1', x_G2'', z_G2'', w2') and the multipliers.
    """
    b, c, tau, sig = mode
    th1, phi, w1, wphi = y
    th2, w2 = th1 + phi, w1 + wphi
    s1, s2 = geometry(P, b, c)
    v = maximal_velocity(P, s1, s2, th1, th2, w1, w2, sig)
    p = points(P, s1, s2, th1, th2)
    rows, cent = contact_rows(P, s1, s2, th1, th2)
    keys = mode_row_keys(b, c, sig, P.comoving)
    Gm = np.array([rows[k] for k in keys])
    rhs = np.array([-cent[k](v) for k in keys])
    M = mass6(P)
    nd = P.ndof
    f = np.zeros(nd)
    f[:6] = [-P.m1 * a, -P.m1 * P.gravity, 0.0, -P.m2 * a, -P.m2 * P.gravity, 0.0]
    if P.comoving:
        # the beam: its weight N and its inertia force -m_N a act on it, it bears on p
        f[6:8] = [-P.mN * a, -P.top_load]
    else:
        Lp, gp = P.load_geom[(s2, sig)]
        xp = p["Q"] + Lp * np.array([math.sin(th2 + gp), math.cos(th2 + gp)])
        force = np.array([F, -P.top_load])
        r = xp - p["G2"]
        f[3:5] += force
        f[5] += force @ perp(r)
    n = len(keys)
    K = np.zeros((nd + n, nd + n))
    K[:nd, :nd] = M
    K[:nd, nd:] = -Gm.T
    K[nd:, :nd] = Gm
    sol = np.linalg.solve(K, np.concatenate([f, rhs]))
    return sol[:nd], dict(zip(keys, sol[nd:]))

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
