"""One-storey box models of the shaking-table tests (Section 4.2.3: Models I, II, III).

Plan (before ``yaw``/``origin``), centred on x = y = 0, m:

* long walls L1 (y < 0) and L2 (y > 0) run along x, ``length`` = 7 bricks in their through
  courses (outer length 7 x 105 = 735 mm); short walls T1 (x < 0) and T2 (x > 0) run along y,
  ``width`` = 5 bricks (525 mm); wall thickness t = brick width (50 mm), stretcher bond;
* corners fully interlocked: even courses (0, 2, ...) run L1 and L2 through the corners and T1,
  T2 butt between them; odd courses the other way round.  The butting walls are laid with their
  joints half a brick from those of the course below, centred in their span: 4 whole bricks in
  the 425 mm between the L walls and 6 in the 635 mm between the T walls, with a 2.5 mm gap at
  each end.  Per course 7 + 7 + 4 + 4 = 6 + 6 + 5 + 5 = 22 bricks.
* which walls are long: the thesis rocks L1, L2 out of plane under y excitation and gives their
  L/H as 2.33 (= 735 / 315), so the 7-brick walls are normal to y, i.e. run along x.  (The text's
  "730 mm x 525 mm (y x x)" contradicts this and 730 is not a whole number of 105 mm bricks;
  7 bricks = 735 mm is used.)  L1 and T1 are the back walls (near the actuators), L2 and T2 the
  front walls; back = negative side is an assumption.
* roof (Models I-III): ``beams`` timber beams spanning y over the tops of L1 and L2, evenly spaced
  along x (centres at X (i + 1/2) / beams), each end held by a 1 kg steel block over the wall;
  Models II and III add a 0.5 kg steel block on each corner.  All of these are separate blocks
  resting on the walls with friction.  Beam section and steel block sizes are assumptions
  (:class:`dem.builders.spec.RoofSpec`).
* ``corners="unbonded"`` (a bound: no interlock at all) replaces the interlock by a straight
  vertical joint: every course runs L1 and L2 through the corners over the full length X and
  T1, T2 butt between them, so no brick of an L wall and no brick of a T wall share a t x t
  corner square in any course.  Inside the walls the bond is kept: the L walls alternate
  7 whole bricks with [half, 6 whole, half] (flush ends, half-brick stagger); the T walls
  alternate the 4 whole bricks of the interlocked model (2.5 mm gap at each end) with
  [55 mm, 3 whole, 55 mm] laid flush against the L walls.  Per course 7 + 7 + 4 + 4 = 22 and
  8 + 8 + 5 + 5 = 26 pieces.  The corners hold only by friction on the bed joints of each wall
  and by the T walls' ends bearing on the L walls' inner faces.
"""

from __future__ import annotations

from dem.builders.bricks import brick as as_brick
from dem.builders.layout import BoxList, course_pieces
from dem.builders.spec import MODEL_CORNER_MASS, MODEL_COURSES, RoofSpec
from dem.builders.wall import default_min_piece
from dem.scene import Scene


def build_box_model(
    model: str | None = "II",
    brick="small",
    *,
    length: int = 7,
    width: int = 5,
    courses: int | None = None,
    roof: RoofSpec | dict | None | bool = True,
    min_piece: float | None = None,
    origin=(0.0, 0.0, 0.0),
    yaw: int = 0,
    corners: str = "interlocked",
) -> Scene:
    """A box model (m, kg).  ``model`` 'I' / 'II' / 'III' sets courses (9 / 9 / 15) and corner
    masses (0 / 0.5 / 0.5 kg) unless given; ``roof`` True (thesis roof), a RoofSpec / mapping,
    or None / False (bare walls).

    ``corners``: 'interlocked' (the thesis' models) or 'unbonded' (straight vertical joints,
    module docstring).

    Groups: L1, L2, T1, T2, roof-beam, roof-mass, corner-mass.  Roof blocks have course -1.
    """
    if corners not in ("interlocked", "unbonded"):
        raise ValueError(f"corners must be 'interlocked' or 'unbonded', got {corners!r}")
    b = as_brick(brick)
    unit, t, h = b.dims("flat")
    if courses is None:
        if model is None:
            raise ValueError("give courses (or a thesis model: I, II or III)")
        courses = MODEL_COURSES[model]
    if roof is True:
        roof = RoofSpec()
    elif roof is False:
        roof = None
    elif isinstance(roof, dict):
        roof = RoofSpec(**roof)
    mp = default_min_piece(b) if min_piece is None else float(min_piece)
    s = unit / 2.0

    X, Y = length * unit, width * unit  # outer plan, m
    boxes = BoxList()
    for k in range(courses):
        z0, z1 = k * h, (k + 1) * h
        l_through = k % 2 == 0
        # long walls along x
        if l_through:
            a, e, phase = -X / 2, X / 2, -X / 2
        elif corners == "unbonded":  # through every course, shifted by half a brick
            a, e, phase = -X / 2, X / 2, -X / 2 + s
        else:
            a, e, phase = -X / 2 + t, X / 2 - t, -X / 2 + s
        for name, y0 in (("L1", -Y / 2), ("L2", Y / 2 - t)):
            for p0, p1 in course_pieces(a, e, phase, unit, mp):
                boxes.add_piece((p0, y0, z0), (p1, y0 + t, z1), b.density, name, k)
        # short walls along y
        if l_through:
            a, e, phase = -Y / 2 + t, Y / 2 - t, -Y / 2 + s
        elif corners == "unbonded":  # butting every course, joints half a brick from below
            a, e, phase = -Y / 2 + t, Y / 2 - t, -Y / 2 + 2 * s
        else:
            a, e, phase = -Y / 2, Y / 2, -Y / 2
        for name, x0 in (("T1", -X / 2), ("T2", X / 2 - t)):
            for p0, p1 in course_pieces(a, e, phase, unit, mp):
                boxes.add_piece((x0, p0, z0), (x0 + t, p1, z1), b.density, name, k)

    if roof is not None:
        H = courses * h
        corner_mass = roof.corner_mass
        if corner_mass is None:
            corner_mass = MODEL_CORNER_MASS[model] if model is not None else 0.0
        bw, bd = roof.beam_width, roof.beam_depth
        mx, my, mz = roof.end_mass_size
        for i in range(roof.beams):
            xc = -X / 2 + X * (i + 0.5) / roof.beams
            boxes.add((xc - bw / 2, -Y / 2, H), (xc + bw / 2, Y / 2, H + bd), roof.beam_mass, "roof-beam")
            if roof.end_mass > 0:
                for yc in (-Y / 2 + t / 2, Y / 2 - t / 2):
                    boxes.add(
                        (xc - mx / 2, yc - my / 2, H + bd), (xc + mx / 2, yc + my / 2, H + bd + mz),
                        roof.end_mass, "roof-mass",
                    )
        if corner_mass > 0:
            cx, cy, cz = roof.corner_mass_size
            for xc in (-X / 2 + t / 2, X / 2 - t / 2):
                for yc in (-Y / 2 + t / 2, Y / 2 - t / 2):
                    boxes.add(
                        (xc - cx / 2, yc - cy / 2, H), (xc + cx / 2, yc + cy / 2, H + cz),
                        corner_mass, "corner-mass",
                    )
    return boxes.to_scene(origin=origin, yaw=yaw)
