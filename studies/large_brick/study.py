"""Why the thesis' L/H = 2.5 walls of large bricks slide in the DEM (the thesis' tests
read 0.36-0.48, below the friction 0.56).

    python -m studies large-brick --out results/tilt/large-brick-diagnostic
    python -m studies large-brick --out ... --dem all   # also the DEM runs
    python -m studies large-brick --out ... --dem on-edge-free-mu1.5  # or some
The thesis' limit analysis (Section 3.4.2, eq 3-1..3-3, D'Ayala and Speranza 2003;
postprocess.limit_analysis) gives OVERTURNING at lambda = tan(alpha_b) / 2 = 0.38 (English bond,
s/h = 0.76) and 0.40 (stretcher bond on edge, s/h = 0.8) for these walls (eq 3-2b at the bond
angle tan(alpha_b) = s/h, alpha from the vertical): a continuum wedge cut off by a stepped
crack from the leeward bottom corner at the bond angle, turning about that corner.  The DEM
walls slide at lambda = mu = 0.56.  This module checks the mechanisms on the EXACT blocks the
builder lays (dem.run.build.scene_from_case), with postprocess.block_limit:

* the rigid-block LP limit analysis (equilibrium, no tension, Coulomb; Gilbert and Melbourne
  1994) of the in-plane (x-z) projection: the largest lambda at which any admissible set of
  contact forces exists.  Three variants: head joints with the brick friction, frictionless
  head joints (the thesis' crack takes no friction) and no head joints at all (blocks push on
  each other through their beds only).  Load along +x (the cases' tilt about +y) and along -x
  (the same wall built mirrored);
* every 'leeward wedge': a course k, a head joint of it, the blocks from there to the leeward
  end and everything resting on them (the smallest portion that can turn rigidly about its toe
  without lifting a block that stays behind), turning about the toe (x_end, z_k):
  lambda_rot = sum W_i (x_p - x_i) / sum W_i (z_i - z_p) (frictionless crack, as eq 3-2b);
* the mean step a crack that climbs windward through the head joints must take per course
  (upward closure forces it: English bond alternates 37.5 and 114.5 mm, stretcher on edge 60
  and 92 mm, i.e. half a brick, 76 mm, per course in both), and eq 3-2 with that effective
  stagger in place of the short overlap s;
* the thesis' crack line drawn on the exact blocks (blocks whose centroid lies leeward of
  x = x_end - (s/h) z): its rotation factor and whether it is admissible (blocks that stay
  behind resting on it).

DEM diagnostics (``--dem``; quasi-static tilt about +y, the case's material unless stated; each
run in ``--runs``, default /tmp/large-brick-diagnostic-runs, only summary numbers kept): the
exact blocks as an explicit-block case, free (the case itself); with every block outside the
thesis' crack portion (and what rests on it) fixed (``fixed: true``: held to the table; its
contacts keep the brick friction); and both with the friction raised to 1.5 everywhere
(sliding suppressed: a check that the DEM turns a portion at its rigid-block value; a
diagnostic, not a model of the test).

Units: m, kg, load factor lambda = a/g = tan(tilt angle) (dimensionless).
"""

from __future__ import annotations

import json
import os
import subprocess
import sys
import time
from pathlib import Path
from types import SimpleNamespace

import numpy as np
import typer

from dem.case import load_case
from dem.output.plotting import agg_pyplot
from dem.run.build import scene_from_case
from postprocess.block_limit import (Blocks2D, crack_profile, leeward_wedges, lp_limit,
                                     rotation_factor, upward_closure)
from postprocess.limit_analysis import in_plane_limit
from studies.kit import cli
from studies.kit.provenance import ROOT

CASES = ROOT / "cases" / "tilt" / "in-plane"
WALLS = {  # name: (case file, s/h of the thesis' analysis, thesis lambda)
    "large-english-5x6": ("large-english-5x6.yaml", 0.76, 0.45),
    "large-stretcher-flat-5x6": ("large-stretcher-flat-5x6.yaml", 1.5, 0.48),
    "large-stretcher-on-edge-5x4": ("large-stretcher-on-edge-5x4.yaml", 0.8, 0.36),
    "large-stretcher-on-edge-5x6": ("large-stretcher-on-edge-5x6.yaml", 1.0, None),
}
# the small-brick walls whose DEM overturns: the same analysis, as a check of the LP against
# the DEM (results/tilt/results.json, quasi-static lambda)
CHECKS = {"small-5x15": 1.5, "small-5x20": 1.5, "small-5x25": 1.5, "small-9x15-s10": 0.29,
          "small-9x15-s35": 1.0, "small-9x15-s52.5": 1.5}


