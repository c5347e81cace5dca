"""What an integration of the two-block model records: samples, the event log, the episodes.

:class:`Recorder` keeps the output grid (every ``output_interval``), the exact event log (with
the guards that stop a run that produces too many events or chatters), the maximal runs of one
contact mode (episodes) and the counters, and assembles them into a :class:`RockingResult`.
A run that cannot continue raises :class:`RockingError`, which carries the result so far.
"""

from __future__ import annotations

import math
from dataclasses import dataclass, field

import numpy as np

from dem.rocking.patterns import pattern_name


class RockingError(RuntimeError):
    """The integration cannot continue; ``partial`` holds the result up to ``t``."""

    def __init__(self, message: str, t: float, partial: "RockingResult | None" = None):
        super().__init__(message)
        self.t = t
        self.partial = partial


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


class Recorder:
    """Samples on the output grid, the event log, the episodes and the counters of one run.

    ``S`` is the run's :class:`dem.rocking.integrate.Settings` (duration, output_interval,
    max_events, chatter_events, chatter_dt).  ``stats`` is shared with the mode selection and
    the impact resolution, which count into it.
    """

    def __init__(self, S):
        self.S = S
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

    # ------------------------------------------------------------------ samples
    def record(self, ts, ys, mode):
        if len(ts) == 0:
            return
        self.out_t.append(np.asarray(ts, dtype=float))
        self.out_y.append(np.asarray(ys, dtype=float).reshape(4, -1))
        self.out_mode.append(np.tile(np.array(mode, dtype=np.int8), (len(ts), 1)))

    def record_constant(self, t0, t1, y, mode, include_end=False):
        """The grid points in [t0, t1) (or [t0, t1]) not yet recorded take the state y."""
        side = "right" if include_end else "left"
        j = int(np.searchsorted(self.grid, t1, side=side))
        if j > self.i_next:
            ts = self.grid[self.i_next:j]
            self.record(ts, np.repeat(np.asarray(y, float)[:, None], len(ts), axis=1), mode)
            self.i_next = j

    def last_time(self) -> float:
        return float(self.out_t[-1][-1]) if self.out_t else 0.0

    # ------------------------------------------------------------------ events, episodes
    def event(self, t, kind, before, after, **detail):
        """Log an event; too many events, or too many in a row too close together, stop the run."""
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

    def episode(self, t, old, new):
        """Close the episode of mode ``old`` at t when the mode changes."""
        if tuple(old) != tuple(new):
            self.stats["mode_changes"] += 1
            self.episodes.append((self._ep_start, float(t), pattern_name(*old[:2]), int(old[2])))
            self._ep_start = float(t)

    def close_episode(self, t, mode):
        self.episodes.append((self._ep_start, float(t), pattern_name(*mode[:2]), int(mode[2])))

    # ------------------------------------------------------------------ result
    def result(self, status, message, wall) -> RockingResult:
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
