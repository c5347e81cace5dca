"""What each solver knob buys and costs: speed against error, on a tilt case and a
Model II shake case.

    python benchmarks/speed_error.py                  # all knobs, both cases (~1-2 h, 2 cores)
    python benchmarks/speed_error.py --case tilt-ip   # one case
    python benchmarks/speed_error.py --report         # rebuild the table/plot from the saved json

Cases (short versions of the thesis runs, so that every knob can be tried):
  tilt-ip   in-plane small-brick wall 5 x 7 (38 blocks), brought smoothly to 30 deg in 1 s, then
            2 deg/s; result: collapse load factor lambda
  tilt-oop  out-of-plane large-brick facade 5 x 9 without wings (49 blocks), 2 deg/s from 0;
            result: lambda
  shake-m2  Model II (217 blocks), y, 2.8 Hz, 1.53 m/s2 (thesis group 3), 4 cycles; result:
            amplitude and phase (first harmonic over the last two cycles) of the displacement
            of the facade's top-centre instrument (ds-centre) relative to the table
Every variant runs in a fresh process (thread count and precision are per process) and reports
wall-clock, CPU time (the machine is shared: CPU time is the steadier figure), brick-steps per
second and its error against the converged reference of its case (same physical parameters,
safety 0.05, i.e. dt 4x smaller than the default, f64).  Joint stiffness and damping are physical
parameters: their rows show how much the result depends on them, not a numerical error.
Writes benchmarks/speed_error.json, benchmarks/speed_error.md and benchmarks/speed_error.png.
"""

from __future__ import annotations

import argparse
import json
import os
import resource
import subprocess
import sys
import time
from concurrent.futures import ThreadPoolExecutor
from pathlib import Path

import numpy as np

HERE = Path(__file__).resolve().parent
ROOT = HERE.parent

CASES = {
    "tilt-ip": {
        "name": "tilt-ip", "scene": {"wall": {"brick": "small", "length": 5, "courses": 7}},
        "material": {"friction": 0.81, "base_friction": 1.5},
        "loading": {"type": "tilt", "axis": "y", "rate": 2.0, "start_angle": 30.0,
                    "start_time": 1.0, "max_angle": 45.0, "collapse": {"after": 0.3}},
        "run": {"duration": 8.5, "output_interval": 0.01, "vtk": False, "snapshot": False},
    },
    "tilt-oop": {
        "name": "tilt-oop", "scene": {"facade": {"brick": "large", "length": 5, "courses": 9}},
        "material": {"friction": 0.56},
        "loading": {"type": "tilt", "axis": "x", "rate": 2.0, "max_angle": 30.0,
                    "collapse": {"after": 0.3}},
        "run": {"duration": 8.0, "output_interval": 0.01, "vtk": False, "snapshot": False},
    },
    "shake-m2": {
        "name": "shake-m2", "scene": {"box_model": {"model": "II"}},
        "material": {"friction": 0.81, "base_friction": 1.5},
        "loading": {"type": "shake", "direction": [0, 1, 0], "frequency": 2.8,
                    "peak_acceleration": 1.53, "cycles": 4},
        "run": {"duration": 4 / 2.8, "output_interval": 0.02, "vtk": False, "snapshot": False},
    },
}

# variant name -> changes (dotted keys); "reference" is the converged run of each case
VARIANTS = {
    "reference": {"solver.safety": 0.05},
    "default": {},
    "safety 0.1": {"solver.safety": 0.1},
    "safety 0.3": {"solver.safety": 0.3},
    "safety 0.4": {"solver.safety": 0.4},
    "safety 0.6": {"solver.safety": 0.6},
    "kn 2e9": {"material.normal_stiffness": 2e9},
    "kn 1e10": {"material.normal_stiffness": 1e10},
    "kn 2e10": {"material.normal_stiffness": 2e10},
    "damping 0.1": {"material.damping": 0.1},
    "damping 0.3": {"material.damping": 0.3},
    "damping 0.7": {"material.damping": 0.7},
    "output 0.002 s": {"run.output_interval": 0.002},
    "output 0.05 s": {"run.output_interval": 0.05},
    "skin x0.3": {"solver.skin_factor": 0.3},
    "skin x3": {"solver.skin_factor": 3.0},
    "f32": {"solver.precision": "f32"},
    "parallel kernel, 2 threads": {"solver.mode": "parallel", "solver.threads": 2},
    "parallel kernel, 1 thread": {"solver.mode": "parallel", "solver.threads": 1},
    "patch reuse off": {"solver.patch_reuse": 0.0},
    "patch reuse 1e-7 m": {"solver.patch_reuse": 1e-7},
    "patch reuse 1e-6 m": {"solver.patch_reuse": 1e-6},
    "patch reuse 1e-5 m": {"solver.patch_reuse": 1e-5},
}


