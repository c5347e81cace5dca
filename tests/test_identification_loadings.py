"""The identification loadings against closed forms (dem.table_motion.SweepMotion, NoiseMotion),
the stepped shake's per-step levels (SteppedSineMotion ``levels``), and the errors that name a
bad field."""

from __future__ import annotations

import math

import numpy as np
import pytest
from scipy import signal

from dem.table_motion import NoiseMotion, SteppedSineMotion, SweepMotion


# --------------------------------------------------------------------------------------------
# sine sweep
# --------------------------------------------------------------------------------------------
def _crossing_times(t, u):
    """Times of the sign changes of u (linear interpolation between samples)."""
    i = np.flatnonzero(np.sign(u[:-1]) * np.sign(u[1:]) < 0)
    return t[i] - u[i] * (t[i + 1] - t[i]) / (u[i + 1] - u[i])


@pytest.mark.parametrize("law", ["linear", "log"])
def test_the_sweeps_zero_crossings_follow_its_instantaneous_frequency(law):
    """u = E U sin(phi) with E, U > 0 crosses zero exactly at phi = m pi, i.e. at
    linear: f0 t + k t^2 / 2 = m / 2  ->  t_m = (-f0 + sqrt(f0^2 + k m)) / k;
    log:   f0 T (r^(t/T) - 1) / ln r = m / 2  ->  t_m = T ln(1 + m ln r / (2 f0 T)) / ln r.
    Sampled at 20 kHz, the interpolated crossings lie within (w dt)^2 / 8-ish of a sample
    interval: 1e-6 s is ample."""
    f0, f1, T = 1.0, 8.0, 12.0
    sw = SweepMotion(f0, f1, T, law, peak_acceleration=0.5)
    t = np.arange(0.0, T, 5e-5)
    tc = _crossing_times(t, sw.displacement(t))
    m = np.arange(1, len(tc) + 1)
    if law == "linear":
        k = (f1 - f0) / T
        closed = (-f0 + np.sqrt(f0 * f0 + k * m)) / k
    else:
        r = f1 / f0
        closed = T * np.log(1 + m * math.log(r) / (2 * f0 * T)) / math.log(r)
    np.testing.assert_allclose(tc, closed, atol=1e-6)
    # the frequency reached: crossings m pi of phi(T) = 2 pi (f0 T + k T^2 / 2) (linear)
    n_total = (f0 + f1) * T if law == "linear" else 2 * f0 * T * (f1 / f0 - 1) / math.log(f1 / f0)
    assert len(tc) == math.floor(n_total - 1e-9)
    np.testing.assert_allclose(sw.frequency([0.0, T]), [f0, f1])


@pytest.mark.parametrize("law,level", [("linear", {"peak_acceleration": 0.5}),
                                       ("log", {"amplitude": 2e-3})])
def test_the_sweep_starts_and_ends_at_rest_with_a_continuous_velocity(law, level):
    """u, v, a are zero at t = 0 and from T on, and v, a are the derivatives of u, v (central
    differences at 20 kHz: error (w dt)^2 / 6 of the amplitude, < 1e-5 at 8 Hz)."""
    sw = SweepMotion(1.0, 8.0, 12.0, law, **level)
    t = np.arange(-0.5, 12.5, 5e-5)
    u, v, a = sw.displacement(t), sw.velocity(t), sw.acceleration(t)
    for q in (u, v, a):
        assert np.all(q[(t <= 0) | (t >= 12.0)] == 0.0)
    np.testing.assert_allclose(np.gradient(u, t), v, atol=1e-5 * np.abs(v).max())
    np.testing.assert_allclose(np.gradient(v, t), a, atol=1e-4 * np.abs(a).max())
    assert sw.acceleration_at(0.0) == 0.0 and sw.acceleration_at(12.0) == 0.0


def test_a_slow_constant_acceleration_sweep_peaks_at_its_level():
    """Away from the tapers the acceleration's local peaks are a_p up to the terms in U', U''
    and phi'' (SweepMotion's docstring), of relative size ~ 2 k / (2 pi f^2): 1e-3 for
    k = 0.1 Hz/s above 4 Hz; 1 % bounds it with the sampling (1 - cos(pi f dt) < 1e-6)."""
    a_p = 0.7
    sw = SweepMotion(4.0, 8.0, 40.0, "linear", peak_acceleration=a_p)
    t = np.arange(2.0, 38.0, 1e-4)
    a = np.abs(sw.acceleration(t))
    peaks, _ = signal.find_peaks(a)
    np.testing.assert_allclose(a[peaks], a_p, rtol=0.01)


