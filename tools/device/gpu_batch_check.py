"""The batched engine's GPU check, on a borrowed machine (tools/device/README.md): run from the repository
root with `bash tools/device/gpu_batch_check.sh` (carry [".device"]).

Parts, each with its own time budget, results appended to $OUT as they come (part 0 first:
Taichi's kernel profiler on K = PROFILE_KS, each task's GPU time, printed to log.txt):
  1. realisations: ``R`` realisations (seeds 0..R-1) of Model II y at 2.8 Hz, 1.53 m/s^2,
     ``CYCLES`` cycles, as `dem ensemble` runs them (settling, table-frame start, the shake
     analysis of each point), in one engine on the GPU (dem.run.batched, arch cuda) and, at the
     same time, each alone in its own single-threaded process on the CPU cores: per seed, the shake
     analysis of both (points_gpu.json, points_cpu.json: ds amplification, lag, ...);
  2. throughput (benchmarks/batch_speed.py cuda): brick-steps/s against K on the GPU, the error
     of scenes 0 and K-1 against each alone on the CPU, the 100 x 50-cycle extrapolation
     (gpu.jsonl), run while part 1's CPU processes run (stated in the output);
  3. the CPU baseline of the same machine: 16 single-threaded processes of one scene
     (cpu_lone.jsonl), after part 1's CPU runs end;
  4. this host's Python of one stepping launch (benchmarks/host_share.py --launch, K = 64:
     host_launch.jsonl), against the project VM's 75 us (170 us with cold caches), by which
     the VM's estimate of a GPU run's host time (results/batched-engine/README.md) scales.
``PARTS`` (default "0,2,1,4") picks the parts to run (3 runs where time is left, LONE_BEFORE_S);
``CPU_PROCS`` (default R) the processes of part 1's CPU side; each point's record carries its
run's size and speed (steps, dt, wall seconds, neighbour rebuilds: SUMMARY_KEYS).

``python tools/device/gpu_batch_check.py --dry-run`` (any machine, no GPU, nothing run): imports
everything the parts import (Taichi, the engine and its device kernels, the shake analysis, the
benchmarks' realisations), builds the case of realisation 0, and prints the plan: each part's
command, its time budget and the files it writes, with the settings read from the environment
as a real call would read them.  The host's share of a GPU step comes from parts 0 and 2 of
one call: 1 - (the stepping kernel's time a step, part 0's profile) / (part 2's step time).
"""

from __future__ import annotations

import json
import multiprocessing as mp
import os
import subprocess
import sys
import threading
import time
from pathlib import Path


ROOT = Path(__file__).resolve().parents[2]
sys.path.insert(0, str(ROOT))
sys.path.insert(0, str(ROOT / "benchmarks"))
from batch_speed import case_of  # noqa: E402 - the realisations the benchmarks run
OUT = Path(os.environ.get("OUT", "/tmp/out"))
T0 = time.time()
ARCH = os.environ.get("ARCH", "cuda")  # cpu: a dry run of this script on any machine
TAG = os.environ.get("TAG", "")  # suffix of part 1's files (points_gpu<TAG>.json ...)


def say(*a):
    print(f"[{time.time() - T0:6.1f} s]", *a, flush=True)


SUMMARY_KEYS = ("steps", "dt", "sim_time", "wall_seconds", "neighbour_rebuilds",
                "brick_steps_per_second", "n_pairs", "max_penetration_m")


def compact_post(rec: dict) -> dict:
    """A point's status, its shake analysis (postprocess.sweep.compact: amplification,
    lag, ...) and its run's size and speed (summary.json), compared here and back home."""
    summary = rec.get("summary") or {}
    return {"status": rec["status"], "error": rec.get("error"), "post": rec.get("post"),
            "run": {k: summary.get(k) for k in SUMMARY_KEYS}}


def cpu_point(args):
    seed, cycles, out = args
    os.environ["DEM_THREADS"] = "1"
    from dem.batch import run_one
    from postprocess.sweep import analyze_point

    case = case_of(seed, cycles)
    t0 = time.time()
    rec = run_one(f"seed{seed}", case.model_dump_json(), str(out / f"seed{seed}"), 1, None,
                  analyze_point, ())
    return seed, {**compact_post(rec), "wall_s": time.time() - t0}


