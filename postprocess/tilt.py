"""Results of a tilting-table run: mechanism and limit analysis next to the simulated lambda.

Called by the run loop at the end of a tilt run (``dem.runner``) and usable on saved frames.
"""

from __future__ import annotations

import numpy as np

from postprocess.limit_analysis import in_plane_limit
from postprocess.mechanisms import in_plane_mechanism, out_of_plane_mechanism


def wall_geometry(case) -> dict | None:
    """Stagger s, course height h, length L and height H (m) of a case's built wall, or None."""
    spec = case.scene.wall
    if spec is None:
        return None
    from dem.builders.bricks import brick as as_brick

    b = as_brick(spec.brick)
    unit, _, h = b.dims(spec.laying)
    s = spec.stagger if spec.stagger is not None else unit / 2
    if spec.bond == "english":
        s = unit / 4  # quarter-brick lap of English bond
    return {"stagger": s, "course_height": h, "length": spec.length * unit,
            "height": spec.courses * h, "l_over_h": spec.length * unit / (spec.courses * h),
            "s_over_h": s / h}


def classify(case, scene, pos0, quat0, pos, quat, moved, load_dir) -> dict:
    """Mechanism (in plane or out of plane) and, for walls loaded in plane, eq 3-1..3-3."""
    moved_mask = np.zeros(scene.n_blocks, dtype=bool)
    moved_mask[np.asarray(moved, dtype=int)] = True
    names = list(scene.group_names)
    load_dir = np.asarray(load_dir, float)
    out: dict = {}
    if "facade" in names:
        out["kind"] = "out-of-plane"
        out.update(out_of_plane_mechanism(scene, pos0, moved_mask))
        return out
    geom = wall_geometry(case)
    if geom is None:
        out["kind"] = "blocks"
        out["n_moving"] = int(moved_mask.sum())
        return out
    in_plane = abs(load_dir[0]) > 0.7  # builder walls run along x
    if not in_plane:
        out["kind"] = "out-of-plane"
        scene_as_facade = _as_facade(scene)
        out.update(out_of_plane_mechanism(scene_as_facade, pos0, moved_mask))
        return out
    out["kind"] = "in-plane"
    normal = np.cross([0.0, 0.0, 1.0], load_dir)
    out.update(in_plane_mechanism(scene, pos0, quat0, pos, quat, moved_mask, load_dir, normal,
                                  geom["stagger"], geom["course_height"]))
    la = in_plane_limit(case.material.friction, geom["s_over_h"], geom["l_over_h"])
    out["limit_analysis"] = {**la.as_dict(), "s_over_h": geom["s_over_h"],
                             "l_over_h": geom["l_over_h"], "mu": case.material.friction}
    return out


def _as_facade(scene):
    """A lone wall tilted out of plane is a facade without wings."""
    from dataclasses import replace

    names = ["facade" if n == "wall" else n for n in scene.group_names]
    return replace(scene, group_names=names)
