"""The cold compile of the device's stepping kernel against its steps a launch.

    python benchmarks/device_compile.py [--steps-per-launch 1,2,4]

For each U: a fresh process with an empty private Taichi cache (TI_OFFLINE_CACHE_FILE_PATH in a
temporary directory) builds an engine of two small walls (tests/test_engine_batch.wall) on device
arrays at U steps a launch (dem.engine.step_device) and prints the process's CPU seconds of the
construction (its warm-up compiles every kernel the engine uses, the stepping kernel the largest)
and the engine's own compile_seconds (wall).  Why: each step of a launch is its own code, and
Taichi's whole-kernel passes grow faster than the kernel (benchmarks/RESULTS.md, "The device's
broad phase in the stepping kernel's launch").  One JSON line per U.
"""

from __future__ import annotations

import argparse
import json
import os
import subprocess
import sys
import tempfile
from pathlib import Path

ROOT = Path(__file__).resolve().parents[1]

CHILD = r"""
import json, os, time
from dem import ti_runtime
ti_runtime.init(threads=1)
from dem.engine.simulation import Engine
from tests.test_engine_batch import JOINTS, options, wall
t = time.process_time()
e = Engine([wall(), wall()], JOINTS, options(), device_arrays=True,
           steps_per_launch=int(os.environ["U"]))
print(json.dumps({"steps_per_launch": int(os.environ["U"]),
                  "construction_cpu_s": time.process_time() - t,
                  "engine_compile_wall_s": e.compile_seconds}))
"""


def main() -> int:
    ap = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    ap.add_argument("--steps-per-launch", default="1,2,4")
    args = ap.parse_args()
    for u in args.steps_per_launch.split(","):
        with tempfile.TemporaryDirectory() as cache:
            env = dict(os.environ, U=u, TI_OFFLINE_CACHE_FILE_PATH=cache, PYTHONPATH=str(ROOT))
            out = subprocess.run([sys.executable, "-c", CHILD], env=env, cwd=ROOT,
                                 capture_output=True, text=True)
        lines = out.stdout.strip().splitlines()
        if out.returncode != 0 or not lines:
            print(json.dumps({"steps_per_launch": int(u), "error": out.stderr[-2000:]}))
            continue
        print(lines[-1], flush=True)
    return 0


if __name__ == "__main__":
    sys.exit(main())
