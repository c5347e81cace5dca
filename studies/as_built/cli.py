"""``python -m studies as-built ...``: the as-built study's experiments (studies/as_built)."""

from __future__ import annotations

import typer

app = typer.Typer(add_completion=False, no_args_is_help=True,
                  help="Masonry as built by hand: the corner bound, loose corners, the input's "
                       "bounds (a kick-start, the table's waveform).  results/as-built/.")


@app.callback()
def as_built() -> None:
    """One subcommand per kind of experiment."""


@app.command()
def grid(keys: list[str] = typer.Argument(..., help="experiments to run together, seed by seed: "
                                          "corner-bound-model-ii-y, corner-bound-model-iii-y, "
                                          "loose-corners-model-ii-y, loose-corners-model-i-y, "
                                          "loose-corners-model-i-y-12mm, waveform-model-ii-y"),
         workers: int = typer.Option(1, help="dem sweep workers (one single-threaded run each)"),
         stop_at: str = typer.Option(None, help="UTC HH:MM after which no new sweep starts"),
         report: bool = typer.Option(False, "--report", help="only rebuild the reports (the rows "
                                     "again from the run directories kept here)")) -> None:
    """Case variants x frequencies x 3 seeds from rest, each run judged rocking or not and
    standing or not (resumable: finished runs are skipped; touch runs/as-built/DRAIN to end
    softly after the sweep in flight).  studies/as_built/grids.py."""
    from studies.as_built.grids import GRIDS
    from studies.diagnosis import grid as exp

    bad = [k for k in keys if k not in GRIDS]
    if bad:
        raise typer.BadParameter(f"unknown experiment(s) {bad}; choose from {sorted(GRIDS)}",
                                 param_hint="KEYS")
    grids = [GRIDS[k] for k in keys]
    if not report:
        exp.run(grids, workers=workers, stop_at=stop_at)
    for g in grids:
        if report:
            exp.refresh(g)
        exp.report(g)


@app.command()
def identification(model: list[str] = typer.Option(None, help="only these models (repeatable; "
                                                   "default all four, Model II y first)"),
                   stop_at: str = typer.Option(None, help="UTC HH:MM after which no new run "
                                               "starts")) -> None:
    """Each model's own frequency response: band-limited noise at two levels below uplift, three
    joints (frozen, E1's softest, unbonded corners), then Model II y with each loose-corner set
    at 0.8 m/s2 RMS (criterion (iii)), f_n and zeta identified (resumable: a
    recorded point never runs again; touch runs/as-built/identification/DRAIN to end softly).
    studies/as_built/identification.py."""
    from studies.as_built import identification as exp

    bad = [m for m in model or () if m not in exp.MODELS]
    if bad:
        raise typer.BadParameter(f"unknown model(s) {bad}; choose from {list(exp.MODELS)}")
    exp.run(only=tuple(model or ()), stop_at=stop_at)


@app.command("kick-start")
def kick_start(stop_at: str = typer.Option(None, help="UTC HH:MM after which no new run starts"),
               seed: list[int] = typer.Option(None, help="only these seeds (repeatable; "
                                              "default 0, 1, 2)"),
               report: bool = typer.Option(False, "--report",
                                           help="only rebuild the records: analyse again the "
                                           "finished runs whose directories are here, then "
                                           "summary.json")
               ) -> None:
    """Model II y at 2.8 Hz kick-started (2 cycles at 2.3 m/s2, then 50 at 1.53 m/s2), seeds
    0-2: does the rocking branch hold 50 cycles with at most the roof masses moving?
    (resumable: a recorded seed never runs again; touch runs/as-built/kick-start-model-ii-y/
    DRAIN to end softly after the run in flight).  studies/as_built/kick_start.py."""
    from studies.as_built import kick_start as exp

    bad = [s for s in seed or () if s not in exp.SEEDS]
    if bad:
        raise typer.BadParameter(f"seed(s) {bad} are not in the plan {list(exp.SEEDS)}",
                                 param_hint="--seed")
    if report:
        from studies.prediction.plan import load_frozen
        from studies.prediction.protocol import DEFAULT_FROZEN

        exp.refresh(load_frozen(DEFAULT_FROZEN))
        exp.report()
        return
    exp.run(stop_at=stop_at, seeds=tuple(seed or exp.SEEDS))


@app.command()
def chapter3(sets: list[str] = typer.Option(None, "--set", help="loose sets (repeatable; default "
                                            "all three: loose-1mm, loose-2mm, loose-0.5mm)"),
             seeds: int = typer.Option(1, metavar="N", help="the calibration's seeds 0 .. N-1"),
             specimens: list[str] = typer.Option(None, help="calibration specimens (repeatable; "
                                                 "default all)"),
             large: bool = typer.Option(True, "--large/--no-large",
                                        help="the large-brick L/H = 2.5 walls too"),
             stop_at: str = typer.Option(None, help="UTC HH:MM after which no new point starts"),
             max_steps: int = typer.Option(None, help="cap each run (smoke only)"),
             compare_only: bool = typer.Option(False, "--compare-only", help="run nothing")
             ) -> None:
    """Criterion (i) of the loose sets: the Chapter 3 tilts with the frozen candidate plus a
    set's as-built fields, compared seed by seed with the calibration, the invariants, and the
    large-brick L/H = 2.5 walls (resumable).  studies/as_built/chapter3.py."""
    import sys

    from studies.as_built import chapter3 as exp
    from studies.chapter3.check import CheckInputError

    if seeds < 1:
        raise typer.BadParameter("must be >= 1", param_hint="--seeds")
    try:
        s = exp.run(tuple(sets or exp.ORDER), seeds, specimens or None, large, stop_at,
                    max_steps, compare_only, argv=sys.argv[1:],
                    log=lambda m: print(m, flush=True))
    except (CheckInputError, ValueError) as err:
        print(f"error: {err}", file=sys.stderr)
        raise typer.Exit(2) from None
    print(exp.table(s))


def main(argv=None) -> int:
    app(args=argv, prog_name="python -m studies as-built", standalone_mode=True)
    return 0
