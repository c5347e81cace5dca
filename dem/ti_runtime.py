"""The one place where Taichi is initialised.

Every module that needs Taichi calls :func:`init` (idempotent) before allocating arrays or calling
kernels.  Defaults: CPU, ``default_fp=ti.f64``, offline cache on (Taichi's default), all cores.
The first call decides the settings for the whole process; a later call that asks for different
settings raises instead of silently keeping the old ones.
"""

from __future__ import annotations

import contextlib
import io
import os
import sys

import taichi as ti

from dem.signals import deferred

_settings: dict | None = None


ARCHS = ("cpu", "cuda")


def init(threads: int | None = None, precision: str = "f64", debug: bool = False,
         arch: str | None = None, kernel_profiler: bool = False) -> dict:
    """Initialise Taichi once per process.

    threads   : CPU threads for parallel loops (None: the ``DEM_THREADS`` environment variable,
                else all cores).
    precision : "f64" (default) or "f32", used as ``default_fp``.
    arch      : "cpu" (default) or "cuda" (issue 35: an engine of many scenes on a GPU; the
                engine then keeps its arrays on the device, dem.engine.device).  None: the
                ``DEM_ARCH`` environment variable, else cpu; a later call with None accepts
                the arch in use.  Taichi falls back to the CPU silently where CUDA is absent:
                that raises RuntimeError here.
    kernel_profiler : Taichi's per-task kernel timing (``ti.profiler``), for benchmarks
                (benchmarks/batch_speed.py --profile); off by default.
    """
    global _settings
    if threads is None and os.environ.get("DEM_THREADS"):
        threads = int(os.environ["DEM_THREADS"])
    if arch is None and _settings is None:
        arch = os.environ.get("DEM_ARCH") or "cpu"
    if arch is not None and arch not in ARCHS:
        raise ValueError(f"arch must be one of {', '.join(ARCHS)}, got {arch!r}")
    wanted = {"threads": threads, "precision": precision, "debug": debug, "arch": arch}
    if _settings is not None:
        for key, value in wanted.items():
            if key in ("threads", "arch") and value is None:
                continue
            if _settings[key] != value:
                raise RuntimeError(
                    f"Taichi is already initialised with {key}={_settings[key]!r}; "
                    f"cannot switch to {value!r} in the same process"
                )
        return _settings
    kwargs = dict(
        arch=ti.cuda if arch == "cuda" else ti.cpu,
        default_fp=ti.f64 if precision == "f64" else ti.f32,
        default_ip=ti.i32,
        debug=debug,
        log_level=ti.WARN,
    )
    if kernel_profiler:
        kwargs["kernel_profiler"] = True
    if threads is not None:
        kwargs["cpu_max_num_threads"] = int(threads)
    # ti.init prints "[Taichi] Starting on arch=x64" on stdout unconditionally; stdout is for
    # results, and the line repeated by every worker of a sweep or an ensemble only buried
    # their progress (issue 36 defect 7): it is kept out (the import banner is off too:
    # dem/__init__.py); anything else ti.init prints still goes to stderr
    banner = io.StringIO()
    with contextlib.redirect_stdout(banner), deferred():  # deferred: see dem.signals
        ti.init(**kwargs)
    rest = [ln for ln in banner.getvalue().splitlines()
            if ln.strip() and not ln.startswith("[Taichi] Starting on arch")]
    if rest:
        print("\n".join(rest), file=sys.stderr)
    if not debug and not os.environ.get("DEM_TI_SOURCE_CARETS"):
        short_source_positions()
    if arch == "cuda":
        from taichi.lang import impl

        if impl.current_cfg().arch != ti.cuda:
            raise RuntimeError("arch cuda: CUDA was asked for and is not available (Taichi "
                               "started on the CPU)")
    _settings = wanted
    return _settings


def short_source_positions() -> bool:
    """Make Taichi's front end record a kernel statement's source position as one line
    ('File "...", line N, in func') instead of that line re-drawn with a caret underline.

    Why: Taichi 1.7.4 re-runs its Python front end (the AST transform of every kernel and the
    functions it inlines) in each process even when the compiled kernel comes from the offline
    cache, and for every statement and expression it builds the position text of a possible
    error message eagerly, through textwrap: about a quarter of a process's start-up (issue 36
    defect 8: building the 9 x 15 wall's Simulation took 5.9 -> 4.3 CPU-s, median of 5 fresh
    processes on the 2-core test machine, benchmarks/startup_time.py and RESULTS.md).  The text only ever appears in compile-error messages
    (Taichi's DebugInfo); the compiled code and the offline-cache key do not depend on it, so
    results are the same bit for bit.  Errors still name the file, line and function.  Off with
    ``DEM_TI_SOURCE_CARETS=1`` or ``init(debug=True)`` (the full text, for kernel development).
    Returns False, changing nothing, where Taichi's internals are not as expected."""
    try:
        from taichi.lang.ast.ast_transformer_utils import ASTTransformerContext
    except ImportError:
        return False
    if not hasattr(ASTTransformerContext, "get_pos_info"):
        return False

    def get_pos_info(self, node):
        return (f'File "{self.file}", line {node.lineno + self.lineno_offset}, '
                f"in {self.func.func.__name__}:\n")

    ASTTransformerContext.get_pos_info = get_pos_info
    return True


def real_dtype():
    """numpy dtype of the engine's real arrays: float64, or float32 with precision "f32"."""
    import numpy as np

    return np.float32 if _settings is not None and _settings["precision"] == "f32" else np.float64


def settings() -> dict | None:
    """The settings of the current Taichi runtime, or None before :func:`init`."""
    return _settings