def exact_blocks(case_file: str):
    case = load_case(CASES / case_file)
    scene = scene_from_case(case)
    return case, scene, Blocks2D.from_scene(scene)


def thesis_crack_portion(bl: Blocks2D, s_over_h: float, course_height: float) -> np.ndarray:
    """Blocks whose centroid lies leeward of the thesis' crack line x = x_end - (s/h) z."""
    x_end = bl.hi[:, 0].max()
    c = bl.centroid
    return (~bl.fixed) & (c[:, 0] > x_end - s_over_h * c[:, 2])


def lifted_blocks(bl: Blocks2D, portion) -> list[int]:
    """Blocks outside ``portion`` that rest on a block of it (a rigid rotation of the portion
    about its toe would have to lift them: the portion is not admissible alone)."""
    return [int(i) for i in np.flatnonzero(upward_closure(bl, np.flatnonzero(portion)) & ~portion)]


def course_height(bl: Blocks2D) -> float:
    return float(np.median(bl.hi[:, 2] - bl.lo[:, 2]))


def analyse_wall(name: str, case_file: str, s_over_h: float) -> dict:
    case, scene, bl = exact_blocks(case_file)
    mu, mub = case.material.friction, case.material.mu_base
    h = course_height(bl)
    length = bl.hi[:, 0].max() - bl.lo[:, 0].min()
    height = bl.hi[:, 2].max()
    out = {"n_blocks": bl.n, "mu": mu, "mu_base": mub, "course_height_m": h,
           "l_over_h": length / height, "s_over_h_thesis": s_over_h,
           "eq3": in_plane_limit(mu, s_over_h, length / height).as_dict()}
    t0 = time.process_time()
    lp = {}
    for label, mh in (("head_friction_mu", None), ("head_frictionless", 0.0),
                      ("no_head_joints", -1.0)):
        for d, dname in ((1.0, "+x"), (-1.0, "-x")):
            r = lp_limit(bl, mu, mub, direction=d, mu_head=mh)
            lp[f"{label} {dname}"] = {"load_factor": r.load_factor,
                                      "moving_blocks": int(r.moving().sum())}
    # the builder's 0.7-0.8 mm head gaps of the English header courses taken as closed
    r = lp_limit(bl, mu, mub, head_gap=2e-3)
    lp["head_friction_mu, gaps up to 2 mm closed +x"] = {"load_factor": r.load_factor,
                                                         "moving_blocks": int(r.moving().sum())}
    # no sliding possible anywhere: what turning alone needs (a diagnostic of the geometry)
    r = lp_limit(bl, 100.0, 100.0, mu_head=0.0)
    lp["friction 100, head frictionless +x"] = {"load_factor": r.load_factor,
                                                "moving_blocks": int(r.moving().sum())}
    out["lp"] = lp
    wedges = leeward_wedges(bl)
    out["wedges_best5"] = [{k: v for k, v in w.items() if k != "blocks"} for w in wedges[:5]]
    # the load along -x: the same wedges of the mirrored wall
    lo_m, hi_m = bl.lo.copy(), bl.hi.copy()
    lo_m[:, 0], hi_m[:, 0] = -bl.hi[:, 0], -bl.lo[:, 0]
    mirrored = Blocks2D(lo_m, hi_m, bl.mass, bl.fixed)
    out["wedges_best_load_minus_x"] = {k: v for k, v in leeward_wedges(mirrored)[0].items()
                                       if k != "blocks"}
    w0 = [w for w in wedges if w["course"] == 0]
    if w0:
        # the wedge from the leeward bottom block: its crack profile and mean step per course
        best0 = min(w0, key=lambda w: w["load_factor"])
        portion = np.zeros(bl.n, bool)
        portion[best0["blocks"]] = True
        prof = crack_profile(bl, portion)
        x_min = bl.lo[:, 0].min()
        # steps until the crack reaches the windward end (beyond it the wedge is the whole width)
        reach = [k for k, x in enumerate(prof) if x <= x_min + 1e-6]
        last = reach[0] if reach else len(prof) - 1
        steps = -np.diff(prof[: last + 1])
        out["bottom_wedge"] = {"load_factor": best0["load_factor"], "crack_x_per_course": prof,
                               "steps_m": steps.tolist(),
                               "mean_step_over_h": float(np.mean(steps) / h)}
        s_eff = float(np.mean(steps) / h)
        out["eq3_effective_stagger"] = in_plane_limit(mu, s_eff, length / height).as_dict()
    tp0 = thesis_crack_portion(bl, s_over_h, h)
    # admissible alone only with what rests on it: the DEM diagnostic frees that closure
    tp = upward_closure(bl, np.flatnonzero(tp0)) if tp0.any() else tp0
    if tp.any():
        low = tp & (bl.lo[:, 2] <= bl.lo[tp, 2].min() + 1e-6)
        pivot = np.array([bl.hi[low, 0].max(), bl.lo[tp, 2].min()])
        out["thesis_crack_portion"] = {
            "blocks_on_line": np.flatnonzero(tp0).tolist(),
            "load_factor_rotation_on_line": rotation_factor(bl, tp0, pivot),
            "lifted_blocks_outside": lifted_blocks(bl, tp0),
            "blocks": np.flatnonzero(tp).tolist(), "pivot": pivot.tolist(),
            "mass_share": float(bl.mass[tp].sum() / bl.mass.sum()),
            "load_factor_rotation": rotation_factor(bl, tp, pivot)}
        fixed = bl.fixed | ~tp
        held = Blocks2D(bl.lo, bl.hi, bl.mass, fixed)
        # head joints with friction against fixed blocks can clamp the portion without limit
        # (the fixed blocks push as hard as needed): the LP is then unbounded (None)
        for key, mh in (("lp_rest_fixed", None), ("lp_rest_fixed_head_frictionless", 0.0)):
            out["thesis_crack_portion"][key] = {}
            for m in (mu, 1.5):
                r = lp_limit(held, m, max(mub, m), mu_head=mh)
                out["thesis_crack_portion"][key][f"mu {m:g}"] = (
                    r.load_factor if r.status == "optimal" else None)
    out["cpu_seconds"] = time.process_time() - t0
    return out


