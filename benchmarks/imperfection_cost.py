"""What the imperfect-joint code costs the engine, perfect and imperfect.

    python benchmarks/imperfection_cost.py --before /tmp/tree_before [--repeats 5]

where /tmp/tree_before holds the code before the change (``git archive 116485c dem | tar -x -C
/tmp/tree_before``).  On the resting 9 x 15 small-brick wall (142 blocks, one thread, serial
kernel) it runs, interleaved so that the machine's load hits all alike, --repeats fresh processes
of each of:

  before     the perfect wall on the code before the change (--before)
  perfect    the perfect wall on this code (the same trajectory, bit for bit: printed)
  warped     the wall with bed_unevenness 0.1 mm and arris 0.5 mm (settled first, then timed)

and prints the median CPU time per brick-step of each and the ratios to ``before``.

    python benchmarks/imperfection_cost.py --overlap [--before TREE] [--repeats 5] [--tol 1e-7]

times the warped kernels' overlap reuse (dem.engine.coherence
.set_overlap_reuse) on the resting 9 x 15 wall with planar 0.1 mm beds (seed 0): one process
builds and settles the wall once, then alternates, --repeats times, runs of --steps steps from
that same snapshot with the reuse off (tol 0, today's path) and on (--tol), so the ratio is
measured on the same machine state; it prints the median CPU time per brick-step of each, their
ratio, the share of pairs whose overlap was kept, and the largest difference of the final
positions.  With --before, a fresh process on the code in TREE runs the same wall without the
option and the final positions of the reuse-off run are compared with it bit for bit.

    python benchmarks/imperfection_cost.py --model-ii [--repeats 3] [--seconds 0.2]

times the as-built box models (docs/imperfections.md, "As built") against today's: Model II
shaken along y at 2.8 Hz, 1.53 m/s2 (cases/shake/model-ii/group-3-y-1.53.yaml), serial, one
thread, each variant in a fresh process, interleaved --repeats times: ``today`` (interlocked,
no gaps), ``corner gaps`` (imperfections.corner_gap 1.0 +- 0.5 mm, seed 0, as
cases/shake/as-built/), ``unbonded`` (box_model.corners: unbonded).  The gapped model is
settled first, as a run does (not timed); then --seconds of shaking from t = 0 are timed.
Prints the median CPU seconds per simulated second, the time step and the contact pairs.
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


OVERLAP_CHILD = r"""
import json, sys, time
import numpy as np
from dem.case import parse_case
from dem.run.build import build
from dem.run.settle import settle
steps, repeats, tol, with_reuse = int(sys.argv[1]), int(sys.argv[2]), float(sys.argv[3]), \
    sys.argv[4] == "1"
data = {"name": "wall", "scene": {"wall": {"brick": "small", "length": 9, "courses": 15}},
        "material": {"friction": 0.81}, "run": {"duration": 1.0},
        "solver": {"threads": 1, "mode": "serial"},
        "imperfections": {"bed_unevenness": 1e-4, "face_shape": "planar", "seed": 0}}
b = build(parse_case(data))
sim = b.sim
g = b.loading.gravity(np.array([0.0]))[0]
loads = lambda t: (np.tile(g, (len(t), 1)), np.zeros((len(t), 3)))
settle(sim, b.loading, 0.0)
snap = sim.snapshot()
res = {"n_pairs": sim.contacts.n_pairs}
tols = (0.0, tol) if with_reuse else (0.0,)
times = {str(t): [] for t in tols}
for r in range(repeats):
    for t in tols:
        sim.restore(snap)
        if with_reuse:
            from dem.engine import coherence
            coherence.set_overlap_reuse(sim.contacts, t)
        sim.advance(200, loads)  # warm (and the first keep)
        c0 = time.process_time()
        sim.advance(steps, loads)
        times[str(t)].append(1e9 * (time.process_time() - c0) / (steps * sim.n_blocks))
        res["pos_" + str(t)] = sim.state.pos[:sim.n_blocks].tolist()
        res["kept_" + str(t)] = int((sim.contacts.patch_shape[:sim.contacts.n_pairs, 0, 3]
                                     < 0).sum())
        res["touching_" + str(t)] = int((sim.contacts.npts[:sim.contacts.n_pairs] > 0).sum())
res["times"] = times
print(json.dumps(res))
"""


MODEL_II_CHILD = r"""
import json, sys, time
import numpy as np
from dem.case import parse_case
from dem.run.build import build
imp, box, seconds = json.loads(sys.argv[1]), json.loads(sys.argv[2]), float(sys.argv[3])
data = {"name": "model-ii", "scene": {"box_model": {"model": "II", **box}},
        "material": {"friction": 0.81, "base_friction": 1.5},
        "loading": {"type": "shake", "direction": [0, 1, 0], "frequency": 2.8,
                    "peak_acceleration": 1.53, "cycles": 50},
        "run": {"duration": 18.86}, "solver": {"threads": 1, "mode": "serial"}}
if imp:
    data["imperfections"] = imp
case = parse_case(data)
b = build(case)
sim = b.sim
if case.imperfections.any():
    from dem.run.settle import settle
    settle(sim, b.loading, case.solver.local_damping)
n = int(round(seconds / sim.dt))
sim.advance(200, b.loading)  # warm
c0 = time.process_time()
sim.advance(n, b.loading)
cpu = time.process_time() - c0
print(json.dumps({"cpu_per_sim_s": cpu / (n * sim.dt), "dt": sim.dt, "steps": n,
                  "n_pairs": int(sim.contacts.n_pairs), "n_blocks": sim.n_blocks}))
