"""Start-up cost of a short run: what a fresh process pays before and around its first steps.

Why: with every kernel in Taichi's offline cache a process
still runs Taichi's Python front end (AST transform of each kernel it calls) and the first
launch.  This script runs ``CHILD`` in a fresh interpreter ``--repeat`` times and prints, per
phase, the median process CPU time (user + system, s; the 2-core test machine is shared, CPU
time is steadier than wall time) and wall time:

    import       import dem.engine and the case machinery
    build        read the case, build the scene and the Simulation (ti.init, kernels compiled
                 or loaded from the offline cache, first launch, overlap probe, dt)
    advance      the first ``--duration`` s of simulated time (0.02 s: ~500 steps of the wall)
    energy       one elastic-energy evaluation (its kernel's first call)

With ``--breakdown`` the build is split further (the child times Taichi's calls from outside,
adding a few ms):

    import Taichi, engine  Taichi's import and the engine's modules (the kernels' decorators)
    ti.init      Taichi's runtime (LLVM context, runtime module)
    front end    Taichi's Python front end: the AST transform of each kernel called (and of the
                 functions it inlines), in every process, even with the kernel in the cache
    cache load   the kernel's cache key (a hash of its IR) and its LLVM IR read from the cache
    first launch LLVM's optimisation and code generation of each kernel's IR (no object code is
                 cached: every process pays it), plus the launch itself (no work)
    other        the rest of the build (case, scene, arrays, neighbour list, probe, dt)

Usage::

    .venv/bin/python benchmarks/startup_time.py [--case cases/analytic/wall-at-rest.yaml]
        [--duration 0.02] [--repeat 5] [--breakdown]

Run it once first to fill the offline cache (its first run compiles, ~40 s per new kernel).
"""

from __future__ import annotations

import argparse
import json
import statistics
import subprocess
import sys

CHILD = r"""
import json, resource, sys, time

def clock():
    r = resource.getrusage(resource.RUSAGE_SELF)
    return r.ru_utime + r.ru_stime, time.perf_counter()

marks = [("start", *clock())]
from dem.case.document import load_case
from dem.run.build import build
import dem.engine  # noqa: F401
marks.append(("import", *clock()))
split = {}
if len(sys.argv) > 3:  # --breakdown: Taichi and the kernels' modules imported here (in build)
    exec(BREAKDOWN)
    from dem.engine import Simulation  # noqa: F401
    split["import Taichi, engine"] = clock()[0] - marks[-1][1] - sum(split.values())
case = load_case(sys.argv[1])
built = build(case)
sim = built.sim
marks.append(("build", *clock()))
n = max(1, int(round(float(sys.argv[2]) / sim.dt)))
sim.advance(n, built.loading)
marks.append(("advance", *clock()))
sim.elastic_energy()
marks.append(("energy", *clock()))
out = {name: {"cpu_s": c - marks[k][1], "wall_s": w - marks[k][2]}
       for k, (name, c, w) in enumerate(marks[1:])}
out["steps"] = n
out["compile_seconds"] = sim.compile_seconds
out["split"] = dict(split)
print(json.dumps(out))
"""

# the same run, Taichi's calls timed (--breakdown): installed before the build
BREAKDOWN = r"""
import collections
import taichi as ti
from taichi.lang import impl, kernel_impl
split = collections.defaultdict(float)
launched = {}  # id -> the compiled kernel (kept: its id is not reused)
_init = ti.init
def init(*a, **k):
    t = clock()[0]
    try:
        return _init(*a, **k)
    finally:
        split["ti.init"] += clock()[0] - t
        runtime = impl.get_runtime()
        runtime.prog = Prog(runtime.prog)
class Prog:
    def __init__(self, prog):
        self._prog = prog
    def __getattr__(self, name):
        return getattr(self._prog, name)
    def compile_kernel(self, *a):
        t = clock()[0]
        try:
            return self._prog.compile_kernel(*a)
        finally:
            split["cache load"] += clock()[0] - t
    def launch_kernel(self, compiled, ctx):
        if id(compiled) in launched:
            return self._prog.launch_kernel(compiled, ctx)
        launched[id(compiled)] = compiled
        t = clock()[0]
        try:
            return self._prog.launch_kernel(compiled, ctx)
        finally:
            split["first launch"] += clock()[0] - t
ti.init = init
_materialize = kernel_impl.Kernel.materialize
def materialize(self, *a, **k):
    t = clock()[0]
    try:
        return _materialize(self, *a, **k)
    finally:
        split["front end"] += clock()[0] - t
kernel_impl.Kernel.materialize = materialize
"""

PHASES = ("import", "build", "advance", "energy")
SPLIT = ("import Taichi, engine", "ti.init", "front end", "cache load", "first launch")


def main(argv=None) -> None:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--case", default="cases/analytic/wall-at-rest.yaml")
    ap.add_argument("--duration", type=float, default=0.02, help="simulated time (s)")
    ap.add_argument("--repeat", type=int, default=5)
    ap.add_argument("--breakdown", action="store_true",
                    help="split the build: ti.init, front end, cache load, first launch, other")
    args = ap.parse_args(argv)
    runs = []
    child = CHILD.replace("exec(BREAKDOWN)", "exec(" + repr(BREAKDOWN) + ")")
    for _ in range(args.repeat):
        res = subprocess.run([sys.executable, "-c", child, args.case, str(args.duration)]
                             + (["breakdown"] if args.breakdown else []),
                             capture_output=True, text=True, check=True)
        runs.append(json.loads(res.stdout.strip().splitlines()[-1]))
    print(f"{args.case}, {args.duration} s ({runs[0]['steps']} steps), median of "
          f"{args.repeat} fresh processes")
    print(f"{'phase':10s} {'CPU s':>8s} {'wall s':>8s}   (each run's CPU s)")
    if args.breakdown:
        for r in runs:
            r["other"] = r["build"]["cpu_s"] - sum(r["split"].get(k, 0.0) for k in SPLIT)
        for k in SPLIT + ("other",):
            cpu = [r["other"] if k == "other" else r["split"].get(k, 0.0) for r in runs]
            print(f"  {k:21s} {statistics.median(cpu):5.2f}   "
                  + " ".join(f"{c:.2f}" for c in cpu))
    total_cpu = [sum(r[p]["cpu_s"] for p in PHASES) for r in runs]
    total_wall = [sum(r[p]["wall_s"] for p in PHASES) for r in runs]
    for p in PHASES:
        cpu = [r[p]["cpu_s"] for r in runs]
        wall = [r[p]["wall_s"] for r in runs]
        print(f"{p:10s} {statistics.median(cpu):8.2f} {statistics.median(wall):8.2f}   "
              + " ".join(f"{c:.2f}" for c in cpu))
    print(f"{'total':10s} {statistics.median(total_cpu):8.2f} "
          f"{statistics.median(total_wall):8.2f}   " + " ".join(f"{c:.2f}" for c in total_cpu))
    print(f"Simulation.compile_seconds (wall): "
          f"{statistics.median(r['compile_seconds'] for r in runs):.2f}")


if __name__ == "__main__":
    main()
