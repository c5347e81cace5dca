"""Atomic file writes: the one way every output file of a run, a sweep or an analysis is written.

A file is written to a temporary file in the same directory (same file system, so the final
``os.replace`` is atomic), flushed and fsync'ed, then renamed over the target.  A reader sees
either the old file or the new one, never a half-written one; a write that fails (ENOSPC, EIO,
an interrupt) removes its temporary file and leaves the old file (or none) in place.

    with atomic_path(path) as tmp:        # any writer that takes a path (np.savez, savefig ...)
        write_somehow(tmp)
    write_text(path, text)                # str
    write_json(path, data)                # dict -> indented JSON (numpy scalars / arrays ok)
    save_npz(path, arrays)                # np.savez_compressed (compressed=False: np.savez)

Temporary names start with ``.`` and end with ``.tmp`` + the target's suffix (writers such as
``np.savez`` and ``savefig`` pick the format from the suffix), so a stray one is easy to spot
and is never mistaken for an output.
"""

from __future__ import annotations

import contextlib
import json
import math
import os
import secrets
from pathlib import Path
from typing import Iterator

import numpy as np


class OutputError(OSError):
    """An output file could not be written (disk full, I/O error, read-only file system): exit
    code 1 for every command (dem_cli.commands.exit_codes); ``dem.run.OutputError`` is this class.
    Made as OutputError(errno or None, message); its text is the message, with the errno in
    words after it where there is one (never OSError's "[Errno None] ...")."""

    def __str__(self) -> str:
        if self.strerror is None:
            return super().__str__()
        return self.strerror + (f" (errno {self.errno})" if self.errno is not None and
                                f"errno {self.errno}" not in self.strerror else "")


@contextlib.contextmanager
def atomic_path(path: str | Path) -> Iterator[Path]:
    """Yield a temporary path next to ``path``; on a clean exit fsync it and move it onto
    ``path``; on any exception remove it and re-raise.

    The temporary name is chosen before the ``try`` and the file created inside it, so an
    exception at any point after its creation (a stop signal, dem.signals, raises between any
    two bytecodes) removes it: with ``tempfile.mkstemp`` the file existed before its name was
    returned, and a SIGTERM landing there left a stray ``.tmp`` file (seen once under load in
    tests/test_reliability.py).  The name carries 48 random bits and is created with O_EXCL:
    a clash raises FileExistsError and leaves the other file alone."""
    path = Path(path)
    tmp: Path | None = path.parent / f".{path.stem}.{secrets.token_hex(6)}.tmp{path.suffix}"
    try:
        try:
            os.close(os.open(tmp, os.O_CREAT | os.O_EXCL | os.O_WRONLY, 0o644))
        except FileExistsError:
            tmp = None  # another writer's file: not ours to remove
            raise
        yield tmp
        with open(tmp, "rb+") as fh:
            os.fsync(fh.fileno())
        os.replace(tmp, path)
    except BaseException:
        if tmp is not None:
            with contextlib.suppress(OSError):
                tmp.unlink()
        raise
    _fsync_dir(path.parent)


def _fsync_dir(directory: Path) -> None:
    """Make the rename itself durable (best effort: not every file system allows it)."""
    with contextlib.suppress(OSError):
        fd = os.open(directory, os.O_RDONLY)
        try:
            os.fsync(fd)
        finally:
            os.close(fd)


def write_bytes(path: str | Path, data: bytes) -> None:
    with atomic_path(path) as tmp:
        with open(tmp, "wb") as fh:
            fh.write(data)


def write_text(path: str | Path, text: str) -> None:
    write_bytes(path, text.encode("utf-8"))


def json_default(o):
    """numpy scalars and arrays in json.dumps."""
    if isinstance(o, (np.floating, np.integer, np.bool_)):
        return o.item()
    if isinstance(o, np.ndarray):
        return o.tolist()
    raise TypeError(type(o).__name__)


def strict_json(o):
    """NaN / inf -> None (strict JSON), recursively."""
    if isinstance(o, dict):
        return {k: strict_json(v) for k, v in o.items()}
    if isinstance(o, (list, tuple)):
        return [strict_json(v) for v in o]
    if isinstance(o, (float, np.floating)) and not math.isfinite(float(o)):
        return None
    return o


def write_json(path: str | Path, data, indent: int = 2, strict: bool = False) -> None:
    """JSON through :func:`atomic_path`; ``strict`` turns NaN / inf into null."""
    if strict:
        data = strict_json(json.loads(json.dumps(data, default=json_default)))
    write_text(path, json.dumps(data, indent=indent, default=json_default) + "\n")


def save_npz(path: str | Path, arrays: dict, compressed: bool = True) -> None:
    """np.savez_compressed (``compressed``, the default) or np.savez through
    :func:`atomic_path`."""
    with atomic_path(path) as tmp:
        with open(tmp, "wb") as fh:
            (np.savez_compressed if compressed else np.savez)(fh, **arrays)


def savefig(fig, path: str | Path, **kwargs) -> None:
    """matplotlib ``fig.savefig`` through :func:`atomic_path` (the format from the suffix)."""
    with atomic_path(path) as tmp:
        fig.savefig(tmp, **kwargs)
