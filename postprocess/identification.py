"""A model's own frequency response from a sweep or a band-limited noise run: each instrument's
transfer function over the table's acceleration, its coherence, and the first mode's frequency
and damping ratio (what a shaking-table laboratory measures between tests).

Units: SI; frequencies in Hz, omega = 2 pi f in rad/s; the damping ratio zeta is a fraction of
critical.  Pure functions on 1-D histories sampled on a uniform grid (the signals of
postprocess.shake_signals), then :func:`analyze_identification_run` for a run directory.

Transfer functions (x = the table's acceleration a_g, m/s2; y = a response):

* H1 (Bendat & Piersol, Random Data, 4th ed. 2010, Section 9.1): H1(f) = G_xy(f) / G_xx(f),
  the cross- over the auto-spectral density (scipy.signal.csd / welch, Hann segments of
  ``nperseg`` samples, half overlapping), with the coherence
  gamma^2(f) = |G_xy|^2 / (G_xx G_yy) in [0, 1] (1: y is a linear response to x; less: noise,
  a nonlinearity or leakage).  Its frequency resolution is fs / nperseg.
* Ratio of spectra: H(f) = Y(f) / X(f), the discrete Fourier transforms of the whole record
  (rectangular window).  Exact for a linear system when the input and the response are at
  rest at both ends of the record (the Fourier transform of a finite-support signal), which a
  sweep or a noise tapered to rest and followed by the response's decay are: no leakage, a
  resolution 1 / T_record.  Used where |X| is at least ``INPUT_FLOOR`` of its largest value
  (the excited band).  The headline identification uses it where it can.

  H1's coherence presumes a stationary input: under a sweep a Welch segment sees the resonance
  pass as a transient, and the coherence dips there whatever the system (a linear one too);
  read it under noise.

Frames (the thesis' instruments, postprocess.shake_signals): ``ds`` (the transducer at the
facade centre, displacement RELATIVE TO THE TABLE, m), ``a`` (the accelerometer, ABSOLUTE,
m/s2), ``a_rel`` = a - a_g (relative to the table), and where there is a corner instrument
``dsr`` (centre relative to the corner) and the front facade's ``a_front`` / ``a_front_rel``.
Each transfer function is over a_g: ds / a_g in s^2 (a receptance), a / a_g and a_rel / a_g
dimensionless (the absolute one is the transmissibility: 1 for a body the table carries).

One degree of freedom (the first mode): its relative displacement x under the table's
acceleration, x'' + 2 zeta w_n x' + w_n^2 x = -Gamma a_g (Gamma the participation factor, 1
for a single mass), gives

    R(w) = X / A_g = -Gamma / (w_n^2 - w^2 + 2 i zeta w_n w)            (receptance, s^2)
    relative acceleration / a_g = -w^2 R,   absolute acceleration / a_g = 1 - w^2 R.

Every instrument's transfer function is turned into its receptance R (ds: itself; a_rel: -H /
w^2; a: (1 - H) / w^2) and identified in two ways, the method named in the output:

* ``half_power`` (Chopra, Dynamics of Structures, 4th ed. 2012, Section 3.2.6): the peak of |R|
  at f_p, the frequencies f_a < f_p < f_b where |R| = |R(f_p)| / sqrt(2) (linear
  interpolation), zeta = (f_b - f_a) / (2 f_p), f_n = f_p (the receptance peaks at
  f_n sqrt(1 - 2 zeta^2); the bandwidth rule is first order in zeta);
* ``sdof_fit``: least squares of R(w) = G / (w_n^2 - w^2 + 2 i zeta w_n w) with a complex G
  (Gamma, and a phase for the residual of other modes) over the points within
  ``FIT_HALF_WIDTHS`` half-power half-widths of the peak, each weighted by the coherence
  (H1) or by |X| (the ratio); G enters linearly and is solved for at each (f_n, zeta)
  (variable projection), f_n and zeta by scipy.optimize.least_squares from the half-power
  values, then refitted over three half-widths f_n zeta of that fit.  It uses the phase as
  well as the magnitude and reads between the frequency bins.

The first mode is taken at the largest |R| in the excited band (the lowest mode of a
rocking facade dominates its receptance); higher modes are not identified.

Tests: tests/test_identification.py (a one-degree-of-freedom system of known f_n and zeta
under white noise; a block on a penalty joint against its closed-form rocking-sliding
frequency; the amplitude dependence of a softening joint); docs/identification.md.
"""

