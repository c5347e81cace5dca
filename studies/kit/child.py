"""The studies' way of running a ``dem`` command as a child process (the calibration,
prediction and other studies): this checkout's package (not another one an editable install points at), one
Taichi thread, its output relayed line by line, the CPU seconds (user + system) of its process
tree measured, and a clean stop: SIGTERM or SIGINT to the study is passed on to the child, which
stops like Ctrl-C and keeps what finished (``dem ensemble`` / ``dem sweep`` resume from it), and
:func:`stopped` tells the study's loop to start nothing new.
"""

from __future__ import annotations

import os
import resource
import signal
import subprocess
import sys
import time
from studies.kit.provenance import ROOT

_CHILDREN: list[subprocess.Popen] = []
_STOP = [False]


def _on_signal(signum, _frame):
    _STOP[0] = True
    for p in _CHILDREN:
        if p.poll() is None:
            p.send_signal(signal.SIGTERM)


def install_signal_handlers() -> None:
    """SIGTERM and SIGINT stop the running child cleanly and set :func:`stopped`."""
    signal.signal(signal.SIGTERM, _on_signal)
    signal.signal(signal.SIGINT, _on_signal)


def stopped() -> bool:
    """Whether a stop signal (or :func:`request_stop`) came: start no new child."""
    return _STOP[0]


def request_stop() -> None:
    _STOP[0] = True


def _children_cpu() -> float:
    """CPU seconds (user + system) of the terminated, waited-for descendants of this process."""
    r = resource.getrusage(resource.RUSAGE_CHILDREN)
    return r.ru_utime + r.ru_stime


def run_dem(args: list[str], log) -> tuple[int, float, float]:
    """Run ``dem ARGS`` in a child process with DEM_THREADS=1 and this checkout first on the
    path, passing each output line to ``log``.  Returns (exit code, CPU s of the child's process
    tree, wall-clock s)."""
    cmd = [sys.executable, "-c",
           "import sys; sys.argv[0] = 'dem'; from dem_cli.app import app; app()", *args]
    env = {**os.environ, "DEM_THREADS": "1",
           "PYTHONPATH": os.pathsep.join([str(ROOT), *filter(None, [os.environ.get(
               "PYTHONPATH")])])}
    cpu0, t0 = _children_cpu(), time.perf_counter()
    proc = subprocess.Popen(cmd, env=env, cwd=ROOT, stdout=subprocess.PIPE,
                            stderr=subprocess.STDOUT, text=True)
    _CHILDREN.append(proc)
    try:
        for line in proc.stdout:
            log("    " + line.rstrip())
        rc = proc.wait()
    finally:
        _CHILDREN.remove(proc)
    return rc, _children_cpu() - cpu0, time.perf_counter() - t0
