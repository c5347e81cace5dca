"""Where does the DEM's Model II resonate?  Context for the blind prediction (studies.prediction),
run AFTER the freeze; it changes nothing in the frozen set and is not a prediction.

Why: in both finished Model II sweeps (results/prediction, y: 1.8-3.6 Hz, x: 1.8-3.8 Hz) every
seed's ds amplification rises monotonically to the sweep's top edge, roughly as f^2, with a
lag of 0.01-0.02 s: a response below a resonance that lies above the thesis' frequencies.  A
linear single-degree-of-freedom oscillator on a moving base (natural frequency f_n, damping
ratio zeta) has, for the relative displacement z of its mass against the base displacement
y = Y sin(2 pi f t) (Chopra, Dynamics of Structures, 4th ed., Section 3.6 / eq. 3.6.5 with
the relative motion; r = f / f_n):

    |z| / Y = r^2 / sqrt((1 - r^2)^2 + (2 zeta r)^2)          (dimensionless)

The thesis' amplification of ds (Section 4.2.5: peak-to-peak of the displacement relative to
the table over the table's peak-to-peak) is this |z| / Y.  Fitted to the committed medians
(:func:`fit_natural_frequency`, zeta = 0: below r ~ 0.5 the damping changes |z| / Y by under
~5 % and cannot be told from the amplitudes), the curves read f_n = 7.31 Hz (Model II y,
largest relative residual 6.2 % over its ten frequencies; per seed 6.7-8.2 Hz) and 10.0 Hz
(Model II x, 6.1 % over eight; per seed 8.7-11.9 Hz), i.e. 2.6 and 3.6 times the thesis'
2.8 Hz.  These numbers, and
the frequencies of :data:`FREQUENCIES` chosen from them, were committed before any run here.

What runs: the prediction's own case of each sweep (studies.prediction.plan.sweep_case:
the cases/shake file, friction 0.81, the same constant peak acceleration, the frozen set) at
frequencies above the sweep that bracket the fitted f_n, ``CYCLES`` cycles after settling,
seeds 0 .. SEEDS-1 (the prediction's first seeds): one ``dem sweep --realisations`` per sweep
in a child process (studies.kit.child), resumable (dem sweep skips finished points;
``touch <out>/runs/DRAIN`` ends a call after the runs in flight).

What it reports (``<out>/summary.json``, ``README.md``, ``amplification.png``), per sweep: the
fit of the prediction's curve (median and per seed), the above-range points (median and 10-90 %
of ds, da and dsr amplification, ds lag, survival, rocking check), and the characteristic
frequency of the joined median curve of seeds 0 .. SEEDS-1 (prediction frequencies and these)
by the prediction's own rule (postprocess.sweep.effective_range): a peak inside the joined range
confirms a resonance where the fit put it; a curve still rising at the top, or one that
departs from the fit, says the linear reading is wrong.  Either answer is reported as it falls.
"""

from __future__ import annotations

import json
import sys
from pathlib import Path
from types import SimpleNamespace

import numpy as np
import typer

from dem.output.plotting import agg_pyplot
from postprocess.ensemble import statistics
from postprocess.sweep import effective_range
from postprocess.verdicts import band_text, is_rocking
from studies.kit import cli, session
from studies.prediction.analysis import survived
from studies.prediction.plan import sweep_case
from studies.prediction.points import collect_rows, points_path
from studies.prediction import side
from studies.prediction.protocol import DEFAULT_FROZEN
from studies.prediction.side import sweep_realisations
from studies.kit.provenance import ROOT


# chosen from the fits above (II y f_n 7.3 Hz, per seed 6.7-8.2; II x 10.0 Hz, 8.7-11.9);
# 3.8, 4.0 and 4.2 Hz in y were added after the first runs had shown a jump between the
# prediction's 3.6 Hz (0.32) and 4.5 Hz (3.4), to place it
FREQUENCIES = {"model-ii-y": (3.8, 4.0, 4.2, 4.5, 5.5, 6.5, 7.5, 8.5, 10.0),
               "model-ii-x": (5.0, 7.0, 8.5, 10.0, 11.5, 13.0)}
CYCLES = 20.0
SEEDS = 3


