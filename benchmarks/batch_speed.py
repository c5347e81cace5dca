"""Throughput of an engine of K scenes (issue 35): brick-steps per second against K, beside K
separate single-threaded processes, with the error of the batch against the scenes run alone.

    python benchmarks/batch_speed.py cpu  --ks 1,4,16,64 --steps 400 --threads 2
    python benchmarks/batch_speed.py cuda --ks 1,16,64,100,256 --steps 2000
    python benchmarks/batch_speed.py lone --steps 400          # one scene, serial, 1 thread
    python benchmarks/batch_speed.py cuda --ks 16,64 --steps 300 --profile   # + each task's time

The scenes: Model II shaken along y at 2.8 Hz, 1.53 m/s^2 (cases/shake/model-ii/
group-3-y-1.53.yaml: 217 bodies, 212 blocks), each with the frozen imperfection set
(studies/calibration/frozen.yaml: planar beds, sigma 0.1 mm) and its own seed, as the
prediction's ensembles ran them, from rest in the table frame (no settling phase: this measures
the step, not a run).  For each K: one warm-up advance of 256 steps (compiles, first rebuilds),
then ``--repeats`` timed advances of ``--steps`` steps; the median is printed.  ``cpu``: the
parallel kernel on ``--threads`` threads (one process); ``cuda``: the engine's device path
(dem.engine.device), parallel kernel.  ``lone``: one scene, serial kernel, one thread (what
each of K separate processes runs); ``--procs N`` runs N of them at once and prints the
aggregate (K separate processes on C cores run min(K, C) at a time).

Error: after the timed steps, the first and last scenes of the batch against the same scene run
alone for the same steps with the batch's time step (on the CPU: serial kernel; on a GPU: alone
on the GPU, one process runs one arch): the largest |position difference| (m) and |quaternion
difference|.  ``--save DIR``: the states of every scene after the timed steps of each K <= 16
(states_K<k>.npz: pos, quat, steps, dt), to compare a GPU's with the CPU's elsewhere
(``compare DIR``: runs scenes 0 and K-1 alone on this machine's CPU and prints the difference).

The time for 100 realisations of 50 cycles is extrapolated from the K=100 step time (the
loading phase only: 50 / 2.8 Hz + 1 s = 18.86 s of simulated time at the batch's dt).
Prints one JSON line per measurement (``--json FILE`` appends them to FILE).
"""

from __future__ import annotations

import argparse
import json
import os
import subprocess
import sys
import time
from pathlib import Path

import numpy as np
import yaml

ROOT = Path(__file__).resolve().parents[1]
sys.path.insert(0, str(ROOT))
CASE = ROOT / "cases/shake/model-ii/group-3-y-1.53.yaml"
FROZEN = ROOT / "studies/calibration/frozen.yaml"
SIM_SECONDS_50_CYCLES = 50 / 2.8 + 1.0


def realisation(seed: int, mode: str, dt: float | None = None):
    """(scene, joints, options, loading) of one realisation."""
    from dem.case import parse_case
    from dem.loading import loading_from_case
    from dem.run.build import case_joint_law, scene_from_case, step_options

    doc = yaml.safe_load(CASE.read_text())
    doc["imperfections"] = {**yaml.safe_load(FROZEN.read_text())["imperfections"], "seed": seed}
    doc["solver"] = {**doc.get("solver", {}), "mode": mode}
    if dt is not None:
        doc["solver"]["dt"] = dt
    case = parse_case(doc)
    scene = scene_from_case(case)
    return scene, case_joint_law(case, scene), step_options(case.solver), \
        loading_from_case(case)


_BUILT: dict = {}


def build(k: int, mode: str, device: bool | None, dt: float | None = None):
    """An engine of realisations 0..k-1 (the scenes built once per seed and mode)."""
    from dem.engine.simulation import Engine

    for seed in range(k):
        if (seed, mode) not in _BUILT:
            _BUILT[seed, mode] = realisation(seed, mode, dt)
    parts = [_BUILT[seed, mode] for seed in range(k)]
    engine = Engine([p[0] for p in parts], [p[1] for p in parts], parts[0][2],
                    device_arrays=device)
    return engine, [p[3] for p in parts]


def timed(engine, loads, steps: int, repeats: int) -> list[float]:
    out = []
    for _ in range(repeats):
        t0 = time.perf_counter()
        engine.advance(steps, loads)
        out.append(time.perf_counter() - t0)
    return out


def error_against_alone(engine, steps_done: int, which: list[int]) -> dict:
    """Largest position / quaternion difference of scenes ``which`` against each run alone on
    the CPU (serial kernel, numpy arrays, the batch's dt)."""
    from dem.engine.simulation import Engine

    dpos = dquat = 0.0
    for g in which:
        scene, joints, opts, loading = realisation(g, "serial", engine.dt)
        alone = Engine([scene], [joints], opts)  # on a GPU: alone on the GPU
        alone.advance(steps_done, [loading])
        a, b = engine.simulations[g].state, alone.simulations[0].state
        dpos = max(dpos, float(np.abs(a.pos - b.pos).max()))
        dquat = max(dquat, float(np.abs(a.quat - b.quat).max()))
    return {"max_dpos_m": dpos, "max_dquat": dquat, "scenes_checked": which}


