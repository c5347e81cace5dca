"""Rigid-block DEM of dry masonry (box bricks, Coulomb friction) on a tilting or shaking table.

Layout (data flows one way):
    case YAML -> dem.case (validated Case) -> dem.scene (Scene arrays)
    -> dem.engine (Model / State / Contacts, stepping kernels) -> dem.runner (loop, recording)
    -> dem.output (summary.json, frames.npz, VTK) -> postprocess/ (analysis, figures)
"""

import os as _os

__version__ = "0.1.0"

# Taichi prints a "[Taichi] version ..." banner on stdout when it is imported; stdout is for
# results (dem check / dem run print their result lines there), so it is off unless the user
# sets ENABLE_TAICHI_HEADER_PRINT=1 (the version is in `dem --version`).
_os.environ.setdefault("ENABLE_TAICHI_HEADER_PRINT", "0")
