"""studies.qs_validation: the slow-tilt check of the calibration's quasi-static lambda."""

from __future__ import annotations

import json

import pytest

from studies.calibration import points as cal_points
from studies.calibration import specimens as cal_specimens
from studies.qs_validation import study as qv


def test_the_rate_case_is_the_calibration_case_on_a_constant_rate_tilt():
    spec = cal_specimens.specimens()["ip-small-5x7"]
    params = cal_specimens.load_candidates()["bed-0.1-planar"]
    qs = cal_specimens.specimen_case(spec["path"], params, "a")
    slow = cal_specimens.specimen_case(spec["path"], params, "a", rate=0.5)
    assert qs.loading.method == "quasi_static"
    assert slow.loading.method == "constant_rate" and slow.loading.rate == 0.5
    assert slow.loading.start_angle == 0.0
    assert slow.loading.collapse.confirm == cal_specimens.RUNAWAY_COLLAPSE["confirm"] == 0.02
    assert slow.loading.collapse.onset_speed == qs.loading.collapse.onset_speed
    assert slow.imperfections == qs.imperfections and slow.material == qs.material
    # long enough to reach the case's largest angle at that rate
    assert slow.run.duration >= slow.loading.max_angle / 0.5


def test_the_quasi_static_case_is_unchanged_by_the_rate_option():
    spec = cal_specimens.specimens()["ip-small-5x5"]
    params = cal_specimens.load_candidates()["perfect"]
    assert cal_specimens.specimen_case(spec["path"], params, "b").model_dump() == \
        cal_specimens.specimen_case(spec["path"], params, "b", rate=None).model_dump()


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


@pytest.mark.slow
def test_smoke_run_resumes_and_reports(tmp_path):
    out, cal = tmp_path / "v", tmp_path / "cal"
    args = ["--out", str(out), "--calibration", str(cal), "--specimens", "ip-small-5x5",
            "--rates", "2", "1", "0.5", "--max-steps", "300"]
    assert qv.main(args) == 0
    for r in (2.0, 1.0, 0.5):
        p = json.loads(cal_points.point_path(qv.rate_dir(out, r), "perfect", "ip-small-5x5").read_text())
        assert p["calibration"]["rate_deg_per_s"] == r
        assert p["calibration"]["finished"]
    first = cal_points.point_path(qv.rate_dir(out, 0.5), "perfect", "ip-small-5x5").stat().st_mtime_ns
    assert qv.main(args) == 0                      # finished: nothing runs again
    assert cal_points.point_path(qv.rate_dir(out, 0.5), "perfect",
                         "ip-small-5x5").stat().st_mtime_ns == first
    s = json.loads((out / "summary.json").read_text())
    assert s["specimens"]["ip-small-5x5"]["rows"] == []       # no quasi-static point here
    assert not s["specimens"]["ip-small-5x5"]["quasi_static_finished"]
    assert "quasi-static point pending" in (out / "README.md").read_text()


def test_rates_that_do_not_converge_give_no_lambda0_and_only_a_bound():
    # the perfect 5 x 15 wall (results/calibration/qs-validation): 2, 1, 0.5 deg/s read
    # 0.5839, 0.5966, 0.6087: the differences barely shrink (2^p = 1.05), and lambda = lambda0 -
    # c r^p through them would put lambda0 at 0.865, far beyond the 0.025 the rates span
    rates = {2.0: {"seed-0": 0.5839}, 1.0: {"seed-0": 0.5966}, 0.5: {"seed-0": 0.6087}}
    pts = sorted((r, v["seed-0"]) for r, v in rates.items())
    assert qv.rate_extrapolation(pts) > 0.8              # the raw fit
    assert qv.rate_limit(pts) == (None, "not converging")
    (r,) = qv.compare({"seed-0": 0.6241}, rates)          # above the slowest: the trend's side
    assert r["lambda0"] is None and r["verdict"] == "unconfirmed" and not r["flag"]
    (r,) = qv.compare({"seed-0": 0.6087 * 0.96}, rates)   # 4 % below the slowest: against it
    assert r["verdict"] == "flag" and r["flag"]
    (r,) = qv.compare({"seed-0": 0.6087 * 0.98}, rates)   # 2 % below: within the tolerance
    assert r["verdict"] == "unconfirmed"


def test_a_converging_trio_extrapolates_within_its_span():
    # lambda = 0.62 - 0.02 r exactly (p = 1): lambda0 is the intercept
    pts = [(r, 0.62 - 0.02 * r) for r in (0.5, 1.0, 2.0)]
    lam0, how = qv.rate_limit(pts)
    assert how == "extrapolated" and lam0 == pytest.approx(0.62)
    # the edge is p = 1/2 (correction D1 / (2^p - 1) = span D1 (1 + 2^p)): 0.6 in, 0.4 out
    pts = [(r, 0.62 - 0.02 * r ** 0.6) for r in (0.5, 1.0, 2.0)]
    assert qv.rate_limit(pts)[0] == pytest.approx(0.62)
    pts = [(r, 0.62 - 0.02 * r ** 0.4) for r in (0.5, 1.0, 2.0)]
    assert qv.rate_limit(pts) == (None, "not converging")


def test_a_slower_rate_on_disk_joins_the_specimens_that_have_it(tmp_path):
    out, cal = tmp_path / "v", tmp_path / "cal"

    def point(d, spec, lam):
        p = cal_points.point_path(d, "perfect", spec)
        p.parent.mkdir(parents=True, exist_ok=True)
        p.write_text(json.dumps({"realisations": [{"name": "seed-0", "status": "ok",
                                                   "lambda": lam}]}))

    lam = {0.25: 0.6191, 0.5: 0.6087, 1.0: 0.5966, 2.0: 0.5839}
    for spec in ("ip-small-5x15", "ip-small-5x20"):
        point(cal, spec, 0.6241)
        for r in (0.5, 1.0, 2.0):
            point(qv.rate_dir(out, r), spec, lam[r])
    point(qv.rate_dir(out, 0.25), "ip-small-5x15", lam[0.25])
    orig = cal_points.point_finished
    cal_points.point_finished = lambda data: data is not None      # the synthetic points are complete
    try:
        res = qv.collect(out, cal, "perfect", {"ip-small-5x15": {}, "ip-small-5x20": {}},
                         (2.0, 1.0, 0.5))
    finally:
        cal_points.point_finished = orig
    assert qv.rates_on_disk(out) and 0.25 in qv.rates_on_disk(out)
    (a,), (b,) = res["ip-small-5x15"]["rows"], res["ip-small-5x20"]["rows"]
    assert set(a["rates"]) == {"0.25", "0.5", "1", "2"} and set(b["rates"]) == {"0.5", "1", "2"}
    assert res["ip-small-5x20"]["pending_rates"] == []
    # 0.25, 0.5, 1 deg/s: differences 0.0104, 0.0121 -> 2^p = 1.16, still not converging
    assert a["rate_limit"] == "not converging"
