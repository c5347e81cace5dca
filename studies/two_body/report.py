"""Tables of results/two-body/README.md: the two-block model against the thesis (Chapter 5).

    python -m studies two-body-report [--dem]        # markdown on stdout; --dem adds the DEM
                                                        # comparison (runs the DEM, dem.run)
    python -m studies two-body-report --top-contact  # section 9: the two top contacts
    python -m studies two-body-report --dem-sweep    # section 9: against the DEM's rocking
                                                        # sweep (reads results/shake/, runs no DEM)

A study above both models (it runs the two-body model and, with --dem, the DEM's run loop), so it
lives with the other studies in studies/ (shake, tilt), not in the model package
(tests/test_layers.py puts it in the top layer, with the commands and the studies).
Every number is computed here from the case files in cases/rocking/ and the closed forms of
dem.rocking.analysis; the thesis' numbers are quoted from ../shared/REFERENCE.md and the thesis.
"""

from __future__ import annotations

import math
import sys
from types import SimpleNamespace

import numpy as np
import typer

from dem.rocking import analysis as an
from dem.rocking.params import RockingParams
from dem.rocking.runner import run_rocking_case
from dem.rocking.schema import load_rocking_case
from dem.rocking.sweep import sweep
from studies.kit import cli
from studies.kit.provenance import ROOT

CASES = ROOT / "cases" / "rocking"
MODEL = {
    "II": dict(thickness=0.05, h1=0.14, m1=6.05, h2=0.14, m2=9.41),
    "III": dict(thickness=0.05, h1=0.175, m1=6.72, h2=0.21, m2=14.11),
}
# Experimental top amplitudes (m) of the back facade, from the thesis' amplification tables
# (Table 4.9 Model II y, Table 4.11 Model III y; amplification = peak-to-peak response /
# peak-to-peak input, so amplitude = amplification x input amplitude).
EXPERIMENT = {
    ("II", 2.4): 2.034 * 6.75e-3, ("II", 2.8): 2.120 * 4.69e-3,
    ("III", 2.0): 2.388 * 7.81e-3, ("III", 2.2): 2.266 * 6.46e-3, ("III", 2.8): 2.127 * 3.99e-3,
}
THESIS_ERROR = {("II", 1.8): 33.2, ("II", 2.0): 34.7, ("II", 2.4): 36.8, ("II", 2.8): 31.4,
                ("III", 2.0): 45.0, ("III", 2.4): 39.0, ("III", 2.8): 38.0}


def mm(x):
    return "-" if x is None or (isinstance(x, float) and math.isnan(x)) else f"{1e3 * x:.2f}"


def thresholds_table() -> str:
    rows = ["| model | top load N, mu | load point | uplift threshold, ours (m/s2) | "
            "thesis eq. 5-4 (m/s2) | Part 2 alone (m/s2) | Table 5.2 peak (m/s2) |",
            "|---|---|---|---|---|---|---|"]
    for name, peak in (("II", 1.53), ("III", 1.23)):
        for N, mu, lp in ((58.8, 0.81, "corner"), (58.8, 0.81, "centre"), (58.8, 0.0, "corner"),
                          (0.0, 0.0, "-")):
            P = RockingParams(**MODEL[name], top_load=N, top_friction=mu,
                              load_point=lp if lp != "-" else "corner")
            rows.append(f"| {name} | {N:g} N, {mu:g} | {lp} | {an.uplift_threshold(P):.2f} | "
                        f"{an.thesis_uplift_threshold(P):.2f} | {an.uplift_threshold(P, 'upper'):.2f}"
                        f" | {peak} |")
    return "\n".join(rows)


def friction_moments() -> str:
    out = []
    for name in ("II", "III"):
        P = RockingParams(**MODEL[name], top_load=58.8, top_friction=0.81)
        restoring = P.mass * P.gravity * P.thickness / 2 + P.top_load * P.thickness
        friction = P.Fmax * P.height
        out.append(f"| {name} | {restoring:.2f} | {friction:.2f} | {P.Fmax:.2f} |")
    return ("| model | restoring moment at rest, g M T/2 + N T (N m) | friction moment mu N H (N m) "
            "| mu N (N) |\n|---|---|---|---|\n" + "\n".join(out))


def case_row(stem: str):
    case = load_rocking_case(CASES / f"{stem}.yaml")
    P, exc, res, err = run_rocking_case(case)
    d = an.top_displacement(P, res.theta1, res.theta2)
    stats, _ = an.pattern_statistics(res.episodes, float(res.t[-1]))
    ci, cmax, cmin = an.cycle_amplitudes(res.t, d, exc.period, exc.t_end) if exc.period else ([], [], [])
    first = next((e["t"] for e in res.events if e["before"] == "rest"), None)
    return case, P, exc, res, d, stats, (ci, cmax, cmin), first


