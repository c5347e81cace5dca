"""Event-driven integration of the two-block rocking model.

Between events the motion is smooth and integrated with ``scipy.integrate.solve_ivp`` (DOP853 by
default) in the current contact mode; every condition that ends the mode is an event function
located by solve_ivp to its root-finding tolerance on the dense output:

* impacts: theta1 -> 0 (Part 1 on the base), phi = theta2 - theta1 -> 0 (Part 2 on Part 1);
* lift-off: the normal force at a corner of a flat contact -> 0;
* top friction: the load point's velocity -> 0 (slide reversal or stick), or |F| -> mu N (slip);
* the beam load moving to the other top corner (theta2 -> 0 in Patterns 2/4, corner load);
* collapse: |theta1| or |theta2| reaches ``collapse_angle``.

Stationary modes (rest, a tilted wall held by the top friction) are not integrated: their
conditions are affine in the base acceleration a(t), so the exit time is found exactly by root
finding on a(t) between its extrema.

At an event the new mode is chosen by complementarity (the rigid-contact LCP, solved by
enumeration of the few candidate modes): at velocity level for impacts (:func:`resolve_impact`,
Moreau's plastic impact = Housner for one block) and at acceleration level otherwise
(:func:`select_mode`).  Accumulating impacts (the rocking decaying to rest, a Zeno sequence) are
ended by locking a contact whose post-impact rate is below ``zeno_velocity``.  A run that cannot
continue raises :class:`RockingError`, which carries everything computed so far.
"""

from __future__ import annotations

import math
import time
from dataclasses import dataclass, field

import numpy as np
from scipy.integrate import solve_ivp
from scipy.optimize import brentq

from dem.rocking.excitation import Excitation
from dem.rocking.model import (
    STATIONARY,
    terms,
    RockingParams,
    contact_rows,
    evaluate,
    flow_kind,
    geometry,
    make_rhs,
    mass6,
    maximal_velocity,
    mode_row_keys,
    pattern_name,
)

TOL_REL = 1e-9  # relative tolerance of the complementarity checks (scaled by RockingParams.scales)
NUDGE = 1e-6    # s: a stationary mode is left this long after its exact exit time (see _leave_stationary)


def bb_default(b, bs):
    return b if b in bs else bs[0]


def cc_default(c, cs):
    return c if c in cs else cs[0]


class RockingError(RuntimeError):
    """The integration cannot continue; ``partial`` holds the result up to ``t``."""

    def __init__(self, message: str, t: float, partial: "RockingResult | None" = None):
        super().__init__(message)
        self.t = t
        self.partial = partial


@dataclass
class Settings:
    """Numerical settings.  Defaults are justified by the convergence study in
    docs/rocking_results.md (event times converge to < 1e-8 s)."""

    duration: float
    output_interval: float = 0.001
    restitution: str | float = "housner"
    method: str = "DOP853"
    rtol: float = 1e-10
    atol: float = 1e-12
    max_step_fraction: float = 1.0 / 16.0   # of the excitation period (or of 2 pi sqrt(H/g))
    zeno_velocity: float = 1e-6             # rad/s
    zeno_time: float = 1e-4                 # s: lock a joint whose next flight is shorter
    collapse_angle: float = 1.0             # rad
    max_events: int = 200000
    chatter_events: int = 200               # this many events closer than chatter_dt in a row: fail
    chatter_dt: float = 1e-9                # s


@dataclass
class RockingResult:
    t: np.ndarray
    theta1: np.ndarray
    theta2: np.ndarray
    omega1: np.ndarray
    omega2: np.ndarray
    mode: np.ndarray            # [T, 4] int8: b, c, tau, sigma
    pattern: np.ndarray         # [T] str
    events: list                # dicts: t, kind, before, after (patterns), detail
    episodes: list              # (t_start, t_end, pattern, top) maximal runs of one mode
    status: str = "ok"          # ok | collapsed | failed
    message: str = ""
    stats: dict = field(default_factory=dict)
    wall_seconds: float = 0.0

    @property
    def top_stick(self) -> np.ndarray:
        return self.mode[:, 2] == 0


