"""Closed-form results and post-processing of the two-block rocking model.

Closed forms (Housner 1963, "The behavior of inverted pendulum structures during earthquakes",
BSSA 53(2)), for a rigid block rocking on its corners (T thickness, z_G height of the centre of
mass, I_O moment of inertia about a bottom corner, M mass):

* uplift from rest (Pattern 3 about the +x corner, base acceleration a < 0), with the top load N on
  the raised corner (lever c = T; c = T/2 on the top centre):
  - ``sliding`` top (the thesis: N fixed in space, the friction mu N resisting at the top):
      -a > (g M T/2 + N c + mu N H) / (M z_G)
    which is g T / H for a uniform block without load (Housner's g tan alpha), and the thesis'
    eq. 5-4 with N T/2 in place of N T when N acts on the centre of the top;
  - ``co-moving`` top (N a mass m_N = N/g moving with the top, its inertia force m_N a at height H):
      -a > (g M T/2 + N c) / (M z_G + m_N H)
    which is g T / H for a uniform column with any top mass on its corner (the rocking frame,
    Makris & Vassiliou 2013, "Planar rocking response and stability analysis of an array of
    free-standing columns capped with a freely supported rigid beam", EESD 42(3));
  Part 2 alone (Pattern 4) is the same with M -> m2, z_G -> H2/2, H -> H2;
* restitution of a plastic impact on the opposite corner (angular momentum about it conserved):
      r = omega+ / omega- = 1 - M T^2 / (2 I_O)   (= 1 - 3/2 sin^2 alpha for a uniform block)
  and with a co-moving top mass, which passes from one top corner to the other at the same
  instant (generalised momentum about the new corner):
      r = (I_O - M T^2/2 + m_N (H^2 - c^2)) / (I_O + m_N (H^2 + c^2))
  = (1 - 3/2 sin^2 alpha + 3 gamma cos 2 alpha) / (1 + 3 gamma), gamma = m_N / M, for a uniform
  column with the mass on its corner (Makris & Vassiliou 2013);
* free rocking (no load): quarter period by quadrature of the energy integral,
      t_q = int_0^theta0 d theta / sqrt(2 M g (z(theta0) - z(theta)) / I_O),
  and Housner's linearised value t_q = (1/p) arccosh(1 / (1 - theta0/alpha)), p^2 = M g R / I_O.
"""

from __future__ import annotations

import math
from collections import defaultdict

import numpy as np
from scipy.integrate import quad

from dem.rocking.params import RockingParams


def centre_of_mass_height(P: RockingParams) -> float:
    """z_G of the two parts standing upright, m."""
    return (P.m1 * P.h1 / 2 + P.m2 * (P.h1 + P.h2 / 2)) / P.mass


def io_composite(P: RockingParams) -> float:
    """Moment of inertia of the locked pair about a bottom corner of Part 1, kg m2."""
    return P.IO1 + P.IO2 + P.m2 * (P.h1 ** 2 + P.h1 * P.h2)


def uplift_threshold(P: RockingParams, part: str = "whole") -> float:
    """Base acceleration magnitude (m/s2) that lifts the wall from rest, statically.

    ``part = "whole"``: Pattern 3 (both parts as one block); ``"upper"``: Pattern 4 (Part 2 alone
    on a resting Part 1).  N on the raised top corner (lever T) or the top centre (lever T/2)
    following ``P.load_point``; friction mu N resists at the top (lever = height of the top).
    """
    T, g, N, mu = P.thickness, P.gravity, P.top_load, P.top_friction
    lever_N = T if P.load_point == "corner" else T / 2
    if part == "whole":
        M, zG, H = P.mass, centre_of_mass_height(P), P.height
    elif part == "upper":
        M, zG, H = P.m2, P.h2 / 2, P.h2
    else:
        raise ValueError(part)
    if P.top_contact == "co-moving":
        # the beam's weight N on the raised corner restores, its inertia force m_N a at the top
        # overturns; no friction
        return (g * M * T / 2 + N * lever_N) / (M * zG + P.mN * H)
    return (g * M * T / 2 + N * lever_N + mu * N * H) / (M * zG)


