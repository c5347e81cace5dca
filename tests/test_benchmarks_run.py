"""The benchmark scripts still run against today's engine (their shortest modes).

A benchmark calls the engine's kernels and containers directly, so a change of a kernel's
signature or of an array's shape breaks it without breaking any other test (a scene axis added
to Control.loads and a ``batched`` flag to the stages broke ``engine_speed.py --stages`` /
``--launch``, and nothing else noticed).  Each case runs the
script as a user would (a fresh interpreter) and looks for a figure it prints.  Slow (kernel
compiles in fresh processes, ~3-5 min on the 2-core VM): ``pytest -m slow
tests/test_benchmarks_run.py``.  Timings are not judged here (benchmarks/RESULTS.md)."""

from __future__ import annotations

import os
import subprocess
import sys
from pathlib import Path

import pytest

ROOT = Path(__file__).resolve().parents[1]

#: (script and arguments, a piece of text its output must hold)
RUNS = [
    (["engine_speed.py", "--stages", "--repeats", "1"], "| serial step |"),
    (["engine_speed.py", "--stages", "--imperfections", "1e-4", "--face-shape", "planar",
      "--repeats", "1"], "touching face pairs whole"),
    (["engine_speed.py", "--launch", "--repeats", "1"], "| serial, cached launch |"),
    (["engine_speed.py", "--scaling", "--threads", "1", "--sizes", "142", "--steps", "100",
      "--repeats", "1"], "| 142 |"),
    (["batch_speed.py", "cpu", "--ks", "1,2", "--steps", "50", "--repeats", "1", "--threads",
      "1", "--error"], '"error_vs_alone"'),
    (["batch_speed.py", "lone", "--steps", "50", "--repeats", "1"], '"brick_steps_per_s"'),
    (["startup_time.py", "--repeat", "1"], "Simulation.compile_seconds"),
    (["rocking_speed.py", "--repeat", "1"], "50-cycle rocking run"),
    (["checkpoint_cost.py", "--duration", "0.3", "--repeats", "1", "--batch", "1,64"],
     "| 64 |"),
    (["engine_branches.py"], "device or not:"),
    (["cpu_batch.py", "--engine", "--ks", "2", "--steps", "50", "--repeats", "1"],
     '"batch_over_lone"'),
    (["host_share.py", "--ks", "2", "--steps", "300", "--repeats", "1", "--phases", "shaking"],
     '"window_stage_ms_per_chunk"'),
    (["host_share.py", "--launch", "--ks", "2"], '"python_per_launch_after_64MB_sweep_us"'),
    (["graph_launch.py", "--args", "4", "--dispatches", "2"], '"graph_per_dispatch_us"'),
]


@pytest.mark.slow
@pytest.mark.parametrize("args, expected", RUNS, ids=[" ".join(a[:2]) for a, _ in RUNS])
def test_benchmark_runs(args, expected):
    res = subprocess.run([sys.executable, str(ROOT / "benchmarks" / args[0]), *args[1:]],
                         cwd=ROOT, capture_output=True, text=True, timeout=900)
    assert res.returncode == 0, res.stderr[-3000:]
    assert expected in res.stdout, res.stdout[-3000:]


def test_the_gpu_check_dry_run_imports_what_it_runs_and_prints_its_plan(tmp_path):
    """tools/device/gpu_batch_check.py --dry-run on the CPU: every import of its parts, the
    case of a realisation, and its plan (the K's, the profile, the GPU-vs-CPU realisations);
    nothing runs and nothing is written."""
    out = tmp_path / "out"
    env = dict(os.environ, ARCH="cpu", OUT=str(out), KS="1,16,64,100", R="4", CYCLES="3")
    res = subprocess.run([sys.executable, str(ROOT / "tools/device/gpu_batch_check.py"),
                          "--dry-run"], cwd=ROOT, capture_output=True, text=True, timeout=300,
                         env=env)
    assert res.returncode == 0, res.stderr[-3000:]
    for text in ("imports fine", "--ks 1,16,64,100", "--profile", "part 1 GPU",
                 "part 1 CPU: 4 realisations", "3 cycles"):
        assert text in res.stdout, (text, res.stdout)
    assert not out.exists()
