"""The two-body model against the DEM's rocking sweep, where the DEM rocks (a
comparison at the thesis' level would only compare two resting models).

    python -m studies two-body-vs-dem        # markdown on stdout, ~10 s
    python -m studies two-body-report --dem-sweep  # the same

The DEM rocks only in one shaking study: Model II, y, 4.0 m/s2 constant peak acceleration, 10
cycles + 1 s margin at 1.8, 2.0, 2.4, 2.8, 3.2, 3.6 Hz (results/shake/model-ii-y-amplified/,
FINDINGS.md section 2).  This module READS those result files (sweep.json and each point's
analysis.json; the DEM engine is not run) and runs the two-body model with Model II's Table 5.1
parts at the same peak acceleration, frequencies, cycle count and margin, with both top contacts.

The DEM's measure is the amplification of ds (postprocess/signal_analysis.py, Section 4.2.5):

    A_ds = (P - N) / (P_in - N_in)

ds = displacement RELATIVE TO THE TABLE of the transducer point, on the facade's centre brick of
the penultimate course (course 8 of 9, mid-height: z = 7.5 x 35 mm = 262.5 mm above the table;
dem/instruments.py); P, N = means over the steady cycles of the per-cycle max / min; P_in, N_in
the same for the table displacement; the steady window is cycle 0 dropped, then the first cycle
from which every per-cycle peak-to-peak lies within 25 % of their median.  The same functions
(postprocess.signal_analysis.steady_window / amplification / phase_lag) are applied here to the two-body
output, so the two numbers are computed by one code path.

Where ds sits in the two-body model: Table 5.1's parts are 4 + 4 courses (H1 = H2 = 140 mm) of a
9-course (315 mm) facade, i.e. the parts above the bottom course (the DEM's excited portion is
likewise the top 8 courses).  The model's base is therefore at z = 35 mm and the transducer at
Z_S = 227.5 mm above it, in Part 2, 87.5 mm above the interface:

    ds = H1 sin(theta1) + (Z_S - H1) sin(theta2)

(the same small-offset approximation as the thesis' top displacement, eq. 5-31, which is also
reported).  Both models take displacement positive along +y (the table's axis) and the same
table motion u = A sin(2 pi f t), so the lags compare directly.

Besides Table 5.1's parts, the model is also run with the masses of the DEM's own excited portion
at 2.8 Hz (30 upper bricks 10.08 kg, 13 lower bricks 4.37 kg, read from analysis.json): a check
of how much the mass split matters, not a fit (nothing is adjusted to the DEM's response).
"""

from __future__ import annotations

import json
import math
import sys
from pathlib import Path

import numpy as np
import typer

from dem.rocking import analysis as an
from dem.rocking.integrate import RockingError, Settings, integrate_rocking
from dem.rocking.params import RockingParams
from dem.table_motion import SineMotion
from postprocess.signal_analysis import amplification, cycle_extrema, phase_lag, steady_window
from studies.kit import cli
from studies.kit.provenance import ROOT

DEM_SWEEP = ROOT / "results" / "shake" / "model-ii-y-amplified"
TABLE_5_1_II = dict(thickness=0.05, h1=0.14, m1=6.05, h2=0.14, m2=9.41)
TOP_LOAD, TOP_FRICTION = 58.8, 0.81
COURSE = 0.035             # m, course height of Model II (small bricks; 9 courses = 315 mm)
MODEL_BASE = 1 * COURSE    # the two parts are the top 8 courses: base on top of course 1
Z_S = 7.5 * COURSE - MODEL_BASE   # ds transducer: mid-height of course 8, above the model base
SAMPLE = 0.001             # s, uniform grid for the analysis (the DEM's instruments: 2 ms)


def load_dem(sweep_dir: Path = DEM_SWEEP) -> tuple[dict, list[dict]]:
    """The DEM sweep's settings and one dict per frequency, from sweep.json and analysis.json."""
    sw = json.loads((sweep_dir / "sweep.json").read_text())
    rows = []
    for p in sw["points"]:
        a = json.loads((sweep_dir / p["dir"] / "analysis.json").read_text())
        y = a["axes"]["y"]
        q = y["quantities"]["ds"]
        ex = y["excited_portion"]
        rows.append({
            "f": p["frequency_hz"], "A": p["amplitude_m"], "A_ds": q["amplification"],
            "P": q["positive_amplitude"], "N": q["negative_amplitude"], "lag_s": q["lag_s"],
            "max_abs_ds": y["max_abs_ds_m"], "collapse_suspected": y["collapse_suspected"],
            "warnings": a.get("warnings", []), "response": y["mechanism"].get("response"),
            "corners": y["mechanism"].get("corners"), "n_upper": ex["n_upper"],
            "n_lower": ex["n_lower"], "m_upper": ex["mass_upper_kg"], "m_lower": ex["mass_lower_kg"],
            "steady_first_cycle": y["steady_state"]["first_cycle"],
            "steady_reference": y["steady_state"]["reference"],
            "rot_upper": ex.get("mean_rotation_amplitude_rad", {}).get("upper"),
            "rot_lower": ex.get("mean_rotation_amplitude_rad", {}).get("lower"),
        })
    return sw, rows