def uplift_thresholds(P: RockingParams) -> dict:
    """Closed-form uplift thresholds (m/s2) of the chosen top contact: the whole wall (Pattern 3),
    Part 2 alone (Pattern 4), the lower of the two (the wall leaves rest there) and its pattern."""
    whole, upper = uplift_threshold(P, "whole"), uplift_threshold(P, "upper")
    return {"top_contact": P.top_contact, "whole": whole, "upper": upper,
            "governing": min(whole, upper), "first_pattern": "3" if whole <= upper else "4"}


def thesis_uplift_threshold(P: RockingParams) -> float:
    """The thesis' eq. 5-4/5-5: (T/H)(g + N/M) + 2 mu N / M (uniform block, N at the centre)."""
    M, H, T = P.mass, P.height, P.thickness
    return T / H * (P.gravity + P.top_load / M) + 2 * P.top_friction * P.top_load / M


def housner_restitution(P: RockingParams) -> float:
    """r = 1 - M T^2 / (2 I_O) of the locked pair (Housner's 1 - 1.5 sin^2 alpha if uniform);
    with a co-moving top mass m_N (lever c = T on the corner, T/2 on the centre):
    r = (I_O - M T^2/2 + m_N (H^2 - c^2)) / (I_O + m_N (H^2 + c^2)) (module docstring)."""
    IO, M, T = io_composite(P), P.mass, P.thickness
    if P.comoving:
        H, mN = P.height, P.mN
        c = T if P.load_point == "corner" else T / 2
        return (IO - M * T * T / 2 + mN * (H * H - c * c)) / (IO + mN * (H * H + c * c))
    return 1.0 - M * T ** 2 / (2.0 * IO)


def free_rocking_quarter_period(P: RockingParams, theta0: float) -> tuple[float, float]:
    """(exact by quadrature, Housner's linearised) time from theta0 at rest to the impact, s.

    For the locked pair without top load (N = 0).
    """
    M, g, T = P.mass, P.gravity, P.thickness
    zG = centre_of_mass_height(P)
    R = math.hypot(T / 2, zG)
    al = math.atan2(T / 2, zG)
    I = io_composite(P)

    def z(th):
        return R * math.cos(al - th)

    def integrand(th):
        return 1.0 / math.sqrt(2.0 * M * g * (z(theta0) - z(th)) / I)

    # the integrand has an integrable 1/sqrt singularity at theta0: substitute th = theta0 - u^2
    exact = quad(lambda u: 2.0 * u * integrand(theta0 - u * u), 0.0, math.sqrt(theta0),
                 epsabs=0, epsrel=1e-12, limit=200)[0]
    p = math.sqrt(M * g * R / I)
    lin = math.acosh(1.0 / (1.0 - theta0 / al)) / p
    return exact, lin


def top_displacement(P: RockingParams, theta1, theta2):
    """d = H1 sin(theta1) + H2 sin(theta2), m (thesis eq. 5-31)."""
    return P.h1 * np.sin(theta1) + P.h2 * np.sin(theta2)


def cycle_amplitudes(t, d, period: float, t_stop: float):
    """Largest and smallest d in each excitation cycle [k T, (k+1) T), k = 0 .. n-1.

    Returns (index, max, min) arrays (m); cycles without samples are dropped.
    """
    t = np.asarray(t)
    d = np.asarray(d)
    n = int(math.floor(t_stop / period + 1e-9))
    idx, mx, mn = [], [], []
    k_of = np.floor(t / period + 1e-12).astype(int)
    for k in range(n):
        sel = k_of == k
        if sel.any():
            idx.append(k)
            mx.append(float(d[sel].max()))
            mn.append(float(d[sel].min()))
    return np.array(idx, dtype=int), np.array(mx), np.array(mn)


