"""One study session: the drain file that ends it softly, the SIGTERM / SIGINT handlers that end
it at once (:mod:`studies.kit.child`), an optional UTC stop time, the CPU ledger that adds each
session's CPU seconds to a committed ``cpu.json``, and the echo of the command that regenerates
the study's outputs."""

from __future__ import annotations

import sys
import time
from pathlib import Path

from studies.kit import child
from studies.kit.records import merge_json


def log_err(message: str) -> None:
    print(message, file=sys.stderr)


def start(runs: Path, drain_file: Path | None = None, log=log_err) -> Path:
    """Begin a session that runs: clear a drain file left by the last one (dem.batch) and install
    the signal handlers; returns the drain file (default ``<runs>/DRAIN``)."""
    from dem.batch import DRAIN_FILE, clear_drain_file

    drain = Path(drain_file) if drain_file is not None else Path(runs) / DRAIN_FILE
    clear_drain_file(drain, log)
    child.install_signal_handlers()
    return drain


_DEADLINES: dict[str, float] = {}  # stop_at -> the epoch second it stands for (first look)


def stop_deadline(stop_at: str, now: float | None = None) -> float:
    """The epoch second of the UTC time ``stop_at`` (HH:MM) nearest to ``now`` (default: the
    first call for this ``stop_at``, then kept): within the last 12 hours it has passed, within
    the next 12 it is ahead, so a session started at 23:50 with --stop-at 00:05 runs for 15
    minutes, where comparing the clock's HH:MM with it would stop at once."""
    if stop_at in _DEADLINES and now is None:
        return _DEADLINES[stop_at]
    try:
        hh, mm = (int(x) for x in stop_at.split(":"))
        if not (0 <= hh < 24 and 0 <= mm < 60):
            raise ValueError
    except ValueError:
        raise ValueError(f"--stop-at wants a UTC time HH:MM, got {stop_at!r}") from None
    t = time.time() if now is None else now
    midnight = t - t % 86400.0
    at = midnight + 3600.0 * hh + 60.0 * mm
    best = min((at - 86400.0, at, at + 86400.0), key=lambda c: abs(c - t))
    if now is None:
        _DEADLINES[stop_at] = best
    return best


def should_stop(drain: Path | None = None, stop_at: str | None = None, log=print) -> bool:
    """Start nothing new: a stop signal came, the drain file exists, or the UTC time ``stop_at``
    (HH:MM; :func:`stop_deadline`: the one nearest to the first look, so past midnight works)
    is reached (then the stop is requested, so that later checks agree)."""
    if child.stopped() or (drain is not None and Path(drain).exists()):
        return True
    if stop_at and time.time() >= stop_deadline(stop_at):
        log(f"--stop-at {stop_at} UTC reached: nothing new starts")
        child.request_stop()
        return True
    return False


def add_cpu(path: Path, key: str, seconds: float) -> dict:
    """Add ``seconds`` to ``key`` of the CPU ledger ``path`` (JSON {key: CPU s}) under a lock:
    two sessions beside each other on other keys keep both."""
    def add(data):
        data[key] = data.get(key, 0.0) + seconds
    return merge_json(path, add)


def command(prog: str, *parts, **options) -> str:
    """The command line that regenerates a study's outputs: ``python -m studies PROG PARTS`` and
    each ``--option value`` whose value is not None (a value (value, default) pair is left out
    when it equals its default; a list is spread; a float is written with :g)."""
    def text(v):
        return f"{v:g}" if isinstance(v, float) else str(v)

    cmd = [f"python -m studies {prog}", *map(str, parts)]
    for key, value in options.items():
        if isinstance(value, tuple) and len(value) == 2:
            value, default = value
            if value == default:
                continue
        if value is None or value is False:
            continue
        flag = "--" + key.replace("_", "-")
        if value is True:
            cmd.append(flag)
        elif isinstance(value, (list, tuple)):
            cmd += [flag, *map(text, value)]
        else:
            cmd += [flag, text(value)]
    return " ".join(cmd)


def begin(out: Path, runs: Path | None = None) -> tuple[Path, Path]:
    """Begin a session of a study that stops on signals and a stop time only (calibration,
    qs-validation): ``out`` made, the raw runs' folder (default ``<out>/runs``) and the signal
    handlers installed; returns (out, runs)."""
    out = Path(out)
    out.mkdir(parents=True, exist_ok=True)
    child.install_signal_handlers()
    return out, Path(runs) if runs is not None else out / "runs"