def base_transfer(f, fn: float, zeta: float = 0.0):
    """|z| / Y of a linear oscillator (natural frequency ``fn`` Hz, damping ratio ``zeta``) under
    the base displacement Y sin(2 pi f t): its relative displacement's amplitude over the base's
    (module docstring; dimensionless, f in Hz)."""
    r = np.asarray(f, float) / fn
    return r ** 2 / np.sqrt((1.0 - r ** 2) ** 2 + (2.0 * zeta * r) ** 2)


def fit_natural_frequency(freqs, amps, guess: float = 7.0) -> dict:
    """Least-squares f_n (Hz) of :func:`base_transfer` with zeta = 0 on relative residuals
    (scipy.optimize.curve_fit with sigma = the amplitudes); returns fn, its standard error and
    the largest |fit / amplification - 1| over the points."""
    from scipy.optimize import curve_fit

    f, a = np.asarray(freqs, float), np.asarray(amps, float)
    ok = np.isfinite(f) & np.isfinite(a) & (a > 0)
    f, a = f[ok], a[ok]
    if len(f) < 2:
        return {"fn_hz": None, "note": f"{len(f)} valid point(s): a fit needs 2"}
    (fn,), cov = curve_fit(lambda x, p: base_transfer(x, p), f, a, p0=[max(guess, 1.5 * f.max())], sigma=a,
                           bounds=(1.01 * f.max(), 100.0 * f.max()))
    resid = base_transfer(f, fn) / a - 1.0
    return {"fn_hz": float(fn), "fn_se_hz": float(np.sqrt(cov[0, 0])),
            "max_relative_residual": float(np.abs(resid).max()), "n_points": int(len(f))}


def _ok_rows(rows):
    return [r for r in rows if r.get("run_status") == "ok" and r.get("analysis_status") == "ok"
            and (r.get("amplification") or {}).get("ds") is not None]


def median_curve(rows, seeds=None) -> tuple[list[float], list[float]]:
    """(frequencies, median ds amplification) over the surviving rows of ``seeds`` (all: None)."""
    rows = [r for r in _ok_rows(rows) if survived(r)
            and (seeds is None or r["seed"] in set(seeds))]
    fs = sorted({r["frequency_hz"] for r in rows})
    return fs, [float(np.median([r["amplification"]["ds"] for r in rows
                                 if r["frequency_hz"] == f])) for f in fs]


def prediction_fit(rows) -> dict:
    """Fit of the prediction sweep's median curve and of each seed's curve."""
    fs, med = median_curve(rows)
    per = {}
    for s in sorted({r["seed"] for r in _ok_rows(rows)}):
        pts = sorted((r["frequency_hz"], r["amplification"]["ds"]) for r in _ok_rows(rows)
                     if r["seed"] == s and survived(r))
        if pts:
            per[str(s)] = fit_natural_frequency(*zip(*pts)).get("fn_hz")
    return {"median": fit_natural_frequency(fs, med), "per_seed_fn_hz": per,
            "frequencies_hz": fs, "median_ds": med}


def run_sweep(runs: Path, frozen: dict, name: str, seeds: int, cycles: float, log=print,
              drain_file: Path | None = None) -> tuple[int, float]:
    """One ``dem sweep --realisations`` of ``name``'s case above its range; (exit code, CPU s)."""
    case = sweep_case(name, frozen["parameters"])
    data = case.model_dump()
    data["name"] = f"res-{name}"
    return sweep_realisations(runs, name, type(case).model_validate(data), FREQUENCIES[name],
                              cycles, seeds, log, drain_file)


def sweep_summary(pred_rows, above_rows, seeds: int) -> dict:
    """The fit, the above-range statistics per frequency, and the joined curve's peak."""
    per_f = {}
    for f in sorted({r["frequency_hz"] for r in above_rows}):
        rows = [r for r in above_rows if r["frequency_hz"] == f]
        ok = _ok_rows(rows)
        alive = [r for r in ok if survived(r)]
        per_f[f"{f:g}"] = {
            "n_run": len(ok), "n_expected": len(rows), "n_survived": len(alive),
            "amplification": {q: statistics((r.get("amplification") or {}).get(q)
                                            for r in alive) for q in ("ds", "da", "dsr")},
            "lag_ds_s": statistics((r.get("lag_s") or {}).get("ds") for r in alive),
            "rocking": sum(1 for r in alive if is_rocking(r)["rocking"]),
            "per_seed_ds": {str(r["seed"]): r["amplification"]["ds"] for r in alive}}
    my = list(range(seeds))
    f1, a1 = median_curve(pred_rows, my)
    f2, a2 = median_curve(above_rows, my)
    joined = sorted(zip(f1 + f2, a1 + a2))
    fit = prediction_fit(pred_rows)
    return {"prediction_fit": fit, "above": per_f,
            "joined_seeds": my, "joined_curve": [[f, a] for f, a in joined],
            "joined_peak": effective_range([f for f, _ in joined], [a for _, a in joined])
            if joined else None}