def _apply(case: dict, changes: dict) -> dict:
    case = json.loads(json.dumps(case))
    for key, value in changes.items():
        if key == "solver.skin_factor":
            continue  # resolved in the child (needs the default skin)
        node = case
        *path, last = key.split(".")
        for p in path:
            node = node.setdefault(p, {})
        node[last] = value
    return case


def run_variant(case_dict: dict, changes: dict) -> dict:
    """Child-process body: run one variant, return timing and result."""
    from dem.case import parse_case
    from dem.run import run_case

    case = parse_case(_apply(case_dict, changes))
    if "solver.skin_factor" in changes:
        from dem.run import scene_from_case

        sc = scene_from_case(case, check=False)
        case.solver.skin = changes["solver.skin_factor"] * 0.1 * float(0.5 * sc.size.min())
    cpu0 = resource.getrusage(resource.RUSAGE_SELF)
    t0 = time.perf_counter()
    res = run_case(case, progress=False)
    wall = time.perf_counter() - t0
    cpu1 = resource.getrusage(resource.RUSAGE_SELF)
    s = res.summary
    run_s = wall - s["compile_seconds"]
    cpu = (cpu1.ru_utime - cpu0.ru_utime) + (cpu1.ru_stime - cpu0.ru_stime)
    out = {"wall_s": wall, "run_s": run_s, "cpu_s": cpu, "compile_s": s["compile_seconds"],
           "steps": s["steps"], "n_blocks": s["n_blocks"], "dt": s["dt"],
           "brick_steps_per_s": s["n_blocks"] * s["steps"] / run_s, "status": s["status"],
           "energy_gain_rel": s["energy"]["gain"] / max(abs(s["energy"]["work_gravity"])
                                                        + abs(s["energy"]["work_base"]), 1e-30)}
    if "collapse" in s:
        out["lambda"] = s["collapse"].get("load_factor")
    if case.loading.type == "shake":
        out.update(_top_response(res, case))
    return out


def _top_response(res, case) -> dict:
    """Amplitude (m) and phase (deg) of ds-centre, first harmonic over the last two cycles."""
    from dem.instruments import InstrumentRecorder, thesis_instruments

    # instruments.npz is only written with an output dir; recompute ds-centre from the frames
    inst = [i for i in thesis_instruments(res.scene, "y") if i.name == "ds-centre"][0]
    rec = InstrumentRecorder([inst], res.scene)
    for k in range(len(res.t)):
        rec.sample(res.t[k], res.pos[k], res.quat[k], res.vel[k], np.zeros_like(res.vel[k]),
                   np.zeros(3), np.zeros(3))
    t = np.asarray(rec.rows["t"])
    y = np.asarray(rec.rows["disp"])[:, 0, 1]
    f = case.loading.frequency
    m = t >= t[-1] - 2.0 / f
    w = 2 * np.pi * f
    A = np.column_stack([np.ones(m.sum()), t[m], np.sin(w * t[m]), np.cos(w * t[m])])
    c = np.linalg.lstsq(A, y[m], rcond=None)[0]
    return {"amplitude_m": float(np.hypot(c[2], c[3])),
            "phase_deg": float(np.degrees(np.arctan2(c[3], c[2])))}


def _child(case_name: str, variant: str) -> dict:
    env = dict(os.environ)
    threads = VARIANTS[variant].get("solver.threads")
    env["DEM_THREADS"] = str(threads or 1)
    code = (f"import json, sys; sys.path.insert(0, {str(HERE)!r}); "
            f"from speed_error import run_variant, CASES, VARIANTS; "
            f"print('RESULT', json.dumps(run_variant(CASES[{case_name!r}], "
            f"VARIANTS[{variant!r}])))")
    out = subprocess.run([sys.executable, "-c", code], env=env, capture_output=True, text=True,
                         cwd=ROOT)
    commit = subprocess.run(["git", "rev-parse", "--short", "HEAD"], capture_output=True,
                            text=True, cwd=ROOT).stdout.strip()
    for line in out.stdout.splitlines():
        if line.startswith("RESULT "):
            return {"case": case_name, "variant": variant, **json.loads(line[7:]),
                    "measured": f"{time.strftime('%Y-%m-%d')} {commit}"}
    return {"case": case_name, "variant": variant, "status": "failed",
            "error": out.stderr[-1500:]}


def _errors(rows: list[dict]) -> None:
    """Add the error of every row against its case's reference."""
    ref = {r["case"]: r for r in rows if r["variant"] == "reference" and r.get("status") == "ok"}
    for r in rows:
        R = ref.get(r["case"])
        if R is None or r.get("status") != "ok":
            continue
        if "lambda" in r and r["lambda"] is not None and R.get("lambda"):
            r["error"] = abs(r["lambda"] - R["lambda"]) / R["lambda"]
        if "amplitude_m" in r and R.get("amplitude_m"):
            r["error"] = abs(r["amplitude_m"] - R["amplitude_m"]) / R["amplitude_m"]
            dphi = (r["phase_deg"] - R["phase_deg"] + 180) % 360 - 180
            r["phase_error_deg"] = abs(dphi)


