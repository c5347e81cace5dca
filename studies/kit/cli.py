"""A study's command line: one Typer command per study, run by ``main(argv)``.

Every study module keeps ``main(argv=None) -> int`` (the entry ``python -m studies <study>``
hands it what follows the study's name; tests call it with a list) and builds its options as a
Typer command (:func:`study_app`, its help the study's docstring).  :func:`run` parses ``argv``
with it and returns the exit code instead of leaving the process: 0 ok, what the command
returned, 2 for bad options (Typer's usage errors, as argparse's were).
"""

from __future__ import annotations

import sys
from collections.abc import Iterable, Sequence

import typer
from rich.markup import escape


def text(doc: str | None) -> str:
    """A docstring or option help as Typer's help text: Rich markup escaped, so that a
    bracketed span such as ``[m, m, m]`` is shown rather than read as a style tag."""
    return escape(doc or "")


def study_app() -> typer.Typer:
    """A Typer app for one study command: add it with ``@app.command(help=text(__doc__))``
    (the study's docstring as its help) and run it with :func:`run`."""
    return typer.Typer(add_completion=False)


def spread_lists(argv: Sequence[str], flags: Iterable[str]) -> list[str]:
    """``--flag a b c`` as ``--flag a --flag b --flag c`` for each of ``flags`` (options that
    take one or more values, Typer's ``list[...]`` options): the values are the words up to the
    next word that starts with ``--``.  ``--flag=a`` and a flag with no value pass unchanged (a
    flag with no value is then a usage error: Click asks for its value)."""
    flags, out, i = set(flags), [], 0
    argv = list(argv)
    while i < len(argv):
        word = argv[i]
        i += 1
        if word not in flags:
            out.append(word)
            continue
        values = []
        while i < len(argv) and not argv[i].startswith("--"):
            values.append(argv[i])
            i += 1
        if not values:
            out.append(word)
        for v in values:
            out += [word, v]
    return out


def usage_error(message: str) -> None:
    """Refuse the options (exit 2 with the usage line and ``message``, as argparse's
    ``error`` did); call it from inside a study's command."""
    raise typer.BadParameter(message)


def run(app: typer.Typer, argv: Sequence[str] | None, name: str,
        lists: Iterable[str] = ()) -> int:
    """Run the study command of ``app`` on ``argv`` (None: ``sys.argv[1:]``) as
    ``python -m studies <name>``; ``lists`` are its options that take several values
    (:func:`spread_lists`).  The command sees ``argv`` as given in ``ctx.obj["argv"]`` (for
    its command echo).  Returns the exit code: the command's return value (None: 0), a
    ``typer.Exit``'s code, 2 for a usage error (printed to stderr), 1 for an abort."""
    given = list(sys.argv[1:] if argv is None else argv)
    try:
        rc = app(args=spread_lists(given, lists), prog_name=f"python -m studies {name}",
                 standalone_mode=False, obj={"argv": given})
    except typer.Exit as err:
        return err.exit_code
    except typer.Abort:
        print("Aborted!", file=sys.stderr)
        return 1
    except typer.TyperException as err:    # Typer's usage errors (its own Click's exceptions)
        err.show()
        return err.exit_code
    return int(rc or 0)
