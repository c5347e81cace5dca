"""Tilting-table study (thesis Chapter 3): run the tilt cases and variations, tabulate and plot.

    python -m studies tilt --out results/tilt            # run everything, then report
    python -m studies tilt --out results/tilt --report   # report from saved results
    python -m studies tilt --out results/tilt --only rate # a subset (name substring)

Runs go through dask.distributed (``dem.batch``: one single-threaded worker per core).  Each run
writes ``<out>/runs/<name>/`` (summary.json, frames.npz; not committed); the collected numbers go
to ``<out>/results.json`` (rewritten as each run lands) and the report to ``<out>/README.md``
with PNG plots.  Resumable: a run already in results.json with status ok is not run again
(``--force`` reruns it).

Every specimen runs twice: with the case file's constant-rate tilt (2 deg/s; the rate study
varies it) and as a quasi-static tilt (``qs-<name>``: dem.run.quasi_static, its defaults), the
converged lambda the findings are read at (the 2 deg/s onset reads low while a wall leans).
"""

from __future__ import annotations

import json
import sys
import time
from pathlib import Path
from types import SimpleNamespace

import numpy as np
import typer

from dem.case import Case, load_case
from dem.output.plotting import agg_pyplot
from studies.kit import cli
from studies.kit.provenance import ROOT

CASES = ROOT / "cases" / "tilt"
RATES = (8.0, 4.0, 1.0, 0.5)  # deg/s, besides the default 2 deg/s of the case files

# thesis numbers quoted in the text (Section 3.4.1): L/H = 2.5, large bricks
THESIS_IN_PLANE = {"large-stretcher-flat-5x6": 0.48, "large-english-5x6": 0.45,
                   "large-stretcher-on-edge-5x4": 0.36}
THESIS_MECHANISM_IN_PLANE = {3.0: "sliding", 2.14: "sliding (leeward column overturns)",
                             1.0: "mixed (two columns overturn)", 0.75: "overturning dominant",
                             0.6: "pure overturning"}
THESIS_MECHANISM_OOP = {"no-wings": "A (lowest lambda)", "poor-poor": "A", "poor-good": "B1",
                        "poor-strong": "D", "strong-strong": "B2 (G on long facades)"}


def _variant(case: Case, name: str, **changes) -> Case:
    """A copy of a case with nested fields changed, e.g. loading={"rate": 1.0}."""
    data = case.model_dump()
    data["name"] = name
    for key, upd in changes.items():
        if isinstance(upd, dict):
            data[key] = {**(data[key] or {}), **upd}
        else:
            data[key] = upd
    return Case.model_validate(data)


QS_DURATION = 60.0  # s: a bound on the simulated time of a quasi-static run (they take 2-10 s)


def study_settings(case: Case, name: str) -> Case:
    """Output suited to a study: frames every 0.02 s, no VTK/PNG, long enough for slow rates."""
    angle_max = case.loading.max_angle
    duration = angle_max / case.loading.rate + 2.0 if case.loading.rate else QS_DURATION
    return _variant(case, name, run={"output_interval": 0.02, "vtk": False, "snapshot": False,
                                     "duration": duration})


def quasi_static_case(case: Case, name: str) -> Case:
    """The same specimen on a quasi-static tilt (the quasi_static defaults)."""
    data = case.model_dump()
    data["name"] = name
    ld = data["loading"]
    for key in ("rate", "step", "hold"):
        ld.pop(key, None)
    ld["method"] = "quasi_static"
    ld.pop("quasi_static", None)
    return Case.model_validate(data)


def build_runs() -> list[tuple[str, Case]]:
    runs: dict[str, Case] = {}
    for f in sorted((CASES / "in-plane").glob("*.yaml")):
        runs[f"ip-{f.stem}"] = load_case(f)
    for f in sorted((CASES / "out-of-plane").glob("*.yaml")):
        runs[f"oop-{f.stem}"] = load_case(f)
    base = load_case(CASES / "in-plane" / "small-5x15.yaml")
    # size effect: same L/H, more bricks
    for length, courses in ((3, 9), (7, 21), (3, 3), (7, 7)):
        runs[f"size-small-{length}x{courses}"] = _variant(
            base, f"size-small-{length}x{courses}",
            scene={"wall": {**base.scene.wall.model_dump(), "length": length, "courses": courses}})
    # friction
    for mu in (0.6, 1.0):
        runs[f"mu-{mu}-small-5x15"] = _variant(base, f"mu-{mu}-small-5x15",
                                               material={"friction": mu})
    # tilt rate
    for rate in RATES:
        for src in ("ip-small-5x7", "oop-large-5x9-no-wings"):
            runs[f"rate-{rate:g}-{src}"] = _variant(runs[src], f"rate-{rate:g}-{src}",
                                                    loading={"rate": rate})
    specimens = {n: c for n, c in runs.items() if not n.startswith("rate-")}
    for n, c in specimens.items():
        runs[f"qs-{n}"] = quasi_static_case(c, f"qs-{n}")
    return [(name, study_settings(c, name)) for name, c in runs.items()]


