"""Which contact mode the two-block model is in: complementarity at acceleration level.

A mode is (b, c, tau, sigma): the rocking corner of Part 1 on the base (b = +1, -1, or 0 flat),
of Part 2 on Part 1 (c), the sliding direction of the top load (tau = +1, -1, or 0 stuck) and the
top corner the load bears on (sigma); see dem.rocking.patterns.  At a state (t, y) the candidate modes
are enumerated (the rigid-contact LCP is small) and the one whose conditions all hold is taken:
a contact that opens must accelerate open, a flat contact must press at both corners, a sliding
load must keep sliding, a stuck one must stay within mu N.  Conditions are scaled by tolerances
TOL_REL times the model's scales (:func:`tolerances`).

Stationary modes (rest, a tilted wall held by the top friction) are not integrated: their
conditions are affine in the base acceleration a(t), so :meth:`ModeSelector.stationary_exit`
finds the exit time exactly by root finding on a(t) between its extrema.
"""

from __future__ import annotations

import math
from dataclasses import dataclass

from scipy.optimize import brentq

from dem.rocking.equations import evaluate
from dem.rocking.params import RockingParams
from dem.rocking.patterns import flow_kind
from dem.rocking.recording import RockingError

TOL_REL = 1e-9  # relative tolerance of the complementarity checks (scaled by RockingParams.scales)


@dataclass(frozen=True)
class Tolerances:
    """Absolute tolerances of the complementarity checks and event functions."""

    acc: float        # rad/s2
    force: float      # N
    point_vel: float  # m/s: load point velocity
    point_acc: float  # m/s2: load point acceleration


def tolerances(P: RockingParams) -> Tolerances:
    sc = P.scales()
    return Tolerances(acc=TOL_REL * sc["acc"], force=TOL_REL * sc["force"],
                      point_vel=TOL_REL * sc["vel"] * sc["length"],
                      point_acc=TOL_REL * sc["acc"] * sc["length"])