DEFAULTS = """## The defaults and why (dem/case/settings.py)

Rows are marked with the day and commit they were measured at: the issue-7 rows ran the engine
before issue 10 (f32 clipping buffers, the box models' dt 9.6e-6 s); the references, the
defaults, the output and kernel rows were re-run after it (fd5247d).  An error is taken against
its case's current reference.

* `solver.safety` 0.3: every step from 0.05 to 0.4 gives the reference's result (tilt lambda to
  0.0003 % in plane and out of plane, the Model II amplitude to 0.13 %, its phase to 0.02 deg):
  the error left is the collapse detection's, not the integrator's.  Model II's amplitude moves by
  ~0.1 % with the last bit of its loads (the same default run before and after fd5247d, which
  changed only the round-off of the load times: 3.9814e-5 against 3.9789e-5 m), so its errors
  below ~0.1 % are round-off, not step size.  0.6 breaks the out-of-plane tilt (the resting
  facade jitters and is taken as collapsing at once, lambda = 0).  0.3 is the fastest setting
  with a factor 2 of margin below that failure; `pytest -m stability` passes at it.
* The box models' step (issue 10): light large-faced blocks (the roof beams) are capped at the
  smallest face area that keeps the stability margin, no longer at a brick's face: Model II dt
  9.6e-6 -> 1.445e-5 s at the same safety.
* `material.normal_stiffness` 5e9 Pa/m, `shear_stiffness` 0.4 kn, `damping` 0.5: physical
  parameters, chosen once for every model on physical grounds (docs/engine.md), not from these
  tables.  What they cost: lambda moves 1.5-6 % per factor 2 of kn (the elastic joints let the
  walls lean before they go), and Model II's sub-rocking response is the elastic deformation of
  the joints, so its amplitude goes as 1/kn.  A stiffer joint also costs dt ~ 1/sqrt(kn).
* `run.output_interval` 0.01 s and the neighbour-list skin (0.05 of the smallest edge): the
  trajectory does not depend on them (bit for bit since fd5247d); the results move only by the
  resolution of the measurement by the frames (the collapse time read every 0.002 or 0.05 s
  instead of 0.01 s: lambda 0.0-0.1 % and 0.3-0.8 %; the amplitude fitted to frames every 0.002
  or 0.05 s: within 0.06 %); frames every 0.002 s cost 10-30 % more.
* f64: f32 is not faster (the contact stage is latency-bound, not memory-bound) and it is wrong:
  the resting walls jitter, energy is created, lambda is 10 % and 40 % low, Model II's amplitude
  75 % high.
* Serial kernel: at these sizes (38-217 blocks) the parallel kernel gives the same results (bit
  for bit) 1.1-4.8x slower, on 1 or 2 threads: Taichi's thread-pool dispatch, 30-100 us per step,
  is most of a step here.  Auto mode takes it from 2500 blocks on 2-3 threads, from 500 on 4 or
  more (PARALLEL_MIN_BODIES, benchmarks/RESULTS.md).
* `solver.patch_reuse` 1e-7 m (issue 10; dem/engine/coherence.py): a closed flat joint keeps
  its contact polygon while its faces drift less than the tolerance in their plane (the depths
  are recomputed every step).  Rows of 2026-11-24, all in one session: 1.13-1.15x less CPU on
  the three cases at 1e-7 to 1e-5 m (the resting 9 x 15 wall: a step 124 -> 94 us, 1.3x;
  benchmarks/RESULTS.md).  Errors against the reference: in-plane lambda unchanged; out of plane
  unchanged at 1e-7, -0.26 % at 1e-6 and 1e-5 (one collapse-detection step); Model II amplitude
  0.21 / 0.18 / 0.56 % against the default's 0.14 % (its round-off sensitivity is ~0.1 %), phase
  within 0.05 deg.  1e-7 is the largest tolerance that changes neither tilt result here; it
  gains as much as the larger ones.  On the ten Chapter 3 small-brick walls on a quasi-static
  tilt (the calibration study's perfect reference, results/calibration, run before and after):
  lambda unchanged on 5, -0.13 % to +0.59 % on the other 5 (one to three steps of the
  quasi-static search, as round-off changes of the code move it: issue 11 found 6 of 25 walls
  within 0.5 % between code versions).  Perfect faces only: the imperfect (warped) kernels never
  reuse.
* Not built: sleeping blocks, a planar mode."""


# rows without a "measured" stamp: measured for issue 7, before the engine changes of issue 10
OLD_ROWS = "2026-11-22, issue 7"


