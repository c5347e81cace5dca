"""postprocess.qs_validation: the slow-tilt check of the calibration's quasi-static lambda."""

from __future__ import annotations

import json

import pytest

from postprocess import calibration_study as cs
from postprocess import qs_validation as qv


def test_the_rate_case_is_the_calibration_case_on_a_constant_rate_tilt():
    spec = cs.specimens()["ip-small-5x7"]
    params = cs.load_candidates()["bed-0.1-planar"]
    qs = cs.specimen_case(spec["path"], params, "a")
    slow = cs.specimen_case(spec["path"], params, "a", rate=0.5)
    assert qs.loading.method == "quasi_static"
    assert slow.loading.method == "constant_rate" and slow.loading.rate == 0.5
    assert slow.loading.start_angle == 0.0
    assert slow.loading.collapse.confirm == cs.RUNAWAY_COLLAPSE["confirm"] == 0.02
    assert slow.loading.collapse.onset_speed == qs.loading.collapse.onset_speed
    assert slow.imperfections == qs.imperfections and slow.material == qs.material
    # long enough to reach the case's largest angle at that rate
    assert slow.run.duration >= slow.loading.max_angle / 0.5


def test_the_quasi_static_case_is_unchanged_by_the_rate_option():
    spec = cs.specimens()["ip-small-5x5"]
    params = cs.load_candidates()["perfect"]
    assert cs.specimen_case(spec["path"], params, "b").model_dump() == \
        cs.specimen_case(spec["path"], params, "b", rate=None).model_dump()


def test_compare_extrapolates_to_rate_zero_and_flags_a_far_quasi_static_value():
    # the perfect 9 x 15 s = 10 mm wall (benchmarks/speed_error.md): 2, 1, 0.5 deg/s
    # 0.5228, 0.5104, 0.5067 and quasi-static 0.5408.  lambda0 = l1 + d1 / (d2 / d1 - 1)
    rows = qv.compare({"seed-0": 0.5408},
                      {2.0: {"seed-0": 0.5228}, 1.0: {"seed-0": 0.5104}, 0.5: {"seed-0": 0.5067}})
    (r,) = rows
    # here a faster tilt reads HIGH: both differences negative, shrinking towards r -> 0
    d1, d2 = 0.5067 - 0.5104, 0.5104 - 0.5228
    assert r["lambda0"] == pytest.approx(0.5067 + d1 / (d2 / d1 - 1))
    assert r["lambda0"] < 0.5067
    assert r["qs_vs_lambda0"] == pytest.approx(0.5408 / r["lambda0"] - 1)
    assert r["flag"]
    # the perfect 5 x 7 wall (results/tilt: 0.7701, 0.784, 0.791; a faster tilt reads low;
    # lambda0 0.8001 there from 4 digits): quasi-static within 0.1 % of lambda0: not flagged
    rows = qv.compare({"seed-0": 0.8008},
                      {2.0: {"seed-0": 0.7701}, 1.0: {"seed-0": 0.784}, 0.5: {"seed-0": 0.791}})
    assert rows[0]["lambda0"] > 0.791
    assert not rows[0]["flag"]


def test_compare_without_a_monotone_trio_falls_back_to_the_slowest_rate():
    rows = qv.compare({"seed-0": 0.60, "seed-1": 0.60},
                      {2.0: {"seed-0": 0.58, "seed-1": 0.58}, 1.0: {"seed-0": 0.59},
                       0.5: {"seed-0": 0.585, "seed-1": 0.58}})
    (r,) = rows                                    # seed-1 lacks 1 deg/s: not compared
    assert r["lambda0"] is None
    assert r["qs_vs_slowest"] == pytest.approx(0.60 / 0.585 - 1)
    assert not r["flag"]                           # 2.6 % < 3 %


def test_smoke_run_resumes_and_reports(tmp_path):
    out, cal = tmp_path / "v", tmp_path / "cal"
    args = ["--out", str(out), "--calibration", str(cal), "--specimens", "ip-small-5x5",
            "--rates", "2", "1", "0.5", "--max-steps", "300"]
    assert qv.main(args) == 0
    for r in (2.0, 1.0, 0.5):
        p = json.loads(cs.point_path(qv.rate_dir(out, r), "perfect", "ip-small-5x5").read_text())
        assert p["calibration"]["rate_deg_per_s"] == r
        assert p["calibration"]["finished"]
    first = cs.point_path(qv.rate_dir(out, 0.5), "perfect", "ip-small-5x5").stat().st_mtime_ns
    assert qv.main(args) == 0                      # finished: nothing runs again
    assert cs.point_path(qv.rate_dir(out, 0.5), "perfect",
                         "ip-small-5x5").stat().st_mtime_ns == first
    s = json.loads((out / "summary.json").read_text())
    assert s["specimens"]["ip-small-5x5"]["rows"] == []       # no quasi-static point here
    assert not s["specimens"]["ip-small-5x5"]["quasi_static_finished"]
    assert "quasi-static point pending" in (out / "README.md").read_text()
