"""``python -m studies impact-dissipation``: the command line of the study (the protocol:
studies/impact_dissipation/__init__.py).
"""

from __future__ import annotations

import json
import math
import os
import sys
import time
from pathlib import Path
from types import SimpleNamespace

import numpy as np
import typer

from studies.kit import cli
from studies.kit.provenance import ROOT
from studies.impact_dissipation.dem_runs import run_block, run_portion, run_stack
from studies.impact_dissipation.physics import BRICK
from studies import impact_dissipation
from studies.impact_dissipation.report import (compact_json, markdown_tables, plot_histories,
                                                rounded_record)
from studies.impact_dissipation.two_body import two_body_forced, two_body_free, two_body_params


app = cli.study_app()


@app.command(help=cli.text(impact_dissipation.__doc__.split("\n\n")[0]))
def impact_dissipation_command(
        out: str = typer.Option("results/prediction/impact-dissipation"),
        parts: str = typer.Option("abcd", help="which parts to run (a, b, c, d)"),
        portion_duration: float = typer.Option(1.2),
        tables: bool = typer.Option(False, "--tables",
                                    help="print the README's tables from OUT/summary.json and "
                                         "stop")) -> None:
    _impact_dissipation(SimpleNamespace(out=out, parts=parts, portion_duration=portion_duration,
                                        tables=tables))


def main(argv=None) -> int:
    """``python -m studies impact-dissipation ARGV``; returns the exit code."""
    return cli.run(app, argv, "impact-dissipation")


