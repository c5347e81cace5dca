"""Taichi's decorators made cheap from Taichi's own import on (every process pays them).

Every ``@ti.func`` / ``@ti.kernel`` / ``@pyfunc`` asks ``taichi.lang.kernel_impl._inside_class``
whether it decorates a method, which reads the decorating frame's source line through
``inspect.getframeinfo``; for the import machinery's frames that costs ``inspect.getmodule``
scans of every loaded module, ~1 ms a decoration.  Taichi decorates ~100 of its own helpers while
it is imported (about half of its import), the engine 63 more.  :func:`inside_class` reads the
same line through ``linecache`` (the file, line and cache ``inspect`` would use) and gives the
same answer.

:func:`install` (called by ``dem/__init__.py``, so before any dem module imports Taichi) puts a
finder on ``sys.meta_path`` that, when ``taichi.lang.kernel_impl`` is loaded, swaps in
:func:`inside_class` right after the module runs, before the rest of Taichi decorates anything,
and then takes itself off.  It imports nothing of Taichi; ``DEM_TI_PLAIN_FRONT_END=1`` leaves
Taichi as it is.  Where Taichi is already imported, or its ``_inside_class`` is not the one this
was written for (1.7.4), nothing changes (dem.ti_runtime.quick_front_end still swaps it for the
engine's own decorators).
"""

from __future__ import annotations

import importlib.abc
import itertools
import linecache
import os
import sys

MODULE = "taichi.lang.kernel_impl"


def inside_class_reader(class_line_patterns):
    """An ``_inside_class(level_of_class_stackframe)`` that tests the line of the frame that
    Taichi's tests (``level`` frames below it) against ``class_line_patterns``."""

    def _inside_class(level_of_class_stackframe):
        try:
            frame = sys._getframe(level_of_class_stackframe)
            code = frame.f_code
            lineno = None
            if frame.f_lasti >= 0:  # the line of the current instruction, as inspect takes it
                lineno = next(itertools.islice(code.co_positions(), frame.f_lasti // 2,
                                               None))[0]
            if lineno is None:
                lineno = frame.f_lineno
            file = code.co_filename
            if not (file.startswith("<") and file.endswith(">")):
                linecache.checkcache(file)
            lines = linecache.getlines(file, frame.f_globals)
            if not lines:
                return False
            first = lines[max(0, min(lineno - 1, len(lines) - 1))].strip()
            return any(pat.match(first) for pat in class_line_patterns)
        except Exception:
            return False

    return _inside_class


def swap(kernel_impl) -> bool:
    """Put the line-cache reader in place of Taichi's ``_inside_class`` (kept as
    ``_dem_taichi_inside_class``); False, changing nothing, where it is not Taichi's 1.7.4 one."""
    if getattr(kernel_impl, "_dem_taichi_inside_class", None) is not None:
        return True
    taichis = getattr(kernel_impl, "_inside_class", None)
    patterns = getattr(kernel_impl, "_KERNEL_CLASS_STACKFRAME_STMT_RES", None)
    code = getattr(taichis, "__code__", None)
    if (code is None or patterns is None or code.co_varnames[:1] != ("level_of_class_stackframe",)
            or "getframeinfo" not in code.co_names):
        return False
    kernel_impl._dem_taichi_inside_class = taichis
    kernel_impl._inside_class = inside_class_reader(patterns)
    return True


class _Finder(importlib.abc.MetaPathFinder):
    """Finds nothing itself: asks the other finders for taichi.lang.kernel_impl's spec and wraps
    its loader so that :func:`swap` runs right after the module's code."""

    def find_spec(self, fullname, path, target=None):
        if fullname != MODULE:
            return None
        uninstall()
        for finder in sys.meta_path:
            find = getattr(finder, "find_spec", None)
            spec = find(fullname, path, target) if find is not None else None
            if spec is not None:
                break
        else:
            return None
        loader = spec.loader
        run = getattr(loader, "exec_module", None)
        if run is None:
            return spec

        def exec_module(module):
            run(module)
            swap(module)

        loader.exec_module = exec_module
        return spec


_finder = _Finder()


def install() -> bool:
    """Watch for Taichi's import (see the module's docstring); False where Taichi is already
    imported or ``DEM_TI_PLAIN_FRONT_END`` is set."""
    if os.environ.get("DEM_TI_PLAIN_FRONT_END") or MODULE in sys.modules:
        return False
    if _finder not in sys.meta_path:
        sys.meta_path.insert(0, _finder)
    return True


def uninstall() -> None:
    if _finder in sys.meta_path:
        sys.meta_path.remove(_finder)
