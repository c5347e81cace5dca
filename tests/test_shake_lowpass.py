"""The assumed accelerometer low-pass of the shake analysis (postprocess.shake_signals.lowpass,
``a_lp``, ``a_front_lp``, ``a_lowpass_sensitivity``): on analytic signals it
keeps the excitation's harmonic within its passband error and removes impact spikes and tones
above the cutoff, and the unfiltered ``a`` is what it was."""

from __future__ import annotations

import numpy as np
import pytest

from postprocess import shake as sh
from postprocess import signal_analysis as sa
from postprocess import shake_signals as ss

F, A, DT = 2.8, 0.005, 0.002   # Hz, m, s (the instruments' 500 Hz)


def _gain(f, fc=ss.LOWPASS_HZ, order=ss.LOWPASS_ORDER):
    """|H(f)|^2 of a Butterworth run forward and backward."""
    return 1.0 / (1.0 + (f / fc) ** (2 * order))


def _h1(t, y, f):
    """First-harmonic amplitude at f over the middle of the record (away from the filter's
    edge transients)."""
    m = (t > 2 / f) & (t < t[-1] - 2 / f)
    return abs(sa.harmonic_fit(t[m], y[m], f))


def _doublets(t, f, height):
    """Impact spikes: two per excitation cycle, each +height then -height on the next sample
    (a bounce: a zero-area pulse, no net velocity change), at 0.3 / f and 0.8 / f."""
    y = np.zeros_like(t)
    for t0 in np.concatenate([np.arange(0.3, t[-1] * f, 1.0), np.arange(0.8, t[-1] * f, 1.0)]) / f:
        k = int(np.searchsorted(t, t0))
        if k + 1 < len(t):
            y[k], y[k + 1] = height, -height
    return y


def test_lowpass_keeps_the_harmonic_at_f_and_removes_spikes_and_tones_above_the_cutoff():
    t = np.arange(0, 20 / F, DT)
    w = 2 * np.pi * F
    sine = -A * w**2 * np.sin(w * t)                 # table-like acceleration, 1.55 m/s2
    P = A * w**2
    # 1. the harmonic at f keeps |H(f)|^2 = 1 - 1e-6 of its amplitude (passband error); the
    #    fit of 52 000 samples at f is exact to round-off
    assert _h1(t, ss.lowpass(sine, t), F) == pytest.approx(P * _gain(F), rel=1e-6)
    # 2. at the cutoff: -6 dB (|H|^2 = 1/2); at 100 Hz the analog 1 / (1 + 5^8) = 2.6e-6 (the
    #    digital filter's bilinear warp makes it 8.4e-7): a unit tone is gone
    tone = np.sin(2 * np.pi * ss.LOWPASS_HZ * t)
    assert _h1(t, ss.lowpass(tone, t), ss.LOWPASS_HZ) == pytest.approx(0.5, rel=1e-3)
    mid = (t > 2 / F) & (t < t[-1] - 2 / F)
    assert np.abs(ss.lowpass(np.sin(2 * np.pi * 100.0 * t), t)[mid]).max() < _gain(100.0)
    # 3. impact spikes 10 x the table's peak: the raw peak-to-peak is the spikes', the filtered
    #    one the sine's within 3 % (a doublet keeps 2 pi f dt of its height at f; its harmonics
    #    2f .. 6f below the cutoff pass: 2 x 5.6 x 0.002 x 0.07 x 10 P = 0.016 P each)
    spikes = _doublets(t, F, 10 * P)
    lp = ss.lowpass(sine + spikes, t)
    assert np.ptp((sine + spikes)[mid]) > 10 * P
    assert np.ptp(lp[mid]) == pytest.approx(2 * P, rel=0.03)
    assert np.abs(ss.lowpass(spikes, t)[mid]).max() < 0.03 * 10 * P
    # linear and zero phase: the filtered sine lags the sine by nothing
    res = sa.harmonic_fit(t[mid], np.column_stack([lp, sine])[mid], F)
    assert abs(np.angle(res[0] / res[1])) < 1e-3