class ModeSelector:
    """Candidate modes at a state, their complementarity conditions, the consistent one.

    ``exc`` is the table motion (dem.table_motion: ``acceleration_at(t)`` in m/s2,
    ``breakpoints``, ``t_end``); ``stats`` the run's counters (``no_consistent_mode`` is counted
    here).
    """

    def __init__(self, P: RockingParams, exc, tol: Tolerances, stats: dict):
        self.P, self.exc, self.stats = P, exc, stats
        self.tol_a = tol.acc
        self.tol_f = tol.force
        self.tol_x = tol.point_vel
        self.tol_xa = tol.point_acc

    # ------------------------------------------------------------------ candidates
    def sig_choices(self, y):
        th2, w2 = y[0] + y[1], y[2] + y[3]
        if th2 != 0.0:
            return [1 if th2 > 0 else -1], False
        if w2 != 0.0:
            return [1 if w2 > 0 else -1], False
        if self.P.load_point == "centre":
            return [1], False
        return [1, -1], True

    @staticmethod
    def contact_choices(angle, rate, locked=False):
        if locked:
            return [0], False
        if angle != 0.0:
            return [1 if angle > 0 else -1], False
        if rate != 0.0:
            return [1 if rate > 0 else -1], False
        return [1, -1, 0], True

    def conditions(self, mode, y, a, base_free, iface_free, sig_free):
        """Complementarity conditions of a candidate mode: list of (value/scale, strict)."""
        P = self.P
        b, c, tau, sig = mode
        e = evaluate(P, mode, y, a)
        kind = flow_kind(b, c, tau)
        conds = []
        if b != 0 and base_free:
            conds.append((b * e.dd1 / self.tol_a, True))
        if b == 0 and e.base is not None:
            conds += [(e.base[0] / self.tol_f, False), (e.base[1] / self.tol_f, False)]
        if c != 0 and iface_free:
            conds.append((c * (e.dd2 - e.dd1) / self.tol_a, True))
        if c == 0 and e.iface is not None:
            conds += [(e.iface[0] / self.tol_f, False), (e.iface[1] / self.tol_f, False)]
        if P.friction and kind != "rest":
            if tau != 0:
                if abs(e.xd) <= self.tol_x:
                    conds.append((tau * e.xdd / self.tol_xa, True))
            else:
                conds += [((P.Fmax - e.F) / self.tol_f, False), ((P.Fmax + e.F) / self.tol_f, False)]
        if sig_free and kind != "rest":
            conds.append((sig * e.dd2 / self.tol_a, True))
        return conds, e

    def candidates(self, y, t):
        P = self.P
        th1, phi, w1, wphi = y
        bs, base_free = self.contact_choices(th1, w1)
        cs, iface_free = self.contact_choices(phi, wphi, P.locked)
        sigs, sig_free = self.sig_choices(y)
        out = []
        for b in bs:
            for c in cs:
                if b == 0 and c == 0:
                    out.append(((0, 0, 1, sigs[0]), base_free, iface_free, False))
                    continue
                for sig in sigs:
                    if not P.friction:
                        taus = [1]
                    else:
                        xd = evaluate(P, (b, c, 1, sig), y, 0.0, want_forces=False).xd
                        if abs(xd) > self.tol_x:
                            taus = [1 if xd > 0 else -1]
                        else:
                            taus = [1, -1, 0]
                    for tau in taus:
                        if tau == 0 and b != 0 and c == 0 and (w1 != 0.0):
                            continue
                        if tau == 0 and b == 0 and c != 0 and (w1 + wphi != 0.0):
                            continue
                        out.append(((b, c, tau, sig), base_free, iface_free, sig_free))
        return out

    # ------------------------------------------------------------------ choice
    def select(self, t, y, exclude=None, prev=None):
        """The contact mode consistent with complementarity at (t, y) (acceleration level)."""
        a = self.exc.acceleration_at(t)
        ok, bad = [], []
        rest = None
        for mode, bf, ifr, sf in self.candidates(y, t):
            if mode[0] == 0 and mode[1] == 0:
                rest = mode
                continue
            if exclude is not None and tuple(mode) == tuple(exclude):
                continue
            conds, _ = self.conditions(mode, y, a, bf, ifr, sf)
            margin = min((v for v, _ in conds), default=math.inf)
            strict_ok = all((v > 1.0) if strict else (v >= -1.0) for v, strict in conds)
            (ok if strict_ok else bad).append((margin, mode))
        if ok:
            if len(ok) > 1:
                ok.sort(key=lambda m: (-self._closeness(m[1], prev), -m[0]))
            return ok[0][1]
        if rest is not None:
            return rest
        # nothing consistent: take the least violated candidate, and count it
        self.stats["no_consistent_mode"] += 1
        if not bad:
            raise RockingError(f"no admissible contact mode at t = {t:.9g} s, state {list(y)}", t)
        bad.sort(key=lambda m: -m[0])
        return bad[0][1]

    @staticmethod
    def _closeness(mode, prev):
        if prev is None:
            return 0
        return sum(int(x == y) for x, y in zip(mode, prev))

    def check_release(self, cand, t, y, old):
        """Accept the released mode unless another condition of it is clearly violated."""
        a = self.exc.acceleration_at(t)
        _, sf = self.sig_choices(y)
        conds, _ = self.conditions(cand, y, a, False, False, sf)
        if all(v >= -1.0 for v, _ in conds):
            return cand
        return self.select(t, y, exclude=old, prev=cand)

    # ------------------------------------------------------------------ stationary modes
    def _affine_conditions(self, mode, y, t, from_rest):
        """Conditions of ``mode`` at state y as affine functions c0 + c1 a of the base acceleration."""
        if from_rest:
            bf, ifr = True, not self.P.locked
            sigs, sf = self.sig_choices(y)
        else:
            bf = ifr = sf = False
        c0, _ = self.conditions(mode, y, 0.0, bf, ifr, sf)
        c1, _ = self.conditions(mode, y, 1.0, bf, ifr, sf)
        return [(v0[0], v1[0] - v0[0]) for v0, v1 in zip(c0, c1)]

    def _forbidden_intervals(self, mode, y, t):
        """Open intervals of base acceleration a in which the stationary ``mode`` cannot persist."""
        kind = flow_kind(*mode[:3])
        if kind == "rest":
            out = []
            for cand, bf, ifr, sf in self.candidates(y, t):
                if cand[0] == 0 and cand[1] == 0:
                    continue
                lo, hi = -math.inf, math.inf
                for v0, v1 in self._affine_conditions(cand, y, t, True):
                    # candidate fires where v0 + v1 a > 0 (scaled units)
                    if v1 > 0:
                        lo = max(lo, -v0 / v1)
                    elif v1 < 0:
                        hi = min(hi, -v0 / v1)
                    elif v0 <= 0:
                        lo, hi = math.inf, -math.inf
                # ignore intervals of zero width (consistent at one exact acceleration only)
                if lo < hi and (math.isinf(lo) or math.isinf(hi)
                                or hi - lo > 1e-9 * max(1.0, abs(lo), abs(hi))):
                    out.append((lo, hi))
            return out
        lo, hi = -math.inf, math.inf
        for v0, v1 in self._affine_conditions(mode, y, t, False):
            # valid where v0 + v1 a >= 0
            if v1 > 0:
                lo = max(lo, -v0 / v1)
            elif v1 < 0:
                hi = min(hi, -v0 / v1)
            elif v0 < -1.0:
                return [(-math.inf, math.inf)]
        return [(-math.inf, lo), (hi, math.inf)]

    def stationary_exit(self, mode, y, t0, t_end):
        """First time in (t0, t_end] at which a(t) enters a forbidden interval, or None."""
        forb = [iv for iv in self._forbidden_intervals(mode, y, t0) if iv[0] < iv[1]]
        if not forb:
            return None
        exc = self.exc
        acc = exc.acceleration_at
        pts = [t0] + exc.breakpoints(t0, t_end) + [t_end]
        if exc.t_end < t_end and exc.t_end > t0:
            pts = sorted(set(pts))
        for ta, tb in zip(pts[:-1], pts[1:]):
            # a is monotone on (ta, tb); use one-sided values at a possible jump
            aa = acc(ta + 1e-12 * max(1.0, abs(ta))) if ta > t0 else acc(ta)
            tb_left = tb - 1e-12 * max(1.0, abs(tb))
            ab = acc(tb_left)
            # a(t) drops to 0 at the end of the motion (a(t_end) = 0): find roots on its left side
            a_piece = acc if tb != exc.t_end else (lambda s: acc(min(s, tb_left)))
            best = None
            for lo, hi in forb:
                inside_a = lo < aa < hi
                if inside_a:
                    best = ta if best is None else min(best, ta)
                    continue
                for bound in (lo, hi):
                    if not math.isfinite(bound):
                        continue
                    if (aa - bound) * (ab - bound) < 0:
                        tc = brentq(lambda s: a_piece(s) - bound, ta, tb, xtol=1e-14, rtol=1e-15)
                        best = tc if best is None else min(best, tc)
            if best is not None:
                return best
        return None
