"""Analysis of one shaking-table run (thesis Chapter 4: Sections 4.2.5 and 4.3).

Everything here is plain numpy / scipy on the recorded arrays; :func:`analyze_run` reads a run
directory (``case.json``, ``instruments.npz`` or ``frames.npz``) and writes ``analysis.json``, the
PNG plots and ``excited.vtu``.  Units: SI (m, s, m/s, m/s2, kg, J); phases in degrees.

Signals (Section 4.2.5), all projected on the instrument's measuring direction e (the excitation
axis; for the diagonal tests each axis is analysed on its own):

    u, u', u''  table displacement, velocity, acceleration (the input; absolute, lab frame)
    ds          transducer at the facade centre: displacement of the brick RELATIVE TO THE TABLE
                (the thesis' transducers are bolted to the table)
    dsr         ds(centre) - ds(corner): centre relative to the corner brick (corner "a", the
                brick that also carries the corner accelerometer, so dsr and dar compare)
    a, ar       accelerometer at the centre (ABSOLUTE acceleration) and a(centre) - a(corner)
    da, dar     a and ar integrated twice (ABSOLUTE displacement for da; dar is relative again)
    vs, vsr     d(ds)/dt and d(dsr)/dt (the thesis differentiates the transducer readings)
    va, var     a and ar integrated once (absolute / relative velocity)
    a_front, da_front   the front facade's centre accelerometer (L2 or T2; Tables 4.9 - 4.11)

Integration (da, va; the thesis does not say how it removed the drift): cumulative_trapezoid
(scipy) once for velocity, twice for displacement; then
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

Steady state (the thesis: amplitudes "when it has settled into a steady state"): the record is cut
into excitation cycles [k/f, (k+1)/f) while the table shakes (t <= cycles / f).  Cycle 0 is always
dropped (start-up: the response builds up from rest relative to the table).  The reference is
ds (per-cycle peak-to-peak pp_k); if ds stays below 1e-3 of the table's peak-to-peak (a block
moving with the table), the absolute displacement u + ds is used instead.  The steady state
starts at the first cycle k >= 1 from which every pp_j (j >= k) lies within +-``STEADY_TOL`` =
25 % of the median of those pp_j, keeping at least min(3, n - 1) cycles; if no such cycle exists,
the last half of the cycles is used (rule "last-half").  The same window serves every quantity.

Amplification (Section 4.2.5, exactly as defined there):

    A_q = (P - N) / (P_in - N_in)

P, N = positive and negative amplitudes of quantity q in the steady state = the means over the
steady cycles of the per-cycle maximum and minimum; P_in, N_in the same for the excitation OF THE
SAME KIND: table displacement for ds, dsr, da, dar; table velocity for vs, vsr, va, var; table
acceleration for a, ar.  ds, dsr, vs, vsr, ar, dar, var are relative (to the table or to the
corner); a, da, va are absolute.  A block bolted to the table therefore has A = 1 for a, da, va and
A = 0 for ds, vs (and for the relative quantities).  Per-cycle extrema come from the samples: the
sampling error of a peak is at most 1 - cos(pi f dt) (2e-4 at 500 Hz, 2 % at 50 Hz and 3 Hz).
Also reported: the first-harmonic amplitude ratio (from the fit below).

Phase lag (Tables 4.2, 4.3, Fig 4.32, 4.33): least-squares fit over the steady window of
y(t) = c0 + c1 t + R sin(2 pi f t + phi) to the response and to the same-kind excitation (the
linear term absorbs sliding drift); lag = phi_in - phi_out wrapped to (-180, 180] degrees,
positive when the response lags; lag time = lag / (360 f) s.  Note: the thesis' tables give
"Phase (deg)" = degrees(f * lag_time) (e.g. 2.0 Hz, 0.16 s -> 18.33 deg), i.e. 1/(2 pi) of the
phase angle 360 f t used here; compare lag TIMES, or multiply the printed phases by 2 pi.

Spectrum (Figs 4.15, 4.16, 4.26, 4.27): single-sided amplitude spectrum (scipy.fft.rfft, Hann
window normalised so that a sine of amplitude R shows R, linear trend removed) over the steady
window (a whole number of excitation cycles, so f falls on a bin).  Peaks: local maxima
(scipy.signal.find_peaks) above ``PEAK_REL`` = 10 % of the largest; "single_peak" when there is one.

Hysteresis (Figs 4.17, 4.18, 4.28, 4.29, 4.42): F = m_e a (eq 4-3; m_e = mass of the excited
portion's bricks, from :mod:`postprocess.excited`; a = centre accelerometer, absolute) against ds
(the transducer) over the steady window.  In the table frame m_e a_abs = -(restoring + dissipative
forces), so the energy dissipated per cycle is E_loop = -closed integral of F d(ds) (J, > 0 when
the loop dissipates; pi c omega X^2 for a linear viscous oscillator).

Kinetic energy: eq 4-4, E = 1/2 m_e (2 pi f)^2 sum_i [y(t_i) + y(t_(i-1))][y(t_i) - y(t_(i-1))],
evaluated literally as a running sum on y = ds (relative, so it estimates the energy of the rocking
relative to the table).  The sum telescopes to 1/2 m_e (2 pi f)^2 (y(t)^2 - y(t_0)^2): it is the
work of the spring-like force m_e (2 pi f)^2 y, whose peak equals the peak kinetic energy of a mass
m_e moving as the facade centre.  Next to it, the true kinetic energy of the excited bricks relative
to the table, sum 1/2 m |v|^2 + 1/2 w.I.w, from frames.npz (v recorded; w from successive
orientations).  For a rigid facade rocking about its base the true value is about a third of eq 4-4
(the bricks below the centre move less), plus the rotational part.

Unit drift (Section 4.2.5): amplification of dar / height of the facade (1/m).

Mechanism labels (Section 4.3, observations): see :func:`postprocess.excited.mechanism_labels`.
"""

