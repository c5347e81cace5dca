"""The environment variables dem reads, each checked when a command starts (dem_cli.app), so that a
bad value is one line naming it (exit 2) instead of a C++ abort after Taichi's start-up
(``DEM_THREADS=0``), an internal message, or a value silently ignored.

=========================  ==========================================================
``DEM_THREADS``            Taichi's CPU threads, an integer 1 - :data:`MAX_THREADS`
``DEM_MAX_BLOCKS``         the scene size limit (``--max-blocks``), an integer >= 1
``DEM_ARCH``               where Taichi runs: ``cpu`` or ``cuda``
``DEM_TRACEBACK``          ``1``: an unforeseen error shows its traceback
``DEM_TI_SOURCE_CARETS``   ``1``: Taichi's full kernel error messages
``DEM_TI_PLAIN_FRONT_END`` ``1``: Taichi's own kernel front end (dem.ti_runtime)
``DEM_DEVICE_ARRAYS``      ``1``: a batch keeps its arrays as on a GPU, K to an engine on the
                           CPU too (dem.run.batched)
``DEM_STEPS_PER_LAUNCH``   the device kernel's steps a launch, an integer 1 -
                           :data:`MAX_STEPS_PER_LAUNCH` (dem.engine.step_device)
=========================  ==========================================================

An unset or empty variable is the default.  The flags are on when set to any non-empty value
(the readers test ``os.environ.get``), so ``0`` would turn them on: it is refused, as is any
other value than ``1``.  Pure Python, no imports beyond the standard library (it runs before
every command).
"""

from __future__ import annotations

import os

# a thread count above this is a typo (no node the project targets has a thousand cores, and
# Taichi's thread pool would only contend for the cores there are)
MAX_THREADS = 1024
ARCHS = ("cpu", "cuda")
# the scene size limit without --max-blocks or DEM_MAX_BLOCKS (dem.validate: why)
DEFAULT_MAX_BLOCKS = 20_000
# the device kernel's steps a launch above this would compile for hours (its compile grows
# faster than the steps: 32 / 101 / 579 CPU-s at 1 / 2 / 4 on the test VM, benchmarks/RESULTS.md)
MAX_STEPS_PER_LAUNCH = 8

# the integer variables: name, lowest, highest (None: no bound)
INTEGERS = (("DEM_THREADS", 1, MAX_THREADS), ("DEM_MAX_BLOCKS", 1, None),
            ("DEM_STEPS_PER_LAUNCH", 1, MAX_STEPS_PER_LAUNCH))

FLAGS = ("DEM_TRACEBACK", "DEM_TI_SOURCE_CARETS", "DEM_TI_PLAIN_FRONT_END", "DEM_DEVICE_ARRAYS")


class EnvironmentInputError(ValueError):
    """An environment variable with a value dem cannot use (bad input: exit code 2)."""


def int_variable(name: str, lo: int, hi: int | None = None) -> int | None:
    """The integer value of environment variable ``name`` (None when unset or empty); raises
    EnvironmentInputError naming it when it is not an integer in [lo, hi]."""
    raw = os.environ.get(name, "").strip()
    if not raw:
        return None
    try:
        value = int(raw)
    except ValueError:
        value = None
    if value is None or value < lo or (hi is not None and value > hi):
        rng = f"{lo} - {hi}" if hi is not None else f">= {lo}"
        raise EnvironmentInputError(
            f"environment variable {name}={raw!r}: must be a whole number {rng} (or unset)")
    return value


def max_blocks_default() -> int:
    """``DEM_MAX_BLOCKS`` if set (a bad value raises EnvironmentInputError, naming it), else
    DEFAULT_MAX_BLOCKS."""
    env = int_variable("DEM_MAX_BLOCKS", 1)
    return DEFAULT_MAX_BLOCKS if env is None else env


def environment_errors() -> list[str]:
    """One line per environment variable of the table above whose value dem cannot use."""
    errors = []
    for name, lo, hi in INTEGERS:
        try:
            int_variable(name, lo, hi)
        except EnvironmentInputError as err:
            errors.append(str(err))
    arch = os.environ.get("DEM_ARCH", "")
    if arch and arch not in ARCHS:
        errors.append(f"environment variable DEM_ARCH={arch!r}: must be one of "
                      f"{', '.join(ARCHS)} (or unset)")
    for name in FLAGS:
        value = os.environ.get(name, "")
        if value and value != "1":
            errors.append(f"environment variable {name}={value!r}: set it to 1 to turn it on, "
                          f"or unset it (any other non-empty value would turn it on too)")
    return errors
