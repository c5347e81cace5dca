"""What the imperfect-joint code (issue 12) costs the engine, perfect and imperfect.

    python benchmarks/imperfection_cost.py --before /tmp/tree_before [--repeats 5]

where /tmp/tree_before holds the code before the change (``git archive 116485c dem | tar -x -C
/tmp/tree_before``).  On the resting 9 x 15 small-brick wall (142 blocks, one thread, serial
kernel) it runs, interleaved so that the machine's load hits all alike, --repeats fresh processes
of each of:

  before     the perfect wall on the code before issue 12
  perfect    the perfect wall on this code (the same trajectory, bit for bit: printed)
  warped     the wall with bed_unevenness 0.1 mm and arris 0.5 mm (settled first, then timed)

and prints the median CPU time per brick-step of each and the ratios to ``before``.
"""

from __future__ import annotations

import argparse
import json
import os
import statistics
import subprocess
import sys
from pathlib import Path

ROOT = Path(__file__).resolve().parents[1]

CHILD = r"""
import json, sys, time
import numpy as np
from dem.case import parse_case
from dem.run.build import build
imp = json.loads(sys.argv[1]); steps = int(sys.argv[2])
data = {"name": "wall", "scene": {"wall": {"brick": "small", "length": 9, "courses": 15}},
        "material": {"friction": 0.81}, "run": {"duration": 1.0},
        "solver": {"threads": 1, "mode": "serial"}}
if imp:
    data["imperfections"] = imp
case = parse_case(data)
b = build(case)
sim = b.sim
g = b.loading.gravity(np.array([0.0]))[0]
loads = lambda t: (np.tile(g, (len(t), 1)), np.zeros((len(t), 3)))
if imp:
    from dem.run.settle import settle
    settle(sim, b.loading, 0.0)
sim.advance(500, loads)  # warm
c0 = time.process_time()
sim.advance(steps, loads)
cpu = time.process_time() - c0
print(json.dumps({"ns_per_brick_step": 1e9 * cpu / (steps * sim.n_blocks),
                  "pos_hex": float(sim.state.pos[:sim.n_blocks].sum()).hex()}))
"""


def run(tree: Path, imp: dict, steps: int) -> dict:
    env = dict(os.environ, PYTHONPATH=str(tree), DEM_THREADS="1")
    out = subprocess.run([sys.executable, "-c", CHILD, json.dumps(imp), str(steps)], cwd=tree,
                         env=env, capture_output=True, text=True, check=True)
    return json.loads(out.stdout.strip().splitlines()[-1])


def main() -> None:
    ap = argparse.ArgumentParser()
    ap.add_argument("--before", type=Path, required=True)
    ap.add_argument("--repeats", type=int, default=5)
    ap.add_argument("--steps", type=int, default=20000)
    args = ap.parse_args()
    warped = {"bed_unevenness": 1e-4, "arris": 5e-4, "seed": 0}
    runs = {"before": [], "perfect": [], "warped": []}
    hexes = {"before": set(), "perfect": set()}
    for _ in range(args.repeats):
        for name, tree, imp in (("before", args.before, {}), ("perfect", ROOT, {}),
                                ("warped", ROOT, warped)):
            r = run(tree, imp, args.steps)
            runs[name].append(r["ns_per_brick_step"])
            if name in hexes:
                hexes[name].add(r["pos_hex"])
    base = statistics.median(runs["before"])
    print(f"resting 9 x 15 wall (142 blocks), serial, 1 thread, {args.steps} steps, "
          f"{args.repeats} runs each (CPU time):")
    print("| code | ns per brick-step (median) | min | ratio to before |")
    print("|---|---|---|---|")
    for name, vals in runs.items():
        med = statistics.median(vals)
        print(f"| {name} | {med:.0f} | {min(vals):.0f} | {med / base:.3f} |")
    same = hexes["before"] == hexes["perfect"] and len(hexes["before"]) == 1
    print(f"perfect wall: final positions identical to the code before: {same}")


if __name__ == "__main__":
    main()