from __future__ import annotations

from dem.output.atomic import savefig as _atomic_savefig

import json
import math
from dataclasses import dataclass, field
from pathlib import Path

import numpy as np
from scipy import fft as sfft
from scipy import signal
from scipy.integrate import cumulative_trapezoid
from scipy.spatial.transform import Rotation
from scipy.stats import binned_statistic

HARMONICS = 3            # harmonics of f fitted with the integration constants
STEADY_TOL = 0.25        # steady state: per-cycle pp within +-25 % of their median
PEAK_REL = 0.10          # spectral peaks above 10 % of the largest
REL_FLOOR = 1e-3         # ds below 1e-3 of the table's pp: "moves with the table"

KIND_OF = {  # quantity -> (kind of the excitation it is compared with, frame)
    "ds": ("displacement", "relative"), "dsr": ("displacement", "relative"),
    "da": ("displacement", "absolute"), "dar": ("displacement", "relative"),
    "vs": ("velocity", "relative"), "vsr": ("velocity", "relative"),
    "va": ("velocity", "absolute"), "var": ("velocity", "relative"),
    "a": ("acceleration", "absolute"), "ar": ("acceleration", "relative"),
    "a_front": ("acceleration", "absolute"), "da_front": ("displacement", "absolute"),
}


class ShakeAnalysisError(ValueError):
    """The run directory cannot be analysed; the message names the file or field."""


# ---------------------------------------------------------------------------------------------
# signals
# ---------------------------------------------------------------------------------------------
@dataclass
class ShakeSignals:
    """Histories of one measuring axis, on a uniform time grid ``t`` [K] (s).

    excitation: {"displacement": u [K] m, "velocity": u' [K] m/s, "acceleration": u'' [K] m/s2}
    ds_centre, ds_corner, ds_corner_b: transducer displacements relative to the table [K], m
    a_centre, a_corner, a_front: absolute accelerations [K], m/s2 (None where absent)
    """

    t: np.ndarray
    f: float
    t_end: float
    direction: np.ndarray
    axis: str
    excitation: dict
    ds_centre: np.ndarray
    ds_corner: np.ndarray | None = None
    ds_corner_b: np.ndarray | None = None
    a_centre: np.ndarray | None = None
    a_corner: np.ndarray | None = None
    a_front: np.ndarray | None = None
    source: str = ""
    blocks: dict = field(default_factory=dict)   # role -> block index
    facade: str | None = None                    # facade group name (box models)
    side_walls: tuple = ()
    front: str | None = None


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


