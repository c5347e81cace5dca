"""Checks of a built scene before it is run: initial overlaps, floating blocks, a report.

All lengths in m, masses in kg.  The table is the plane z = 0.

* overlap: two blocks interpenetrate by more than ``overlap_tolerance`` (the penetration depth is
  the smallest overlap over the separating axes: exact for axis-aligned boxes, the 15 box-box
  axes otherwise), or a movable block reaches below the table;
* floating: a movable block that neither touches the table (lowest corner within
  ``contact_tolerance`` of z = 0) nor rests on another block or a fixed block (axis-aligned
  pairs: the bottom face lies on the other's top face with a plan overlap; other pairs: the two
  touch and the other block's centre is lower);
* warning (not an error): an axis-aligned block whose centre of mass lies outside the convex hull
  of its supports will tip as soon as the run starts.

Builders only produce boxes turned by multiples of 90 degrees, for which the axis-aligned test is
exact; explicit blocks may be turned arbitrarily (e.g. a block on an incline).
"""

from __future__ import annotations

from dataclasses import dataclass, field

import numpy as np
from scipy.spatial import ConvexHull, QhullError

from dem.scene import Scene

_UNIT = np.array([[sx, sy, sz] for sx in (-1, 1) for sy in (-1, 1) for sz in (-1, 1)], dtype=np.float64)


class SceneError(ValueError):
    """A scene that cannot be run (overlapping or floating blocks); the message names them."""


@dataclass
class SceneReport:
    """What ``dem check`` prints about a scene, and the problems found."""

    n_blocks: int
    n_fixed: int
    mass: float  # kg, movable blocks
    bbox_lo: np.ndarray  # m
    bbox_hi: np.ndarray  # m
    groups: dict[str, tuple[int, float]]  # name -> (blocks, kg)
    courses: dict[int, int]  # course index -> blocks (course >= 0 only)
    overlaps: list[str] = field(default_factory=list)
    floating: list[str] = field(default_factory=list)
    warnings: list[str] = field(default_factory=list)

    @property
    def ok(self) -> bool:
        return not self.overlaps and not self.floating

    def format(self) -> str:
        lo, hi = self.bbox_lo, self.bbox_hi
        ext = hi - lo
        lines = [
            f"{self.n_blocks} blocks ({self.n_fixed} fixed), {self.mass:.3f} kg movable",
            "bounding box [{:.4f}, {:.4f}, {:.4f}] .. [{:.4f}, {:.4f}, {:.4f}] m "
            "(extent {:.4f} x {:.4f} x {:.4f} m)".format(*lo, *hi, *ext),
            "groups: " + ", ".join(f"{g} {n} ({m:.3f} kg)" for g, (n, m) in self.groups.items()),
        ]
        if self.courses:
            counts = [self.courses[k] for k in sorted(self.courses)]
            lines.append(f"{len(counts)} courses, blocks per course: {counts}")
        lines += [f"overlap: {m}" for m in self.overlaps]
        lines += [f"floating: {m}" for m in self.floating]
        lines += [f"warning: {m}" for m in self.warnings]
        return "\n".join(lines)


def block_label(scene: Scene, i: int) -> str:
    """'block 17 (L1, course 3)': a block named the way a user finds it in the output."""
    name = scene.group_names[scene.group[i]]
    course = f", course {scene.course[i]}" if scene.course[i] >= 0 else ""
    return f"block {i} ({name}{course})"


def vertices(scene: Scene) -> np.ndarray:
    """Corners of every block [N, 8, 3], m."""
    r = scene.rotation_matrices()
    half = 0.5 * scene.size
    return scene.position[:, None, :] + np.einsum("nij,nkj->nki", r, _UNIT[None] * half[:, None, :])


def _axis_aligned(r: np.ndarray) -> np.ndarray:
    """True where the rotation is a signed permutation (a multiple of 90 degrees about axes)."""
    a = np.abs(r)
    return np.all((a < 1e-9) | (np.abs(a - 1.0) < 1e-9), axis=(1, 2))


def _sat_separation(c1, r1, h1, c2, r2, h2) -> float:
    """Largest separation over the 15 separating axes of two boxes (centre, rotation with the
    box axes as columns, half extents).  > 0: apart by at least that; < 0: penetration depth."""
    d = c2 - c1
    axes = [r1[:, i] for i in range(3)] + [r2[:, i] for i in range(3)]
    for i in range(3):
        for j in range(3):
            a = np.cross(r1[:, i], r2[:, j])
            n = np.linalg.norm(a)
            if n > 1e-9:
                axes.append(a / n)
    best = -np.inf
    for a in axes:
        ra = np.sum(h1 * np.abs(r1.T @ a))
        rb = np.sum(h2 * np.abs(r2.T @ a))
        best = max(best, abs(d @ a) - ra - rb)
    return float(best)


