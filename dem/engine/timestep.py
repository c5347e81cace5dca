"""Critical time step of the explicit scheme.

For a mass-spring pair, symplectic Euler is stable for dt < 2 / omega, omega = sqrt(k / m); a
viscous ratio zeta lowers that to (2 / omega)(sqrt(1 + zeta^2) - zeta).  For a box we bound the
highest frequency by assuming every face of the block in contact over an area A_f (at most the
whole face) with joints of stiffness kn (normal) and ks (shear) per unit area, against a neighbour
of equal mass (factor 2 on k/m):

  translation along x:  k_x = kn (A_+x + A_-x) + ks (A_+y + A_-y + A_+z + A_-z)
  rotation about x:     k_rx = kn (f_+z + f_-z) l_x l_y^3/12 + kn (f_+y + f_-y) l_x l_z^3/12
                               (bending of the faces normal to z and y; f = A_f / face area)
                               + ks (A_+x + A_-x) (l_y^2 + l_z^2)/12      (torsion of x faces)
                               + ks (A_+z + A_-z) l_z^2/4 + ks (A_+y + A_-y) l_y^2/4
  omega^2 = 2 max(k_x / m, ..., k_rx / I_x, ...)

(and likewise for y, z), which covers thin blocks whose rotation about the long axis is the
fastest mode.  With every A_f the whole face this is a bound for any configuration.
dt_crit = min over movable blocks; the default step is ``safety * dt_crit``.

Capped faces.  A light block with a large face (a timber roof beam, 0.158 kg on 525 x 30 mm)
would set dt for the whole scene although it only ever touches the walls on small patches.
:func:`face_area_caps` caps the contact area of such faces (blocks with a face larger than the
largest face of a typical block, the 90th percentile over the movable blocks) at the smallest
area for which the capped bound underestimates the block's worst-case stiffness by at most
``0.5 / safety^2``, but never below the block's largest contact patch at the start.  Stability
argument: whatever patch a block later makes, even whole faces, the step in use stays below
sqrt(0.5) of the true critical step.  When a patch exceeds its cap, the simulation raises the
cap to twice that patch (whole faces once that reaches the largest face) and shortens the step
(dem.engine.simulation); any cap above the smallest allowed one keeps the argument.  A cap at the
typical face itself would be too tight: for the box models' roof beams (which touch the
walls and the steel blocks on 30 x 50 mm patches) it lets the beams set dt at 3.2e-5 s against
the bricks' 4.95e-5 s (benchmarks/RESULTS.md, "Engine containers, stages, launch and
throughput").
"""

from __future__ import annotations

import numpy as np


VERTEX_LEVER = 3.0  # the vertices' second moment of area over the face's (rectangle)


def omega2_bound(size, mass, inertia, face_area, kn, ks):
    """omega^2 bound per block; face_area [N,3,2]: contact area of the -/+ faces of each axis."""
    omega2 = np.zeros(len(size))
    full = np.stack([size[:, 1] * size[:, 2], size[:, 0] * size[:, 2],
                     size[:, 0] * size[:, 1]], axis=1)
    frac = face_area / np.maximum(full, 1e-300)[:, :, None]
    area = face_area.sum(axis=2)  # both faces of each axis
    fsum = frac.sum(axis=2)
    for a in range(3):
        b, c = (a + 1) % 3, (a + 2) % 3
        la, lb, lc = size[:, a], size[:, b], size[:, c]
        k_t = kn * area[:, a] + ks * (area[:, b] + area[:, c])
        k_r = (kn * fsum[:, c] * la * lb**3 / 12.0 + kn * fsum[:, b] * la * lc**3 / 12.0
               + ks * area[:, a] * (lb**2 + lc**2) / 12.0
               + ks * (area[:, c] * lc**2 + area[:, b] * lb**2) / 4.0)
        omega2 = np.maximum(omega2, 2.0 * np.maximum(k_t / mass, k_r / inertia[:, a]))
    return omega2


def full_face_areas(size) -> np.ndarray:
    """[N,3,2] areas of the -/+ faces normal to each body axis, m^2."""
    size = np.asarray(size, dtype=float)
    full = np.stack([size[:, 1] * size[:, 2], size[:, 0] * size[:, 2],
                     size[:, 0] * size[:, 1]], axis=1)
    return np.repeat(full[:, :, None], 2, axis=2)


def critical_time_step(size: np.ndarray, mass: np.ndarray, inertia: np.ndarray,
                       movable: np.ndarray, kn: float, ks: float, zeta: float,
                       face_area: np.ndarray | None = None, beta: float = 0.0) -> float:
    """Critical time step (s); size [N,3] full edges (m), inertia [N,3] (kg m^2), face_area
    [N,3,2] contact areas assumed for the faces (default: whole faces, a strict bound).

    ``beta`` (s): the largest damping time of a stiffness-proportional normal dashpot
    (dem.engine.laws.normal_law_stiffness_damped), which gives a mode of frequency omega the
    ratio beta omega / 2; its dashpots act at the patch's vertices, whose second moment of area
    is up to 3x the face's (a rectangle: A b^2/4 against A b^2/12), so the rocking modes may get
    3x that.  The step takes zeta_eff = max(zeta, VERTEX_LEVER beta omega / 2) at the highest
    omega (beta = 0: zeta, the step of before)."""
    size = np.asarray(size, dtype=float)
    if face_area is None:
        face_area = full_face_areas(size)
    movable = np.asarray(movable, dtype=bool)
    if not movable.any():
        return np.inf
    w2 = omega2_bound(size[movable], np.asarray(mass, float)[movable],
                      np.asarray(inertia, float)[movable], np.asarray(face_area)[movable], kn, ks)
    omega = np.sqrt(w2.max())
    if beta > 0.0:
        zeta = max(zeta, VERTEX_LEVER * beta * omega / 2.0)
    return float(2.0 / omega * (np.sqrt(1.0 + zeta**2) - zeta))