def plot_layouts(res: dict, path: Path) -> None:
    """The three thesis walls as the builder lays them (x-z, front wythe on top where two
    overlap): the thesis' crack line from the leeward toe at tan = s/h (dashed), the blocks left
    of it that rest on the portion (hatched: they would have to be lifted), and the smallest
    portion that can turn about its toe (shaded), with its lambda_rot."""
    plt = agg_pyplot()
    from matplotlib.patches import Rectangle

    names = ["large-english-5x6", "large-stretcher-flat-5x6", "large-stretcher-on-edge-5x4"]
    fig, axes = plt.subplots(1, 3, figsize=(15, 3.6))
    for ax, name in zip(axes, names):
        case_file, s_over_h, thesis = WALLS[name]
        _, _, bl = exact_blocks(case_file)
        r = res[name]
        tp = r["thesis_crack_portion"]
        portion = set(tp["blocks"])
        on_line = set(tp["blocks_on_line"])
        best = r["wedges_best5"][0]
        for i in np.argsort(-bl.lo[:, 1]):  # back wythe first
            x0, z0 = bl.lo[i, 0] * 1e3, bl.lo[i, 2] * 1e3
            w, h = (bl.hi[i, 0] - bl.lo[i, 0]) * 1e3, (bl.hi[i, 2] - bl.lo[i, 2]) * 1e3
            face = "tab:orange" if i in portion else "0.9"
            ax.add_patch(Rectangle((x0, z0), w, h, facecolor=face, edgecolor="k", lw=0.6,
                                   hatch="///" if i in portion - on_line else None))
        x_end, top = bl.hi[:, 0].max() * 1e3, bl.hi[:, 2].max() * 1e3
        ax.plot([x_end, x_end - s_over_h * top], [0, top], "b--", lw=1.5,
                label=f"thesis crack tan = s/h = {s_over_h:g}: eq 3-2 "
                      f"{r['eq3']['lambda_overturning']:.2f}")
        ax.plot(*(np.array(tp["pivot"]) * 1e3), "ko")
        lp = r["lp"]["head_frictionless +x"]["load_factor"]
        ax.set_title(f"{name}: thesis {thesis}, DEM {r['dem_quasi_static_lambda']:.3f}\n"
                     f"shaded portion turns at {tp['load_factor_rotation']:.3f} (best wedge "
                     f"{best['load_factor']:.3f}); LP {lp:.3f}", fontsize=8)
        ax.set_xlim(-400, 400)
        ax.set_ylim(-10, 320)
        ax.set_aspect("equal")
        ax.set_xlabel("x, mm (load along +x)")
        ax.legend(fontsize=7, loc="upper left")
    axes[0].set_ylabel("z, mm")
    fig.tight_layout()
    fig.savefig(path, dpi=110)
    plt.close(fig)