def candidate_pairs(lo: np.ndarray, hi: np.ndarray, pad: float) -> list[tuple[int, int]]:
    """Pairs whose bounding boxes come within ``pad`` of each other (sweep along x)."""
    order = np.argsort(lo[:, 0])
    pairs = []
    lo_s, hi_s = lo[order], hi[order]
    for a in range(len(order)):
        b = a + 1 + np.searchsorted(lo_s[a + 1 :, 0], hi_s[a, 0] + pad, side="right")
        if b <= a + 1:
            continue
        cand = np.arange(a + 1, b)
        ok = np.all(
            (lo_s[cand, 1:] <= hi_s[a, 1:] + pad) & (lo_s[a, 1:] <= hi_s[cand, 1:] + pad), axis=1
        )
        for c in cand[ok]:
            i, j = int(order[a]), int(order[c])
            pairs.append((min(i, j), max(i, j)))
    return pairs


def _plan_overlap(lo: np.ndarray, hi: np.ndarray, a: int, b: int) -> np.ndarray:
    """The overlap in plan of the bounding boxes of blocks a and b, [[xlo, ylo], [xhi, yhi]]."""
    return np.array([np.maximum(lo[a, :2], lo[b, :2]), np.minimum(hi[a, :2], hi[b, :2])])


def _rectangle_corners(rects: list[np.ndarray]) -> np.ndarray:
    """The four corners of each support rectangle [[xlo, ylo], [xhi, yhi]], as points [4k, 2]."""
    r = np.array(rects)  # [k, 2, 2]
    return np.concatenate([r[:, 0], r[:, 1], np.stack([r[:, 0, 0], r[:, 1, 1]], axis=1),
                           np.stack([r[:, 1, 0], r[:, 0, 1]], axis=1)])


def _inside_hull(p: np.ndarray, pts: np.ndarray, tol: float) -> bool:
    try:
        hull = ConvexHull(pts)
    except (QhullError, ValueError):
        # degenerate support (a line): inside only if p lies on the segment
        span = pts.max(axis=0) - pts.min(axis=0)
        axis = int(np.argmax(span))
        other = 1 - axis
        return bool(
            pts[:, axis].min() - tol <= p[axis] <= pts[:, axis].max() + tol
            and abs(p[other] - pts[0, other]) <= tol
        )
    return bool(np.all(hull.equations[:, :2] @ p + hull.equations[:, 2] <= tol))


