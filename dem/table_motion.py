"""The shaking table's motion along its direction: one definition for the DEM and the two-body model.

The sinusoidal test signal of the thesis (Section 4.2), with w = 2 pi f and T = n / f the end of
the n cycles (A in m, f in Hz, t in s):

    u(t) = A sin(w t)          m       table displacement     for 0 <= t <= T,
    v(t) = A w cos(w t)        m/s     table velocity         for 0 <= t <= T,
    a(t) = -A w^2 sin(w t)     m/s2    table acceleration     for 0 <= t <  T;

before t = 0 the table is at rest at u = 0; after T, a = 0 and u, v are the exact integrals of
that: the table keeps the velocity of the end of its last cycle, v = v(T) = A w cos(2 pi n),
u = u(T) + v(T) (t - T).  (The thesis' table stops after the test; stopping it takes a
deceleration that the bodies would feel.  Reporting a stopped table without applying that
deceleration made the absolute motion of the bodies jump by A w at T: the shake analysis,
which rebuilds absolute accelerations from relative motion plus the table's, saw a spike there
(tried in 1955d72 and reverted).)  The peak acceleration is A w^2.  At the ends a(T) = 0: a
time step that starts at T feels no more shaking (a(t) is sampled at the start of each DEM
step).

Both models work in the table's frame: a body feels the inertia force -m a(t) and nothing else
of the table.  So the velocity jump v: 0 -> A w at t = 0 is not applied as an impulse: seen
from the lab, every body jumps with the table (a body the table carries moves off with it; one
that could slide freely would, in reality, keep its lab velocity).  The start at velocity A w is what keeps u bounded by A
while the table shakes: started from rest, -A w^2 sin(w t) would carry it away by 2 pi A per
cycle.  Only a(t) enters the dynamics; u and v are reported (the DEM's frames and instruments,
the rocking model's ``base_disp``).

:class:`TableMotion` is the table at rest (the base of the interface), :class:`SineMotion` the
shake.  ``displacement``, ``velocity`` and ``acceleration`` take arrays of times;
``acceleration_at`` takes one time (the event-driven integrator calls it at every right-hand
side evaluation); ``breakpoints`` splits an interval into pieces on which a(t) is monotone.
The DEM multiplies these by its direction vector (dem.loading.Shake); the two-body model uses
them along its rocking plane.
"""

from __future__ import annotations

import math

import numpy as np


class TableMotion:
    """The table at rest: u = v = a = 0 at all times (the base of the interface)."""

    period: float | None = None   # s, of the excitation (None: no periodic motion)
    t_end: float = 0.0            # s, from which on the table is at rest

    def displacement(self, t) -> np.ndarray:
        return np.zeros_like(np.asarray(t, dtype=float))

    def velocity(self, t) -> np.ndarray:
        return np.zeros_like(np.asarray(t, dtype=float))

    def acceleration(self, t) -> np.ndarray:
        return np.zeros_like(np.asarray(t, dtype=float))

    def acceleration_at(self, t: float) -> float:
        return 0.0

    def breakpoints(self, t0: float, t1: float) -> list[float]:
        """Times in (t0, t1) that split [t0, t1] into pieces on which a(t) is monotone."""
        return []

    def describe(self) -> dict:
        return {"type": "none"}


class SineMotion(TableMotion):
    """u(t) = A sin(2 pi f t) for ``cycles`` cycles, then the final velocity kept (module
    docstring)."""

    def __init__(self, amplitude: float, frequency: float, cycles: float):
        if not (amplitude > 0 and frequency > 0 and cycles > 0):
            raise ValueError("amplitude, frequency and cycles must be > 0")
        self.amplitude = float(amplitude)                    # A, m
        self.frequency = float(frequency)                    # f, Hz
        self.cycles = float(cycles)                          # n
        self.omega = 2.0 * np.pi * self.frequency            # w, rad/s
        self.t_end = self.cycles / self.frequency            # T, s
        self.period = 1.0 / self.frequency                   # s
        self.peak_acceleration = self.amplitude * self.omega**2   # A w^2, m/s2

    def displacement(self, t) -> np.ndarray:
        t = np.asarray(t, dtype=float)
        u = self.amplitude * np.sin(self.omega * np.clip(t, 0.0, self.t_end))
        v_end = self.amplitude * self.omega * np.cos(self.omega * self.t_end)
        return u + np.where(t > self.t_end, v_end * (t - self.t_end), 0.0)

    def velocity(self, t) -> np.ndarray:
        t = np.asarray(t, dtype=float)
        tc = np.minimum(t, self.t_end)
        return np.where(t >= 0.0, self.amplitude * self.omega * np.cos(self.omega * tc), 0.0)

    def acceleration(self, t) -> np.ndarray:
        t = np.asarray(t, dtype=float)
        moving = (t >= 0.0) & (t < self.t_end)
        return -self.peak_acceleration * np.sin(self.omega * t) * moving

    def acceleration_at(self, t: float) -> float:
        if t < 0.0 or t >= self.t_end:
            return 0.0
        return -self.peak_acceleration * math.sin(self.omega * t)

    def breakpoints(self, t0: float, t1: float) -> list[float]:
        # extrema of sin(w t) at w t = pi/2 + k pi, plus the end of shaking (a may jump to 0)
        out = []
        k = math.ceil((self.omega * t0 - math.pi / 2) / math.pi)
        while True:
            tk = (math.pi / 2 + k * math.pi) / self.omega
            if tk >= min(t1, self.t_end):
                break
            if tk > t0:
                out.append(tk)
            k += 1
        if t0 < self.t_end < t1:
            out.append(self.t_end)
        return out

    def describe(self) -> dict:
        return {"frequency_hz": self.frequency, "amplitude_m": self.amplitude,
                "peak_acceleration_m_s2": self.peak_acceleration, "cycles": self.cycles,
                "end_time_s": self.t_end}