def run_point(P: RockingParams, f: float, peak: float, cycles: float, margin: float) -> dict:
    """One two-body run at the DEM's point; the DEM's ds amplification computed on its output."""
    A = peak / (2 * math.pi * f) ** 2
    exc = SineMotion(A, f, cycles)
    try:
        res = integrate_rocking(P, exc, Settings(duration=cycles / f + margin))
    except RockingError as e:                       # never seen; reported rather than hidden
        res = e.partial
    t_end = float(res.t[-1])
    first = next((e["t"] for e in res.events if e["before"] == "rest"), None)
    stats, _ = an.pattern_statistics(res.episodes, t_end)
    out = {"f": f, "A": A, "status": res.status, "t_end": t_end, "uplift": first,
           "patterns": {k: v["time_fraction"] for k, v in stats.items()},
           "impacts": res.stats["impacts_base"] + res.stats["impacts_interface"],
           "A_ds": math.nan, "A_top": math.nan, "P": math.nan, "N": math.nan, "lag_s": None,
           "max_abs_ds": math.nan}
    t = np.arange(0.0, t_end + 0.5 * SAMPLE, SAMPLE)
    th1 = np.interp(t, res.t, res.theta1)
    th2 = np.interp(t, res.t, res.theta2)
    ds = P.h1 * np.sin(th1) + (Z_S - P.h1) * np.sin(th2)
    top = an.top_displacement(P, th1, th2)
    u = exc.displacement(t)
    out["max_abs_ds"] = float(np.abs(ds).max())
    # ds peak-to-peak / table peak-to-peak in every complete cycle (before overturning, if it does)
    n = int(math.floor(min(t_end, exc.t_end) * f + 1e-9))
    if n >= 1:
        rmx, rmn = cycle_extrema(t, ds, f, 0, n)
        emx, emn = cycle_extrema(t, u, f, 0, n)
        out["cycle_ratio"] = [float(v) for v in (rmx - rmn) / (emx - emn)]
    else:
        out["cycle_ratio"] = []
    if res.status != "ok":                          # overturned before the end of the shaking
        return out
    win = steady_window(t, ds, u, f, exc.t_end)
    if win is None:
        return out
    a = amplification(t, ds, u, win)
    out.update(A_ds=a["amplification"], P=a["positive_amplitude"], N=a["negative_amplitude"],
               A_top=amplification(t, top, u, win)["amplification"],
               steady_first_cycle=win.first_cycle + 1)
    if out["max_abs_ds"] > 0:
        out["lag_s"] = phase_lag(t, ds, u, f, win)["lag_s"]
    return out


def params(top_contact: str, masses: tuple[float, float] | None = None) -> RockingParams:
    kw = dict(TABLE_5_1_II)
    if masses is not None:
        kw["m1"], kw["m2"] = masses
    return RockingParams(**kw, top_load=TOP_LOAD, top_friction=TOP_FRICTION, top_contact=top_contact)


def _fmt(x, scale=1.0, nd=2):
    return "-" if x is None or (isinstance(x, float) and math.isnan(x)) else f"{scale * x:.{nd}f}"


def _pats(p: dict) -> str:
    return ", ".join(f"{k} {100 * v:.0f}%" for k, v in sorted(p.items(), key=lambda kv: -kv[1])
                     if v >= 0.01)


def _two_body_cell(r: dict) -> tuple[str, str, str, str]:
    """(response, A_ds, P/N mm, lag s) cells of one two-body run."""
    if r["uplift"] is None:
        return "rest (never lifts)", "0", "0 / 0", "-"
    if r["status"] != "ok":
        return (f"overturns at {r['t_end']:.2f} s (uplift {r['uplift']:.3f} s; {_pats(r['patterns'])})",
                "-", "-", "-")
    return (f"rocks to the end ({_pats(r['patterns'])}; {r['impacts']} impacts)", _fmt(r["A_ds"]),
            f"+{_fmt(r['P'], 1e3, 1)} / {_fmt(r['N'], 1e3, 1)}", _fmt(r["lag_s"], 1, 3))


