"""``dem ensemble`` on a real dask cluster: a ``dask scheduler`` and two
``dask worker`` processes on localhost; one worker is killed after the first realisation lands.
Every realisation must still finish (dask reschedules the tasks the dead worker held on the other
one) and give what a serial run of the same seeds gives, bit for bit."""

from __future__ import annotations

import json
import os
import signal
import socket
import subprocess
import sys
import time
from pathlib import Path

import numpy as np
import pytest

from tests.test_ensemble import stack_case

DASK = Path(sys.executable).with_name("dask")
DEM = [sys.executable, "-m", "dem_cli"]


def _free_port() -> int:
    with socket.socket() as s:
        s.bind(("127.0.0.1", 0))
        return s.getsockname()[1]


def _start(cmd, log: Path) -> subprocess.Popen:
    env = dict(os.environ, DEM_THREADS="1")
    return subprocess.Popen(cmd, stdout=log.open("w"), stderr=subprocess.STDOUT, env=env,
                            start_new_session=True)


def _stop(proc: subprocess.Popen) -> None:
    if proc.poll() is None:
        os.killpg(proc.pid, signal.SIGKILL)
    proc.wait(timeout=30)


def _landed(out: Path) -> int:
    try:
        data = json.loads((out / "ensemble.json").read_text())
    except (OSError, ValueError):
        return 0
    return sum(1 for r in data["realisations"] if r["status"] == "ok")


@pytest.mark.skipif(not DASK.exists(), reason="the dask command line is not installed")
@pytest.mark.slow
def test_an_ensemble_survives_a_killed_worker_and_equals_the_serial_run(tmp_path):
    case = stack_case(tmp_path)
    port = _free_port()
    address = f"tcp://127.0.0.1:{port}"
    procs = []
    try:
        procs.append(_start([str(DASK), "scheduler", "--host", "127.0.0.1", "--port", str(port),
                             "--no-dashboard"], tmp_path / "scheduler.log"))
        time.sleep(2.0)
        workers = [_start([str(DASK), "worker", address, "--nworkers", "1", "--nthreads", "1",
                           "--no-dashboard"], tmp_path / f"worker{k}.log") for k in range(2)]
        procs += workers
        out = tmp_path / "cluster"
        ens = _start([*DEM, "ensemble", str(case), "--out", str(out), "--realisations", "4",
                      "--seed", "10", "--scheduler", address], tmp_path / "ensemble.log")
        procs.append(ens)
        deadline = time.time() + 240
        while _landed(out) < 1 and ens.poll() is None and time.time() < deadline:
            time.sleep(0.2)
        assert _landed(out) >= 1, (tmp_path / "ensemble.log").read_text()
        killed_after = _landed(out)
        _stop(workers[0])  # in the middle: the other realisations are queued or running
        assert ens.wait(timeout=max(1.0, deadline - time.time())) == 0, \
            (tmp_path / "ensemble.log").read_text()
    finally:
        for p in reversed(procs):
            _stop(p)
    assert killed_after < 4
    serial = tmp_path / "serial"
    res = subprocess.run([*DEM, "ensemble", str(case), "--out", str(serial), "--realisations",
                          "4", "--seed", "10", "--workers", "1"], capture_output=True, text=True,
                         env=dict(os.environ, DEM_THREADS="1"))
    assert res.returncode == 0, res.stderr
    a = json.loads((out / "ensemble.json").read_text())
    b = json.loads((serial / "ensemble.json").read_text())
    assert [r["status"] for r in a["realisations"]] == ["ok"] * 4
    assert [r["lambda"] for r in a["realisations"]] == [r["lambda"] for r in b["realisations"]]
    for seed in range(10, 14):
        fa = np.load(out / f"seed-{seed}" / "frames.npz")
        fb = np.load(serial / f"seed-{seed}" / "frames.npz")
        assert np.array_equal(fa["pos"], fb["pos"]) and np.array_equal(fa["quat"], fb["quat"])