from __future__ import annotations

import json
from pathlib import Path

import numpy as np
from scipy import optimize, signal

#: the ratio of spectra is used where |X(f)| >= this fraction of its largest value
INPUT_FLOOR = 0.05
#: the SDOF fit takes points within this many half-power half-widths of the peak
FIT_HALF_WIDTHS = 3.0
#: the H1 segment's default share of the record (Welch: 7 half-overlapping segments)
WELCH_SEGMENTS = 4


def h1_estimate(t, x, y, nperseg: int | None = None) -> dict:
    """H1 = G_xy / G_xx and the coherence gamma^2 (module docstring) of response y [K] over
    input x [K] on the uniform grid t [K] (s).  ``nperseg``: samples per Hann segment (default
    K / WELCH_SEGMENTS).  Returns {"f": Hz [M], "H": complex [M] (unit of y / unit of x),
    "coherence": [M], "resolution_hz"}."""
    t, x, y = (np.asarray(v, float) for v in (t, x, y))
    fs = 1.0 / float(np.median(np.diff(t)))
    n = int(nperseg or max(16, len(t) // WELCH_SEGMENTS))
    n = min(n, len(t))
    f, gxy = signal.csd(x, y, fs=fs, nperseg=n, window="hann", detrend="constant")
    _, gxx = signal.welch(x, fs=fs, nperseg=n, window="hann", detrend="constant")
    _, gyy = signal.welch(y, fs=fs, nperseg=n, window="hann", detrend="constant")
    with np.errstate(divide="ignore", invalid="ignore"):
        H = np.where(gxx > 0, gxy / gxx, np.nan)
        coh = np.where((gxx > 0) & (gyy > 0), np.abs(gxy) ** 2 / (gxx * gyy), 0.0)
    return {"f": f, "H": H, "coherence": np.clip(coh, 0.0, 1.0), "resolution_hz": fs / n}


def ratio_estimate(t, x, y) -> dict:
    """H = Y / X of the whole record (module docstring), where |X| >= INPUT_FLOOR max |X|.
    Returns {"f": Hz [M], "H": complex [M], "weight": |X| / max |X| [M], "resolution_hz"}."""
    t, x, y = (np.asarray(v, float) for v in (t, x, y))
    dt = float(np.median(np.diff(t)))
    X, Y = np.fft.rfft(x), np.fft.rfft(y)
    f = np.fft.rfftfreq(len(t), dt)
    w = np.abs(X) / max(float(np.abs(X).max()), 1e-300)
    keep = (w >= INPUT_FLOOR) & (f > 0)
    return {"f": f[keep], "H": Y[keep] / X[keep], "weight": w[keep],
            "resolution_hz": 1.0 / (len(t) * dt)}


def receptance(f, H, kind: str) -> np.ndarray:
    """The receptance R = relative displacement / a_g (s^2) of a transfer function H over the
    table's acceleration (module docstring): kind "relative_displacement" (R = H),
    "relative_acceleration" (R = -H / w^2) or "absolute_acceleration" (R = (1 - H) / w^2)."""
    f = np.asarray(f, float)
    w2 = np.where(f > 0, (2.0 * np.pi * f) ** 2, np.nan)   # no receptance at f = 0
    with np.errstate(invalid="ignore"):
        if kind == "relative_displacement":
            return np.asarray(H)
        if kind == "relative_acceleration":
            return -np.asarray(H) / w2
        if kind == "absolute_acceleration":
            return (1.0 - np.asarray(H)) / w2
    raise ValueError(f"kind: {kind!r} is not relative_displacement, relative_acceleration or "
                     f"absolute_acceleration")


def half_power(f, R, band: tuple[float, float] | None = None) -> dict | None:
    """f_n and zeta by the half-power bandwidth of |R| (module docstring) within ``band``
    (Hz); None when the peak has no half-power point on one side inside the data."""
    f, mag = np.asarray(f, float), np.abs(np.asarray(R))
    m = np.isfinite(mag) & (f > 0)
    if band is not None:
        m &= (f >= band[0]) & (f <= band[1])
    idx = np.flatnonzero(m)
    if len(idx) < 3:
        return None
    k = idx[np.argmax(mag[idx])]
    half = mag[k] / np.sqrt(2.0)
    lo = k
    while lo > idx[0] and mag[lo] > half:
        lo -= 1
    hi = k
    while hi < idx[-1] and mag[hi] > half:
        hi += 1
    if mag[lo] > half or mag[hi] > half or lo == k or hi == k:
        return None
    fa = np.interp(half, [mag[lo], mag[lo + 1]], [f[lo], f[lo + 1]])
    fb = np.interp(half, [mag[hi], mag[hi - 1]], [f[hi], f[hi - 1]])
    fp = float(f[k])
    return {"method": "half_power", "f_n_hz": fp, "zeta": float((fb - fa) / (2.0 * fp)),
            "f_a_hz": float(fa), "f_b_hz": float(fb), "peak": float(mag[k])}


def sdof_model(f, f_n: float, zeta: float) -> np.ndarray:
    """1 / (w_n^2 - w^2 + 2 i zeta w_n w) at f (Hz): the receptance of a unit participation
    with the sign left to G (module docstring)."""
    w, wn = 2.0 * np.pi * np.asarray(f, float), 2.0 * np.pi * f_n
    return 1.0 / (wn * wn - w * w + 2j * zeta * wn * w)


def fit_sdof(f, R, weight, start: dict) -> dict | None:
    """f_n, zeta and the complex G of R(w) = G / (w_n^2 - w^2 + 2 i zeta w_n w) by weighted
    least squares (module docstring) over the points within FIT_HALF_WIDTHS half-power
    half-widths of ``start`` (a :func:`half_power` result), then once more over the points
    within FIT_HALF_WIDTHS half-widths f_n zeta of the first fit (a half-power width read off
    one noisy peak bin can be far too narrow); None when fewer than 4 points."""
    f, R, wt = np.asarray(f, float), np.asarray(R), np.sqrt(np.asarray(weight, float))
    fn0, z0 = start["f_n_hz"], max(start["zeta"], 1e-3)
    hw = max(fn0 * z0, 0.5 * (start["f_b_hz"] - start["f_a_hz"]))
    first = _fit_window(f, R, wt, fn0, z0, hw)
    if first is None:
        return None
    again = _fit_window(f, R, wt, first["f_n_hz"], first["zeta"],
                        first["f_n_hz"] * first["zeta"])
    return again if again is not None else first


def _fit_window(f, R, wt, fn0: float, z0: float, hw: float) -> dict | None:
    """:func:`fit_sdof` over the points within FIT_HALF_WIDTHS x hw (Hz) of fn0."""
    m = (np.abs(f - fn0) <= FIT_HALF_WIDTHS * hw) & np.isfinite(R) & (wt > 0)
    if m.sum() < 4:
        return None
    f, R, wt = f[m], R[m], wt[m]

    def gain(p):
        b = sdof_model(f, *p) * wt
        return np.vdot(b, R * wt) / np.vdot(b, b)

    def resid(p):
        r = (gain(p) * sdof_model(f, *p) - R) * wt
        return np.concatenate([r.real, r.imag])

    sol = optimize.least_squares(resid, [fn0, z0], bounds=([0.5 * fn0, 1e-4], [2.0 * fn0, 0.9]),
                                 x_scale=[fn0 * z0, z0])
    fn, z = (float(v) for v in sol.x)
    G = complex(gain(sol.x))
    scale = float(np.sqrt(np.sum(np.abs(R * wt) ** 2)))
    return {"method": "sdof_fit", "f_n_hz": fn, "zeta": z, "gain_s2": [G.real, G.imag],
            "participation": float(-G.real), "points": int(m.sum()),
            "band_hz": [float(f.min()), float(f.max())],
            "relative_residual": float(np.linalg.norm(sol.fun) / scale) if scale > 0 else None}


def identify_mode(f, R, weight, band: tuple[float, float] | None = None) -> dict:
    """Both identifications of the first mode from the receptance R [M] at f [M] (Hz), weighted
    by ``weight`` [M] (coherence or |X|): {"half_power": ..., "sdof_fit": ...} (None where
    one cannot be made)."""
    hp = half_power(f, R, band)
    fit = fit_sdof(f, R, weight, hp) if hp is not None else None
    return {"half_power": hp, "sdof_fit": fit}


def transfer_functions(t, a_g, responses: dict, nperseg: int | None = None) -> dict:
    """Every response's transfer function over the table acceleration a_g [K] (m/s2) on the
    grid t [K] (s), both estimators, and its first mode.  ``responses``: {name: (y [K], kind)}
    with kind as :func:`receptance`.  Returns {name: {"kind", "h1": {...}, "ratio": {...},
    "mode": {"h1": identify_mode, "ratio": identify_mode}}} with numpy arrays."""
    out = {}
    for name, (y, kind) in responses.items():
        h1 = h1_estimate(t, a_g, y, nperseg)
        ra = ratio_estimate(t, a_g, y)
        R1, Rr = receptance(h1["f"], h1["H"], kind), receptance(ra["f"], ra["H"], kind)
        band = (float(ra["f"].min()), float(ra["f"].max())) if len(ra["f"]) else None
        out[name] = {"kind": kind, "h1": {**h1, "R": R1}, "ratio": {**ra, "R": Rr},
                     "mode": {"h1": identify_mode(h1["f"], R1, h1["coherence"], band),
                              "ratio": identify_mode(ra["f"], Rr, ra["weight"], band)}}
    return out


def best_mode(entry: dict) -> dict | None:
    """The headline identification of one response: the SDOF fit on the ratio of spectra where
    it exists (the finer resolution, no leakage), else on H1, else a half-power value."""
    for est in ("ratio", "h1"):
        fit = entry["mode"][est]["sdof_fit"]
        if fit is not None:
            return {**fit, "estimator": est}
    for est in ("ratio", "h1"):
        hp = entry["mode"][est]["half_power"]
        if hp is not None:
            return {**hp, "estimator": est}
    return None


# ---------------------------------------------------------------------------------------------
# a run directory
# ---------------------------------------------------------------------------------------------
#: the responses identified, from postprocess.shake_signals.ShakeSignals: name -> (what, kind)
RESPONSES = {
    "ds": ("transducer at the facade centre, relative to the table", "relative_displacement"),
    "dsr": ("ds relative to the corner (centre minus corner)", "relative_displacement"),
    "a": ("centre accelerometer, absolute", "absolute_acceleration"),
    "a_rel": ("centre accelerometer relative to the table (a - a_g)", "relative_acceleration"),
    "a_front": ("front facade's centre accelerometer, absolute", "absolute_acceleration"),
    "a_front_rel": ("front facade's centre accelerometer relative to the table",
                    "relative_acceleration"),
}


def signal_responses(sig) -> dict:
    """{name: (y [K], kind)} of one axis' signals (postprocess.shake_signals.ShakeSignals)."""
    a_g = sig.excitation["acceleration"]
    out = {"ds": (sig.ds_centre, RESPONSES["ds"][1])}
    if sig.ds_corner is not None:
        out["dsr"] = (sig.ds_centre - sig.ds_corner, RESPONSES["dsr"][1])
    for name, acc in (("a", sig.a_centre), ("a_front", sig.a_front)):
        if acc is not None:
            out[name] = (acc, RESPONSES[name][1])
            out[f"{name}_rel"] = (acc - a_g, RESPONSES[f"{name}_rel"][1])
    return out


def analyze_identification_run(run_dir, plots: bool = True, write: bool = True) -> dict:
    """Read a sweep or noise run directory (case.json, instruments.npz or frames.npz), identify
    every instrument of every axis, write identification.json and identification.png.
    ShakeAnalysisError naming the file when it cannot."""
    from dem.case import NoiseLoading, SweepLoading
    from dem.output.atomic import write_json
    from postprocess.shake_signals import ShakeAnalysisError, load_run, read_signals

    run_dir = Path(run_dir)
    case, scene = load_run(run_dir)
    ld = case.loading
    if not isinstance(ld, (SweepLoading, NoiseLoading)):
        raise ShakeAnalysisError(f"{run_dir / 'case.json'}: loading.type is '{ld.type}', not "
                                 f"'sweep' or 'noise'")
    sigs, _ = read_signals(run_dir, case, scene)
    motion = ld.motion()
    summary_path = run_dir / "summary.json"
    status = json.loads(summary_path.read_text()).get("status") if summary_path.is_file() \
        else None
    band = (ld.f0, ld.f1) if isinstance(ld, SweepLoading) else (ld.f_lo, ld.f_hi)
    out = {"kind": "identification", "case": case.name, "run_status": status,
           "excitation": {"type": ld.type, **motion.describe()}, "band_hz": list(band),
           "definitions": {
               "transfer_function": "response over the table acceleration a_g (instruments' "
                                    "table_acc or the frames' table): ds / a_g in s^2, "
                                    "accelerations / a_g dimensionless",
               "h1": "G_xy / G_xx (scipy.signal.csd, welch; Hann segments), coherence "
                     "|G_xy|^2 / (G_xx G_yy)",
               "ratio": "Y / X of the whole record (rectangular window), where |X| >= "
                        f"{INPUT_FLOOR} max |X|",
               "half_power": "f_n = peak of the receptance |R|, zeta = (f_b - f_a) / (2 f_n) "
                             "at |R| = peak / sqrt 2",
               "sdof_fit": "least squares of R = G / (w_n^2 - w^2 + 2 i zeta w_n w), G complex",
               "receptance": "R = ds / a_g; = -a_rel / (w^2 a_g); = (1 - a / a_g) / w^2",
               "responses": {k: v[0] for k, v in RESPONSES.items()}},
           "axes": {}, "plots": [], "warnings": []}
    t_rec = float(sigs[0].t[-1])
    if t_rec < motion.t_end:
        out["warnings"].append(f"the record ends at t = {t_rec:.3f} s, before the {ld.type}'s "
                               f"end {motion.t_end:.3f} s: the ratio of spectra assumes both "
                               f"ends at rest, and the band is not covered")
    curves = {}
    for sig in sigs:
        fs = 1.0 / float(np.median(np.diff(sig.t)))
        if band[1] >= 0.5 * fs:
            out["warnings"].append(f"{sig.axis}: the band's top {band[1]:g} Hz is at or above "
                                   f"the samples' Nyquist frequency {0.5 * fs:.4g} Hz")
        tf = transfer_functions(sig.t, sig.excitation["acceleration"], signal_responses(sig))
        curves[sig.axis] = tf
        axis = {"source": sig.source, "direction": sig.direction.tolist(),
                "sampling_hz": fs, "instruments": {}}
        for name, e in tf.items():
            axis["instruments"][name] = {
                "kind": e["kind"], "frame": "absolute" if e["kind"].startswith("absolute")
                else "relative",
                "h1_resolution_hz": e["h1"]["resolution_hz"],
                "ratio_resolution_hz": e["ratio"]["resolution_hz"],
                "mean_coherence_in_band": _mean_coherence(e["h1"], band),
                "mode": e["mode"],
                "first_mode": best_mode(e)}
        head = axis["instruments"]["ds"]["first_mode"]
        if head is None:
            edge = rising_to_band_edge(tf["ds"]["ratio"]["f"], tf["ds"]["ratio"]["R"], band)
            if edge:
                out["warnings"].append(f"{sig.axis}: {edge}")
        axis["f_n_hz"] = None if head is None else head["f_n_hz"]
        axis["zeta"] = None if head is None else head["zeta"]
        axis["method"] = None if head is None else f"{head['method']} ({head['estimator']}) of ds"
        out["axes"][sig.axis] = axis
    primary = sigs[0].axis
    out["primary_axis"] = primary
    for key in ("f_n_hz", "zeta", "method"):
        out[key] = out["axes"][primary][key]
    if write:
        if plots:
            plot_identification(run_dir / "identification.png", curves, band,
                                f"{case.name}: {ld.type} {band[0]:g}-{band[1]:g} Hz")
            out["plots"].append("identification.png")
        write_json(run_dir / "identification.json", out, indent=1, strict=True)
    return out


def rising_to_band_edge(f, R, band) -> str | None:
    """A sentence when |R| is largest at an end of the band (a mode outside it: above f_hi /
    f1 when at the top, below when at the bottom); None otherwise."""
    f, mag = np.asarray(f, float), np.abs(np.asarray(R))
    m = np.isfinite(mag) & (f >= band[0]) & (f <= band[1])
    if m.sum() < 3:
        return None
    fm, mm = f[m], mag[m]
    k = int(np.argmax(mm))
    if k >= len(fm) - 2:
        return (f"the receptance |ds / a_g| is largest at the band's top ({fm[k]:.3g} Hz): the "
                f"first mode lies above the band; raise its top frequency")
    if k <= 1:
        return (f"the receptance |ds / a_g| is largest at the band's bottom ({fm[k]:.3g} Hz): "
                f"a mode below the band; lower its bottom frequency")
    return None


def _mean_coherence(h1: dict, band) -> float | None:
    m = (h1["f"] >= band[0]) & (h1["f"] <= band[1])
    return float(np.mean(h1["coherence"][m])) if m.any() else None


def plot_identification(path, curves: dict, band, title: str = "") -> None:
    """identification.png: per axis, |H| of every instrument (H1 lines, the ratio of spectra as
    dots; relative frame left, absolute right), the coherence, and the fitted SDOF curve of ds
    with its f_n and zeta."""
    from dem.output.atomic import savefig
    from dem.output.plotting import agg_pyplot

    plt = agg_pyplot()
    n = len(curves)
    fig, axs = plt.subplots(3, n, figsize=(6.5 * n, 9), squeeze=False, sharex="col")
    for col, (axis, tf) in enumerate(curves.items()):
        ax_d, ax_a, ax_c = axs[0, col], axs[1, col], axs[2, col]
        for k, (name, e) in enumerate(tf.items()):
            ax = ax_d if e["kind"] == "relative_displacement" else ax_a
            h1, ra = e["h1"], e["ratio"]
            m = (h1["f"] >= band[0]) & (h1["f"] <= band[1])
            color = f"C{k % 10}"   # one colour per instrument on every panel
            ax.semilogy(h1["f"][m], np.abs(h1["H"][m]), color=color,
                        label=f"{name}: H1 (line), ratio of spectra (dots)")
            ax.semilogy(ra["f"], np.abs(ra["H"]), ".", ms=2, color=color, alpha=0.5)
            ax_c.plot(h1["f"][m], h1["coherence"][m], label=name, color=color)
        fit = best_mode(tf["ds"])
        if fit is not None and fit["method"] == "sdof_fit":
            f = np.linspace(band[0], band[1], 800)
            G = complex(*fit["gain_s2"])
            ax_d.semilogy(f, np.abs(G * sdof_model(f, fit["f_n_hz"], fit["zeta"])), "k--",
                          lw=1, label=f"SDOF fit: f_n {fit['f_n_hz']:.3g} Hz, zeta "
                                      f"{fit['zeta']:.3g}")
        ax_d.set_ylabel("|ds / a_g| (s^2), relative")
        ax_a.set_ylabel("|a / a_g| (-)")
        ax_c.set_ylabel("coherence of H1 (-)")
        ax_c.set_xlabel("frequency (Hz)")
        ax_c.set_ylim(0, 1.05)
        ax_d.set_title(f"axis {axis}")
        for ax in (ax_d, ax_a, ax_c):
            ax.grid(alpha=0.3)
            ax.legend(fontsize=7)
    fig.suptitle(title)
    fig.tight_layout()
    savefig(fig, path)
    plt.close(fig)


def identification_line(res: dict) -> str:
    """One line for the command line: the primary axis' f_n and zeta and the method."""
    if res.get("f_n_hz") is None:
        return "no mode identified (no resonance peak with half-power points in the band)"
    return (f"first mode f_n {res['f_n_hz']:.4g} Hz, zeta {res['zeta']:.3g} "
            f"({res['method']}, axis {res['primary_axis']})")