def comparison(sweep_dir: Path = DEM_SWEEP) -> str:
    sw, dem = load_dem(sweep_dir)
    peak, cycles, margin = sw["peak_acceleration_m_s2"], sw["cycles"], sw["margin_s"]
    dem28 = next(r for r in dem if abs(r["f"] - 2.8) < 1e-9)
    masses_dem = (dem28["m_lower"], dem28["m_upper"])
    out = []

    # thresholds of the parameter sets
    out.append("Uplift thresholds (closed form, dem.rocking.analysis.uplift_thresholds) against the "
               f"sweep's {peak:g} m/s2:\n")
    out.append("| parts | m1 / m2 (kg) | top contact | whole wall, Pattern 3 (m/s2) | "
               "Part 2 alone, Pattern 4 (m/s2) | 4.0 / governing threshold |")
    out.append("|---|---|---|---|---|---|")
    for lab, ms in (("Table 5.1", None), ("DEM excited portion at 2.8 Hz", masses_dem)):
        for tc in ("sliding", "co-moving"):
            P = params(tc, ms)
            th = an.uplift_thresholds(P)
            out.append(f"| {lab} | {P.m1:.2f} / {P.m2:.2f} | {tc} | {th['whole']:.3f} | "
                       f"{th['upper']:.3f} | {peak / th['governing']:.2f} |")

    # main table: DEM vs two-body (Table 5.1 parts), both top contacts
    runs = {tc: [run_point(params(tc), r["f"], peak, cycles, margin) for r in dem]
            for tc in ("sliding", "co-moving")}
    out.append(f"\nPer frequency ({peak:g} m/s2, {cycles:g} cycles + {margin:g} s, as the DEM sweep). "
               "A_ds: amplification of ds (postprocess/shake.py); P / N: steady positive / negative "
               "ds amplitudes (mm); lag of ds behind the table displacement (s):\n")
    out.append("| f (Hz) | A (mm) | DEM: mechanism, excited bricks upper + lower (analysis.json) | "
               "DEM: max abs ds (mm) | DEM A_ds | "
               "DEM P / N (mm) | DEM lag (s) | DEM rotation upper / lower (rad) | two-body sliding | "
               "two-body co-moving | co-moving ds pp / table pp per complete cycle | co-moving A_ds | "
               "co-moving P / N (mm) | co-moving lag (s) |")
    out.append("|---|---|---|---|---|---|---|---|---|---|---|---|---|---|")
    for i, r in enumerate(dem):
        sl, co = runs["sliding"][i], runs["co-moving"][i]
        coll = " (analysis: collapse suspected)" if r["collapse_suspected"] else ""
        desc = f"{r['response']}{', ' + r['corners'] if r['corners'] else ''}; " \
               f"{r['n_upper']} + {r['n_lower']} bricks{coll}"
        c_resp, c_A, c_PN, c_lag = _two_body_cell(co)
        out.append(
            f"| {r['f']:.1f} | {1e3 * r['A']:.2f} | {desc} | {1e3 * r['max_abs_ds']:.1f} | "
            f"{r['A_ds']:.3f} | +{1e3 * r['P']:.1f} / {1e3 * r['N']:.1f} | {r['lag_s']:.3f} | "
            f"{_fmt(r['rot_upper'], 1, 3)} / {_fmt(r['rot_lower'], 1, 3)} | "
            f"{_two_body_cell(sl)[0]} | {c_resp} | {', '.join(f'{v:.2f}' for v in co['cycle_ratio']) or '-'} | "
            f"{c_A} | {c_PN} | {c_lag} |")

    # sensitivity: the DEM's own mass split
    out.append("\nSensitivity of the co-moving model to the mass split (status per frequency; A_ds "
               "when it rocks to the end): Table 5.1's parts against the DEM's excited-portion "
               f"masses at 2.8 Hz (m1 = {masses_dem[0]:.2f} kg, m2 = {masses_dem[1]:.2f} kg, same "
               "heights):\n")
    out.append("| f (Hz) | Table 5.1 | DEM masses |")
    out.append("|---|---|---|")
    for r in dem:
        cells = []
        for ms in (None, masses_dem):
            x = run_point(params("co-moving", ms), r["f"], peak, cycles, margin)
            if x["uplift"] is None:
                cells.append("rest")
            elif x["status"] != "ok":
                cells.append(f"overturns {x['t_end']:.2f} s")
            else:
                cells.append(f"rocks, A_ds {_fmt(x['A_ds'])}")
        out.append(f"| {r['f']:.1f} | " + " | ".join(cells) + " |")

    # a finer co-moving sweep over the DEM's range
    fine = np.round(np.arange(1.6, 6.01, 0.2), 2)
    out.append(f"\nCo-moving model, Table 5.1 parts, {peak:g} m/s2, {cycles:g} cycles, every 0.2 Hz "
               "(the frequency trend through and beyond the DEM's range):\n")
    out.append("| f (Hz) | status | ds pp / table pp per complete cycle | A_ds | P / N (mm) | lag (s) |")
    out.append("|---|---|---|---|---|---|")
    for f in fine:
        x = run_point(params("co-moving"), float(f), peak, cycles, margin)
        resp, A_, PN, lag = _two_body_cell(x)
        st = resp.split(" (")[0]
        cyc = ", ".join(f"{v:.2f}" for v in x["cycle_ratio"]) or "-"
        out.append(f"| {f:.1f} | {st} | {cyc} | {A_} | {PN} | {lag} |")
    return "\n".join(out)


app = cli.study_app()


@app.command(help=cli.text(__doc__.split("\n\n")[0]))
def two_body_vs_dem(sweep_dir: Path = typer.Option(DEM_SWEEP, help="DEM sweep directory "
                                                   "(sweep.json + per-frequency analysis.json)")
                    ) -> None:
    print(comparison(sweep_dir))


def main(argv=None) -> int:
    """``python -m studies two-body-vs-dem ARGV`` (Markdown on stdout); returns the exit
    code."""
    return cli.run(app, argv, "two-body-vs-dem")


if __name__ == "__main__":
    sys.exit(main())