def compare_saved(states: Path, path: str | None) -> int:
    """Scenes 0 and K-1 of each saved batch (another machine's, e.g. a GPU's) run alone here on
    the CPU (serial kernel) for the same steps and dt: the largest differences."""
    from dem.engine.simulation import Engine

    for f in sorted(states.glob("states_K*.npz")):
        z = np.load(f)
        k = z["pos"].shape[0]
        for g in sorted({0, k - 1}):
            scene, joints, opts, loading = realisation(g, "serial", float(z["dt"]))
            alone = Engine([scene], [joints], opts)
            alone.advance(int(z["steps"]), [loading])
            st = alone.simulations[0].state
            emit({"compare": f.name, "scene": g, "steps": int(z["steps"]),
                  "max_dpos_m": float(np.abs(z["pos"][g] - st.pos).max()),
                  "max_dquat": float(np.abs(z["quat"][g] - st.quat).max()),
                  "max_disp_from_start_m": float(np.abs(st.pos[:-1] - scene.position).max())},
                 path)
    return 0


def emit(rec: dict, path: str | None) -> None:
    line = json.dumps(rec)
    print(line, flush=True)
    if path:
        with open(path, "a") as f:
            f.write(line + "\n")


def main() -> int:
    ap = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    ap.add_argument("arch", choices=["cpu", "cuda", "lone", "compare"])
    ap.add_argument("states", nargs="?", help="compare: a --save directory")
    ap.add_argument("--ks", default="1,4,16,64")
    ap.add_argument("--steps", type=int, default=400)
    ap.add_argument("--repeats", type=int, default=3)
    ap.add_argument("--threads", type=int, default=None)
    ap.add_argument("--procs", type=int, default=1)
    ap.add_argument("--mode", choices=["parallel", "serial"], default="parallel",
                    help="cpu: the kernel of the batch (dem sweep/ensemble --batch on the CPU "
                         "run single-threaded workers, hence the serial kernel)")
    ap.add_argument("--error", action="store_true", help="also the error against lone runs")
    ap.add_argument("--json", default=None)
    ap.add_argument("--save", default=None)
    ap.add_argument("--profile", action="store_true",
                    help="Taichi's kernel profiler: each task's time, printed after each K")
    args = ap.parse_args()
    if args.arch == "compare":
        return compare_saved(Path(args.states), args.json)
    if args.arch == "lone" and args.procs > 1:
        cmd = [sys.executable, __file__, "lone", "--steps", str(args.steps), "--repeats",
               str(args.repeats)]
        env = dict(os.environ, DEM_THREADS="1")
        procs = [subprocess.Popen(cmd, stdout=subprocess.PIPE, text=True, env=env)
                 for _ in range(args.procs)]
        rates = [json.loads(p.communicate()[0].strip().splitlines()[-1])["brick_steps_per_s"]
                 for p in procs]
        emit({"arch": "lone", "procs": args.procs, "brick_steps_per_s_each": rates,
              "aggregate_brick_steps_per_s": float(sum(rates))}, args.json)
        return 0
    from dem import ti_runtime

    threads = 1 if args.arch == "lone" else args.threads
    ti_runtime.init(threads=threads, arch="cuda" if args.arch == "cuda" else "cpu",
                    kernel_profiler=args.profile)
    ks = [1] if args.arch == "lone" else [int(x) for x in args.ks.split(",")]
    mode = "serial" if args.arch == "lone" else ("parallel" if args.arch == "cuda" else args.mode)
    for k in ks:
        t0 = time.perf_counter()
        engine, loads = build(k, mode, args.arch == "cuda")
        build_s = time.perf_counter() - t0
        t0 = time.perf_counter()
        engine.advance(256, loads)
        warm_s = time.perf_counter() - t0
        times = timed(engine, loads, args.steps, args.repeats)
        step_s = float(np.median(times)) / args.steps
        n_blocks = sum(s.n_blocks for s in engine.simulations)
        rec = {"arch": args.arch, "K": k, "threads": threads, "mode": engine.mode,
               "bodies": engine.model.n_bodies, "dt_s": engine.dt, "steps": args.steps,
               "times_s": times, "step_ms": 1e3 * step_s,
               "brick_steps_per_s": n_blocks / step_s, "build_s": build_s, "warm_s": warm_s,
               "rebuilds": sum(s.n_rebuilds for s in engine.simulations)}
        if k == 100 or (args.arch == "cuda" and k == max(ks)):
            steps = SIM_SECONDS_50_CYCLES / engine.dt
            rec["extrapolated_50_cycles"] = {"K": k, "steps": steps,
                                             "seconds": steps * step_s}
        if args.save and k <= 16:
            Path(args.save).mkdir(parents=True, exist_ok=True)
            np.savez(Path(args.save) / f"states_K{k}.npz",
                     pos=np.stack([s.state.pos for s in engine.simulations]),
                     quat=np.stack([s.state.quat for s in engine.simulations]),
                     steps=engine.simulations[0].step_count, dt=engine.dt)
        if args.error and k > 1:
            rec["error_vs_alone"] = error_against_alone(engine, 256 + args.repeats * args.steps,
                                                        [0, k - 1])
        emit(rec, args.json)
        if args.profile:  # the timed advances' tasks (warm-up and error runs included)
            import taichi as ti

            print(f"kernel profile, K = {k}:", flush=True)
            ti.profiler.print_kernel_profiler_info("count")
            ti.profiler.clear_kernel_profiler_info()
        del engine
    return 0


if __name__ == "__main__":
    sys.exit(main())
