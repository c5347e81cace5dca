"""Event-driven integration of the two-block rocking model: :func:`integrate_rocking`.

Between events the motion is smooth and integrated with ``scipy.integrate.solve_ivp`` (DOP853 by
default) in the current contact mode, in chunks of at most 50 maximum steps, until an event
function fires (dem.rocking.events).  Stationary modes (rest, a tilted wall held by the top
friction) are not integrated: their exit time is found exactly from a(t) (dem.rocking.modes).

At an event the new mode is chosen by complementarity (the rigid-contact LCP, solved by
enumeration of the few candidate modes): at velocity level for impacts (dem.rocking.impacts,
Moreau's plastic impact = Housner for one block) and at acceleration level otherwise
(dem.rocking.modes).  Accumulating impacts (the rocking decaying to rest, a Zeno sequence) are
ended by locking a contact whose post-impact rate is below ``zeno_velocity``.  A run that cannot
continue raises :class:`RockingError`, which carries everything computed so far
(dem.rocking.recording).

    integrate.py  Settings, the integration loop
    modes.py      candidate modes, complementarity conditions, stationary-mode exits
    impacts.py    plastic impacts, joint locks, restitution
    events.py     event functions, what happens at an event, the start of a flow
    recording.py  output samples, event log, episodes; RockingResult, RockingError
"""

from __future__ import annotations

import math
import time
from dataclasses import dataclass

import numpy as np
from scipy.integrate import solve_ivp

from dem.rocking.events import NUDGE, EventHandler, event_functions
from dem.rocking.impacts import ImpactResolver
from dem.rocking.equations import make_rhs
from dem.rocking.modes import ModeSelector, tolerances
from dem.rocking.params import RockingParams
from dem.rocking.patterns import STATIONARY, flow_kind, pattern_name
from dem.rocking.recording import Recorder, RockingError, RockingResult
from dem.table_motion import TableMotion

__all__ = ["Settings", "RockingError", "RockingResult", "integrate_rocking"]


@dataclass
class Settings:
    """Numerical settings.  Defaults are justified by the convergence study in
    results/two-body/README.md (event times converge to < 1e-8 s)."""

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


class _Integration:
    """One run: the loop over smooth flows, stationary modes and events."""

    def __init__(self, P: RockingParams, exc: TableMotion, S: Settings):
        self.P, self.exc, self.S = P, exc, S
        self.tol = tolerances(P)
        self.rec = Recorder(S)
        self.modes = ModeSelector(P, exc, self.tol, self.rec.stats)
        self.impacts = ImpactResolver(P, S, self.rec.stats)
        self.events = EventHandler(P, exc, S, self.tol, self.modes, self.impacts, self.rec)
        period = exc.period if exc.period else 2 * math.pi * math.sqrt(P.height / max(P.gravity, 1e-9))
        self.max_step = S.max_step_fraction * period

    def run(self, y0):
        S, rec = self.S, self.rec
        t, t_end = 0.0, float(S.duration)
        y = tuple(float(v) for v in y0)
        mode = self.modes.select(t, y)
        status, message = "ok", ""
        while t < t_end:
            kind = flow_kind(*mode[:3])
            rec.stats["segments"] += 1
            if kind in STATIONARY:
                t_exit = self.modes.stationary_exit(mode, y, t, t_end)
                if t_exit is None:
                    rec.record_constant(t, t_end, y, mode, include_end=True)
                    t = t_end
                    break
                t_new = max(t_exit, t) + NUDGE
                if t_new >= t_end:
                    rec.record_constant(t, t_end, y, mode, include_end=True)
                    t = t_end
                    break
                rec.record_constant(t, t_new, y, mode)
                new = self.modes.select(t_new, y, exclude=mode, prev=mode)
                if tuple(new) == tuple(mode):
                    raise RockingError(
                        f"stationary mode {pattern_name(*mode[:2])} left at t = {t_new:.9g} s "
                        "but no other mode is consistent", t_new)
                rec.event(t_new, "leave_" + kind, mode, new, a=self.exc.acceleration_at(t_new))
                rec.episode(t_new, mode, new)
                t, mode = t_new, new
                continue
            # smooth flow until an event or a chunk end
            t_old, y_old, mode_old = t, y, mode
            t, y, mode = self.events.start_flow(t, y, mode)
            if t > t_old:  # a grid point inside the tiny start step takes the event state
                rec.record_constant(t_old, t, y_old, mode_old)
            if flow_kind(*mode[:3]) in STATIONARY:
                continue
            t_bound = min(t_end, t + 50.0 * self.max_step)
            j = int(np.searchsorted(rec.grid, t_bound, side="left"))
            t_eval = np.append(rec.grid[rec.i_next:j], t_bound)
            evs, kinds = event_functions(self.P, self.exc, S, self.tol, mode)
            sol = solve_ivp(make_rhs(self.P, mode, self.exc.acceleration_at), (t, t_bound), list(y),
                            method=S.method, t_eval=t_eval, events=evs, rtol=S.rtol,
                            atol=S.atol, max_step=self.max_step)
            if sol.status == -1:
                raise RockingError(f"solve_ivp failed at t = {sol.t[-1]:.9g} s in pattern "
                                   f"{pattern_name(*mode[:2])}: {sol.message}", float(sol.t[-1]))
            n_grid = min(len(sol.t), j - rec.i_next)   # drop the appended t_bound
            if n_grid > 0:
                rec.record(sol.t[:n_grid], np.asarray(sol.y)[:, :n_grid], mode)
            rec.i_next += n_grid
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
                rec.event(t, "collapse", mode, mode)
                y = tuple(y_ev)
                break
            t_before = t
            t, mode, y = self.events.handle(name, t, y_ev, mode)
            if t > t_before:  # a grid point inside the release nudge takes the event state
                rec.record_constant(t_before, t, tuple(y_ev), mode)
        # final sample at t_end (if not yet recorded)
        if status == "ok" and rec.i_next < len(rec.grid):
            rec.record_constant(t, t_end, y, mode, include_end=True)
        rec.close_episode(t, mode)
        return status, message


def integrate_rocking(P: RockingParams, exc: TableMotion, settings: Settings,
                      initial=(0.0, 0.0, 0.0, 0.0)) -> RockingResult:
    """Integrate the two-block model from ``initial = (theta1, theta2, omega1, omega2)`` (absolute)
    under the table motion ``exc`` (dem.table_motion: ``TableMotion()`` for free motion,
    ``SineMotion(A, f, cycles)`` for the shake; along the rocking plane, m).

    Returns a :class:`RockingResult` sampled every ``settings.output_interval`` plus the exact
    event log.  Raises :class:`RockingError` (with ``partial``) when the integration cannot go on.
    """
    th1, th2, w1, w2 = (float(v) for v in initial)
    run = _Integration(P, exc, settings)
    t0 = time.perf_counter()
    try:
        status, message = run.run((th1, th2 - th1, w1, w2 - w1))
    except RockingError as err:
        err.partial = run.rec.result("failed", str(err), time.perf_counter() - t0)
        raise
    except Exception as err:  # numerical trouble deep in scipy/numpy: keep what was computed
        t_fail = run.rec.last_time()
        e = RockingError(f"integration failed near t = {t_fail:.6g} s: {type(err).__name__}: {err}", t_fail)
        e.partial = run.rec.result("failed", str(e), time.perf_counter() - t0)
        raise e from err
    return run.rec.result(status, message, time.perf_counter() - t0)
