"""Facade with side walls (wings): the out-of-plane tilting-table specimens (Sections 3.3.3, 3.5).

Geometry (before ``yaw``/``origin``), stretcher bond, m:

* the facade runs along x in the band y in [-t/2, t/2] (outer face at y = -t/2); its through
  courses (even k) hold ``length`` whole bricks over x in [xa, xb] = [-n L / 2, n L / 2];
* a wing at the left (-x) end runs along +y from the facade's back face y = t/2 in the band
  x in [X0, X0 + t]; the right wing mirrors it;
* corner connection = lap c (0 < c <= t): in even courses the facade's end brick covers c of the
  wing's thickness (X0 = xa - t + c); in odd courses the wing's end brick reaches c into the
  facade's thickness (it starts at y = t/2 - c) and the facade starts beside it, at x = xa + c.
  c = t is the ordinary fully interlocked corner ('strong'); a smaller c leaves a notch on the
  outer corner and a smaller lap (bed-joint area c x c shared by the two walls per course).
  The thesis' staggers at the corner (poor / good / strong = 10 / 50 / 75 mm for large bricks,
  10 / 35 / 50 mm for small ones) are exactly 10 mm / one course height / one wall thickness for
  both brick sizes; they are read here as this lap.  (Assumption: the thesis defines the
  connections only by these numbers, Section 3.3.3.)
* connection 'unbonded' (a bound: no interlock): the facade runs through the corner in every
  course (flush, a half brick at its end in odd courses) and the wing butts against its back face
  in every course, in the band of a strong corner (x in [xa, xa + t] at the left); the wing's
  courses alternate the strong corner's even course with one starting with a (L - t) piece at
  the facade, so its joints stay half a brick from those of the course below.  No facade brick
  overlaps a wing brick in plan: a straight vertical joint;
* inside the walls, successive courses are offset by ``stagger`` (default half a brick); the
  pieces needed to fill up to a corner are cut, and cut pieces shorter than ``min_piece`` are left
  out (with a strong corner and s = L/2 that leaves a (L/2 - t) gap, 2.5 mm for small bricks).
"""

from __future__ import annotations

from dataclasses import dataclass

from dem.builders.bricks import Brick, brick as as_brick
from dem.builders.layout import BoxList, course_pieces
from dem.builders.wall import default_min_piece
from dem.scene import Scene

POOR_LAP = 0.010  # m, 'poor' corner of the thesis for both brick sizes


@dataclass(frozen=True)
class Wing:
    """A side wall: ``length`` whole bricks from the corner; ``connection`` a lap in m or
    'poor' / 'good' / 'strong'."""

    length: int
    connection: str | float = "strong"


def corner_lap(connection, b: Brick, laying: str) -> float:
    """The lap (m) of a named or numeric corner connection: poor 10 mm, good = course height,
    strong = wall thickness; 'unbonded' has the strong corner's plan (lap = wall thickness) but
    no course of the wing runs through (:func:`build_facade`)."""
    _, t, h = b.dims(laying)
    if isinstance(connection, str):
        try:
            lap = {"poor": POOR_LAP, "good": h, "strong": t, "unbonded": t}[connection]
        except KeyError:
            raise ValueError(f"connection must be poor, good, strong, unbonded or a lap in m, "
                             f"got {connection!r}") from None
    else:
        lap = float(connection)
    if not (0.0 < lap <= t + 1e-12):
        raise ValueError(f"a corner lap must be in (0, wall thickness = {t} m], got {lap}")
    return min(lap, t)


def _as_wing(w) -> Wing | None:
    if w is None or isinstance(w, Wing):
        return w
    if hasattr(w, "model_dump"):
        w = w.model_dump()
    return Wing(length=int(w["length"]), connection=w.get("connection", "strong"))


def build_facade(
    brick="small",
    length: int = 5,
    courses: int = 9,
    *,
    left=None,
    right=None,
    laying: str = "flat",
    stagger: float | None = None,
    flush_ends: bool = True,
    min_piece: float | None = None,
    origin=(0.0, 0.0, 0.0),
    yaw: int = 0,
) -> Scene:
    """A facade of ``length`` bricks and ``courses`` courses with optional wings (m, kg).

    ``left`` / ``right``: :class:`Wing` (or a mapping {length, connection}) or None for a free
    end.  Groups: 'facade', 'wing-left', 'wing-right'.  Without wings this is the single wall of
    :func:`dem.builders.wall.build_wall` (same layout).
    """
    b = as_brick(brick)
    unit, t, h = b.dims(laying)
    s = unit / 2.0 if stagger is None else float(stagger)
    if not (0.0 < s < unit):
        raise ValueError(f"stagger must be in (0, brick length = {unit} m), got {s}")
    mp = default_min_piece(b) if min_piece is None else float(min_piece)
    left, right = _as_wing(left), _as_wing(right)
    c_l = corner_lap(left.connection, b, laying) if left else None
    c_r = corner_lap(right.connection, b, laying) if right else None
    bonded_l = left is not None and left.connection != "unbonded"
    bonded_r = right is not None and right.connection != "unbonded"

    xa, xb = -length * unit / 2.0, length * unit / 2.0
    y_front, y_back = -t / 2.0, t / 2.0
    boxes = BoxList()
    for k in range(courses):
        z0, z1 = k * h, (k + 1) * h
        # facade
        if k % 2 == 0:
            a, e = xa, xb
            phase = xa
        else:
            phase = xa + s
            a = xa + c_l if bonded_l else (xa if flush_ends or left else xa + s)
            e = xb - c_r if bonded_r else (xb if flush_ends or right else xb + s)
        for p0, p1 in course_pieces(a, e, phase, unit, mp):
            boxes.add_piece((p0, y_front, z0), (p1, y_back, z1), b.density, "facade", k)
        # wings
        for wing, lap, name in ((left, c_l, "wing-left"), (right, c_r, "wing-right")):
            if wing is None:
                continue
            x0 = xa - t + lap if name == "wing-left" else xb - lap
            y_start = y_back - lap  # start of the wing's through course
            y_end = y_start + wing.length * unit
            if k % 2 == 1 and wing.connection == "unbonded":  # butting, offset by s
                a, e, phase = y_back, y_end, y_start
            elif k % 2 == 1:
                a, e, phase = y_start, y_end, y_start
            else:
                a, phase = y_back, y_start + s
                e = y_end if flush_ends else y_end + s
            for p0, p1 in course_pieces(a, e, phase, unit, mp):
                boxes.add_piece((x0, p0, z0), (x0 + t, p1, z1), b.density, name, k)
    return boxes.to_scene(origin=origin, yaw=yaw)
