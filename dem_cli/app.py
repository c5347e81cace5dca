"""Command line: ``dem run | check | sweep | rocking | post``: parses the options and calls the
command bodies in dem_cli.commands.

Exit codes (a contract, see ../shared/DESIGN.md): 0 ok, 1 the run failed (or was stopped by
a signal, or its output could not be written), 2 bad input (case file, options, --out); what
each failure prints and keeps: docs/failures.md.
Heavy imports (Taichi) happen inside the commands so that ``dem check`` and ``--help`` are fast.
"""

from __future__ import annotations

from pathlib import Path

import typer

class _DemApp(typer.Typer):
    """The ``dem`` program: an exception no command turned into a message (a bug, or a failure
    nobody foresaw) ends in one line and the exit code of dem_cli.commands.exit_codes.exit_code_for,
    not a traceback (a user cannot act on a 34-line traceback); ``DEM_TRACEBACK=1`` shows the traceback."""

    def __call__(self, *args, **kwargs):
        import os
        import sys

        try:
            return super().__call__(*args, **kwargs)
        except Exception as err:  # noqa: BLE001 - the one place that maps what was missed
            if os.environ.get("DEM_TRACEBACK"):
                raise
            from dem_cli.commands.exit_codes import exit_code_for

            print(f"error: {type(err).__name__}: {err} (unexpected: please report it; "
                  f"DEM_TRACEBACK=1 shows where)", file=sys.stderr)
            sys.exit(int(exit_code_for(err)))


app = _DemApp(
    add_completion=False,
    no_args_is_help=True,
    help="Rigid-block DEM of dry masonry on a tilting or shaking table.",
)

from dem_cli.commands.exit_codes import ExitCode

MAX_BLOCKS_HELP = "refuse scenes above this many blocks (default 20000, or DEM_MAX_BLOCKS)"
BATCH_HELP = ("with --arch cuda, run the runs K to an engine: K scenes side by side in one "
              "process and one kernel launch, each written as a lone run (default: one engine "
              "per run).  On the CPU each run keeps an engine of its own whatever K (an engine "
              "of K on one core steps them more slowly than K separate runs: "
              "docs/performance.md, 'Batching on the CPU')")
ARCH_HELP = ("where the engines run: cpu, or cuda (a GPU; an error where Taichi finds none; one "
             "local worker unless --workers)")


def _err(msg: str) -> None:
    typer.echo(msg, err=True)


def _version(value: bool) -> None:
    if value:
        from importlib.metadata import PackageNotFoundError, version

        import dem

        try:
            taichi = version("taichi")
        except PackageNotFoundError:  # pragma: no cover
            taichi = "not installed"
        typer.echo(f"dem-masonry {dem.__version__} (taichi {taichi})")
        raise typer.Exit(ExitCode.OK)


@app.callback()
def main(
    version: bool = typer.Option(False, "--version", callback=_version, is_eager=True,
                                 help="print the version and exit"),
) -> None:
    """Rigid-block DEM of dry masonry on a tilting or shaking table."""
    from dem.environment import environment_errors

    errors = environment_errors()  # before any command: a bad DEM_* is one line, exit 2
    for line in errors:
        _err(f"error: {line}")
    if errors:
        raise typer.Exit(ExitCode.BAD_INPUT)


def _is_rocking_file(path: Path) -> bool:
    """A two-body rocking case (top-level key ``rocking``): dispatched on the content."""
    from dem.case import CaseError
    from dem.case.document import read_case_yaml

    try:
        data, _ = read_case_yaml(path)  # parsed once: the case's loader reuses it
    except CaseError:
        return False
    return "rocking" in data and "scene" not in data


@app.command()
def check(
    case: Path = typer.Argument(..., metavar="CASE", help="case YAML file"),
    max_blocks: int = typer.Option(None, "--max-blocks", help=MAX_BLOCKS_HELP),
    show_defaults: bool = typer.Option(False, "--show-defaults",
                                       help="print the case as it runs: every default filled "
                                            "in, units in comments (YAML)"),
) -> None:
    """Validate a case file and build and check its scene (overlaps, floating blocks, time step,
    loading against the step and the run) without running it: the same checks as ``dem run``;
    print block count, mass, bounding box, time step and size.  A two-body case (``rocking:``)
    is checked against the two-body schema.  Exit 0 ok, 2 bad input."""
    if _is_rocking_file(case):
        from dem_cli.commands.rocking import load_checked

        rc = load_checked(case, _err)
        if rc is None:
            raise typer.Exit(ExitCode.BAD_INPUT)
        typer.echo(f"{case}: ok: '{rc.name}': a two-body rocking case (thesis Chapter 5); run it "
                   f"with `dem rocking {case} --out DIR`")
        return
    from dem.validate import load_and_check

    checked = load_and_check(case, _err, max_blocks)
    if checked is None:
        raise typer.Exit(ExitCode.BAD_INPUT)
    c = checked.case
    # with --show-defaults stdout is the resolved case alone (valid YAML, to be saved): the
    # report goes to stderr then
    typer.echo(f"{case}: ok: '{c.name}', loading {c.loading.type}\n{checked.report.format()}\n"
               f"{checked.size_line()}", err=show_defaults)
    if show_defaults:
        from dem_cli.commands.defaults import resolved_case_yaml

        typer.echo(resolved_case_yaml(c), nl=False)


