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
