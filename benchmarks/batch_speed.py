"""Throughput of an engine of K scenes: brick-steps per second against K, beside K
separate single-threaded processes, with the error of the batch against the scenes run alone.

    python benchmarks/batch_speed.py cpu  --ks 1,4,16,64 --steps 400 --threads 2
    python benchmarks/batch_speed.py cuda --ks 1,16,64,100,256 --steps 2000
    python benchmarks/batch_speed.py lone --steps 400          # one scene, serial, 1 thread
    python benchmarks/batch_speed.py cuda --ks 16,64 --steps 300 --profile   # + each task's time
    python benchmarks/batch_speed.py run --ks 8,16 --steps 32000 --threads 1  # host traffic

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

``run``: the host <-> device traffic of a real batched run, measured on the CPU (no GPU needed):
K realisations (the same scenes, 3 cycles: ``case_of``) run through
dem.run.batched.run_cases_in_one_engine as ``dem ensemble --batch`` runs them (settling, the
table-frame start, 500 Hz instruments, frames every 0.02 s), for ``--steps`` steps each
(--max-steps), with the engine's device arrays on the CPU (``device_arrays=True``: the code a
GPU runs, dem.engine.device; ``--host-arrays``: the numpy path, for the digest only).  The
wall-clock checkpoints (frames.npz / restart.npz every 30 s of wall time) are switched off, so
that the counts depend on the simulated steps only, not on the machine's speed.  Prints the
copies and bytes each way (Engine.transfer_stats) per simulated second (the batch's: steps x dt)
and per 1000 steps, the chunks (Engine.advance's launches), the wall time (all counted after the
engine's construction) and a digest of every point's frames and instruments (sha256 of their arrays:
equal digests, the same outputs bit for bit).

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


def realisation_doc(seed: int) -> dict:
    """The case document of realisation ``seed``: the case file with the frozen imperfection
    set and that seed."""
    doc = yaml.safe_load(CASE.read_text())
    doc["imperfections"] = {**yaml.safe_load(FROZEN.read_text())["imperfections"], "seed": seed}
    return doc


def realisation(seed: int, mode: str, dt: float | None = None):
    """(scene, joints, options, loading) of one realisation."""
    from dem.case import parse_case
    from dem.loading import loading_from_case
    from dem.run.build import case_joint_law, scene_from_case, step_options

    doc = realisation_doc(seed)
    doc["solver"] = {**doc.get("solver", {}), "mode": mode}
    if dt is not None:
        doc["solver"]["dt"] = dt
    case = parse_case(doc)
    scene = scene_from_case(case)
    return scene, case_joint_law(case, scene), step_options(case.solver), \
        loading_from_case(case)


def case_of(seed: int, cycles: int = 3):
    """The Case of realisation ``seed`` as a batched ensemble runs it (settling, instruments,
    frames every 0.02 s, no VTK, no snapshot; tools/device/gpu_batch_check.py runs these)."""
    from dem.case import parse_case

    doc = realisation_doc(seed)
    doc["name"] = f"model-ii-y-2.8-seed{seed}"
    doc["loading"]["cycles"] = cycles
    doc["run"]["duration"] = cycles / 2.8 + 1.0
    doc["run"]["vtk"] = False
    doc["run"]["snapshot"] = False
    return parse_case(doc)


def digest(out_dir: Path) -> str:
    """sha256 of a run directory's frames and instruments (every array, in key order)."""
    import hashlib

    h = hashlib.sha256()
    for name in ("frames.npz", "instruments.npz"):
        f = out_dir / name
        if not f.exists():
            h.update(f"no {name}".encode())
            continue
        with np.load(f) as z:
            for k in sorted(z.files):
                h.update(k.encode())
                h.update(np.ascontiguousarray(z[k]).tobytes())
    return h.hexdigest()[:16]


def since(now: dict, before: dict) -> dict:
    """Engine.transfer_stats ``now`` less ``before`` (every number, recursively)."""
    if isinstance(now, dict):
        return {k: since(v, before.get(k, 0 if not isinstance(v, dict) else {}))
                for k, v in now.items()}
    return now - before