def derived_quantities(sig: ShakeSignals) -> dict:
    """The thesis' quantities (module docstring) as arrays [K]; absent instruments are skipped."""
    t = sig.t

    def dint(acc, n):
        return drift_free_integral(acc, t, sig.f, sig.t_end, n)
    q: dict[str, np.ndarray] = {"ds": sig.ds_centre, "vs": np.gradient(sig.ds_centre, t)}
    if sig.ds_corner is not None:
        q["dsr"] = sig.ds_centre - sig.ds_corner
        q["vsr"] = np.gradient(q["dsr"], t)
    if sig.a_centre is not None:
        q["a"] = sig.a_centre
        q["va"] = dint(sig.a_centre, 1)
        q["da"] = dint(sig.a_centre, 2)
        if sig.a_corner is not None:
            q["ar"] = sig.a_centre - sig.a_corner
            q["var"] = dint(q["ar"], 1)
            q["dar"] = dint(q["ar"], 2)
    if sig.a_front is not None:
        q["a_front"] = sig.a_front
        q["da_front"] = dint(sig.a_front, 2)
    return q


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


def angular_velocity(t: np.ndarray, quat: np.ndarray) -> np.ndarray:
    """omega [T,n,3] (rad/s, table frame) from orientations quat [T,n,4] (w,x,y,z): rotation
    vector of R(t_(k+1)) R(t_(k-1))^-1 over t_(k+1) - t_(k-1) (one-sided at the ends)."""
    T, n = quat.shape[:2]
    R = Rotation.from_quat(np.concatenate([quat[..., 1:], quat[..., :1]], axis=-1).reshape(-1, 4))
    lo = np.clip(np.arange(T) - 1, 0, T - 1)
    hi = np.clip(np.arange(T) + 1, 0, T - 1)
    idx = np.arange(T * n).reshape(T, n)
    dR = R[idx[hi].ravel()] * R[idx[lo].ravel()].inv()
    dt = (t[hi] - t[lo])[:, None, None]
    return dR.as_rotvec().reshape(T, n, 3) / np.where(dt > 0, dt, np.inf)


def kinetic_energy_blocks(t, vel, quat, scene, blocks) -> np.ndarray:
    """True kinetic energy (J) of ``blocks`` relative to the table: translation + rotation."""
    blocks = np.asarray(blocks, dtype=int)
    if blocks.size == 0:
        return np.zeros(len(t))
    v = vel[:, blocks]
    m = scene.mass[blocks]
    e_t = 0.5 * np.einsum("n,tni->t", m, v * v)
    w = angular_velocity(t, quat[:, blocks])
    q = quat[:, blocks]
    R = Rotation.from_quat(np.concatenate([q[..., 1:], q[..., :1]], axis=-1).reshape(-1, 4))
    w_body = R.inv().apply(w.reshape(-1, 3)).reshape(w.shape)
    inertia = scene.inertia()[blocks]
    e_r = 0.5 * np.einsum("ni,tni->t", inertia, w_body * w_body)
    return e_t + e_r


# ---------------------------------------------------------------------------------------------
# reading a run directory
# ---------------------------------------------------------------------------------------------
def load_run(run_dir: Path):
    """(case, scene) of a run directory from its case.json."""
    from dem.case import Case
    from dem.scene import scene_from_case

    path = Path(run_dir) / "case.json"
    if not path.is_file():
        raise ShakeAnalysisError(f"{path}: missing (the run directory must hold case.json)")
    try:
        case = Case.model_validate_json(path.read_text())
    except Exception as err:  # noqa: BLE001 - report which file
        raise ShakeAnalysisError(f"{path}: not a valid case: {err}") from None
    return case, scene_from_case(case, check=False)


def _uniform(t, arrays):
    """Resample arrays (first axis = time) linearly onto a uniform grid if t is not uniform
    (frames are taken at the first step past each output time: jitter of one time step)."""
    dt = np.diff(t)
    if len(dt) and np.allclose(dt, np.median(dt), rtol=1e-3, atol=0):
        return t, arrays
    n = int(round((t[-1] - t[0]) / float(np.median(dt)))) + 1
    tu = np.linspace(t[0], t[-1], n)  # keeps both ends of the record
    out = []
    for a in arrays:
        if a is None:
            out.append(None)
            continue
        flat = a.reshape(len(t), -1)
        res = np.column_stack([np.interp(tu, t, flat[:, j]) for j in range(flat.shape[1])])
        out.append(res.reshape((len(tu),) + a.shape[1:]))
    return tu, out


def _axes_of(direction) -> list[str]:
    d = np.abs(np.asarray(direction, float))
    if d[0] > 1e-9 and d[1] > 1e-9:
        return ["y", "x"]
    return ["x"] if d[0] > d[1] else ["y"]


