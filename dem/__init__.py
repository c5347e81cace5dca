"""Rigid-block DEM of dry masonry (box bricks, Coulomb friction) on a tilting or shaking table.

Layers (each imports only those below it; docs/architecture.md):
    dem.scene (Scene arrays) <- dem.builders (walls, facades, box models) <- dem.case (schema)
    <- dem.engine (Model / State / Contacts, kernels; its own JointLaw / StepOptions)
    <- dem.run (the run loop: build, load, record, stop, write) -> dem.output (files)
Above it, and never imported by it: postprocess/ (analysis of the outputs), then dem_cli/ (the
``dem`` command line, which joins the two).
"""

import os as _os

__version__ = "0.1.0"

# Taichi prints a "[Taichi] version ..." banner on stdout when it is imported; stdout is for
# results (dem check / dem run print their result lines there), so it is off unless the user
# sets ENABLE_TAICHI_HEADER_PRINT=1 (the version is in `dem --version`).
_os.environ.setdefault("ENABLE_TAICHI_HEADER_PRINT", "0")

# Taichi's decorators read each decorating frame's source line through inspect.getframeinfo,
# about half of Taichi's import: dem.ti_import swaps in a line-cache reading (the same answer) as
# soon as Taichi starts importing, so that every process starts faster.  Imports nothing of Taichi.
from dem import ti_import as _ti_import  # noqa: E402

_ti_import.install()