def face_area_caps(size, mass, inertia, movable, kn, ks, safety,
                   patch=None) -> tuple[np.ndarray, np.ndarray]:
    """Face areas to use in the bound (see module docstring) and a per-block cap (m^2; inf for
    blocks left uncapped).  ``patch`` [N]: each block's largest contact patch at the start (m^2;
    default 0).  Returns (face_area [N,3,2], cap [N])."""
    size = np.asarray(size, dtype=float)
    full = full_face_areas(size)
    cap = np.full(len(size), np.inf)
    movable = np.asarray(movable, dtype=bool)
    if movable.sum() < 2:
        return full, cap
    typical = float(np.percentile(full[movable].max(axis=(1, 2)), 90))
    ratio = 0.5 / safety**2
    w_full = omega2_bound(size, mass, inertia, full, kn, ks)

    def allowed(c):  # [N] caps c: the capped bound is within `ratio` of the full one
        capped = np.minimum(full, c[:, None, None])
        return w_full <= ratio * omega2_bound(size, mass, inertia, capped, kn, ks)

    eligible = movable & (full.max(axis=(1, 2)) > typical)
    ok = eligible & allowed(np.full(len(size), typical))
    # the smallest allowed cap in [largest start patch, typical]: the capped bound grows with
    # the cap, so bisect (40 halvings: 1e-12 of the interval)
    lo = np.zeros(len(size)) if patch is None else np.minimum(np.asarray(patch, float), typical)
    hi = np.full(len(size), typical)
    start_ok = allowed(lo)
    for _ in range(40):
        mid = 0.5 * (lo + hi)
        good = allowed(mid)
        hi = np.where(good, mid, hi)
        lo = np.where(good, lo, mid)
    cap_value = np.where(start_ok, lo, hi)
    face_area = np.where(ok[:, None, None], np.minimum(full, cap_value[:, None, None]), full)
    cap[ok] = cap_value[ok]
    return face_area, cap


class Clock:
    """The host clock of a simulation: the time step and what it is made from.

    dt        time step in use (s)
    dt_crit   critical step of the scene with the present area caps (s), :func:`critical_time_step`
    t_anchor, step_anchor
              the time (s) and step count at the last change of dt (or restart of the clock):
              t = t_anchor + (step - step_anchor) dt, so a run never sums dt step by step (no
              rounding that grows with the steps) and a change of dt does not move t
    area_cap  per body, the capped contact area behind dt_crit (m^2, inf: whole faces), and
    face_area per body and face, the areas in the bound (m^2), :func:`face_area_caps`

    Simulation keeps one and reads these names through its own attributes (``sim.dt``,
    ``sim.dt_crit``, ``sim._t_anchor``, ``sim._step_anchor``, ``sim.area_cap``,
    ``sim._face_area``), which are saved in a restart point under those names.
    """

    __slots__ = ("dt", "dt_crit", "t_anchor", "step_anchor", "area_cap", "face_area")

    def __init__(self) -> None:
        self.dt = 0.0
        self.dt_crit = float("inf")
        self.t_anchor = 0.0
        self.step_anchor = 0
        self.area_cap = None
        self.face_area = None

    def time(self, step: int) -> float:
        """t (s) at the start of step ``step``."""
        return self.t_anchor + (step - self.step_anchor) * self.dt

    def times(self, step: int, k: int) -> np.ndarray:
        """t (s) at the start of steps step, ..., step + k - 1 (the loads of one launch)."""
        return self.t_anchor + (step - self.step_anchor + np.arange(k)) * self.dt

    @staticmethod
    def times_of(clocks: list["Clock"], steps: list[int], k: int) -> np.ndarray:
        """[len(clocks), k]: ``clocks[i].times(steps[i], k)`` for every i, in one pass (the same
        numbers: the same integer offsets, product and sum, element by element)."""
        t_anchor = np.array([c.t_anchor for c in clocks], dtype=float)
        dt = np.array([c.dt for c in clocks], dtype=float)
        offset = np.array([s - c.step_anchor for c, s in zip(clocks, steps)], dtype=np.int64)
        return t_anchor[:, None] + (offset[:, None] + np.arange(k)) * dt[:, None]

    def anchor(self, t: float, step: int) -> None:
        """Count time from t at step ``step`` on (before a change of dt, or to restart t)."""
        self.t_anchor, self.step_anchor = t, step
