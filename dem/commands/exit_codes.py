"""Exit codes of every command (a contract: ../shared/DESIGN.md, docs/failures.md).

    0  ok
    1  the run failed, was stopped by a signal, or its output could not be written
    2  bad input: case file, options, --out
"""

from __future__ import annotations

from enum import IntEnum


class ExitCode(IntEnum):
    OK = 0
    RUN_FAILED = 1
    BAD_INPUT = 2


def exit_code_for(err: BaseException) -> ExitCode:
    """The one mapping from what stopped a command to its exit code.

    Bad input is a ValueError (a case field: dem.case.CaseError too; a scene: SceneError; an
    option or engine input: InputError, SweepInputError, RockingCaseError; --out: RunDirError;
    a directory that cannot be analysed: ShakeAnalysisError) -> 2.  Anything else that ends a
    run (SimulationError, RockingError, an OSError such as OutputError, a signal) -> 1.
    """
    from dem.case import CaseError

    if isinstance(err, (ValueError, CaseError)):
        return ExitCode.BAD_INPUT
    return ExitCode.RUN_FAILED


def write_output_file(path, text: str, echo=print, err=print) -> ExitCode:
    """A file a command writes where ``--out`` says (``dem schema --out``), through the atomic
    writer (dem.output.atomic); a path that cannot be written is bad input (exit 2), in one
    line, not a traceback with exit 1."""
    from pathlib import Path

    from dem.output.atomic import write_text

    path = Path(path)
    try:
        write_text(path, text)
    except OSError as e:
        why = e.strerror or str(e)
        if not path.parent.is_dir():
            why = f"the directory {path.parent} does not exist"
        err(f"error: --out {path}: cannot write: {why}")
        return ExitCode.BAD_INPUT
    echo(f"wrote {path}")
    return ExitCode.OK