def thesis_cases_table() -> str:
    rows = ["| case | f (Hz) | A (mm) | peak (m/s2) | ours: status | ours: uplift at | ours: max abs d (mm) "
            "| thesis: amplitude | experiment amplitude (mm) | ours vs experiment | thesis vs experiment |",
            "|---|---|---|---|---|---|---|---|---|---|---|"]
    stems = ([f"model-ii-{f:.1f}hz" for f in (1.8, 2.0, 2.4, 2.8)]
             + [f"model-iii-{f:.1f}hz" for f in (2.0, 2.2, 2.4, 2.8)]
             + ["case3-model-ii-2.8hz-8mm", "case3-model-ii-2.8hz-11mm"]
             + [f"case4-model-ii-n0-{f:.1f}hz" for f in (1.8, 2.0, 2.4, 2.8)]
             + [f"case5-model-ii-e1-{f:.1f}hz" for f in (1.8, 2.0, 2.4, 2.8)])
    thesis_amp = {"model-ii-1.8hz": "~10 mm", "model-ii-2.4hz": "~15 mm (largest)",
                  "model-ii-2.0hz": "10-15 mm", "model-ii-2.8hz": "10-15 mm; theta1 ~0.05 rad",
                  "model-iii-2.2hz": "solver failed", "case3-model-ii-2.8hz-8mm": "grows with A",
                  "case3-model-ii-2.8hz-11mm": "grows with A", "case4-model-ii-n0-1.8hz":
                  "Pattern 3 only, irregular", "case5-model-ii-e1-2.8hz": "larger, fewer Pattern 2"}
    for stem in stems:
        case, P, exc, res, d, stats, _, first = case_row(stem)
        model = "III" if stem.startswith("model-iii") else "II"
        f = exc.frequency
        exp = EXPERIMENT.get((model, f)) if stem.startswith("model-") else None
        ours_err = (f"{100 * abs(np.abs(d).max() - exp) / exp:.0f} %" if exp else "-")
        th_err = (f"{THESIS_ERROR[(model, f)]:.1f} % (mean)" if stem.startswith("model-")
                  and (model, f) in THESIS_ERROR else "-")
        rows.append(f"| {stem} | {f:g} | {1e3 * exc.amplitude:.2f} | {exc.peak_acceleration:.2f} | {res.status} | "
                    f"{'never' if first is None else f'{first:.3f} s'} | {1e3 * np.abs(d).max():.2f} | "
                    f"{thesis_amp.get(stem, '10-15 mm' if model == 'II' and stem.startswith('model') else 'see text')} | "
                    f"{mm(exp) if exp else '-'} | {ours_err} | {th_err} |")
    return "\n".join(rows)


def supra_threshold_table() -> str:
    """What the model does above its threshold: status, amplitudes, patterns."""
    rows = ["| model | N (N), mu | f (Hz) | peak / threshold | status (t) | steady amplitude +/- (mm) | "
            "impacts | pattern time fractions | occurrences |",
            "|---|---|---|---|---|---|---|---|---|"]
    specs = []
    for name, N, mu in (("II", 0.0, 0.0), ("II", 58.8, 0.81), ("III", 0.0, 0.0), ("III", 58.8, 0.81)):
        for fac in (1.05, 1.2, 1.5):
            for f in (2.0, 2.8, 4.0):
                specs.append((name, N, mu, fac, f))
    for name, N, mu, fac, f in specs:
        P = RockingParams(**MODEL[name], top_load=N, top_friction=mu)
        thr = an.uplift_threshold(P)
        r = sweep(P, [f], peak_acceleration=fac * thr)[0]
        pats = ", ".join(f"{k} {100 * v:.0f}%" for k, v in r["patterns"].items() if v >= 0.005)
        occ = ", ".join(f"{k} {v}" for k, v in r["occurrences"].items() if k != "rest")
        status = r["status"] if r["status"] == "ok" else f"{r['status']} ({r['t_end']:.2f} s)"
        amp = f"+{mm(r['amp_pos'])} / {mm(r['amp_neg'])}" if r["status"] == "ok" else "-"
        rows.append(f"| {name} | {N:g}, {mu:g} | {f:g} | {fac:.2f} | {status} | {amp} | "
                    f"{r['impacts']} | {pats} | {occ} |")
    return "\n".join(rows)


