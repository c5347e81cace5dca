"""Run directories: one run per directory, never two at once, never mixed with an old run.

``claim(out, case_json, force)`` is called by ``dem run`` (and for each point of a sweep) before
anything is written.  It

1. refuses (:class:`RunDirError`, exit 2) an ``--out`` that is an existing file, or a directory
   that cannot be written;
2. takes the lock ``OUT/run.lock`` (``fcntl.flock``, exclusive, non-blocking; the pid of the holder
   is written into it).  The kernel drops the lock when the process ends, however it ends, so a
   lock file left by a killed run is stale and simply taken over; a second run into a directory
   that a live run holds is refused;
3. looks at what the directory holds:
   * nothing (or only a stale lock): used as it is;
   * a run of the same case (``case.json`` equal to the new one): the old run's files are removed
     (a rerun; a stale ``analysis.json`` would otherwise survive), unless ``resume`` and it left
     a restart point (dem.run.resume): then the run's own files are kept for the run to go on
     from, and the analysis of the stopped run (analysis.json, PNGs: :func:`drop_analysis`)
     is removed;
   * a different run, a sweep, or anything else: refused, unless ``force``, which removes the
     directory's contents - but only where it holds a dem run or sweep (``case.json``,
     ``summary.json``, ``sweep.json`` or ``run.lock``); a directory of other files is never
     cleared.

``RunDir.release()`` removes the lock file; ``RunDir.abandon()`` (a run rejected before it
started, e.g. an initial overlap found by the engine) also removes what the run wrote and the
directory itself if the claim created it, so ``dem post`` never sees a run that never ran.
"""

from __future__ import annotations

import contextlib
import errno
import fcntl
import json
import os
import shutil
from pathlib import Path

LOCK = "run.lock"
RESTART_FILE = "restart.npz"  # dem.run.resume.RESTART_FILE (this module imports no engine)
RUN_MARKERS = ("case.json", "summary.json", "sweep.json", LOCK)
# what a run itself writes and a resumed run goes on from (dem.run.write, dem.run.resume); the
# rest of a run directory (analysis.json, the PNGs and excited.vtu of ``dem post``, lean.png)
# describes the run as it was when analysed and is dropped when it is resumed
RUN_FILES = ("case.json", "summary.json", "frames.npz", RESTART_FILE, "instruments.npz",
             "imperfections.npz", "vtk", LOCK)


class RunDirError(ValueError):
    """The output directory cannot be used (exit code 2); the message says why and what to do."""


def lock_holder(out: str | Path) -> int | None:
    """The pid of the live process that holds OUT/run.lock (written into it by the holder;
    0 where it cannot be read), or None when no process holds it (no lock, or a stale one left
    by a killed process: the kernel dropped the flock when it ended)."""
    lock = Path(out) / LOCK
    try:
        fh = open(lock, "rb")
    except OSError:
        return None
    with fh:
        try:
            fcntl.flock(fh.fileno(), fcntl.LOCK_EX | fcntl.LOCK_NB)
        except BlockingIOError:
            with contextlib.suppress(OSError, ValueError, IndexError):
                return int(lock.read_text().split()[0])
            return 0
        fcntl.flock(fh.fileno(), fcntl.LOCK_UN)
    return None


def _holder(path: Path) -> str:
    with contextlib.suppress(OSError, ValueError):
        return f" (pid {int(path.read_text().split()[0])})"
    return ""


def _lock(out: Path) -> int:
    """Open and flock OUT/run.lock; returns the fd.  Raises RunDirError if a live run holds it."""
    path = out / LOCK
    while True:
        fd = os.open(path, os.O_RDWR | os.O_CREAT, 0o644)
        try:
            fcntl.flock(fd, fcntl.LOCK_EX | fcntl.LOCK_NB)
        except BlockingIOError:
            os.close(fd)
            raise RunDirError(f"{out}: another dem run{_holder(path)} is writing into this "
                              f"directory; wait for it or choose another --out") from None
        # the holder may have removed the file between our open and flock: lock the file that
        # is there now, not an orphaned inode
        try:
            same = os.stat(path).st_ino == os.fstat(fd).st_ino
        except FileNotFoundError:
            same = False
        if same:
            os.ftruncate(fd, 0)
            os.write(fd, f"{os.getpid()}\n".encode())
            return fd
        os.close(fd)


