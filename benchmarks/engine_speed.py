"""Engine throughput on the resting 9 x 15 stretcher-bond wall (issue 2), and how it scales.

    python benchmarks/engine_speed.py            # full table (a few minutes)
    python benchmarks/engine_speed.py --quick    # threads/modes on the 142-block wall only

Prints, for 1 and 2 threads and both kernels (serial multi-step, parallel per step):
brick-steps per second (median of --repeats runs of --steps steps, after a warm-up), contact
pairs and points; the kernel compile time cold (empty offline cache) and warm (cache filled);
and, for walls of ~50 / 200 / 800 / 3200 bricks, throughput and the bytes held by the engine's
arrays (to show memory proportional to the number of blocks).  Every figure comes from a fresh
process so the thread count and the cache state are what they say.
"""

from __future__ import annotations

import argparse
import json
import os
import subprocess
import sys
import tempfile
import time

WALLS = {50: (5, 10), 200: (10, 19), 800: (20, 38), 3200: (40, 76)}  # ~bricks: (length, courses)


def _measure(length, courses, mode, steps, repeats):
    """Runs inside the child process."""
    t0 = time.perf_counter()
    import numpy as np

    from dem.builders import build_wall
    from dem.case import Material, SolverSpec
    from dem.engine import Simulation

    scene = build_wall("small", length=length, courses=courses)
    t_import = time.perf_counter() - t0
    sim = Simulation(scene, Material(friction=0.81), SolverSpec(mode=mode))
    g = np.array([0.0, 0.0, -9.81])
    loads = lambda t: (np.tile(g, (len(t), 1)), np.zeros((len(t), 3)))  # noqa: E731
    sim.advance(min(steps, 500), loads)  # warm-up (settling, caches)
    rates = []
    for _ in range(repeats):
        t1 = time.perf_counter()
        sim.advance(steps, loads)
        rates.append(steps * sim.n_blocks / (time.perf_counter() - t1))
    c = sim.contacts
    nbytes = sum(a.nbytes for obj in (sim.model, sim.state, c) for a in vars(obj).values()
                 if hasattr(a, "nbytes"))
    return {
        "blocks": sim.n_blocks, "mode": sim.mode, "pairs": c.n_pairs,
        "contact_points": int(c.npts[: c.n_pairs].sum()), "dt": sim.dt,
        "brick_steps_per_s": float(np.median(rates)), "rates": rates,
        "compile_s": sim.compile_seconds, "import_s": t_import, "array_bytes": int(nbytes),
    }


def run_child(length, courses, mode, threads, steps, repeats, cache_dir=None):
    env = dict(os.environ, DEM_THREADS=str(threads))
    if cache_dir is not None:
        env["TI_OFFLINE_CACHE_FILE_PATH"] = cache_dir
    code = (f"import json, sys; sys.path.insert(0, {os.path.dirname(__file__)!r}); "
            f"from engine_speed import _measure; "
            f"print('RESULT', json.dumps(_measure({length}, {courses}, {mode!r}, {steps}, "
            f"{repeats})))")
    out = subprocess.run([sys.executable, "-c", code], env=env, capture_output=True, text=True)
    for line in out.stdout.splitlines():
        if line.startswith("RESULT "):
            return json.loads(line[7:])
    raise RuntimeError(out.stderr[-2000:])


def main():
    ap = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawTextHelpFormatter)
    ap.add_argument("--steps", type=int, default=3000)
    ap.add_argument("--repeats", type=int, default=5)
    ap.add_argument("--quick", action="store_true")
    args = ap.parse_args()
    print(f"# engine_speed  python {sys.version.split()[0]}, {os.cpu_count()} cores, "
          f"{time.strftime('%Y-%m-%d %H:%M')}")
    print("\n## 9 x 15 stretcher wall at rest (142 blocks)")
    print("| threads | kernel | brick-steps/s (median) | min - max | pairs | contact points |")
    print("|---|---|---|---|---|---|")
    for threads in (1, 2):
        for mode in ("serial", "parallel"):
            r = run_child(9, 15, mode, threads, args.steps, args.repeats)
            print(f"| {threads} | {mode} | {r['brick_steps_per_s']:.3g} | "
                  f"{min(r['rates']):.3g} - {max(r['rates']):.3g} | {r['pairs']} | "
                  f"{r['contact_points']} |", flush=True)
    with tempfile.TemporaryDirectory() as cache:
        cold = run_child(9, 15, "serial", 2, 10, 1, cache)
        warm = run_child(9, 15, "serial", 2, 10, 1, cache)
    print(f"\nkernel compile (serial kernel + probes): cold {cold['compile_s']:.1f} s, "
          f"warm (offline cache) {warm['compile_s']:.1f} s; importing the package "
          f"{warm['import_s']:.1f} s")
    if args.quick:
        return
    print("\n## Scaling with wall size (2 threads; auto picks the kernel)")
    print("| bricks | kernel | brick-steps/s | pairs | engine arrays (MB) | bytes/block |")
    print("|---|---|---|---|---|---|")
    for target, (length, courses) in WALLS.items():
        steps = max(100, args.steps * 150 // target)
        for mode in ("serial", "parallel"):
            r = run_child(length, courses, mode, 2, steps, 3)
            print(f"| {r['blocks']} | {mode} | {r['brick_steps_per_s']:.3g} | {r['pairs']} | "
                  f"{r['array_bytes'] / 1e6:.2f} | {r['array_bytes'] / r['blocks']:.0f} |",
                  flush=True)


if __name__ == "__main__":
    main()
