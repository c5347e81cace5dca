"""Batching on the CPU, side by side: K separate single-threaded runs against ``--batch K``,
on the same workers, as a user runs them (``dem sweep``).

    python benchmarks/cpu_batch.py --ks 2,4 --repeats 3 --workers 2
    python benchmarks/cpu_batch.py --ks 2,4 --repeats 3 --before /path/to/other/checkout
    python benchmarks/cpu_batch.py --engine --ks 2,4,8 --steps 2000 --repeats 3

The scene: the 9 x 15 stretcher-bond wall of small bricks (cases/analytic/wall-at-rest.yaml:
142 blocks) shaken in plane at a peak acceleration of 1 m/s^2 (it stays standing), one cycle
at each of K frequencies 6.0, 6.5, ... Hz plus a 0.05 s margin (~0.2 s of simulated time, about
1.5e4 steps and 2 CPU-s of stepping per point on the 2-core VM), no VTK.  For each K and each
repeat, every configuration runs once, in an order that rotates from one repeat to the next
(the load of the machine drifts; alternating spreads it over the configurations):

  separate      ``dem sweep CASE --frequencies ... --workers W``: one run per task, K tasks
  batch         the same with ``--batch K`` (this checkout)
  batch-before  the same with ``--batch K`` run from the checkout ``--before`` (its code, this
                Python), when given
  one-worker    ``dem sweep CASE --frequencies ... --workers 1``: the K runs one after another
                in one worker process (``--configs`` to choose; default: the first three)

Each is a fresh ``dem sweep`` process (its local dask cluster of W single-threaded workers
started and stopped inside it: what a user pays), timed by the wall clock and by the CPU seconds
(user + system) of the whole process tree (getrusage of the reaped children: the workers are
reaped by the sweep process before it exits).  Per scene-step: those divided by the steps of all
K points (their summary.json ``steps``).  CPU-s per scene-step is the robust figure on a shared
machine (its load, the 1-minute load average, is printed with each run); the wall per
scene-step is what a user waits.  Both include the start-up (dask, imports, the kernels from
Taichi's offline cache), the points' analyses and the writing, which separate runs and a batch
pay differently (a batch imports the engine once per engine, not per worker).  Prints one JSON
line per run and, at the end, one per (K, configuration) with the medians (``--json FILE``
appends them to FILE).

``--engine``: the stepping alone, in this process, on one Taichi thread, serial kernel (what a
CPU batch's worker runs): for each K and repeat, alternated, the K scenes one after another,
each in an engine of its own (K lone runs), and the K scenes in one engine, each advanced
``--steps`` steps after a 256-step warm-up (compiles, seats the joints); the CPU time of the
process (time.process_time: the robust figure on a shared machine) per scene-step, and the
ratio batch / lone.  No start-up, no writing: what a long run's step costs.
"""

from __future__ import annotations

import argparse
import json
import os
import resource
import shutil
import subprocess
import sys
import tempfile
import time
from pathlib import Path

import numpy as np
import yaml
from batch_speed import emit  # benchmarks/ is the script's directory, first on sys.path

ROOT = Path(__file__).resolve().parents[1]
FIRST_HZ, STEP_HZ, CYCLES, MARGIN_S = 6.0, 0.5, 1, 0.05


def case_doc() -> dict:
    """The shaken wall (module docstring)."""
    doc = yaml.safe_load((ROOT / "cases/analytic/wall-at-rest.yaml").read_text())
    doc["name"] = "small-wall-shaken-in-plane"
    doc["description"] = "benchmarks/cpu_batch.py: the wall at rest, shaken in plane at 1 m/s2"
    doc["loading"] = {"type": "shake", "direction": [1, 0, 0], "frequency": FIRST_HZ,
                      "peak_acceleration": 1.0, "cycles": CYCLES}
    doc["run"] = {**doc["run"], "duration": CYCLES / FIRST_HZ + MARGIN_S, "vtk": False}
    return doc


def children_cpu() -> float:
    ru = resource.getrusage(resource.RUSAGE_CHILDREN)
    return ru.ru_utime + ru.ru_stime


def one_sweep(tree: Path, case: Path, out: Path, k: int, workers: int,
              batch: bool) -> dict:
    """One ``dem sweep`` of K points from the checkout ``tree``: wall, CPU of the process tree,
    the points' steps and the engines they ran in."""
    freqs = ",".join(f"{FIRST_HZ + STEP_HZ * i:g}" for i in range(k))
    cmd = [sys.executable, "-m", "dem_cli", "sweep", str(case), "--out", str(out),
           "--frequencies", freqs, "--cycles", str(CYCLES), "--margin", f"{MARGIN_S:g}",
           "--workers", str(workers)] + (["--batch", str(k)] if batch else [])
    env = dict(os.environ, PYTHONPATH=str(tree))
    load = os.getloadavg()[0]
    c0, t0 = children_cpu(), time.perf_counter()
    proc = subprocess.run(cmd, cwd=tree, env=env, capture_output=True, text=True)
    wall, cpu = time.perf_counter() - t0, children_cpu() - c0
    if proc.returncode != 0:
        raise SystemExit(f"{' '.join(cmd)}: exit {proc.returncode}\n{proc.stderr[-3000:]}")
    points = json.loads((out / "sweep.json").read_text())["points"]
    summaries = [json.loads((out / p["dir"] / "summary.json").read_text()) for p in points]
    steps = sum(int(s["steps"]) for s in summaries)
    engines = sorted({(s.get("batch") or {}).get("n_scenes", 1) for s in summaries})
    return {"K": k, "workers": workers, "steps": steps, "wall_s": wall, "cpu_s": cpu,
            "load_1min": load, "status": [s["status"] for s in summaries],
            "engine_sizes": engines,
            "cpu_us_per_scene_step": 1e6 * cpu / steps,
            "wall_us_per_scene_step": 1e6 * wall / steps}


