"""What the normal dashpots with the pair's no-tension rule cost (material.normal_damping: pair
at damping 0.75, the value of docs/engine.md section 6; stiffness at damping_time 0.75 ms),
against today's default (critical, damping 0.5): CPU per simulated second.

    DEM_THREADS=1 python benchmarks/impact_cost.py [--repeats 3]

Two scenes, each built once per law in this one process (compilation and the build are not
timed), then --repeats runs of a fixed simulated time from the scene's start, alternating the
laws so that the machine's load hits both alike:

  rocking block   the block of cases/analytic/rocking-block.yaml (0.1 x 0.1 x 0.4 m, from half
                  its slenderness angle), 0.1 s of free rocking (its first impact at 0.19 s is
                  not in it: the cost is the step's)
  Model II y      cases/shake/model-ii/group-3-y-1.53.yaml as built (perfect bricks), its own
                  table motion, the first 5 ms

Prints each run's time step, the median CPU seconds per simulated second and the ratio of each
law to today's.  The step sets most of the cost: dt = safety x (2 / omega)(sqrt(1 + z^2) - z),
z = 0.5 today, 0.75 for pair (1.24x shorter), 3 beta omega / 2 for stiffness (dem.engine.
timestep); pair adds a pass over each pair's points (the pair's pushes and pulls).
"""

from __future__ import annotations

import argparse
import math
import statistics
import time
from pathlib import Path

import numpy as np

ROOT = Path(__file__).resolve().parents[1]


def _rocking(material: dict):
    from scipy.spatial.transform import Rotation

    from dem.case import parse_case
    from dem.run.build import build

    b, h = 0.1, 0.4
    th0 = 0.5 * math.atan2(b, h)
    centre = np.array([b / 2, 0, 0]) + Rotation.from_euler("y", th0).apply([-b / 2, 0, h / 2])
    case = parse_case({"name": "rocking", "scene": {"blocks": [
        {"size": [b, 0.1, h], "position": centre.tolist(), "rotation": [0, math.degrees(th0), 0],
         "density": 2000}]}, "material": {"friction": 0.8, **material},
        "loading": {"type": "none"}, "run": {"duration": 1.0}})
    return build(case)


def _model_ii(material: dict):
    import yaml

    from dem.case import parse_case
    from dem.run.build import build

    doc = yaml.safe_load((ROOT / "cases/shake/model-ii/group-3-y-1.53.yaml").read_text())
    doc["material"] = {**doc.get("material", {}), **material}
    return build(parse_case(doc))


def time_run(built, duration: float) -> float:
    """CPU seconds per simulated second of ``duration`` s from the built scene's start state."""
    sim = built.sim
    n = max(1, int(round(duration / sim.dt)))
    t0 = time.process_time()
    sim.advance(n, built.loading)
    return (time.process_time() - t0) / (n * sim.dt)


def main() -> None:
    ap = argparse.ArgumentParser()
    ap.add_argument("--repeats", type=int, default=3)
    args = ap.parse_args()
    laws = {"critical": {}, "pair": {"normal_damping": "pair", "damping": 0.75},
            "stiffness": {"normal_damping": "stiffness", "damping_time": 7.5e-4}}
    scenes = {"rocking block": (_rocking, 0.1), "Model II y": (_model_ii, 0.005)}
    for name, (make, duration) in scenes.items():
        built = {}
        for law, mat in laws.items():
            built[law] = make(mat)
            time_run(built[law], min(duration, 50 * built[law].sim.dt))  # compile, warm up
        per = {law: [] for law in laws}
        for _ in range(args.repeats):
            for law in laws:
                fresh = make(laws[law])  # the same start state every repeat
                per[law].append(time_run(fresh, duration))
        med = {law: statistics.median(v) for law, v in per.items()}
        for law in laws:
            print(f"{name:14s} {law:9s} dt {built[law].sim.dt:.3g} s  CPU per simulated s: "
                  f"median {med[law]:.3g} (runs {', '.join(f'{x:.3g}' for x in per[law])})")
        for law in ("pair", "stiffness"):
            print(f"{name:14s} {law} / critical: {med[law] / med['critical']:.2f}x")


if __name__ == "__main__":
    main()
