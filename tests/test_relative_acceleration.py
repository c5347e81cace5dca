"""Accelerations relative to the table (postprocess.shake.relative_to_table; the thesis' a
and da almost certainly are these, docs/table_protocols.md).

Closed form: the table moves u = A sin(w t); a point on the back facade moves u + R sin(w t - phi)
(absolute), one on the front facade u + R_f sin(w t - phi_f).  Relative to the table their
accelerations are -w^2 R sin(w t - phi) and -w^2 R_f sin(w t - phi_f), so

    amplification(a_rel) = amplification(da_rel) = R / A,  lag(a_rel) = phi,
    front / back (relative) = R_f / R,
    amplification(a) (absolute) = |1 + (R / A) e^(-i phi)|   (the phasor sum),

and a body the table carries (R = 0) reads a_rel = 0.  Tolerances: per-cycle peaks of samples
2 ms apart at 2.4 Hz miss a sine's peak by 1 - cos(pi f dt) = 1.1e-4; the drift-free double
integral's error (test_shake_analysis: 1e-3); the low-pass passes 2.4 Hz within 1e-6.
"""

from __future__ import annotations

import numpy as np
import pytest

from postprocess import shake as sh
from postprocess.shake_signals import ShakeSignals
from postprocess.signal_analysis import steady_window

F, A = 2.4, 0.006          # Hz, m
W = 2 * np.pi * F


def _signals(R, phi, R_f, phi_f, n_cycles=30, dt=0.002):
    t = np.arange(0.0, n_cycles / F, dt)
    u = A * np.sin(W * t)
    back = R * np.sin(W * t - phi)
    front = R_f * np.sin(W * t - phi_f)
    exc = {"displacement": u, "velocity": A * W * np.cos(W * t), "acceleration": -W**2 * u}
    sig = ShakeSignals(t=t, f=F, t_end=n_cycles / F, direction=np.array([0, 1.0, 0]), axis="y",
                       excitation=exc, ds_centre=back, a_centre=-W**2 * (u + back),
                       a_front=-W**2 * (u + front), blocks={"centre": 0})
    win = steady_window(t, back, u, F, sig.t_end)
    return sig, win


def test_relative_accelerations_of_a_known_response():
    R, phi, R_f, phi_f = 1.8 * A, np.radians(60.0), 0.7 * A, np.radians(40.0)
    sig, win = _signals(R, phi, R_f, phi_f)
    out = sh.relative_to_table(sig, win)
    amp, q = out["amplification"], out["quantities"]
    for name in ("a_rel", "a_rel_lp"):
        assert amp[name] == pytest.approx(R / A, rel=1e-3), name
        assert q[name]["lag_deg"] == pytest.approx(60.0, abs=0.1), name
    assert amp["da_rel"] == pytest.approx(R / A, rel=2e-3)
    for name in ("a_front_rel", "a_front_rel_lp"):
        assert amp[name] == pytest.approx(R_f / A, rel=1e-3), name
    ratios = out["front_back_ratio"]
    assert ratios["a_front_rel/a_rel"] == pytest.approx(R_f / R, rel=2e-3)
    assert ratios["da_front_rel/da_rel"] == pytest.approx(R_f / R, rel=4e-3)
    # the absolute ones: the phasor sum, so their ratio is not R_f / R
    a_back = abs(1 + R / A * np.exp(-1j * phi))
    a_front = abs(1 + R_f / A * np.exp(-1j * phi_f))
    assert ratios["a_front/a (absolute)"] == pytest.approx(a_front / a_back, rel=2e-3)
    # and the absolute a beside them, from the ordinary analysis
    res, _ = sh.analyze_signals(sig)
    assert res["amplification"]["a"] == pytest.approx(a_back, rel=1e-3)


def test_a_body_the_table_carries_reads_zero_relative_acceleration():
    sig, win = _signals(0.0, 0.0, 0.0, 0.0)
    sig.ds_centre = np.zeros_like(sig.t)
    win = steady_window(sig.t, sig.ds_centre, sig.excitation["displacement"], F, sig.t_end)
    out = sh.relative_to_table(sig, win)
    for name, value in out["amplification"].items():
        assert value < 1e-9, name
    res, _ = sh.analyze_signals(sig)
    assert res["amplification"]["a"] == pytest.approx(1.0, rel=1e-3)   # absolute: the table's


def test_a_real_bolted_block_reads_zero_relative_and_one_absolute(tmp_path):
    """A squat block far below its thresholds (mu = 0.8, b/h = 2, 1.5 m/s2) shaken in the DEM:
    relative to the table its acceleration is the elastic give's (0.08 um), absolute the
    table's; analysis.json carries both."""
    import json

    from dem.case import parse_case
    from dem.run import run_case

    case = parse_case({
        "name": "bolted", "scene": {"blocks": [{"size": [0.2, 0.2, 0.1],
                                                "position": [0, 0, 0.05], "mass": 4.0}]},
        "material": {"friction": 0.8},
        "loading": {"type": "shake", "direction": [0, 1, 0], "frequency": 2.0,
                    "peak_acceleration": 1.5, "cycles": 4},
        "run": {"duration": 2.0, "output_interval": 0.005, "vtk": False, "snapshot": False}})
    run_case(case, tmp_path)
    res = sh.analyze_run(tmp_path, plots=False)
    rel = res["axes"]["y"]["relative_to_table"]["amplification"]
    assert rel["a_rel"] < 1e-3 and rel["da_rel"] < 1e-3 and rel["a_rel_lp"] < 1e-3
    assert res["amplification"]["a"] == pytest.approx(1.0, abs=5e-3)
    written = json.loads((tmp_path / "analysis.json").read_text())
    assert written["axes"]["y"]["relative_to_table"]["amplification"]["a_rel"] == \
        pytest.approx(rel["a_rel"])


def test_first_harmonic_estimate_from_an_absolute_entry_is_the_relative_amplitude():
    """analysis.json files written before the relative accelerations hold only the absolute a:
    its phasor against the
    table's acceleration is 1 + (R / A) e^(-i phi), so |phasor - 1| = R / A (the relative one,
    studies.diagnosis.relative_thesis)."""
    from studies.diagnosis.relative_thesis import first_harmonic_relative, relative_row

    R, phi, R_f, phi_f = 1.8 * A, np.radians(60.0), 0.7 * A, np.radians(40.0)
    sig, win = _signals(R, phi, R_f, phi_f)
    res, _ = sh.analyze_signals(sig)
    assert first_harmonic_relative(res["quantities"]["a"]) == pytest.approx(R / A, rel=1e-6)
    assert first_harmonic_relative(res["quantities"]["a_front"]) == pytest.approx(R_f / A,
                                                                                   rel=1e-6)
    row = relative_row({"primary_axis": "y", "axes": {"y": res}})
    assert row["source"] == "first-harmonic estimate"
    assert row["front_back"] == pytest.approx(R_f / R, rel=1e-6)
    # with the recorded relative quantities the row reads them
    res["relative_to_table"] = sh.relative_to_table(sig, win)
    row = relative_row({"primary_axis": "y", "axes": {"y": res}})
    assert row["source"] == "relative_to_table"
    assert row["a_rel"] == pytest.approx(R / A, rel=1e-3)
