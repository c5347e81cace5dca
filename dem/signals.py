"""SIGTERM and SIGHUP turned into the same clean stop as Ctrl-C (SIGINT).

``timeout``, batch schedulers (Slurm, PBS), ``docker stop`` and a closed terminal send SIGTERM or
SIGHUP, whose default action kills the process at once: no summary.json, frames since the last
checkpoint lost.  Inside :func:`stop_on_signals` each of SIGINT, SIGTERM and SIGHUP raises
:class:`Interrupted` (a KeyboardInterrupt, so every ``except KeyboardInterrupt`` of the run loop
handles it exactly as Ctrl-C), once: a second signal while the run writes its final files is
ignored, so the stop stays clean (SIGKILL still ends it).  Python runs the handler between
bytecodes of the main thread, i.e. after the kernel launch that is running returns (a few ms).

Two places where the raised :class:`Interrupted` would be lost, and what covers them:

* Taichi's import and its ``@ti.func`` / ``@ti.kernel`` decorators call code with bare
  ``except:`` clauses (``taichi.lang.kernel_impl._inside_class``, ``_wrap_inspect``), which
  swallow the exception: a SIGTERM there was lost and the run went on to its end; one that fired
  while the C extension initialised became ``ImportError: initialization failed``.  The import
  of the engine and ``ti.init`` run inside :func:`deferred` (a signal is recorded there and
  raised when the block exits).
* Kernel compilation (first launch) runs Taichi's AST transformer, which has bare ``except:``
  clauses too: the run loop calls :func:`raise_if_stopped` between launches, which raises
  :class:`Interrupted` again for a signal that was received but swallowed.
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


# the stop signals received inside stop_on_signals (its one writer is the handler)
_received: list[int] = []
_holding = False  # inside deferred(): the handler records the signal and does not raise
_held = False  # a signal arrived inside deferred() and is raised when the block exits


@contextlib.contextmanager
def stop_on_signals():
    """Install the handlers (main thread only; elsewhere a no-op) and restore the old ones."""
    global _held
    if threading.current_thread() is not threading.main_thread():
        yield
        return

    def handler(signum, frame):
        global _held
        if _received:
            return  # already stopping: let the final writes finish
        _received.append(signum)
        if _holding:
            _held = True
        else:
            raise Interrupted(signal.Signals(signum).name)

    _received.clear()
    old = {s: signal.signal(s, handler) for s in STOP_SIGNALS}
    try:
        yield
    finally:
        for s, h in old.items():
            signal.signal(s, h)
        _received.clear()
        _held = False


def raise_if_stopped() -> None:
    """Raise :class:`Interrupted` if a stop signal was received inside :func:`stop_on_signals`.

    The handler raises once; a caller that goes on normally after it must have had the exception
    swallowed by someone else's bare ``except:`` (Taichi's compiler), so the stop is raised
    again here.  Called by the run loop between kernel launches; a no-op when no signal came."""
    if _received:
        raise Interrupted(signal.Signals(_received[0]).name)


@contextlib.contextmanager
def deferred():
    """Hold the stop signals while the block runs: one that arrives is recorded, and
    :class:`Interrupted` is raised when the block exits, not inside it.  For code that must not be
    interrupted half way: importing Taichi and defining the kernels, ``ti.init``, recording one
    frame (dem.run.record: a frame cut between its time and its positions left frames.npz with
    one more time than positions).  A signal that came before the block (the stop already under
    way, e.g. the last frame written after Ctrl-C) is not raised again at its exit.  (Blocking the
    signals with ``pthread_sigmask`` would not do: a process-directed signal goes to any thread
    that does not block it, e.g. a BLAS thread, and Python still runs the handler in the main
    thread.)  Nested blocks hold until the outermost exits.  A no-op outside the main thread."""
    global _holding, _held
    if threading.current_thread() is not threading.main_thread():
        yield
        return
    outer = not _holding
    _holding = True
    try:
        yield
    finally:
        if outer:
            _holding = False
    if outer and _held:
        _held = False
        raise_if_stopped()