def signals_from_instruments(npz, case) -> list[ShakeSignals]:
    """Signals per axis from ``instruments.npz`` (layout in :mod:`dem.instruments`)."""
    ld = case.loading
    t = np.asarray(npz["t"], float)
    names = [str(n) for n in npz["names"]]
    groups = [str(g) for g in npz["group"]]
    out = []
    for axis in _axes_of(ld.direction):
        prefix = f"{axis}-" if any(n.startswith(f"{axis}-") for n in names) else ""

        def idx(nm):
            full = prefix + nm
            return names.index(full) if full in names else None

        i_c = idx("ds-centre")
        if i_c is None:
            raise ShakeAnalysisError(f"instruments.npz: no '{prefix}ds-centre' among {names}")
        e = np.asarray(npz["direction"][i_c], float)
        proj = lambda arr, i: None if i is None else np.asarray(arr)[:, i, :] @ e  # noqa: E731
        tu, (disp, acc, tdisp, tacc) = _uniform(t, [np.asarray(npz["disp"]), np.asarray(npz["acc"]),
                                                    np.asarray(npz["table_disp"]),
                                                    np.asarray(npz["table_acc"])])
        u = tdisp @ e
        exc = {"displacement": u, "velocity": np.gradient(u, tu), "acceleration": tacc @ e}
        i_ca, i_cb = idx("ds-corner-a"), idx("ds-corner-b")
        i_a, i_ac, i_af = idx("a-centre"), idx("a-corner"), idx("a-front-centre")
        blocks = {r: int(npz["block"][i]) for r, i in (("centre", i_c), ("corner_a", i_ca),
                                                        ("corner_b", i_cb), ("front", i_af))
                  if i is not None}
        facade = groups[i_c]
        out.append(ShakeSignals(
            t=tu, f=ld.frequency, t_end=ld.cycles / ld.frequency, direction=e, axis=axis,
            excitation=exc, ds_centre=proj(disp, i_c), ds_corner=proj(disp, i_ca),
            ds_corner_b=proj(disp, i_cb), a_centre=proj(acc, i_a), a_corner=proj(acc, i_ac),
            a_front=proj(acc, i_af), source="instruments.npz", blocks=blocks, facade=facade,
            side_walls=_side_walls(facade),
            front=groups[i_af] if i_af is not None else None))
    return out


def _side_walls(facade: str) -> tuple:
    return ("T1", "T2") if facade in ("L1", "L2") else ("L1", "L2")


def point_histories(pos, quat, blocks, points) -> np.ndarray:
    """Positions [T,n,3] of body-frame ``points`` [n,3] of ``blocks`` over the frames."""
    q = quat[:, blocks]
    R = Rotation.from_quat(np.concatenate([q[..., 1:], q[..., :1]], axis=-1).reshape(-1, 4))
    T, n = q.shape[:2]
    r = R.apply(np.tile(np.asarray(points, float), (T, 1))).reshape(T, n, 3)
    return pos[:, blocks] + r