def report(rows: list[dict]) -> None:
    from dem.output.plotting import agg_pyplot

    plt = agg_pyplot()

    _errors(rows)
    lines = ["# Speed against error (issues 7 and 10)", "",
             "Command: `python benchmarks/speed_error.py` (this file is written by it).  "
             "Machine: the project's 2-core test machine (shared; CPU time is the steadier "
             "figure).  Error: relative to the converged reference of each case (safety 0.05); "
             "tilt: collapse load factor; shake: amplitude of the facade top-centre displacement "
             "relative to the table (phase error in degrees).  kn and damping rows are physical "
             "parameters (dependence, not numerical error).", "", DEFAULTS, ""]
    fig, axs = plt.subplots(1, len(CASES), figsize=(5 * len(CASES), 4))
    for ax, case in zip(np.atleast_1d(axs), CASES):
        sub = [r for r in rows if r["case"] == case]
        if not sub:
            continue
        res_key = "amplitude_m" if case.startswith("shake") else "lambda"
        header = (f"| variant | measured (code) | dt (s) | wall (s) | CPU (s) | "
                  f"brick-steps/s (CPU) | "
                  f"{'amplitude (mm)' if res_key == 'amplitude_m' else 'lambda'} | error "
                  f"{'| phase error (deg) ' if res_key == 'amplitude_m' else ''}| energy gain |")
        lines += [f"## {case}", "", header, "|" + "---|" * (header.count("|") - 1)]
        for r in sub:
            if r.get("status") != "ok":
                lines.append(f"| {r['variant']} | failed: {r.get('error', '')[-120:]!r} |")
                continue
            val = r.get(res_key)
            val_s = (f"{1e3 * val:.4f}" if res_key == "amplitude_m" else f"{val:.4f}") \
                if val is not None else "-"
            err = r.get("error")
            bps = r["n_blocks"] * r["steps"] / max(r["cpu_s"] - r["compile_s"], 1e-9)
            lines.append(
                f"| {r['variant']} | {r.get('measured', OLD_ROWS)} | {r['dt']:.3g} | "
                f"{r['wall_s']:.0f} | {r['cpu_s']:.0f} | "
                f"{bps:.3g} | {val_s} | {f'{100 * err:.2f} %' if err is not None else '-'} "
                + (f"| {r.get('phase_error_deg', 0):.2f} " if res_key == "amplitude_m" else "")
                + f"| {r['energy_gain_rel']:.1e} |")
            if err is not None and r["variant"] != "reference":
                ax.scatter(r["cpu_s"], max(err, 1e-5), s=14)
                ax.annotate(r["variant"], (r["cpu_s"], max(err, 1e-5)), fontsize=6)
        lines.append("")
        ax.set_xscale("log")
        ax.set_yscale("log")
        ax.set_xlabel("CPU time (s)")
        ax.set_ylabel("relative error")
        ax.set_title(case)
    fig.tight_layout()
    fig.savefig(HERE / "speed_error.png", dpi=120)
    plot = "![speed vs error](speed_error.png)"
    lines += [plot, ""]
    # sections written by hand below the plot (other studies' rows) are kept as they are
    md = HERE / "speed_error.md"
    old = md.read_text() if md.exists() else ""
    tail = old.split(plot, 1)[1].lstrip("\n") if plot in old else ""
    md.write_text("\n".join(lines) + tail)
    (HERE / "speed_error.json").write_text(json.dumps(rows, indent=1))


def main():
    ap = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawTextHelpFormatter)
    ap.add_argument("--case", action="append", choices=list(CASES))
    ap.add_argument("--variant", action="append", choices=list(VARIANTS))
    ap.add_argument("--jobs", type=int, default=2, help="variants run at once (one core each)")
    ap.add_argument("--report", action="store_true", help="only rebuild from speed_error.json")
    args = ap.parse_args()
    path = HERE / "speed_error.json"
    rows = json.loads(path.read_text()) if path.exists() else []
    if not args.report:
        todo = [(c, v) for c in (args.case or CASES) for v in (args.variant or VARIANTS)]
        rows = [r for r in rows if (r["case"], r["variant"]) not in set(todo)]
        print(f"{len(todo)} runs, {args.jobs} at a time", flush=True)
        with ThreadPoolExecutor(args.jobs) as pool:
            for r in pool.map(lambda cv: _child(*cv), todo):
                print(f"{r['case']:9s} {r['variant']:28s} {r.get('status')} "
                      f"wall {r.get('wall_s', 0):.0f} s  lambda {r.get('lambda')} "
                      f"amp {r.get('amplitude_m')}", flush=True)
                rows.append(r)
                path.write_text(json.dumps(rows, indent=1))
    report(rows)


if __name__ == "__main__":
    main()
