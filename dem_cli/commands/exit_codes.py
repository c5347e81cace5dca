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


# errnos of a path that cannot be written at all (a bad --out: exit 2), as opposed to a fault
# while writing (disk full, I/O error: exit 1)
import errno as _errno

PATH_ERRNOS = {_errno.ENOENT, _errno.ENOTDIR, _errno.EACCES, _errno.EPERM, _errno.EROFS,
               _errno.EISDIR, _errno.ENAMETOOLONG, _errno.EEXIST}


def os_error_text(e: OSError, path=None) -> str:
    """Why a write failed, in words, without the temporary file's name OSError carries (the
    atomic writer's ``.name.xxxx.tmp``): 'No space left on device', or for a missing parent
    'the directory D does not exist'.  Never "[Errno None]"."""
    from pathlib import Path

    if path is not None and e.errno == _errno.ENOENT and not Path(path).parent.is_dir():
        return f"the directory {Path(path).parent} does not exist"
    return e.strerror or type(e).__name__


def os_error_code(e: OSError) -> ExitCode:
    """2 where the path cannot be written at all (PATH_ERRNOS), 1 for a fault while writing."""
    return ExitCode.BAD_INPUT if e.errno in PATH_ERRNOS else ExitCode.RUN_FAILED


def writable_directory(directory, option: str = "--out") -> str | None:
    """None when ``directory`` exists (or can be created) and a file can be made in it, else why
    not, as one line naming ``option``.  Tried with a real file (removed at once): permissions
    alone miss a read-only file system and root's rights."""
    import tempfile
    from pathlib import Path

    directory = Path(directory)
    try:
        directory.mkdir(parents=True, exist_ok=True)
        with tempfile.TemporaryFile(dir=directory):
            pass
    except OSError as e:
        if directory.exists() and not directory.is_dir():
            return f"{option} {directory}: exists and is not a directory"
        return f"{option} {directory}: cannot write here ({os_error_text(e)})"
    return None


def write_output_file(path, text: str, echo=print, err=print, option: str = "--out") -> ExitCode:
    """A file a command writes where ``--out`` (``option``) says (``dem schema --out``,
    ``dem summary --csv``), through the atomic writer (dem.output.atomic): one line and exit 2
    for a path that cannot be written (a missing directory, no permission, a read-only file
    system), exit 1 for a fault while writing (disk full); nothing half-written is left."""
    from pathlib import Path

    from dem.output.atomic import write_text

    path = Path(path)
    try:
        write_text(path, text)
    except OSError as e:
        err(f"error: {option} {path}: cannot write: {os_error_text(e, path)}")
        return os_error_code(e)
    echo(f"wrote {path}")
    return ExitCode.OK