def _impact_dissipation(args) -> dict | None:
    """The parts of ``args.parts`` into ``args.out``/summary.json; returns the summary (None
    after --tables)."""
    if args.tables:
        print(markdown_tables(json.loads((Path(args.out) / "summary.json").read_text())))
        return None
    os.environ.setdefault("DEM_THREADS", "1")
    out = Path(args.out)
    out.mkdir(parents=True, exist_ok=True)
    summary_path = out / "summary.json"
    summary = json.loads(summary_path.read_text()) if summary_path.exists() else {}
    hist = {}
    cpu = summary.setdefault("cpu_s", {})

    if "a" in args.parts:
        t0 = time.process_time()
        L, W, H = BRICK
        blocks = {
            "brick-on-end-35": (H, W, L, 0.5, 0.6),      # b = 35, h = 105 mm (b/h = 1/3)
            "brick-on-end-50": (W, H, L, 0.5, 0.6),      # b = 50, h = 105 mm
            "excited-portion-block": (0.05, 0.30, 0.28, 0.5, 2.5),   # b/h = 50 / 280
        }
        res = {}
        for name, (b, depth, h, frac, dur) in blocks.items():
            r = run_block(b, h, depth, frac=frac, duration=dur)
            hist["a:" + name] = r
            res[name] = rounded_record(r)
            print(f"a {name}: b/h {b/h:.3f} Housner r {r['housner_r']:.4f} amp {r['housner_first_amplitude_ratio']:.4f}"
                  f" | DEM amp {r['mean_amplitude_ratio']} r_eq {r['mean_r_eq']} omega {r['mean_omega_ratio']}"
                  f" cpu {r['cpu_s']:.1f}", flush=True)
        for name, kw in (("two-block-stack", {}), ("two-block-stack-friction-2", {"friction": 2.0})):
            r = run_stack(**kw)
            hist["a:" + name] = r
            res[name] = rounded_record(r)
            print(f"a {name}: Housner r {r['housner_r']:.4f} amp {r['housner_first_amplitude_ratio']:.4f}"
                  f" | DEM amp {np.round(r['amplitude_ratio'], 4)} r_eq {r['mean_r_eq']}"
                  f" cpu {r['cpu_s']:.1f}", flush=True)
        summary["a_blocks"] = res
        cpu["a"] = time.process_time() - t0

    if "b" in args.parts:
        t0 = time.process_time()
        res = {}
        variants = {
            "upper-tilt": dict(free="upper", start="tilt"),
            "upper-tilt-no-side-walls": dict(free="upper", start="tilt", side_walls=False),
            "upper-tilt-quarter": dict(free="upper", start="tilt", frac=0.25),
            "portion-kick": dict(free="portion", start="kick"),
        }
        for name, kw in variants.items():
            r = run_portion(ROOT, duration=args.portion_duration, **kw)
            hist["b:" + name] = r
            res[name] = rounded_record(r)
            print(f"b {name}: Housner r {r['housner_r_outer_to_inner']:.4f} | DEM peaks "
                  f"{np.round(r['peaks_rad'], 4)} amp {np.round(r['amplitude_ratio'], 3)} "
                  f"r_eq {np.round(r['r_eq'], 3)} same-side {np.round(r['r_eq_same_side'], 3)} up/lo {r['max_rotation_upper_rad']:.4f} / "
                  f"{r['max_rotation_lower_rad']} cpu {r['cpu_s']:.1f}", flush=True)
        # the two-body model's own impact map on the same bodies: the DEM's masses (upper 10.08
        # kg, lower 4.368 kg, H1 = H2 = 140 mm) and Table 5.1's; the upper part tilted alone
        # (Pattern 4 start, as "upper-tilt") and the pair kicked from upright (as "portion-kick")
        tb = {}
        up, pk_ = res["upper-tilt"], res["portion-kick"]
        for label, masses in (("dem-masses", (4.368, 10.08)), ("table-5.1", "table-5.1")):
            P = two_body_params(masses)
            for kind, init, meas in (
                    ("upper-tilt", (0.0, up["theta0_rad"], 0.0, 0.0), "upper"),
                    ("portion-kick", (0.0, 0.0, -pk_["omega0_rad_s"], -pk_["omega0_rad_s"]),
                     "whole")):
                r = two_body_free(P, init, measure=meas)
                hist[f"b:two-body:{label}:{kind}"] = r
                tb[f"{label}|{kind}"] = rounded_record(r)
                print(f"b two-body {label} {kind}: peaks {np.round(r['peaks_rad'], 4)} amp "
                      f"{np.round(r['amplitude_ratio'], 3)} r_eq {np.round(r['r_eq'], 3)}",
                      flush=True)
        res["two_body_free"] = tb
        summary["b_portion"] = res
        cpu["b"] = time.process_time() - t0

    if "c" in args.parts:
        t0 = time.process_time()
        # the DEM's measured restitutions: a monolithic block of the portion's b/h (part a) and
        # the brick-built upper part in its seat, with and without the side walls (part b)
        laws = {"housner": "housner",
                "dem-block": round(summary["a_blocks"]["excited-portion-block"]["mean_r_eq"], 3),
                "dem-upper-no-side-walls": round(
                    summary["b_portion"]["upper-tilt-no-side-walls"]["mean_r_eq"], 3),
                "dem-upper-side-walls": round(
                    summary["b_portion"]["upper-tilt"]["mean_r_eq_same_side"], 3)}
        freqs = [2.0, 2.2, 2.4, 2.6, 2.8, 3.0, 3.2, 3.4, 3.6, 3.8, 4.0]
        scenarios = {
            "thesis-sliding-1.53": (two_body_params("table-5.1", 58.8, 0.81, "sliding"), 1.53),
            "co-moving-1.53": (two_body_params("table-5.1", 58.8, 0.81, "co-moving"), 1.53),
            "co-moving-1.98": (two_body_params("table-5.1", 58.8, 0.81, "co-moving"), 1.98),
            "no-load-1.84": (two_body_params("table-5.1"), 1.84),
            "co-moving-4.0": (two_body_params("table-5.1", 58.8, 0.81, "co-moving"), 4.0),
        }
        res = {"laws": laws, "frequencies_hz": freqs, "cycles": 20, "runs": {}}
        for sname, (P, acc) in scenarios.items():
            for lname, law in laws.items():
                rows = [two_body_forced(P, f, acc, law, cycles=20) for f in freqs]
                res["runs"][f"{sname}|{lname}"] = rows
                print(sname, lname, [(r['f_hz'], r['status'], r['amplification'] and round(r['amplification'], 2)) for r in rows], flush=True)
        summary["c_two_body"] = res
        cpu["c"] = time.process_time() - t0

    if "d" in args.parts:
        t0 = time.process_time()
        res = {"zetas": [0.1, 0.3, 0.5, 0.7, 0.9], "block": {}, "stack": {}, "upper": {},
               "upper-no-side-walls": {}, "point_restitution": {}}
        for z in res["zetas"]:
            # normal restitution of a point contact with damping ratio z (docs/engine.md)
            res["point_restitution"][str(z)] = math.exp(-math.pi * z / math.sqrt(1 - z * z))
            r = run_block(0.05, 0.28, 0.30, 0.5, damping=z, duration=1.6)
            hist[f"d:block:{z}"] = r
            res["block"][str(z)] = rounded_record(r)
            r2 = run_stack(damping=z)
            hist[f"d:stack:{z}"] = r2
            res["stack"][str(z)] = rounded_record(r2)
            print(f"d zeta {z}: block amp {r['mean_amplitude_ratio']:.4f} r_eq {r['mean_r_eq']:.4f}"
                  f" | stack amp {r2['mean_amplitude_ratio']:.4f} r_eq {r2['mean_r_eq']:.4f}",
                  flush=True)
        for z in (0.1, 0.9):
            for key, sw in (("upper", True), ("upper-no-side-walls", False)):
                r = run_portion(ROOT, "upper", "tilt", side_walls=sw, damping=z,
                                duration=args.portion_duration)
                hist[f"d:{key}:{z}"] = r
                res[key][str(z)] = rounded_record(r)
                print(f"d {key} zeta {z}: peaks {np.round(r['peaks_rad'], 4)} amp "
                      f"{np.round(r['amplitude_ratio'], 3)} same-side "
                      f"{np.round(r['r_eq_same_side'], 3)}", flush=True)
        summary["d_damping"] = res
        cpu["d"] = time.process_time() - t0

    summary_path.write_text(compact_json(rounded_record(summary)) + "\n")
    if set("abcd") <= set(args.parts):
        plot_histories(hist, summary, out / "impact-dissipation.png")
    np.savez_compressed("/tmp/impact_dissipation_histories.npz",
                        **{k + "|t": v["_t"] for k, v in hist.items()},
                        **{k + "|theta": v["_theta"] for k, v in hist.items()})
    return summary


if __name__ == "__main__":
    sys.exit(main())
