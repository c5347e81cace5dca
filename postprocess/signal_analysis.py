"""Signal maths of the shake analysis (thesis Section 4.2.5): plain numpy / scipy on 1-D histories
sampled on a uniform time grid, knowing nothing of instruments, frames or run directories.

Units: those of the signal (m, m/s, m/s2; forces in N, energies in J); times in s, phases in
degrees, f = the excitation frequency (Hz).

Integration (:func:`drift_free_integral`; the thesis does not say how it removed the drift):
cumulative_trapezoid (scipy) once for velocity, twice for displacement; then
  1. the polynomial c_0 + ... + c_n t^n (n = 1 velocity, 2 displacement: the n unknown constants
     of integration, i.e. the initial velocity and position, plus a constant accelerometer bias)
     is removed, fitted by least squares JOINTLY with the first three harmonics of f over the
     shaking (t <= cycles / f) so that the fit does not absorb the oscillation;
  2. the centred running mean over exactly one excitation period is removed: the thesis' da
     "ignores the initial displacement in each rocking cycle".  This takes out sliding and other
     slow wander and leaves every component at f and its harmonics untouched (zero phase); it
     also removes about 64 % of a sub-harmonic at f/2.
Measured on a sine table acceleration sampled at 500 Hz: the recovered displacement and velocity
are within 2e-4 of their amplitudes everywhere (the trapezoid error, 2 (2 pi f dt)^2 / 12), for
4 to 50 cycles; a 3 mm slide during the shaking leaves 2 % of the amplitude in da after it.
The usual detrend + zero-phase Butterworth high-pass at f/4 (sosfiltfilt) was tried first and
rejected: its edge transients spoilt da by 10 - 100 % over the first and last ~8 cycles, and
a cosine-like velocity throughout.

Steady state (:func:`steady_window`; the thesis: amplitudes "when it has settled into a steady
state"): the record is cut into excitation cycles [k/f, (k+1)/f) while the table shakes
(t <= cycles / f).  Cycle 0 is always dropped (start-up: the response builds up from rest
relative to the table).  The reference is ds (per-cycle peak-to-peak pp_k); if ds stays below
1e-3 of the table's peak-to-peak (a block moving with the table), the absolute displacement
u + ds is used instead.  The steady state starts at the first cycle k >= 1 from which every pp_j
(j >= k) lies within +-``STEADY_TOL`` = 25 % of the median of those pp_j, keeping at least
min(3, n - 1) cycles; if no such cycle exists, the last half of the cycles is used (rule
"last-half").  The same window serves every quantity.

Amplification (:func:`amplification`; Section 4.2.5, exactly as defined there):

    A_q = (P - N) / (P_in - N_in)

P, N = positive and negative amplitudes of quantity q in the steady state = the means over the
steady cycles of the per-cycle maximum and minimum; P_in, N_in the same for the excitation OF THE
SAME KIND (which kind: postprocess.shake_signals.KIND_OF).  Per-cycle extrema come from the
samples: the sampling error of a peak is at most 1 - cos(pi f dt) (2e-4 at 500 Hz, 2 % at 50 Hz
and 3 Hz).  Also reported: the first-harmonic amplitude ratio (from the fit below).

Phase lag (:func:`phase_lag`; Tables 4.2, 4.3, Fig 4.32, 4.33): least-squares fit over the steady
window of y(t) = c0 + c1 t + R sin(2 pi f t + phi) (:func:`harmonic_fit`) to the response and to
the same-kind excitation (the linear term absorbs sliding drift); lag = phi_in - phi_out wrapped
to (-180, 180] degrees, positive when the response lags; lag time = lag / (360 f) s.  Note: the
thesis' tables give "Phase (deg)" = degrees(f * lag_time) (e.g. 2.0 Hz, 0.16 s -> 18.33 deg),
i.e. 1/(2 pi) of the phase angle 360 f t used here; compare lag TIMES, or multiply the printed
phases by 2 pi.

Spectrum (:func:`spectrum`, :func:`spectral_peaks`; Figs 4.15, 4.16, 4.26, 4.27): single-sided
amplitude spectrum (scipy.fft.rfft, Hann window normalised so that a sine of amplitude R shows R,
linear trend removed) over the steady window (a whole number of excitation cycles, so f falls on
a bin).  Peaks: local maxima (scipy.signal.find_peaks) above ``PEAK_REL`` = 10 % of the largest;
"single_peak" when there is one.

Hysteresis (:func:`loop_energy`; Figs 4.17, 4.18, 4.28, 4.29, 4.42): F = m_e a (eq 4-3) against
ds (the transducer) over the steady window.  In the table frame m_e a_abs = -(restoring +
dissipative forces), so the energy dissipated per cycle is E_loop = -closed integral of F d(ds)
(J, > 0 when the loop dissipates; pi c omega X^2 for a linear viscous oscillator).

Kinetic energy (:func:`kinetic_energy_eq44`): eq 4-4,
E = 1/2 m_e (2 pi f)^2 sum_i [y(t_i) + y(t_(i-1))][y(t_i) - y(t_(i-1))], evaluated literally as a
running sum on y = ds (relative, so it estimates the energy of the rocking relative to the
table).  The sum telescopes to 1/2 m_e (2 pi f)^2 (y(t)^2 - y(t_0)^2): it is the work of the
spring-like force m_e (2 pi f)^2 y, whose peak equals the peak kinetic energy of a mass m_e
moving as the facade centre.  The true kinetic energy of the blocks, to compare it with:
postprocess.block_kinematics.kinetic_energy_blocks.
"""