def check_scene(
    scene: Scene,
    overlap_tolerance: float = 1e-4,
    contact_tolerance: float = 1e-5,
    allow_floating: bool = False,
    max_listed: int = 20,
    settle_gap: float = 0.0,
) -> SceneReport:
    """Check a scene for initial overlaps and floating blocks and summarise it (m, kg).

    ``settle_gap`` (m): blocks below within this gap of a block's bottom count as where it will
    land if it tips while the scene settles (size scatter: a brick laid on the higher of the two
    bricks it bridges rocks onto the lower one).  A block whose centre of mass is outside its
    support but inside that wider one is not warned about one by one: one line counts them."""
    n = scene.n_blocks
    verts = vertices(scene)
    lo, hi = verts.min(axis=1), verts.max(axis=1)
    rot = scene.rotation_matrices()
    aligned = _axis_aligned(rot)
    half = 0.5 * scene.size
    movable = ~scene.fixed

    overlaps: list[tuple[float, str]] = []
    supported = np.zeros(n, dtype=bool)
    supports: list[list[np.ndarray]] = [[] for _ in range(n)]  # support rectangles (aligned)

    on_table = lo[:, 2] <= contact_tolerance
    supported |= on_table | scene.fixed
    for i in np.flatnonzero(movable & (lo[:, 2] < -overlap_tolerance)):
        overlaps.append((-lo[i, 2], f"{block_label(scene, i)} reaches {-lo[i, 2] * 1e3:.3f} mm below the table"))
    for i in np.flatnonzero(on_table & aligned):
        supports[i].append(np.array([[lo[i, 0], lo[i, 1]], [hi[i, 0], hi[i, 1]]]))

    landing: list[list[np.ndarray]] = [[] for _ in range(n)]  # supports within settle_gap
    for i, j in candidate_pairs(lo, hi, max(contact_tolerance, settle_gap, 0.0)):
        if scene.fixed[i] and scene.fixed[j]:
            continue
        if aligned[i] and aligned[j]:
            gaps = np.maximum(lo[i], lo[j]) - np.minimum(hi[i], hi[j])  # > 0 apart, < 0 overlap
            sep = float(gaps.max())
        else:
            sep = _sat_separation(scene.position[i], rot[i], half[i], scene.position[j], rot[j], half[j])
            gaps = None
        if sep < -overlap_tolerance:
            overlaps.append(
                (-sep, f"{block_label(scene, i)} and {block_label(scene, j)} overlap by {-sep * 1e3:.3f} mm")
            )
            # in contact, if too deep: reported as an overlap, not also as floating (one
            # problem, one message)
            supported[i if scene.position[i, 2] > scene.position[j, 2] else j] = True
            continue
        if sep > contact_tolerance:
            if gaps is not None and sep <= settle_gap and gaps[0] < 0 and gaps[1] < 0:
                up, down = (i, j) if lo[i, 2] > lo[j, 2] else (j, i)
                landing[up].append(_plan_overlap(lo, hi, up, down))
            continue
        # the two touch: does one rest on the other?
        for up, down in ((i, j), (j, i)):
            if gaps is not None:
                # bottom on the other's top, or into it by up to the accepted overlap (a
                # 0.1 mm overlap would otherwise be reported as floating)
                rests = (
                    -(overlap_tolerance + contact_tolerance) <= lo[up, 2] - hi[down, 2]
                    <= contact_tolerance
                    and gaps[0] < -contact_tolerance
                    and gaps[1] < -contact_tolerance
                )
                if rests:
                    supports[up].append(_plan_overlap(lo, hi, up, down))
            else:
                rests = scene.position[down, 2] < scene.position[up, 2] or scene.fixed[down]
            if rests:
                supported[up] = True

    floating = [
        f"{block_label(scene, i)} at z = {lo[i, 2]:.4f} .. {hi[i, 2]:.4f} m rests on nothing"
        for i in np.flatnonzero(movable & ~supported)
    ]
    warnings = []
    n_land = 0
    for i in np.flatnonzero(movable & aligned & supported):
        if on_table[i] or not supports[i]:
            continue
        com = scene.position[i, :2]
        if not _inside_hull(com, _rectangle_corners(supports[i]), 1e-9):
            if landing[i] and _inside_hull(com, _rectangle_corners(supports[i] + landing[i]),
                                           1e-9):
                n_land += 1
            else:
                warnings.append(f"{block_label(scene, i)}: centre of mass outside its support, "
                                f"it will tip")
    if n_land:
        warnings.append(f"{n_land} blocks bridge supports of different heights: each rests on "
                        f"the higher and will rock onto the lower (at most "
                        f"{settle_gap * 1e3:.2f} mm below) while the scene settles")

    groups: dict[str, tuple[int, float]] = {}
    for g, name in enumerate(scene.group_names):
        sel = scene.group == g
        if sel.any():
            groups[name] = (int(sel.sum()), float(scene.mass[sel & movable].sum()))
    courses = {int(c): int((scene.course == c).sum()) for c in np.unique(scene.course) if c >= 0}
    overlaps.sort(key=lambda x: -x[0])
    over_msgs = [m for _, m in overlaps]
    if len(over_msgs) > max_listed:
        over_msgs = over_msgs[:max_listed] + [f"... and {len(overlaps) - max_listed} more"]
    if len(floating) > max_listed:
        floating = floating[:max_listed] + [f"... and {len(floating) - max_listed} more"]
    if allow_floating and floating:
        warnings = [f"floating (allowed): {m}" for m in floating] + warnings
        floating = []
    if len(warnings) > max_listed:
        warnings = warnings[:max_listed] + [f"... and {len(warnings) - max_listed} more"]
    return SceneReport(
        n_blocks=n,
        n_fixed=int(scene.fixed.sum()),
        mass=float(scene.mass[movable].sum()),
        bbox_lo=lo.min(axis=0),
        bbox_hi=hi.max(axis=0),
        groups=groups,
        courses=courses,
        overlaps=over_msgs,
        floating=floating,
        warnings=warnings,
    )


def require_valid(report: SceneReport) -> SceneReport:
    """Raise :class:`SceneError` naming the overlapping / floating blocks, else return the report."""
    if not report.ok:
        raise SceneError("\n".join([f"overlap: {m}" for m in report.overlaps] + [f"floating: {m}" for m in report.floating]))
    return report