# --- DEM diagnostics --------------------------------------------------------------------------
def diagnostic_case(case, scene, fixed, name: str, friction: float | None = None) -> dict:
    """The exact blocks as an explicit-block case (``fixed`` [N] held), on the quasi-static
    tilt about +y; ``friction`` replaces the brick and base friction when given."""
    from dem.scene import scene_to_blocks

    blocks = scene_to_blocks(scene, groups=False)
    for b, held in zip(blocks, fixed):
        b.update({"fixed": True, "group": "held"} if held else {"group": "wall"})
    mat = {"friction": case.material.friction, "base_friction": case.material.mu_base}
    if friction is not None:
        mat = {"friction": friction, "base_friction": max(friction, case.material.mu_base)}
    return {"name": name, "description": "issue 11 item 5 diagnostic "
            "(studies/large_brick/study.py)",
            "scene": {"blocks": blocks}, "material": mat,
            "loading": {"type": "tilt", "axis": "y", "max_angle": 60.0},
            "run": {"duration": 60.0, "output_interval": 0.05, "vtk": False,
                    "snapshot": False}}


def dem_configs() -> dict:
    """name -> (wall, which blocks are free, friction override)."""
    out = {}
    for wall in ("large-english-5x6", "large-stretcher-on-edge-5x4"):
        short = "english" if "english" in wall else "on-edge"
        out[f"{short}-free"] = (wall, "all", None)  # the case itself, as explicit blocks
        out[f"{short}-thesis-crack-rest-fixed"] = (wall, "thesis", None)
        out[f"{short}-thesis-crack-rest-fixed-mu1.5"] = (wall, "thesis", 1.5)
        out[f"{short}-free-mu1.5"] = (wall, "all", 1.5)
    return out


def run_dem(name: str, runs: Path) -> dict:
    import yaml

    wall, which, friction = dem_configs()[name]
    case_file, s_over_h, _ = WALLS[wall]
    case, scene, bl = exact_blocks(case_file)
    if which == "thesis":
        tp0 = thesis_crack_portion(bl, s_over_h, course_height(bl))
        free = upward_closure(bl, np.flatnonzero(tp0))
    else:
        free = ~bl.fixed
    data = diagnostic_case(case, scene, ~free, name, friction)
    runs.mkdir(parents=True, exist_ok=True)
    path = runs / f"{name}.yaml"
    path.write_text(yaml.safe_dump(data, sort_keys=False))
    out_dir = runs / name
    dem_exe = Path(sys.executable).with_name("dem")
    env = {**os.environ, "DEM_THREADS": os.environ.get("DEM_THREADS", "1")}
    import resource

    t0 = time.time()
    cpu0 = resource.getrusage(resource.RUSAGE_CHILDREN)
    proc = subprocess.run([str(dem_exe), "run", str(path), "--out", str(out_dir), "--force",
                           "--no-progress"], env=env, capture_output=True, text=True)
    wall_s = time.time() - t0
    cpu1 = resource.getrusage(resource.RUSAGE_CHILDREN)
    cpu_s = (cpu1.ru_utime - cpu0.ru_utime) + (cpu1.ru_stime - cpu0.ru_stime)
    summ = json.loads((out_dir / "summary.json").read_text())
    col = summ.get("collapse", {})
    mech = summ.get("mechanism") or {}
    rec = {"wall": wall, "free_blocks": int(free.sum()), "held_blocks": int((~free).sum()),
           "friction": data["material"]["friction"],
           "base_friction": data["material"]["base_friction"], "status": summ["status"],
           "rc": proc.returncode, "load_factor": col.get("load_factor"),
           "angle_deg": col.get("angle_deg"), "failed_angle_deg": col.get("failed_angle_deg"),
           "n_moved": col.get("n_moved"), "moved_blocks": col.get("moved_blocks"),
           "mechanism": {k: mech.get(k) for k in ("kind", "mechanism", "overturning_share",
                                                  "n_turning", "turning_mass_fraction")
                         if k in mech},
           "collapsed_blocks": (mech.get("collapsed") or {}).get("blocks"),
           "max_motion_m": mech.get("max_motion_m"),
           "quasi_static_criterion": col.get("criterion"),
           "wall_seconds": wall_s, "cpu_seconds": cpu_s,
           "sim_wall_seconds": summ.get("wall_seconds")}
    # what the free blocks did at the end: mean slide and rotation (from the last frame)
    try:
        fr = np.load(out_dir / "frames.npz")
        pos, quat = fr["pos"], fr["quat"]
        from dem import quaternion

        d = pos[-1] - pos[0]
        rot = quaternion.rotation(quat[-1]).as_rotvec()
        idx = np.flatnonzero(free)
        rec["final_mean_dx_m"] = float(d[idx, 0].mean())
        rec["final_mean_dz_m"] = float(d[idx, 2].mean())
        rec["final_mean_rot_y_rad"] = float(rot[idx, 1].mean())
    except Exception as exc:  # noqa: BLE001 - the numbers above stand without it
        rec["frames_error"] = str(exc)
    return rec