from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np
from scipy import fft as sfft
from scipy import signal
from scipy.integrate import cumulative_trapezoid
from scipy.stats import binned_statistic

HARMONICS = 3            # harmonics of f fitted with the integration constants
STEADY_TOL = 0.25        # steady state: per-cycle pp within +-25 % of their median
PEAK_REL = 0.10          # spectral peaks above 10 % of the largest
REL_FLOOR = 1e-3         # ds below 1e-3 of the table's pp: "moves with the table"


# ---------------------------------------------------------------------------------------------
# integration
# ---------------------------------------------------------------------------------------------
def period_mean(y: np.ndarray, t: np.ndarray, f: float) -> np.ndarray:
    """Centred running mean of y over exactly one period 1/f (from the cumulative trapezoid
    integral, interpolated, so 1/f need not be a whole number of samples); within half a period
    of either end the nearest full window is used.  It is zero for any component at f or its
    harmonics and follows constants, ramps and slow wander."""
    T = 1.0 / f
    if t[-1] - t[0] <= T:
        return np.full_like(y, np.mean(y))
    c = cumulative_trapezoid(y, t, initial=0.0)
    mid = np.clip(t, t[0] + T / 2, t[-1] - T / 2)
    return (np.interp(mid + T / 2, t, c) - np.interp(mid - T / 2, t, c)) / T


def drift_free_integral(a: np.ndarray, t: np.ndarray, f: float, t_end: float, n: int
                        ) -> np.ndarray:
    """n-fold integral (n = 1 velocity, 2 displacement) of an acceleration without drift
    (module docstring): cumulative_trapezoid n times; remove the polynomial c_0 + ... + c_n t^n
    fitted jointly with the first ``HARMONICS`` harmonics of f over the shaking (t <= t_end);
    remove the one-period running mean (:func:`period_mean`)."""
    y = np.asarray(a, float)
    for _ in range(n):
        y = cumulative_trapezoid(y, t, initial=0.0)
    m = t <= t_end + 1e-9
    if m.sum() > 2 * (n + 1 + 2 * HARMONICS):
        T = max(float(t[m][-1] - t[0]), 1e-12)
        x = (t - t[0]) / T
        w = 2.0 * np.pi * f
        poly = np.column_stack([x**k for k in range(n + 1)])
        harm = np.column_stack([g(h * w * t) for h in range(1, HARMONICS + 1)
                                for g in (np.cos, np.sin)])
        coef, *_ = np.linalg.lstsq(np.hstack([poly, harm])[m], y[m], rcond=None)
        y = y - poly @ coef[: n + 1]
    return y - period_mean(y, t, f)


