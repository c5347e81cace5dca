"""``python -m studies diagnosis ...``: the diagnosis' experiments (E1-E7, results/diagnosis/)."""

from __future__ import annotations

from pathlib import Path

import typer

app = typer.Typer(add_completion=False, no_args_is_help=True,
                  help="The diagnosis: why the laboratory's models rocked and the "
                       "DEM's did not.  results/diagnosis/.")


@app.callback()
def diagnosis() -> None:
    """One subcommand per experiment (the table of results/diagnosis/README.md)."""


@app.command()
def e4(workers: int = typer.Option(1, help="dem sweep workers (one single-threaded run each)"),
       stop_at: str = typer.Option(None, help="UTC HH:MM after which no new sweep starts"),
       report: bool = typer.Option(False, "--report", help="only rebuild the report")) -> None:
    """E4: Model II y at 2.4-3.2 Hz x 1.9-3.0 m/s2 x 3 seeds, 10 cycles: the onset acceleration
    of the rocking branch (resumable; touch runs/diagnosis/e4/DRAIN to end softly)."""
    from studies.diagnosis import e4 as exp

    if not report:
        exp.run(workers=workers, stop_at=stop_at)
    exp.report()


@app.command()
def e2(stop_at: str = typer.Option(None, help="UTC HH:MM after which no new specimen starts"),
       sweep: list[str] = typer.Option(None, help="only these models (repeatable; default: "
                                       "model-ii-y and model-iii-y)"),
       seed: list[int] = typer.Option(None, help="only these seeds (repeatable; default 0 1 2)"),
       report: bool = typer.Option(False, "--report", help="only rebuild the report")) -> None:
    """E2: one specimen per (model, seed) stepped down from 4.4 to 2.0 Hz and up again, 15 cycles
    a step: does a rocking specimen stay rocking where one from rest does not?  (resumable; a
    killed run continues from its restart point; touch runs/diagnosis/e2/DRAIN to end softly).
    Two processes may share the work if their --sweep / --seed choices do not overlap."""
    from studies.diagnosis import e2 as exp

    if not report:
        sweeps = tuple(sweep) if sweep else exp.SWEEPS
        seeds = tuple(seed) if seed else exp.SEEDS
        unknown = [s for s in sweeps if s not in exp.SWEEPS] + \
            [str(s) for s in seeds if s not in exp.SEEDS]
        if unknown:
            raise typer.BadParameter(f"not one of E2's specimens: {', '.join(unknown)} "
                                     f"(models {', '.join(exp.SWEEPS)}; seeds "
                                     f"{', '.join(map(str, exp.SEEDS))})")
        exp.run(sweeps=sweeps, seeds=seeds, stop_at=stop_at)
    exp.report()


@app.command()
def grid(keys: list[str] = typer.Argument(..., help="experiments to run together, seed by seed: "
                                          "e3 (the table's start), e5 (Model III at 5 mm), "
                                          "e6 (the roof boundary), survival-model-i-y, "
                                          "survival-model-ii-x (50 cycles), e1-<sweep> (E1's "
                                          "fingerprint runs)"),
         workers: int = typer.Option(1, help="dem sweep workers (one single-threaded run each)"),
         stop_at: str = typer.Option(None, help="UTC HH:MM after which no new sweep starts"),
         report: bool = typer.Option(False, "--report", help="only rebuild the reports (the rows again "
                                     "from the run directories kept here)")) -> None:
    """E1 / E3 / E5 / E6 and the survival points: case variants x frequencies x 3 seeds, each
    run judged rocking or not and standing or not (resumable; touch runs/diagnosis/DRAIN to end
    softly).  studies/diagnosis/experiments.py."""
    from studies.diagnosis import grid as exp
    from studies.diagnosis.experiments import GRIDS

    bad = [k for k in keys if k not in GRIDS]
    if bad:
        raise typer.BadParameter(f"unknown experiment(s) {bad}; choose from {sorted(GRIDS)}",
                                 param_hint="KEYS")
    grids = [GRIDS[k] for k in keys]
    if not report:
        exp.run(grids, workers=workers, stop_at=stop_at)
    for g in grids:
        if report:
            exp.refresh(g)   # the rows again from the runs kept here
        exp.report(g)


@app.command()
def e1() -> None:
    """E1: the low-branch frequency fingerprint of each candidate joint from the runs of the
    e1-* grids (analysis only: run them with `grid e1-model-ii-y e1-model-i-y e1-model-ii-x
    e1-model-iii-y`)."""
    from studies.diagnosis import e1 as exp

    exp.report()


@app.command()
def e7() -> None:
    """E7: the thesis' accelerations read as relative to the table, from the first prediction's
    committed rows (analysis only: no run)."""
    from studies.diagnosis import e7 as exp

    exp.report()


@app.command("onset-rule")
def onset_rule() -> None:
    """The onset rule A T(f) >= a0 fitted to every from-rest run of E1, E4, E5 and the band
    runs (T: the quiet branch's amplification of a mode with E1's f_n), checked on the other
    from-rest runs of the first prediction's joints: onset-rule.json and onset-rule.png
    (analysis only: no run)."""
    from studies.diagnosis import onset_rule as exp

    exp.report()


@app.command()
def relative(results: Path = typer.Argument(..., help="a folder holding analysis.json files "
                                            "(e.g. results/shake)")) -> None:
    """The DEM's accelerations relative to the table against the thesis': a
    Markdown table of every analysis.json under RESULTS (recorded relative quantities, else the
    first-harmonic estimate from the absolute ones)."""
    from studies.diagnosis.relative_thesis import report

    print(report(results))


def main(argv=None) -> int:
    app(args=argv, prog_name="python -m studies diagnosis", standalone_mode=True)
    return 0
