"""studies/unevenness/study.py: the prediction's Model II y case with only the bed
unevenness changed, and the report's statistics on hand-made sweep records."""

from __future__ import annotations

import json

import pytest

from studies.prediction import plan as pl
from studies.unevenness import study as us
from tests.test_prediction_study import FROZEN, frozen_repo


def test_a_level_is_the_prediction_case_with_only_the_bed_unevenness_changed(tmp_path):
    _, path = frozen_repo(tmp_path)
    fr = pl.load_frozen(path)
    pred = pl.sweep_case(us.SWEEP, fr["parameters"]).model_dump()
    for b in us.LEVELS_M:
        lv = us.level_case(fr, b).model_dump()
        assert {k for k in lv if lv[k] != pred[k]} <= {"name", "imperfections"}
        assert lv["imperfections"] == {**pred["imperfections"], "bed_unevenness": b}
    # the frozen level is the prediction's case itself (but for the name)
    same = us.level_case(fr, FROZEN["imperfections"]["bed_unevenness"]).model_dump()
    assert {k for k in same if same[k] != pred[k]} == {"name"}


def _point(ds, collapse=False):
    """A sweep.json point as postprocess.sweep.point_record writes it (the fields read)."""
    f = us.FREQUENCY_HZ
    return {"frequency_hz": f, "status": "ok", "analysis_status": "ok", "amplitude_m": 0.005,
            "amplification": {"ds": ds, "da": abs(1 + ds), "dsr": 0.5 * ds, "a": 2.0,
                              "a_lp": 1.5},
            "lag": {"ds": {"s": 0.0}, "dsr": {"s": 0.0}},
            "h1_amplitude_ratio": {"ds": ds}, "dominant_frequency_hz": f,
            "excited": {"n_excited": 50}, "collapse_suspected": collapse, "mechanism": {}}


def test_report_gives_the_medians_of_the_survivors_per_level(tmp_path):
    _, path = frozen_repo(tmp_path)
    fr = pl.load_frozen(path)
    out = tmp_path / "sens"
    ds = {us.LEVELS_M[0]: [0.1, 0.2, 0.3], us.LEVELS_M[-1]: [3.0, 4.0, 99.0]}
    for b, vals in ds.items():
        for s, v in enumerate(vals):
            d = out / "runs" / us.level_name(b) / f"seed-{s}"
            d.mkdir(parents=True)
            (d / "sweep.json").write_text(json.dumps({"points": [_point(v, collapse=v > 50)]}))
    data = us.report(out, fr, 3, 10.0, {us.level_name(us.LEVELS_M[0]): 12.0}, "test")
    lo = data["levels"][us.level_name(us.LEVELS_M[0])]
    hi = data["levels"][us.level_name(us.LEVELS_M[-1])]
    assert lo["n_run"] == 3 and lo["n_survived"] == 3
    assert lo["amplification"]["ds"]["median"] == pytest.approx(0.2)
    assert hi["n_survived"] == 2                             # the collapsed seed is left out
    assert hi["amplification"]["ds"]["median"] == pytest.approx(3.5)
    mid = data["levels"][us.level_name(us.LEVELS_M[1])]
    assert mid["n_run"] == 0 and mid["amplification"]["ds"]["median"] is None
    assert data["cpu_seconds"] == 12.0
    text = (out / "README.md").read_text()
    assert "NOT a result" in text and "(frozen)" in text
    assert (out / "amplification.png").is_file()
