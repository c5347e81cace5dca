"""Resuming a run from its last checkpoint (dem.run.resume): a run stopped after a checkpoint
and resumed is, bit for bit, the run that was never stopped (frames, instrument samples,
steps, energy), the frames recorded after the checkpoint made again; a restart point that does
not fit is refused with the reason and the run starts over; a finished run leaves none."""

from __future__ import annotations

import json
import math

import numpy as np
import pytest
import yaml
from typer.testing import CliRunner

import dem.run.write
from dem.case import Case, load_case
from dem_cli.app import app
from dem.run import run_case
from dem.run.resume import RESTART_FILE
from dem.run.write import RunWriter

# three bricks on a table shaken beyond their sliding threshold (peak 6 m/s2 > mu g = 4.9 m/s2):
# the bricks slide on each other, so the shear history of the contacts matters; warped beds make
# the run settle first (the settling record must survive the resumption)
STACK = {
    "name": "sliding-stack",
    "scene": {"blocks": [{"size": [0.2, 0.1, 0.05], "position": [0, 0, 0.025 + 0.05 * k],
                          "density": 2000.0} for k in range(3)]},
    "material": {"friction": 0.5},
    # 0.6 cycles: the shake the 0.12 s run holds (dem run refuses a shake the run cuts short)
    "loading": {"type": "shake", "direction": [0, 1, 0], "frequency": 5.0,
                "peak_acceleration": 6.0, "cycles": 0.6},
    "run": {"duration": 0.12, "output_interval": 0.01, "vtk": False, "snapshot": False},
    "imperfections": {"bed_unevenness": 2e-4, "face_shape": "planar", "seed": 3},
}

# the thesis' Model II (217 blocks, the prediction's scene) with its instruments, perfect
# geometry (no settling: short enough for a test)
MODEL_II = {
    "name": "model-ii-shaken",
    "scene": {"box_model": {"brick": "small", "model": "II", "length": 7, "width": 5,
                            "roof": {"beams": 5}}},
    "material": {"friction": 0.81},
    "loading": {"type": "shake", "direction": [0, 1, 0], "frequency": 10.0,
                "peak_acceleration": 3.0, "cycles": 1},
    "run": {"duration": 0.03, "output_interval": 0.003, "instrument_interval": 0.001,
            "instruments": "thesis", "vtk": False, "snapshot": False},
}


def _case(data) -> Case:
    return Case.model_validate(data)


def _stop_after_checkpoints(monkeypatch, n: int) -> None:
    """A checkpoint at every frame; the run is stopped (as by Ctrl-C) one frame after the n-th,
    so that the frames after the last restart point must be dropped and made again."""
    monkeypatch.setattr(dem.run.write, "CHECKPOINT_SECONDS", -1.0)
    monkeypatch.setattr(dem.run.write, "CHECKPOINT_SHARE", math.inf)  # never paced apart
    calls = [0]
    original = RunWriter.checkpoint

    def checkpoint(self, *args):
        calls[0] += 1
        if calls[0] > n:
            raise KeyboardInterrupt
        original(self, *args)

    monkeypatch.setattr(RunWriter, "checkpoint", checkpoint)


def _arrays(path) -> dict:
    with np.load(path) as z:
        return {k: z[k] for k in z.files}


def _assert_same_run(a, b) -> None:
    fa, fb = _arrays(a / "frames.npz"), _arrays(b / "frames.npz")
    assert fa.keys() == fb.keys()
    for k in fa:
        np.testing.assert_array_equal(fa[k], fb[k], err_msg=k)
    sa, sb = (json.loads((d / "summary.json").read_text()) for d in (a, b))
    for k in ("status", "steps", "sim_time", "dt", "neighbour_rebuilds", "energy",
              "max_penetration_m", "settling", "n_pairs"):
        assert sa.get(k) == sb.get(k), k
    if (a / "instruments.npz").exists():
        ia, ib = _arrays(a / "instruments.npz"), _arrays(b / "instruments.npz")
        for k in ia:
            np.testing.assert_array_equal(ia[k], ib[k], err_msg=k)
    assert not (a / RESTART_FILE).exists() and not (b / RESTART_FILE).exists()