@app.command()
def schema(
    out: Path = typer.Option(
        None, "--out", "-o", help="write the JSON schema here (default: print it)"
    ),
    rocking: bool = typer.Option(
        False, "--rocking",
        help="the schema of two-body cases (dem rocking; cases/rocking/rocking.schema.json)"),
) -> None:
    """Export the JSON schema of case files (for editor completion and validation).
    Exit 0 ok, 2 --out cannot be written."""
    from dem_cli.commands.exit_codes import write_output_file

    if rocking:
        from dem.rocking.schema import rocking_case_json_schema as make
    else:
        from dem.case import case_json_schema as make
    text = make()
    if out is None:
        typer.echo(text)
    else:
        raise typer.Exit(write_output_file(out, text, typer.echo, _err))


@app.command()
def run(
    case: Path = typer.Argument(..., metavar="CASE", help="case YAML file"),
    out: Path = typer.Option(..., "--out", "-o", help="output directory"),
    progress: bool = typer.Option(True, help="show a progress bar"),
    force: bool = typer.Option(False, "--force",
                               help="clear OUT if it holds a different run (or a sweep)"),
    max_blocks: int = typer.Option(None, "--max-blocks", help=MAX_BLOCKS_HELP),
    resume: bool = typer.Option(
        False, "--resume",
        help="if OUT holds an unfinished run of the same case (killed, stopped) with a restart "
             "point (restart.npz, written at each checkpoint), go on from it instead of "
             "starting over"),
) -> None:
    """Run one case and write summary.json, frames.npz (and VTK) into OUT.  OUT must be new,
    empty, or hold a run of the same case (replaced, or with --resume continued); another run
    is refused unless --force.
    SIGTERM / SIGHUP stop the run like Ctrl-C.  A two-body case (``rocking:``) runs the two-body
    model, as ``dem rocking``.  Exit 0 ok, 1 failed or stopped, 2 bad input."""
    if _is_rocking_file(case):
        _err(f"{case}: a two-body rocking case: running the two-body model (dem rocking)")
        raise typer.Exit(_rocking(case, out, True, force))
    from dem_cli.commands.run import run_case_file

    raise typer.Exit(run_case_file(case, out, progress=progress, force=force,
                                   max_blocks=max_blocks, resume=resume))


def _rocking(case: Path, out: Path, plots: bool, force: bool) -> int:
    from dem_cli.commands.rocking import rocking_command

    return rocking_command(case, out, plots=plots, force=force, echo=typer.echo, err=_err)


@app.command()
def rocking(
    case: Path = typer.Argument(..., metavar="CASE",
                                help="two-body case YAML file (cases/rocking/)"),
    out: Path = typer.Option(..., "--out", "-o", help="output directory"),
    plots: bool = typer.Option(True, help="write PNG plots"),
    force: bool = typer.Option(False, "--force", help="clear OUT if it holds another run"),
) -> None:
    """Run the two-body rocking model (thesis Ch. 5): summary.json, rocking.npz, plots in OUT."""
    raise typer.Exit(_rocking(case, out, plots, force))


