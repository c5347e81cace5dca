"""Issue 36, "a user's second day": one test per defect (1-8), each failing on the code before
the fix.  Fast: no test here runs the DEM engine (the runs they need are planted files)."""

from __future__ import annotations

import json
import math

import numpy as np
import pytest
import yaml
from typer.testing import CliRunner

from dem.cli import app

CASES = __import__("pathlib").Path(__file__).resolve().parent.parent / "cases"


def _invoke(*args):
    return CliRunner().invoke(app, [str(a) for a in args])


# ------------------------------------------------------------------------------------------
# defect 1: dem post on an ensemble directory
# ------------------------------------------------------------------------------------------
def _planted_tilt_ensemble(root, lambdas):
    """A `dem ensemble` directory of a tilt case with planted results (what dem.batch writes:
    seed-S/case.json, summary.json; ensemble.json with the seeds)."""
    from dem.case import load_case

    case = load_case(CASES / "analytic" / "block-on-tilt.yaml")
    root.mkdir()
    rows = []
    for i, lam in enumerate(lambdas):
        d = root / f"seed-{i}"
        d.mkdir()
        (d / "case.json").write_text(case.model_dump_json(indent=1))
        col = {"detected": lam is not None, "load_factor": lam,
               "angle_deg": math.degrees(math.atan(lam)) if lam else None}
        (d / "summary.json").write_text(json.dumps(
            {"name": d.name, "status": "ok", "collapse": col,
             "mechanism": {"mechanism": "overturning"}}))
        rows.append({"name": d.name, "seed": i, "status": "pending"})
    (root / "ensemble.json").write_text(json.dumps(
        {"kind": "ensemble", "case": case.name, "seeds": list(range(len(lambdas))),
         "realisations": rows, "aggregate": {}}))


def test_post_of_an_ensemble_reaggregates_it(tmp_path):
    lambdas = [0.41, 0.45, 0.47]
    _planted_tilt_ensemble(tmp_path / "ens", lambdas)
    res = _invoke("post", tmp_path / "ens")
    assert res.exit_code == 0, res.output
    assert "Traceback" not in res.output
    data = json.loads((tmp_path / "ens" / "ensemble.json").read_text())
    stats = data["aggregate"]["statistics"]["lambda"]
    assert stats["n"] == 3 and stats["median"] == float(np.median(lambdas))
    assert data["aggregate"]["mechanisms"] == {"overturning": 3}
    assert (tmp_path / "ens" / "lambda.png").is_file()


def test_post_of_a_directory_that_is_none_of_them_says_so_in_one_line(tmp_path):
    (tmp_path / "x").mkdir()
    (tmp_path / "x" / "notes.txt").write_text("hello")
    res = _invoke("post", tmp_path / "x")
    assert res.exit_code == 2
    assert len(res.output.strip().splitlines()) == 1
    assert "not a run" in res.output and "ensemble" in res.output


def test_post_of_run_directories_of_a_tilt_case_is_not_taken_for_a_sweep(tmp_path):
    _planted_tilt_ensemble(tmp_path / "ens", [0.4, 0.5])
    (tmp_path / "ens" / "ensemble.json").unlink()  # just a folder of tilt runs
    res = _invoke("post", tmp_path / "ens")
    assert res.exit_code == 2, res.output
    assert "Traceback" not in res.output and "not a sweep" in res.output


# ------------------------------------------------------------------------------------------
# defect 2: --resume drops the killed run's analysis and says what it does
# ------------------------------------------------------------------------------------------
def test_resume_drops_the_stopped_runs_analysis_and_says_where_it_goes_on(tmp_path,
                                                                          monkeypatch):
    import dem.run.write
    from dem.case import load_case
    from dem.run import run_case
    from dem.run.write import RunWriter

    data = {
        "name": "one-brick-shaken",
        "scene": {"blocks": [{"size": [0.2, 0.1, 0.05], "position": [0, 0, 0.025],
                              "density": 2000.0}]},
        "material": {"friction": 0.5},
        "loading": {"type": "shake", "direction": [0, 1, 0], "frequency": 5.0,
                    "peak_acceleration": 2.0, "cycles": 1},
        "run": {"duration": 0.1, "output_interval": 0.01, "vtk": False, "snapshot": False},
    }
    path = tmp_path / "brick.yaml"
    path.write_text(yaml.safe_dump(data))
    out = tmp_path / "cut"
    with monkeypatch.context() as m:  # a checkpoint at every frame, stopped after the 3rd
        m.setattr(dem.run.write, "CHECKPOINT_SECONDS", -1.0)
        calls, original = [0], RunWriter.checkpoint

        def checkpoint(self, *args):
            calls[0] += 1
            if calls[0] > 3:
                raise KeyboardInterrupt
            original(self, *args)

        m.setattr(RunWriter, "checkpoint", checkpoint)
        with pytest.raises(KeyboardInterrupt):
            run_case(load_case(path), out)
    stopped_at = json.loads((out / "summary.json").read_text())["sim_time"]
    # what `dem post` of the stopped run leaves (its analysis of the run so far)
    (out / "analysis.json").write_text(json.dumps({"run_status": "interrupted"}))
    (out / "time_histories.png").write_bytes(b"png")
    r = _invoke("run", path, "--out", out, "--resume", "--no-progress")
    assert r.exit_code == 0, r.output
    assert "resuming from t = " in r.output
    said = float(r.output.split("resuming from t = ")[1].split()[0])
    assert 0 < said <= stopped_at  # the last checkpoint, at or before the stop
    assert not (out / "analysis.json").exists() and not (out / "time_histories.png").exists()
    assert json.loads((out / "summary.json").read_text())["status"] == "ok"
    # a finished run cannot be resumed: said, and it starts over
    r = _invoke("run", path, "--out", out, "--resume", "--no-progress")
    assert r.exit_code == 0, r.output
    assert "cannot resume: the run in" in r.output and "starting over" in r.output
