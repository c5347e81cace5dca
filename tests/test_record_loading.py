"""Base-acceleration records (CSV or inline) as table motion."""

import numpy as np
import pytest

from dem.case import CaseError, load_case, parse_case
from dem.loading import loading_from_case
from dem.run import run_case

BLOCK = {"size": [0.2, 0.2, 0.1], "position": [0, 0, 0.05], "mass": 4.0}


def _case(loading, **extra):
    return parse_case({"name": "rec", "scene": {"blocks": [BLOCK]}, "material": {"friction": 0.3},
                       "loading": loading, "run": {"duration": 0.5, "output_interval": 0.01},
                       **extra})


def test_record_integrates_to_the_table_motion_from_rest():
    """Constant 2 m/s2 along x from t = 0 to 1 s: v = 2 t, u = t^2 (trapezoid exact here);
    after the record the acceleration is 0 and the table keeps its speed."""
    t = np.linspace(0, 1, 11)
    ld = loading_from_case(_case({"type": "record", "time": t.tolist(),
                                  "ax": [2.0] * 11, "ay": [0.0] * 11}))
    tt = np.array([0.25, 0.5, 1.0, 2.0])
    assert np.allclose(ld.base_accel(tt)[:, 0], [2, 2, 2, 0])
    assert np.allclose(ld.base_vel(tt)[:, 0], [0.5, 1.0, 2.0, 2.0])
    assert np.allclose(ld.base_disp(tt)[:, 0], [0.0625, 0.25, 1.0, 3.0])


def test_csv_and_inline_records_agree_and_scale(tmp_path):
    t = np.linspace(0, 0.4, 41)
    ay = 3.0 * np.sin(2 * np.pi * 5 * t)
    (tmp_path / "rec.csv").write_text("t,ax,ay\n" + "\n".join(
        f"{a},0,{b}" for a, b in zip(t, ay)))
    (tmp_path / "case.yaml").write_text(
        "name: r\nscene: {blocks: [{size: [0.2, 0.2, 0.1], position: [0, 0, 0.05], mass: 4}]}\n"
        "material: {friction: 0.3}\nloading: {type: record, file: rec.csv, scale: 2.0}\n"
        "run: {duration: 0.5}\n")
    from_csv = loading_from_case(load_case(tmp_path / "case.yaml"))
    inline = loading_from_case(_case({"type": "record", "time": t.tolist(), "ax": [0.0] * 41,
                                      "ay": ay.tolist(), "scale": 2.0}))
    probe = np.linspace(0, 0.6, 37)
    assert np.allclose(from_csv.base_accel(probe), inline.base_accel(probe))
    assert np.allclose(from_csv.base_disp(probe), inline.base_disp(probe))
    assert np.abs(inline.base_accel(probe)[:, 1]).max() == pytest.approx(6.0, rel=0.01)


def test_bad_records_name_the_problem(tmp_path):
    with pytest.raises(CaseError, match="ay has 2 samples, time has 3"):
        _case({"type": "record", "time": [0, 1, 2], "ay": [0, 1]})
    with pytest.raises(CaseError, match="strictly increasing"):
        _case({"type": "record", "time": [0, 1, 1], "ay": [0, 1, 2]})
    (tmp_path / "bad.csv").write_text("t,ax\n0,1\n1,2\n")
    (tmp_path / "case.yaml").write_text(
        "name: r\nscene: {blocks: [{size: [0.2, 0.2, 0.1], position: [0, 0, 0.05], mass: 4}]}\n"
        "material: {friction: 0.3}\nloading: {type: record, file: bad.csv}\nrun: {duration: 1}\n")
    with pytest.raises(CaseError, match=r"loading\.file: .*3 or 4 columns"):
        load_case(tmp_path / "case.yaml")


def test_block_slides_under_a_recorded_acceleration_above_mu_g():
    """A squat block (mu 0.3) under a recorded constant 0.5 g table acceleration slides relative
    to the table at (0.5 - 0.3) g."""
    g = 9.81
    t = np.linspace(0, 1, 3)
    res = run_case(_case({"type": "record", "time": t.tolist(), "ax": [0.5 * g] * 3,
                          "ay": [0.0] * 3}))
    x = res.pos[:, 0, 0] - res.pos[0, 0, 0]
    fit = res.t > 0.05
    accel = 2 * np.polyfit(res.t[fit], x[fit], 2)[0]
    assert accel == pytest.approx(-(0.5 - 0.3) * g, rel=0.02)