@app.command()
def sweep(
    case: Path = typer.Argument(..., metavar="CASE", help="shake case YAML file"),
    out: Path = typer.Option(..., "--out", "-o", help="output directory"),
    frequencies: str = typer.Option(None, "--frequencies", help="comma-separated, Hz: 1.8,2.0,2.4"),
    range_: str = typer.Option(None, "--range", help="start:stop:step, Hz (stop included)"),
    cycles: float = typer.Option(None, "--cycles", help="cycles per run (default: the case's)"),
    margin: float = typer.Option(1.0, "--margin", help="s simulated after the last cycle"),
    workers: int = typer.Option(None, "--workers", help="local workers (default: one per core)"),
    scheduler: str = typer.Option(None, "--scheduler", help="address of a running dask scheduler"),
    max_steps: int = typer.Option(None, "--max-steps", help="cap the steps of each run (smoke)"),
    realisations: int = typer.Option(None, "--realisations", "-n",
                                     help="run the sweep for N realisations of the case's "
                                          "imperfections (seeds S, S+1, ...)"),
    seed: int = typer.Option(None, "--seed", help="first seed of --realisations"),
    drain_file: Path = typer.Option(None, "--drain-file",
                                    help="once this file exists, no new run starts and the runs "
                                         "in flight finish (default: OUT/DRAIN)"),
    batch: int = typer.Option(None, "--batch", help=BATCH_HELP),
    arch: str = typer.Option("cpu", "--arch", help=ARCH_HELP),
    max_points: int = typer.Option(None, "--max-points",
                                   help="refuse more frequencies than this (default 100: a "
                                        "larger sweep is almost always a typo in --range)"),
) -> None:
    """Frequency sweep of a shake case at its constant peak acceleration (or amplitude): one run
    per frequency on dask, each analysed (postprocess.shake), then the amplification curves,
    characteristic frequency, effective range and lag times in OUT/sweep.json and sweep.png.
    To end a long sweep without losing the runs in flight, ``touch OUT/DRAIN`` (Ctrl-C or
    SIGTERM stop at once and lose them; a rerun resumes either way).
    Exit 0 all points ok, 1 a point failed or the sweep was stopped or drained, 2 bad input."""
    from dem.batch import DRAIN_FILE, clear_drain_file
    from dem_cli.commands.sweep import run_sweep, say

    drain_file = drain_file if drain_file is not None else out / DRAIN_FILE
    clear_drain_file(drain_file, say)
    raise typer.Exit(run_sweep(case, out, frequencies, range_, cycles, margin, scheduler, workers,
                               max_steps, realisations, seed, drain_file=drain_file, batch=batch,
                               arch=arch, max_points=max_points))


@app.command()
def ensemble(
    case: Path = typer.Argument(..., metavar="CASE", help="case YAML file with imperfections:"),
    out: Path = typer.Option(..., "--out", "-o", help="output directory"),
    realisations: int = typer.Option(..., "--realisations", "-n", help="number of realisations"),
    seed: int = typer.Option(None, "--seed", help="first seed (default: the case's)"),
    workers: int = typer.Option(None, "--workers", help="local workers (default: one per core)"),
    scheduler: str = typer.Option(None, "--scheduler", help="address of a running dask scheduler"),
    max_steps: int = typer.Option(None, "--max-steps", help="cap the steps of each run (smoke)"),
    drain_file: Path = typer.Option(None, "--drain-file",
                                    help="once this file exists, no new realisation starts and "
                                         "those in flight finish (default: OUT/DRAIN)"),
    batch: int = typer.Option(None, "--batch", help=BATCH_HELP),
    arch: str = typer.Option("cpu", "--arch", help=ARCH_HELP),
) -> None:
    """Run N realisations of an imperfect case (seeds S, S+1, ...) on dask; OUT/ensemble.json
    holds each realisation's results and their statistics (median, 10-90 %, mean, std,
    mechanism counts).  A rerun skips finished realisations.  Exit 0 all ok, 1 one failed,
    2 bad input.  ``touch OUT/DRAIN`` ends it without losing the realisations in flight."""
    from dem.batch import DRAIN_FILE, clear_drain_file
    from dem_cli.commands.ensemble import run_ensemble, say

    drain_file = drain_file if drain_file is not None else out / DRAIN_FILE
    clear_drain_file(drain_file, say)
    raise typer.Exit(run_ensemble(case, out, realisations, seed, scheduler, workers, max_steps,
                                  drain_file=drain_file, batch=batch, arch=arch))


@app.command()
def post(
    directory: Path = typer.Argument(..., metavar="DIR",
                                     help="run, sweep or ensemble directory"),
) -> None:
    """(Re)build the analysis of a run directory (shake: analysis.json, PNGs, excited.vtu; tilt:
    collapse and mechanism into analysis.json), of a sweep directory (every point re-analysed,
    sweep.json and sweep.png re-aggregated) or of an ensemble directory (every realisation
    re-read, ensemble.json and lambda.png re-aggregated).  Anything else is named in one line.
    Exit 0 ok, 1 a point or realisation failed, 2 bad input."""
    from dem_cli.commands.post import post_command

    raise typer.Exit(post_command(directory))


@app.command()
def summary(
    directories: list[Path] = typer.Argument(..., metavar="DIR",
                                         help="run, sweep or ensemble directories"),
    csv_file: Path = typer.Option(None, "--csv", help="also write the rows as CSV to this file"),
    fmt: str = typer.Option("table", "--format", help="table (rich, on screen) or csv (stdout)"),
) -> None:
    """One row per run, sweep or ensemble directory: kind, case name, status, lambda (a tilt;
    an ensemble's median and 10-90 %), ds amplification and f_c (a shake run, a sweep), the
    mechanism, wall and CPU seconds (a sweep's or an ensemble's: the sums over its runs); read
    from the files the runs wrote.  Exit 0, or 2 when a directory is none of those (1 when
    --csv cannot be written for a fault of the disk)."""
    from dem_cli.commands.summary import summary_command

    raise typer.Exit(summary_command(directories, csv_file, fmt, echo=typer.echo, err=_err))


