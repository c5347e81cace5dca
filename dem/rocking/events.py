"""Events of the two-block model: the functions that end a smooth flow, and what happens at one.

While a mode lasts the state moves smoothly; every condition that ends it is an event function
(value >= 0 while the mode is valid, terminal, direction -1) located by solve_ivp on its dense
output (:func:`event_functions`):

* impacts: theta1 -> 0 (Part 1 on the base), phi = theta2 - theta1 -> 0 (Part 2 on Part 1);
* lift-off: the normal force at a corner of a flat contact -> 0;
* top friction: the load point's velocity -> 0 (slide reversal or stick), or |F| -> mu N (slip);
* the beam load moving to the other top corner (theta2 -> 0 in Patterns 2/4, corner load);
* collapse: |theta1| or |theta2| reaches ``collapse_angle``.

:class:`EventHandler` resolves a located event (an impact through dem.rocking.impacts, a release
by a NUDGE step past the root, a friction reversal by snapping the load point's velocity to 0)
and chooses the next mode (dem.rocking.modes); :meth:`EventHandler.start_flow` steps a new flow
off its event point, locking a joint whose next flight would be shorter than ``zeno_time``.
"""

from __future__ import annotations

import math

from dem.rocking.equations import evaluate, terms
from dem.rocking.impacts import ImpactResolver
from dem.rocking.modes import ModeSelector, Tolerances
from dem.rocking.params import RockingParams
from dem.rocking.patterns import STATIONARY, flow_kind, geometry, pattern_name
from dem.rocking.recording import Recorder, RockingError

NUDGE = 1e-6    # s: a released or stationary mode is left this long after its exact exit time


def event_functions(P: RockingParams, exc, S, tol: Tolerances, mode):
    """Event functions of a flow in ``mode`` and their names: (functions, names)."""
    b, c, tau, sig = mode
    kind = flow_kind(b, c, tau)
    tol_f = tol.force
    cache = {}

    def ev(t, y):
        key = (t, y[0], y[1], y[2], y[3])
        e = cache.get(key)
        if e is None:
            cache.clear()
            e = evaluate(P, mode, y, exc.acceleration_at(t), want_forces=True)
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
        add(lambda t, y: ev(t, y).iface[0] / tol_f, "liftoff_iface+")
        add(lambda t, y: ev(t, y).iface[1] / tol_f, "liftoff_iface-")
    if kind == "p4":
        add(lambda t, y: ev(t, y).base[0] / tol_f, "liftoff_base+")
        add(lambda t, y: ev(t, y).base[1] / tol_f, "liftoff_base-")
    if P.friction:
        if tau != 0:
            add(lambda t, y: tau * ev(t, y).xd, "top_reversal")
        elif kind == "free_stick":
            add(lambda t, y: (P.Fmax - ev(t, y).F) / tol_f, "slip+")
            add(lambda t, y: (P.Fmax + ev(t, y).F) / tol_f, "slip-")
    if kind in ("free", "free_stick") and P.load_point == "corner":
        add(lambda t, y: sig * (y[0] + y[1]), "load_switch")
    ca = S.collapse_angle
    add(lambda t, y: ca - max(abs(y[0]), abs(y[0] + y[1])), "collapse")
    return evs, kinds


class EventHandler:
    """What happens at an event, and the start of the flow after it."""

    def __init__(self, P: RockingParams, exc, S, tol: Tolerances, modes: ModeSelector,
                 impacts: ImpactResolver, rec: Recorder):
        self.P, self.exc, self.S = P, exc, S
        self.tol_x = tol.point_vel
        self.modes, self.impacts, self.rec = modes, impacts, rec
        self.stats = rec.stats
        self.eps_start = 1e-9 * math.sqrt(P.height / max(P.gravity, 1e-9)) if P.gravity > 0 else 1e-10

    def _flight(self, rate, acc) -> bool:
        """True when a joint opening at ``rate`` against ``acc`` (both signed positive = opening)
        would close again within ``zeno_time``: 2 rate / (-acc) < zeno_time."""
        return rate > 0.0 and acc < 0.0 and 2.0 * rate < -acc * self.S.zeno_time

    def start_flow(self, t, y, mode):
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
            e = evaluate(P, mode, y, self.exc.acceleration_at(t), want_forces=False)
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
            bb, cc, y = self.impacts.lock(mode, y, lock_b, lock_c)
            new = self.modes.select(t, y, prev=(bb, cc, tau, sig))
            self.rec.event(t, "zeno_lock", mode, new)
            self.rec.episode(t, mode, new)
            mode = new
            if flow_kind(*mode[:3]) in STATIONARY:
                return t, y, mode
        raise RockingError(f"could not start a flow at t = {t:.9g} s in pattern "
                           f"{pattern_name(*mode[:2])}", t)

    def handle(self, name, t, y_ev, mode):
        """Resolve the event ``name`` located at (t, y_ev) in ``mode``: returns (t, mode, y)."""
        P = self.P
        b, c, tau, sig = mode
        y = list(y_ev)
        closing = set()
        if name == "load_switch" and P.comoving:
            # the beam (a mass moving with the top) passes to the other top corner, which strikes
            # it: an impact (resolved with the other contacts unchanged unless they close too)
            y[1] = -y[0]  # theta2 = 0 exactly
            self.stats["beam_switches"] = self.stats.get("beam_switches", 0) + 1
            (bb, cc, sg), y_new, info = self.impacts.resolve(mode, tuple(y), {"beam"})
            y = list(y_new)
            new = self.modes.select(t, tuple(y), prev=(bb, cc, tau, sg))
            self.rec.event(t, "impact_top", mode, new, theta1=y_ev[0], theta2=0.0, **info)
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
            (bb, cc, sg), y_new, info = self.impacts.resolve(mode, tuple(y), closing)
            y = list(y_new)
            new = self.modes.select(t, tuple(y), prev=(bb, cc, tau, sg))
            self.rec.event(t, name if len(closing) == 1 else "impact_double", mode, new,
                           theta1=y_ev[0], theta2=y_ev[0] + y_ev[1], **info)
        elif name == "load_switch":
            y[1] = -y[0]  # theta2 = 0 exactly
            new = self.modes.select(t, tuple(y), prev=(b, c, tau, -sig))
            self.rec.event(t, name, mode, new)
        elif name == "top_reversal":
            y = list(self.snap_top_velocity(mode, y))
            new = self.modes.select(t, tuple(y), prev=mode, exclude=mode)
            self.rec.event(t, name, mode, new)
        else:
            # A validity condition of the mode has just been violated: release it.  At the
            # located root the released mode is only marginally consistent (its opening
            # acceleration is exactly 0), so first continue the old mode NUDGE past the root
            # (second-order Taylor step; the neglected motion is ~ jerk NUDGE^3 / 6).
            e = evaluate(P, mode, tuple(y), self.exc.acceleration_at(t), want_forces=False)
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
            new = self.modes.check_release(cand, t, tuple(y), mode)
            self.rec.event(t, name, mode, new)
        self.rec.episode(t, mode, new)
        return t, new, tuple(y)

    def snap_top_velocity(self, mode, y):
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
