"""Closed forms of rocking impacts (Housner's restitution, the rigid impact of a body, the energy
and amplitude after an impact) and their measurement on a rotation history (half-cycle peaks,
impact and angular-velocity ratios).
"""

from __future__ import annotations

import math

import numpy as np


G = 9.81
SHAKE_MATERIAL = {"friction": 0.81, "base_friction": 1.5}   # cases/shake/*: the shake cases
BRICK = (0.105, 0.05, 0.035)        # small brick L x W x H, m
BRICK_DENSITY = 0.336 / (0.105 * 0.05 * 0.035)   # kg/m3 (1829)


# ------------------------------------------------------------------------------------------
# closed forms
# ------------------------------------------------------------------------------------------
def housner_r(alpha):
    """Housner's restitution of a uniform rectangular block, r = 1 - 1.5 sin^2 alpha (-);
    alpha = atan(b / h) in rad."""
    return 1.0 - 1.5 * np.sin(alpha) ** 2


def housner_r_block(b: float, h: float) -> float:
    """r of a uniform block of width b and height h (m) rocking in the plane of b."""
    return float(housner_r(math.atan2(b, h)))


def rigid_impact_r(mass: float, i_g: float, c: float, z: float, b: float) -> float:
    """Plastic impact on the new edge O' a distance b (m) from the old pivot O, for a rigid body
    of mass M (kg), centroidal moment of inertia I_G (kg m2) about the rocking axis, and centre
    of mass at (c, z) (m) from O (c towards O'): r = (I_O - M b c) / I_O'."""
    i_o = i_g + mass * (c * c + z * z)
    i_o2 = i_g + mass * ((b - c) ** 2 + z * z)
    return (i_o - mass * b * c) / i_o2


def rocking_energy(theta, c: float, z: float, mass: float = 1.0, g: float = G):
    """E(theta) = M g (z cos theta + c sin theta - z), J (per kg with mass = 1): the rise of the
    centre of mass of a body tilted by theta >= 0 (rad) about its pivot, G at (c, z) from it."""
    th = np.abs(np.asarray(theta, dtype=float))
    return mass * g * (z * np.cos(th) + c * np.sin(th) - z)


def amplitude_after_impact(theta0: float, r: float, c0: float, z0: float,
                           c1: float | None = None, z1: float | None = None) -> float:
    """Amplitude (rad) reached after an impact of restitution r, released from theta0 at rest
    about a pivot with G at (c0, z0), rocking next about a pivot with G at (c1, z1) (default the
    same): solves E1(theta1) = r^2 E0(theta0) by bisection on [0, atan(c1/z1)]."""
    c1 = c0 if c1 is None else c1
    z1 = z0 if z1 is None else z1
    target = r * r * float(rocking_energy(theta0, c0, z0))
    lo, hi = 0.0, math.atan2(c1, z1)   # E1 increases on [0, alpha1]
    if target >= float(rocking_energy(hi, c1, z1)):
        return hi
    for _ in range(200):
        mid = 0.5 * (lo + hi)
        if float(rocking_energy(mid, c1, z1)) < target:
            lo = mid
        else:
            hi = mid
    return 0.5 * (lo + hi)


# ------------------------------------------------------------------------------------------
# measuring on a history
# ------------------------------------------------------------------------------------------
def half_cycle_peaks(t, theta, rel_floor: float = 0.02, return_frac: float = 0.3):
    """Half-cycle amplitudes of a rocking history: (t_peak, theta_peak) of the extremes of
    |theta| between impacts.

    A lobe ends at a sign change of theta or when |theta| falls below ``return_frac`` of the
    lobe's largest value (a return to the upright position without crossing it: a bounce on
    the same side); after such a return the next lobe starts once |theta| grows again.  Its
    peak is the largest |theta| in it.  Peaks below ``rel_floor`` of the largest are dropped
    (the rattle at rest), and so is a last lobe that never turned back.  theta in rad, t in s."""
    t = np.asarray(t, dtype=float)
    th = np.asarray(theta, dtype=float)
    a = np.abs(th)
    if len(a) == 0:
        return np.zeros(0), np.zeros(0)
    floor = rel_floor * a.max()
    peaks = []
    i_best, best, waiting, sign = None, 0.0, False, 0

    def close():
        if i_best is not None and best > floor:
            peaks.append(i_best)

    for i in range(len(a)):
        s = int(np.sign(th[i]))
        if s != 0 and sign != 0 and s != sign:          # crossed the upright position
            close()
            i_best, best, waiting = i, a[i], False
        elif waiting:
            if i > 0 and a[i] > a[i - 1]:               # rising again: a new lobe
                i_best, best, waiting = i, a[i], False
        else:
            if i_best is None or a[i] > best:
                i_best, best = i, a[i]
            elif a[i] < return_frac * best:             # came back without crossing
                close()
                i_best, best, waiting = None, 0.0, True
        if s != 0:
            sign = s
    if i_best is not None and not waiting and a[-1] < 0.9 * best and i_best not in peaks:
        close()
    idx = np.array(peaks, dtype=int)
    return t[idx], th[idx]