def signals_from_frames(frames, case, scene) -> list[ShakeSignals]:
    """Signals per axis from ``frames.npz`` when a run has no instruments.npz.

    Box models: the Fig 4.4 instruments (dem.instruments.thesis_instruments) read from the block
    poses.  Other scenes: the centre of the top block (highest top face; nearest the plan centre
    on ties); no corner, so no relative quantities.  Accelerations: the point's relative velocity
    np.gradient(x_rel) plus the exact table velocity, differentiated again with np.gradient; the
    excitation's acceleration is differentiated from the table velocity on the same samples, so a
    block moving with the table reads exactly the table.
    """
    from dem.instruments import thesis_instruments
    from dem.loading import loading_from_case

    loading = loading_from_case(case)
    t0 = np.asarray(frames["t"], float)
    t, (pos, quat) = _uniform(t0, [np.asarray(frames["pos"]), np.asarray(frames["quat"])])
    quat = quat / np.linalg.norm(quat, axis=-1, keepdims=True)
    table_disp = loading.base_disp(t)
    table_vel = loading.base_vel(t)
    ld = case.loading
    boxy = {"L1", "L2", "T1", "T2"} <= set(scene.group_names)
    out = []
    for axis in _axes_of(ld.direction):
        if boxy:
            inst = {i.name: i for i in thesis_instruments(scene, axis)}
            e = inst["ds-centre"].direction
            roles = {"centre": inst["ds-centre"], "corner_a": inst["ds-corner-a"],
                     "corner_b": inst["ds-corner-b"], "front": inst["a-front-centre"]}
            blocks = {r: i.block for r, i in roles.items()}
            pts = np.array([roles[r].point for r in roles])
            facade = scene.group_names[scene.group[blocks["centre"]]]
            front = scene.group_names[scene.group[blocks["front"]]]
        else:
            d = np.asarray(ld.direction, float)
            e = np.eye(3)[{"x": 0, "y": 1}[axis]] if len(_axes_of(d)) > 1 else d / np.linalg.norm(d)
            free = np.flatnonzero(~scene.fixed)
            top = scene.position[free, 2] + 0.5 * scene.size[free, 2]
            cand = free[top >= top.max() - 1e-6]
            c = cand[np.argmin(np.linalg.norm(scene.position[cand, :2], axis=1))]
            blocks, pts, facade, front = {"centre": int(c)}, np.zeros((1, 3)), None, None
        x = point_histories(pos, quat, list(blocks.values()), pts)
        rel = (x - x[:1]) @ e                       # [T, n] relative to the table
        u = table_disp @ e
        uv = table_vel @ e
        v_abs = np.gradient(rel, t, axis=0) + uv[:, None]
        a_abs = np.gradient(v_abs, t, axis=0)
        exc = {"displacement": u, "velocity": np.gradient(u, t),
               "acceleration": np.gradient(uv, t)}
        col = {r: k for k, r in enumerate(blocks)}
        get = lambda arr, r: arr[:, col[r]] if r in col else None  # noqa: E731
        out.append(ShakeSignals(
            t=t, f=ld.frequency, t_end=ld.cycles / ld.frequency, direction=np.asarray(e, float),
            axis=axis, excitation=exc, ds_centre=get(rel, "centre"),
            ds_corner=get(rel, "corner_a"), ds_corner_b=get(rel, "corner_b"),
            a_centre=get(a_abs, "centre"), a_corner=get(a_abs, "corner_a"),
            a_front=get(a_abs, "front"), source="frames.npz", blocks=blocks, facade=facade,
            side_walls=_side_walls(facade) if facade else (), front=front))
    return out


# ---------------------------------------------------------------------------------------------
# one axis
# ---------------------------------------------------------------------------------------------
def analyze_signals(sig: ShakeSignals, m_e: float | None = None) -> tuple[dict, dict]:
    """Amplification, lag and spectrum of every quantity of one axis.

    Returns (result dict for analysis.json, arrays for plots: {"q": quantities, "window": ...}).
    """
    q = derived_quantities(sig)
    win = steady_window(sig.t, sig.ds_centre, sig.excitation["displacement"], sig.f, sig.t_end)
    res: dict = {"axis": sig.axis, "direction": sig.direction.tolist(), "source": sig.source,
                 "facade": sig.facade, "side_walls": list(sig.side_walls), "front": sig.front,
                 "instrument_blocks": sig.blocks}
    if win is None:
        n = n_complete_cycles(sig.t, sig.f, sig.t_end)
        res["steady_state"] = None
        res["error"] = (f"only {n} complete excitation cycle(s) of {1 / sig.f:.3f} s in the record "
                        f"(t <= {min(sig.t[-1], sig.t_end):.3f} s); need 2 (cycle 1 is dropped)")
        res["quantities"], res["amplification"], res["lag"] = {}, {}, {}
        return res, {"q": q, "window": None}
    res["steady_state"] = win.as_dict()
    quantities, amp, lag = {}, {}, {}
    for name, y in q.items():
        kind, frame = KIND_OF[name]
        exc = sig.excitation[kind]
        a = amplification(sig.t, y, exc, win)
        p = phase_lag(sig.t, y, exc, sig.f, win)
        s = spectral_peaks(*spectrum(sig.t, y, win))
        quantities[name] = {"kind": kind, "frame": frame, **a, **p, **s}
        amp[name] = a["amplification"]
        lag[name] = {"s": p["lag_s"], "deg": p["lag_deg"]}
    res["quantities"], res["amplification"], res["lag"] = quantities, amp, lag
    return res, {"q": q, "window": win}


# ---------------------------------------------------------------------------------------------
# plots
# ---------------------------------------------------------------------------------------------
def _plt():
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    return plt


