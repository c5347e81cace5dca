"""Rigid-block DEM of dry masonry (box bricks, Coulomb friction) on a tilting or shaking table.

Layout (data flows one way):
    case YAML -> dem.case (validated Case) -> dem.scene (Scene arrays)
    -> dem.engine (Model / State / Contacts, stepping kernels) -> dem.runner (loop, recording)
    -> dem.output (summary.json, frames.npz, VTK) -> postprocess/ (analysis, figures)
"""

__version__ = "0.1.0"
