"""Writers of the excited portion (postprocess.excited): ``excited.png``, the elevations of the
facade and its side walls with the bricks coloured by part, and ``excited.vtu``, one hexahedron
per block with the portion's cell data for ParaView.
"""

from __future__ import annotations

import numpy as np

from dem.output.atomic import atomic_path, savefig
from dem.output.plotting import agg_pyplot
from postprocess.excited import ExcitedPortion, aabb, group_mask

PART_COLOURS = {0: "#dddddd", 1: "#f4a259", 2: "#bc4b51"}


def plot_elevation(path, scene, portion: ExcitedPortion, title: str = "") -> None:
    """Elevations of the facade and its side walls, bricks coloured by part."""
    plt = agg_pyplot()
    from matplotlib.patches import Rectangle

    lo, hi = aabb(scene)
    if portion.facade is not None:
        panels = [(portion.side_walls[0], 1 if portion.facade in ("L1", "L2") else 0)] \
            if portion.side_walls else []
        fac_axis = 0 if portion.facade in ("L1", "L2") else 1
        panels += [(portion.facade, fac_axis)]
        panels += [(sw, 1 - fac_axis) for sw in portion.side_walls[1:]]
        masks = [(name, group_mask(scene, name), ax) for name, ax in panels]
    else:
        masks = [("blocks", ~scene.fixed, 0)]
    widths = [max(hi[m, ax].max() - lo[m, ax].min(), 0.05) if m.any() else 0.1
              for _, m, ax in masks]
    fig, axs = plt.subplots(1, len(masks), figsize=(12, 4), gridspec_kw={"width_ratios": widths},
                            squeeze=False)
    for axp, (name, m, ax) in zip(axs[0], masks):
        for i in np.flatnonzero(m):
            axp.add_patch(Rectangle((lo[i, ax], lo[i, 2]), hi[i, ax] - lo[i, ax],
                                    hi[i, 2] - lo[i, 2], edgecolor="k", lw=0.5,
                                    facecolor=PART_COLOURS[int(portion.part[i])]))
        if m.any():
            axp.set_xlim(lo[m, ax].min() - 0.01, hi[m, ax].max() + 0.01)
            axp.set_ylim(0, hi[m, 2].max() + 0.01)
        axp.set_aspect("equal")
        axp.set_title(f"{name} ({'xy'[ax]} along)", fontsize=9)
        axp.set_xlabel(f"{'xy'[ax]} (m)")
    axs[0, 0].set_ylabel("z (m)")
    s = portion.summary()
    fig.suptitle(f"{title}\nexcited {s['n_excited']} bricks: upper {s['n_upper']} (red), "
                 f"lower {s['n_lower']} (orange)", fontsize=10)
    fig.tight_layout()
    savefig(fig, path, dpi=110)
    plt.close(fig)


def write_vtu(path, scene, portion: ExcitedPortion) -> None:
    """excited.vtu: one hexahedron per block at its initial pose (dem.output.vtk.blocks_grid)
    with cell data excited_part (0 not excited / 1 lower / 2 upper), translation_amplitude (m),
    rotation_amplitude (rad) and their phases relative to the reference (deg)."""
    from dem.output.vtk import blocks_grid

    grid = blocks_grid(scene, scene.position, scene.quat)
    grid.cell_data["excited_part"] = portion.part.astype(np.int32)
    grid.cell_data["translation_amplitude"] = portion.trans_amp.astype(np.float32)
    grid.cell_data["translation_phase_deg"] = \
        np.nan_to_num(portion.trans_phase_deg).astype(np.float32)
    grid.cell_data["rotation_amplitude"] = portion.rot_amp.astype(np.float32)
    grid.cell_data["rotation_phase_deg"] = np.nan_to_num(portion.rot_phase_deg).astype(np.float32)
    with atomic_path(path) as tmp:
        grid.save(str(tmp), binary=True)