def _record(rec: dict) -> dict:
    """The numbers of one run that the report needs."""
    out = {"name": rec["name"], "status": rec["status"]}
    if rec["status"] != "ok":
        out["error"] = rec.get("error")
        return out
    s = rec["summary"]
    out.update({k: s.get(k) for k in ("n_blocks", "dt", "sim_time", "wall_seconds",
                                      "brick_steps_per_second")})
    out["loading"] = s["loading"]
    out["friction"] = s["material"]["friction"]
    out["collapse"] = {k: v for k, v in s.get("collapse", {}).items()
                       if k not in ("first_moving_blocks", "moved_blocks", "angles")}
    out["mechanism"] = s.get("mechanism")
    return out


def run_all(out: Path, only: str | None, workers: int | None, force: bool = False
            ) -> list[dict]:
    from dem.batch import run_batch
    from dem_cli.commands.run import RUN_ANALYSES
    from dem.output.atomic import write_json

    runs = build_runs()
    if only:
        runs = [(n, c) for n, c in runs if only in n]
    path = out / "results.json"
    old = {r["name"]: r for r in json.loads(path.read_text())} if path.exists() else {}
    if not force:
        runs = [(n, c) for n, c in runs if (old.get(n) or {}).get("status") != "ok"]
    t0 = time.perf_counter()

    def done(rec):
        col = (rec.get("summary") or {}).get("collapse", {})
        lam = col.get("load_factor")
        print(f"[{time.perf_counter() - t0:7.0f} s] {rec['name']}: {rec['status']}"
              + (f", lambda = {lam:.3f}" if lam is not None else "")
              + (f" ({rec.get('error')})" if rec["status"] != "ok" else ""), flush=True)
        old[rec["name"]] = _record(rec)
        write_json(path, list(old.values()), indent=1)  # resumable: each run as it lands

    print(f"{len(runs)} runs to do", flush=True)
    if runs:
        run_batch(runs, out / "runs", n_workers=workers, on_done=done, analyses=RUN_ANALYSES)
    return list(old.values())


# ------------------------------------------------------------------------------------------
def _lam(r):
    c = r.get("collapse") or {}
    return c.get("load_factor") if c.get("detected") else None


def rate_extrapolation(pts) -> float | None:
    """lambda as the rate r -> 0 from the three slowest rates (r, 2r, 4r), fitting
    lambda = lambda0 - c r^p exactly: the differences D1 = lambda(r) - lambda(2r) and
    D2 = lambda(2r) - lambda(4r) give 2^p = D2 / D1 and lambda0 = lambda(r) + D1 / (2^p - 1).
    None unless the three rates double and the differences shrink towards the slow end with
    one sign (|D2| > |D1|, D1 D2 > 0): c > 0 when a faster tilt reads low (the usual case),
    c < 0 when it reads high."""
    if len(pts) < 3:
        return None
    (r1, l1, *_), (r2, l2, *_), (r3, l3, *_) = pts[:3]
    if not (np.isclose(r2, 2 * r1) and np.isclose(r3, 2 * r2)):
        return None
    d1, d2 = l1 - l2, l2 - l3
    if not (d1 * d2 > 0 and abs(d2) > abs(d1)):
        return None
    return l1 + d1 / (d2 / d1 - 1.0)


