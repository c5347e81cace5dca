"""The wall geometry the mechanism analysis needs, for any scene: read from what a builder laid
(dem.scene.Scene.layout, Scene.course) or derived from the blocks themselves.

Derived from the blocks (a wall given as explicit blocks):

* courses: the blocks' bottoms (lowest corner, table frame) clustered by height: bottoms closer
  than ``COURSE_TOL`` x the smallest block height are one course; course 0 is the lowest;
* course height h: the median step between successive course bottoms (one course: the median
  block height);
* the wall's axis ``along``: the principal horizontal direction of the blocks' corners (the
  direction of largest extent of the footprint, taken along its edges, not its diagonal).  A
  footprint without a clear long direction (principal extents within ``ISOTROPIC`` of each
  other, e.g. a stack of square blocks) has no axis of its own: the load direction is used,
  and the load counts as in plane;
* head joints: in each course, the meeting points of blocks adjacent along the axis (gap below
  ``JOINT_TOL`` x h);
* stagger s: the median, over every head joint of a course, of its distance to the nearest head
  joint of the course below (for a stretcher bond of bond length L this is min(s, L - s), the
  overlap the bond guarantees); None where no two successive courses both hold head joints (a
  stack of single blocks).

Builder walls keep the builder's numbers (and its course indices), so their mechanism reads the
same as before this module existed; the derived values agree with them (tested).
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from dem.builders.checks import vertices

COURSE_TOL = 0.25   # bottoms closer than this fraction of the smallest block height: one course
JOINT_TOL = 0.1     # blocks closer than this fraction of the course height along the axis meet
ISOTROPIC = 1.25    # ratio of principal horizontal extents below which there is no wall axis
IN_PLANE_COS = 0.7  # the load is in plane within ~45 deg of the wall's axis (|cos| > 0.7)



@dataclass
class WallGeometry:
    """A wall's geometry (m).  ``members``: bool [N], the blocks of the wall; ``course``: int
    [N], course index of each member, -1 elsewhere."""

    source: str                 # "builder" (Scene.layout) or "blocks" (derived here)
    members: np.ndarray
    course: np.ndarray
    along: np.ndarray           # unit horizontal vector of the wall's axis
    course_height: float
    stagger: float | None
    length: float
    height: float
    has_axis: bool = True       # False: no long direction (the load direction was used)
    group: str | None = None    # builder group name

    @property
    def n_courses(self) -> int:
        return int(self.course.max()) + 1 if (self.course >= 0).any() else 0

    @property
    def l_over_h(self) -> float:
        return self.length / self.height

    @property
    def s_over_h(self) -> float | None:
        return None if self.stagger is None else self.stagger / self.course_height

    def in_plane(self, load_dir) -> bool:
        """Whether a load along ``load_dir`` acts in the wall's plane (within ~45 deg)."""
        return not self.has_axis or abs(np.asarray(load_dir, float) @ self.along) > IN_PLANE_COS

    def as_dict(self, load_dir=None) -> dict:
        out = {"source": self.source, "n_blocks": int(self.members.sum()),
               "n_courses": self.n_courses, "along": [float(v) for v in self.along],
               "has_axis": self.has_axis, "course_height_m": self.course_height,
               "stagger_m": self.stagger, "length_m": self.length, "height_m": self.height,
               "l_over_h": self.l_over_h, "s_over_h": self.s_over_h}
        if load_dir is not None:
            c = abs(float(np.asarray(load_dir, float) @ self.along))
            out["load_angle_to_axis_deg"] = float(np.degrees(np.arccos(min(c, 1.0))))
        return out


def cluster_levels(z, tol: float) -> tuple[np.ndarray, np.ndarray]:
    """(index of each value's level, mean of each level): values sorted and split where two
    successive ones differ by more than ``tol``."""
    z = np.asarray(z, float)
    order = np.argsort(z, kind="stable")
    idx = np.empty(len(z), int)
    level = 0
    for k, i in enumerate(order):
        if k and z[i] - z[order[k - 1]] > tol:
            level += 1
        idx[i] = level
    means = np.array([z[idx == c].mean() for c in range(level + 1)]) if len(z) else np.zeros(0)
    return idx, means


