"""Geometry helpers shared by the builders: cutting a course into pieces, collecting boxes.

Builders lay axis-aligned boxes only (bricks turned by multiples of 90 degrees give axis-aligned
boxes too), so each block is stored as its table-frame extents [lo, hi] with an identity
orientation; the Scene's ``size`` is then hi - lo.
"""

from __future__ import annotations

import math

import numpy as np

from dem.scene import Scene

_EPS = 1e-9  # m: a joint closer than this to a course end is no joint


def course_pieces(a: float, b: float, phase: float, unit: float, min_piece: float) -> list[tuple[float, float]]:
    """Cut the course interval [a, b] at the joints ``phase + k * unit`` (all integers k).

    Returns the pieces (x0, x1) in order; pieces shorter than ``min_piece`` are left out (they
    would be slivers; the gap stays).  Lengths in m.
    """
    if b - a <= _EPS:
        return []
    k0 = math.floor((a - phase) / unit) + 1
    cuts = [a]
    k = k0
    while True:
        x = phase + k * unit
        if x >= b - _EPS:
            break
        if x > a + _EPS:
            cuts.append(x)
        k += 1
    cuts.append(b)
    return [(x0, x1) for x0, x1 in zip(cuts[:-1], cuts[1:]) if x1 - x0 >= min_piece - _EPS]


class BoxList:
    """Accumulates axis-aligned boxes (table-frame extents, mass, group, course)."""

    def __init__(self) -> None:
        self.lo: list[tuple[float, float, float]] = []
        self.hi: list[tuple[float, float, float]] = []
        self.mass: list[float] = []
        self.group: list[str] = []
        self.course: list[int] = []

    def add(self, lo, hi, mass: float, group: str, course: int = -1) -> None:
        lo = tuple(float(v) for v in lo)
        hi = tuple(float(v) for v in hi)
        if any(h - l <= 0 for l, h in zip(lo, hi)):
            raise ValueError(f"degenerate box {lo} .. {hi}")
        self.lo.append(lo)
        self.hi.append(hi)
        self.mass.append(float(mass))
        self.group.append(group)
        self.course.append(int(course))

    def add_piece(self, lo, hi, brick_density: float, group: str, course: int) -> None:
        """A (possibly cut) brick: its mass is density x volume."""
        vol = float(np.prod(np.subtract(hi, lo)))
        self.add(lo, hi, brick_density * vol, group, course)

    def __len__(self) -> int:
        return len(self.mass)

    def to_scene(self, origin=(0.0, 0.0, 0.0), yaw: int = 0) -> Scene:
        """Scene of the boxes, turned by ``yaw`` degrees (multiple of 90) about z, then moved by
        ``origin``."""
        if len(self) == 0:
            raise ValueError("the builder produced no blocks")
        lo = np.array(self.lo, dtype=np.float64)
        hi = np.array(self.hi, dtype=np.float64)
        lo, hi = _yaw_boxes(lo, hi, yaw)
        lo += np.asarray(origin, dtype=np.float64)
        hi += np.asarray(origin, dtype=np.float64)
        names: list[str] = []
        for g in self.group:
            if g not in names:
                names.append(g)
        n = len(self)
        quat = np.zeros((n, 4))
        quat[:, 0] = 1.0
        return Scene(
            size=hi - lo,
            position=0.5 * (lo + hi),
            quat=quat,
            mass=np.array(self.mass),
            fixed=np.zeros(n, dtype=bool),
            velocity=np.zeros((n, 3)),
            angular_velocity=np.zeros((n, 3)),
            group=np.array([names.index(g) for g in self.group], dtype=np.int32),
            course=np.array(self.course, dtype=np.int32),
            group_names=names,
        )


def _yaw_boxes(lo: np.ndarray, hi: np.ndarray, yaw: int) -> tuple[np.ndarray, np.ndarray]:
    """Turn axis-aligned boxes about the z axis through the origin by 0/90/180/270 degrees."""
    yaw = int(yaw) % 360
    if yaw not in (0, 90, 180, 270):
        raise ValueError(f"yaw must be a multiple of 90 degrees, got {yaw}")
    if yaw == 0:
        return lo.copy(), hi.copy()
    c, s = {90: (0, 1), 180: (-1, 0), 270: (0, -1)}[yaw]
    rot = np.array([[c, -s, 0], [s, c, 0], [0, 0, 1]], dtype=np.float64)
    a, b = lo @ rot.T, hi @ rot.T
    return np.minimum(a, b), np.maximum(a, b)
