"""studies.prediction.pool (`python -m studies point-pool`): prediction points run in a process pool (no dask) land in the
directories dem sweep uses, with the case dem sweep would build, so the study takes them as
finished (dem_cli.commands.sweep.finished_point) and merges them into points.json without a rerun."""

from __future__ import annotations

import json
from pathlib import Path

import pytest

from studies.prediction import pool as pp
from studies.prediction import cycles as cyc
from studies.prediction import plan as pl
from studies.prediction import protocol as proto
from studies.prediction import run as runner
from tests.test_prediction_study import frozen_repo


def test_parse_points_names_the_bad_item():
    assert pp.parse_points("0:3.2, 9:3.6,") == [(0, 3.2), (9, 3.6)]
    for bad in ("3.2", "a:3.2", "1:2:3", ""):
        with pytest.raises(proto.PredictionInputError, match="--points"):
            pp.parse_points(bad)


def test_points_outside_the_plan_are_refused(tmp_path, capsys):
    _, path = frozen_repo(tmp_path)
    out = tmp_path / "out"
    pl.write_plan(out, pl.make_plan(pl.load_frozen(path), ["model-ii-y"], 2, 50, None))
    for pts, what in (("5:2.8", "seed 5"), ("0:9.9", "9.9 Hz")):
        assert pp.main(["--out", str(out), "--sweep", "model-ii-y", "--points", pts]) == 2
        assert what in capsys.readouterr().err
    assert pp.main(["--out", str(out), "--sweep", "model-x", "--points", "0:2.8"]) == 2
    assert not (out / "runs" / "model-ii-y").exists()      # nothing ran


def test_a_pooled_point_is_taken_by_the_study_without_a_rerun(tmp_path, monkeypatch):
    monkeypatch.setenv("DEM_THREADS", "1")
    _, path = frozen_repo(tmp_path)
    out = tmp_path / "out"
    plan = pl.make_plan(pl.load_frozen(path), ["model-ii-y"], 2, 50, 50)   # 50-step smoke runs
    plan["sweeps"]["model-ii-y"]["frequencies_hz"] = [2.8]
    plan = pl.write_plan(out, plan)
    assert pp.main(["--out", str(out), "--sweep", "model-ii-y", "--points", "1:2.8",
                    "--workers", "1"]) == 0
    d = out / "runs" / "model-ii-y" / "seed-1" / "f2.800Hz"
    summ = json.loads((d / "summary.json").read_text())
    assert summ["status"] == "ok" and summ["step_limit"] == 50
    assert json.loads((d / "case.json").read_text())["imperfections"]["seed"] == 1
    # the analyses of its first N cycles travel with it (50 steps: no shaking, failed rows)
    trunc = json.loads((d / cyc.POOL_TRUNCATED).read_text())
    assert sorted(trunc) == sorted(f"{n}" for n in proto.TRUNCATED_CYCLES)
    assert all(r["seed"] == 1 and r["frequency_hz"] == 2.8 for r in trunc.values())
    lines = []
    assert runner.run_sweep_point(out, out / "runs", "model-ii-y", plan, workers=1,
                              log=lines.append, only_seeds=[1]) == "pending"  # seed 0 not run
    assert any("1 point(s) already finished" in ln for ln in lines), lines
    assert json.loads((d / "summary.json").read_text()) == summ          # not run again
    rows = json.loads((out / "model-ii-y" / "points.json").read_text())["rows"]
    assert [(r["seed"], r["run_status"]) for r in rows] == [(0, "pending"), (1, "ok")]
    kept = json.loads(cyc.truncated_path(out, "model-ii-y").read_text())["rows"]
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

    _, path = frozen_repo(tmp_path)
    out = tmp_path / "out"
    plan = pl.make_plan(pl.load_frozen(path), ["model-ii-y"], 1, 50, 10 ** 6)  # a long run
    plan["sweeps"]["model-ii-y"]["frequencies_hz"] = [2.8]
    pl.write_plan(out, plan)
    env = {**os.environ, "DEM_THREADS": "1", "PYTHONPATH": str(pp.ROOT)}
    proc = subprocess.Popen([sys.executable, "-m", "studies", "point-pool", "--out", str(out),
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


def _sleep_task(item) -> float:
    """A stand-in point for each_in_own_process (module level: a spawned child imports it):
    sleeps ``item`` seconds, or ``item[0]`` seconds after writing its pid to ``item[1]``."""
    import os
    import time

    seconds = item
    if isinstance(item, tuple):
        seconds, pidfile = item
        Path(pidfile).write_text(str(os.getpid()))
    if seconds < 0:
        raise ValueError("a failing point")
    time.sleep(seconds)
    return seconds


def test_each_point_runs_in_its_own_process_and_failures_are_reported():
    got = []
    pp.each_in_own_process(_sleep_task, [0.1, -1.0, 0.2], 2, got.append,
                           failed=lambda item, err: ("failed", item, err))
    assert sorted(r for r in got if not isinstance(r, tuple)) == [0.1, 0.2]
    (bad,) = [r for r in got if isinstance(r, tuple)]
    assert bad[:2] == ("failed", -1.0) and "ValueError: a failing point" in bad[2]


def test_a_pool_stopped_after_some_points_finished_ends_at_once(tmp_path):
    """multiprocessing.Pool's terminate() hangs for ever once a worker is idle, i.e. once
    points have finished and fewer are left than workers (a borrowed machine lost nine finished
    points to it).  Here two quick points finish, SIGTERM comes while a long one runs: the call
    must end within seconds, the long point's process with it."""
    import os
    import signal
    import subprocess
    import sys
    import time

    pidfile = tmp_path / "long.pid"
    script = (
        "import sys, time\n"
        "from dem.signals import stop_on_signals\n"
        "from studies.prediction.pool import each_in_own_process\n"
        "from tests.test_point_pool import _sleep_task\n"
        "def show(r): print('done', r, flush=True)\n"
        "try:\n"
        "    with stop_on_signals():\n"
        f"        each_in_own_process(_sleep_task, [0.1, 0.1, (120.0, {str(pidfile)!r})], 3,\n"
        "                            show, lambda i, e: e)\n"
        "except KeyboardInterrupt:\n"
        "    print('stopped', flush=True)\n")
    env = {**os.environ, "PYTHONPATH": str(pp.ROOT)}
    proc = subprocess.Popen([sys.executable, "-c", script], cwd=tmp_path, env=env,
                            stdout=subprocess.PIPE, text=True)
    assert proc.stdout.readline().startswith("done 0.1")
    assert proc.stdout.readline().startswith("done 0.1")
    deadline = time.monotonic() + 60
    while not pidfile.is_file() or not pidfile.read_text():     # the long point has started
        assert time.monotonic() < deadline
        time.sleep(0.1)
    t = time.monotonic()
    proc.send_signal(signal.SIGTERM)
    assert proc.wait(timeout=60) == 0
    assert proc.stdout.read().strip() == "stopped"
    assert time.monotonic() - t < 30             # the grace; the 120 s point did not run out
    long_pid = int(pidfile.read_text())
    with pytest.raises(ProcessLookupError):      # the long point's process has ended too
        os.kill(long_pid, 0)
