"""In-plane limit analysis of dry stretcher-bond walls (thesis eq 3-1 .. 3-3, after D'Ayala and
Speranza 2003).  Load factor lambda = a/g at incipient collapse.

Angles (all measured from the VERTICAL, so that tan(alpha) = horizontal run / vertical rise):
    alpha_c  crack angle: a stepped crack from the leeward bottom corner; it follows the bond
             when tan(alpha_c) = s/h (s stagger, h course height)
    alpha_b  brick (bond) angle, tan(alpha_b) = s/h
    alpha_p  wall (panel) angle, tan(alpha_p) = L/H
The thesis' text calls alpha_c "the angle between the main crack line and the bottom line", but
its formulas and worked values (minimum at 56.3 deg = atan(1.5) for s/h = 1.5) only hold with
the angle from the vertical; this module uses that reading.

    sliding      lambda_s = mu (s/h) / tan(alpha_c)                                   (3-1)
    overturning  lambda_o = (tan^2 a + mu s/h) / (2 tan a)       a <= min(alpha_p, alpha_b) (3-2a)
                          = tan(a) / 2                           alpha_b < a < alpha_p     (3-2b)
                          = [tan^2 a (3 tan a - 2 tan p + 2 mu) - mu tan p (2 tan a - s/h)]
                            / (3 tan^2 a - tan^2 p) * tan p / tan a  alpha_p < a < alpha_b (3-2c)
                          = tan a tan p (3 tan a - 2 tan p) / (3 tan^2 a - tan^2 p)
                                                                 a >= max(alpha_b, alpha_p) (3-2d)
    lambda_c = min over alpha_c of min(lambda_o, lambda_s)                                 (3-3)

Sliding needs a crack along the joints, so its crack can be no flatter than the bond:
tan(alpha_c) <= s/h, and its minimum is lambda_s = mu at the bond angle.  Overturning is searched
over all crack angles.
Check against the thesis' worked example (Section 3.4.2, s/h = 1.5, mu = 0.66): this module gives
sliding 0.66, overturning 0.75 (L/H = 3, 2.14), 0.652 (L/H = 1), 0.545 (L/H = 0.75); the thesis
reads 0.67, 0.78, 0.65, 0.56 off its curves ("the small difference relates to the resolution used
in the calculations").
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np


def sliding_factor(tan_c, mu, s_over_h):
    """lambda_s (eq 3-1)."""
    return mu * s_over_h / np.asarray(tan_c, dtype=float)


def overturning_factor(tan_c, mu, s_over_h, l_over_h):
    """lambda_o (eq 3-2a..d) for crack angles with tan(alpha_c) = tan_c."""
    t = np.asarray(tan_c, dtype=float)
    tb, tp = s_over_h, l_over_h
    a = (t**2 + mu * s_over_h) / (2 * t)
    b = t / 2
    with np.errstate(divide="ignore", invalid="ignore"):
        c = ((t**2 * (3 * t - 2 * tp + 2 * mu) - mu * tp * (2 * t - s_over_h))
             / (3 * t**2 - tp**2) * tp / t)
        d = t * tp * (3 * t - 2 * tp) / (3 * t**2 - tp**2)
    return np.where(t <= min(tb, tp), a,
                    np.where((t > tb) & (t < tp), b,
                             np.where((t > tp) & (t < tb), c, d)))


@dataclass
class LimitAnalysis:
    """Result of eq 3-3 for one wall."""

    lambda_sliding: float
    alpha_sliding_deg: float      # from the vertical
    lambda_overturning: float
    alpha_overturning_deg: float  # from the vertical
    lambda_c: float
    mechanism: str                # "sliding" | "overturning" | "mixed" (within 5 % of each other)

    def as_dict(self) -> dict:
        return dict(self.__dict__)


def in_plane_limit(mu: float, s_over_h: float, l_over_h: float, n: int = 20001) -> LimitAnalysis:
    """Minimum of eq 3-1 and 3-2 over the crack angle (grid of n angles, 0.004 deg spacing)."""
    alpha = np.linspace(1e-3, np.radians(89.0), n)
    t = np.tan(alpha)
    slide = np.where(t <= s_over_h * (1 + 1e-12), sliding_factor(t, mu, s_over_h), np.inf)
    over = overturning_factor(t, mu, s_over_h, l_over_h)
    over = np.where(np.isfinite(over) & (over > 0), over, np.inf)
    i_s, i_o = int(np.argmin(slide)), int(np.argmin(over))
    ls, lo = float(slide[i_s]), float(over[i_o])
    lc = min(ls, lo)
    if abs(ls - lo) <= 0.05 * lc:
        mech = "mixed"
    else:
        mech = "sliding" if ls < lo else "overturning"
    return LimitAnalysis(ls, float(np.degrees(alpha[i_s])), lo, float(np.degrees(alpha[i_o])),
                         lc, mech)


def elastic_tipping_factor(b: float, h: float, density: float, kn: float,
                           g: float = 9.81) -> float:
    """Load factor tan(theta) at which a block (or a wall tipping as one body about its base) of
    thickness b [m] in the tipping direction, height h [m] and density [kg/m3] tips on a penalty
    joint of normal stiffness kn [Pa/m] (docs/engine.md section 5):

        tan theta = b/h - (6 rho g b cos theta / (kn h))^(1/3)

    (the rigid value b/h minus the rotation the elastic joint allows before the heel lifts and
    the triangular pressure block runs out of width).  Solved by fixed-point iteration on theta
    (the offset depends on theta through cos theta only: a contraction).
    """
    if min(b, h, density, kn) <= 0:
        raise ValueError("b, h, density and kn must be > 0")
    lam = b / h
    for _ in range(50):
        cos_t = 1.0 / np.sqrt(1.0 + lam * lam)
        new = b / h - (6.0 * density * g * b * cos_t / (kn * h)) ** (1.0 / 3.0)
        if abs(new - lam) < 1e-14:
            break
        lam = new
    return float(lam)