@app.command()
def view(
    directory: Path = typer.Argument(..., metavar="DIR",
                                     help="run, sweep or ensemble directory"),
    out: Path = typer.Option(None, "--out", "-o", help="write here (default: the drawn run's "
                                                       "directory)"),
    point: str = typer.Option(None, "--point", help="the sweep point (f2.800Hz, or 2.8) or "
                                                    "realisation (seed-5) to draw"),
    frames: int = typer.Option(40, "--frames", help="frames drawn, spread over the recording "
                                                    "(a 142-block wall: ~1-3 s each)"),
    fps: float = typer.Option(10.0, "--fps", help="frames per second of the animation"),
    panels: int = typer.Option(6, "--panels", help="panels of the frame strip"),
    fmt: str = typer.Option("gif", "--format", help="gif, or mp4 (needs ffmpeg)"),
    magnify: float = typer.Option(None, "--magnify",
                                  help="draw the motion relative to the table this many times "
                                       "larger (default: 1 for a tilt; a shake: the motion "
                                       "made 5 % of the model's size)"),
) -> None:
    """A look at a run without ParaView: animation.gif (or .mp4) and strip.png drawn off-screen
    from frames.npz (blocks coloured by their displacement; a tilt drawn on its turning table, a
    shake on its moving table).  Given a sweep or an ensemble, draws one of its runs and says
    which (--point for another).  Exit 0 written, 1 a drawing failed, 2 bad input."""
    from dem_cli.commands.view import view_command

    raise typer.Exit(view_command(directory, out, point, frames, fps, panels, fmt, magnify,
                                  echo=typer.echo, err=_err))


# --- help text: one line per command in ``dem --help`` (the details are in
# each command's --help), docstrings reflowed with their ``literals`` as plain quotes, and no
# "<bool>" type shown on flags ---
SHORT_HELP = {
    "check": "validate a case file and its scene without running it",
    "schema": "export the JSON schema of case files (--rocking: two-body cases)",
    "run": "run one case into an output directory",
    "rocking": "run the two-body rocking model (thesis Ch. 5)",
    "sweep": "frequency sweep of a shake case (amplification curves)",
    "ensemble": "N realisations of an imperfect case and their statistics",
    "post": "(re)build the analysis of a run, sweep or ensemble directory",
    "summary": "one table row per run, sweep or ensemble directory",
    "view": "an animation and a frame strip of a run (no ParaView needed)",
}


def _plain_help(doc: str) -> str:
    """A docstring as one reflowed paragraph per blank-line block, ``x`` shown as 'x'."""
    import inspect
    import re

    text = re.sub(r"``([^`]+)``", r"'\1'", inspect.cleandoc(doc))
    return "\n\n".join(" ".join(p.split()) for p in text.split("\n\n"))


def _first_sentence(doc: str) -> str:
    text = _plain_help(doc).split("\n\n")[0]
    cut = text.find(". ")
    return text if cut < 0 else text[:cut]


def _polish_help() -> None:
    for info in app.registered_commands:
        doc = info.help or (info.callback.__doc__ if info.callback else None)
        name = info.name or (info.callback.__name__ if info.callback else None)
        if doc:
            info.help = _plain_help(doc)
            info.short_help = info.short_help or SHORT_HELP.get(name) or _first_sentence(doc)
    try:
        from typer.core import TyperArgument, TyperOption
    except ImportError:  # pragma: no cover - another typer
        return
    if hasattr(TyperArgument, "_usage_display_name") and \
            not getattr(TyperArgument, "_dem_plain_usage", False):
        # the usage line names arguments as the help text does, CASE and DIR... (this typer
        # writes a required one {case})
        def _usage_display_name(self):
            name = (self.metavar or self.name or "").upper()
            name = name if self.required else f"[{name}]"
            return name + ("..." if self.nargs != 1 else "")

        TyperArgument._usage_display_name = _usage_display_name
        TyperArgument._dem_plain_usage = True
    if not getattr(TyperOption, "_dem_no_bool", False):
        shown = TyperOption.display_type_rich

        def display_type_rich(self, ctx):
            return None if getattr(self, "is_flag", False) else shown(self, ctx)

        TyperOption.display_type_rich = display_type_rich
        TyperOption._dem_no_bool = True


_polish_help()

if __name__ == "__main__":  # pragma: no cover
    app()
