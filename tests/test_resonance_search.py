"""studies/resonance/study.py: the base-excited linear oscillator against its closed-form
limits, the fit recovering a known natural frequency, and the report on hand-made records."""

from __future__ import annotations

import json

import numpy as np
import pytest

from studies.prediction import plan as pl
from studies.prediction import points as pred_points
from studies.resonance import study as rs
from tests.test_prediction_study import frozen_repo


def test_base_transfer_limits():
    # quasi-static (r << 1): |z| / Y -> r^2 (the mass follows the base, z = -m a / k)
    assert rs.base_transfer(1.0, 10.0) == pytest.approx(0.01 / 0.99)
    # at resonance the damping alone bounds it: 1 / (2 zeta)
    assert rs.base_transfer(5.0, 5.0, zeta=0.05) == pytest.approx(10.0)
    # far above (r >> 1) the mass stands still: |z| -> Y
    assert rs.base_transfer(1000.0, 1.0, zeta=0.1) == pytest.approx(1.0, rel=1e-5)


def test_fit_recovers_the_natural_frequency_of_a_noisy_curve():
    f = np.array([1.8, 1.9, 2.0, 2.1, 2.2, 2.4, 2.5, 2.8, 3.2, 3.6])
    rng = np.random.default_rng(3)
    noise = 1.0 + 0.05 * rng.uniform(-1, 1, len(f))
    fit = rs.fit_natural_frequency(f, rs.base_transfer(f, 7.0) * noise)
    # 5 % amplitude noise: f_n = f sqrt(1 / (1 + 1/A)) moves by < 2.5 % + the fit's averaging
    assert fit["fn_hz"] == pytest.approx(7.0, rel=0.025)
    assert fit["max_relative_residual"] < 0.11
    assert rs.fit_natural_frequency([2.0], [0.1])["fn_hz"] is None


def _row(seed, f, ds, collapse=False):
    return {"seed": seed, "frequency_hz": f, "run_status": "ok", "analysis_status": "ok",
            "collapse_suspected": collapse, "amplification": {"ds": ds, "da": 1 + ds,
                                                             "dsr": 0.5 * ds},
            "lag_s": {"ds": 0.01}, "dominant_frequency_hz": f, "h1_ds": ds}


def _point(f, ds, collapse=False):
    """A sweep.json point as postprocess.sweep.point_record writes it (the fields read)."""
    return {"frequency_hz": f, "status": "ok", "analysis_status": "ok", "amplitude_m": 0.001,
            "amplification": {"ds": ds, "da": abs(1 + ds), "dsr": 0.5 * ds, "a": 2.0,
                              "a_lp": 1.5},
            "lag": {"ds": {"s": 0.01}, "dsr": {"s": 0.0}},
            "h1_amplitude_ratio": {"ds": ds}, "dominant_frequency_hz": f,
            "excited": {"n_excited": 50}, "collapse_suspected": collapse, "mechanism": {}}


def test_report_joins_the_prediction_curve_and_the_points_above_it(tmp_path, monkeypatch):
    _, path = frozen_repo(tmp_path)
    fr = pl.load_frozen(path)
    monkeypatch.setattr(rs, "FREQUENCIES", {"model-ii-y": (6.0, 8.0, 10.0)})
    pred_out, out = tmp_path / "pred", tmp_path / "res"
    pf = [2.0, 2.8, 3.6]
    rows = [_row(s, f, float(rs.base_transfer(f, 8.0, 0.2)) * (1 + 0.01 * s))
            for s in range(3) for f in pf]
    (pred_out / "model-ii-y").mkdir(parents=True)
    pred_points.points_path(pred_out, "model-ii-y").write_text(json.dumps({"rows": rows}))
    above = {6.0: [1.0, 1.1, 1.2], 8.0: [2.4, 2.5, 99.0], 10.0: [1.5, 1.6, 1.7]}
    for s in range(3):
        d = out / "runs" / "model-ii-y" / f"seed-{s}"
        d.mkdir(parents=True)
        pts = [_point(f, v[s], collapse=v[s] > 50) for f, v in above.items()]
        (d / "sweep.json").write_text(json.dumps({"points": pts}))
    data = rs.report(out, pred_out, fr, 3, 20.0, {"model-ii-y": 30.0}, "test")
    v = data["sweeps"]["model-ii-y"]
    # the prediction rows were made with f_n = 8 Hz and zeta = 0.2: the undamped fit of three
    # points at r <= 0.45 reads f_n within (2 zeta r)^2 / 4 ~ 1 % of it
    assert v["prediction_fit"]["median"]["fn_hz"] == pytest.approx(8.0, rel=0.02)
    a8 = v["above"]["8"]
    assert a8["n_run"] == 3 and a8["n_survived"] == 2          # the collapsed seed is left out
    assert a8["amplification"]["ds"]["median"] == pytest.approx(2.45)
    assert [f for f, _ in v["joined_curve"]] == pf + [6.0, 8.0, 10.0]
    assert v["joined_peak"]["characteristic_frequency_hz"] == 8.0
    assert data["cpu_seconds"] == 30.0
    text = (out / "README.md").read_text()
    assert "NOT a result" in text and "8 Hz (amplification 2.45)" in text
    assert (out / "amplification.png").is_file()