STACK_PARALLEL = {**STACK, "solver": {"mode": "parallel"}}


@pytest.mark.parametrize("data,stop_at", [(STACK, 4), (STACK_PARALLEL, 4), (MODEL_II, 3)],
                         ids=["settled-sliding-stack", "parallel-kernel", "model-ii-instruments"])
def test_a_resumed_run_is_the_run_never_stopped(tmp_path, monkeypatch, data, stop_at):
    case = _case(data)
    whole = run_case(case, tmp_path / "whole")
    assert whole.summary["status"] == "ok"
    assert whole.summary["resume"]["restart_points"]

    cut = tmp_path / "cut"
    with monkeypatch.context() as m:
        _stop_after_checkpoints(m, stop_at)
        with pytest.raises(KeyboardInterrupt):
            run_case(case, cut)
    summ = json.loads((cut / "summary.json").read_text())
    assert summ["status"] == "interrupted" and (cut / RESTART_FILE).is_file()
    n_cut = len(_arrays(cut / "frames.npz")["t"])
    saved = _arrays(cut / RESTART_FILE)
    assert int(saved["rec.n_frames"]) < n_cut  # frames after the restart point: made again
    assert 0 < int(saved["sim.step_count"]) < whole.summary["steps"]

    res = run_case(case, cut, resume=True)
    assert res.summary["status"] == "ok"
    (entry,) = res.summary["resumed"]
    assert entry["step"] == int(saved["sim.step_count"]) and entry["machine"]
    assert res.summary["wall_seconds"] >= entry["wall_seconds_before"] > 0
    assert ("settling" in whole.summary) == (data is not MODEL_II)
    _assert_same_run(tmp_path / "whole", cut)


def test_a_restart_point_that_does_not_fit_is_refused_and_the_run_starts_over(tmp_path,
                                                                             monkeypatch):
    case = _case(STACK)
    whole = tmp_path / "whole"
    run_case(case, whole)
    cut = tmp_path / "cut"
    with monkeypatch.context() as m:
        _stop_after_checkpoints(m, 2)
        with pytest.raises(KeyboardInterrupt):
            run_case(case, cut)
    # the same files from an engine of another results revision
    arrays = _arrays(cut / RESTART_FILE)
    arrays["results_revision"] = arrays["results_revision"] - 1
    with open(cut / RESTART_FILE, "wb") as fh:
        np.savez(fh, **arrays)
    res = run_case(case, cut, resume=True)
    assert "resumed" not in res.summary
    assert "results revision" in res.summary["resume"]["refused"]
    _assert_same_run(whole, cut)
    # a step limit other than the checkpoint's is refused too
    with monkeypatch.context() as m:
        _stop_after_checkpoints(m, 2)
        with pytest.raises(KeyboardInterrupt):
            run_case(case, cut)
    res = run_case(case, cut, resume=True, max_steps=10 ** 9)
    assert "step limit" in res.summary["resume"]["refused"]


def test_runs_that_cannot_resume_say_why_and_write_no_restart_point(tmp_path, monkeypatch):
    data = json.loads(json.dumps(STACK))
    data["run"]["vtk"] = True
    monkeypatch.setattr(dem.run.write, "CHECKPOINT_SECONDS", -1.0)
    monkeypatch.setattr(dem.run.write, "CHECKPOINT_SHARE", math.inf)  # never paced apart
    res = run_case(_case(data), tmp_path / "vtk")
    assert res.summary["resume"] == {"restart_points": False, "refused": None,
                                     "why_not": "run.vtk (the VTK series is not saved)"}
    assert not (tmp_path / "vtk" / RESTART_FILE).exists()


