"""The onset rule's pure functions (studies/diagnosis/onset_rule.py): the oscillator's
amplifications against their closed forms, the damped-mode reading of one response, and the fit
recovering a rule that generated synthetic outcomes."""

from __future__ import annotations

import math

import numpy as np
import pytest

from studies.diagnosis import onset_rule as R


def test_transmissibility_closed_forms():
    f = np.array([1.0, 2.0, 3.0])
    fn = 4.0
    r = f / fn
    # zeta = 0: E1's relative amplification r^2 / |1 - r^2| (Chopra 3.6, undamped)
    np.testing.assert_allclose(R.transmissibility(f, fn, 0.0), r ** 2 / np.abs(1 - r ** 2),
                               rtol=1e-12)
    # at resonance: relative and deformation 1 / (2 zeta), absolute sqrt(1 + 4 zeta^2) / 2 zeta
    z = 0.2
    assert R.transmissibility(4.0, fn, z) == pytest.approx(1 / (2 * z), rel=1e-12)
    assert R.transmissibility(4.0, fn, z, "deformation") == pytest.approx(1 / (2 * z), rel=1e-12)
    assert R.transmissibility(4.0, fn, z, "absolute") == pytest.approx(
        math.sqrt(1 + 4 * z * z) / (2 * z), rel=1e-12)
    # static limit: the deformation factor and the absolute transmissibility tend to 1
    assert R.transmissibility(1e-6, fn, z, "deformation") == pytest.approx(1.0, abs=1e-9)
    assert R.transmissibility(1e-6, fn, z, "absolute") == pytest.approx(1.0, abs=1e-9)
    with pytest.raises(ValueError, match="kind"):
        R.transmissibility(f, fn, 0.1, "spectral")
    with pytest.raises(ValueError, match="zeta"):
        R.transmissibility(f, fn, -0.1)


@pytest.mark.parametrize("fn, zeta, f", [(7.2, 0.0, 2.0), (4.4, 0.15, 2.0), (3.0, 0.3, 2.8)])
def test_sdof_from_response_inverts_the_transfer_function(fn, zeta, f):
    """The amplification and phase of H = r^2 / (1 - r^2 + 2 i zeta r) give back f_n and zeta
    to round-off, below resonance and (f = 2.8 > f_n = 3.0 x 0.93) near it."""
    r = f / fn
    h = r ** 2 / complex(1 - r ** 2, 2 * zeta * r)
    amp, phase = abs(h), math.degrees(math.atan2(2 * zeta * r, 1 - r ** 2))
    got_fn, got_z = R.sdof_from_response(amp, phase, f)
    assert got_fn == pytest.approx(fn, rel=1e-12)
    assert got_z == pytest.approx(zeta, abs=1e-12)
    if zeta == 0.0:   # E1's undamped formula f sqrt((1 + A) / A)
        assert got_fn == pytest.approx(f * math.sqrt((1 + amp) / amp), rel=1e-12)


def test_best_threshold_on_separable_and_noisy_scores():
    s = np.array([0.1, 0.2, 0.3, 0.5, 0.8, 1.3])
    y = np.array([0, 0, 0, 1, 1, 1], bool)
    b = R.best_threshold(s, y)
    assert b["correct"] == 6 and b["lo"] == 0.3 and b["hi"] == 0.5
    assert b["a0"] == pytest.approx(math.sqrt(0.3 * 0.5))
    # one quiet run above the cut: the best count is n - 1 and the cut stays between 0.3, 0.5
    y2 = y.copy()
    y2[5] = False
    b2 = R.best_threshold(s, y2)
    assert b2["correct"] == 5 and 0.3 < b2["a0"] <= 0.5
    assert R.confusion(s, y2, b2["a0"]) == {
        "rocking_predicted_rocking": 2, "rocking_predicted_quiet": 0,
        "quiet_predicted_rocking": 1, "quiet_predicted_quiet": 3}
    # every run quiet: the cut goes above the largest score
    b3 = R.best_threshold(s, np.zeros(6, bool))
    assert b3["correct"] == 6 and b3["a0"] > 1.3


