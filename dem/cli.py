"""Command line: ``dem run | check | sweep | rocking | post``.

Exit codes (a contract, see ../shared/DESIGN.md): 0 ok, 1 the run failed, 2 bad input.
Heavy imports (Taichi) happen inside the commands so that ``dem check`` and ``--help`` are fast.
"""

from __future__ import annotations

from pathlib import Path

import typer

app = typer.Typer(
    add_completion=False,
    no_args_is_help=True,
    help="Rigid-block DEM of dry masonry on a tilting or shaking table.",
)

EXIT_OK, EXIT_RUN_FAILED, EXIT_BAD_INPUT = 0, 1, 2


def _err(msg: str) -> None:
    typer.echo(msg, err=True)


@app.command()
def check(case: Path = typer.Argument(..., help="case YAML file")) -> None:
    """Validate a case file and build and check its scene (overlaps, floating blocks) without
    running it; print block count, mass and bounding box.  Exit 0 ok, 2 bad input."""
    from dem.builders import check_scene
    from dem.case import CaseError, load_case
    from dem.scene import scene_from_case

    try:
        c = load_case(case)
        scene = scene_from_case(c, check=False)
    except (CaseError, ValueError) as err:
        _err(f"error: {err}" if str(err).startswith(str(case)) else f"error: {case}: {err}")
        raise typer.Exit(EXIT_BAD_INPUT)
    report = check_scene(
        scene,
        overlap_tolerance=c.solver.overlap_tolerance,
        allow_floating=c.scene.allow_floating,
    )
    if not report.ok:
        _err(f"error: {case}: the scene cannot be run:\n{report.format()}")
        raise typer.Exit(EXIT_BAD_INPUT)
    typer.echo(f"{case}: ok: '{c.name}', loading {c.loading.type}\n{report.format()}")


@app.command()
def schema(
    out: Path = typer.Option(
        None, "--out", "-o", help="write the JSON schema here (default: print it)"
    ),
) -> None:
    """Export the JSON schema of case files (for editor completion and validation)."""
    from dem.case import case_json_schema

    text = case_json_schema()
    if out is None:
        typer.echo(text)
    else:
        out.write_text(text)
        typer.echo(f"wrote {out}")


@app.command()
def run(
    case: Path = typer.Argument(..., help="case YAML file"),
    out: Path = typer.Option(..., "--out", "-o", help="output directory"),
    progress: bool = typer.Option(True, help="show a progress bar"),
) -> None:
    """Run one case and write summary.json, frames.npz (and VTK) into OUT."""
    from dem.runner import run_case_file

    raise typer.Exit(run_case_file(case, out, progress=progress))


@app.command()
def rocking(
    case: Path = typer.Argument(..., help="rocking case YAML file (see dem/rocking/schema.py)"),
    out: Path = typer.Option(..., "--out", "-o", help="output directory"),
    plots: bool = typer.Option(True, help="write PNG plots"),
) -> None:
    """Run the two-body rocking model (thesis Ch. 5): summary.json, rocking.npz, plots in OUT."""
    from dem.rocking.runner import run_rocking_case_file

    raise typer.Exit(run_rocking_case_file(case, out, plots=plots, echo=typer.echo, err=_err))


@app.command()
def sweep(
    case: Path = typer.Argument(..., help="shake case YAML file"),
    out: Path = typer.Option(..., "--out", "-o", help="output directory"),
    frequencies: str = typer.Option(None, "--frequencies", help="comma-separated, Hz: 1.8,2.0,2.4"),
    range_: str = typer.Option(None, "--range", help="start:stop:step, Hz (stop included)"),
    cycles: float = typer.Option(None, "--cycles", help="cycles per run (default: the case's)"),
    margin: float = typer.Option(1.0, "--margin", help="s simulated after the last cycle"),
    workers: int = typer.Option(None, "--workers", help="local workers (default: one per core)"),
    scheduler: str = typer.Option(None, "--scheduler", help="address of a running dask scheduler"),
    max_steps: int = typer.Option(None, "--max-steps", help="cap the steps of each run (smoke)"),
) -> None:
    """Frequency sweep of a shake case at its constant peak acceleration (or amplitude): one run
    per frequency on dask, each analysed (postprocess.shake), then the amplification curves,
    characteristic frequency, effective range and lag times in OUT/sweep.json and sweep.png.
    Exit 0 all points ok, 1 a point failed (the others still land), 2 bad input."""
    from postprocess.sweep import run_sweep

    raise typer.Exit(run_sweep(case, out, frequencies, range_, cycles, margin, scheduler, workers,
                               max_steps))


@app.command()
def post(
    directory: Path = typer.Argument(..., help="run directory or sweep directory"),
) -> None:
    """(Re)build the analysis of a run directory (shake: analysis.json, PNGs, excited.vtu; tilt:
    collapse and mechanism into analysis.json) or of a sweep directory (every point re-analysed,
    sweep.json and sweep.png re-aggregated).  Exit 0 ok, 1 a sweep point failed, 2 bad input."""
    from postprocess.sweep import post_command

    raise typer.Exit(post_command(directory))


if __name__ == "__main__":  # pragma: no cover
    app()
