"""Quasi-static tilt against the constant-rate tilt: lambda error and CPU time.

    python benchmarks/quasi_static_tilt.py [--out benchmarks/quasi_static_tilt.json] [--only NAME]
                                           [--repeat 3]

For two walls of Chapter 3 with a rate -> 0 reference (results/tilt/FINDINGS.md: the in-plane
5 x 7 small-brick wall 0.800, the out-of-plane large-brick wall without wings 0.1545; its static
elastic-tipping value is 0.1514, postprocess/limit_analysis.py) it runs the constant-rate tilt at
the default 2 deg/s and the quasi-static tilt at its defaults and with one setting changed at a
time, one Taichi thread each, and prints lambda, its error against the reference, the CPU
seconds of the run's process (compile excluded) and the ratio to the 2 deg/s run.  The timed
variants (the 2 deg/s run and the defaults) run ``--repeat`` times and show the median (the
machine is shared).
Finished points are kept in the JSON and skipped on a rerun (resumable); points of an older
RULES are dropped.
"""

from __future__ import annotations

import argparse
import json
import os
import statistics
import sys
import time
from pathlib import Path

import yaml

ROOT = Path(__file__).resolve().parents[1]
WALLS = {
    "in-plane-5x7": ("cases/tilt/in-plane/small-5x7.yaml", 0.800),
    "out-of-plane-no-wings": ("cases/tilt/out-of-plane/large-5x9-no-wings.yaml", 0.1545),
}
RULES = "2026-11-24b"  # the quasi-static search's rules the stored points were run with
VARIANTS = [  # (name, method, quasi_static settings, timed: repeated for a median)
    ("rate 2 deg/s", "constant_rate", {}, True),
    ("qs defaults", "quasi_static", {}, True),
    ("qs tolerance 1e-2", "quasi_static", {"tolerance": 1e-2}, False),
    ("qs tolerance 1e-4", "quasi_static", {"tolerance": 1e-4}, False),
    ("qs increment 0.5", "quasi_static", {"increment": 0.5}, False),
    ("qs increment 2", "quasi_static", {"increment": 2.0}, False),
    ("qs max_relax_time 0.5", "quasi_static", {"max_relax_time": 0.5}, False),
    ("qs max_relax_time 2", "quasi_static", {"max_relax_time": 2.0}, False),
]


def case_for(path: str, method: str, qs: dict):
    from dem.case import parse_case

    d = yaml.safe_load((ROOT / path).read_text())
    ld = d["loading"]
    if method == "quasi_static":
        for k in ("rate", "step", "hold"):
            ld.pop(k, None)
        ld["method"] = "quasi_static"
        ld["quasi_static"] = dict(qs)
    else:
        ld["method"] = "constant_rate"
    d["run"].update({"vtk": False, "snapshot": False})
    return parse_case(d)


def run_point(path: str, method: str, qs: dict) -> dict:
    from dem.run import run_case

    case = case_for(path, method, qs)
    c0 = time.process_time()
    res = run_case(case, None)
    cpu = time.process_time() - c0
    col = res.summary["collapse"]
    return {"load_factor": col.get("load_factor") if col.get("detected") else None,
            "angle_deg": col.get("angle_deg"), "cpu_s": cpu, "steps": res.summary["steps"],
            "sim_time_s": res.summary["sim_time"], "compile_s": res.summary["compile_seconds"],
            "relaxations": col.get("relaxations"),
            "resolution_deg": col.get("resolution_deg")}


def main() -> None:
    ap = argparse.ArgumentParser()
    ap.add_argument("--out", default=str(ROOT / "benchmarks/quasi_static_tilt.json"))
    ap.add_argument("--only", default=None, help="run only this wall")
    ap.add_argument("--repeat", type=int, default=3, help="runs of the timed variants")
    args = ap.parse_args()
    os.environ.setdefault("DEM_THREADS", "1")
    out = Path(args.out)
    data = json.loads(out.read_text()) if out.is_file() else {}
    data = {k: v for k, v in data.items() if v.get("rules") == RULES}
    for rep in range(args.repeat):  # interleaved: drifts of the machine's load hit all alike
        for wall, (path, ref) in WALLS.items():
            if args.only and wall != args.only:
                continue
            for name, method, qs, timed in VARIANTS:
                key = f"{wall} | {name}"
                rec = data.get(key)
                if rec is not None and len(rec["cpu_net_runs"]) >= (args.repeat if timed else 1):
                    continue
                if rec is not None and len(rec["cpu_net_runs"]) > rep:
                    continue
                print(f"running {key} (run {rep + 1}) ...", flush=True)
                r = run_point(path, method, qs)
                if rec is None:
                    rec = dict(r, wall=wall, variant=name, reference=ref, rules=RULES,
                               date=time.strftime("%Y-%m-%d"), cpu_net_runs=[])
                rec["cpu_net_runs"].append(r["cpu_s"] - r["compile_s"])
                rec["lambda_runs"] = rec.get("lambda_runs", []) + [r["load_factor"]]
                data[key] = rec
                out.write_text(json.dumps(data, indent=1))
    print("\n| wall | variant | lambda | error vs rate->0 | CPU s (median, excl. compile) | "
          "runs | x 2 deg/s run |")
    print("|---|---|---|---|---|---|---|")
    for wall, (_, ref) in WALLS.items():
        base = data.get(f"{wall} | rate 2 deg/s")
        for name, _, _, _ in VARIANTS:
            r = data.get(f"{wall} | {name}")
            if r is None:
                continue
            lam = r["load_factor"]
            err = f"{100 * (lam / ref - 1):+.2f} %" if lam else "no collapse"
            cpu = statistics.median(r["cpu_net_runs"])
            ratio = f"{cpu / statistics.median(base['cpu_net_runs']):.2f}" if base else "-"
            print(f"| {wall} | {name} | {lam if lam is None else round(lam, 4)} | {err} | "
                  f"{cpu:.1f} | {len(r['cpu_net_runs'])} | {ratio} |")


if __name__ == "__main__":
    sys.exit(main())
