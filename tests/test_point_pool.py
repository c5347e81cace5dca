"""postprocess.point_pool: prediction points run in a process pool (no dask) land in the
directories dem sweep uses, with the case dem sweep would build, so the study takes them as
finished (dem.commands.sweep.finished_point) and merges them into points.json without a rerun."""

from __future__ import annotations

import json

import pytest

from postprocess import point_pool as pp
from postprocess import prediction_study as ps
from tests.test_prediction_study import _repo


def test_parse_points_names_the_bad_item():
    assert pp.parse_points("0:3.2, 9:3.6,") == [(0, 3.2), (9, 3.6)]
    for bad in ("3.2", "a:3.2", "1:2:3", ""):
        with pytest.raises(ps.PredictionInputError, match="--points"):
            pp.parse_points(bad)


def test_points_outside_the_plan_are_refused(tmp_path, capsys):
    _, path = _repo(tmp_path)
    out = tmp_path / "out"
    ps.write_plan(out, ps.make_plan(ps.load_frozen(path), ["model-ii-y"], 2, 50, None))
    for pts, what in (("5:2.8", "seed 5"), ("0:9.9", "9.9 Hz")):
        assert pp.main(["--out", str(out), "--sweep", "model-ii-y", "--points", pts]) == 2
        assert what in capsys.readouterr().err
    assert pp.main(["--out", str(out), "--sweep", "model-x", "--points", "0:2.8"]) == 2
    assert not (out / "runs" / "model-ii-y").exists()      # nothing ran


def test_a_pooled_point_is_taken_by_the_study_without_a_rerun(tmp_path, monkeypatch):
    monkeypatch.setenv("DEM_THREADS", "1")
    _, path = _repo(tmp_path)
    out = tmp_path / "out"
    plan = ps.make_plan(ps.load_frozen(path), ["model-ii-y"], 2, 50, 50)   # 50-step smoke runs
    plan["sweeps"]["model-ii-y"]["frequencies_hz"] = [2.8]
    plan = ps.write_plan(out, plan)
    assert pp.main(["--out", str(out), "--sweep", "model-ii-y", "--points", "1:2.8",
                    "--workers", "1"]) == 0
    d = out / "runs" / "model-ii-y" / "seed-1" / "f2.800Hz"
    summ = json.loads((d / "summary.json").read_text())
    assert summ["status"] == "ok" and summ["step_limit"] == 50
    assert json.loads((d / "case.json").read_text())["imperfections"]["seed"] == 1
    # the analyses of its first N cycles travel with it (50 steps: no shaking, failed rows)
    trunc = json.loads((d / ps.POOL_TRUNCATED).read_text())
    assert sorted(trunc) == sorted(f"{n}" for n in ps.TRUNCATED_CYCLES)
    assert all(r["seed"] == 1 and r["frequency_hz"] == 2.8 for r in trunc.values())
    lines = []
    assert ps.run_sweep_point(out, out / "runs", "model-ii-y", plan, workers=1,
                              log=lines.append, only_seeds=[1]) == "pending"  # seed 0 not run
    assert any("1 point(s) already finished" in ln for ln in lines), lines
    assert json.loads((d / "summary.json").read_text()) == summ          # not run again
    rows = json.loads((out / "model-ii-y" / "points.json").read_text())["rows"]
    assert [(r["seed"], r["run_status"]) for r in rows] == [(0, "pending"), (1, "ok")]
    kept = json.loads(ps.truncated_path(out, "model-ii-y").read_text())["rows"]
    assert [(r["seed"], r["frequency_hz"]) for r in kept["20"]] == [(1, 2.8)]


def test_a_stopped_pool_leaves_no_worker_holding_a_point(tmp_path):
    """SIGTERM to the pool (the device call's ``timeout``) ends its workers with it: the point's
    directory is free again (a second call can resume it), not held by an orphaned worker."""
    import fcntl
    import os
    import signal
    import subprocess
    import sys
    import time

    _, path = _repo(tmp_path)
    out = tmp_path / "out"
    plan = ps.make_plan(ps.load_frozen(path), ["model-ii-y"], 1, 50, 10 ** 6)  # a long run
    plan["sweeps"]["model-ii-y"]["frequencies_hz"] = [2.8]
    ps.write_plan(out, plan)
    env = {**os.environ, "DEM_THREADS": "1", "PYTHONPATH": str(pp.ps.ROOT)}
    proc = subprocess.Popen([sys.executable, "-m", "postprocess.point_pool", "--out", str(out),
                             "--sweep", "model-ii-y", "--points", "0:2.8", "--workers", "1"],
                            cwd=tmp_path, env=env, stderr=subprocess.PIPE, text=True)
    lock = out / "runs" / "model-ii-y" / "seed-0" / "f2.800Hz" / "run.lock"
    deadline = time.monotonic() + 240
    while not lock.exists():                     # the worker has claimed the point
        assert proc.poll() is None and time.monotonic() < deadline, proc.stderr.read()
        time.sleep(0.2)
    time.sleep(1.0)
    proc.send_signal(signal.SIGTERM)
    assert proc.wait(timeout=60) == 1
    assert "stopped by SIGTERM" in proc.stderr.read()
    time.sleep(1.0)
    if lock.exists():                            # a lock file left behind must be stale
        fd = os.open(lock, os.O_RDWR)
        try:
            fcntl.flock(fd, fcntl.LOCK_EX | fcntl.LOCK_NB)   # raises if a worker still holds it
        finally:
            os.close(fd)
