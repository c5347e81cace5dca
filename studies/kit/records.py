"""A study's JSON records: read one (None when missing or unreadable) and change one under an
exclusive lock, so that two study processes on one record (e.g. different --seeds of a sweep)
never lose each other's rows."""

from __future__ import annotations

import contextlib
import fcntl
import json
from pathlib import Path


def read_json(path: Path) -> dict | None:
    """The parsed JSON at ``path``; None when it is missing or not JSON."""
    try:
        return json.loads(Path(path).read_text())
    except (OSError, ValueError):
        return None


@contextlib.contextmanager
def locked(path: Path):
    """An exclusive lock on ``path``.lock for a read-merge-write of ``path``."""
    path = Path(path)
    path.parent.mkdir(parents=True, exist_ok=True)
    with open(str(path) + ".lock", "w") as fh:
        fcntl.flock(fh, fcntl.LOCK_EX)
        try:
            yield
        finally:
            fcntl.flock(fh, fcntl.LOCK_UN)


def merge_json(path: Path, change) -> dict:
    """Read ``path`` (``{}`` when missing), ``change(data)`` it in place or return a new dict,
    write it back atomically, all under :func:`locked`; returns what was written."""
    from dem.output.atomic import write_json

    with locked(path):
        data = read_json(path) or {}
        new = change(data)
        data = data if new is None else new
        write_json(path, data, indent=1)
    return data