def gpu_points(R: int, cycles: int) -> None:
    """Part 1 on the GPU (its own process: a time limit can stop it)."""
    from dem.run.batched import run_cases_in_one_engine
    from postprocess.sweep import analyze_point

    cases = [(f"seed{s}", case_of(s, cycles)) for s in range(R)]
    runs = Path(f"/tmp/gpu_runs{TAG}")
    t0 = time.time()
    threading.Thread(target=heartbeat, args=(t0,), daemon=True).start()
    try:
        recs = run_cases_in_one_engine(cases, [runs / n for n, _ in cases],
                                       arch=ARCH, post=analyze_point)
        gpu = {s: compact_post(r) for s, r in enumerate(recs)}
        batch = json.loads((runs / "seed0/summary.json").read_text()).get("batch")
    except Exception as err:  # noqa: BLE001 - report it
        gpu, batch = {"error": f"{type(err).__name__}: {err}"}, None
    gpu_s = time.time() - t0
    (OUT / f"points_gpu{TAG}.json").write_text(json.dumps(
        {"wall_s": gpu_s, "R": R, "cycles": cycles, "batch": batch, "points": gpu}, indent=1,
        default=str))
    say(f"part 1 GPU: {R} realisations in {gpu_s:.1f} s")


def heartbeat(t0: float, every: float = 15.0) -> None:
    """Every ``every`` s: the batch's steps and neighbour rebuilds so far (a call cut at its
    time limit still tells how fast the batch went)."""
    import gc

    from dem.engine.simulation import Engine

    while True:
        time.sleep(every)
        engines = [o for o in gc.get_objects() if isinstance(o, Engine)]
        if engines:
            sims = engines[-1].simulations
            say(f"heartbeat {time.time() - t0:.0f} s: scene 0 at step "
                f"{sims[0].step_count}, {sum(s.n_rebuilds for s in sims)} rebuilds "
                f"({len(sims)} scenes)")


def plan() -> list[tuple[str, list[str], float, str]]:
    """The GPU parts in the order they run, as the environment sets them: (part, command,
    time budget in s, what it writes to $OUT)."""
    ks = os.environ.get("KS", "1,16,64,100")
    # part 2: throughput on the GPU (part 1's CPU processes running on other cores)
    cmd = [sys.executable, str(ROOT / "benchmarks/batch_speed.py"), ARCH, "--ks", ks,
           "--steps", os.environ.get("STEPS", "1000"), "--repeats", "3", "--error",
           "--json", str(OUT / "gpu.jsonl"), "--save", str(OUT)]
    profile = [sys.executable, str(ROOT / "benchmarks/batch_speed.py"), ARCH, "--ks",
               os.environ.get("PROFILE_KS", "16,64"), "--steps", "300", "--repeats", "1",
               "--profile", "--json", str(OUT / "gpu_profile.jsonl")]
    # part 4: the Python of one stepping launch on this machine's host (the CPU proxy's
    # engine, the C++ launch stubbed): what the estimate of a GPU run's host time scales by
    host = [sys.executable, str(ROOT / "benchmarks/host_share.py"), "--launch", "--ks", "64",
            "--json", str(OUT / "host_launch.jsonl")]
    out = [("0 (each kernel task's time)", profile, float(os.environ.get("PROFILE_S", "150")),
            "gpu_profile.jsonl, the profile in log.txt"),
           ("2 (throughput)", cmd, float(os.environ.get("THROUGHPUT_S", "240")),
            "gpu.jsonl (step time against K, error against lone runs), states_K*.npz"),
           ("1 GPU (realisations)", [sys.executable, __file__, "gpu-points"],
            float(os.environ.get("GPU_POINTS_S", "200")),
            f"points_gpu{TAG}.json (ds amplification and lag of each seed)"),
           ("4 (the host's Python of a launch)", host, float(os.environ.get("HOST_S", "120")),
            "host_launch.jsonl (this host's Python of one stepping launch, K = 64)")]
    parts = os.environ.get("PARTS", "0,2,1,4")  # which of parts 0, 2, 1, 4 (in that order) run
    return [p for p in out if p[0][0] in parts.split(",")]