def frequency_sweep_table() -> str:
    P = RockingParams(**MODEL["II"])
    freqs = np.linspace(1.5, 6.0, 20)
    rows = sweep(P, freqs, peak_acceleration=1.84)
    out = ["| f (Hz) | A (mm) | status | steady amplitude + / - (mm) | impacts |", "|---|---|---|---|---|"]
    for r in rows:
        st = r["status"] if r["status"] == "ok" else f"collapsed at {r['t_end']:.2f} s"
        out.append(f"| {r['frequency']:.2f} | {1e3 * r['amplitude']:.2f} | {st} | "
                   f"{mm(r['amp_pos'])} / {mm(r['amp_neg'])} | {r['impacts']} |")
    return "\n".join(out)


#: the two-block release of tests/test_rocking_vs_dem.py: thickness T, heights H1 / H2 (m),
#: masses M1 / M2 (kg), length along y (m; the model is planar), initial rotation THETA0 (rad)
RELEASE = {"T": 0.05, "H1": 0.14, "H2": 0.14, "M1": 6.05, "M2": 9.41, "LENGTH": 0.3,
           "THETA0": 0.02}


def released_block(h: float, zc: float, m: float, r: dict = RELEASE) -> dict:
    """A block of the stack (height h, centre height zc before the rotation, mass m) rotated by
    THETA0 about the base pivot (x, z) = (T/2, 0): its case-file block entry."""
    t, th = r["T"], r["THETA0"]
    cx, cz = -t / 2, zc
    return {"size": [t, r["LENGTH"], h],
            "position": [t / 2 + cx * math.cos(th) + cz * math.sin(th), 0.0,
                         -cx * math.sin(th) + cz * math.cos(th)],
            "rotation": [0.0, math.degrees(th), 0.0], "mass": m}


def tilt_about_y(quat) -> np.ndarray:
    """Rotation angle (rad) about +y (top towards +x) of unit quaternions (w, x, y, z)."""
    w, x, y, z = quat[..., 0], quat[..., 1], quat[..., 2], quat[..., 3]
    return np.arcsin(np.clip(2.0 * (w * y - z * x), -1.0, 1.0))


def dem_comparison() -> str:
    """Two blocks released from 0.02 rad: zero crossings of theta1, DEM vs reduced model."""
    from dem.case import parse_case
    from dem.rocking.integrate import Settings, integrate_rocking
    from dem.run import run_case as run_dem_case
    from dem.table_motion import TableMotion

    r = RELEASE
    P = RockingParams(thickness=r["T"], h1=r["H1"], m1=r["M1"], h2=r["H2"], m2=r["M2"])
    red = integrate_rocking(P, TableMotion(), Settings(duration=0.8),
                            (r["THETA0"], r["THETA0"], 0, 0))
    case = parse_case({
        "name": "two-block-release",
        "scene": {"blocks": [released_block(r["H1"], r["H1"] / 2, r["M1"]),
                             released_block(r["H2"], r["H1"] + r["H2"] / 2, r["M2"])]},
        "material": {"friction": 2.0}, "loading": {"type": "none"},
        "run": {"duration": 0.8, "output_interval": 0.0005}})
    dem = run_dem_case(case)
    th = tilt_about_y(dem.quat)
    s = np.sign(th[:, 0])
    idx = np.flatnonzero(np.diff(s) != 0)
    t_dem = [dem.t[i] + (dem.t[i + 1] - dem.t[i]) * th[i, 0] / (th[i, 0] - th[i + 1, 0]) for i in idx]
    t_red = [e["t"] for e in red.events if e["kind"] == "impact_base"]
    # amplitude of each half-cycle
    def lobes(t, x):
        sgn = np.sign(x)
        cut = np.flatnonzero(np.diff(sgn) != 0) + 1
        return [float(np.max(np.abs(x[seg]))) for seg in np.split(np.arange(len(x)), cut) if len(seg)]
    a_dem = lobes(dem.t, th[:, 0])
    a_red = lobes(red.t, red.theta1)
    rel = np.abs(th[:, 1] - th[:, 0]).max()
    out = ["| impact k | reduced t_k (s) | DEM t_k (s) | difference | reduced amplitude after (rad) | "
           "DEM amplitude after (rad) |", "|---|---|---|---|---|---|"]
    for k in range(min(len(t_red), len(t_dem), 5)):
        out.append(f"| {k + 1} | {t_red[k]:.4f} | {t_dem[k]:.4f} | {100 * (t_dem[k] - t_red[k]) / t_red[k]:+.1f} % "
                   f"| {a_red[k + 1] if k + 1 < len(a_red) else float('nan'):.4f} | "
                   f"{a_dem[k + 1] if k + 1 < len(a_dem) else float('nan'):.4f} |")
    out.append(f"\nLargest relative rotation of the two DEM blocks: {rel:.2e} rad (Pattern 3 throughout; "
               f"the reduced model stays in Pattern 3 too). DEM: dt = {dem.summary['dt']:.3g} s, "
               f"{dem.summary['steps']} steps.")
    return "\n".join(out)


