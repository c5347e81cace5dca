"""Base motion of the rocking model: horizontal table displacement u(t) and acceleration a(t).

The model is written in the table's frame (as the DEM is, ../shared/DESIGN.md): the base is fixed
and every body feels the inertia force -m a(t).  For the sinusoidal test signal of the thesis
(Section 4.2):

    u(t) = A sin(2 pi f t),  a(t) = -A (2 pi f)^2 sin(2 pi f t)   for 0 <= t <= n / f,

u and a frozen at their final values (a = 0) afterwards.  The velocity step A 2 pi f at t = 0 is not
applied (no impulse), as in the DEM.  Units: m, s, m/s2.
"""

from __future__ import annotations

import math

import numpy as np


class Excitation:
    """No base motion (free motion from the initial state)."""

    period: float | None = None
    t_stop: float = 0.0

    def acc(self, t: float) -> float:
        return 0.0

    def disp(self, t):
        return np.zeros_like(np.asarray(t, dtype=float))

    def acc_array(self, t):
        return np.zeros_like(np.asarray(t, dtype=float))

    def breakpoints(self, t0: float, t1: float) -> list[float]:
        """Times in (t0, t1) that split [t0, t1] into pieces on which a(t) is monotone."""
        return []

    def describe(self) -> dict:
        return {"type": "none"}


class Sine(Excitation):
    """u(t) = A sin(2 pi f t) for ``cycles`` cycles (A in m, f in Hz)."""

    def __init__(self, amplitude: float, frequency: float, cycles: float):
        if not (amplitude > 0 and frequency > 0 and cycles > 0):
            raise ValueError("amplitude, frequency and cycles must be > 0")
        self.A = float(amplitude)
        self.f = float(frequency)
        self.w = 2.0 * math.pi * self.f
        self.cycles = float(cycles)
        self.t_stop = self.cycles / self.f
        self.period = 1.0 / self.f
        self.peak = self.A * self.w * self.w

    def acc(self, t: float) -> float:
        if t < 0.0 or t > self.t_stop:
            return 0.0
        return -self.peak * math.sin(self.w * t)

    def acc_array(self, t):
        t = np.asarray(t, dtype=float)
        inside = (t >= 0.0) & (t <= self.t_stop)
        return np.where(inside, -self.peak * np.sin(self.w * t), 0.0)

    def disp(self, t):
        t = np.asarray(t, dtype=float)
        tc = np.clip(t, 0.0, self.t_stop)
        return self.A * np.sin(self.w * tc)

    def breakpoints(self, t0: float, t1: float) -> list[float]:
        # extrema of sin(w t) at w t = pi/2 + k pi, plus the end of shaking (a may jump to 0)
        out = []
        k = math.ceil((self.w * t0 - math.pi / 2) / math.pi)
        while True:
            tk = (math.pi / 2 + k * math.pi) / self.w
            if tk >= min(t1, self.t_stop):
                break
            if tk > t0:
                out.append(tk)
            k += 1
        if t0 < self.t_stop < t1:
            out.append(self.t_stop)
        return out

    def describe(self) -> dict:
        return {
            "type": "shake",
            "amplitude": self.A,
            "frequency": self.f,
            "cycles": self.cycles,
            "peak_acceleration": self.peak,
        }
