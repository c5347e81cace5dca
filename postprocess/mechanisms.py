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
run / rise) like the stagger angle atan(s/h): CRACK_ANGLE_DEFINITION says why that is the
thesis' alpha_c; the angle from the bottom line is 90 deg minus it.

Collapsed portion (any scene): the blocks that moved with the mechanism, those whose
displacement or rotation is at least 30 % of the largest of any block (a sliding portion
translates, an overturning one turns by one angle whatever a block's distance from the pivot).

Out of plane (Fig 3.14): bricks turning with the facade's top course (about its overturning
axis) give, in each column of the facade, the lowest course that collapsed (the crack line);
side-wall ("wing") bricks that turn with it show which corners joined.  The shape of the crack
line decides first (depths per column, in courses from the top):
  horizontal  depths within one course of each other:
      A   no wing brick joined (or no wings);  B1  wings joined on one side;  B2  on both sides
  diagonal    the two ends differ by two courses or more and no column lies more than one
              course deeper than the deeper end: D (a crack from one edge down to the other)
  arch        otherwise (the deepest column inside the facade, both ends shallower):
      G   arch three courses deep or more, wings joined on both sides;  B2 otherwise
(:func:`crack_shape`.  The middle is looked at because a rule on the ends alone (two courses
apart: diagonal) reads an asymmetric arch, e.g. depths [2, 12, 14, 15, 15, 16, 16, 14,
12, 8] on an imperfect 10 x 21 facade, as D; no perfect wall of cases/tilt has such a profile.)
"""

from __future__ import annotations

import numpy as np

from dem import quaternion


CRACK_ANGLE_DEFINITION = (
    "alpha_c of the thesis (Section 3.4.2, eq 3-1..3-3): the angle of the main crack line with "
    "tan(alpha_c) = horizontal run / vertical rise, i.e. measured from the vertical, so that a "
    "stepped crack along the bond has tan(alpha_c) = s/h (56.3 deg at s/h = 1.5, the thesis' "
    "worked value).  The thesis' text calls it the angle between the main crack line and the "
    "bottom line of the wall; read literally (from the horizontal) that is 90 deg - alpha_c, "
    "given as crack_angle_from_bottom_line_deg.  Line: least squares through the windward edge "
    "of the most windward moving block of every course holding moving and resting blocks")

COLLAPSED_FRACTION = 0.3  # of the largest displacement / rotation: the block moved with the rest
COLLAPSED_FLOOR = 1e-3    # m (displacement, or rotation x half diagonal): below this, at rest


def collapsed_portion(scene, pos0, quat0, pos, quat, candidates=None) -> dict:
    """The blocks that moved with the mechanism between two poses: displacement at least
    COLLAPSED_FRACTION of the largest displacement, or rotation at least that fraction of the
    largest rotation (and above COLLAPSED_FLOOR either way), among ``candidates`` (bool [N],
    default every block that is not fixed).  Returns the block indices, their number and mass
    share (of the candidates' mass) and a bool mask."""
    cand = ~scene.fixed if candidates is None else np.asarray(candidates, bool)
    disp = np.linalg.norm(np.asarray(pos) - np.asarray(pos0), axis=1)
    rot = np.linalg.norm(_rotvecs(quat0, quat), axis=1)
    r = 0.5 * np.linalg.norm(scene.size, axis=1)
    d_max = disp[cand].max(initial=0.0)
    a_max = rot[cand].max(initial=0.0)
    by_disp = (disp >= COLLAPSED_FRACTION * d_max) & (disp >= COLLAPSED_FLOOR)
    by_rot = (rot >= COLLAPSED_FRACTION * a_max) & (rot * r >= COLLAPSED_FLOOR)
    mask = cand & (by_disp | by_rot)
    m_all = scene.mass[cand].sum()
    return {"blocks": np.flatnonzero(mask).tolist(), "n_blocks": int(mask.sum()),
            "n_candidates": int(cand.sum()),
            "mass_fraction": float(scene.mass[mask].sum() / m_all) if m_all > 0 else 0.0,
            "mask": mask}


def _rotvecs(quat0, quat):
    """Rotation vectors (table frame, rad) taking the initial to the final orientations."""
    return (quaternion.rotation(quat) * quaternion.rotation(quat0).inv()).as_rotvec()


def in_plane_mechanism(scene, pos0, quat0, pos, quat, moving, load_dir, wall_normal,
                       stagger=None, course_height=None, course=None) -> dict:
    """Classify an in-plane collapse.

    load_dir     unit vector of the lateral load (towards the leeward side)
    wall_normal  unit vector normal to the wall plane, z x load_dir: a positive rotation about
                 it moves the top leeward (overturning)
    course       course index of every block, -1 outside the wall (default scene.course, what a
                 builder laid; postprocess.wall_geometry derives it for explicit blocks)
    """
    course = scene.course if course is None else np.asarray(course, int)
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
    for c in np.unique(course[course >= 0]):
        inc = course == c
        if moving[inc].any() and (~moving[inc]).any():
            k = np.flatnonzero(inc & moving)
            edge = (along[k] - half_along[k]).min()
            pts.append((edge, pos0[inc, 2].mean()))
    crack = None
    if len(pts) >= 2:
        pts = np.array(pts)
        slope = np.polyfit(pts[:, 1], pts[:, 0], 1)[0]  # d(edge)/dz
        from_vertical = float(np.degrees(np.arctan(abs(slope))))
        crack = {
            "angle_from_vertical_deg": from_vertical,
            "angle_from_bottom_line_deg": 90.0 - from_vertical,
            "rises_towards_windward": bool(slope < 0),
            "points": pts.tolist(),
        }
        if stagger and course_height:
            crack["stagger_angle_deg"] = float(np.degrees(np.arctan(stagger / course_height)))
    # columns (brick lengths from the leeward end) holding overturning blocks
    cols = None
    if over.any():
        lee = (along + half_along).max()
        brick_len = float(np.median(2 * half_along[course >= 0])) if (course >= 0).any() \
            else float(np.median(2 * half_along))
        cols = int(np.unique(np.floor((lee - along[over]) / brick_len)).size)
    return {
        "mechanism": mech,
        "overturning_mass_fraction": f_over,
        "n_moving": int(moving.sum()),
        "moving_mass_fraction": float(moving_mass / m.sum()),
        "courses_involved": sorted({int(c) for c in course[moving] if c >= 0}),
        "overturning_columns": cols,
        "crack": crack,
    }


def crack_shape(depth) -> str:
    """The shape of an out-of-plane crack line from its depth per facade column (courses from
    the top, left to right): "horizontal" (depths within one course), "diagonal" (the ends
    differ by two courses or more and the deepest column is within one course of the deeper
    end: the line runs from one edge down to the other, mechanism D) or "arch" (any other
    profile: the deepest part inside the facade)."""
    d = np.asarray(depth, int)
    if d.max() - d.min() <= 1:
        return "horizontal"
    if abs(d[0] - d[-1]) >= 2 and d.max() - max(d[0], d[-1]) <= 1:
        return "diagonal"
    return "arch"


def out_of_plane_mechanism(scene, pos0, quat0, pos, quat, load_dir,
                           facade_group: str = "facade", course=None, facade=None) -> dict:
    """Classify an out-of-plane collapse of a facade with wings from the brick rotations.

    Each brick's rotation about the facade's overturning axis (z x load direction; positive when
    its top moves with the load) is compared with the rotation of the facade's top course,
    theta_top (median).  A brick turns with the collapsing portion when its rotation is at least
    theta_top / 2.  Crack line: in each column of the facade, the lowest course from which every
    course up to the top turns with it.  Wing bricks that turn with it have joined.
    Best applied at incipient collapse (postprocess.tilt uses the first frame with 10 mm of
    motion).  ``course``: course index of every block (default scene.course, what a builder
    laid); ``facade``: bool [N], the facade's blocks (default: the group ``facade_group``).
    """
    names = list(scene.group_names)
    gid = {n: i for i, n in enumerate(names)}
    course = scene.course if course is None else np.asarray(course, int)
    fac = scene.group == gid.get(facade_group, -1) if facade is None else np.asarray(facade, bool)
    wings = {side: scene.group == gid[f"wing-{side}"] for side in ("left", "right")
             if f"wing-{side}" in gid}
    axis = np.cross([0.0, 0.0, 1.0], np.asarray(load_dir, float))
    axis /= np.linalg.norm(axis)
    theta = _rotvecs(quat0, quat) @ axis
    n_courses = int(course[fac].max()) + 1 if fac.any() else 0
    top = fac & (course == n_courses - 1)
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
            row = inb[course[inb] == c]
            if len(row) and turning[row].all():
                lowest = c
            elif len(row):
                break
        depth.append(n_courses - lowest)
    depth = np.array(depth)
    sides = [s for s, n in wing_joined.items() if n > 0]
    shape = crack_shape(depth)
    arch_depth = int(depth.max()) - max(int(depth[0]), int(depth[-1]))
    if theta_top <= 0 or depth.max() == 0:
        mech = "none"
    elif shape == "horizontal":
        mech = {0: "A", 1: "B1"}.get(len(sides), "B2")
    elif shape == "diagonal":
        mech = "D"
    else:
        mech = "G" if arch_depth >= 3 and len(sides) == 2 else "B2"
    return {
        "mechanism": mech,
        "collapsed_courses": int(depth.max()),
        "facade_courses": n_courses,
        "crack_depth_per_column": depth.tolist(),
        "crack_shape": shape,
        "wing_bricks_joined": wing_joined,
        "facade_rotation_mrad": 1e3 * theta_top,
        "n_turning": int(turning.sum()),
        "turning_mass_fraction": float(scene.mass[turning].sum() / scene.mass.sum()),
    }