# ------------------------------------------------------------------------------------------
# the two top contacts: the thesis' sliding roof and one that moves with the facade top
# ------------------------------------------------------------------------------------------
THESIS_STEMS = ([f"model-ii-{f:.1f}hz" for f in (1.8, 2.0, 2.4, 2.8)]
                + [f"model-iii-{f:.1f}hz" for f in (2.0, 2.2, 2.4, 2.8)]
                + ["case3-model-ii-2.8hz-8mm", "case3-model-ii-2.8hz-11mm"]
                + [f"case4-model-ii-n0-{f:.1f}hz" for f in (1.8, 2.0, 2.4, 2.8)]
                + [f"case5-model-ii-e1-{f:.1f}hz" for f in (1.8, 2.0, 2.4, 2.8)])


def top_contact_thresholds_table() -> str:
    """Closed-form uplift thresholds of both top contacts, Table 5.1 parts, N = 58.8 N."""
    rows = ["| model | top contact | whole wall, Pattern 3 (m/s2) | Part 2 alone, Pattern 4 (m/s2) | "
            "locked-pair restitution r | Table 5.2 peak (m/s2) |", "|---|---|---|---|---|---|"]
    for name, peak in (("II", "1.45-1.53"), ("III", "1.23")):
        for tc in ("sliding", "co-moving"):
            P = RockingParams(**MODEL[name], top_load=58.8, top_friction=0.81, top_contact=tc)
            th = an.uplift_thresholds(P)
            rows.append(f"| {name} | {tc} | {th['whole']:.3f} | {th['upper']:.3f} | "
                        f"{an.housner_restitution(P):.4f} | {peak} |")
    return "\n".join(rows)


def top_contact_cases_table() -> str:
    """The thesis' cases with each top contact: status, uplift, amplitude, patterns, errors."""
    rows = ["| case | peak (m/s2) | top contact | threshold (m/s2) | status | uplift at (s) | "
            "max abs d (mm) | steady +/- (mm) | patterns (time) | impacts base/iface/top | "
            "beam friction demand abs(H)/V (abs(theta) <= atan(T/H); impulses) | experiment (mm) | ours vs experiment | "
            "thesis vs experiment |", "|---|---|---|---|---|---|---|---|---|---|---|---|---|---|"]
    for stem in THESIS_STEMS:
        for tc in ("sliding", "co-moving"):
            case = load_rocking_case(CASES / f"{stem}.yaml", {"rocking": {"top_contact": tc}})
            P, exc, res, err = run_rocking_case(case)
            d = an.top_displacement(P, res.theta1, res.theta2)
            stats, _ = an.pattern_statistics(res.episodes, float(res.t[-1]))
            first = next((e["t"] for e in res.events if e["before"] == "rest"), None)
            ci, cmax, cmin = an.cycle_amplitudes(res.t, d, exc.period,
                                                 min(exc.t_end, float(res.t[-1]) + 1e-12))
            steady = "-"
            if res.status == "ok" and len(ci):
                half = ci >= (ci.max() + 1) / 2
                steady = f"+{mm(float(np.mean(cmax[half])))} / {mm(float(np.mean(cmin[half])))}"
            model = "III" if stem.startswith("model-iii") else "II"
            exp = EXPERIMENT.get((model, exc.frequency)) if stem.startswith("model-") else None
            ours = abs(float(np.abs(d).max()) - exp) / exp if exp else None
            th_err = THESIS_ERROR.get((model, exc.frequency)) if stem.startswith("model-") else None
            pats = ", ".join(f"{k} {100 * v['time_fraction']:.0f}%" for k, v in stats.items()
                             if v["time_fraction"] >= 0.005)
            st = res.status if res.status != "collapsed" else f"collapsed ({res.t[-1]:.2f} s)"
            dem = "-"
            if P.comoving and first is not None:
                fd = an.top_friction_demand(P, res, exc, stride=2)
                dem = (f"{fd['rocking_max_abs_H_over_V']:.2f} rocking, "
                       f"{fd['impact_max_abs_H_over_V']:.2f} impacts")
            s = res.stats
            rows.append(
                f"| {stem} | {exc.peak_acceleration:.2f} | {tc} | {an.uplift_thresholds(P)['governing']:.2f} | {st} | "
                f"{'never' if first is None else f'{first:.3f}'} | {1e3 * np.abs(d).max():.1f} | {steady} | "
                f"{pats} | {s['impacts_base']}/{s['impacts_interface']}/{s.get('impacts_top', 0)} | {dem} | "
                f"{mm(exp) if exp else '-'} | {'-' if ours is None else f'{100 * ours:.0f} %'} | "
                f"{'-' if th_err is None else f'{th_err:.1f} %'} |")
    return "\n".join(rows)