def engine_scenes(k: int) -> list:
    """(scene, joints, options, loading) of the K points of the shaken wall (their
    frequencies as in the sweeps), serial kernel."""
    from dem.case import parse_case
    from dem.loading import loading_from_case
    from dem.run.build import case_joint_law, scene_from_case, step_options

    out = []
    for i in range(k):
        doc = case_doc()
        doc["loading"]["frequency"] = FIRST_HZ + STEP_HZ * i
        doc["solver"] = {"mode": "serial"}
        case = parse_case(doc)
        scene = scene_from_case(case)
        out.append((scene, case_joint_law(case, scene), step_options(case.solver),
                    loading_from_case(case)))
    return out


def engine_cpu(parts: list, steps: int) -> tuple[float, int]:
    """CPU seconds of ``steps`` steps of an engine of the scenes ``parts`` (after the
    warm-up), and the engine's scene-steps."""
    from dem.engine.simulation import Engine

    engine = Engine([p[0] for p in parts], [p[1] for p in parts], parts[0][2])
    loads = [p[3] for p in parts]
    engine.advance(256, loads)
    c0 = time.process_time()
    engine.advance(steps, loads)
    cpu = time.process_time() - c0
    assert engine.mode == "serial"
    return cpu, steps * len(parts)


def engine_side_by_side(ks: list[int], steps: int, repeats: int, path: str | None) -> None:
    """--engine (module docstring)."""
    from dem import ti_runtime

    ti_runtime.init(threads=1)
    for k in ks:
        parts = engine_scenes(k)
        lone, batch = [], []
        for rep in range(repeats):
            for which in (("lone", "batch") if rep % 2 == 0 else ("batch", "lone")):
                if which == "lone":
                    done = [engine_cpu([p], steps) for p in parts]
                    lone.append(1e6 * sum(c for c, _ in done) / sum(n for _, n in done))
                else:
                    cpu, n = engine_cpu(parts, steps)
                    batch.append(1e6 * cpu / n)
        emit({"engine": True, "K": k, "steps": steps, "repeats": repeats, "threads": 1,
              "mode": "serial", "lone_cpu_us_per_scene_step": lone,
              "batch_cpu_us_per_scene_step": batch,
              "median_lone": float(np.median(lone)), "median_batch": float(np.median(batch)),
              "batch_over_lone": float(np.median(batch) / np.median(lone)),
              "load_1min": round(os.getloadavg()[0], 1)}, path)


def main() -> int:
    ap = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    ap.add_argument("--ks", default="2,4")
    ap.add_argument("--repeats", type=int, default=3)
    ap.add_argument("--workers", type=int, default=2)
    ap.add_argument("--before", default=None, help="another checkout: its --batch beside ours")
    ap.add_argument("--configs", default="separate,batch,batch-before",
                    help="which of separate, batch, batch-before, one-worker (module docstring)")
    ap.add_argument("--json", default=None)
    ap.add_argument("--engine", action="store_true",
                    help="the stepping alone, one thread, serial kernel (module docstring)")
    ap.add_argument("--steps", type=int, default=2000, help="--engine: timed steps")
    args = ap.parse_args()
    if args.engine:
        sys.path.insert(0, str(ROOT))
        engine_side_by_side([int(x) for x in args.ks.split(",")], args.steps, args.repeats,
                            args.json)
        return 0
    known = {"separate": (ROOT, False, args.workers), "batch": (ROOT, True, args.workers),
             "one-worker": (ROOT, False, 1)}
    if args.before:
        known["batch-before"] = (Path(args.before).resolve(), True, args.workers)
    configs = [(name, *known[name]) for name in args.configs.split(",") if name in known]
    tmp = Path(tempfile.mkdtemp(prefix="cpu-batch-"))
    try:
        case = tmp / "wall-shaken.yaml"
        case.write_text(yaml.safe_dump(case_doc()))
        runs: dict = {}
        n = 0
        for k in [int(x) for x in args.ks.split(",")]:
            for rep in range(args.repeats):
                order = configs[rep % len(configs):] + configs[:rep % len(configs)]
                for name, tree, batch, workers in order:
                    out = tmp / f"run{n}"
                    n += 1
                    rec = {"config": name, "repeat": rep,
                           **one_sweep(tree, case, out, k, workers, batch)}
                    shutil.rmtree(out, ignore_errors=True)
                    runs.setdefault((k, name), []).append(rec)
                    emit(rec, args.json)
        for (k, name), recs in runs.items():
            emit({"summary": name, "K": k, "workers": recs[0]["workers"], "repeats": len(recs),
                  "engine_sizes": recs[0]["engine_sizes"],
                  "median_cpu_us_per_scene_step":
                      float(np.median([r["cpu_us_per_scene_step"] for r in recs])),
                  "median_wall_us_per_scene_step":
                      float(np.median([r["wall_us_per_scene_step"] for r in recs])),
                  "median_cpu_s": float(np.median([r["cpu_s"] for r in recs])),
                  "median_wall_s": float(np.median([r["wall_s"] for r in recs])),
                  "steps": recs[0]["steps"],
                  "load_1min": [round(r["load_1min"], 1) for r in recs]}, args.json)
    finally:
        shutil.rmtree(tmp, ignore_errors=True)
    return 0


if __name__ == "__main__":
    sys.exit(main())
