"""studies.chapter3.check (`python -m studies chapter3-check`): the prediction's Chapter 3
criterion (the calibrated tilt results unchanged within 5 %), judged seed by seed against the committed calibration.  Hand-made
ensemble records; nothing runs the engine (run_point: studies.calibration.points, tested there)."""

from __future__ import annotations

import json

import pytest
import yaml

from studies.calibration import points as cal_points
from studies.calibration import specimens as cal_specimens
from studies.chapter3 import check as c3
from studies.prediction import criteria as crit

PARAMS = {"bed_unevenness": 0.0001, "face_shape": "planar", "size_scatter": [0.0, 0.0, 0.0],
          "arris": 0.0}


def _ens(lams: dict[int, float], mech="sliding", **cal_block):
    return {"realisations": [{"seed": s, "status": "ok", "lambda": v, "mechanism": mech}
                             for s, v in lams.items()], "calibration": cal_block}


def test_a_seed_within_5_percent_passes_one_beyond_fails_a_missing_one_is_pending():
    calib = _ens({0: 0.80, 1: 0.60})
    assert c3.compare_point(calib, _ens({0: 0.80 * 1.049}), [0])["status"] == "pass"
    p = c3.compare_point(calib, _ens({0: 0.80 * 1.051}), [0])
    assert p["status"] == "fail" and p["max_rel_diff"] == pytest.approx(0.051)
    assert c3.compare_point(calib, _ens({0: 0.80}), [0, 1])["status"] == "pending"
    # one seed beyond decides even when another is missing
    assert c3.compare_point(calib, _ens({0: 0.70}), [0, 1])["status"] == "fail"


def test_a_different_mechanism_is_reported_not_judged():
    p = c3.compare_point(_ens({0: 0.5}, "mixed"), _ens({0: 0.5}, "overturning"), [0])
    assert p["status"] == "pass" and p["rows"][0]["same_mechanism"] is False
    assert "same mechanism in 0 of 1" in c3.verdict({"x": p})["why"]


def test_fewer_specimens_than_the_calibration_pass_nothing_but_can_fail():
    ok = c3.compare_point(_ens({0: 0.5}), _ens({0: 0.5}), [0])
    bad = c3.compare_point(_ens({0: 0.5}), _ens({0: 0.6}), [0])
    assert c3.verdict({"a": ok}, n_specimens=1)["status"] == "pass"
    v = c3.verdict({"a": ok}, n_specimens=10)
    assert v["status"] == "pending" and "only 1 of the calibration's 10" in v["why"]
    assert c3.verdict({"a": ok, "b": bad}, n_specimens=10)["status"] == "fail"
    assert c3.verdict({})["status"] == "pending"


def test_the_frozen_set_must_be_its_candidate_naming_the_file(tmp_path):
    f = tmp_path / "frozen.yaml"
    f.write_text(yaml.safe_dump({"candidate": "bed-0.1-planar", "imperfections": PARAMS}))
    assert c3.frozen_candidate(f, {"bed-0.1-planar": PARAMS}) == ("bed-0.1-planar", PARAMS)
    with pytest.raises(c3.CheckInputError, match="frozen.yaml.*differ"):
        c3.frozen_candidate(f, {"bed-0.1-planar": {**PARAMS, "arris": 0.001}})
    with pytest.raises(c3.CheckInputError, match="not in the candidates file"):
        c3.frozen_candidate(f, {"perfect": PARAMS})


def test_compare_reads_both_records_and_recognises_the_calibrations_case(tmp_path):
    spec_name = "ip-small-5x5"
    spec = cal_specimens.specimens()[spec_name]
    case = cal_specimens.specimen_case(spec["path"], PARAMS, f"cal-bed-0.1-planar-{spec_name}")
    calib_dir, out = tmp_path / "calibration", tmp_path / "check"
    for root, data in (
            (calib_dir, _ens({0: 0.8044, 1: 0.799}, n_realisations=20,
                             fingerprint=cal_specimens.fingerprint(case, 20, None))),
            (out, _ens({0: 0.8053}, n_realisations=1, cpu_seconds=20.0))):
        dest = cal_points.point_path(root, "bed-0.1-planar", spec_name)
        dest.parent.mkdir(parents=True)
        dest.write_text(json.dumps(data))
    rec = c3.compare(out, calib_dir, "bed-0.1-planar", {spec_name: spec}, [0], PARAMS)
    p = rec["specimens"][spec_name]
    assert p["status"] == "pass" and p["same_case"] is True and p["cpu_seconds"] == 20.0
    assert p["rows"][0]["rel_diff"] == pytest.approx(abs(0.8053 - 0.8044) / 0.8044)
    assert rec["verdict"]["status"] == "pending"  # one of the calibration's specimens only


def test_the_prediction_report_takes_its_chapter_3_row_from_the_check():
    def row(chapter3):
        return [r for r in crit.criteria({}, chapter3) if r["sweep"] == "chapter 3"][0]
    assert row(None)["status"] == "pending" and "chapter3-check" in row(None)["why"]
    rec = {"verdict": {"status": "fail", "why": "beyond"}, "seeds": [0],
           "source": {"commit": "abcdef0123", "dirty": False}, "engine_results_revision": 3}
    r = row(rec)
    assert r["status"] == "fail" and "abcdef0" in r["why"] and "revision 3" in r["why"]


def test_unknown_specimen_exits_2_running_nothing(tmp_path, capsys):
    assert c3.main(["--specimens", "no-such-wall", "--out", str(tmp_path)]) == 2
    assert "no-such-wall" in capsys.readouterr().err and not any(tmp_path.iterdir())
