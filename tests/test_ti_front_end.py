"""dem.ti_runtime.short_source_positions: Taichi's front end records a statement's position as one
line (it is paid at start-up by every process), and a kernel's compile error still names the
file, the line and the function."""

import inspect
import os

import pytest
import taichi as ti
from taichi.lang.ast.ast_transformer_utils import ASTTransformerContext

from dem import ti_runtime


def test_compile_error_names_file_line_and_function():
    ti_runtime.init()
    if "DEM_TI_SOURCE_CARETS" not in os.environ:
        assert ti_runtime.short_source_positions()
        assert ASTTransformerContext.get_pos_info.__module__ == "dem.ti_runtime"

    @ti.kernel
    def broken() -> ti.i32:
        return undefined_name_for_the_test  # noqa: F821

    with pytest.raises(Exception) as err:
        broken()
    text = str(err.value)
    assert f'File "{__file__}"' in text
    assert "in broken" in text
    assert "undefined_name_for_the_test" in text  # Taichi's own message follows the position
    # the reported line is the one of the bad statement
    src, first = inspect.getsourcelines(test_compile_error_names_file_line_and_function)
    bad = first + next(k for k, ln in enumerate(src) if "return undefined_name" in ln)
    assert f"line {bad}," in text


def test_quick_front_end_gives_taichi_answers():
    """ti_runtime.quick_front_end: the kept source text gives the tree and context Taichi's own
    _get_tree_and_ctx gives, and the line-cache reading of the decorating frame says 'inside a
    class' exactly where Taichi's does (a data-oriented class's kernel still works)."""
    import ast

    from taichi.lang import kernel_impl

    from dem.engine import geometry, step  # noqa: F401  (their kernels use the shortcut)

    if "DEM_TI_PLAIN_FRONT_END" in os.environ:
        pytest.skip("DEM_TI_PLAIN_FRONT_END set: Taichi's front end as it is")
    assert ti_runtime.quick_front_end()
    plain_tree_and_ctx, plain_inside_class = kernel_impl._dem_taichi_originals
    ti_runtime.init()
    funcs = [f.func for f in (geometry.box_contact, geometry.face_contact, step.probe_pair)]
    for fn in funcs + funcs:  # the second round reads the kept text
        ours, taichi_s = kernel_impl._get_tree_and_ctx(fn, is_kernel=False), \
            plain_tree_and_ctx(fn, is_kernel=False)
        assert ast.dump(ours[0]) == ast.dump(taichi_s[0])
        for attr in ("src", "file", "lineno_offset", "is_kernel", "excluded_parameters"):
            assert getattr(ours[1], attr) == getattr(taichi_s[1], attr), attr

    # level 1: this function's frame (its line is no class statement); level 2 from a class
    # body: the frame running the `class` statement (where a decorator's level points)
    assert (kernel_impl._inside_class(1), plain_inside_class(1)) == (False, False)

    class Probe:
        found = (kernel_impl._inside_class(2), plain_inside_class(2))

    assert Probe.found == (True, True)

    @ti.data_oriented
    class Doubler:
        def __init__(self):
            self.k = 2

        @ti.kernel
        def twice(self, x: ti.i32) -> ti.i32:
            return x * self.k

    assert Doubler().twice(21) == 42


KERNEL_OF_HELPERS = r'''
import json, sys
import numpy as np
from dem import ti_runtime  # before Taichi, as in a dem process (dem.ti_import)
import taichi as ti
from taichi.lang import kernel_impl
print(json.dumps({"quick": ti_runtime.quick_front_end(),
                  "reader": kernel_impl._inside_class.__module__}))
ti_runtime.init()

@ti.func
def helpers(a, b, m):
    n = m @ m.transpose()  # matmul (matrix @ matrix), transpose
    u = m @ a + a @ m      # matrix @ vector, vector @ matrix
    w = a.cross(b) + n @ u
    c2 = ti.math.vec2(a[0], b[1]).cross(ti.math.vec2(b[0], a[2]))  # 2-D cross: a scalar
    return a.dot(w) + w.sum() + m.sum() + w.norm() + w.norm_sqr() + c2

@ti.kernel
def run(x: ti.types.ndarray(dtype=ti.f64, ndim=1)) -> ti.f64:
    a = ti.math.vec3(x[0], x[1], x[2])
    b = ti.math.vec3(x[3], x[4], x[5])
    m = ti.math.mat3(x[0], x[1], x[2], x[3], x[4], x[5], x[6], x[7], x[8])
    return helpers(a, b, m)

x = np.linspace(-1.3, 2.1, 9)
print(json.dumps({"value": run(x).hex()}))
'''


def test_quick_matrix_ops_compile_the_same_kernel(tmp_path):
    """ti_runtime.quick_matrix_ops: a kernel using every replaced helper (dot, cross in 2-D and
    3-D, sum of a vector and of a matrix, transpose, matrix @ matrix, matrix @ vector,
    vector @ matrix, and norm / norm_sqr, Taichi's own helpers calling them) gets the same
    offline-cache key (a hash of its IR) with the quick front end as with Taichi's own, hence
    the same compiled code, and the same value bit for bit."""
    import json
    import subprocess
    import sys
    from pathlib import Path

    root = Path(__file__).resolve().parents[1]
    script = tmp_path / "helpers_kernel.py"  # Taichi reads a kernel's source from its file
    script.write_text(KERNEL_OF_HELPERS)
    out = {}
    for label, plain in (("taichi", "1"), ("quick", "")):
        cache = tmp_path / label
        env = dict(os.environ, TI_OFFLINE_CACHE_FILE_PATH=str(cache), PYTHONPATH=str(root))
        env.pop("DEM_TI_PLAIN_FRONT_END", None)
        if plain:
            env["DEM_TI_PLAIN_FRONT_END"] = plain
        res = subprocess.run([sys.executable, str(script)], env=env, cwd=root,
                             capture_output=True, text=True, timeout=600)
        assert res.returncode == 0, res.stderr
        assert "non-taichi function" not in res.stderr
        lines = [json.loads(ln) for ln in res.stdout.splitlines() if ln.startswith("{")]
        keys = sorted(p.name for p in cache.rglob("*.tic"))
        out[label] = (lines[0]["quick"], lines[1]["value"], keys, lines[0]["reader"])
    assert out["taichi"][0] is False and out["quick"][0] is True
    # from Taichi's own import on, its decorators used dem.ti_import's reader (Taichi's not)
    assert out["taichi"][3] == "taichi.lang.kernel_impl" and out["quick"][3] == "dem.ti_import"
    assert out["quick"][1] == out["taichi"][1]
    assert out["quick"][2] == out["taichi"][2] and len(out["quick"][2]) == 1
