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
    arch      : "cpu" (default) or "cuda" (an engine of many scenes on a GPU; the
                engine then keeps its arrays on the device, dem.engine.device).  None: the
                ``DEM_ARCH`` environment variable, else cpu; a later call with None accepts
                the arch in use.  Taichi falls back to the CPU silently where CUDA is absent:
                that raises RuntimeError here.
    kernel_profiler : Taichi's per-task kernel timing (``ti.profiler``), for benchmarks
                (benchmarks/batch_speed.py --profile); off by default.
    """
    global _settings
    if threads is None:
        from dem.environment import MAX_THREADS, int_variable

        threads = int_variable("DEM_THREADS", 1, MAX_THREADS)  # a bad value: one clear line
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
    # their progress: it is kept out (the import banner is off too:
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
    error message eagerly, through textwrap: about a quarter of a process's start-up (building
    the 9 x 15 wall's Simulation took 5.9 -> 4.3 CPU-s, median of 5 fresh
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


def quick_front_end() -> bool:
    """Two of Taichi 1.7.4's Python front-end costs that repeat work whose answer cannot change
    within a process, replaced by equivalents that keep the answer (every process pays them, cached kernels
    or not):

    * ``kernel_impl._get_tree_and_ctx`` runs for the kernel and again at every call site of
      every ``ti.func`` it inlines (~500 for the stepping kernel): each time it re-reads the
      function's source through ``inspect.getsourcelines`` (which tokenizes the module's text
      to find the block), passes every line through ``textwrap.fill`` and dedents it.  Here
      that text is worked out once per function object and kept; each call still parses it into
      a fresh tree (the transformer writes into the tree's nodes) and builds its own context
      and globals, exactly as Taichi does.
    * ``kernel_impl._inside_class`` (each ``@ti.func`` / ``@ti.kernel`` decoration: is it
      inside a ``class`` body?) reads the decorating frame's line through
      ``inspect.getframeinfo``, whose ``inspect.getmodule`` scans every loaded module (twice
      for the import machinery's frozen frames): :func:`dem.ti_import.swap` reads the same
      line from ``linecache`` directly (the file, line and cache ``inspect`` would use); it is
      swapped in from Taichi's own import on where dem is imported first (dem.ti_import).

    It also applies :func:`quick_matrix_ops` (Taichi's vector helpers without the transform).
    The kernels' source text, hence their IR, the compiled code and the offline-cache keys, are
    those Taichi builds itself: results are the same bit for bit.  Called (idempotent) by each
    kernel module of dem.engine before its decorators run; ``DEM_TI_PLAIN_FRONT_END=1`` leaves
    Taichi as it is.  Returns False, changing nothing, where Taichi's internals are not as
    expected (another Taichi than 1.7.4)."""
    if os.environ.get("DEM_TI_PLAIN_FRONT_END"):
        return False
    try:
        from taichi.lang import kernel_impl
        from taichi.lang.ast.ast_transformer_utils import ASTTransformerContext
    except ImportError:
        return False
    if getattr(kernel_impl, "_dem_quick_front_end", False):
        return True
    needed = ("_get_tree_and_ctx", "_inside_class", "_get_global_vars", "getsourcefile",
              "getsourcelines", "_KERNEL_CLASS_STACKFRAME_STMT_RES")
    if ti.__version__ != (1, 7, 4) or not all(hasattr(kernel_impl, n) for n in needed):
        return False
    import ast
    import textwrap

    from dem import ti_import

    sources: dict = {}  # function object -> (file, lines, first line number, dedented text)

    def source_of(func):
        known = sources.get(func)
        if known is None:
            file = kernel_impl.getsourcefile(func)
            lines, start_lineno = kernel_impl.getsourcelines(func)
            lines = [textwrap.fill(line, tabsize=4, width=9999) for line in lines]
            known = (file, lines, start_lineno, textwrap.dedent("\n".join(lines)))
            sources[func] = known
        return known

    def get_tree_and_ctx(self, excluded_parameters=(), is_kernel=True, arg_features=None,
                         args=None, ast_builder=None, is_real_function=False):
        file, src, start_lineno, text = source_of(self.func)
        tree = ast.parse(text)
        tree.body[0].decorator_list = []
        global_vars = kernel_impl._get_global_vars(self.func)
        if is_kernel or is_real_function:  # template arguments are seen as globals
            for i in self.template_slot_locations:
                global_vars[self.arguments[i].name] = args[i]
        return tree, ASTTransformerContext(
            excluded_parameters=excluded_parameters, is_kernel=is_kernel, func=self,
            arg_features=arg_features, global_vars=global_vars, argument_data=args,
            src=src, start_lineno=start_lineno, file=file, ast_builder=ast_builder,
            is_real_function=is_real_function)

    quick_matrix_ops()
    # Taichi's own versions kept for tests/test_ti_front_end.py, which compares the two
    # (dem.ti_import swapped _inside_class already where dem was imported before Taichi)
    ti_import.swap(kernel_impl)
    kernel_impl._dem_taichi_originals = (
        kernel_impl._get_tree_and_ctx,
        getattr(kernel_impl, "_dem_taichi_inside_class", kernel_impl._inside_class))
    kernel_impl._get_tree_and_ctx = get_tree_and_ctx
    kernel_impl._dem_quick_front_end = True
    return True


def quick_matrix_ops() -> bool:
    """Taichi's vector and matrix helpers (``a.dot(b)``, ``a.cross(b)``, ``m @ v``,
    ``m.transpose()``, ``v.sum()``: ``taichi.lang.matrix_ops``) are Taichi functions written
    in Python that the front end transforms from their source at every call site, with their
    loops over the components unrolled statement by statement: ~300 call sites and a third of
    the front end of the stepping kernel, paid by every process.  Inside a kernel, the versions
    here make the same calls on Taichi's expression builder, in the same order, that the
    transform of Taichi's source makes (each argument copied into a local variable, each
    assignment initialised twice, as Taichi's ``build_FunctionDef`` / ``build_Assign`` do), so
    the kernel's IR, hence its offline-cache key and compiled code, are those of Taichi's own
    helpers; their argument checks run as before.  Outside kernels, and with keyword arguments,
    Taichi's own functions run.  Called by :func:`quick_front_end`; returns False, changing
    nothing, where Taichi's internals are not as expected."""
    import functools

    try:
        from taichi.lang import impl, matrix, matrix_ops
        from taichi.lang import ops as ti_ops
        from taichi.lang.exception import TaichiCompilationError
        from taichi.lang.matrix_ops_utils import do_check
    except ImportError:
        return False
    names = ("_reduce", "sum", "dot", "cross", "transpose", "_matmul_helper", "matmul",
             "_filled_vector", "_filled_matrix")
    if getattr(matrix_ops, "_dem_quick", False) or not all(
            callable(getattr(matrix_ops, n, None)) for n in names):
        return getattr(matrix_ops, "_dem_quick", False)

    def checks_of(fn):
        """The argument checks of Taichi's @preconditions wrapper (none for a bare pyfunc)."""
        code = getattr(fn, "__code__", None)
        if code is None or "checker_funcs" not in code.co_freevars:
            return ()
        return fn.__closure__[code.co_freevars.index("checker_funcs")].cell_contents

    def builder():
        return impl.get_runtime().current_kernel.ast_builder()

    def sub(value, *indices):  # value[indices], as build_Subscript makes it
        return impl.subscript(builder(), value, *indices)

    def copy(value):  # a non-template argument, passed by value (build_FunctionDef)
        return impl.expr_init_func(value)

    def assign_new(value):  # `name = value` for a new name (build_Assign + build_assign_basic)
        return impl.expr_init(impl.expr_init(value))

    def reduce_(mat, fun):
        mat = copy(mat)
        shape = mat.get_shape()
        if len(shape) == 1:
            result = assign_new(sub(mat, 0))
            for i in range(1, shape[0]):
                result._assign(impl.expr_init(fun(result, sub(mat, i))))
            return result
        result = assign_new(sub(mat, 0, 0))
        for i in range(shape[0]):
            for j in range(shape[1]):
                if i != 0 or j != 0:
                    result._assign(impl.expr_init(fun(result, sub(mat, i, j))))
        return result

    def sum_(mat):
        mat = copy(mat)
        return matrix_ops._reduce(mat, ti_ops.add)

    def dot_(vec_x, vec_y):
        vec_x, vec_y = copy(vec_x), copy(vec_y)
        return matrix_ops.sum(vec_x * vec_y)

    def cross_(vec_x, vec_y):
        vec_x, vec_y = copy(vec_x), copy(vec_y)
        shape = vec_x.get_shape()
        x, y = vec_x, vec_y
        if shape[0] == 2:
            return sub(x, 0) * sub(y, 1) - sub(x, 1) * sub(y, 0)
        if shape[0] == 3:
            return matrix.make_matrix([sub(x, 1) * sub(y, 2) - sub(x, 2) * sub(y, 1),
                                       sub(x, 2) * sub(y, 0) - sub(x, 0) * sub(y, 2),
                                       sub(x, 0) * sub(y, 1) - sub(x, 1) * sub(y, 0)])
        return None

    def transpose_(mat):
        mat = copy(mat)
        shape = mat.get_shape()
        return matrix.make_matrix([[sub(mat, i, j) for i in range(shape[0])]
                                   for j in range(shape[1])])

    def filled_vector_(n, dtype, val):  # template arguments: no copies
        return matrix.make_matrix([val for _ in range(n)], dtype)

    def filled_matrix_(n, m, dtype, val):
        return matrix.make_matrix([[val for _ in range(m)] for _ in range(n)], dtype)

    def matmul_helper_(mat_x, mat_y):
        mat_x, mat_y = copy(mat_x), copy(mat_y)
        shape_x, shape_y = mat_x.get_shape(), mat_y.get_shape()
        if len(shape_x) == 1 and len(shape_y) == 1:
            return matrix_ops.dot(mat_x, mat_y)
        if len(shape_y) == 1:
            zero_elem = assign_new(sub(mat_x, 0, 0) * sub(mat_y, 0) * 0)
            vec_z = assign_new(matrix_ops._filled_vector(shape_x[0], None, zero_elem))
            for i in range(shape_x[0]):
                for j in range(shape_x[1]):
                    value = impl.expr_init(sub(vec_z, i) + sub(mat_x, i, j) * sub(mat_y, j))
                    sub(vec_z, i)._assign(value)
            return vec_z
        zero_elem = assign_new(sub(mat_x, 0, 0) * sub(mat_y, 0, 0) * 0)
        mat_z = assign_new(matrix_ops._filled_matrix(shape_x[0], shape_y[1], None, zero_elem))
        for i in range(shape_x[0]):
            for j in range(shape_y[1]):
                for k in range(shape_x[1]):
                    value = impl.expr_init(sub(mat_z, i, j) + sub(mat_x, i, k) * sub(mat_y, k, j))
                    sub(mat_z, i, j)._assign(value)
        return mat_z

    def matmul_(mat_x, mat_y):
        mat_x, mat_y = copy(mat_x), copy(mat_y)
        shape_x, shape_y = mat_x.get_shape(), mat_y.get_shape()
        if len(shape_x) == 1 and len(shape_y) == 2:
            return matrix_ops._matmul_helper(matrix_ops.transpose(mat_y), mat_x)
        return matrix_ops._matmul_helper(mat_x, mat_y)

    def quick(name, ours):
        taichis = getattr(matrix_ops, name)
        checks = checks_of(taichis)

        def helper(*args, **kwargs):
            if kwargs or not impl.inside_kernel() or impl.get_runtime().current_kernel is None:
                return taichis(*args, **kwargs)
            if checks:
                ok, msg = do_check(checks, *args)
                if not ok:
                    raise TaichiCompilationError(msg)
            return ours(*args)

        # Taichi's marks (_is_taichi_function, func, module): its transformer treats the helper
        # as the Taichi function it replaces (no 'non-taichi function' warning)
        functools.update_wrapper(helper, taichis)
        helper.taichis = taichis
        setattr(matrix_ops, name, helper)

    for name, ours in (("_reduce", reduce_), ("sum", sum_), ("dot", dot_), ("cross", cross_),
                       ("transpose", transpose_), ("_filled_vector", filled_vector_),
                       ("_filled_matrix", filled_matrix_), ("_matmul_helper", matmul_helper_),
                       ("matmul", matmul_)):
        quick(name, ours)
    matrix_ops._dem_quick = True
    return True


def real_dtype():
    """numpy dtype of the engine's real arrays: float64, or float32 with precision "f32"."""
    import numpy as np

    return np.float32 if _settings is not None and _settings["precision"] == "f32" else np.float64


def settings() -> dict | None:
    """The settings of the current Taichi runtime, or None before :func:`init`."""
    return _settings
