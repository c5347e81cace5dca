"""Single straight walls: stretcher bond or English bond, bricks flat or on edge.

Geometry (before ``yaw``/``origin``): the wall runs along +x and is centred on x = 0 (its full
courses span [-n L / 2, n L / 2]), its thickness is centred on y = 0, course k spans
z in [k h, (k + 1) h].  Units: m, kg.
"""

from __future__ import annotations

import math

from dem.builders.bricks import Brick, brick as as_brick
from dem.builders.layout import BoxList, course_pieces
from dem.scene import Scene

MIN_PIECE_FRACTION = 0.15  # default min_piece = 0.15 x brick length


def default_min_piece(b: Brick) -> float:
    return MIN_PIECE_FRACTION * b.length


def stretcher_courses(
    boxes: BoxList,
    b: Brick,
    *,
    x0: float,
    n_bricks: int,
    courses: int,
    stagger: float,
    flush_ends: bool,
    laying: str,
    min_piece: float,
    y0: float,
    group: str,
) -> None:
    """Lay a stretcher-bond wall along +x from x0, thickness band [y0, y0 + t]."""
    unit, t, h = b.dims(laying)
    for k in range(courses):
        z = (k * h, (k + 1) * h)
        if k % 2 == 0:
            a, e, phase = x0, x0 + n_bricks * unit, x0
        elif flush_ends:
            a, e, phase = x0, x0 + n_bricks * unit, x0 + stagger
        else:
            a, e, phase = x0 + stagger, x0 + stagger + n_bricks * unit, x0 + stagger
        for p0, p1 in course_pieces(a, e, phase, unit, min_piece):
            boxes.add_piece((p0, y0, z[0]), (p1, y0 + t, z[1]), b.density, group, k)


def english_courses(
    boxes: BoxList, b: Brick, *, x0: float, n_bricks: int, courses: int, laying: str, group: str
) -> None:
    """Lay an English-bond wall (one brick length thick) along +x from x0, centred on y = 0.

    Even courses: two rows of n stretchers (front and back).  Odd courses: slots of width L/2
    along the wall, [header, queen closer (L/4 slot), 2n - 3 headers, queen closer, header];
    the joints of successive courses are offset by a quarter brick.  Each header (width W flat or
    H on edge along the wall) is centred in its L/2 slot, so with real bricks (L > 2W) a small
    gap remains between headers (1 mm large bricks, 2.5 mm small bricks) and between the two
    stretcher rows (L - 2 x thickness of a row).  Queen closers are bricks halved lengthwise.
    """
    unit, t_row, h = b.dims(laying)
    thick = b.length
    w_head = t_row  # a header shows its width (flat) or height (on edge) along the wall
    slot = unit / 2.0
    for k in range(courses):
        z = (k * h, (k + 1) * h)
        if k % 2 == 0:
            for y0 in (-thick / 2.0, thick / 2.0 - t_row):
                for i in range(n_bricks):
                    boxes.add_piece(
                        (x0 + i * unit, y0, z[0]), (x0 + (i + 1) * unit, y0 + t_row, z[1]), b.density, group, k
                    )
            continue
        slots = [(slot, w_head)] + [(slot / 2.0, w_head / 2.0)]
        slots += [(slot, w_head)] * (2 * n_bricks - 3)
        slots += [(slot / 2.0, w_head / 2.0), (slot, w_head)]
        x = x0
        for width, w in slots:
            c = x + width / 2.0
            boxes.add_piece((c - w / 2.0, -thick / 2.0, z[0]), (c + w / 2.0, thick / 2.0, z[1]), b.density, group, k)
            x += width


def build_wall(
    brick="small",
    length: int = 5,
    courses: int = 5,
    *,
    bond: str = "stretcher",
    laying: str = "flat",
    stagger: float | None = None,
    flush_ends: bool = True,
    min_piece: float | None = None,
    origin=(0.0, 0.0, 0.0),
    yaw: int = 0,
    group: str = "wall",
) -> Scene:
    """A straight wall of ``length`` bricks and ``courses`` courses (m, kg).

    Stretcher bond: odd courses are offset by ``stagger`` (default half a brick length).  With
    ``flush_ends`` they hold pieces of length s and L - s at the ends (two half bricks by default),
    so a 9-brick, 15-course wall has 8 x 9 + 7 x 10 = 142 blocks; without it every course holds
    ``length`` whole bricks and odd courses overhang by s at +x.  English bond: see
    :func:`english_courses`.  Pieces shorter than ``min_piece`` (default 0.15 L) are left out.
    """
    b = as_brick(brick)
    if length < 1 or courses < 1:
        raise ValueError("a wall needs length >= 1 brick and courses >= 1")
    unit = b.dims(laying)[0]
    boxes = BoxList()
    x0 = -length * unit / 2.0
    if bond == "stretcher":
        s = unit / 2.0 if stagger is None else float(stagger)
        if not (0.0 < s < unit):
            raise ValueError(f"stagger must be in (0, brick length = {unit} m), got {s}")
        t = b.dims(laying)[1]
        stretcher_courses(
            boxes, b, x0=x0, n_bricks=length, courses=courses, stagger=s, flush_ends=flush_ends,
            laying=laying, min_piece=default_min_piece(b) if min_piece is None else min_piece,
            y0=-t / 2.0, group=group,
        )
    elif bond == "english":
        if length < 2:
            raise ValueError("an English-bond wall needs length >= 2 bricks")
        english_courses(boxes, b, x0=x0, n_bricks=length, courses=courses, laying=laying, group=group)
    else:
        raise ValueError(f"bond must be 'stretcher' or 'english', got {bond!r}")
    scene = boxes.to_scene(origin=origin, yaw=yaw)
    h = b.dims(laying)[2]
    s = unit / 4.0 if bond == "english" else s  # quarter-brick lap of English bond
    along = [round(math.cos(math.radians(yaw)), 12), round(math.sin(math.radians(yaw)), 12), 0.0]
    scene.layout[group] = {"kind": "wall", "along": along, "stagger": s, "course_height": h,
                           "length": length * unit, "height": courses * h,
                           "l_over_h": length * unit / (courses * h), "s_over_h": s / h}
    return scene