# ---------------------------------------------------------------------------------------------
# cycles, steady state, amplification, phase, spectrum
# ---------------------------------------------------------------------------------------------
def n_complete_cycles(t: np.ndarray, f: float, t_end: float) -> int:
    """Complete excitation cycles [k/f, (k+1)/f) inside the record and the shaking."""
    half_step = 0.5 * float(np.median(np.diff(t))) if len(t) > 1 else 0.0
    return int(math.floor((min(t_end, float(t[-1]) + half_step)) * f + 1e-9))


def cycle_extrema(t: np.ndarray, y: np.ndarray, f: float, k0: int, k1: int):
    """Per-cycle (max, min) of y over cycles k0 .. k1-1 (scipy.stats.binned_statistic)."""
    edges = np.arange(k0, k1 + 1) / f
    mx = binned_statistic(t, y, statistic="max", bins=edges).statistic
    mn = binned_statistic(t, y, statistic="min", bins=edges).statistic
    return mx, mn


@dataclass
class SteadyWindow:
    first_cycle: int     # k0 (0-based)
    end_cycle: int       # k1 (exclusive)
    f: float
    rule: str
    reference: str

    @property
    def t0(self) -> float:
        return self.first_cycle / self.f

    @property
    def t1(self) -> float:
        return self.end_cycle / self.f

    @property
    def n_cycles(self) -> int:
        return self.end_cycle - self.first_cycle

    def mask(self, t: np.ndarray) -> np.ndarray:
        return (t >= self.t0 - 1e-12) & (t < self.t1 - 1e-12)

    def as_dict(self) -> dict:
        return {"t0_s": self.t0, "t1_s": self.t1, "first_cycle": self.first_cycle + 1,
                "last_cycle": self.end_cycle, "n_cycles": self.n_cycles, "rule": self.rule,
                "reference": self.reference}