def report(out: Path, pred_out: Path, frozen: dict, seeds: int, cycles: float, cpu: dict,
           command: str) -> dict:
    from dem.output.atomic import write_json

    out.mkdir(parents=True, exist_ok=True)
    sweeps = {}
    for name, freqs in FREQUENCIES.items():
        pred = json.loads(points_path(pred_out, name).read_text())["rows"]
        above = collect_rows(out / "runs" / name, list(range(seeds)), list(freqs))
        sweeps[name] = {**sweep_summary(pred, above, seeds), "cpu_seconds": cpu.get(name)}
    data = {"kind": "resonance-search", "command": command, "cycles": cycles,
            "seeds": list(range(seeds)), "frequencies_hz": {k: list(v) for k, v in
                                                             FREQUENCIES.items()},
            "frozen": {k: frozen[k] for k in ("path", "parameters", "commit")},
            "sweeps": sweeps, "cpu_seconds": sum(v for v in cpu.values() if v)}
    write_json(out / "summary.json", data, indent=1)
    _plot(out / "amplification.png", sweeps)
    L = ["# Where does the DEM's Model II resonate? (context for issue 13; after the freeze)", "",
         f"Generated by `{command}` (studies/resonance/study.py; its docstring has the "
         "equation and the why).  NOT a result of the prediction: the frozen set "
         f"(`{frozen['path']}`, commit `{frozen['commit']}`) and the prediction's cases are "
         "unchanged; only the frequencies lie above the thesis' sweeps (same constant peak "
         f"acceleration, so the table moves less).  {cycles:g} cycles, seeds 0-{seeds - 1}.  "
         f"CPU time: {data['cpu_seconds']:.0f} s.", "",
         "Linear oscillator on a moving base, |z| / Y = r^2 / |1 - r^2| with r = f / f_n, "
         "fitted to the finished prediction sweeps' median ds amplification:", "",
         "| sweep | f_n of the median curve (Hz) | largest residual | f_n per seed (Hz) | "
         "joined curve (seeds above): peak |", "|---|---|---|---|---|"]
    for name, v in sweeps.items():
        m = v["prediction_fit"]["median"]
        per = [x for x in v["prediction_fit"]["per_seed_fn_hz"].values() if x is not None]
        pk = v["joined_peak"] or {}
        peak = (f"{pk['characteristic_frequency_hz']:g} Hz (amplification "
                f"{pk['peak_amplification']:.3g})" if pk.get("characteristic_frequency_hz")
                else pk.get("characteristic_frequency_note", "not run"))
        L.append(f"| {name} | {m.get('fn_hz', float('nan')):.3g} +- "
                 f"{m.get('fn_se_hz', float('nan')):.2g} | "
                 f"{100 * m.get('max_relative_residual', float('nan')):.1f} % | "
                 f"{min(per):.3g}-{max(per):.3g} | {peak} |" if per else f"| {name} | - | - | - | "
                 f"{peak} |")
    for name, v in sweeps.items():
        L += ["", f"## {name} above its range", "",
              "| f (Hz) | runs (survived) | ds | per seed | da | dsr | ds lag (s) | rocking | "
              "linear fit |", "|---|---|---|---|---|---|---|---|---|"]
        fn = v["prediction_fit"]["median"].get("fn_hz")
        for f, p in v["above"].items():
            a = p["amplification"]
            lin = f"{float(base_transfer(float(f), fn)):.3g}" if fn else "-"
            L.append(f"| {f} | {p['n_run']}/{p['n_expected']} ({p['n_survived']}) | "
                     f"{band_text(a['ds'])} | "
                     + ", ".join(f"{x:.3g}" for x in p["per_seed_ds"].values())
                     + f" | {band_text(a['da'])} | {band_text(a['dsr'])} | "
                     f"{band_text(p['lag_ds_s'])} | {p['rocking']}/{p['n_survived']} | {lin} |")
    L += ["", f"Cycles: {cycles:g}.  On the finished Model II y sweep the first 20 cycles read "
          "the ds amplification ~6 % above all 50 (results/prediction/model-ii-y/"
          "cycles-check-20.json).  The linear fit's column is the undamped |z| / Y at the fitted "
          "f_n: near f_n it diverges, and the measured peak's height is set by the damping, "
          "which the fit does not know.", "", "![amplification](amplification.png)", ""]
    (out / "README.md").write_text("\n".join(L) + "\n")
    return data