def clear(out: Path) -> None:
    """Remove everything in a claimed run directory but its lock (a resume that could not go
    on: dem.run.loop.run_case)."""
    _clear(Path(out))


def _clear(out: Path, keep: str = LOCK) -> None:
    for p in out.iterdir():
        if p.name == keep:
            continue
        if p.is_dir() and not p.is_symlink():
            shutil.rmtree(p)
        else:
            p.unlink()


def drop_analysis(out: Path) -> list[str]:
    """Remove what is not the run's own (RUN_FILES) from a run directory about to be resumed:
    an analysis of the killed run (``dem post``: analysis.json saying ``running``, PNGs ending
    at the kill time) would otherwise sit next to the finished run's summary.json and
    contradict it.  Returns the names removed."""
    removed = []
    for p in Path(out).iterdir():
        if p.name in RUN_FILES:
            continue
        if p.is_dir() and not p.is_symlink():
            shutil.rmtree(p)
        else:
            p.unlink()
        removed.append(p.name)
    return sorted(removed)


class RunDir:
    def __init__(self, out: Path, fd: int, created: bool):
        self.out = out
        self.fd = fd
        self.created = created

    def release(self) -> None:
        if self.fd is None:
            return
        with contextlib.suppress(OSError):
            (self.out / LOCK).unlink()
        os.close(self.fd)
        self.fd = None

    def abandon(self) -> None:
        """The run never started: remove what it wrote (and the directory if it made it)."""
        if self.fd is None:
            return
        with contextlib.suppress(OSError):
            _clear(self.out)
        self.release()
        if self.created:
            with contextlib.suppress(OSError):
                self.out.rmdir()


def claim(out: str | Path, case_json: str | None, force: bool = False,
          what: str = "--out", rerun_marker: str | None = None,
          resume: bool = False) -> RunDir:
    """Claim ``out`` for a run of the case whose validated JSON is ``case_json`` (module
    docstring).  ``rerun_marker``: for runs without a case.json (the two-body model), a file
    whose presence (with no case.json) marks a run of the same kind, replaced like a rerun.
    ``resume``: a run of the same case that left a restart point (dem.run.resume.RESTART_FILE)
    is kept, not cleared, for dem.run.run_case(resume=True) to go on from (or clear).
    Raises RunDirError (exit code 2)."""
    out = Path(out)
    if out.exists() and not out.is_dir():
        raise RunDirError(f"{what} {out}: exists and is not a directory")
    created = not out.exists()
    try:
        out.mkdir(parents=True, exist_ok=True)
        fd = _lock(out)
    except OSError as err:
        if err.errno in (errno.EACCES, errno.EPERM, errno.EROFS):
            raise RunDirError(f"{what} {out}: cannot write here ({err.strerror})") from None
        raise RunDirError(f"{what} {out}: {err.strerror or err}") from None
    rd = RunDir(out, fd, created)
    try:
        others = [p for p in out.iterdir() if p.name != LOCK]
        if not others:
            return rd
        old_case = out / "case.json"
        same = False
        if case_json is not None and old_case.is_file():
            with contextlib.suppress(OSError, ValueError):
                same = json.loads(old_case.read_text()) == json.loads(case_json)
        if rerun_marker is not None and (out / rerun_marker).is_file() \
                and not old_case.exists():
            same = True
        is_run = any((out / m).exists() for m in RUN_MARKERS if m != LOCK)
        if same and resume and (out / RESTART_FILE).is_file():
            drop_analysis(out)
            return rd
        if same or (force and is_run):
            _clear(out)
            return rd
        if not is_run:
            raise RunDirError(
                f"{what} {out}: the directory holds {len(others)} file(s) that are not a dem run "
                f"(e.g. {others[0].name}); choose an empty or new directory")
        name = None
        with contextlib.suppress(OSError, ValueError, AttributeError):
            name = json.loads(old_case.read_text()).get("name")
        kind = "a sweep" if (out / "sweep.json").exists() else \
            (f"a different run ('{name}')" if name else "a different run")
        raise RunDirError(f"{what} {out}: holds {kind}; use --force to clear it, or choose "
                          f"another directory")
    except BaseException:
        rd.release()
        raise
