"""The response-branch verdict (postprocess.verdicts.response_branch): a run is on the
rocking branch when its ds amplification reaches 1 AND its phase behind the table passes 90 deg
(a driven oscillator's phase at resonance).  The rows are built from a linear oscillator's
closed-form response, so the test does not rest on any number the DEM printed."""

from __future__ import annotations

import math

import pytest

from postprocess.verdicts import BRANCH_AMPLIFICATION, BRANCH_PHASE_DEG, response_branch


def oscillator_row(f: float, fn: float, zeta: float) -> dict:
    """The relative response of a base-excited linear oscillator (natural frequency fn, damping
    ratio zeta) as a study's row: amplification r^2 / |1 - r^2 + 2 i zeta r| and its phase lag
    atan2(2 zeta r, 1 - r^2) converted to a time lag (s)."""
    r = f / fn
    amp = r * r / abs(complex(1 - r * r, 2 * zeta * r))
    phase = math.atan2(2 * zeta * r, 1 - r * r)
    return {"frequency_hz": f, "amplification": {"ds": amp},
            "lag_s": {"ds": phase / (2 * math.pi * f)}}


def test_below_resonance_is_quasi_static_and_above_is_rocking():
    fn, zeta = 4.0, 0.1
    low = response_branch(oscillator_row(2.0, fn, zeta))
    high = response_branch(oscillator_row(4.6, fn, zeta))
    assert low["branch"] == "quasi-static"
    assert low["ds"] < BRANCH_AMPLIFICATION and low["phase_deg"] < BRANCH_PHASE_DEG
    assert high["branch"] == "rocking"
    # the phase read back is the closed form's (360 f lag = the phase angle in degrees)
    r = 4.6 / fn
    assert high["phase_deg"] == pytest.approx(math.degrees(math.atan2(2 * zeta * r, 1 - r * r)))


def test_one_criterion_alone_is_between():
    # a heavily damped oscillator at resonance lags 90+ deg with an amplification below 1
    row = oscillator_row(4.05, 4.0, 0.8)
    assert row["amplification"]["ds"] < 1
    assert response_branch(row)["branch"] == "between"


def test_missing_quantities_give_no_branch():
    assert response_branch({"frequency_hz": 2.8, "amplification": {"ds": None},
                            "lag_s": {"ds": 0.1}})["branch"] is None
    assert response_branch({"frequency_hz": 2.8, "amplification": {"ds": 0.5}})["branch"] is None