def _plot(path: Path, sweeps: dict) -> None:
    plt = agg_pyplot()

    fig, axes = plt.subplots(1, len(sweeps), figsize=(5.5 * len(sweeps), 4), squeeze=False)
    for ax, (name, v) in zip(axes[0], sweeps.items()):
        fit = v["prediction_fit"]
        ax.plot(fit["frequencies_hz"], fit["median_ds"], "o-", label="prediction, median")
        fs = [float(f) for f in v["above"]]
        med = [p["amplification"]["ds"]["median"] for p in v["above"].values()]
        keep = [(f, m) for f, m in zip(fs, med) if m is not None]
        if keep:
            ax.plot(*zip(*keep), "s-", color="C1", label="above the range, median")
        for f, p in v["above"].items():
            for x in p["per_seed_ds"].values():
                ax.plot(float(f), x, "k.", ms=4)
        fn = fit["median"].get("fn_hz")
        if fn:
            grid = np.linspace(1.5, max(fs + [fn * 1.5]), 400)
            ax.plot(grid, base_transfer(grid, fn), "g--", lw=1,
                    label=f"linear oscillator, f_n = {fn:.2f} Hz (fit)")
            ax.axvline(fn, color="g", ls=":", lw=0.8)
        ax.set_yscale("log")
        ax.set_ylim(0.01, 20)
        ax.set_xlabel("frequency (Hz)")
        ax.set_ylabel("ds amplification")
        ax.set_title(f"{name} (context)")
        ax.legend(fontsize=7)
    fig.tight_layout()
    fig.savefig(path, dpi=110)
    plt.close(fig)


app = cli.study_app()


@app.command(help=cli.text(__doc__))
def resonance(frozen: Path = typer.Option(DEFAULT_FROZEN),
              out: Path = typer.Option(ROOT / "results" / "prediction" / "resonance-search"),
              seeds: int = typer.Option(SEEDS),
              cycles: float = typer.Option(CYCLES),
              report_only: bool = typer.Option(False, "--report",
                                               help="only rebuild the report"),
              prediction: Path = typer.Option(ROOT / "results" / "prediction",
                                              help="the prediction's output folder (its "
                                                   "<sweep>/points.json are fitted)"),
              only: str = typer.Option(",".join(FREQUENCIES),
                                       help="comma-separated sweeps to run (default: all)")
              ) -> int:
    return _resonance(SimpleNamespace(frozen=frozen, out=out, seeds=seeds, cycles=cycles,
                                      report=report_only, prediction=prediction, only=only))


def main(argv=None) -> int:
    """``python -m studies resonance ARGV``; returns the exit code (0 ok, 1 a run failed or
    was stopped, 2 bad input)."""
    return cli.run(app, argv, "resonance")


def _resonance(args) -> int:
    frozen = side.frozen_and_checked(args)
    if frozen is None:
        return 2
    only = [s for s in args.only.split(",") if s]
    bad = [s for s in only if s not in FREQUENCIES]
    if bad:
        print(f"error: --only must name sweeps of {list(FREQUENCIES)} (got {bad})",
              file=sys.stderr)
        return 2
    out = Path(args.out)
    # a call on another sweep may run beside this one: the ledger is merged under its lock
    cpu, codes = side.run_items(out, [] if args.report else only, lambda name, drain: (
        run_sweep(out / "runs", frozen, name, args.seeds, args.cycles, drain_file=drain)))
    cmd = session.command("resonance", seeds=(args.seeds, SEEDS), cycles=(args.cycles, CYCLES))
    report(out, Path(args.prediction), frozen, args.seeds, args.cycles, cpu, cmd)
    print(f"{out}/summary.json, {out}/README.md", file=sys.stderr)
    return 0 if all(c == 0 for c in codes) else 1


if __name__ == "__main__":
    sys.exit(main())