def report(out: Path) -> None:
    """``out``/README.md: the tables of limit_analysis.json and dem_runs.json."""
    res = json.loads((out / "limit_analysis.json").read_text())
    dpath = out / "dem_runs.json"
    dem = json.loads(dpath.read_text()) if dpath.exists() else {}

    def f(v, n=3):
        return "-" if v is None else f"{v:.{n}f}"

    lines = ["# The thesis' L/H = 2.5 large-brick walls on their exact layouts (issue 11 item 5)",
             "", "Generated by `python -m studies large-brick --out "
             "results/tilt/large-brick-diagnostic --dem all` (`--report`: this page from the "
             "JSON).  Equations and definitions: the docstrings of "
             "studies/large_brick/study.py and postprocess/block_limit.py; findings: "
             "[../FINDINGS.md](../FINDINGS.md).  Load along +x (leeward end at +x) unless "
             "stated; lambda = a/g.", "",
             "## Limit analysis", "",
             "| wall | mu | thesis | eq 3-2 (s/h) | mean crack step / h | eq 3-2 at that step "
             "| best turning portion (+x / -x) | thesis' line on the blocks | LP: heads mu / "
             "frictionless / none | DEM quasi-static |",
             "|---|---|---|---|---|---|---|---|---|---|"]
    for name, r in res.items():
        lp = r["lp"]
        tp = r.get("thesis_crack_portion") or {}
        line = (f"{f(tp.get('load_factor_rotation_on_line'))}"
                + (f" ({len(tp.get('lifted_blocks_outside', []))} blocks rest on it; with "
                   f"them {f(tp.get('load_factor_rotation'))})"
                   if tp.get("lifted_blocks_outside") else ""))
        bw = r.get("bottom_wedge") or {}
        lines.append(
            f"| {name} | {r['mu']:g} | {f(r.get('thesis_lambda'), 2)} | "
            f"{f(r['eq3']['lambda_c'])} {r['eq3']['mechanism']} ({r['s_over_h_thesis']:g}) | "
            f"{f(bw.get('mean_step_over_h'), 2)} | "
            f"{f((r.get('eq3_effective_stagger') or {}).get('lambda_c'))} | "
            f"{f(r['wedges_best5'][0]['load_factor'])} / "
            f"{f(r['wedges_best_load_minus_x']['load_factor'])} | {line} | "
            f"{f(lp['head_friction_mu +x']['load_factor'])} / "
            f"{f(lp['head_frictionless +x']['load_factor'])} / "
            f"{f(lp['no_head_joints +x']['load_factor'])} | "
            f"{f(r.get('dem_quasi_static_lambda'))} |")
    lowest = {n: min(v["load_factor"] for k, v in r["lp"].items() if "friction 100" not in k)
              for n, r in res.items() if n.startswith("large")}
    lines += ["", "LP over both load directions and all three head-joint variants: "
              + ", ".join(f"{n} {v:.3f}" for n, v in lowest.items()) + ".", ""]
    if dem:
        lines += ["## DEM diagnostics (quasi-static tilt about +y)", "",
                  "| run | free blocks | friction (base) | lambda | angle (deg) | mechanism | "
                  "blocks that went | CPU s |", "|---|---|---|---|---|---|---|---|"]
        for name, d in dem.items():
            went = d.get("collapsed_blocks") or d.get("moved_blocks") or []
            shown = went if len(went) <= 16 else str(went[:8])[:-1] + ", ...]"
            lines.append(f"| {name} | {d['free_blocks']} | {d['friction']:g} "
                         f"({d['base_friction']:g}) | {f(d['load_factor'], 4)} | "
                         f"{f(d['angle_deg'], 2)} | {(d.get('mechanism') or {}).get('mechanism')}"
                         f" | {len(went)}: {shown}"
                         f" | {f(d.get('cpu_seconds'), 1)} |")
    lines += ["", "![layouts](layouts.png)", ""]
    (out / "README.md").write_text("\n".join(lines))


