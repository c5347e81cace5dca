"""SIGTERM and SIGHUP turned into the same clean stop as Ctrl-C (SIGINT).

``timeout``, batch schedulers (Slurm, PBS), ``docker stop`` and a closed terminal send SIGTERM or
SIGHUP, whose default action kills the process at once: no summary.json, frames since the last
checkpoint lost.  Inside :func:`stop_on_signals` each of SIGINT, SIGTERM and SIGHUP raises
:class:`Interrupted` (a KeyboardInterrupt, so every ``except KeyboardInterrupt`` of the run loop
handles it exactly as Ctrl-C), once: a second signal while the run writes its final files is
ignored, so the stop stays clean (SIGKILL still ends it).  Python runs the handler between
bytecodes of the main thread, i.e. after the kernel launch that is running returns (a few ms).
"""

from __future__ import annotations

import contextlib
import signal
import threading

STOP_SIGNALS = tuple(s for s in (signal.SIGINT, signal.SIGTERM, getattr(signal, "SIGHUP", None))
                     if s is not None)


class Interrupted(KeyboardInterrupt):
    """The run was stopped by a signal; ``signame`` is e.g. "SIGTERM"."""

    def __init__(self, signame: str = "SIGINT"):
        super().__init__(signame)
        self.signame = signame


def signal_name(err: BaseException) -> str:
    return getattr(err, "signame", "SIGINT")


@contextlib.contextmanager
def stop_on_signals():
    """Install the handlers (main thread only; elsewhere a no-op) and restore the old ones."""
    if threading.current_thread() is not threading.main_thread():
        yield
        return
    fired = []

    def handler(signum, frame):
        if fired:
            return  # already stopping: let the final writes finish
        fired.append(signum)
        raise Interrupted(signal.Signals(signum).name)

    old = {s: signal.signal(s, handler) for s in STOP_SIGNALS}
    try:
        yield
    finally:
        for s, h in old.items():
            signal.signal(s, h)
