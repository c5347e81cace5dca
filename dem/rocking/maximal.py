"""The two parts as free planar rigid bodies (maximal coordinates x_G, z_G, theta per body).

World positions of corners, centres and pivots (:func:`points`), body velocities from the
generalised ones (:func:`maximal_velocity`), the mass matrix (:func:`mass6`), the velocity rows of
every contact as a constraint (:func:`contact_rows`, :func:`mode_row_keys`): what the impacts
(dem.rocking.impacts) work with.  :func:`constrained_acc_maximal` solves Newton-Euler with these
constraints, independently of the Lagrangian closed forms of :mod:`dem.rocking.equations`; the
tests use it to check them.  Conventions: :mod:`dem.rocking.params`.
"""

from __future__ import annotations

import math

import numpy as np

from dem.rocking.params import RockingParams
from dem.rocking.patterns import geometry


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