class _Sim:
    def __init__(self, P: RockingParams, exc: Excitation, S: Settings):
        self.P, self.exc, self.S = P, exc, S
        sc = P.scales()
        self.tol_a = TOL_REL * sc["acc"]
        self.tol_w = TOL_REL * sc["vel"]
        self.tol_f = TOL_REL * sc["force"]
        self.tol_x = TOL_REL * sc["vel"] * sc["length"]       # load point velocity, m/s
        self.tol_xa = TOL_REL * sc["acc"] * sc["length"]      # load point acceleration, m/s2
        period = exc.period if exc.period else 2 * math.pi * math.sqrt(P.height / max(P.gravity, 1e-9))
        self.max_step = S.max_step_fraction * period
        self.eps_start = 1e-9 * math.sqrt(P.height / max(P.gravity, 1e-9)) if P.gravity > 0 else 1e-10
        n = int(math.floor(S.duration / S.output_interval + 1e-9)) + 1
        self.grid = np.arange(n) * S.output_interval
        self.i_next = 0
        self.out_t, self.out_y, self.out_mode = [], [], []
        self.events: list = []
        self.episodes: list = []
        self.stats = {
            "impacts_base": 0, "impacts_interface": 0, "impacts_double": 0, "zeno_locks": 0,
            "inconsistent_impacts": 0, "tension_impulses": 0, "mode_changes": 0,
            "segments": 0, "rhs_evaluations": 0, "no_consistent_mode": 0,
        }
        self._ep_start = 0.0
        self._recent = 0
        self._last_event_t = -1.0

    # ------------------------------------------------------------------ recording
    def _record(self, ts, ys, mode):
        if len(ts) == 0:
            return
        self.out_t.append(np.asarray(ts, dtype=float))
        self.out_y.append(np.asarray(ys, dtype=float).reshape(4, -1))
        self.out_mode.append(np.tile(np.array(mode, dtype=np.int8), (len(ts), 1)))

    def _record_constant(self, t0, t1, y, mode, include_end=False):
        side = "right" if include_end else "left"
        j = int(np.searchsorted(self.grid, t1, side=side))
        if j > self.i_next:
            ts = self.grid[self.i_next:j]
            self._record(ts, np.repeat(np.asarray(y, float)[:, None], len(ts), axis=1), mode)
            self.i_next = j

    def _event(self, t, kind, before, after, **detail):
        self.events.append({"t": float(t), "kind": kind, "before": pattern_name(*before[:2]),
                            "after": pattern_name(*after[:2]), **detail})
        if len(self.events) > self.S.max_events:
            raise RockingError(f"more than max_events = {self.S.max_events} events by t = {t:.6g} s", t)
        if t - self._last_event_t < self.S.chatter_dt:
            self._recent += 1
            if self._recent > self.S.chatter_events:
                raise RockingError(
                    f"chatter: {self._recent} events within {self.S.chatter_dt:g} s of each other "
                    f"at t = {t:.9g} s (last: {kind}, {pattern_name(*before[:2])} -> "
                    f"{pattern_name(*after[:2])})", t)
        else:
            self._recent = 0
        self._last_event_t = t

    def _episode(self, t, old, new):
        if tuple(old) != tuple(new):
            self.stats["mode_changes"] += 1
            self.episodes.append((self._ep_start, float(t), pattern_name(*old[:2]), int(old[2])))
            self._ep_start = float(t)

    # ------------------------------------------------------------------ helpers
    def _sig_choices(self, y):
        th2, w2 = y[0] + y[1], y[2] + y[3]
        if th2 != 0.0:
            return [1 if th2 > 0 else -1], False
        if w2 != 0.0:
            return [1 if w2 > 0 else -1], False
        if self.P.load_point == "centre":
            return [1], False
        return [1, -1], True

    @staticmethod
    def _contact_choices(angle, rate, locked=False):
        if locked:
            return [0], False
        if angle != 0.0:
            return [1 if angle > 0 else -1], False
        if rate != 0.0:
            return [1 if rate > 0 else -1], False
        return [1, -1, 0], True

    def _conditions(self, mode, y, a, base_free, iface_free, sig_free):
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

    def _candidates(self, y, t):
        P = self.P
        th1, phi, w1, wphi = y
        bs, base_free = self._contact_choices(th1, w1)
        cs, iface_free = self._contact_choices(phi, wphi, P.locked)
        sigs, sig_free = self._sig_choices(y)
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

    def select_mode(self, t, y, exclude=None, prev=None):
        """The contact mode consistent with complementarity at (t, y) (acceleration level)."""
        a = self.exc.acc(t)
        ok, bad = [], []
        rest = None
        for mode, bf, ifr, sf in self._candidates(y, t):
            if mode[0] == 0 and mode[1] == 0:
                rest = mode
                continue
            if exclude is not None and tuple(mode) == tuple(exclude):
                continue
            conds, _ = self._conditions(mode, y, a, bf, ifr, sf)
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

    # ------------------------------------------------------------------ impacts
    def resolve_impact(self, mode, y, closing):
        """Plastic (Moreau / Housner) impact, then the restitution rule; returns (mode, y).

        The post-impact velocities minimise the kinetic energy of the velocity jump, in the
        metric of the mass matrix, over the velocities allowed by the post-impact contact modes:
        M (v+ - v-) = G^T Lambda, G v+ = 0.  Candidate post modes are enumerated; the one whose
        normal impulses are compressive and whose released corners separate is taken.
        """
        P, S = self.P, self.S
        b, c, tau, sig = mode
        th1, phi, w1, wphi = y
        th2, w2 = th1 + phi, w1 + wphi
        s1, s2 = geometry(P, b, c)
        v_minus = maximal_velocity(P, s1, s2, th1, th2, w1, w2, sig)
        M = mass6(P)
        ke_minus = 0.5 * v_minus @ M @ v_minus
        p_scale = max(np.linalg.norm(M @ v_minus), 1e-300)
        tol_p = TOL_REL * p_scale
        tol_v = TOL_REL * max(np.max(np.abs(v_minus)), 1e-300)
        base_zero = th1 == 0.0
        if_zero = phi == 0.0
        # co-moving top load: at theta2 = 0 the beam may pass to the other top corner (the rising
        # corner strikes it); the post-impact corner is chosen with the other contacts
        beam_zero = P.comoving and P.load_point == "corner" and th2 == 0.0
        bs = [1, -1, 0] if base_zero else [b]
        cs = ([0] if P.locked else [1, -1, 0]) if if_zero else [c]
        ss = [-sig, sig] if beam_zero else [sig]
        n1 = np.array([math.sin(th1), math.cos(th1)])
        best = None
        order = [(bb, cc, sg) for bb in bs for cc in cs for sg in ss]
        # the usual outcome first: the closing joint swaps corners, the others keep their mode
        natural = (-b if base_zero and b != 0 else bb_default(b, bs),
                   -c if if_zero and c != 0 else cc_default(c, cs), ss[0])
        if natural in order:
            order.remove(natural)
            order.insert(0, natural)
        for bb, cc, sg in order:
            vplus, lam, rows = self._plastic(bb, cc, th1, th2, v_minus, M, sg)
            conds = []
            if beam_zero:
                # the beam's new corner pushes it up; the corner it leaves separates from it
                k, o = ("+", "-") if sg > 0 else ("-", "+")
                conds += [lam["beam_z" + k] / tol_p, rows["beam_z" + o] @ vplus / tol_v]
            if base_zero:
                if bb != 0:
                    k, o = ("+", "-") if bb > 0 else ("-", "+")
                    conds += [lam["base_z" + k] / tol_p, rows["base_z" + o] @ vplus / tol_v]
                else:
                    conds += [lam["base_z+"] / tol_p, lam["base_z-"] / tol_p]
            if if_zero and not P.locked:
                if cc != 0:
                    k, o = ("+", "-") if cc > 0 else ("-", "+")
                    ln = n1 @ np.array([lam["if_x" + k], lam["if_z" + k]])
                    conds += [ln / tol_p, rows["if_n" + o] @ vplus / tol_v]
                else:
                    ln = n1 @ np.array([lam["if_x+"], lam["if_z+"]])
                    conds += [ln / tol_p, lam["if_n-"] / tol_p]
            margin = min(conds) if conds else math.inf
            n_flat = int(bb == 0) + int(cc == 0)
            # consistent first, strictly consistent next; among marginal ones (zero post-impact
            # rate) prefer locking, the acceleration-level choice then decides about lift-off
            key = (margin >= -1.0, margin > 1.0, n_flat, margin)
            if best is None or key > best[0]:
                best = (key, bb, cc, sg, vplus, lam)
            if margin > 1.0:   # strictly consistent: the unique solution of the LCP
                break
        (consistent, _, _, margin), bb, cc, sg, vplus, lam = best
        if not consistent:
            self.stats["inconsistent_impacts"] += 1
        # persistent pivots pulled apart (flight would be needed; the model keeps contact)
        if not base_zero and lam.get("base_z" + ("+" if bb > 0 else "-"), 0.0) < -tol_p:
            self.stats["tension_impulses"] += 1
        if not if_zero and cc != 0:
            k = "+" if cc > 0 else "-"
            if n1 @ np.array([lam["if_x" + k], lam["if_z" + k]]) < -tol_p:
                self.stats["tension_impulses"] += 1
        # Zeno: a contact that closes with a negligible rate is locked
        w1p, w2p = vplus[2], vplus[5]
        relock = False
        if base_zero and bb != 0 and abs(w1p) < S.zeno_velocity:
            bb, relock = 0, True
        if if_zero and cc != 0 and abs(w2p - w1p) < S.zeno_velocity:
            cc, relock = 0, True
        if relock:
            self.stats["zeno_locks"] += 1
            vplus, lam, _ = self._plastic(bb, cc, th1, th2, v_minus, M, sg)
        if P.comoving:
            # friction the beam would need to follow the top through the impact: |H| / V of the
            # impulse it receives at its corner (a stick-slip condition would be <= mu)
            k = "+" if sg > 0 else "-"
            jx, jz = lam["beam_x" + k], lam["beam_z" + k]
            if jz > tol_p:
                self.stats["top_impulse_ratio_max"] = max(
                    self.stats.get("top_impulse_ratio_max", 0.0), float(abs(jx) / jz))
            if beam_zero and sg != sig:
                self.stats["impacts_top"] = self.stats.get("impacts_top", 0) + 1
        # restitution: a number e keeps the plastic velocity direction and e^2 of the energy
        if S.restitution != "housner":
            ke_plus = 0.5 * vplus @ M @ vplus
            if ke_plus > 1e-300:
                vplus = vplus * (float(S.restitution) * math.sqrt(ke_minus / ke_plus))
        ke_after = 0.5 * vplus @ M @ vplus
        w1p, w2p = float(vplus[2]), float(vplus[5])
        if bb == 0:
            w1p = 0.0
        if cc == 0:
            w2p = w1p
        y_new = (th1, phi, w1p, w2p - w1p)
        info = {"ke_before": float(ke_minus), "ke_after": float(ke_after), "margin": float(margin)}
        return (bb, cc, sg), y_new, info

    def _plastic(self, bb, cc, th1, th2, v_minus, M, sig=1):
        """Plastic impact onto the modes (bb, cc) (beam on the corner sigma = sig if co-moving):
        M (v+ - v-) = G^T Lambda, G v+ = 0; returns v+, the impulses Lambda by row, the rows."""
        P = self.P
        s1, s2 = geometry(P, bb, cc)
        rows, _ = contact_rows(P, s1, s2, th1, th2)
        keys = mode_row_keys(bb, cc, sig, P.comoving)
        G = np.array([rows[k] for k in keys])
        n = len(keys)
        nd = len(v_minus)
        K = np.zeros((nd + n, nd + n))
        K[:nd, :nd] = M
        K[:nd, nd:] = -G.T
        K[nd:, :nd] = G
        sol = np.linalg.solve(K, np.concatenate([M @ v_minus, np.zeros(n)]))
        return sol[:nd], dict(zip(keys, sol[nd:])), rows

    # ------------------------------------------------------------------ stationary modes
    def _affine_conditions(self, mode, y, t, from_rest):
        """Conditions of ``mode`` at state y as affine functions c0 + c1 a of the base acceleration."""
        if from_rest:
            bf, ifr = True, not self.P.locked
            sigs, sf = self._sig_choices(y)
        else:
            bf = ifr = sf = False
        c0, _ = self._conditions(mode, y, 0.0, bf, ifr, sf)
        c1, _ = self._conditions(mode, y, 1.0, bf, ifr, sf)
        return [(v0[0], v1[0] - v0[0]) for v0, v1 in zip(c0, c1)]

    def _forbidden_intervals(self, mode, y, t):
        """Open intervals of base acceleration a in which the stationary ``mode`` cannot persist."""
        kind = flow_kind(*mode[:3])
        if kind == "rest":
            out = []
            for cand, bf, ifr, sf in self._candidates(y, t):
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

    def _stationary_exit(self, mode, y, t0, t_end):
        """First time in (t0, t_end] at which a(t) enters a forbidden interval, or None."""
        forb = [iv for iv in self._forbidden_intervals(mode, y, t0) if iv[0] < iv[1]]
        if not forb:
            return None
        exc = self.exc
        pts = [t0] + exc.breakpoints(t0, t_end) + [t_end]
        if exc.t_stop < t_end and exc.t_stop > t0:
            pts = sorted(set(pts))
        for ta, tb in zip(pts[:-1], pts[1:]):
            # a is monotone on (ta, tb); use one-sided values at a possible jump
            aa = exc.acc(ta + 1e-12 * max(1.0, abs(ta))) if ta > t0 else exc.acc(ta)
            ab = exc.acc(tb - 1e-12 * max(1.0, abs(tb)))
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
                        tc = brentq(lambda s: exc.acc(s) - bound, ta, tb, xtol=1e-14, rtol=1e-15)
                        best = tc if best is None else min(best, tc)
            if best is not None:
                return best
        return None

    # ------------------------------------------------------------------ flow
    def _make_rhs(self, mode):
        return make_rhs(self.P, mode, self.exc.acc)

    def _make_events(self, mode):
        """Event functions (value >= 0 while the mode is valid; terminal, direction -1)."""
        P, exc, S = self.P, self.exc, self.S
        b, c, tau, sig = mode
        kind = flow_kind(b, c, tau)
        cache = {}

        def ev(t, y):
            key = (t, y[0], y[1], y[2], y[3])
            e = cache.get(key)
            if e is None:
                cache.clear()
                e = evaluate(P, mode, y, exc.acc(t), want_forces=True)
                cache[key] = e
            return e

        evs, kinds = [], []

        def add(fun, name):
            fun.terminal = True
            fun.direction = -1
            evs.append(fun)
            kinds.append(name)

        if b != 0:
            add(lambda t, y: b * y[0], "impact_base")
        if c != 0:
            add(lambda t, y: c * y[1], "impact_iface")
        if kind == "p3" and not P.locked:
            add(lambda t, y: ev(t, y).iface[0] / self.tol_f, "liftoff_iface+")
            add(lambda t, y: ev(t, y).iface[1] / self.tol_f, "liftoff_iface-")
        if kind == "p4":
            add(lambda t, y: ev(t, y).base[0] / self.tol_f, "liftoff_base+")
            add(lambda t, y: ev(t, y).base[1] / self.tol_f, "liftoff_base-")
        if P.friction:
            if tau != 0:
                add(lambda t, y: tau * ev(t, y).xd, "top_reversal")
            elif kind == "free_stick":
                add(lambda t, y: (P.Fmax - ev(t, y).F) / self.tol_f, "slip+")
                add(lambda t, y: (P.Fmax + ev(t, y).F) / self.tol_f, "slip-")
        if kind in ("free", "free_stick") and P.load_point == "corner":
            add(lambda t, y: sig * (y[0] + y[1]), "load_switch")
        ca = S.collapse_angle
        add(lambda t, y: ca - max(abs(y[0]), abs(y[0] + y[1])), "collapse")
        return evs, kinds

    # ------------------------------------------------------------------ main loop
    def run(self, y0):
        S, P = self.S, self.P
        t, t_end = 0.0, float(S.duration)
        y = tuple(float(v) for v in y0)
        mode = self.select_mode(t, y)
        self.mode0 = mode
        status, message = "ok", ""
        while t < t_end:
            kind = flow_kind(*mode[:3])
            self.stats["segments"] += 1
            if kind in STATIONARY:
                t_exit = self._stationary_exit(mode, y, t, t_end)
                if t_exit is None:
                    self._record_constant(t, t_end, y, mode, include_end=True)
                    t = t_end
                    break
                t_new = max(t_exit, t) + NUDGE
                if t_new >= t_end:
                    self._record_constant(t, t_end, y, mode, include_end=True)
                    t = t_end
                    break
                self._record_constant(t, t_new, y, mode)
                new = self.select_mode(t_new, y, exclude=mode, prev=mode)
                if tuple(new) == tuple(mode):
                    raise RockingError(
                        f"stationary mode {pattern_name(*mode[:2])} left at t = {t_new:.9g} s "
                        "but no other mode is consistent", t_new)
                self._event(t_new, "leave_" + kind, mode, new, a=self.exc.acc(t_new))
                self._episode(t_new, mode, new)
                t, mode = t_new, new
                continue
            # smooth flow until an event or a chunk end
            t_old, y_old, mode_old = t, y, mode
            t, y, mode = self._taylor_start(t, y, mode)
            if t > t_old:  # a grid point inside the tiny start step takes the event state
                self._record_constant(t_old, t, y_old, mode_old)
            if flow_kind(*mode[:3]) in STATIONARY:
                continue
            t_bound = min(t_end, t + 50.0 * self.max_step)
            j = int(np.searchsorted(self.grid, t_bound, side="left"))
            t_eval = np.append(self.grid[self.i_next:j], t_bound)
            evs, kinds = self._make_events(mode)
            sol = solve_ivp(self._make_rhs(mode), (t, t_bound), list(y), method=S.method,
                            t_eval=t_eval, events=evs, rtol=S.rtol, atol=S.atol,
                            max_step=self.max_step)
            if sol.status == -1:
                raise RockingError(f"solve_ivp failed at t = {sol.t[-1]:.9g} s in pattern "
                                   f"{pattern_name(*mode[:2])}: {sol.message}", float(sol.t[-1]))
            n_grid = min(len(sol.t), j - self.i_next)   # drop the appended t_bound
            if n_grid > 0:
                self._record(sol.t[:n_grid], np.asarray(sol.y)[:, :n_grid], mode)
            self.i_next += n_grid
            if sol.status == 0:
                t = float(t_bound)
                y = tuple(float(v) for v in sol.y[:, -1])
                continue
            fired = [(float(te[0]), i) for i, te in enumerate(sol.t_events) if len(te)]
            t_ev, i_ev = min(fired)
            y_ev = [float(v) for v in sol.y_events[i_ev][0]]
            name = kinds[i_ev]
            t = t_ev
            if name == "collapse":
                status = "collapsed"
                message = (f"collapse: |theta| reached {S.collapse_angle} rad at t = {t:.6g} s "
                           f"in pattern {pattern_name(*mode[:2])}")
                self._event(t, "collapse", mode, mode)
                y = tuple(y_ev)
                break
            t_before = t
            t, mode, y = self._handle_event(name, t, y_ev, mode)
            if t > t_before:  # a grid point inside the release nudge takes the event state
                self._record_constant(t_before, t, tuple(y_ev), mode)
        # final sample at t_end (if not yet recorded)
        if status == "ok" and self.i_next < len(self.grid):
            self._record_constant(t, t_end, y, mode, include_end=True)
        self.episodes.append((self._ep_start, float(t), pattern_name(*mode[:2]), int(mode[2])))
        return status, message

    def _flight(self, rate, acc) -> bool:
        """True when a joint opening at ``rate`` against ``acc`` (both signed positive = opening)
        would close again within ``zeno_time``: 2 rate / (-acc) < zeno_time."""
        return rate > 0.0 and acc < 0.0 and 2.0 * rate < -acc * self.S.zeno_time

    def _taylor_start(self, t, y, mode):
        """Step a flow off an event point by a tiny second-order Taylor step.

        Event functions that are exactly 0 at the start of a segment (a joint that has just
        opened, a load point that has just stopped) would make solve_ivp's root finder return the
        segment start.  The state is advanced by EPS_START (error ~ jerk * EPS_START^3 / 6, far
        below the integration tolerance) so that they start on their valid side.  A joint that
        would close again within EPS_START, or whose next flight (2 rate / closing acceleration)
        is shorter than ``zeno_time``, is locked: the end of an accumulation of impacts, whose
        remaining micro-rocking has an amplitude below |acc| zeno_time^2 / 8 (~1e-7 rad).
        """
        P = self.P
        for _ in range(4):
            b, c, tau, sig = mode
            starting = (b != 0 and y[0] == 0.0) or (c != 0 and y[1] == 0.0) or tau != 0
            if not starting:
                return t, y, mode
            e = evaluate(P, mode, y, self.exc.acc(t), want_forces=False)
            if (tau != 0 and abs(e.xd) > self.tol_x and b * y[0] != 0 and c * y[1] != 0
                    and (y[0] + y[1] != 0.0 or P.load_point != "corner")):
                # (theta2 = 0 exactly: the load has just passed to the other corner; its event
                # function starts at 0, so step off it too)
                return t, y, mode
            h = self.eps_start
            dphi = e.dd2 - e.dd1
            yn = (y[0] + h * y[2] + 0.5 * h * h * e.dd1, y[1] + h * y[3] + 0.5 * h * h * dphi,
                  y[2] + h * e.dd1, y[3] + h * dphi)
            lock_b = b != 0 and y[0] == 0.0 and (not b * yn[0] > 0.0
                                                  or self._flight(b * y[2], b * e.dd1))
            lock_c = c != 0 and y[1] == 0.0 and (not c * yn[1] > 0.0
                                                  or self._flight(c * y[3], c * dphi))
            if not (lock_b or lock_c):
                return t + h, yn, mode
            # the joint recloses at once: plastic lock of that joint, then a new mode
            self.stats["zeno_locks"] += 1
            th1, phi, w1, wphi = y
            s1, s2 = geometry(P, b, c)
            v = maximal_velocity(P, s1, s2, th1, th1 + phi, w1, w1 + wphi, sig)
            bb, cc = (0 if lock_b else b), (0 if lock_c else c)
            M = mass6(P)
            vp, _, _ = self._plastic(bb, cc, th1, th1 + phi, v, M, sig)
            if self.S.restitution != "housner":
                # with a restitution number the lock keeps the kinetic energy (e was applied
                # at the impact that started this flight)
                ke0, ke1 = 0.5 * v @ M @ v, 0.5 * vp @ M @ vp
                if ke1 > 1e-300:
                    vp = vp * math.sqrt(ke0 / ke1)
            w1p, w2p = (0.0 if bb == 0 else float(vp[2])), float(vp[5])
            if cc == 0:
                w2p = w1p
            y = (th1, phi, w1p, w2p - w1p)
            new = self.select_mode(t, y, prev=(bb, cc, tau, sig))
            self._event(t, "zeno_lock", mode, new)
            self._episode(t, mode, new)
            mode = new
            if flow_kind(*mode[:3]) in STATIONARY:
                return t, y, mode
        raise RockingError(f"could not start a flow at t = {t:.9g} s in pattern "
                           f"{pattern_name(*mode[:2])}", t)

    def _handle_event(self, name, t, y_ev, mode):
        P = self.P
        b, c, tau, sig = mode
        y = list(y_ev)
        closing = set()
        if name == "load_switch" and P.comoving:
            # the beam (a mass moving with the top) passes to the other top corner, which strikes
            # it: an impact (resolved with the other contacts unchanged unless they close too)
            y[1] = -y[0]  # theta2 = 0 exactly
            self.stats["beam_switches"] = self.stats.get("beam_switches", 0) + 1
            (bb, cc, sg), y_new, info = self.resolve_impact(mode, tuple(y), {"beam"})
            y = list(y_new)
            new = self.select_mode(t, tuple(y), prev=(bb, cc, tau, sg))
            self._event(t, "impact_top", mode, new, theta1=y_ev[0], theta2=0.0, **info)
        elif name.startswith("impact"):
            # snap the closing joint(s); a second joint closing within a tiny angle is simultaneous
            ang_tol = 1e-12
            if b != 0 and (name == "impact_base" or abs(y[0]) < ang_tol and b * y[2] < 0):
                y[0] = 0.0  # keep phi (the interface's own gap; exactly 0 when it is closed)
                closing.add("base")
            if c != 0 and (name == "impact_iface" or abs(y[1]) < ang_tol and c * y[3] < 0):
                y[1] = 0.0
                closing.add("iface")
            if len(closing) == 2:
                self.stats["impacts_double"] += 1
            if "base" in closing:
                self.stats["impacts_base"] += 1
            if "iface" in closing:
                self.stats["impacts_interface"] += 1
            (bb, cc, sg), y_new, info = self.resolve_impact(mode, tuple(y), closing)
            y = list(y_new)
            new = self.select_mode(t, tuple(y), prev=(bb, cc, tau, sg))
            self._event(t, name if len(closing) == 1 else "impact_double", mode, new,
                        theta1=y_ev[0], theta2=y_ev[0] + y_ev[1], **info)
        elif name == "load_switch":
            y[1] = -y[0]  # theta2 = 0 exactly
            new = self.select_mode(t, tuple(y), prev=(b, c, tau, -sig))
            self._event(t, name, mode, new)
        elif name == "top_reversal":
            y = list(self._snap_top_velocity(mode, y))
            new = self.select_mode(t, tuple(y), prev=mode, exclude=mode)
            self._event(t, name, mode, new)
        else:
            # A validity condition of the mode has just been violated: release it.  At the
            # located root the released mode is only marginally consistent (its opening
            # acceleration is exactly 0), so first continue the old mode NUDGE past the root
            # (second-order Taylor step; the neglected motion is ~ jerk NUDGE^3 / 6).
            e = evaluate(P, mode, tuple(y), self.exc.acc(t), want_forces=False)
            h = NUDGE
            dphi = e.dd2 - e.dd1
            y = [y[0] + h * y[2] + 0.5 * h * h * e.dd1, y[1] + h * y[3] + 0.5 * h * h * dphi,
                 y[2] + h * e.dd1, y[3] + h * dphi]
            if flow_kind(b, c, tau) in ("p3", "p3_stuck"):
                y[1], y[3] = 0.0, 0.0
            if flow_kind(b, c, tau) in ("p4", "p4_stuck"):
                y[0], y[2] = 0.0, 0.0
            t = t + h
            if name == "liftoff_iface+":    # force at the + corner -> 0: rock on the - corner
                cand = (b, -1, tau, sig)
            elif name == "liftoff_iface-":
                cand = (b, 1, tau, sig)
            elif name == "liftoff_base+":
                cand = (-1, c, tau, sig)
            elif name == "liftoff_base-":
                cand = (1, c, tau, sig)
            elif name == "slip+":           # F -> +mu N: friction pushes +x, the point moves -x
                cand = (b, c, -1, sig)
            elif name == "slip-":
                cand = (b, c, 1, sig)
            else:
                raise RockingError(f"unknown event {name}", t)
            new = self._check_release(cand, t, tuple(y), mode)
            self._event(t, name, mode, new)
        self._episode(t, mode, new)
        return t, new, tuple(y)

    def _snap_top_velocity(self, mode, y):
        """Make the load point's velocity exactly 0 (it is ~1e-15 at the located event).

        The smallest change of the velocities in the kinetic-energy metric: q' <- q' -
        (J q') M^-1 J^T / (J M^-1 J^T); in Patterns 3 and 4 this sets the one rate to 0.
        """
        P = self.P
        b, c, tau, sig = mode
        th1, phi, w1, wphi = y
        kind = flow_kind(b, c, tau)
        if kind in ("p3", "p3_stuck"):
            return (th1, phi, 0.0, 0.0)
        if kind in ("p4", "p4_stuck"):
            return (th1, phi, 0.0, 0.0)
        s1, s2 = geometry(P, b, c)
        M11, M12, M22, k, Q1, Q2, J1, J2, beta = terms(P, s1, s2, sig, th1, th1 + phi, w1, w1 + wphi, 0.0)
        det = M11 * M22 - M12 * M12
        f1, f2 = (M22 * J1 - M12 * J2) / det, (M11 * J2 - M12 * J1) / det
        w2 = w1 + wphi
        lam = (J1 * w1 + J2 * w2) / (J1 * f1 + J2 * f2)
        w1n, w2n = w1 - lam * f1, w2 - lam * f2
        return (th1, phi, w1n, w2n - w1n)

    def _check_release(self, cand, t, y, old):
        """Accept the released mode unless another condition of it is clearly violated."""
        a = self.exc.acc(t)
        th1, phi, w1, wphi = y
        _, bf = self._contact_choices(th1, w1)
        _, ifr = self._contact_choices(phi, wphi, self.P.locked)
        _, sf = self._sig_choices(y)
        conds, _ = self._conditions(cand, y, a, False, False, sf)
        if all(v >= -1.0 for v, _ in conds):
            return cand
        return self.select_mode(t, y, exclude=old, prev=cand)

    def result(self, status, message, wall):
        if self.out_t:
            t = np.concatenate(self.out_t)
            Y = np.concatenate(self.out_y, axis=1)
            modes = np.concatenate(self.out_mode, axis=0)
        else:
            t = np.zeros(0)
            Y = np.zeros((4, 0))
            modes = np.zeros((0, 4), dtype=np.int8)
        th1, phi, w1, wphi = Y
        names = np.array([pattern_name(int(b), int(c)) for b, c in modes[:, :2]] or [], dtype="<U4")
        return RockingResult(
            t=t, theta1=th1, theta2=th1 + phi, omega1=w1, omega2=w1 + wphi, mode=modes,
            pattern=names, events=self.events, episodes=self.episodes, status=status,
            message=message, stats=dict(self.stats), wall_seconds=wall)


def simulate(P: RockingParams, exc: Excitation, settings: Settings, initial=(0.0, 0.0, 0.0, 0.0)) -> RockingResult:
    """Integrate the two-block model from ``initial = (theta1, theta2, omega1, omega2)`` (absolute).

    Returns a :class:`RockingResult` sampled every ``settings.output_interval`` plus the exact
    event log.  Raises :class:`RockingError` (with ``partial``) when the integration cannot go on.
    """
    th1, th2, w1, w2 = (float(v) for v in initial)
    sim = _Sim(P, exc, settings)
    t0 = time.perf_counter()
    try:
        status, message = sim.run((th1, th2 - th1, w1, w2 - w1))
    except RockingError as err:
        err.partial = sim.result("failed", str(err), time.perf_counter() - t0)
        raise
    except Exception as err:  # numerical trouble deep in scipy/numpy: keep what was computed
        t_fail = float(sim.out_t[-1][-1]) if sim.out_t else 0.0
        e = RockingError(f"integration failed near t = {t_fail:.6g} s: {type(err).__name__}: {err}", t_fail)
        e.partial = sim.result("failed", str(e), time.perf_counter() - t0)
        raise e from err
    return sim.result(status, message, time.perf_counter() - t0)
