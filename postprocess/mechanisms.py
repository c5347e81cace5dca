"""Collapse mechanisms of tilted walls, from the block motions (thesis Sections 3.4, 3.5).

Inputs are the initial and final poses of the blocks (table frame) and the mask of blocks that
moved (see :mod:`dem.collapse`).  Definitions follow the thesis' descriptions.

In plane (Fig 3.1, 3.12): each moving block either *slides* (translates; bricks dragged along may
tip backwards) or *overturns* (rotates about the axis normal to the wall with its top moving
leeward).  A block counts as overturning when its leeward rotation accounts for at least 30 % of
its displacement about a pivot at the table, theta z / |dx| >= 0.3 (theta signed, > 0 leeward).  Mechanism: "sliding" if overturning blocks are < 20 % of the moving
mass, "overturning" if > 80 %, "mixed" otherwise.  Main crack: in every course holding both
moving and resting bricks, the windward edge of the most windward moving brick; a least-squares
line through these points gives the crack angle, measured from the vertical (tan = horizontal
run / rise) like the stagger angle atan(s/h).

Out of plane (Fig 3.14): bricks turning with the facade's top course (about its overturning
axis) give, in each column of the facade, the lowest course that collapsed (the crack line);
side-wall ("wing") bricks that turn with it show which corners joined.  The shape of the crack
line decides first (depths per column, in courses from the top):
  horizontal  depths within one course of each other:
      A   no wing brick joined (or no wings);  B1  wings joined on one side;  B2  on both sides
  diagonal    the two ends differ by two courses or more: D (from one edge to the other)
  arch        both ends at least two courses shallower than the deepest column:
      G   arch three courses deep or more, wings joined on both sides;  B2 otherwise
"""

from __future__ import annotations

import numpy as np

from dem import quaternion


def _rotvecs(quat0, quat):
    """Rotation vectors (table frame, rad) taking the initial to the final orientations."""
    return (quaternion.rotation(quat) * quaternion.rotation(quat0).inv()).as_rotvec()


def in_plane_mechanism(scene, pos0, quat0, pos, quat, moving, load_dir, wall_normal,
                       stagger=None, course_height=None) -> dict:
    """Classify an in-plane collapse.

    load_dir     unit vector of the lateral load (towards the leeward side)
    wall_normal  unit vector normal to the wall plane, z x load_dir: a positive rotation about
                 it moves the top leeward (overturning)
    """
    moving = np.asarray(moving, dtype=bool)
    d = np.asarray(load_dir, float)
    nrm = np.asarray(wall_normal, float)
    disp = pos - pos0
    theta = _rotvecs(quat0, quat) @ nrm
    height = np.maximum(pos0[:, 2], 1e-9)
    dnorm = np.linalg.norm(disp, axis=1)
    with np.errstate(divide="ignore", invalid="ignore"):
        share = np.where(dnorm > 0, theta * height / dnorm, 0.0)
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


def out_of_plane_mechanism(scene, pos0, quat0, pos, quat, load_dir,
                           facade_group: str = "facade") -> dict:
    """Classify an out-of-plane collapse of a facade with wings from the brick rotations.

    Each brick's rotation about the facade's overturning axis (z x load direction; positive when
    its top moves with the load) is compared with the rotation of the facade's top course,
    theta_top (median).  A brick turns with the collapsing portion when its rotation is at least
    theta_top / 2.  Crack line: in each column of the facade, the lowest course from which every
    course up to the top turns with it.  Wing bricks that turn with it have joined.
    Best applied at incipient collapse (dem.runner uses the first frame with 10 mm of motion).
    """
    names = list(scene.group_names)
    gid = {n: i for i, n in enumerate(names)}
    fac = scene.group == gid.get(facade_group, -1)
    wings = {side: scene.group == gid[f"wing-{side}"] for side in ("left", "right")
             if f"wing-{side}" in gid}
    axis = np.cross([0.0, 0.0, 1.0], np.asarray(load_dir, float))
    axis /= np.linalg.norm(axis)
    theta = _rotvecs(quat0, quat) @ axis
    n_courses = int(scene.course[fac].max()) + 1 if fac.any() else 0
    top = fac & (scene.course == n_courses - 1)
    theta_top = float(np.median(theta[top])) if top.any() else 0.0
    turning = theta >= 0.5 * theta_top if theta_top > 0 else np.zeros(len(theta), bool)
    wing_joined = {side: int((mask & turning).sum()) for side, mask in wings.items()}
    # crack profile along the facade (columns one brick length wide)
    along = np.abs(axis)  # the facade runs along its overturning axis
    x = pos0[fac] @ along
    fac_idx = np.flatnonzero(fac)
    lo, hi = x.min(), x.max()
    n_bins = max(3, int(round((hi - lo) / np.median(np.abs(scene.size[fac] @ along)))) + 1)
    edges = np.linspace(lo - 1e-9, hi + 1e-9, n_bins + 1)
    depth = []
    for b in range(n_bins):
        inb = fac_idx[(x >= edges[b]) & (x < edges[b + 1])]
        lowest = n_courses  # lowest course of the turning portion in this column
        for c in range(n_courses - 1, -1, -1):
            row = inb[scene.course[inb] == c]
            if len(row) and turning[row].all():
                lowest = c
            elif len(row):
                break
        depth.append(n_courses - lowest)
    depth = np.array(depth)
    sides = [s for s, n in wing_joined.items() if n > 0]
    horizontal = depth.max() - depth.min() <= 1
    diagonal = not horizontal and abs(int(depth[0]) - int(depth[-1])) >= 2
    arch_depth = int(depth.max()) - max(int(depth[0]), int(depth[-1]))
    if theta_top <= 0 or depth.max() == 0:
        mech = "none"
    elif horizontal:
        mech = {0: "A", 1: "B1"}.get(len(sides), "B2")
    elif diagonal:
        mech = "D"
    else:
        mech = "G" if arch_depth >= 3 and len(sides) == 2 else "B2"
    return {
        "mechanism": mech,
        "collapsed_courses": int(depth.max()),
        "facade_courses": n_courses,
        "crack_depth_per_column": depth.tolist(),
        "crack_shape": "horizontal" if horizontal else ("diagonal" if diagonal else "arch"),
        "wing_bricks_joined": wing_joined,
        "facade_rotation_mrad": 1e3 * theta_top,
        "n_turning": int(turning.sum()),
        "turning_mass_fraction": float(scene.mass[turning].sum() / scene.mass.sum()),
    }
