"""dem.ti_runtime.short_source_positions: Taichi's front end records a statement's position as one
line (start-up cost, issue 36 defect 8), and a kernel's compile error still names the file, the
line and the function."""

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
