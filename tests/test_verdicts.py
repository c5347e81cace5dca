"""postprocess/verdicts.py against closed forms and independent computations.
The study-level uses (the prediction's criteria and rocking check on hand-made sweeps) are in
tests/test_prediction_study.py."""

from __future__ import annotations

import math

import numpy as np
import pytest

from postprocess import verdicts as vd


@pytest.mark.parametrize("a1, lag_cycles", [(0.5, 0.0), (1.56, 0.41), (2.0, 0.5), (0.3, 0.25)])
def test_da_expected_is_the_peak_to_peak_of_table_plus_ds(a1, lag_cycles):
    """da_expected: |1 + A1 exp(-i 2 pi f lag)| is the amplification of u + ds for a table
    motion u = sin(2 pi f t) and ds = A1 sin(2 pi f (t - lag)); here measured on sampled
    signals (peak-to-peak over whole cycles), not from the phasor.  The sampling error of a
    peak on 20 000 samples a cycle is below 1e-7 of the amplitude (cos(pi / 20 000) - 1)."""
    f = 2.8
    lag = lag_cycles / f
    t = np.linspace(0.0, 5.0 / f, 100_001)
    u = np.sin(2 * np.pi * f * t)
    total = u + a1 * np.sin(2 * np.pi * f * (t - lag))
    measured = np.ptp(total) / np.ptp(u)
    row = {"frequency_hz": f, "h1_ds": a1, "lag_s": {"ds": lag}}
    assert vd.da_expected(row) == pytest.approx(measured, abs=1e-6)


def test_is_rocking_names_each_failed_condition():
    """A consistent row rocks; each of the three conditions, broken alone, fails it with its
    own reason (the thresholds are the module's)."""
    f, a1, lag = 2.8, 1.5, 0.05
    da = abs(1 + a1 * complex(math.cos(2 * math.pi * f * lag), -math.sin(2 * math.pi * f * lag)))
    row = {"frequency_hz": f, "dominant_frequency_hz": f, "h1_ds": a1, "lag_s": {"ds": lag},
           "amplification": {"ds": 2.0, "da": da, "dsr": 1.0}}
    assert vd.is_rocking(row) == {"rocking": True, "why": "rocking"}
    slow = dict(row, dominant_frequency_hz=f * (1 + 2 * vd.DOMINANT_REL_TOL))
    assert "dominant frequency" in vd.is_rocking(slow)["why"]
    drift = dict(row, h1_ds=0.9 * vd.H1_SHARE_MIN * 2.0)
    assert "drift or ratchet" in vd.is_rocking(drift)["why"]
    deaf = dict(row, amplification={**row["amplification"], "da": da * (1.5 + vd.DA_REL_TOL)})
    assert "accelerometer" in vd.is_rocking(deaf)["why"]
    slide = dict(row, amplification={**row["amplification"], "dsr": 0.5 * vd.DSR_SHARE_MIN * 2})
    assert "rigid slide" in vd.is_rocking(slide)["why"]
    assert vd.is_rocking({"frequency_hz": f, "amplification": {}})["rocking"] is None


def _transmissibility(f, fn, zeta):
    """|relative displacement / base displacement| of a linear oscillator under base motion:
    r^2 / sqrt((1 - r^2)^2 + (2 zeta r)^2), r = f / fn; its peak is at r = 1 / sqrt(1 - 2 zeta^2)."""
    r = np.asarray(f) / fn
    return r ** 2 / np.sqrt((1 - r ** 2) ** 2 + (2 * zeta * r) ** 2)


def test_characteristic_frequency_of_a_linear_oscillator_and_its_edge_rules():
    fn, zeta, step = 3.0, 0.1, 0.1
    peak = fn / math.sqrt(1 - 2 * zeta ** 2)              # the closed-form peak, Hz
    freqs = [round(1.5 + step * k, 10) for k in range(31)]   # 1.5 .. 4.5 Hz
    curve = dict(zip(freqs, _transmissibility(freqs, fn, zeta)))
    got = vd.characteristic(freqs, curve)
    assert abs(got["characteristic_frequency_hz"] - peak) <= step / 2 + 1e-12
    lo, hi = got["effective_range_hz"]
    assert lo <= got["characteristic_frequency_hz"] <= hi
    # a sweep that stops below the resonance rises to its top: no characteristic frequency
    below = [f for f in freqs if f < 2.5]
    edge = vd.characteristic(below, {f: curve[f] for f in below})
    assert edge["characteristic_frequency_hz"] is None and edge["peak_at_edge"]
    assert "highest" in edge["characteristic_frequency_note"]
    # the same curve with the frequencies above still to run is pending, not an edge
    pending = vd.characteristic(freqs, {f: curve[f] for f in below}, unrun=freqs[len(below):])
    assert pending["characteristic_frequency_note"].startswith("pending")
    assert not pending.get("peak_at_edge")


def test_band_text_and_band_verdict():
    st = {"n": 10, "median": 2.0, "q10": 1.5, "q90": 2.5}
    assert vd.band_text(st) == "2 (1.5 - 2.5)"
    assert vd.band_text({"n": 0}) == "-" and vd.fmt(float("nan")) == "-"
    assert vd.band_verdict(st, 2.2, tol_abs=0.3)["status"] == "pass"
    # a close median from a band that misses the reference fails
    narrow = {"n": 10, "median": 2.0, "q10": 1.95, "q90": 2.05}
    v = vd.band_verdict(narrow, 2.2, tol_abs=0.3)
    assert v["status"] == "fail" and v["by_median"] and not v["in_band"]