def run_batch(k: int, steps: int, threads: int | None, device: bool, out_root: Path) -> dict:
    """One batched run of realisations 0..k-1 (module docstring, ``run``); its counts."""
    import dem.run.write
    from dem.run.batched import run_cases_in_one_engine

    dem.run.write.CHECKPOINT_SECONDS = float("inf")  # counts per step, not per wall second
    cases = [(f"seed{s}", case_of(s)) for s in range(k)]
    dirs = [out_root / f"K{k}" / name for name, _ in cases]
    held: dict = {}

    def on_engine(engine) -> None:  # the counts of the construction are left out
        held["engine"], held["t"] = engine, time.perf_counter()
        held["before"] = engine.transfer_stats()

    t0 = time.perf_counter()
    records = run_cases_in_one_engine(cases, dirs, max_steps=steps, resume=False,
                                      threads=threads, device_arrays=device or None,
                                      on_engine=on_engine)
    t1 = time.perf_counter()
    if "engine" not in held:  # the batch failed before its engine existed (its records say why)
        raise SystemExit(f"run K={k}: no engine was built: "
                         f"{[(r.get('status'), r.get('error')) for r in records]}")
    engine = held["engine"]
    stats = since(engine.transfer_stats(), held["before"])
    summaries = [r.get("summary") or {} for r in records]
    done = [s.get("steps") for s in summaries]
    dt = float(engine.dt)
    sim_s = steps * dt
    rec = {"arch": "run", "K": k, "device_arrays": engine.on_device, "threads": threads,
           "mode": engine.mode, "steps": steps, "steps_done": done, "dt_s": dt,
           "dt_changes": len(engine.simulations[0].dt_changes), "sim_s": sim_s,
           "status": [r["status"] for r in records],
           "settling_steps": [(s.get("settling") or {}).get("steps") for s in summaries],
           "rebuilds": sum(s.n_rebuilds for s in engine.simulations),
           "chunks": stats["chunks"], "build_s": held["t"] - t0, "wall_s": t1 - held["t"],
           "wall_per_1000_steps_s": 1e3 * (t1 - held["t"]) / steps,
           "digests": [digest(d) for d in dirs]}
    for key in ("host_to_device", "device_to_host"):
        x = stats[key]
        rec[key] = {"copies": x["copies"], "MB": x["bytes"] / 1e6, "copy_s": x["seconds"],
                    "copies_per_sim_s": x["copies"] / sim_s,
                    "MB_per_sim_s": x["bytes"] / 1e6 / sim_s,
                    "copies_per_1000_steps": 1e3 * x["copies"] / steps,
                    "MB_per_1000_steps": 1e3 * x["bytes"] / 1e6 / steps,
                    "MB_by_container": {n: v["bytes"] / 1e6
                                        for n, v in x["by_container"].items()},
                    "copies_by_container": {n: v["copies"]
                                            for n, v in x["by_container"].items()},
                    "MB_by_field": {f"{n}.{f}": b / 1e6 for n, v in x["by_container"].items()
                                    for f, b in sorted(v.get("fields", {}).items(),
                                                       key=lambda fb: -fb[1]) if b}}
    rec["install_pairs"] = stats["install_pairs"]
    rec["chunks_per_sim_s"] = stats["chunks"] / sim_s
    return rec


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
    ap.add_argument("arch", choices=["cpu", "cuda", "lone", "compare", "run"])
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
    ap.add_argument("--host-arrays", action="store_true",
                    help="run: the numpy path instead of the device arrays (digests only)")
    ap.add_argument("--out", default=None,
                    help="run: where the points' directories go (default: a temporary one)")
    ap.add_argument("--profile", action="store_true",
                    help="Taichi's kernel profiler: each task's time, printed after each K")
    args = ap.parse_args()
    if args.arch == "compare":
        return compare_saved(Path(args.states), args.json)
    if args.arch == "run":
        import shutil
        import tempfile

        root = Path(args.out) if args.out else Path(tempfile.mkdtemp(prefix="batch-run-"))
        try:
            for k in [int(x) for x in args.ks.split(",")]:
                emit(run_batch(k, args.steps, args.threads, not args.host_arrays, root),
                     args.json)
        finally:
            if not args.out:
                shutil.rmtree(root, ignore_errors=True)
        return 0
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