# --------------------------------------------------------------------------------------------
# band-limited white noise
# --------------------------------------------------------------------------------------------
def test_the_noise_has_its_rms_and_band_and_is_bounded_from_rest_to_rest():
    """The multisine a0 has RMS c sqrt(N / 2) = a_rms over its period (exactly, on a grid
    finer than its Nyquist); between the tapers the table's acceleration (the spline's second
    derivative) is a0 within 1e-3 of a_rms (the quintic spline's error at 32 samples per
    period); outside the band the middle's spectrum holds < 1e-3 of the power (Welch, Hann);
    u, v, a are zero at 0 and from T on, v = u'; the same seed gives the same motion."""
    rms, lo, hi, T = 0.3, 2.0, 25.0, 20.0
    nz = NoiseMotion(rms, lo, hi, T, seed=7, taper=1.5)
    grid = np.arange(0.0, T, 1.0 / (4 * hi))
    assert np.sqrt(np.mean(nz.untapered_acceleration(grid) ** 2)) == pytest.approx(rms, rel=1e-9)
    t = np.arange(0.0, T, 1e-3)
    a = nz.acceleration(t)
    mid = (t > 1.5) & (t < T - 1.5)
    np.testing.assert_allclose(a[mid], nz.untapered_acceleration(t[mid]), atol=1e-3 * rms)
    f, p = signal.welch(a[mid], fs=1e3, nperseg=4096)
    out = (f < lo - 0.5) | (f > hi + 0.5)
    assert p[out].sum() < 1e-3 * p.sum()
    for q in (nz.displacement, nz.velocity, nz.acceleration):
        assert np.all(q(np.array([-1.0, 0.0, T, T + 1.0])) == 0.0)
    # v = u' (central differences at 10 kHz: error (w dt)^2 / 6 = 4e-5 at 25 Hz)
    tf = np.arange(0.0, T, 1e-4)
    np.testing.assert_allclose(np.gradient(nz.displacement(tf), tf), nz.velocity(tf),
                               atol=1e-4 * np.abs(nz.velocity(tf)).max())
    # bounded: the displacement is the double integral of lines >= f_lo, at most
    # sum c / (2 pi f_j)^2 (every line in phase)
    bound = nz.line_amplitude * np.sum(1.0 / (2 * np.pi * nz.lines_hz) ** 2)
    assert np.abs(nz.displacement(t)).max() <= bound
    again = NoiseMotion(rms, lo, hi, T, seed=7, taper=1.5)
    assert np.array_equal(again.acceleration(t), a)
    assert not np.array_equal(NoiseMotion(rms, lo, hi, T, seed=8, taper=1.5).acceleration(t), a)


# --------------------------------------------------------------------------------------------
# stepped levels
# --------------------------------------------------------------------------------------------
def test_a_kick_start_steps_its_level_with_a_continuous_velocity():
    """Two cycles at 2.3 m/s2, then the test level 1.53 m/s2, both at 2.8 Hz: u and v are
    continuous at the switch (v = 0 there: the step ends at a displacement extreme), a steps
    from -2.3 s to -1.53 s (s = +-1 the side), the offset keeps u continuous:
    c_1 = (A_0 - A_1) s_0; the peaks of each step are its level."""
    w = 2 * np.pi * 2.8
    m = SteppedSineMotion([(2.8, 2), (2.8, 6)], peak_acceleration=1.53,
                          levels=[("peak_acceleration", 2.3), None])
    t1 = m.t0[1]
    eps = 1e-9
    u, v = m.displacement([t1 - eps, t1 + eps]), m.velocity([t1 - eps, t1 + eps])
    a = m.acceleration([t1 - eps, t1 + eps])
    s = m.sign[0]
    assert abs(u[1] - u[0]) < 1e-9 and np.abs(v).max() < 1e-6
    np.testing.assert_allclose(a, [-2.3 * s, -1.53 * s], rtol=1e-6)
    assert m.offset[1] == pytest.approx((2.3 - 1.53) / w**2 * s)
    st = m.steps_run()
    assert [x["peak_acceleration_m_s2"] for x in st] == pytest.approx([2.3, 1.53])
    assert m.constant == "per_step" and m.describe()["constant"] == "per_step"
    t = np.linspace(0, m.t_end, 200001)
    assert np.abs(m.acceleration(t)).max() == pytest.approx(2.3, rel=1e-6)


def test_levels_equal_to_the_common_one_give_the_same_table_bit_for_bit():
    """A stepped shake whose steps repeat the common level runs the table of the one without
    levels, bit for bit (the old cases keep their motion; their case.json keeps its keys)."""
    from dem.case import FrequencyStep

    steps = [(1.8, 3), (2.4, 4.5), (3.6, 2)]
    old = SteppedSineMotion(steps, peak_acceleration=1.53)
    new = SteppedSineMotion(steps, peak_acceleration=1.53,
                            levels=[("peak_acceleration", 1.53)] * 3)
    t = np.linspace(-0.1, old.t_end + 0.1, 50001)
    for q in ("displacement", "velocity", "acceleration"):
        assert np.array_equal(getattr(old, q)(t), getattr(new, q)(t)), q
    assert FrequencyStep(frequency=2.0, cycles=3).model_dump() == {"frequency": 2.0,
                                                                  "cycles": 3.0}