def test_dem_run_resume_goes_on_and_a_plain_rerun_starts_over(tmp_path, monkeypatch):
    path = tmp_path / "stack.yaml"
    path.write_text(yaml.safe_dump(STACK))
    whole = tmp_path / "whole"
    run_case(load_case(path), whole)
    cut = tmp_path / "cut"
    with monkeypatch.context() as m:
        _stop_after_checkpoints(m, 3)
        with pytest.raises(KeyboardInterrupt):
            run_case(load_case(path), cut)
    r = CliRunner().invoke(app, ["run", str(path), "--out", str(cut), "--resume",
                                 "--no-progress"])
    assert r.exit_code == 0, r.output
    summ = json.loads((cut / "summary.json").read_text())
    assert len(summ["resumed"]) == 1
    _assert_same_run(whole, cut)
    # without --resume the same case is rerun from t = 0 (the claim clears the directory)
    with monkeypatch.context() as m:
        _stop_after_checkpoints(m, 3)
        with pytest.raises(KeyboardInterrupt):
            run_case(load_case(path), cut)
    r = CliRunner().invoke(app, ["run", str(path), "--out", str(cut), "--no-progress"])
    assert r.exit_code == 0, r.output
    assert "resumed" not in json.loads((cut / "summary.json").read_text())


def test_a_sweep_point_resumes_in_the_batch(tmp_path, monkeypatch):
    """dem.batch._run_one, the body of every sweep point (dem sweep, the prediction study,
    studies.prediction.pool), goes on from a restart point of the same case."""
    from dem.batch import run_batch

    case = _case(STACK)
    whole = tmp_path / "whole"
    run_case(case, whole)
    cut = tmp_path / "points" / "cut"
    with monkeypatch.context() as m:
        _stop_after_checkpoints(m, 5)
        with pytest.raises(KeyboardInterrupt):
            run_case(case, cut)
    (rec,) = run_batch([("cut", case)], tmp_path / "points", n_workers=1)
    assert rec["status"] == "ok", rec
    assert len(rec["summary"]["resumed"]) == 1
    _assert_same_run(whole, cut)


def test_dem_sweep_resumes_a_stopped_point_and_says_so(tmp_path, monkeypatch):
    from dem.run.sweep import point_name, sweep_cases

    path = tmp_path / "stack.yaml"
    path.write_text(yaml.safe_dump(STACK))
    out = tmp_path / "sweep"
    ((name, case),) = sweep_cases(load_case(path), [5.0], 1, 0.05)
    assert name == point_name(5.0)
    with monkeypatch.context() as m:
        _stop_after_checkpoints(m, 3)
        with pytest.raises(KeyboardInterrupt):
            run_case(case, out / name)
    r = CliRunner().invoke(app, ["sweep", str(path), "--out", str(out), "--frequencies", "5",
                                 "--cycles", "1", "--margin", "0.05", "--workers", "1"])
    assert r.exit_code == 0, r.output
    assert "5 Hz: ok" in r.output and "resumed at t = " in r.output
    summ = json.loads((out / name / "summary.json").read_text())
    assert summ["status"] == "ok" and len(summ["resumed"]) == 1


def test_a_run_stopped_twice_resumes_twice(tmp_path, monkeypatch):
    case = _case(STACK)
    whole = tmp_path / "whole"
    run_case(case, whole)
    cut = tmp_path / "cut"
    for resume in (False, True):
        with monkeypatch.context() as m:
            _stop_after_checkpoints(m, 2)
            with pytest.raises(KeyboardInterrupt):
                run_case(case, cut, resume=resume)
    res = run_case(case, cut, resume=True)
    first, second = res.summary["resumed"]
    assert first["step"] < second["step"] < res.summary["steps"]
    assert first["wall_seconds_before"] < second["wall_seconds_before"] < \
        res.summary["wall_seconds"]
    _assert_same_run(whole, cut)