def _rate_comment(extrapolated: dict) -> str:
    """The rate error of the default 2 deg/s, and the static check of the wall without wings."""
    from dem.builders.bricks import LARGE_SIZE, SMALL_DENSITY
    from dem.case import Material
    from postprocess.limit_analysis import elastic_tipping_factor

    static = elastic_tipping_factor(b=LARGE_SIZE[1], h=9 * LARGE_SIZE[2], density=SMALL_DENSITY,
                                    kn=Material(friction=0.81).normal_stiffness)
    txt = ("'vs rate -> 0': against lambda extrapolated to a vanishing rate from the three "
           "slowest rates (lambda = lambda0 - c r^p through the three points")
    txt += ("; " + ", ".join(f"{k}: lambda0 = {v:.4f}" for k, v in extrapolated.items())
            + ")." if extrapolated else "; not monotone here).")
    txt += (f"  Static check: the 5 x 9 facade without wings tips about its base as one body "
            f"(mechanism A); an elastic joint of the default stiffness lets it tip at "
            f"tan theta = b/h - (6 rho g b cos theta / (kn h))^(1/3) = {static:.4f} "
            f"(b/h = {LARGE_SIZE[1] / (9 * LARGE_SIZE[2]):.4f} rigid; "
            "postprocess/limit_analysis.py: elastic_tipping_factor).  The rate dependence is "
            "mostly the onset criterion's: the collapse is taken to start when a block moves at "
            "1 mm/s relative to the table (dem/collapse.py), and the elastic lean of a wall near "
            "its limit moves at (d lean / d theta) x rate, so a faster tilt crosses 1 mm/s "
            "earlier, before the equilibrium is actually lost.")
    return txt


def _converged_section(rate: dict, qs: dict) -> list[str]:
    """The specimens at their converged (quasi-static) lambda next to the 2 deg/s one."""
    if not qs:
        return []
    lines = ["## Converged lambda (quasi-static tilt)", "",
             "Every specimen again on a quasi-static tilt (dem/run/quasi_static.py, its defaults: "
             "1 deg increments relaxed to an unbalanced-force ratio below 1e-3, the first failing "
             "one bisected to 0.05 deg; lambda = tan of the last angle in equilibrium).  The "
             "findings are read at these values; the 2 deg/s tables below are the earlier record "
             "(the onset criterion reads them low, more so out of plane).", "",
             "| run | bricks | lambda 2 deg/s | lambda quasi-static | change | mechanism "
             "(quasi-static) | collapsed blocks | relaxations | wall time (s) |",
             "|---|---|---|---|---|---|---|---|---|"]
    for n in sorted(qs):
        r, q = rate.get(n, {}), qs[n]
        lam_r, lam_q = _lam(r) if r else None, _lam(q)
        m = q.get("mechanism") or {}
        label = m.get("mechanism") or m.get("kind") or "-"
        if m.get("kind") == "in-plane" and m.get("overturning_mass_fraction") is not None:
            label += f" ({m['overturning_mass_fraction']:.0%} overturning)"
        coll = (m.get("collapsed") or {}).get("n_blocks", "-")
        change = (f"{100 * (lam_q / lam_r - 1):+.1f} %" if lam_q and lam_r else "-")
        fmt = lambda x: f"{x:.4f}" if x is not None else "no collapse"  # noqa: E731
        lines.append(f"| {n} | {q.get('n_blocks', '-')} | {fmt(lam_r)} | {fmt(lam_q)} | "
                     f"{change} | {label} | {coll} | "
                     f"{(q.get('collapse') or {}).get('relaxations', '-')} | "
                     f"{q.get('wall_seconds') or 0:.0f} |")
    return lines + [""]


