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

How the table starts (``start``; the case field ``loading.start``):

* ``table-frame`` (the default, all of the above): the table's velocity is A w from t = 0 on,
  the blocks never feel the jump from rest to A w;
* ``lab``: the table is at rest before t = 0 and moves as the sine after it, as a real table
  started from rest (thesis line 698) must: u, a as above, v = 0 for t < 0 and A w cos(w t)
  after, so v jumps 0 -> A w at t = 0 (an infinite acceleration for an instant: an impulse).
  A body at rest in the lab before t = 0 keeps its lab velocity through that instant (no finite
  force acts on it during it), so relative to the table it starts with -A w along the shake
  direction (:attr:`SineMotion.velocity_jump`; the DEM applies it once, after settling:
  dem.run.table_start).  Displacement starts at 0: the table then moves as u(t) = A sin(w t);
* ``ramp`` with ``ramp_cycles`` = n_r: the sine's amplitude rises over the first n_r cycles
  (T_r = n_r / f) along the quintic e(s) = 10 s^3 - 15 s^4 + 6 s^5, s = t / T_r (e, e', e''
  are 0 at s = 0 and e = 1, e' = e'' = 0 at s = 1), then holds:
      u = A e sin(w t),  v = A (e' sin + w e cos),  a = A ((e'' - w^2 e) sin + 2 w e' cos)
  (' = d/dt; e' = e_s / T_r, e'' = e_ss / T_r^2): displacement, velocity and acceleration are
  continuous from rest at t = 0 and into the held sine at T_r, so nothing jumps.  The peak
  acceleration during the ramp may exceed A w^2 by a little (the 2 w e' cos term:
  |2 e' / w| <= 15 / (8 pi n_r) of A w^2).  The ramp's cycles count among ``cycles``.

:class:`SteppedSineMotion` steps the frequency through a list on one
specimen without stopping; its docstring says how the steps join.

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


START_MODES = ("table-frame", "lab", "ramp")


def _quintic(s):
    """The ramp's envelope e(s) = 10 s^3 - 15 s^4 + 6 s^5 on s in [0, 1] (1 beyond, 0 before)
    and its first three derivatives with respect to s: (e, e_s, e_ss, e_sss)."""
    s = np.clip(np.asarray(s, dtype=float), 0.0, 1.0)
    inside = (s > 0.0) & (s < 1.0)
    e = s**3 * (10.0 - 15.0 * s + 6.0 * s * s)
    e_s = 30.0 * s * s * (1.0 - s) ** 2 * inside
    e_ss = 60.0 * s * (1.0 - s) * (1.0 - 2.0 * s) * inside
    e_sss = 60.0 * (1.0 - 6.0 * s + 6.0 * s * s) * inside
    return e, e_s, e_ss, e_sss


class SineMotion(TableMotion):
    """u(t) = A sin(2 pi f t) for ``cycles`` cycles, then the final velocity kept (module
    docstring); ``start``: "table-frame" (default), "lab" or "ramp" with ``ramp_cycles``."""

    def __init__(self, amplitude: float, frequency: float, cycles: float,
                 start: str = "table-frame", ramp_cycles: float | None = None):
        if not (amplitude > 0 and frequency > 0 and cycles > 0):
            raise ValueError("amplitude, frequency and cycles must be > 0")
        if start not in START_MODES:
            raise ValueError(f"start must be one of {START_MODES}, got {start!r}")
        if (start == "ramp") != (ramp_cycles is not None):
            raise ValueError("ramp_cycles goes with start = 'ramp' (and only with it)")
        if ramp_cycles is not None and not (0 < ramp_cycles <= cycles):
            raise ValueError(f"ramp_cycles must lie in (0, cycles = {cycles:g}], got "
                             f"{ramp_cycles}")
        self.amplitude = float(amplitude)                    # A, m
        self.frequency = float(frequency)                    # f, Hz
        self.cycles = float(cycles)                          # n
        self.omega = 2.0 * np.pi * self.frequency            # w, rad/s
        self.t_end = self.cycles / self.frequency            # T, s
        self.period = 1.0 / self.frequency                   # s
        self.peak_acceleration = self.amplitude * self.omega**2   # A w^2, m/s2
        self.start = start
        self.ramp_cycles = None if ramp_cycles is None else float(ramp_cycles)
        self.t_ramp = 0.0 if ramp_cycles is None else self.ramp_cycles / self.frequency  # T_r, s

    @property
    def velocity_jump(self) -> float:
        """m/s: the table's velocity jump at t = 0 that the bodies take as an impulse (relative
        to the table they start with minus this): A w for a ``lab`` start, else 0."""
        return self.amplitude * self.omega if self.start == "lab" else 0.0

    def _ramped(self, t, order: int):
        """d^order u / dt^order (order 0 - 3) of the ramped sine u = A e(t / T_r) sin(w t) at
        times t in [0, T] (module docstring)."""
        A, w, T = self.amplitude, self.omega, self.t_ramp
        e, e_s, e_ss, e_sss = _quintic(np.asarray(t, dtype=float) / T)
        e1, e2, e3 = e_s / T, e_ss / T**2, e_sss / T**3
        s, c = np.sin(w * t), np.cos(w * t)
        if order == 0:
            return A * e * s
        if order == 1:
            return A * (e1 * s + w * e * c)
        if order == 2:
            return A * ((e2 - w * w * e) * s + 2.0 * w * e1 * c)
        return A * ((e3 - 3.0 * w * w * e1) * s + (3.0 * w * e2 - w**3 * e) * c)

    def displacement(self, t) -> np.ndarray:
        t = np.asarray(t, dtype=float)
        if self.start == "ramp":
            v_end = float(self._ramped(self.t_end, 1))
            return self._ramped(np.clip(t, 0.0, self.t_end), 0) + \
                np.where(t > self.t_end, v_end * (t - self.t_end), 0.0)
        u = self.amplitude * np.sin(self.omega * np.clip(t, 0.0, self.t_end))
        v_end = self.amplitude * self.omega * np.cos(self.omega * self.t_end)
        return u + np.where(t > self.t_end, v_end * (t - self.t_end), 0.0)

    def velocity(self, t) -> np.ndarray:
        """Table velocity, m/s: 0 before t = 0 (for every start; with ``table-frame`` the bodies
        are not told of the jump at 0, with ``lab`` they take it, with ``ramp`` there is none)."""
        t = np.asarray(t, dtype=float)
        tc = np.minimum(t, self.t_end)
        if self.start == "ramp":
            return np.where(t >= 0.0, self._ramped(np.maximum(tc, 0.0), 1), 0.0)
        return np.where(t >= 0.0, self.amplitude * self.omega * np.cos(self.omega * tc), 0.0)

    def acceleration(self, t) -> np.ndarray:
        t = np.asarray(t, dtype=float)
        moving = (t >= 0.0) & (t < self.t_end)
        if self.start == "ramp":
            return self._ramped(np.clip(t, 0.0, self.t_end), 2) * moving
        return -self.peak_acceleration * np.sin(self.omega * t) * moving

    def acceleration_at(self, t: float) -> float:
        if t < 0.0 or t >= self.t_end:
            return 0.0
        if self.start == "ramp" and t < self.t_ramp:
            return float(self._ramped(t, 2))
        return -self.peak_acceleration * math.sin(self.omega * t)

    def breakpoints(self, t0: float, t1: float) -> list[float]:
        # extrema of sin(w t) at w t = pi/2 + k pi, plus the end of shaking (a may jump to 0);
        # during a ramp, the roots of the jerk (the third derivative of u) instead
        out = []
        if self.start == "ramp" and t0 < self.t_ramp:
            out += self._ramp_extrema(max(t0, 0.0), min(t1, self.t_ramp))
            if self.t_ramp < t1:
                out.append(self.t_ramp)
            t0 = self.t_ramp
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

    def _ramp_extrema(self, t0: float, t1: float) -> list[float]:
        """Times in (t0, t1) where the ramped acceleration has an extremum (jerk = 0),
        bracketed on a grid of 64 points a period and refined by scipy's brentq."""
        from scipy.optimize import brentq

        if t1 <= t0:
            return []
        n = max(2, int(math.ceil(64 * (t1 - t0) / self.period)) + 1)
        grid = np.linspace(t0, t1, n)
        j = self._ramped(grid, 3)
        out = []
        for a, b, ja, jb in zip(grid[:-1], grid[1:], j[:-1], j[1:]):
            if ja == 0.0 and a > t0:
                out.append(float(a))
            elif ja * jb < 0.0:
                out.append(float(brentq(lambda x: float(self._ramped(x, 3)), a, b, xtol=1e-14)))
        return out

    def describe(self) -> dict:
        out = {"frequency_hz": self.frequency, "amplitude_m": self.amplitude,
               "peak_acceleration_m_s2": self.peak_acceleration, "cycles": self.cycles,
               "end_time_s": self.t_end}
        if self.start != "table-frame":   # (the default writes what it always wrote)
            out["start"] = self.start
            if self.start == "lab":
                out["velocity_jump_m_s"] = self.velocity_jump
            if self.start == "ramp":
                out.update({"ramp_cycles": self.ramp_cycles, "ramp_time_s": self.t_ramp})
        return out


class SteppedSineMotion(TableMotion):
    """A sine whose frequency steps through a list on one specimen, never stopped between steps
    (the case's ``loading: {type: stepped_shake}``).

    ``steps``: [(f_k Hz, n_k cycles)] in the order run (rising frequencies: an up pass; falling:
    a down pass); every step has the same peak acceleration a_p (A_k = a_p / w_k^2, m) or the
    same displacement amplitude A (A_k = A), w_k = 2 pi f_k.  Step k runs from t_k (t_0 = 0):

        u(t) = c_k + A_k sin(w_k (t - t_k) + phi_k)                  m
        v(t) = A_k w_k cos(w_k (t - t_k) + phi_k)                    m/s
        a(t) = -A_k w_k^2 sin(w_k (t - t_k) + phi_k)                 m/s2

    with phi_0 = 0, c_0 = 0.  Phase matching: step k runs its n_k cycles, then on to the next
    displacement extreme, where the table's velocity is zero: its end phase Phi_k is the first
    pi/2 + m pi at or after phi_k + 2 pi n_k (so each step runs at most half a period more than
    its n_k cycles; ``steps_run`` lists the cycles run).  The next step starts from that extreme
    on the same side: phi_k+1 = Phi_k mod 2 pi (pi/2 or 3 pi/2, sin = s_k = +-1), and its
    offset keeps the displacement continuous: c_k+1 = c_k + (A_k - A_k+1) s_k.  So v is
    continuous (0 on both sides); at constant peak acceleration a is too (-a_p s_k on both
    sides), and the offset left is only a shift of the table (the bodies, in the table's frame,
    feel only a); at constant amplitude the offset stays 0 and a jumps from -A w_k^2 s_k to
    -A w_k+1^2 s_k, a finite step.  The last step also ends at a displacement extreme: the table
    is then at rest (v = 0) where it is, a = 0 after (a step of a_p that the bodies feel, as
    when a real table stops at an extreme; no drift, unlike the single sine's end).

    ``start`` as :class:`SineMotion`'s (module docstring), applied to the first step: ``lab``
    makes the bodies take -A_0 w_0 (:attr:`velocity_jump`), ``ramp`` raises the first step's
    amplitude over its first ``ramp_cycles`` cycles (at most n_0).
    """

    def __init__(self, steps, amplitude: float | None = None,
                 peak_acceleration: float | None = None, start: str = "table-frame",
                 ramp_cycles: float | None = None):
        steps = [(float(f), float(n)) for f, n in steps]
        if not steps or any(not (f > 0 and n > 0) for f, n in steps):
            raise ValueError("steps must be a non-empty list of (frequency > 0, cycles > 0)")
        if (amplitude is None) == (peak_acceleration is None):
            raise ValueError("give exactly one of amplitude or peak_acceleration")
        if not ((amplitude or peak_acceleration) > 0):
            raise ValueError("amplitude / peak_acceleration must be > 0")
        self.steps = steps
        self.constant = "amplitude" if amplitude is not None else "peak_acceleration"
        self.freq = np.array([f for f, _ in steps])                       # f_k, Hz
        self.omega = 2.0 * np.pi * self.freq                              # w_k, rad/s
        self.amp = (np.full(len(steps), float(amplitude)) if amplitude is not None
                    else float(peak_acceleration) / self.omega**2)       # A_k, m
        self.peak_acceleration = float(np.max(self.amp * self.omega**2))  # m/s2
        n = len(steps)
        self.t0 = np.zeros(n + 1)      # t_k, s (t_0 .. t_n = end)
        self.phi = np.zeros(n)         # phi_k, rad
        self.offset = np.zeros(n)      # c_k, m
        self.cycles_run = np.zeros(n)  # (Phi_k - phi_k) / 2 pi
        self.sign = np.zeros(n)        # s_k = sin(Phi_k)
        for k, (f, cyc) in enumerate(steps):
            target = self.phi[k] + 2.0 * np.pi * cyc
            m = math.ceil((target - 0.5 * np.pi) / np.pi - 1e-9)
            end_phase = 0.5 * np.pi + m * np.pi
            self.sign[k] = 1.0 if m % 2 == 0 else -1.0
            self.cycles_run[k] = (end_phase - self.phi[k]) / (2.0 * np.pi)
            self.t0[k + 1] = self.t0[k] + (end_phase - self.phi[k]) / self.omega[k]
            if k + 1 < n:
                self.phi[k + 1] = 0.5 * np.pi if self.sign[k] > 0 else 1.5 * np.pi
                self.offset[k + 1] = self.offset[k] + (self.amp[k] - self.amp[k + 1]) * \
                    self.sign[k]
        self.t_end = float(self.t0[-1])
        self.u_end = float(self.offset[-1] + self.amp[-1] * self.sign[-1])
        self.period = None   # no single period
        self.start = start
        self.first = SineMotion(self.amp[0], self.freq[0], self.cycles_run[0], start,
                                ramp_cycles)   # step 0 (phase 0, offset 0), with its start
        if ramp_cycles is not None and ramp_cycles > steps[0][1]:
            raise ValueError(f"ramp_cycles must not exceed the first step's cycles "
                             f"({steps[0][1]:g}), got {ramp_cycles}")

    @property
    def velocity_jump(self) -> float:
        """m/s: A_0 w_0 for a ``lab`` start (the bodies take minus this at t = 0), else 0."""
        return self.first.velocity_jump

    def step_of(self, t) -> np.ndarray:
        """Index k of the step running at each time t (-1 before 0, n after the end)."""
        t = np.asarray(t, dtype=float)
        k = np.searchsorted(self.t0, t, side="right") - 1
        return np.where(t < 0.0, -1, np.minimum(k, len(self.steps)))

    def _eval(self, t, order: int) -> np.ndarray:
        t = np.asarray(t, dtype=float)
        out = np.zeros_like(t)
        k_of = self.step_of(t)
        for k in range(len(self.steps)):
            m = k_of == k
            if not m.any():
                continue
            tau = t[m] - self.t0[k]
            if k == 0:
                out[m] = (self.first.displacement, self.first.velocity,
                          self.first.acceleration)[order](tau)
                continue
            ph = self.omega[k] * tau + self.phi[k]
            A, w = self.amp[k], self.omega[k]
            out[m] = (self.offset[k] + A * np.sin(ph), A * w * np.cos(ph),
                      -A * w * w * np.sin(ph))[order]
        if order == 0:
            out[k_of >= len(self.steps)] = self.u_end
        return out

    def displacement(self, t) -> np.ndarray:
        return self._eval(t, 0)

    def velocity(self, t) -> np.ndarray:
        return self._eval(t, 1)

    def acceleration(self, t) -> np.ndarray:
        return self._eval(t, 2)

    def acceleration_at(self, t: float) -> float:
        return float(self._eval(np.array([t]), 2)[0])

    def breakpoints(self, t0: float, t1: float) -> list[float]:
        """The step switches and each step's acceleration extrema (the first step's from
        :class:`SineMotion`) in (t0, t1)."""
        out = [float(x) for x in self.first.breakpoints(t0 - self.t0[0],
                                                         min(t1, self.t0[1]))
               if t0 < x < min(t1, self.t0[1])]
        for k in range(1, len(self.steps)):
            a, b = max(t0, self.t0[k]), min(t1, self.t0[k + 1])
            if self.t0[k] > t0 and self.t0[k] < t1:
                out.append(float(self.t0[k]))
            if b <= a:
                continue
            w = self.omega[k]
            m = math.ceil(((a - self.t0[k]) * w + self.phi[k] - 0.5 * np.pi) / np.pi)
            while True:
                tk = self.t0[k] + (0.5 * np.pi + m * np.pi - self.phi[k]) / w
                if tk >= b:
                    break
                if tk > a:
                    out.append(float(tk))
                m += 1
        if t0 < self.t_end < t1:
            out.append(self.t_end)
        return sorted(set(out))

    def steps_run(self) -> list[dict]:
        """Each step as run: frequency, amplitude, peak acceleration, start and end times,
        the cycles asked for and run, the displacement offset c_k and the end side s_k."""
        return [{"frequency_hz": float(self.freq[k]), "amplitude_m": float(self.amp[k]),
                 "peak_acceleration_m_s2": float(self.amp[k] * self.omega[k] ** 2),
                 "t_start_s": float(self.t0[k]), "t_end_s": float(self.t0[k + 1]),
                 "cycles": self.steps[k][1], "cycles_run": float(self.cycles_run[k]),
                 "start_phase_rad": float(self.phi[k]), "offset_m": float(self.offset[k]),
                 "end_side": int(self.sign[k])} for k in range(len(self.steps))]

    def describe(self) -> dict:
        out = {"constant": self.constant, "peak_acceleration_m_s2": self.peak_acceleration,
               "end_time_s": self.t_end, "start": self.start, "steps": self.steps_run()}
        if self.start == "lab":
            out["velocity_jump_m_s"] = self.velocity_jump
        if self.start == "ramp":
            out.update({"ramp_cycles": self.first.ramp_cycles, "ramp_time_s": self.first.t_ramp})
        return out