app = cli.study_app()


@app.command(help=cli.text(__doc__.split("\n\n")[0]))
def large_brick(out: Path = typer.Option(...),
                dem: str = typer.Option(None, help="'all' or a comma list of DEM diagnostics to "
                                                   "run (dem_configs)"),
                runs: Path = typer.Option(Path("/tmp/large-brick-diagnostic-runs")),
                report_only: bool = typer.Option(False, "--report",
                                                 help="only README.md from the JSON")) -> None:
    _large_brick(SimpleNamespace(out=out, dem=dem, runs=runs, report=report_only))


def main(argv=None) -> int:
    """``python -m studies large-brick ARGV``; returns the exit code."""
    return cli.run(app, argv, "large-brick")


def _large_brick(args) -> None:
    args.out.mkdir(parents=True, exist_ok=True)
    if args.report:
        report(args.out)
        return
    path = args.out / "limit_analysis.json"
    res = {}
    for name, (f, sh, thesis) in WALLS.items():
        res[name] = analyse_wall(name, f, sh)
        res[name]["thesis_lambda"] = thesis
    qs = {}
    rj = ROOT / "results" / "tilt" / "results.json"
    if rj.exists():
        qs = {r["name"]: r for r in json.loads(rj.read_text())}
    for name, sh in CHECKS.items():
        res[name] = analyse_wall(name, f"{name}.yaml", sh)
        r = qs.get(f"qs-ip-{name}") or {}
        res[name]["dem_quasi_static_lambda"] = (r.get("collapse") or {}).get("load_factor")
    for name in WALLS:
        r = qs.get(f"qs-ip-{name}") or {}
        res[name]["dem_quasi_static_lambda"] = (r.get("collapse") or {}).get("load_factor")
    path.write_text(json.dumps(res, indent=1, default=float))
    print(f"wrote {path}")
    plot_layouts(res, args.out / "layouts.png")
    for name, r in res.items():
        lp = r["lp"]
        print(f"{name:30s} eq3 {r['eq3']['lambda_c']:.3f} ({r['eq3']['mechanism']}), "
              f"eq3 eff {r.get('eq3_effective_stagger', {}).get('lambda_c', float('nan')):.3f}, "
              f"LP {lp['head_friction_mu +x']['load_factor']:.3f} / "
              f"{lp['head_frictionless +x']['load_factor']:.3f} / "
              f"{lp['no_head_joints +x']['load_factor']:.3f}, "
              f"best wedge {r['wedges_best5'][0]['load_factor']:.3f}, "
              f"DEM {r.get('dem_quasi_static_lambda')}")
    if args.dem:
        dpath = args.out / "dem_runs.json"
        done = json.loads(dpath.read_text()) if dpath.exists() else {}
        for name in dem_configs():
            if args.dem != "all" and name not in args.dem.split(","):
                continue
            print(f"DEM {name} ...", flush=True)
            t0 = time.time()
            done[name] = run_dem(name, args.runs)
            print(f"  -> lambda {done[name]['load_factor']}, {time.time() - t0:.0f} s", flush=True)
            dpath.write_text(json.dumps(done, indent=1))
    report(args.out)


if __name__ == "__main__":
    sys.exit(main())
