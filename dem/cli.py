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
    """Validate a case file (and build its scene) without running it."""
    from dem.case import CaseError, load_case
    from dem.scene import scene_from_case

    try:
        c = load_case(case)
        scene = scene_from_case(c)
    except (CaseError, ValueError) as err:
        _err(f"error: {case}:\n{err}")
        raise typer.Exit(EXIT_BAD_INPUT)
    lo, hi = scene.bounding_box()
    typer.echo(
        f"{case}: ok: '{c.name}', {scene.n_blocks} blocks, "
        f"{scene.mass[~scene.fixed].sum():.3f} kg, bounding box {lo.round(4).tolist()} .. "
        f"{hi.round(4).tolist()} m, loading {c.loading.type}"
    )


@app.command()
def run(
    case: Path = typer.Argument(..., help="case YAML file"),
    out: Path = typer.Option(..., "--out", "-o", help="output directory"),
    progress: bool = typer.Option(True, help="show a progress bar"),
) -> None:
    """Run one case and write summary.json, frames.npz (and VTK) into OUT."""
    from dem.runner import run_case_file

    raise typer.Exit(run_case_file(case, out, progress=progress))


if __name__ == "__main__":  # pragma: no cover
    app()