def impact_ratios(peaks, pivot_pos: tuple[float, float], pivot_neg: tuple[float, float] | None = None
                  ) -> dict:
    """Per-impact ratios from successive half-cycle peaks (rad, signed).

    ``pivot_pos`` = (c, z) of the centre of mass seen from the pivot of the theta > 0 lobes (m),
    ``pivot_neg`` the same for theta < 0 (default: the same).  Returns lists ``amplitude_ratio``
    (A_{k+1} / A_k), ``energy_ratio`` (E(A_{k+1}) / E(A_k)) and ``r_eq`` (its square root), and
    their means; ``r_eq_same_side``: (E(A_{k+2}) / E(A_k))^(1/4) for peaks two impacts apart on
    the same side (one pivot only: the mean r of the two impacts between them)."""
    pivot_neg = pivot_pos if pivot_neg is None else pivot_neg
    peaks = np.asarray(peaks, dtype=float)
    amp, ene = [], []
    for p0, p1 in zip(peaks[:-1], peaks[1:]):
        c0, z0 = pivot_pos if p0 > 0 else pivot_neg
        c1, z1 = pivot_pos if p1 > 0 else pivot_neg
        amp.append(abs(p1) / abs(p0))
        ene.append(float(rocking_energy(p1, c1, z1) / rocking_energy(p0, c0, z0)))
    # two impacts apart, the same side and pivot: independent of the other pivot's geometry
    same = []
    for p0, p2 in zip(peaks[:-2], peaks[2:]):
        if np.sign(p0) == np.sign(p2):
            c0, z0 = pivot_pos if p0 > 0 else pivot_neg
            same.append(float((rocking_energy(p2, c0, z0) / rocking_energy(p0, c0, z0)) ** 0.25))
    amp, ene, same = np.array(amp), np.array(ene), np.array(same)
    r = np.sqrt(ene)
    mean = lambda x: float(np.mean(x)) if len(x) else None  # noqa: E731
    return {"peaks_rad": peaks.tolist(), "amplitude_ratio": amp.tolist(),
            "energy_ratio": ene.tolist(), "r_eq": r.tolist(), "r_eq_same_side": same.tolist(),
            "mean_amplitude_ratio": mean(amp), "mean_energy_ratio": mean(ene),
            "mean_r_eq": mean(r), "mean_r_eq_same_side": mean(same)}


def omega_ratios(theta, omega, c: float, z: float, i_o_over_m: float, d: float,
                 g: float = G) -> list[float]:
    """omega+ / omega- at every sign change of theta (a single uniform block, pivots symmetric):
    omega read where |theta| = d (rad) just before and just after, carried to theta = 0 with
    omega(0)^2 = omega(d)^2 + 2 E(d) / I_O (E per kg with (c, z), I_O / M = ``i_o_over_m``, m2)."""
    th = np.asarray(theta, dtype=float)
    w = np.asarray(omega, dtype=float)
    lift = 2.0 * float(rocking_energy(d, c, z, 1.0, g)) / i_o_over_m
    out = []
    for k in np.flatnonzero(np.sign(th[:-1]) * np.sign(th[1:]) < 0):
        s = np.sign(th[k])
        # last sample before the crossing with |theta| >= d, first after with |theta| >= d
        j0 = k
        while j0 > 0 and abs(th[j0]) < d:
            j0 -= 1
        j1 = k + 1
        while j1 < len(th) - 1 and abs(th[j1]) < d:
            j1 += 1
        if abs(th[j0]) < d or abs(th[j1]) < d or np.sign(th[j1]) == s:
            continue
        wb = np.interp(d, [abs(th[j0 + 1]), abs(th[j0])], [w[j0 + 1], w[j0]])
        wa = np.interp(d, [abs(th[j1 - 1]), abs(th[j1])], [w[j1 - 1], w[j1]])
        out.append(float(math.sqrt(wa * wa + lift) / math.sqrt(wb * wb + lift)))
    return out


