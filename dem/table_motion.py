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

:class:`DistortedSineMotion` plays the sine as a servo-hydraulic table might, with a third
harmonic and a spike at every velocity reversal (``loading.distortion``); its docstring
derives the displacement and velocity.  :class:`SteppedSineMotion` steps the frequency through
a list on one specimen without stopping; its docstring says how the steps join.
:class:`SweepMotion` (a sine sweep) and :class:`NoiseMotion` (band-limited white noise) drive
a model's identification (docs/identification.md); both start and end at rest.

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
    same displacement amplitude A (A_k = A), w_k = 2 pi f_k, unless ``levels`` gives step k a
    level of its own, ("peak_acceleration", a_p,k) or ("amplitude", A_k) (None: the common
    one): a kick-start (two cycles above a threshold, then the test level), a protocol of
    rising intensity, a continuation in amplitude at one frequency.  Step k runs from t_k
    (t_0 = 0):

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
    -A w_k+1^2 s_k, a finite step; with levels of their own, a steps from -A_k w_k^2 s_k to
    -A_k+1 w_k+1^2 s_k (the kick-start's drop from its level to the test level).  The last
    step also ends at a displacement extreme: the table is then at rest (v = 0) where it is,
    a = 0 after (a step of a_p that the bodies feel, as when a real table stops at an extreme;
    no drift, unlike the single sine's end).

    ``start`` as :class:`SineMotion`'s (module docstring), applied to the first step: ``lab``
    makes the bodies take -A_0 w_0 (:attr:`velocity_jump`), ``ramp`` raises the first step's
    amplitude over its first ``ramp_cycles`` cycles (at most n_0).
    """

    def __init__(self, steps, amplitude: float | None = None,
                 peak_acceleration: float | None = None, start: str = "table-frame",
                 ramp_cycles: float | None = None, levels=None):
        steps = [(float(f), float(n)) for f, n in steps]
        if not steps or any(not (f > 0 and n > 0) for f, n in steps):
            raise ValueError("steps must be a non-empty list of (frequency > 0, cycles > 0)")
        levels = [None] * len(steps) if levels is None else list(levels)
        if len(levels) != len(steps):
            raise ValueError(f"levels: {len(levels)} entries for {len(steps)} steps")
        for k, lev in enumerate(levels):
            if lev is not None and (len(lev) != 2 or lev[0] not in
                                    ("amplitude", "peak_acceleration") or not lev[1] > 0):
                raise ValueError(f"levels[{k}]: need (\"amplitude\" | \"peak_acceleration\", "
                                 f"value > 0) or None, got {lev!r}")
        if amplitude is not None and peak_acceleration is not None:
            raise ValueError("give exactly one of amplitude or peak_acceleration")
        if amplitude is None and peak_acceleration is None and None in levels:
            raise ValueError("give amplitude or peak_acceleration (for the steps without a "
                             "level of their own)")
        if not all(x is None or x > 0 for x in (amplitude, peak_acceleration)):
            raise ValueError("amplitude / peak_acceleration must be > 0")
        self.steps = steps
        self.freq = np.array([f for f, _ in steps])                       # f_k, Hz
        self.omega = 2.0 * np.pi * self.freq                              # w_k, rad/s
        if all(lev is None for lev in levels):   # one level for every step
            self.constant = "amplitude" if amplitude is not None else "peak_acceleration"
            self.amp = (np.full(len(steps), float(amplitude)) if amplitude is not None
                        else float(peak_acceleration) / self.omega**2)   # A_k, m
        else:                                    # a level per step (kick-start, protocols)
            self.constant = "per_step"
            own = [lev if lev is not None else
                   (("amplitude", amplitude) if amplitude is not None
                    else ("peak_acceleration", peak_acceleration)) for lev in levels]
            self.amp = np.array([float(v) if kind == "amplitude"
                                 else float(v) / float(self.omega[k]) ** 2
                                 for k, (kind, v) in enumerate(own)])    # A_k, m
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


def _taper(t, t_in: float, t_out: float, t_end: float):
    """Envelope E(t) = e(t / t_in) e((t_end - t) / t_out) with the ramp's quintic e
    (:func:`_quintic`) and its first two time derivatives (E, E', E''): 0 with E' = E'' = 0 at
    t = 0 and t = t_end, 1 in between the tapers (t_in + t_out <= t_end)."""
    a, a_s, a_ss, _ = _quintic(np.asarray(t, dtype=float) / t_in)
    b, b_s, b_ss, _ = _quintic((t_end - np.asarray(t, dtype=float)) / t_out)
    a1, a2 = a_s / t_in, a_ss / t_in**2
    b1, b2 = -b_s / t_out, b_ss / t_out**2
    return a * b, a1 * b + a * b1, a2 * b + 2.0 * a1 * b1 + a * b2


class _GridBreakpoints:
    """``breakpoints`` of a motion without closed-form acceleration extrema: the local extrema
    of a(t) on a grid of ``_grid_points`` points per shortest period (approximate, to that
    grid; only the two-body model's event integrator asks, and it takes shakes only).  Such a
    motion starts from rest: no velocity jump for the bodies to take."""

    velocity_jump = 0.0   # m/s

    def breakpoints(self, t0: float, t1: float) -> list[float]:
        a, b = max(t0, 0.0), min(t1, self.t_end)
        if b <= a:
            return [self.t_end] if t0 < self.t_end < t1 else []
        n = max(3, int(math.ceil(32 * (b - a) * self.f_max)) + 1)
        grid = np.linspace(a, b, n)
        d = np.diff(self.acceleration(grid))
        out = [float(grid[i + 1]) for i in range(len(d) - 1) if d[i] * d[i + 1] < 0.0]
        if t0 < self.t_end < t1:
            out.append(self.t_end)
        return [x for x in out if t0 < x < t1]

    def acceleration_at(self, t: float) -> float:
        return float(self.acceleration(np.array([float(t)]))[0])


class DistortedSineMotion(SineMotion):
    """A sine shake as a servo-hydraulic table plays it: the commanded sine plus a third
    harmonic and a spike at every velocity reversal (the case's ``loading.distortion``).

    A table driven by a displacement command adds harmonics of its own (the servo valve's and
    the oil column's nonlinearity) and a short acceleration spike where the velocity reverses
    (the valve's spool crossing its lap, the friction of the actuator's seals changing sign);
    their size is rarely reported with a test.  This motion bounds what such a distortion can do
    to a rigid-block response; its sizes are inputs, not measurements.

    Nominal motion (:class:`SineMotion`, w = 2 pi f, a_p = A w^2): u0 = A sin(w t),
    a0 = -a_p sin(w t).  Added to it, for 0 <= t < T (T = cycles / f):

    * the third harmonic of relative size h (-), in the phase that sharpens the peaks:

          a_h = +h a_p sin(3 w t)         so  a0 + a_h = -a_p [sin(w t) - h sin(3 w t)],
          v_h = -(h A w / 3) cos(3 w t),   u_h = -(h A / 9) sin(3 w t)

      (the integrals without constants: periodic, zero mean, u_h(0) = 0, as the fundamental's
      A sin(w t) is).  With x = sin(w t), sin(w t) - h sin(3 w t) = (1 - 3 h) x + 4 h x^3, which
      rises monotonically over x in [-1, 1] for h >= 0: the peak acceleration is a_p (1 + h),
      at the fundamental's own peaks (w t = pi/2 + k pi, where sin(3 w t) = -sin(w t));

    * a reversal spike of relative peak s (-) and duration tau (s): at every velocity reversal
      of the nominal motion, t_k = (pi/2 + k pi) / w (k = 0, 1, ...; the displacement extremes),
      a half-sine pulse of the acceleration starting at t_k, in the direction of the nominal
      acceleration there (sigma_k = -sin(w t_k) = -(-1)^k), so that it adds to the peak:

          a_s(t) = sigma_k s a_p sin(pi (t - t_k) / tau)    for t_k <= t < t_k + tau, else 0.

      Each pulse changes the velocity by sigma_k delta, delta = 2 s a_p tau / pi; the pulses
      alternate in sign, so the velocity is a square wave of +-delta / 2 with half-cosine edges.
      With P(r) = s a_p (tau / pi) (1 - cos(pi r / tau)) (r <= tau; delta beyond) and
      Q(r) = s a_p (tau / pi) (r - (tau / pi) sin(pi r / tau)) (r <= tau;
      delta tau / 2 + delta (r - tau) beyond) its integrals from the pulse's start, and
      r = t - t_k for the last reversal t_k <= t:

          v_s(t) = delta / 2                               for t < t_0 = T_1 / 4,
          v_s(t) = sigma_k (P(r) - delta / 2)              after t_k,
          u_s(t) = delta t / 2                             for t < t_0,
          u_s(t) = u_s(t_k) + sigma_k (Q(r) - delta r / 2) after t_k,
          u_s(t_k) = delta T_1 / 8 (k even),  -delta T_1 / 8 + delta tau / 2 (k odd)

      (T_1 = 1 / f).  The constants are those that keep the table where a sine keeps it: the
      velocity of zero mean over every period (a bounded displacement, as the fundamental's
      start at velocity A w gives: dem.table_motion's module docstring) and u_s(0) = 0 (the
      displacement starts at 0, so a ``lab`` start has no displacement jump); u_s is then
      periodic with period T_1.  The pulses must not overlap: tau <= T_1 / 2.

    ``start`` applies to the whole distorted motion as to the sine: ``table-frame`` starts
    with the velocity v(0) = A w (1 - h / 3) + delta / 2 without telling the bodies; ``lab``
    makes them take minus that (:attr:`velocity_jump`); ``ramp`` multiplies the distortion's
    displacement d = u_h + u_s by the ramp's envelope e(t) as it does the sine's, so its
    velocity and acceleration are e' d + e d' and e'' d + 2 e' d' + e d'' (nothing jumps).
    After T, a = 0 and the table keeps its final velocity, as the sine's.  Everything else
    (``peak_acceleration`` = a_p, the nominal level; ``frequency``, ``period``, ``t_end``) is
    the nominal sine's; :attr:`distorted_peak_acceleration` is the distorted motion's.
    """

    def __init__(self, amplitude: float, frequency: float, cycles: float,
                 start: str = "table-frame", ramp_cycles: float | None = None,
                 third_harmonic: float = 0.0, spike_peak: float = 0.0,
                 spike_duration: float | None = None):
        super().__init__(amplitude, frequency, cycles, start, ramp_cycles)
        if not (math.isfinite(third_harmonic) and third_harmonic >= 0.0):
            raise ValueError(f"third_harmonic must be >= 0, got {third_harmonic}")
        if not (math.isfinite(spike_peak) and spike_peak >= 0.0):
            raise ValueError(f"spike_peak must be >= 0, got {spike_peak}")
        if spike_peak > 0.0 and spike_duration is None:
            raise ValueError("a reversal spike needs its duration (spike_duration, s)")
        if spike_duration is not None and not (0.0 < spike_duration <= 0.5 * self.period):
            raise ValueError(f"spike_duration must lie in (0, half a period = "
                             f"{0.5 * self.period:.4g} s], got {spike_duration}")
        self.third_harmonic = float(third_harmonic)                       # h, -
        self.spike_peak = float(spike_peak)                               # s, -
        self.spike_duration = None if spike_duration is None else float(spike_duration)  # tau
        tau = self.spike_duration or 0.0
        self.spike_dv = 2.0 * self.spike_peak * self.peak_acceleration * tau / np.pi  # delta
        # the grid breakpoints' finest feature: the harmonic's period or the spike's length
        self.f_max = max(3.0 * self.frequency, 0.5 / tau if tau > 0.0 else 0.0)

    # -- the distortion d(t) = u_h + u_s of the periodic motion (t >= 0), and its derivatives
    def _spike(self, t, order: int) -> np.ndarray:
        """d^order u_s / dt^order (order 0 - 2) at times t >= 0 (class docstring)."""
        t = np.asarray(t, dtype=float)
        if self.spike_peak == 0.0:
            return np.zeros_like(t)
        tau, delta, T1 = self.spike_duration, self.spike_dv, self.period
        c = self.spike_peak * self.peak_acceleration            # s a_p, m/s2
        k = np.floor((t - 0.25 * T1) / (0.5 * T1))             # last reversal (-1: none yet)
        before = k < 0
        k = np.maximum(k, 0.0)
        sigma = np.where(k % 2 == 0, -1.0, 1.0)
        r = t - (0.25 * T1 + 0.5 * T1 * k)
        inside = r < tau
        x = np.pi * np.minimum(r, tau) / tau
        if order == 2:
            return np.where(before | ~inside, 0.0, sigma * c * np.sin(x))
        if order == 1:
            P = np.where(inside, c * tau / np.pi * (1.0 - np.cos(x)), delta)
            return np.where(before, 0.5 * delta, sigma * (P - 0.5 * delta))
        Q = np.where(inside, c * tau / np.pi * (r - tau / np.pi * np.sin(x)),
                     0.5 * delta * tau + delta * (r - tau))
        u_k = np.where(sigma < 0.0, delta * T1 / 8.0, -delta * T1 / 8.0 + 0.5 * delta * tau)
        return np.where(before, 0.5 * delta * t, u_k + sigma * (Q - 0.5 * delta * r))

    def _harmonic(self, t, order: int) -> np.ndarray:
        """d^order u_h / dt^order (order 0 - 2) at times t (class docstring)."""
        h, A, w = self.third_harmonic, self.amplitude, self.omega
        x = 3.0 * w * np.asarray(t, dtype=float)
        return (-(h * A / 9.0) * np.sin(x), -(h * A * w / 3.0) * np.cos(x),
                h * A * w * w * np.sin(x))[order]

    def distortion(self, t, order: int) -> np.ndarray:
        """d^order/dt^order of what the distortion adds to the sine's displacement, at times t
        in [0, T]: d = u_h + u_s, times the ramp's envelope for a ``ramp`` start."""
        t = np.asarray(t, dtype=float)
        d = [self._harmonic(t, n) + self._spike(t, n) for n in range(order + 1)]
        if self.start != "ramp":
            return d[order]
        e, e_s, e_ss, _ = _quintic(t / self.t_ramp)
        e1, e2 = e_s / self.t_ramp, e_ss / self.t_ramp**2
        if order == 0:
            return e * d[0]
        if order == 1:
            return e1 * d[0] + e * d[1]
        return e2 * d[0] + 2.0 * e1 * d[1] + e * d[2]

    @property
    def velocity_jump(self) -> float:
        """m/s: for a ``lab`` start the distorted table's velocity at t = 0+,
        A w (1 - h / 3) + delta / 2 (the bodies take minus this), else 0."""
        if self.start != "lab":
            return 0.0
        return float(self.amplitude * self.omega + self.distortion(0.0, 1))

    def displacement(self, t) -> np.ndarray:
        t = np.asarray(t, dtype=float)
        v_end = float(self.distortion(self.t_end, 1))
        return super().displacement(t) + self.distortion(np.clip(t, 0.0, self.t_end), 0) + \
            np.where(t > self.t_end, v_end * (t - self.t_end), 0.0)

    def velocity(self, t) -> np.ndarray:
        t = np.asarray(t, dtype=float)
        extra = self.distortion(np.clip(t, 0.0, self.t_end), 1)
        return super().velocity(t) + np.where(t >= 0.0, extra, 0.0)

    def acceleration(self, t) -> np.ndarray:
        t = np.asarray(t, dtype=float)
        moving = (t >= 0.0) & (t < self.t_end)
        extra = self.distortion(np.clip(t, 0.0, self.t_end), 2)
        return super().acceleration(t) + np.where(moving, extra, 0.0)

    def acceleration_at(self, t: float) -> float:
        return float(self.acceleration(np.array([float(t)]))[0])

    def breakpoints(self, t0: float, t1: float) -> list[float]:
        """The local extrema of a(t) on a grid (:class:`_GridBreakpoints`), approximate."""
        return _GridBreakpoints.breakpoints(self, t0, t1)

    @property
    def distorted_peak_acceleration(self) -> float:
        """max |a| (m/s2) over one period of the held motion, sampled: 4000 points a period and
        400 across each of its two pulses (the harmonic's peak, a_p (1 + h), is on the grid; a
        spike's crest lies within 1 / 800 of the pulse of a sample)."""
        t0 = self.t_ramp + 0.25 * self.period          # a reversal of the held motion
        t = t0 + np.linspace(0.0, self.period, 4001)
        if self.spike_duration is not None:
            pulse = np.linspace(0.0, self.spike_duration, 401)
            t = np.concatenate([t, t0 + pulse, t0 + 0.5 * self.period + pulse])
        moving = t < self.t_end
        return float(np.abs(self.acceleration(t[moving])).max()) if moving.any() else 0.0

    def describe(self) -> dict:
        out = super().describe()
        out["distortion"] = {"third_harmonic": self.third_harmonic,
                             "spike_peak": self.spike_peak,
                             "spike_duration_s": self.spike_duration,
                             "peak_acceleration_m_s2": self.distorted_peak_acceleration}
        return out   # (a lab start's velocity_jump_m_s is the distorted table's already)


class SweepMotion(_GridBreakpoints, TableMotion):
    """A sine sweep (the case's ``loading: {type: sweep}``): the frequency rises from f0 to f1
    (Hz) over T s, linearly or logarithmically, at constant peak acceleration a_p (m/s2) or
    constant displacement amplitude A (m), started and ended at rest by quintic tapers.

    Phase phi(t) (rad) and instantaneous frequency f(t) = phi'(t) / (2 pi), 0 <= t <= T:

        linear:  f(t) = f0 + k t,  k = (f1 - f0) / T (Hz/s),   phi = 2 pi (f0 t + k t^2 / 2)
        log:     f(t) = f0 r^(t/T), r = f1 / f0,
                 phi = 2 pi f0 T (r^(t/T) - 1) / ln r

    (the exponential sweep: equal time per octave, T / log2(r) s each).  Displacement

        u(t) = E(t) U(t) sin(phi(t)),   U = A  or  U = a_p / phi'(t)^2,

    E(t) = e(t / T_a) e((T - t) / T_b): the ramp's quintic e(s) = 10 s^3 - 15 s^4 + 6 s^5
    (as ``start: ramp`` of a shake) over T_a = n_t / f0 at the start and T_b = n_t / f1 at the
    end (n_t = ``taper_cycles``).  Velocity and acceleration are the exact derivatives (g = E U):

        v = g' sin(phi) + g phi' cos(phi)
        a = (g'' - g phi'^2) sin(phi) + (2 g' phi' + g phi'') cos(phi)

    so u, v, a are continuous, zero at t = 0 (the table starts from rest: no velocity jump for
    the bodies to take, as a ramp start) and zero from T on (the table stops where it started).
    Away from the tapers |a| peaks at a_p (or A w^2) up to the terms in g', g'', phi'', of
    relative size ~ 2 k / (2 pi f^2) for a linear sweep (a slow sweep: k << f^2): the sweep
    rate sets how far the peak acceleration departs from a_p.
    """

    def __init__(self, f0: float, f1: float, duration: float, law: str = "linear",
                 amplitude: float | None = None, peak_acceleration: float | None = None,
                 taper_cycles: float = 2.0):
        if not (0 < f0 < f1):
            raise ValueError(f"need 0 < f0 < f1, got f0 = {f0}, f1 = {f1}")
        if law not in ("linear", "log"):
            raise ValueError(f"law must be 'linear' or 'log', got {law!r}")
        if (amplitude is None) == (peak_acceleration is None):
            raise ValueError("give exactly one of amplitude or peak_acceleration")
        if not ((amplitude or peak_acceleration) > 0 and duration > 0 and taper_cycles > 0):
            raise ValueError("amplitude / peak_acceleration, duration and taper_cycles must be "
                             "> 0")
        self.f0, self.f1, self.law = float(f0), float(f1), law
        self.t_end = float(duration)                                 # T, s
        self.amplitude = None if amplitude is None else float(amplitude)
        self.peak_acceleration = (float(peak_acceleration) if peak_acceleration is not None
                                  else self.amplitude * (2.0 * np.pi * self.f1) ** 2)
        self.constant = "amplitude" if amplitude is not None else "peak_acceleration"
        self.taper_cycles = float(taper_cycles)
        self.t_in, self.t_out = self.taper_cycles / self.f0, self.taper_cycles / self.f1
        if self.t_in + self.t_out > self.t_end:
            raise ValueError(f"the tapers ({self.t_in:.3g} s + {self.t_out:.3g} s: "
                             f"taper_cycles / f0 + taper_cycles / f1) exceed the duration "
                             f"{self.t_end:g} s")
        self.f_max = self.f1
        self.period = None

    def frequency(self, t) -> np.ndarray:
        """Instantaneous frequency f(t) = phi'(t) / (2 pi), Hz, t clipped to [0, T]."""
        t = np.clip(np.asarray(t, dtype=float), 0.0, self.t_end)
        if self.law == "linear":
            return self.f0 + (self.f1 - self.f0) / self.t_end * t
        return self.f0 * (self.f1 / self.f0) ** (t / self.t_end)

    def phase(self, t):
        """(phi, phi', phi'', phi''') at t in [0, T]: rad, rad/s, rad/s2, rad/s3."""
        t = np.asarray(t, dtype=float)
        T, f0 = self.t_end, self.f0
        if self.law == "linear":
            k = (self.f1 - f0) / T
            return (2.0 * np.pi * (f0 * t + 0.5 * k * t * t), 2.0 * np.pi * (f0 + k * t),
                    np.full_like(t, 2.0 * np.pi * k), np.zeros_like(t))
        c = math.log(self.f1 / f0) / T
        f = f0 * np.exp(c * t)
        return 2.0 * np.pi * (f - f0) / c, 2.0 * np.pi * f, 2.0 * np.pi * f * c, \
            2.0 * np.pi * f * c * c

    def _derivatives(self, t):
        """(u, v, a) at t in [0, T] (class docstring)."""
        p, p1, p2, p3 = self.phase(t)
        E, E1, E2 = _taper(t, self.t_in, self.t_out, self.t_end)
        if self.constant == "amplitude":
            U, U1, U2 = np.full_like(p1, self.amplitude), np.zeros_like(p1), np.zeros_like(p1)
        else:
            ap = self.peak_acceleration
            U = ap / p1**2
            U1 = -2.0 * ap * p2 / p1**3
            U2 = -2.0 * ap * p3 / p1**3 + 6.0 * ap * p2**2 / p1**4
        g, g1, g2 = E * U, E1 * U + E * U1, E2 * U + 2.0 * E1 * U1 + E * U2
        s, c = np.sin(p), np.cos(p)
        return (g * s, g1 * s + g * p1 * c,
                (g2 - g * p1 * p1) * s + (2.0 * g1 * p1 + g * p2) * c)

    def _eval(self, t, order: int) -> np.ndarray:
        t = np.asarray(t, dtype=float)
        inside = (t > 0.0) & (t < self.t_end)
        return np.where(inside, self._derivatives(np.clip(t, 0.0, self.t_end))[order], 0.0)

    def displacement(self, t) -> np.ndarray:
        return self._eval(t, 0)

    def velocity(self, t) -> np.ndarray:
        return self._eval(t, 1)

    def acceleration(self, t) -> np.ndarray:
        return self._eval(t, 2)

    def describe(self) -> dict:
        return {"law": self.law, "f0_hz": self.f0, "f1_hz": self.f1,
                "constant": self.constant, "amplitude_m": self.amplitude,
                "peak_acceleration_m_s2": self.peak_acceleration,
                "taper_cycles": self.taper_cycles, "end_time_s": self.t_end}


#: samples per period of the noise's highest frequency on which its displacement is splined
NOISE_SAMPLES_PER_PERIOD = 32


class NoiseMotion(_GridBreakpoints, TableMotion):
    """Band-limited white noise (the case's ``loading: {type: noise}``): a table acceleration of
    RMS a_rms (m/s2) with a flat spectrum on [f_lo, f_hi] (Hz) and nothing outside, for T s,
    drawn from ``seed``; started and ended at rest.

    Synthesis (a random-phase multisine; Pintelon & Schoukens, System Identification: a
    frequency domain approach, 2nd ed. 2012, Section 2.2): lines f_j = j / T in [f_lo, f_hi]
    (N of them), each of the same amplitude c = a_rms sqrt(2 / N) and a phase phi_j drawn
    uniformly in [0, 2 pi) by numpy's default_rng(seed):

        a0(t) = sum_j c cos(2 pi f_j t + phi_j)         (RMS over the period T: a_rms exactly)
        u0(t) = -sum_j c / (2 pi f_j)^2 cos(2 pi f_j t + phi_j)   (its double integral: no
                                                         constant, no drift: bounded)

    computed with an inverse real FFT on a grid of ``NOISE_SAMPLES_PER_PERIOD`` samples per
    period of f_hi.  The table's displacement is u(t) = w(t) u0(t), w the quintic taper
    e(t / T_w) e((T - t) / T_w) over T_w = ``taper`` s at each end (the ramp's e(s): w, w', w''
    vanish at 0 and T), interpolated by a quintic spline (scipy make_interp_spline, k = 5)
    whose first and second derivatives are the velocity and acceleration: u, v, a continuous,
    zero at t = 0 and from T on (the table starts from rest and stops where it started).
    Between the tapers a = a0 up to the spline's error (~(2 pi / 32)^4 relative at f_hi:
    1e-3); in the tapers a = w a0 + 2 w' u0' + w'' u0, whose extra terms lie below f_lo
    (T_w >> 1 / f_lo keeps them small).
    """

    def __init__(self, rms: float, f_lo: float, f_hi: float, duration: float, seed: int = 0,
                 taper: float = 1.0):
        if not (0 < f_lo < f_hi):
            raise ValueError(f"need 0 < f_lo < f_hi, got {f_lo}, {f_hi}")
        if not (rms > 0 and duration > 0 and taper > 0):
            raise ValueError("rms, duration and taper must be > 0")
        if 2.0 * taper > duration:
            raise ValueError(f"two tapers of {taper:g} s exceed the duration {duration:g} s")
        from scipy.interpolate import make_interp_spline

        self.rms, self.f_lo, self.f_hi = float(rms), float(f_lo), float(f_hi)
        self.t_end, self.seed, self.taper = float(duration), int(seed), float(taper)
        T = self.t_end
        j = np.arange(int(math.ceil(self.f_lo * T - 1e-9)), int(math.floor(self.f_hi * T + 1e-9))
                      + 1)
        if len(j) == 0 or j[0] < 1:
            raise ValueError(f"no frequency line j / T in [{f_lo:g}, {f_hi:g}] Hz for "
                             f"T = {T:g} s")
        self.lines_hz = j / T
        self.phases = np.random.default_rng(self.seed).uniform(0.0, 2.0 * np.pi, len(j))
        self.line_amplitude = self.rms * math.sqrt(2.0 / len(j))        # c, m/s2
        n = int(2 ** math.ceil(math.log2(NOISE_SAMPLES_PER_PERIOD * self.f_hi * T)))
        spec = np.zeros(n // 2 + 1, dtype=complex)
        w = 2.0 * np.pi * self.lines_hz
        spec[j] = -self.line_amplitude / w**2 * np.exp(1j * self.phases) * (n / 2.0)
        t = np.arange(n + 1) * (T / n)
        u0 = np.fft.irfft(spec, n)
        u0 = np.append(u0, u0[0])
        env = _taper(t, self.taper, self.taper, T)[0]
        self._u = make_interp_spline(t, env * u0, k=5)
        self._v = self._u.derivative(1)
        self._a = self._u.derivative(2)
        self.f_max = self.f_hi
        self.period = None
        self.peak_acceleration = float(np.abs(self._a(t)).max())

    def untapered_acceleration(self, t) -> np.ndarray:
        """a0(t), m/s2: the multisine itself, summed line by line (a check of the synthesis)."""
        t = np.asarray(t, dtype=float)
        w = 2.0 * np.pi * self.lines_hz
        return self.line_amplitude * np.cos(np.multiply.outer(t, w) + self.phases).sum(axis=-1)

    def _eval(self, spline, t) -> np.ndarray:
        t = np.asarray(t, dtype=float)
        inside = (t > 0.0) & (t < self.t_end)
        return np.where(inside, spline(np.clip(t, 0.0, self.t_end)), 0.0)

    def displacement(self, t) -> np.ndarray:
        return self._eval(self._u, t)

    def velocity(self, t) -> np.ndarray:
        return self._eval(self._v, t)

    def acceleration(self, t) -> np.ndarray:
        return self._eval(self._a, t)

    def describe(self) -> dict:
        return {"rms_acceleration_m_s2": self.rms, "f_lo_hz": self.f_lo, "f_hi_hz": self.f_hi,
                "seed": self.seed, "taper_s": self.taper, "lines": int(len(self.lines_hz)),
                "peak_acceleration_m_s2": self.peak_acceleration, "end_time_s": self.t_end}
