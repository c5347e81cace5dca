"""Fixtures shared by several test modules, and the kernels' warm-up before the workers start.

A fixture shared by several modules is imported here, never into each module that uses it:
pytest keeps one instance per place of definition, so a session fixture imported into N
modules is built N times (``view_runs``: ~17 s a build)."""

import os

import pytest

from tests.view_runs import view_runs  # noqa: F401 - the session fixture of tests/view_runs.py

# One Taichi thread in every process of the test session (unless DEM_THREADS is set): the
# thread count is part of a kernel's key in Taichi's offline cache, and dem.batch starts its
# dask workers with one thread each, so with the default (all cores) in the workers and the
# commands the tests start, the sweep and ensemble tests' dask workers compiled every kernel
# they ran again (~50 CPU-s a test).  Set here, before the warm-up and the xdist workers start,
# so that they and every subprocess inherit it.  The xdist workers keep the cores busy already.
# solver.mode "auto" takes the serial kernel on one thread; with more it took the parallel one
# only from 2 500 bodies (2-3 threads) or 500 (4 or more; dem.engine.simulation), more than the
# largest scenes the tests build (the box models, at most 349 bodies).
os.environ.setdefault("DEM_THREADS", "1")


@pytest.hookimpl(tryfirst=True)
def pytest_sessionstart(session):
    """In the xdist controller (``-n``), before the workers start (xdist starts them in its
    own, trylast, pytest_sessionstart): compile the engine's kernel
    variants once into Taichi's offline cache (tests/warm_kernels.py), one subprocess per core
    (each its share of the variants), instead of once in every worker.  Not in a worker, not
    without ``-n``, not with ``DEM_TEST_NO_WARMUP=1``; a no-op while the cache holds the
    current kernels."""
    config = session.config
    if hasattr(config, "workerinput") or os.environ.get("DEM_TEST_NO_WARMUP") == "1":
        return
    workers = getattr(config.option, "numprocesses", None)
    if not workers or getattr(config.option, "collectonly", False):
        return
    from tests import warm_kernels

    cores = len(os.sched_getaffinity(0)) if hasattr(os, "sched_getaffinity") else os.cpu_count()
    parts = max(1, min(int(cores or 1), len(warm_kernels.VARIANTS)))
    reporter = config.pluginmanager.get_plugin("terminalreporter")
    write = (lambda s: reporter.write(s, flush=True)) if reporter else (lambda s: None)
    if not warm_kernels.needed():
        return
    share = sum(warm_kernels.COMPILE_CPU_S) / parts
    write(f"compiling the engine's kernels once ({len(warm_kernels.VARIANTS)} variants, "
          f"{parts} processes of ~{share:.0f} CPU-s each on the 2-core test VM; "
          f"DEM_TEST_NO_WARMUP=1 skips this)... ")
    n, seconds, errors, cpu = warm_kernels.run_parts(parts)
    write(f"done in {seconds:.0f} s ({cpu:.0f} CPU-s)\n" if not errors else
          f"failed ({'; '.join(errors)}): the workers compile what they need\n")