def dry_run() -> int:
    """Import what every part imports, build realisation 0's case, print the plan (no
    kernel runs, no GPU needed)."""
    import taichi  # noqa: F401
    import dem.engine.device  # noqa: F401 - the device kernels (decorated, not compiled)
    from dem.engine.simulation import Engine  # noqa: F401
    from dem.engine.step_device import DEVICE_STEPS_PER_LAUNCH
    from dem.run.batched import run_cases_in_one_engine  # noqa: F401
    from postprocess.sweep import analyze_point  # noqa: F401

    R = int(os.environ.get("R", "8"))
    cycles = int(os.environ.get("CYCLES", "10"))
    case = case_of(0, cycles)
    print(f"dry run: imports fine (taichi {taichi.__version__}); realisation 0: {case.name}, "
          f"{cycles} cycles, {case.run.duration:.3f} s simulated; ARCH={ARCH}, OUT={OUT}")
    steps = os.environ.get("DEM_STEPS_PER_LAUNCH") or DEVICE_STEPS_PER_LAUNCH.get(ARCH, 1)
    print(f"the device's stepping kernel's steps a launch on {ARCH}: {steps} "
          "(DEM_STEPS_PER_LAUNCH; dem/engine/step_device.py)")
    if os.environ.get("CPU_POINTS", "1") == "1":
        print(f"part 1 CPU: {R} realisations, {int(os.environ.get('CPU_PROCS', str(R)))} "
              f"single-threaded processes from the start -> points_cpu{TAG}.json")
    for part, argv, budget, writes in plan():
        print(f"part {part}, at most {budget:.0f} s: {' '.join(argv[1:])}\n    -> {writes}")
    print(f"part 3 if started before {os.environ.get('LONE_BEFORE_S', '450')} s: 16 lone "
          "single-threaded processes, 90 s at most -> cpu_lone.jsonl")
    print("then: python benchmarks/batch_speed.py compare $OUT (GPU vs CPU states); the host's "
          "share of a step: 1 - part 0's stepping-kernel time a step / part 2's step time")
    return 0


def main() -> int:
    R = int(os.environ.get("R", "8"))
    cycles = int(os.environ.get("CYCLES", "10"))
    if sys.argv[1:] == ["gpu-points"]:
        gpu_points(R, cycles)
        return 0
    if sys.argv[1:] == ["--dry-run"]:
        return dry_run()
    OUT.mkdir(parents=True, exist_ok=True)
    # part 1, CPU side: in the background from the start (one process per realisation)
    cpu_points = os.environ.get("CPU_POINTS", "1") == "1"  # 0: an earlier call's are kept
    procs = int(os.environ.get("CPU_PROCS", str(R)))  # CPU processes of part 1
    pool = mp.get_context("spawn").Pool(procs) if cpu_points else None
    if pool is not None:
        cpu_async = pool.map_async(cpu_point, [(s, cycles, Path("/tmp/cpu_runs"))
                                               for s in range(R)])
        say(f"part 1: {R} CPU processes started ({cycles} cycles each)")
    for part, argv, budget, _ in plan():
        try:
            subprocess.run(argv, timeout=budget, check=False)
            say(f"part {part} done")
        except subprocess.TimeoutExpired:
            say(f"part {part} cut at {budget} s")
    if pool is not None:
        try:
            cpu = dict(cpu_async.get(timeout=float(os.environ.get("CPU_WAIT_S", "60"))))
        except mp.TimeoutError:
            cpu = {"error": "the CPU runs did not finish in time"}
        pool.terminate()
        (OUT / f"points_cpu{TAG}.json").write_text(json.dumps(cpu, indent=1, default=str))
        say("part 1 CPU done")
    # part 3: the CPU baseline, if time is left
    if time.time() - T0 < float(os.environ.get("LONE_BEFORE_S", "450")):
        try:
            subprocess.run([sys.executable, str(ROOT / "benchmarks/batch_speed.py"), "lone",
                            "--steps", "400", "--repeats", "3", "--procs", "16", "--json",
                            str(OUT / "cpu_lone.jsonl")], timeout=90, check=False)
        except subprocess.TimeoutExpired:
            say("part 3 cut at 90 s")
    say("all done")
    return 0


if __name__ == "__main__":
    sys.exit(main())
