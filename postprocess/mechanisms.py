"""Collapse mechanisms of tilted walls, from the block motions (thesis Sections 3.4, 3.5).

Inputs are the initial and final poses of the blocks (table frame) and the mask of blocks that
moved (see :mod:`dem.collapse`).  Definitions follow the thesis' descriptions.

In plane (Fig 3.1, 3.12): each moving block either *slides* (translates, rotation ~ 0) or
*overturns* (rotates about the axis normal to the wall).  A block counts as overturning when its
rotation accounts for at least 30 % of its displacement about a pivot at the table,
|theta| z / |dx| >= 0.3.  Mechanism: "sliding" if overturning blocks are < 20 % of the moving
mass, "overturning" if > 80 %, "mixed" otherwise.  Main crack: in every course holding both
moving and resting bricks, the windward edge of the most windward moving brick; a least-squares
line through these points gives the crack angle, measured from the vertical (tan = horizontal
run / rise) like the stagger angle atan(s/h).

Out of plane (Fig 3.14): the facade's moving bricks give, in each column of the facade, the
lowest course that collapsed (the crack line); side-wall ("wing") bricks that moved show which
corners joined.
  A   no wing brick moves (or there are no wings); the crack line is horizontal
  B1  wing bricks move on one side only and the crack line is horizontal (within one course)
  D   wing bricks move on one side only and the crack line is diagonal (descends towards the
      better connected side by two courses or more)
  B2  wing bricks move on both sides
  G   B2 whose crack line is an arch: the middle of the facade collapses at least three courses
      deeper than both ends
"""

from __future__ import annotations

import numpy as np
from scipy.spatial.transform import Rotation


def _rotvecs(quat0, quat):
    """Rotation vectors (table frame, rad) taking the initial to the final orientations."""
    r0 = Rotation.from_quat(np.column_stack([quat0[:, 1:], quat0[:, :1]]))
    r1 = Rotation.from_quat(np.column_stack([quat[:, 1:], quat[:, :1]]))
    return (r1 * r0.inv()).as_rotvec()


def in_plane_mechanism(scene, pos0, quat0, pos, quat, moving, load_dir, wall_normal,
                       stagger=None, course_height=None) -> dict:
    """Classify an in-plane collapse.

    load_dir     unit vector of the lateral load (towards the leeward side)
    wall_normal  unit vector normal to the wall plane (the overturning axis)
    """
    moving = np.asarray(moving, dtype=bool)
    d = np.asarray(load_dir, float)
    nrm = np.asarray(wall_normal, float)
    disp = pos - pos0
    theta = _rotvecs(quat0, quat) @ nrm
    height = np.maximum(pos0[:, 2], 1e-9)
    dnorm = np.linalg.norm(disp, axis=1)
    with np.errstate(divide="ignore", invalid="ignore"):
        share = np.where(dnorm > 0, np.abs(theta) * height / dnorm, 0.0)
    over = moving & (share >= 0.3)
    m = scene.mass
    moving_mass = m[moving].sum()
    f_over = float(m[over].sum() / moving_mass) if moving_mass > 0 else 0.0
    if not moving.any():
        mech = "none"
    elif f_over < 0.2:
        mech = "sliding"
    elif f_over > 0.8:
        mech = "overturning"
    else:
        mech = "mixed"
    # main crack: windward edge of the most windward moving brick, per course
    along = pos0 @ d
    # half extent of each block along the load direction (body axes projected on d)
    body_d = np.einsum("nji,j->ni", scene.rotation_matrices(), d)
    half_along = 0.5 * (np.abs(body_d) * scene.size).sum(axis=1)
    pts = []
    for c in np.unique(scene.course[scene.course >= 0]):
        inc = scene.course == c
        if moving[inc].any() and (~moving[inc]).any():
            k = np.flatnonzero(inc & moving)
            edge = (along[k] - half_along[k]).min()
            pts.append((edge, pos0[inc, 2].mean()))
    crack = None
    if len(pts) >= 2:
        pts = np.array(pts)
        slope = np.polyfit(pts[:, 1], pts[:, 0], 1)[0]  # d(edge)/dz
        crack = {
            "angle_from_vertical_deg": float(np.degrees(np.arctan(abs(slope)))),
            "rises_towards_windward": bool(slope < 0),
            "points": pts.tolist(),
        }
        if stagger and course_height:
            crack["stagger_angle_deg"] = float(np.degrees(np.arctan(stagger / course_height)))
    # columns (brick lengths from the leeward end) holding overturning blocks
    cols = None
    if over.any():
        lee = (along + half_along).max()
        brick_len = float(np.median(2 * half_along[scene.course >= 0])) if (scene.course >= 0).any() \
            else float(np.median(2 * half_along))
        cols = int(np.unique(np.floor((lee - along[over]) / brick_len)).size)
    return {
        "mechanism": mech,
        "overturning_mass_fraction": f_over,
        "n_moving": int(moving.sum()),
        "moving_mass_fraction": float(moving_mass / m.sum()),
        "courses_involved": sorted({int(c) for c in scene.course[moving] if c >= 0}),
        "overturning_columns": cols,
        "crack": crack,
    }


def out_of_plane_mechanism(scene, pos0, moving) -> dict:
    """Classify an out-of-plane collapse of a facade (group "facade") with wings."""
    moving = np.asarray(moving, dtype=bool)
    names = list(scene.group_names)
    gid = {n: i for i, n in enumerate(names)}
    fac = scene.group == gid.get("facade", -1)
    wings = {side: scene.group == gid[f"wing-{side}"] for side in ("left", "right")
             if f"wing-{side}" in gid}
    n_courses = int(scene.course[fac].max()) + 1 if fac.any() else 0
    wing_moved = {side: int((mask & moving).sum()) for side, mask in wings.items()}
    # crack profile: lowest collapsed course in each column of the facade
    x = pos0[fac, 0]
    lo, hi = x.min(), x.max()
    n_bins = max(3, int(round((hi - lo) / np.median(scene.size[fac, 0]))) + 1)
    edges = np.linspace(lo - 1e-9, hi + 1e-9, n_bins + 1)
    fac_idx = np.flatnonzero(fac)
    profile = []
    for b in range(n_bins):
        inb = fac_idx[(x >= edges[b]) & (x < edges[b + 1])]
        mv = inb[moving[inb]]
        profile.append(int(scene.course[mv].min()) if len(mv) else n_courses)
    profile = np.array(profile)
    depth = n_courses - profile  # collapsed courses in each column (from the top)
    collapsed_courses = sorted({int(c) for c in scene.course[fac & moving]})
    sides = [s for s, n in wing_moved.items() if n > 0]
    horizontal = depth.max() - depth.min() <= 1
    ends = min(depth[0], depth[-1])
    arch = depth[1:-1].max(initial=0) - max(depth[0], depth[-1]) >= 3 if n_bins > 2 else False
    if not (fac & moving).any():
        mech = "none"
    elif not sides:
        mech = "A"
    elif len(sides) == 1:
        mech = "B1" if horizontal else "D"
    else:
        mech = "G" if arch else "B2"
    return {
        "mechanism": mech,
        "collapsed_courses": len(collapsed_courses),
        "facade_courses": n_courses,
        "crack_profile_lowest_course": profile.tolist(),
        "wing_bricks_moved": wing_moved,
        "n_moving": int(moving.sum()),
        "min_depth_at_ends": int(ends),
        "moving_mass_fraction": float(scene.mass[moving].sum() / scene.mass.sum()),
    }