def steady_window(t, ref, exc, f: float, t_end: float, tol: float = STEADY_TOL
                  ) -> SteadyWindow | None:
    """The steady-state window (rule in the module docstring), or None without two cycles.

    ref: the relative response (ds) [K]; exc: the table displacement [K] (m).
    """
    n = n_complete_cycles(t, f, t_end)
    if n < 2:
        return None
    emx, emn = cycle_extrema(t, exc, f, 0, n)
    rmx, rmn = cycle_extrema(t, ref, f, 0, n)
    pp, name = rmx - rmn, "ds"
    if np.nanmedian(pp[1:]) < REL_FLOOR * np.nanmedian(emx - emn):
        amx, amn = cycle_extrema(t, ref + exc, f, 0, n)
        pp, name = amx - amn, "ds + table displacement (ds below 1e-3 of the table's)"
    keep = min(3, n - 1)
    for k in range(1, n - keep + 1):
        tail = pp[k:]
        m = np.nanmedian(tail)
        if np.all(np.abs(tail - m) <= tol * m):
            return SteadyWindow(k, n, f, f"settled: per-cycle pp within {tol:.0%} of median", name)
    return SteadyWindow(max(1, n // 2), n, f, "last-half (no settled envelope)", name)


def amplification(t, resp, exc, window: SteadyWindow) -> dict:
    """A = (P - N) / (P_in - N_in) over the steady cycles (module docstring)."""
    k0, k1 = window.first_cycle, window.end_cycle
    rmx, rmn = cycle_extrema(t, resp, window.f, k0, k1)
    emx, emn = cycle_extrema(t, exc, window.f, k0, k1)
    P, N = float(np.nanmean(rmx)), float(np.nanmean(rmn))
    Pin, Nin = float(np.nanmean(emx)), float(np.nanmean(emn))
    ratio = (rmx - rmn) / (emx - emn)
    return {"amplification": (P - N) / (Pin - Nin) if Pin > Nin else math.nan,
            "positive_amplitude": P, "negative_amplitude": N,
            "excitation_positive": Pin, "excitation_negative": Nin,
            "per_cycle_std": float(np.nanstd(ratio))}


def harmonic_fit(t: np.ndarray, Y: np.ndarray, f: float) -> np.ndarray:
    """Least-squares y = c0 + c1 t + R sin(2 pi f t + phi) for each column of Y [K] or [K,M];
    returns the phasors R exp(i phi) (complex, [M] or scalar)."""
    w = 2.0 * np.pi * f
    tm = t - t.mean()
    A = np.column_stack([np.ones_like(t), tm, np.cos(w * t), np.sin(w * t)])
    coef, *_ = np.linalg.lstsq(A, np.asarray(Y, float), rcond=None)
    return coef[3] + 1j * coef[2]


def phase_lag(t, resp, exc, f: float, window: SteadyWindow) -> dict:
    """Lag of the response behind the same-kind excitation at f (fitted phase; docstring)."""
    m = window.mask(t)
    P = harmonic_fit(t[m], np.column_stack([resp[m], exc[m]]), f)
    if abs(P[1]) == 0 or abs(P[0]) < 1e-9 * abs(P[1]):
        return {"lag_deg": None, "lag_s": None, "h1_amplitude_ratio": 0.0,
                "note": "response too small for a phase"}
    lag = float(np.degrees(np.angle(P[1] * np.conj(P[0]))))
    if lag <= -180.0:
        lag += 360.0
    return {"lag_deg": lag, "lag_s": lag / (360.0 * f),
            "h1_amplitude_ratio": float(abs(P[0]) / abs(P[1]))}


def spectrum(t: np.ndarray, y: np.ndarray, window: SteadyWindow | None = None):
    """Single-sided amplitude spectrum (freqs Hz, amplitudes in y's unit) over the window."""
    if window is not None:
        m = window.mask(t)
        t, y = t[m], y[m]
    n = len(y)
    w = signal.get_window("hann", n)
    Y = sfft.rfft(signal.detrend(y) * w)
    amp = 2.0 * np.abs(Y) / w.sum()
    freqs = sfft.rfftfreq(n, float(np.median(np.diff(t))))
    return freqs, amp


def spectral_peaks(freqs, amp, rel: float = PEAK_REL, n_max: int = 5) -> dict:
    """Dominant frequency and the peaks above ``rel`` of the largest (DC bin excluded)."""
    a = amp.copy()
    a[0] = 0.0
    if a.max() <= 0:
        return {"dominant_frequency_hz": None, "peaks": [], "single_peak": False}
    idx, _ = signal.find_peaks(np.concatenate([[0.0], a, [0.0]]), height=rel * a.max())
    idx = idx - 1
    idx = idx[np.argsort(a[idx])[::-1]]
    return {"dominant_frequency_hz": float(freqs[int(np.argmax(a))]),
            "peaks": [[float(freqs[i]), float(a[i])] for i in idx[:n_max]],
            "n_peaks": int(len(idx)), "single_peak": bool(len(idx) == 1)}


# ---------------------------------------------------------------------------------------------
# hysteresis, energy
# ---------------------------------------------------------------------------------------------
def loop_energy(t, force, disp, f: float, window: SteadyWindow) -> np.ndarray:
    """Energy dissipated per steady cycle, E_k = -closed integral F dx over cycle k (J); the
    cycle ends k/f, (k+1)/f are interpolated so the loop closes between samples."""
    out = []
    for k in range(window.first_cycle, window.end_cycle):
        t0, t1 = k / f, (k + 1) / f
        inside = (t > t0) & (t < t1)
        tt = np.concatenate([[t0], t[inside], [t1]])
        F_ = np.interp(tt, t, force)
        x_ = np.interp(tt, t, disp)
        out.append(-np.trapezoid(F_, x_))
    return np.array(out)


def kinetic_energy_eq44(y: np.ndarray, f: float, m_e: float) -> np.ndarray:
    """Eq 4-4 as a running sum (J):
    E_n = 1/2 m_e (2 pi f)^2 sum_{i<=n} (y_i + y_(i-1)) (y_i - y_(i-1))."""
    terms = (y[1:] + y[:-1]) * (y[1:] - y[:-1])
    return 0.5 * m_e * (2 * np.pi * f) ** 2 * np.concatenate([[0.0], np.cumsum(terms)])


def cycle_peak_mean(t, y, f, win: SteadyWindow) -> float:
    """Mean over the steady cycles of the per-cycle maximum of y."""
    mx, _ = cycle_extrema(t, y, f, win.first_cycle, win.end_cycle)
    return float(np.nanmean(mx))