@pytest.mark.parametrize("kind", R.KINDS)
def test_fit_recovers_a_generating_rule(kind):
    """Outcomes drawn from rule (1) with known (zeta, a0) on two f_n groups: the fit classifies
    every one, its a0 interval contains the true a0 at the true zeta (the interval is bounded by
    the two scores on either side of the true cut, by construction), and the true zeta is among
    those reaching the best count."""
    rng = np.random.default_rng(3)
    n = 300
    f = rng.uniform(1.6, 4.4, n)
    fn = rng.choice([4.4, 7.2], n)
    accel = rng.uniform(0.8, 3.2, n)
    zeta, a0 = 0.2, {"relative": 0.6, "deformation": 2.0, "absolute": 2.0}[kind]
    score = accel * R.transmissibility(f, fn, zeta, kind)
    rocked = score >= a0
    assert 0.2 < rocked.mean() < 0.8          # both outcomes represented
    res = R.fit(f, accel, fn, rocked, kind=kind)
    assert res["best"]["correct"] == n
    per = {p["zeta"]: p for p in res["per_zeta"]}
    at_true = per[zeta]
    assert at_true["correct"] == n
    assert at_true["lo"] < a0 <= at_true["hi"]
    assert at_true["lo"] == score[~rocked].max() and at_true["hi"] == score[rocked].min()


def test_imputed_ratio_stands_in_for_a_model_that_rocked_at_every_seed():
    fns = R.fn_table({"candidates": {
        R.BASELINE: {"sweeps": {"model-ii-y": {"median_fn_hz": 7.0, "fn_hz_by_seed": {"0": 7.0}},
                                "model-iii-y": {"median_fn_hz": None, "fn_hz_by_seed": {}}}},
        "soft": {"sweeps": {"model-ii-y": {"median_fn_hz": 4.0, "fn_hz_by_seed": {}},
                            "model-iii-y": {"median_fn_hz": 2.6, "fn_hz_by_seed": {}}}}}})
    assert R.imputed_ratio(fns, "model-iii-y") == pytest.approx(0.65)
    assert fns[R.BASELINE]["model-ii-y"]["by_seed"] == {0: 7.0}


def _row(seed, f, amp, ds, lag):
    return {"seed": seed, "frequency_hz": f, "run_status": "ok", "amplitude_m": amp,
            "amplification": {"ds": ds}, "lag_s": {"ds": lag}}


def test_outcomes_read_e4_levels_and_grid_variants(tmp_path):
    """E4's records hold levels, the grids' variants; A = (2 pi f)^2 x the amplitude; the branch
    is the library's verdict (ds >= 1 and phase >= 90 deg: rocking); a failed run is skipped."""
    import json

    w = 2 * math.pi * 2.8
    (tmp_path / "e4").mkdir()
    (tmp_path / "e4" / "points.json").write_text(json.dumps({"levels": {"a2.30": {"rows": [
        _row(0, 2.8, 2.3 / w ** 2, 2.4, 0.14), _row(1, 2.8, 2.3 / w ** 2, 0.2, 0.012),
        {"seed": 2, "frequency_hz": 2.8, "run_status": "failed"}]}}}))
    (tmp_path / "e1-band").mkdir()
    (tmp_path / "e1-band" / "points.json").write_text(json.dumps({"sweep": "model-ii-y",
        "variants": {"soft": {"rows": [_row(0, 2.8, 1.53 / w ** 2, 0.4, 0.01)]}}}))
    fns = {R.BASELINE: {"model-ii-y": {"median": 7.0, "by_seed": {0: 6.5}}},
           "soft": {"model-ii-y": {"median": 4.4, "by_seed": {}}}}
    got = R.outcomes({"e4": R.BASELINE, "e1-band": None}, fns, tmp_path)
    assert [(o["experiment"], o["seed"], o["rocked"], o["fn_hz"]) for o in got] == [
        ("e4", 0, True, 7.0), ("e4", 1, False, 7.0), ("e1-band", 0, False, 4.4)]
    assert got[0]["table_acceleration_m_s2"] == pytest.approx(2.3, rel=1e-12)
    assert got[0]["fn_seed_hz"] == 6.5 and got[1]["fn_seed_hz"] == 7.0