def horizontal_axis(corners) -> tuple[np.ndarray, float]:
    """(unit horizontal vector of the largest principal extent, ratio of the principal extents)
    of a cloud of corner points [M,3]."""
    xy = corners[:, :2] - corners[:, :2].mean(axis=0)
    w, v = np.linalg.eigh(xy.T @ xy / max(len(xy), 1))
    a = v[:, 1]
    ratio = float(np.sqrt(w[1] / w[0])) if w[0] > 0 else np.inf
    a = np.where(np.abs(a) < 1e-9, 0.0, a)
    if a[0] < 0 or (a[0] == 0 and a[1] < 0):  # a fixed sign: +x (or +y) side
        a = -a
    return np.array([a[0], a[1], 0.0]) / np.linalg.norm(a), ratio


def head_joints(lo, hi, tol: float) -> np.ndarray:
    """Positions (along the axis) where two blocks of one course meet: intervals [lo, hi] sorted
    by lo; successive ones whose gap is below ``tol`` meet at the middle of the gap."""
    order = np.argsort(lo)
    lo, hi = np.asarray(lo)[order], np.asarray(hi)[order]
    joints = [0.5 * (hi[k] + lo[k + 1]) for k in range(len(lo) - 1)
              if abs(lo[k + 1] - hi[k]) < tol]
    out: list[float] = []
    for j in joints:  # parallel wythes meeting at the same place: one joint
        if not out or j - out[-1] > tol:
            out.append(j)
    return np.array(out)


def stagger_from_joints(joints_per_course: list[np.ndarray]) -> float | None:
    """Median distance of every head joint to the nearest head joint of the course below."""
    d = []
    for lower, upper in zip(joints_per_course[:-1], joints_per_course[1:]):
        if len(lower) and len(upper):
            d.extend(np.abs(upper[:, None] - lower[None, :]).min(axis=1))
    return float(np.median(d)) if d else None


def derive_geometry(scene, members=None, load_dir=None) -> WallGeometry:
    """The geometry of the wall formed by ``members`` (bool [N]; default: every block that is not
    fixed), from the blocks' initial poses."""
    members = ~scene.fixed if members is None else np.asarray(members, bool)
    idx = np.flatnonzero(members)
    corners = vertices(scene)[idx]
    bottoms = corners[:, :, 2].min(axis=1)
    heights = corners[:, :, 2].max(axis=1) - bottoms
    course_m, levels = cluster_levels(bottoms, COURSE_TOL * heights.min())
    course = np.full(scene.n_blocks, -1, int)
    course[idx] = course_m
    h = float(np.median(np.diff(levels))) if len(levels) > 1 else float(np.median(heights))
    along, ratio = horizontal_axis(corners.reshape(-1, 3))
    has_axis = ratio >= ISOTROPIC
    if not has_axis and load_dir is not None:
        d = np.asarray(load_dir, float) * [1.0, 1.0, 0.0]
        along = d / np.linalg.norm(d)
    proj = corners @ along
    lo, hi = proj.min(axis=1), proj.max(axis=1)
    joints = [head_joints(lo[course_m == c], hi[course_m == c], JOINT_TOL * h)
              for c in range(len(levels))]
    z = corners[:, :, 2]
    return WallGeometry(source="blocks", members=members, course=course, along=along,
                        course_height=h, stagger=stagger_from_joints(joints),
                        length=float(proj.max() - proj.min()), height=float(z.max() - z.min()),
                        has_axis=bool(has_axis))


def builder_geometry(scene, group: str, layout: dict) -> WallGeometry:
    """The geometry a builder recorded for its wall ``group`` (Scene.layout)."""
    members = scene.group == list(scene.group_names).index(group)
    course = np.where(members, scene.course, -1)
    return WallGeometry(source="builder", members=members, course=course,
                        along=np.asarray(layout["along"], float),
                        course_height=float(layout["course_height"]),
                        stagger=float(layout["stagger"]), length=float(layout["length"]),
                        height=float(layout["height"]), group=group)