def plot_time_histories(path, sig: ShakeSignals, q: dict, win: SteadyWindow | None, title=""):
    """Absolute quantities (left, with the table's input) and relative ones (right)."""
    plt = _plt()
    fig, axs = plt.subplots(3, 2, figsize=(13, 8), sharex=True)
    t = sig.t
    rows = [("displacement (mm)", 1e3, "displacement", ["da", "da_front"], ["ds", "dsr", "dar"]),
            ("velocity (mm/s)", 1e3, "velocity", ["va"], ["vs", "vsr", "var"]),
            ("acceleration (m/s2)", 1.0, "acceleration", ["a", "a_front"], ["ar"])]
    for (label, s, kind, absolute, relative), (ax_a, ax_r) in zip(rows, axs):
        ax_a.plot(t, s * sig.excitation[kind], color="0.6", lw=1.2, label="table (input)")
        for ax, names in ((ax_a, absolute), (ax_r, relative)):
            for nm in names:
                if nm in q:
                    ax.plot(t, s * q[nm], lw=0.8, label=nm)
            if win is not None:
                ax.axvspan(win.t0, win.t1, color="tab:green", alpha=0.08)
            if ax.lines:
                ax.legend(loc="upper right", fontsize=7, ncol=4)
            ax.grid(alpha=0.3)
        ax_a.set_ylabel(label)
    axs[0, 0].set_title(f"{title}: absolute")
    axs[0, 1].set_title("relative (to the table / to the corner)")
    for ax in axs[-1]:
        ax.set_xlabel("t (s)   (green: steady-state window)")
    fig.tight_layout()
    _atomic_savefig(fig, path, dpi=110)
    plt.close(fig)


def plot_spectrum(path, sig: ShakeSignals, q: dict, win: SteadyWindow, title=""):
    plt = _plt()
    names = [n for n in ("ds", "dsr", "da", "a") if n in q]
    fig, axs = plt.subplots(len(names), 1, figsize=(8, 2.2 * len(names)), squeeze=False)
    for ax, nm in zip(axs[:, 0], names):
        fr, amp = spectrum(sig.t, q[nm], win)
        ax.plot(fr, amp, lw=1.0)
        pk = spectral_peaks(fr, amp)
        for f0, a0 in pk["peaks"]:
            ax.plot([f0], [a0], "rv")
        ax.axvline(sig.f, color="0.5", ls="--", lw=0.8)
        ax.set_xlim(0, max(10.0, 4 * sig.f))
        ax.set_ylabel(f"|{nm}|")
        ax.grid(alpha=0.3)
    axs[-1, 0].set_xlabel("frequency (Hz)   (dashed: excitation)")
    axs[0, 0].set_title(title)
    fig.tight_layout()
    _atomic_savefig(fig, path, dpi=110)
    plt.close(fig)


def plot_hysteresis(path, t, disp, force, win: SteadyWindow, title=""):
    plt = _plt()
    m = win.mask(t)
    fig, ax = plt.subplots(figsize=(6, 5))
    ax.plot(1e3 * disp[m], force[m], lw=0.7)
    ax.set_xlabel("ds (mm, relative to the table)")
    ax.set_ylabel("F = m_e a (N)")
    ax.set_title(title)
    ax.grid(alpha=0.3)
    fig.tight_layout()
    _atomic_savefig(fig, path, dpi=110)
    plt.close(fig)


def plot_energy(path, t, e44, t_blocks, e_blocks, win, title=""):
    plt = _plt()
    fig, ax = plt.subplots(figsize=(9, 4))
    ax.plot(t, e44, lw=0.8, label="eq 4-4 from ds")
    if e_blocks is not None:
        ax.plot(t_blocks, e_blocks, lw=0.8, label="blocks: sum 1/2 m v^2 + 1/2 w.I.w")
    if win is not None:
        ax.axvspan(win.t0, win.t1, color="tab:green", alpha=0.08)
    ax.set_xlabel("t (s)")
    ax.set_ylabel("kinetic energy (J)")
    ax.set_title(title)
    ax.legend()
    ax.grid(alpha=0.3)
    fig.tight_layout()
    _atomic_savefig(fig, path, dpi=110)
    plt.close(fig)


# ---------------------------------------------------------------------------------------------
# the run directory
# ---------------------------------------------------------------------------------------------
def _cycle_peak_mean(t, y, f, win: SteadyWindow) -> float:
    mx, _ = cycle_extrema(t, y, f, win.first_cycle, win.end_cycle)
    return float(np.nanmean(mx))


