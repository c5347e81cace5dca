"""As-built free play of builder walls: open head joints, loose corners, courses out of plumb
(docs/imperfections.md, "As built").  The random draws are made by :mod:`dem.imperfections`;
this module is the geometry, on one builder part (a Scene of axis-aligned boxes as a builder
laid them, possibly re-laid on scattered sizes by dem.builders.scatter), in the table frame.

* **Walls.**  The blocks of a group with course >= 0 form a wall; its axis (x or y) is the
  longer side of the group's plan footprint (a wall is longer than it is thick).
* **Head joints.**  Two blocks of one wall and course whose ends touch along the wall's axis
  (faces within 1 nm, overlapping across the wall and in height).  A gap g is opened by taking
  g / 2 off each of the two bricks at the joint: the joint's centre stays where the bond puts
  it, so joints never drift along a course and the stretcher bond (joints of successive courses
  half a brick apart) is kept exactly; the bricks are shorter than the pitch, as a mason's bricks
  are when the joints are left open.  Mass follows the volume.
* **Corner ends.**  An end of a block of one wall that faces a block of a wall along the other
  axis in the same course, within ``reach`` (the layout's own gap: the slivers a builder leaves
  out are shorter than ``min_piece``) and overlapping it across: the butting wall's end brick at
  an interlocked corner (or at an unbonded corner, every course).  A gap g is opened by taking
  g off that end: the brick stops g further short of the through wall's face than the layout
  left it.
* **Courses out of plumb.**  Every block of course k moves in plan by the course's offset
  (x, y in the builder's frame, turned by its ``yaw``); blocks of course -1 (a box model's roof)
  move with the top course.  Whole courses move, so the interlock of a box model's corners is
  kept (a course is laid with its corners).

Units: m, kg.
"""

from __future__ import annotations

import math

import numpy as np

from dem.scene import Scene

EPS = 1e-9  # m: faces closer than this touch


def wall_axes(scene: Scene) -> dict[int, int]:
    """{group index: axis along the wall (0 = x, 1 = y)} of the groups with bricks in courses."""
    lo = scene.position - 0.5 * scene.size
    hi = scene.position + 0.5 * scene.size
    out = {}
    for g in np.unique(scene.group[scene.course >= 0]):
        sel = (scene.group == g) & (scene.course >= 0)
        ext = hi[sel, :2].max(axis=0) - lo[sel, :2].min(axis=0)
        out[int(g)] = 0 if ext[0] >= ext[1] else 1
    return out


def _overlap(lo, hi, b, c, axes) -> bool:
    return all(min(hi[b, a], hi[c, a]) - max(lo[b, a], lo[c, a]) > EPS for a in axes)


def head_joints(scene: Scene) -> list[tuple[int, int, int]]:
    """The head joints (b, c, axis) inside the walls: b's end touches c's start along the wall's
    axis; in order of group, course and position along the wall."""
    lo = scene.position - 0.5 * scene.size
    hi = scene.position + 0.5 * scene.size
    out = []
    for g, ax in wall_axes(scene).items():
        across = 1 - ax
        for k in np.unique(scene.course[(scene.group == g) & (scene.course >= 0)]):
            idx = np.flatnonzero((scene.group == g) & (scene.course == k) & ~scene.fixed)
            idx = idx[np.argsort(lo[idx, ax], kind="stable")]
            for b in idx:
                for c in idx:
                    if c != b and abs(lo[c, ax] - hi[b, ax]) < EPS and \
                            _overlap(lo, hi, b, c, (across, 2)):
                        out.append((int(b), int(c), ax))
    return out


def corner_ends(scene: Scene, reach: float) -> list[tuple[int, int, int]]:
    """The butting ends (b, axis, side) at corners: side +1 for b's end at +axis, -1 at -axis;
    the end faces a block of a wall along the other axis, same course, within ``reach`` (m)
    and overlapping b across its wall and in height.  In block order."""
    lo = scene.position - 0.5 * scene.size
    hi = scene.position + 0.5 * scene.size
    axes = wall_axes(scene)
    out = []
    for b in range(scene.n_blocks):
        if scene.course[b] < 0 or scene.fixed[b]:
            continue
        ax = axes[int(scene.group[b])]
        across = 1 - ax
        others = np.flatnonzero((scene.course == scene.course[b]) & (scene.group != scene.group[b]))
        others = [c for c in others if axes.get(int(scene.group[c])) == across
                  and _overlap(lo, hi, b, c, (across, 2))]
        for side in (+1, -1):
            for c in others:
                d = lo[c, ax] - hi[b, ax] if side > 0 else lo[b, ax] - hi[c, ax]
                if -EPS <= d <= reach + EPS:
                    out.append((b, ax, side))
                    break
    return out


def cut_ends(scene: Scene, cuts: list[tuple[int, int, int, float]]) -> Scene:
    """A new scene with block b shortened by ``g`` (m) at its end ``side`` (+1: the +axis end)
    along ``axis``, for each (b, axis, side, g); mass follows the volume."""
    out = scene.copy()
    lo = out.position - 0.5 * out.size
    hi = out.position + 0.5 * out.size
    for b, ax, side, g in cuts:
        if side > 0:
            hi[b, ax] -= g
        else:
            lo[b, ax] += g
    cut = np.zeros(scene.n_blocks, dtype=bool)
    cut[[b for b, _, _, _ in cuts]] = True
    size = hi[cut] - lo[cut]
    if (size <= 0).any():
        raise ValueError("a gap took a whole brick away (gaps are limited to a fraction of the "
                         "brick length; this is a builder piece shorter than its gaps)")
    # only the cut blocks are written: the others keep their numbers to the last bit
    out.mass[cut] = scene.mass[cut] * np.prod(size / scene.size[cut], axis=1)
    out.size[cut] = size
    out.position[cut] = 0.5 * (lo[cut] + hi[cut])
    return out


def course_offsets(n_courses: int, sigma, lean_deg, course_height: float,
                   z: np.ndarray | None) -> np.ndarray:
    """[n_courses, 2] plan offsets (m, builder frame) of the courses: course 0 stays, course k
    is offset from k - 1 by sigma * z[k - 1] (z: [n_courses - 1, 2] truncated standard normals,
    None for no walk), plus k h tan(lean) (lean in degrees)."""
    k = np.arange(n_courses, dtype=np.float64)[:, None]
    out = k * course_height * np.tan(np.radians(np.asarray(lean_deg, dtype=np.float64)))[None, :]
    if z is not None and n_courses > 1:
        walk = np.zeros((n_courses, 2))
        walk[1:] = np.cumsum(np.asarray(sigma, dtype=np.float64)[None, :] * z, axis=0)
        out = out + walk
    return out


def shift_courses(scene: Scene, offsets: np.ndarray, yaw: int = 0) -> Scene:
    """A new scene with every block of course k >= 0 moved in plan by offsets[k] (builder frame,
    turned by ``yaw`` degrees into the table frame) and every block of course -1 by the top
    course's offset."""
    c, s = round(math.cos(math.radians(yaw)), 12), round(math.sin(math.radians(yaw)), 12)
    table = offsets @ np.array([[c, s], [-s, c]])  # rows: (c x - s y, s x + c y)
    out = scene.copy()
    k = np.where(scene.course >= 0, scene.course, len(offsets) - 1)
    out.position[:, :2] += np.where(scene.fixed[:, None], 0.0, table[k])
    return out