"""

MODEL_II_VARIANTS = {"today": ({}, {}),
                     "corner gaps 1.0 +- 0.5 mm": (
                         {"corner_gap": {"mean": 1e-3, "scatter": 5e-4}, "seed": 0}, {}),
                     "unbonded corners": ({}, {"corners": "unbonded"})}


def model_ii(args) -> None:
    """The --model-ii measurement (module docstring)."""
    env = dict(os.environ, PYTHONPATH=str(ROOT), DEM_THREADS="1")
    runs: dict[str, list[dict]] = {k: [] for k in MODEL_II_VARIANTS}
    for _ in range(args.repeats):
        for name, (imp, box) in MODEL_II_VARIANTS.items():
            out = subprocess.run([sys.executable, "-c", MODEL_II_CHILD, json.dumps(imp),
                                  json.dumps(box), str(args.seconds)], cwd=ROOT, env=env,
                                 capture_output=True, text=True, check=True)
            runs[name].append(json.loads(out.stdout.strip().splitlines()[-1]))
    base = statistics.median(r["cpu_per_sim_s"] for r in runs["today"])
    print(f"Model II, y, 2.8 Hz, 1.53 m/s2; serial, 1 thread; {args.seconds} s of shaking "
          f"timed per run, {args.repeats} runs each, fresh processes, interleaved (CPU time):")
    print("| model | blocks | dt (s) | contact pairs | CPU s per simulated s (median) | min | "
          "ratio to today |")
    print("|---|---|---|---|---|---|---|")
    for name, rs in runs.items():
        v = [r["cpu_per_sim_s"] for r in rs]
        med = statistics.median(v)
        print(f"| {name} | {rs[0]['n_blocks']} | {rs[0]['dt']:.3g} | {rs[0]['n_pairs']} | "
              f"{med:.1f} | {min(v):.1f} | {med / base:.3f} |")


def overlap(args) -> None:
    """The --overlap measurement (module docstring)."""
    import numpy as np

    def child(tree: Path, with_reuse: bool) -> dict:
        env = dict(os.environ, PYTHONPATH=str(tree), DEM_THREADS="1")
        out = subprocess.run([sys.executable, "-c", OVERLAP_CHILD, str(args.steps),
                              str(args.repeats), str(args.tol), "1" if with_reuse else "0"],
                             cwd=tree, env=env, capture_output=True, text=True, check=True)
        return json.loads(out.stdout.strip().splitlines()[-1])

    r = child(ROOT, True)
    off, on = (statistics.median(r["times"][k]) for k in ("0.0", str(args.tol)))
    print(f"resting 9 x 15 wall, planar 0.1 mm beds (seed 0), settled; serial, 1 thread, "
          f"{args.steps} steps per run, {args.repeats} runs each, alternated in one process "
          f"(CPU time per brick-step):")
    print("| overlap reuse | ns per brick-step (median) | min | pairs kept / touching |")
    print("|---|---|---|---|")
    for name, k in (("off (today)", "0.0"), (f"on, tol {args.tol:g} m", str(args.tol))):
        v = r["times"][k]
        print(f"| {name} | {statistics.median(v):.0f} | {min(v):.0f} | {r['kept_' + k]} / "
              f"{r['touching_' + k]} |")
    print(f"ratio on / off: {on / off:.3f} (speed-up {off / on:.3f}x); pairs listed "
          f"{r['n_pairs']}")
    dx = np.abs(np.array(r["pos_0.0"]) - np.array(r["pos_" + str(args.tol)])).max()
    print(f"largest final position difference on / off: {dx:.3e} m")
    if args.before is not None:
        b = child(args.before, False)
        same = b["pos_0.0"] == r["pos_0.0"]
        print(f"reuse off: final positions identical to the code in {args.before}: {same}"
              + ("" if same else f" (largest difference "
                 f"{np.abs(np.array(b['pos_0.0']) - np.array(r['pos_0.0'])).max():.3e} m)"))
        print(f"that code, same wall: {statistics.median(b['times']['0.0']):.0f} ns per "
              f"brick-step (median; another process)")


def run(tree: Path, imp: dict, steps: int) -> dict:
    env = dict(os.environ, PYTHONPATH=str(tree), DEM_THREADS="1")
    out = subprocess.run([sys.executable, "-c", CHILD, json.dumps(imp), str(steps)], cwd=tree,
                         env=env, capture_output=True, text=True, check=True)
    return json.loads(out.stdout.strip().splitlines()[-1])


def main() -> None:
    ap = argparse.ArgumentParser()
    ap.add_argument("--before", type=Path)
    ap.add_argument("--repeats", type=int, default=5)
    ap.add_argument("--steps", type=int, default=20000)
    ap.add_argument("--overlap", action="store_true",
                    help="time the warped kernels' overlap reuse")
    ap.add_argument("--tol", type=float, default=1e-7, help="overlap reuse tolerance, m")
    ap.add_argument("--model-ii", action="store_true",
                    help="time Model II with corner gaps and unbonded corners against today's")
    ap.add_argument("--seconds", type=float, default=0.2,
                    help="--model-ii: simulated seconds of shaking timed per run")
    args = ap.parse_args()
    if args.model_ii:
        model_ii(args)
        return
    if args.overlap:
        overlap(args)
        return
    if args.before is None:
        ap.error("--before is required (without --overlap)")
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