def _facade_height(scene, sig: ShakeSignals) -> float:
    if sig.facade is not None and sig.facade in scene.group_names:
        m = scene.group == scene.group_names.index(sig.facade)
    else:
        m = np.zeros(scene.n_blocks, bool)
        m[sig.blocks["centre"]] = True
    return float((scene.position[m, 2] + 0.5 * scene.size[m, 2]).max())


def analyze_run(run_dir, plots: bool = True, write: bool = True) -> dict:
    """Analyse a shaking run directory; writes analysis.json, PNGs and excited.vtu into it.

    Raises ShakeAnalysisError (naming the file) when the directory cannot be analysed.
    """
    from dem.case import ShakeLoading
    from postprocess import excited as ex

    run_dir = Path(run_dir)
    case, scene = load_run(run_dir)
    if not isinstance(case.loading, ShakeLoading):
        raise ShakeAnalysisError(f"{run_dir / 'case.json'}: loading.type is "
                                 f"'{case.loading.type}', not 'shake'")
    frames = None
    if (run_dir / "frames.npz").is_file():
        frames = dict(np.load(run_dir / "frames.npz"))
    if (run_dir / "instruments.npz").is_file():
        sigs = signals_from_instruments(np.load(run_dir / "instruments.npz"), case)
    elif frames is not None:
        sigs = signals_from_frames(frames, case, scene)
    else:
        raise ShakeAnalysisError(f"{run_dir}: neither instruments.npz nor frames.npz")
    if len(sigs[0].t) < 4:
        raise ShakeAnalysisError(f"{run_dir}: only {len(sigs[0].t)} samples recorded")
    ld = case.loading
    summary_path = run_dir / "summary.json"
    status = json.loads(summary_path.read_text()).get("status") if summary_path.is_file() else None
    out: dict = {
        "kind": "shake", "case": case.name, "run_status": status,
        "excitation": {"frequency_hz": ld.frequency, "amplitude_m": ld.displacement_amplitude,
                       "peak_acceleration_m_s2": ld.displacement_amplitude
                       * (2 * np.pi * ld.frequency) ** 2,
                       "direction": list(ld.direction), "cycles": ld.cycles,
                       "t_end_s": ld.cycles / ld.frequency},
        "definitions": {
            "amplification": "(P - N) / (P_in - N_in): means of per-cycle max/min over the steady "
                             "cycles, input of the same kind (table displacement / velocity / "
                             "acceleration); ds, dsr, vs, vsr, ar, dar, var relative; a, da, va "
                             "absolute",
            "lag": "fitted phase at f (c0 + c1 t + R sin(2 pi f t + phi)) over the steady window; "
                   "lag_deg = phi_in - phi_out, lag_s = lag_deg / (360 f)",
            "da": "cumulative trapezoid twice; polynomial c0 + c1 t + c2 t^2 removed (fitted "
                  "jointly with 3 harmonics of f over the shaking); one-period running mean "
                  "removed",
            "steady_state": f"cycle 1 dropped; from the first cycle after which per-cycle "
                            f"peak-to-peak of ds stays within {STEADY_TOL:.0%} of its median, else "
                            f"the last half of the cycles",
        },
        "axes": {}, "plots": [], "warnings": [],
    }
    suffix = (lambda a: "") if len(sigs) == 1 else (lambda a: f"_{a}")
    for sig in sigs:
        res, arr = analyze_signals(sig)
        win, q = arr["window"], arr["q"]
        # a steady response needs the facade standing: a centre that moved by more than the
        # brick's own thickness along e has tipped past a rigid block's overturning point
        ref = sig.blocks["centre"]
        thick = float(np.abs(scene.rotation_matrices()[ref].T @ sig.direction) @ scene.size[ref])
        shaking = sig.t <= sig.t_end + 1e-9
        moved = float(np.abs(sig.ds_centre[shaking]).max())
        res["max_abs_ds_m"], res["collapse_suspected"] = moved, bool(moved > thick)
        if moved > thick:
            out["warnings"].append(
                f"{sig.axis}: the centre moved {moved * 1e3:.1f} mm relative to the table, more "
                f"than its thickness {thick * 1e3:.0f} mm: collapse, not a steady response")
        sfx = suffix(sig.axis)
        ttl = f"{case.name}: {sig.axis}, {ld.frequency:g} Hz"
        # excited portion (needs block poses)
        portion = None
        if frames is not None and win is not None:
            try:
                portion = ex.excited_portion(scene, frames, sig.f, win.t0, win.t1, sig.direction,
                                             ref_block=sig.blocks["centre"], facade=sig.facade,
                                             side_walls=sig.side_walls)
            except Exception as err:  # noqa: BLE001 - the rest of the analysis still lands
                out["warnings"].append(f"{sig.axis}: excited portion failed: {err}")
        if portion is not None:
            res["excited_portion"] = portion.summary()
            m_e, m_src = portion.mass, "bricks of the excited portion"
            if not portion.excited.any():
                m_e, m_src = float(scene.mass[sig.blocks["centre"]]), \
                    "reference block (no excited portion found)"
        else:
            m_e, m_src = float(scene.mass[sig.blocks["centre"]]), "reference block (no frames)"
        res["m_e_kg"], res["m_e_source"] = m_e, m_src
        if win is not None:
            A = res["amplification"]
            H = _facade_height(scene, sig)
            res["facade_height_m"] = H
            res["unit_drift_per_m"] = A["dar"] / H if "dar" in A else None
            if "a" in q:
                F = m_e * q["a"]
                E = loop_energy(sig.t, F, q["ds"], sig.f, win)
                res["hysteresis"] = {"m_e_kg": m_e, "loop_energy_J_mean": float(np.mean(E)),
                                     "loop_energy_J_per_cycle": E.tolist()}
            e44 = kinetic_energy_eq44(q["ds"], sig.f, m_e)
            ke = {"eq_4_4_peak_J": _cycle_peak_mean(sig.t, e44, sig.f, win),
                  "definition": "means over the steady cycles of the per-cycle maximum"}
            e_bl = t_bl = None
            if portion is not None and portion.excited.any() and "vel" in frames:
                t_bl = np.asarray(frames["t"], float)
                e_bl = kinetic_energy_blocks(t_bl, frames["vel"], frames["quat"], scene,
                                             np.flatnonzero(portion.excited))
                ke["blocks_peak_J"] = _cycle_peak_mean(t_bl, e_bl, sig.f, win)
                ke["ratio_eq44_over_blocks"] = (ke["eq_4_4_peak_J"] / ke["blocks_peak_J"]
                                                if ke["blocks_peak_J"] > 0 else None)
            res["kinetic_energy"] = ke
            if portion is not None:
                twist = None
                if frames is not None and "corner_a" in sig.blocks:
                    twist = ex.corner_twist(frames, scene, [sig.blocks["corner_a"],
                                                            sig.blocks.get("corner_b")],
                                            sig.f, win.t0, win.t1)
                res["mechanism"] = ex.mechanism_labels(res["quantities"], q, sig, win, portion,
                                                       twist)
            if plots and write:
                plot_time_histories(run_dir / f"time_histories{sfx}.png", sig, q, win, ttl)
                plot_spectrum(run_dir / f"spectrum{sfx}.png", sig, q, win, ttl)
                out["plots"] += [f"time_histories{sfx}.png", f"spectrum{sfx}.png"]
                if "a" in q:
                    plot_hysteresis(run_dir / f"hysteresis{sfx}.png", sig.t, q["ds"],
                                    m_e * q["a"], win, f"{ttl}, m_e = {m_e:.2f} kg")
                    out["plots"].append(f"hysteresis{sfx}.png")
                plot_energy(run_dir / f"energy{sfx}.png", sig.t, e44, t_bl, e_bl, win, ttl)
                out["plots"].append(f"energy{sfx}.png")
        elif plots and write:
            plot_time_histories(run_dir / f"time_histories{sfx}.png", sig, q, None, ttl)
            out["plots"].append(f"time_histories{sfx}.png")
        if portion is not None and write:
            if plots:
                ex.plot_elevation(run_dir / f"excited{sfx}.png", scene, portion, ttl)
                out["plots"].append(f"excited{sfx}.png")
            ex.write_vtu(run_dir / f"excited{sfx}.vtu", scene, portion)
            out.setdefault("vtk", []).append(f"excited{sfx}.vtu")
        out["axes"][sig.axis] = res
    primary = out["axes"][sigs[0].axis]
    out["primary_axis"] = sigs[0].axis
    for key in ("amplification", "lag", "steady_state", "unit_drift_per_m", "mechanism", "error"):
        if key in primary:
            out[key] = primary[key]
    if write:
        _write_json(run_dir / "analysis.json", out)
    return out


def _write_json(path: Path, data: dict) -> None:
    """analysis.json: strict JSON (NaN / inf as null), written atomically."""
    from dem.output.atomic import write_json

    write_json(path, data, indent=1, strict=True)