def test_lowpass_refuses_a_cutoff_the_sampling_cannot_resolve():
    t = np.arange(0, 1.0, 0.02)   # 50 Hz: Nyquist 25 Hz
    with pytest.raises(ValueError, match="cutoff_hz = 30"):
        ss.lowpass(np.zeros_like(t), t, 30.0)
    assert ss.lowpass_resolved(t, 20.0) and not ss.lowpass_resolved(t, 23.0)
    with pytest.raises(ValueError, match="too short"):
        ss.lowpass(np.zeros(10), np.arange(10) * DT)


def _sig(t, a_centre, a_front=None):
    u = A * np.sin(2 * np.pi * F * t)
    exc = {"displacement": u, "velocity": np.gradient(u, t),
           "acceleration": -A * (2 * np.pi * F) ** 2 * np.sin(2 * np.pi * F * t)}
    ds = 1.5 * A * np.sin(2 * np.pi * F * t - 0.5)
    return ss.ShakeSignals(t=t, f=F, t_end=t[-1] + 1e-9, direction=np.array([0, 1.0, 0]),
                           axis="y", excitation=exc, ds_centre=ds, a_centre=a_centre,
                           a_front=a_front, blocks={"centre": 0})


def test_the_unfiltered_a_is_unchanged_and_the_cutoff_sensitivity_is_reported():
    """a keeps the accelerometer's samples and its amplification; a_lp, a_front_lp are the
    low-passed ones (acceleration, absolute); a_lowpass_sensitivity gives a raw and at each
    cutoff.  A 60 Hz ringing of half the table's peak: 10 and 20 Hz remove it (|H|^2 <= 1.5e-4),
    50 Hz keeps 19 % of it, raw all of it."""
    t = np.arange(0, 20 / F, DT)
    w = 2 * np.pi * F
    clean = -w**2 * (A * np.sin(w * t) + 1.5 * A * np.sin(w * t - 0.5))
    ring = 0.5 * A * w**2 * np.sin(2 * np.pi * 60.0 * t)
    sig = _sig(t, clean + ring, a_front=0.4 * clean)
    q = ss.derived_quantities(sig)
    assert q["a"] is sig.a_centre and q["a_front"] is sig.a_front     # the very samples
    assert np.array_equal(q["a_lp"], ss.lowpass(sig.a_centre, t))
    assert ss.KIND_OF["a_lp"] == ss.KIND_OF["a_front_lp"] == ("acceleration", "absolute")
    res, arr = sh.analyze_signals(sig)
    win = arr["window"]
    raw = sa.amplification(t, clean + ring, sig.excitation["acceleration"], win)["amplification"]
    assert res["amplification"]["a"] == raw                          # as before the low-pass
    sens = res["a_lowpass_sensitivity"]["amplification"]
    assert sens["raw"] == raw and set(sens) == {"raw", "10", "20", "50"}
    exact = abs(1 + 1.5 * np.exp(-0.5j))                              # the clean response
    assert sens["20"] == pytest.approx(exact, rel=2e-3) == res["amplification"]["a_lp"]
    assert sens["10"] == pytest.approx(exact, rel=2e-3)
    assert raw > sens["50"] > sens["20"] + 0.05
    assert res["amplification"]["a_front_lp"] == pytest.approx(0.4 * exact, rel=2e-3)
    assert res["quantities"]["a_lp"]["lag_s"] == pytest.approx(res["quantities"]["a"]["lag_s"],
                                                               abs=1e-3)
    # a record too coarse for the cutoff: no a_lp, the sensitivity says None (not a number)
    tc = np.arange(0, 20 / F, 0.05)
    sc = _sig(tc, -w**2 * A * np.sin(w * tc))
    assert "a_lp" not in ss.derived_quantities(sc)
    res_c, _ = sh.analyze_signals(sc)
    assert res_c["a_lowpass_sensitivity"]["amplification"]["20"] is None
    assert res_c["a_lowpass_sensitivity"]["amplification"]["raw"] == res_c["amplification"]["a"]