def top_contact_sweep_table(freqs=None) -> str:
    """Frequency sweeps at constant peak acceleration with the co-moving roof: Model III at the
    tests' 1.23 m/s2, and both models at 1.05 and 1.2 x their co-moving threshold."""
    freqs = np.round(np.linspace(1.5, 6.0, 19), 2) if freqs is None else freqs
    out = []
    specs = [("III", 1.23, "1.23 m/s2 (the tests)")]
    for name in ("II", "III"):
        P = RockingParams(**MODEL[name], top_load=58.8, top_contact="co-moving")
        thr = an.uplift_threshold(P)
        for fac in (1.05, 1.2):
            specs.append((name, fac * thr, f"{fac:.2f} x threshold = {fac * thr:.2f} m/s2"))
    header = "| f (Hz) | " + " | ".join(f"Model {n}, {lab}" for n, _, lab in specs) + " |"
    out.append(header)
    out.append("|---|" + "---|" * len(specs))
    cols = []
    for name, peak, _ in specs:
        P = RockingParams(**MODEL[name], top_load=58.8, top_contact="co-moving")
        cols.append(sweep(P, freqs, peak_acceleration=peak))
    for i, f in enumerate(freqs):
        cells = []
        for col in cols:
            r = col[i]
            if r["status"] == "ok":
                cells.append("rest" if r["impacts"] == 0 and r["max_abs_disp"] == 0 else
                             f"+{mm(r['amp_pos'])} / {mm(r['amp_neg'])}")
            else:
                cells.append(f"{r['status']} {r['t_end']:.1f} s")
        out.append(f"| {f:.2f} | " + " | ".join(cells) + " |")
    return "\n".join(out)


app = cli.study_app()


@app.command(help=cli.text(__doc__))
def two_body_report(
        dem: bool = typer.Option(False, "--dem", help="also run the DEM comparison (Taichi)"),
        top_contact: bool = typer.Option(False, "--top-contact",
                                         help="only the tables comparing the two top contacts "
                                              "(sliding, co-moving)"),
        dem_sweep: bool = typer.Option(False, "--dem-sweep",
                                       help="only the comparison with the DEM's Model II y 4.0 "
                                            "m/s2 sweep (studies.two_body.vs_dem_sweep; reads "
                                            "results/shake/, runs no DEM)")) -> None:
    _report(SimpleNamespace(dem=dem, top_contact=top_contact, dem_sweep=dem_sweep))


def main(argv=None) -> int:
    """``python -m studies two-body-report ARGV`` (Markdown on stdout); returns the exit
    code."""
    return cli.run(app, argv, "two-body-report")


def _report(args) -> None:
    if args.dem_sweep:
        from studies.two_body.vs_dem_sweep import comparison

        print("## The two-body model against the DEM's rocking sweep (Model II y, 4.0 m/s2)\n")
        print(comparison())
        return
    if args.top_contact:
        print("## Uplift thresholds of the two top contacts\n")
        print(top_contact_thresholds_table())
        print("\n## Thesis cases with each top contact\n")
        print(top_contact_cases_table())
        print("\n## Frequency sweep with the co-moving roof\n")
        print(top_contact_sweep_table())
        return
    print("## Uplift thresholds\n")
    print(thresholds_table())
    print("\n## Top friction against the restoring moment\n")
    print(friction_moments())
    print("\n## Thesis cases 1-5\n")
    print(thesis_cases_table())
    print("\n## Above the threshold\n")
    print(supra_threshold_table())
    print("\n## Frequency sweep, Model II without top load, 1.84 m/s2\n")
    print(frequency_sweep_table())
    if args.dem:
        print("\n## DEM against the reduced model: release from 0.02 rad\n")
        print(dem_comparison())


if __name__ == "__main__":
    sys.exit(main())