def test_an_increasing_intensity_protocol_at_constant_amplitude_steps():
    """Amplitude continuation at one frequency: 2, 4, 6 mm at 3 Hz; with levels in amplitude
    the displacement peaks are the amplitudes (around each step's offset)."""
    m = SteppedSineMotion([(3.0, 2), (3.0, 2), (3.0, 2)],
                          levels=[("amplitude", 0.002), ("amplitude", 0.004),
                                  ("amplitude", 0.006)])
    np.testing.assert_allclose([s["amplitude_m"] for s in m.steps_run()], [0.002, 0.004, 0.006])
    t = np.linspace(0, m.t_end, 100001)
    v = m.velocity(t)
    assert np.abs(np.diff(v)).max() < 2 * np.abs(v).max() * 2 * np.pi * 3.0 * (t[1] - t[0])


# --------------------------------------------------------------------------------------------
# bad input
# --------------------------------------------------------------------------------------------
BLOCK = {"name": "b", "scene": {"blocks": [{"size": [0.1, 0.1, 0.2], "position": [0, 0, 0.1],
                                             "mass": 4.0}]},
         "material": {"friction": 0.8, "normal_stiffness": 1e7},
         "run": {"duration": 9.0, "output_interval": 0.005}}
SWEEP = {"type": "sweep", "direction": [1, 0, 0], "f0": 2.0, "f1": 12.0, "duration": 8.0,
         "peak_acceleration": 0.05}
NOISE = {"type": "noise", "direction": [1, 0, 0], "rms_acceleration": 0.05, "f_lo": 1.0,
         "f_hi": 20.0, "duration": 8.0}
STEPPED = {"type": "stepped_shake", "direction": [1, 0, 0], "peak_acceleration": 1.53,
           "steps": [{"frequency": 2.8, "cycles": 2, "peak_acceleration": 2.3},
                     {"frequency": 2.8, "cycles": 5}]}


@pytest.mark.parametrize("loading,change,message", [
    (SWEEP, {"f1": 2.0}, "loading: f1: 2 Hz must be above f0 = 2 Hz"),
    (SWEEP, {"rate": 1.0}, "duration / rate: give exactly one"),
    (SWEEP, {"peak_acceleration": -1.0}, "loading.peak_acceleration: Input should be "
                                          "greater than 0"),
    (SWEEP, {"direction": [1, 0, 1]}, "direction must be horizontal"),
    (SWEEP, {"f1": 150.0}, "loading.f1: 150 Hz is at or above the Nyquist frequency 100 Hz"),
    (NOISE, {"f_hi": 0.5}, "loading: f_hi: 0.5 Hz must be above f_lo = 1 Hz"),
    (NOISE, {"f_hi": 120.0}, "loading.f_hi: 120 Hz is at or above the Nyquist frequency 100 Hz"),
    (NOISE, {"rms_acceleration": -0.1}, "loading.rms_acceleration: Input should be greater"),
    (NOISE, {"f_lo": 0.05}, "f_lo: 0.05 Hz is below 1 / duration"),
    (NOISE, {"taper": 5.0}, "duration: 8 s must exceed the two tapers"),
    (STEPPED, {"steps": [{"frequency": 2.8, "cycles": 2, "peak_acceleration": -2.3}]},
     "loading.steps[0].peak_acceleration: Input should be greater than 0"),
    (STEPPED, {"steps": [{"frequency": 2.8, "cycles": 2, "peak_acceleration": 2.3,
                          "amplitude": 0.01}]}, "give at most one of amplitude"),
    (STEPPED, {"peak_acceleration": None}, "give exactly one of amplitude"),
])
def test_dem_check_names_a_bad_identification_field(tmp_path, loading, change, message):
    import yaml
    from typer.testing import CliRunner

    from dem_cli.app import app

    case = {**BLOCK, "loading": {**loading, **change}}
    case["loading"] = {k: v for k, v in case["loading"].items() if v is not None}
    path = tmp_path / "case.yaml"
    path.write_text(yaml.safe_dump(case))
    r = CliRunner().invoke(app, ["check", str(path)])
    assert r.exit_code == 2, r.output
    assert f"{path}:" in r.output and message in r.output, r.output


def test_a_stepped_shake_with_a_level_on_every_step_needs_no_common_one():
    from dem.case import parse_case

    case = parse_case({**BLOCK, "loading": {**STEPPED, "peak_acceleration": None,
                                            "steps": [{"frequency": 2.8, "cycles": 2,
                                                       "peak_acceleration": 2.3},
                                                      {"frequency": 2.8, "cycles": 5,
                                                       "peak_acceleration": 1.53}]}})
    st = case.loading.motion().steps_run()
    assert [s["peak_acceleration_m_s2"] for s in st] == pytest.approx([2.3, 1.53])


@pytest.mark.parametrize("law,rate,duration", [
    ("linear", 0.5, (12.0 - 2.0) / 0.5),               # Hz/s: T = (f1 - f0) / rate
    ("log", 6.0, 60.0 * math.log2(12.0 / 2.0) / 6.0),  # octaves/min: T = 60 log2(f1/f0) / rate
])
def test_a_sweep_rate_sets_its_duration(law, rate, duration):
    from dem.case import parse_case

    case = parse_case({**BLOCK, "loading": {**SWEEP, "duration": None, "rate": rate,
                                            "law": law}})
    assert case.loading.sweep_duration == pytest.approx(duration, rel=1e-12)
    assert case.loading.motion().t_end == pytest.approx(duration, rel=1e-12)