def report(out: Path) -> None:
    plt = agg_pyplot()

    from postprocess.limit_analysis import in_plane_limit

    from dem.case import Material, SolverSpec

    mat = Material(friction=0.81)
    every = {r["name"]: r for r in json.loads((out / "results.json").read_text())}
    res = {n: r for n, r in every.items() if not n.startswith("qs-")}  # the 2 deg/s record
    qs = {n.removeprefix("qs-"): r for n, r in every.items() if n.startswith("qs-")}
    lines = ["# Tilting-table study (thesis Chapter 3)", "",
             "Generated by `python -m studies tilt --out results/tilt` "
             "(runs, then this report; `--report` rebuilds the report from results.json).",
             "lambda = tan(tilt angle at the collapse onset, see dem/collapse.py); LA = limit "
             "analysis, eq 3-1..3-3 (postprocess/limit_analysis.py) with the brick friction; "
             f"joint stiffness {mat.normal_stiffness:.3g} Pa/m, shear "
             f"{mat.ks(mat.normal_stiffness):.3g} Pa/m, damping "
             f"{mat.damping} of critical, time-step safety {SolverSpec().safety} (the defaults), "
             "tilt rate 2 deg/s unless stated.", ""]

    lines += _converged_section(res, qs)
    # ---- in-plane table
    lines += ["## In plane (2 deg/s)", "",
              "| run | bricks | L/H | s/h | mu | lambda | LA sliding | LA overturning | LA mechanism "
              "| simulated mechanism | crack angle (deg from vertical) / bond angle | thesis |",
              "|---|---|---|---|---|---|---|---|---|---|---|---|"]
    ip = {n: r for n, r in res.items() if (r.get("mechanism") or {}).get("kind") == "in-plane"}
    for n, r in sorted(ip.items()):
        m = r["mechanism"]
        la = m.get("limit_analysis", {})
        crack = m.get("crack") or {}
        cr = (f"{crack['angle_from_vertical_deg']:.0f} / {crack.get('stagger_angle_deg', 0):.0f}"
              if crack else "-")
        stem = n.removeprefix("ip-")
        thesis = THESIS_IN_PLANE.get(stem)
        lh = la.get("l_over_h", np.nan)
        th_mech = THESIS_MECHANISM_IN_PLANE.get(round(lh, 2)) if n.startswith("ip-small-5x") else None
        lam = _lam(r)
        lines.append(
            f"| {n} | {r['n_blocks']} | {lh:.2f} | {la.get('s_over_h', np.nan):.2f} | "
            f"{r['friction']:.2f} | {lam:.3f} | {la.get('lambda_sliding', np.nan):.3f} | "
            f"{la.get('lambda_overturning', np.nan):.3f} | {la.get('mechanism', '-')} | "
            f"{m['mechanism']} ({m['overturning_mass_fraction']:.0%} overturning, "
            f"{m['n_moving']} blocks) | {cr} | "
            f"{(f'lambda {thesis}' if thesis else '') + (th_mech or '')} |"
            if lam is not None else f"| {n} | {r.get('n_blocks')} | no collapse | | | | | | | | | |")
    # ---- out-of-plane table
    lines += ["", "## Out of plane (2 deg/s)", "",
              "| run | bricks | lambda | mechanism | crack line (depth per column, courses) | "
              "wing bricks joined (left/right) | thesis |", "|---|---|---|---|---|---|---|"]
    for n, r in sorted(res.items()):
        m = r.get("mechanism") or {}
        if m.get("kind") != "out-of-plane" or n.startswith("rate-"):
            continue
        key = next((k for k in THESIS_MECHANISM_OOP if k in n), None)
        w = m.get("wing_bricks_joined", {})
        lines.append(f"| {n} | {r['n_blocks']} | {_lam(r):.3f} | {m['mechanism']} | "
                     f"{m['crack_shape']} {m['crack_depth_per_column']} of "
                     f"{m['facade_courses']} | {w.get('left', '-')}/{w.get('right', '-')} | "
                     f"{THESIS_MECHANISM_OOP.get(key, '')} |")
    # ---- rate study
    lines += ["", "## Convergence with the tilt rate", "",
              "| case | rate (deg/s) | lambda | onset angle (deg) | vs rate -> 0 | wall time (s) |",
              "|---|---|---|---|---|---|"]
    extrapolated = {}
    fig, ax = plt.subplots(figsize=(5, 3.5))
    for src in ("ip-small-5x7", "oop-large-5x9-no-wings"):
        pts = []
        for rate in (*RATES, 2.0):
            n = src if rate == 2.0 else f"rate-{rate:g}-{src}"
            if n in res and _lam(res[n]) is not None:
                pts.append((rate, _lam(res[n]), res[n]["wall_seconds"],
                            res[n]["collapse"]["angle_deg"]))
        pts.sort()
        lam0 = rate_extrapolation(pts)
        for rate, lam, wall, ang in pts:
            err = f"{100 * (lam / lam0 - 1):+.1f} %" if lam0 else "-"
            lines.append(f"| {src} | {rate:g} | {lam:.4f} | {ang:.2f} | {err} | {wall:.0f} |")
        if lam0:
            extrapolated[src] = lam0
        if pts:
            p = np.array(pts)
            ax.plot(p[:, 0], p[:, 1] / p[0, 1], "o-", label=f"{src} (/ lambda at {p[0, 0]:g})")
    lines += ["", _rate_comment(extrapolated)]
    ax.set_xscale("log")
    ax.set_xlabel("tilt rate (deg/s)")
    ax.set_ylabel("lambda / lambda at slowest rate")
    ax.legend(fontsize=7)
    fig.tight_layout()
    fig.savefig(out / "lambda_vs_rate.png", dpi=120)
    plt.close(fig)

    # ---- plots: lambda vs L/H with LA, vs s/h, vs bricks, vs mu
    fig, axs = plt.subplots(2, 2, figsize=(10, 7.5))
    ax = axs[0, 0]
    lh_runs = [(r["mechanism"]["limit_analysis"]["l_over_h"], _lam(r)) for n, r in ip.items()
               if n.startswith("ip-small-5x") and _lam(r) is not None]
    if lh_runs:
        p = np.array(sorted(lh_runs))
        ax.plot(p[:, 0], p[:, 1], "ko-", label="DEM (small, L = 5, s/h = 1.5)")
    lhs = np.linspace(0.5, 3.2, 60)
    las = [in_plane_limit(0.81, 1.5, x) for x in lhs]
    ax.plot(lhs, [a.lambda_sliding for a in las], "b--", label="LA sliding (mu 0.81)")
    ax.plot(lhs, [a.lambda_overturning for a in las], "r--", label="LA overturning")
    ax.set_xlabel("L/H")
    ax.set_ylabel("lambda")
    ax.legend(fontsize=7)
    ax = axs[0, 1]
    sh = [(r["mechanism"]["limit_analysis"]["s_over_h"], _lam(r)) for n, r in ip.items()
          if "9x15" in n and _lam(r) is not None]
    if sh:
        p = np.array(sorted(sh))
        ax.plot(p[:, 0], p[:, 1], "ko-", label="DEM (small, 9 x 15)")
    ax.set_xlabel("s/h")
    ax.set_ylabel("lambda")
    ax.legend(fontsize=7)
    ax = axs[1, 0]
    for lh_target, style in ((1.0, "o-"), (3.0, "s-")):
        pts = [(r["n_blocks"], _lam(r)) for n, r in ip.items()
               if (n.startswith("size-") or n.startswith("ip-small-5x"))
               and abs(r["mechanism"]["limit_analysis"]["l_over_h"] - lh_target) < 0.01
               and _lam(r) is not None]
        if pts:
            p = np.array(sorted(pts))
            ax.plot(p[:, 0], p[:, 1], style, label=f"L/H = {lh_target:g}")
    ax.set_xscale("log")
    ax.set_xlabel("blocks in the wall")
    ax.set_ylabel("lambda")
    ax.legend(fontsize=7)
    ax = axs[1, 1]
    mus = [(r["friction"], _lam(r)) for n, r in ip.items()
           if (n.startswith("mu-") or n == "ip-small-5x15") and _lam(r) is not None]
    if mus:
        p = np.array(sorted(mus))
        ax.plot(p[:, 0], p[:, 1], "ko-", label="DEM (small 5 x 15)")
        ax.plot(p[:, 0], [in_plane_limit(m, 1.5, 1.0).lambda_c for m in p[:, 0]], "r--",
                label="LA")
    ax.set_xlabel("friction mu")
    ax.set_ylabel("lambda")
    ax.legend(fontsize=7)
    fig.tight_layout()
    fig.savefig(out / "lambda_trends.png", dpi=120)
    plt.close(fig)
    lines += ["", "![trends](lambda_trends.png)", "", "![rate](lambda_vs_rate.png)", ""]
    if (out / "large-brick-diagnostic" / "README.md").is_file():
        lines += ["## The L/H = 2.5 large-brick walls on their exact layouts", "",
                  "Why they slide at mu where eq 3-2 gives overturning at 0.38 / 0.40: rigid-block "
                  "LP limit analysis and toe-rotation portions on the builder's blocks, and DEM "
                  "runs with the windward part held fixed, in "
                  "[large-brick-diagnostic/README.md](large-brick-diagnostic/README.md) "
                  "(`python -m studies large-brick --out "
                  "results/tilt/large-brick-diagnostic --dem all`); what they show: FINDINGS.md.",
                  ""]
    failed = [r for r in res.values() if r["status"] != "ok"]
    if failed:
        lines += ["## Failed runs", ""] + [f"- {r['name']}: {r.get('error')}" for r in failed]
    (out / "README.md").write_text("\n".join(lines) + "\n")


app = cli.study_app()


@app.command(help=cli.text(__doc__))
def tilt(out: Path = typer.Option(ROOT / "results" / "tilt"),
         only: str = typer.Option(None, help="run only runs whose name contains this"),
         workers: int = typer.Option(None),
         report_only: bool = typer.Option(False, "--report", help="only rebuild the report"),
         force: bool = typer.Option(False, "--force",
                                    help="rerun runs already in results.json")) -> None:
    _tilt(SimpleNamespace(out=out, only=only, workers=workers, report=report_only, force=force))


def main(argv=None) -> int:
    """``python -m studies tilt ARGV``; returns the exit code."""
    return cli.run(app, argv, "tilt")


def _tilt(args) -> None:
    args.out.mkdir(parents=True, exist_ok=True)
    if not args.report:
        run_all(args.out, args.only, args.workers, args.force)
    report(args.out)


if __name__ == "__main__":
    sys.exit(main())