def oscillation_peaks(t, d, threshold: float = 1e-6):
    """The extreme of every lobe of d between sign changes (the thesis' 'amplitude in each
    oscillation of rocking'), lobes with |extreme| <= threshold (m) ignored.

    Returns (t_peak, d_peak).
    """
    t = np.asarray(t)
    d = np.asarray(d)
    if len(d) == 0:
        return np.zeros(0), np.zeros(0)
    s = np.sign(d)
    # split at sign changes (zeros belong to no lobe)
    edges = np.flatnonzero(np.diff(s) != 0) + 1
    tp, dp = [], []
    for seg in np.split(np.arange(len(d)), edges):
        if len(seg) == 0 or s[seg[0]] == 0:
            continue
        j = seg[np.argmax(np.abs(d[seg]))]
        if abs(d[j]) > threshold:
            tp.append(t[j])
            dp.append(d[j])
    return np.array(tp), np.array(dp)


def pattern_statistics(episodes: list, t_total: float) -> dict:
    """Time fraction, number of occurrences and mean duration of each pattern.

    ``episodes`` are (t_start, t_end, pattern, top) maximal runs of one contact mode; runs of the
    same pattern that differ only in the top-friction state are merged.
    """
    merged = []
    for t0, t1, pat, _top in episodes:
        if t1 <= t0 and merged and merged[-1][2] == pat:
            continue
        if merged and merged[-1][2] == pat:
            merged[-1][1] = t1
        else:
            merged.append([t0, t1, pat])
    time_in = defaultdict(float)
    count = defaultdict(int)
    for t0, t1, pat in merged:
        time_in[pat] += max(0.0, t1 - t0)
        count[pat] += 1
    total = sum(time_in.values()) or t_total or 1.0
    return {
        pat: {
            "time_fraction": time_in[pat] / total,
            "occurrences": count[pat],
            "mean_duration": time_in[pat] / count[pat],
        }
        for pat in sorted(time_in, key=lambda p: -time_in[p])
    }, [(float(a), float(b), p) for a, b, p in merged]


def top_friction_demand(P: RockingParams, res, exc, stride: int = 1) -> dict:
    """Friction a co-moving beam needs to follow the top: max of abs(H) / V over the recorded
    moving samples (``equations.top_contact_force``), and the largest impulse ratio at impacts
    (``res.stats['top_impulse_ratio_max']``).  A stick-slip top contact with coefficient mu would
    slip only where these exceed mu.  Samples where the beam's bearing force V is <= 0 (it would
    lift off: flight, outside the model) are left out of the ratio and reported by min_V_over_N."""
    from dem.rocking.equations import top_contact_force

    ratio, t_at, vmin, t_vmin = 0.0, None, math.inf, None
    rocking = 0.0   # the same over the samples within the static stability angle atan(T / H)
    al = math.atan(P.thickness / P.height)
    if P.top_load > 0 and len(res.t):
        for i in range(0, len(res.t), stride):
            b, c, tau, sig = (int(v) for v in res.mode[i])
            if b == 0 and c == 0:
                continue
            y = (res.theta1[i], res.theta2[i] - res.theta1[i], res.omega1[i],
                 res.omega2[i] - res.omega1[i])
            a = float(exc.acceleration_at(res.t[i]))
            H, V = top_contact_force(P, (b, c, tau, sig), y, a)
            if V < vmin:
                vmin, t_vmin = V, float(res.t[i])
            if V <= 0:          # the beam would lift off the wall (flight): no friction question
                continue
            r = abs(H) / V
            if max(abs(res.theta1[i]), abs(res.theta2[i])) <= al:
                rocking = max(rocking, r)
            if r > ratio:
                ratio, t_at = r, float(res.t[i])
    return {"flow_max_abs_H_over_V": float(ratio), "flow_max_at_s": t_at,
            "rocking_max_abs_H_over_V": float(rocking),
            "min_V_over_N": float(vmin / P.top_load) if math.isfinite(vmin) else None,
            "min_V_at_s": t_vmin,
            "impact_max_abs_H_over_V": res.stats.get("top_impulse_ratio_max", 0.0)}
