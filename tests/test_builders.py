"""Scene builders against the specimens of the thesis (Shi 2016), with counts made by hand.

Hand counts (brick L x W x H: small 105 x 50 x 35 mm, large 152 x 75 x 50 mm):

* stretcher-bond wall, 9 bricks x 15 courses, flush ends with half bricks: the 8 even courses
  (0, 2, ..., 14) hold 9 whole bricks, the 7 odd ones 8 whole + 2 halves = 10 pieces:
  8 x 9 + 7 x 10 = 142 blocks; 15 x 9 bricks' worth of clay = 135 x 0.336 = 45.36 kg;
  0.945 x 0.050 x 0.525 m.  Not flush: 15 x 9 = 135 whole bricks.
* English bond, 5 bricks x 6 courses, large bricks flat: stretcher courses 2 rows x 5 = 10,
  header courses [header, queen closer, 2 x 5 - 3 = 7 headers, queen closer, header] = 11:
  3 x 10 + 3 x 11 = 63 blocks; thickness one brick length (0.152 m).
* stretcher bond on edge (h/t = 75/50), large bricks, 5 x 4, s = 60 mm: 5 + 6 + 5 + 6 = 22,
  height 4 x 75 = 300 mm, thickness 50 mm.
* box models (Section 4.2.3: 7 x 5 bricks in plan, 9 or 15 courses, interlocked corners):
  even courses: L1, L2 through (7 each), T1, T2 butting (425 mm between the L walls: 4 each);
  odd courses: T1, T2 through (5 each), L1, L2 butting (635 mm: 6 each); 22 per course.
  Model I: 9 x 22 = 198 bricks + 5 beams + 10 end masses = 213 blocks; Model II adds
  4 corner masses = 217; Model III: 15 x 22 = 330 + 19 = 349.  Roof load 10 x 1 kg = 10 kg
  (thesis: 10 kg), corner masses 4 x 0.5 = 2 kg (thesis: 20 % extra).  On each long facade
  5 x 1 kg + 2 x 0.5 kg = 6 kg, i.e. N = 58.9 N (thesis two-body model: 58.8 N).
* facade 5 x 9 with 3-brick wings, large bricks (t = 75, s = 76 mm, pieces < 22.8 mm left out):
  strong corners (lap 75 mm): even course = facade 5 + each wing [1 mm sliver left out, 2 whole,
  1 half] 3 = 11; odd course = facade [1 mm, 4 whole, 1 mm] 4 + wings 3 + 3 = 10;
  5 x 11 + 4 x 10 = 95.  Poor corners (lap 10 mm): even = 5 + 2 x [66 mm, 2 whole, half] 4 = 13;
  odd = [66 mm, 4 whole, 66 mm] 6 + 3 + 3 = 12; 5 x 13 + 4 x 12 = 113.
"""

from __future__ import annotations

import numpy as np
import pytest

from dem.builders import (
    PRESETS,
    SceneError,
    Wing,
    build_box_model,
    build_facade,
    build_wall,
    check_scene,
    require_valid,
)
from dem.scene import Scene

SMALL, LARGE = PRESETS["small"], PRESETS["large"]
TOL = 1e-9


def lo_hi(scene: Scene):
    return scene.position - scene.size / 2, scene.position + scene.size / 2


def assert_sound(scene: Scene):
    """No initial overlap, nothing floating, nothing about to tip."""
    rep = check_scene(scene, overlap_tolerance=1e-9, contact_tolerance=1e-9)
    assert rep.overlaps == [] and rep.floating == [] and rep.warnings == [], rep.format()


def joints(scene: Scene, course: int, group=None, axis: int = 0) -> np.ndarray:
    """Positions of the vertical joints inside one course (piece faces that are not wall ends)."""
    lo, hi = lo_hi(scene)
    sel = scene.course == course
    if group is not None:
        sel &= scene.group == scene.group_names.index(group)
    faces = np.unique(np.round(np.concatenate([lo[sel, axis], hi[sel, axis]]), 9))
    return faces[1:-1]


def min_offset(a: np.ndarray, b: np.ndarray) -> float:
    """Smallest horizontal distance between a joint of one course and a joint of the other."""
    return float(np.min(np.abs(a[:, None] - b[None, :])))


# ----------------------------------------------------------------------------- bricks
def test_brick_presets():
    assert (SMALL.length, SMALL.width, SMALL.height) == (0.105, 0.050, 0.035)
    assert SMALL.mass == pytest.approx(0.336)
    assert (LARGE.length, LARGE.width, LARGE.height) == (0.152, 0.075, 0.050)
    # large brick mass is not in the thesis: same density as the small brick (~1829 kg/m3)
    assert LARGE.density == pytest.approx(1829, rel=1e-3)
    for b in (SMALL, LARGE):  # shape ratio 6 : 3 : 2 (Section 3.4.1; 50/35 = 1.43 for the small)
        assert b.length / b.height == pytest.approx(3.0, rel=0.05)
        assert b.width / b.height == pytest.approx(1.5, rel=0.05)


# ----------------------------------------------------------------------------- walls
def test_stretcher_wall_9x15_counts_and_dimensions():
    w = build_wall("small", 9, 15)
    assert w.n_blocks == 8 * 9 + 7 * 10 == 142
    per_course = np.bincount(w.course)
    assert per_course[0::2].tolist() == [9] * 8 and per_course[1::2].tolist() == [10] * 7
    assert w.mass.sum() == pytest.approx(135 * 0.336)
    lo, hi = w.bounding_box()
    assert hi - lo == pytest.approx([0.945, 0.050, 0.525])
    assert lo[2] == pytest.approx(0.0)
    # the end pieces of odd courses are half bricks and the ends are flush
    lo_b, hi_b = lo_hi(w)
    odd = w.course % 2 == 1
    lengths = np.round(hi_b[odd, 0] - lo_b[odd, 0], 9)
    assert sorted(set(lengths)) == [0.0525, 0.105]
    assert (lengths == 0.0525).sum() == 2 * 7
    assert_sound(w)


@pytest.mark.parametrize("s", [0.010, 0.035, 0.0525])
def test_stretcher_stagger(s):
    """Vertical joints of successive courses are offset by the stagger s (or L - s)."""
    w = build_wall("small", 9, 15, stagger=s, flush_ends=False)
    assert w.n_blocks == 9 * 15
    for k in range(14):
        assert min_offset(joints(w, k), joints(w, k + 1)) == pytest.approx(min(s, 0.105 - s))
    lo, hi = w.bounding_box()
    assert hi[0] - lo[0] == pytest.approx(0.945 + s)  # odd courses overhang by s at one end
    assert_sound(w)


def test_flush_wall_with_small_stagger_leaves_out_slivers():
    # s = 10 mm flush: the 10 mm end piece is shorter than min_piece (0.15 L = 15.75 mm)
    w = build_wall("small", 9, 3, stagger=0.010)
    assert np.bincount(w.course).tolist() == [9, 9, 9]  # 95 mm piece + 8 whole, sliver left out
    assert_sound(w)


def test_english_bond():
    w = build_wall("large", 5, 6, bond="english")
    assert w.n_blocks == 3 * 10 + 3 * 11 == 63
    lo, hi = w.bounding_box()
    assert hi - lo == pytest.approx([0.760, 0.152, 0.300])
    lo_b, hi_b = lo_hi(w)
    header_course = w.course == 1
    # every piece of a header course spans the whole thickness (it bonds the two leaves)
    assert np.allclose(hi_b[header_course, 1] - lo_b[header_course, 1], 0.152)
    # two queen closers (half the width of a header) per header course
    widths = np.round(hi_b[header_course, 0] - lo_b[header_course, 0], 9)
    assert (widths == 0.0375).sum() == 2 and (widths == 0.075).sum() == 9
    # quarter-brick lap between the face joints of stretcher and header courses
    assert min_offset(joints(w, 0), joints(w, 1)) >= 0.152 / 4 - 0.001
    assert_sound(w)


def test_on_edge_wall():
    w = build_wall("large", 5, 4, laying="on_edge", stagger=0.060)
    assert w.n_blocks == 5 + 6 + 5 + 6 == 22
    lo, hi = w.bounding_box()
    assert hi - lo == pytest.approx([0.760, 0.050, 0.300])  # h/t = 75/50
    assert_sound(w)


def test_yaw_and_origin_move_the_wall():
    a = build_wall("small", 5, 3)
    b = build_wall("small", 5, 3, origin=(1.0, 2.0, 0.0), yaw=90)
    assert b.n_blocks == a.n_blocks
    lo, hi = b.bounding_box()
    assert hi - lo == pytest.approx([0.050, 0.525, 0.105])
    assert (lo + hi)[:2] / 2 == pytest.approx([1.0, 2.0])
    assert_sound(b)


# ----------------------------------------------------------------------------- facades
def corner_laps(scene: Scene, wing: str) -> list[float]:
    """Bed-joint overlap (m^2) between the wing's and the facade's bricks, per pair of courses."""
    lo, hi = lo_hi(scene)
    gw, gf = scene.group_names.index(wing), scene.group_names.index("facade")
    out = []
    for k in range(1, scene.course.max() + 1):
        area = 0.0
        for i in np.flatnonzero((scene.group == gw) & (scene.course == k)):
            for j in np.flatnonzero((scene.group == gf) & (scene.course == k - 1)):
                dx = min(hi[i, 0], hi[j, 0]) - max(lo[i, 0], lo[j, 0])
                dy = min(hi[i, 1], hi[j, 1]) - max(lo[i, 1], lo[j, 1])
                if dx > TOL and dy > TOL:
                    area += dx * dy
        for i in np.flatnonzero((scene.group == gf) & (scene.course == k)):
            for j in np.flatnonzero((scene.group == gw) & (scene.course == k - 1)):
                dx = min(hi[i, 0], hi[j, 0]) - max(lo[i, 0], lo[j, 0])
                dy = min(hi[i, 1], hi[j, 1]) - max(lo[i, 1], lo[j, 1])
                if dx > TOL and dy > TOL:
                    area += dx * dy
        out.append(area)
    return out


def test_facade_strong_corners_counts_and_interlock():
    f = build_facade("large", 5, 9, left=Wing(3, "strong"), right=Wing(3, "strong"))
    assert f.n_blocks == 5 * 11 + 4 * 10 == 95
    per_course = np.bincount(f.course)
    assert per_course[0::2].tolist() == [11] * 5 and per_course[1::2].tolist() == [10] * 4
    # fully interlocked: between every two courses the wing and facade share the whole
    # corner square t x t = 75 x 75 mm in the bed joint
    for wing in ("wing-left", "wing-right"):
        assert corner_laps(f, wing) == pytest.approx([0.075**2] * 8)
    # the outer corner is a plane (no notch): wings flush with the facade ends
    lo, hi = f.bounding_box()
    assert hi[0] - lo[0] == pytest.approx(5 * 0.152)
    assert_sound(f)


def test_facade_poor_corners_counts_and_lap():
    f = build_facade("large", 5, 9, left=Wing(3, "poor"), right=Wing(3, "poor"))
    assert f.n_blocks == 5 * 13 + 4 * 12 == 113
    for wing in ("wing-left", "wing-right"):
        assert corner_laps(f, wing) == pytest.approx([0.010**2] * 8)  # 10 mm lap
    assert_sound(f)


@pytest.mark.parametrize(
    "brick,conn,lap",
    [("large", "poor", 0.010), ("large", "good", 0.050), ("large", "strong", 0.075),
     ("small", "poor", 0.010), ("small", "good", 0.035), ("small", "strong", 0.050)],
)
def test_corner_connections_match_thesis_staggers(brick, conn, lap):
    """Section 3.3.3: poor / good / strong = 10 / 50 / 75 mm (large), 10 / 35 / 50 mm (small)."""
    f = build_facade(brick, 5, 5, left=Wing(3, "poor"), right=Wing(3, conn))
    assert corner_laps(f, "wing-right") == pytest.approx([lap**2] * 4)
    assert corner_laps(f, "wing-left") == pytest.approx([0.010**2] * 4)
    assert_sound(f)


def test_facade_without_wings_is_the_wall():
    f = build_facade("large", 5, 9)
    w = build_wall("large", 5, 9)
    assert f.n_blocks == w.n_blocks == 5 * 5 + 4 * 6
    assert np.allclose(np.sort(f.position, axis=0), np.sort(w.position, axis=0))


def test_wings_run_behind_the_facade():
    f = build_facade("small", 5, 15, left=Wing(5, "strong"), right=Wing(5, "strong"))
    lo, hi = lo_hi(f)
    fac = f.group == f.group_names.index("facade")
    assert np.allclose(lo[fac, 1], -0.025) and np.allclose(hi[fac, 1], 0.025)
    wings = ~fac
    assert (lo[wings, 1] >= 0.025 - 0.050 - TOL).all()  # reach at most t into the facade band
    assert hi[wings, 1].max() == pytest.approx(0.025 - 0.050 + 5 * 0.105)
    assert_sound(f)


def test_lap_larger_than_thickness_is_rejected():
    with pytest.raises(ValueError, match="lap"):
        build_facade("small", 5, 5, left=Wing(3, 0.060))


# ----------------------------------------------------------------------------- box models
@pytest.mark.parametrize(
    "model,courses,n_blocks,corner_kg",
    [("I", 9, 198 + 15, 0.0), ("II", 9, 198 + 19, 0.5), ("III", 15, 330 + 19, 0.5)],
)
def test_box_model_counts(model, courses, n_blocks, corner_kg):
    s = build_box_model(model)
    assert s.n_blocks == n_blocks
    bricks = s.course >= 0
    assert bricks.sum() == 22 * courses
    g = {name: s.group == i for i, name in enumerate(s.group_names)}
    for k in range(courses):
        in_k = s.course == k
        counts = {w: int((g[w] & in_k).sum()) for w in ("L1", "L2", "T1", "T2")}
        if k % 2 == 0:
            assert counts == {"L1": 7, "L2": 7, "T1": 4, "T2": 4}
        else:
            assert counts == {"L1": 6, "L2": 6, "T1": 5, "T2": 5}
    assert s.mass[bricks].sum() == pytest.approx(22 * courses * 0.336)
    assert g["roof-beam"].sum() == 5
    assert g["roof-mass"].sum() == 10 and s.mass[g["roof-mass"]].sum() == pytest.approx(10.0)
    if corner_kg:
        assert s.mass[g["corner-mass"]].tolist() == [corner_kg] * 4
    else:
        assert "corner-mass" not in s.group_names
    lo, hi = s.bounding_box()
    assert (hi - lo)[:2] == pytest.approx([0.735, 0.525])
    wall_top = s.position[bricks, 2] + s.size[bricks, 2] / 2
    assert wall_top.max() == pytest.approx(courses * 0.035)  # 315 / 525 mm
    assert_sound(s)


def test_box_model_corners_interlock():
    """Each t x t corner column is covered in every course by exactly one brick, of an L wall in
    even courses and of a T wall in odd ones (alternating: an interlocked corner)."""
    s = build_box_model("II")
    lo, hi = lo_hi(s)
    t = 0.050
    for cx in (-0.3675 + t / 2, 0.3675 - t / 2):
        for cy in (-0.2625 + t / 2, 0.2625 - t / 2):
            for k in range(9):
                cover = np.flatnonzero(
                    (s.course == k) & (lo[:, 0] <= cx - t / 2 + TOL) & (hi[:, 0] >= cx + t / 2 - TOL)
                    & (lo[:, 1] <= cy - t / 2 + TOL) & (hi[:, 1] >= cy + t / 2 - TOL)
                )
                assert len(cover) == 1
                name = s.group_names[s.group[cover[0]]]
                assert name[0] == ("L" if k % 2 == 0 else "T")


def test_unbonded_box_model_has_straight_corner_joints():
    """corners='unbonded': the L walls run through every course (7 whole bricks, or a half, 6
    whole and a half), the T walls butt between them; no L brick and no T brick share any
    point of the plan (a straight vertical joint), the bond inside each wall is kept (joints of
    successive courses half a brick apart) and the scene is sound.  The plan outline and the
    roof are those of the interlocked model."""
    s = build_box_model("II", corners="unbonded")
    lo, hi = lo_hi(s)
    g = {name: s.group == i for i, name in enumerate(s.group_names)}
    for k in range(9):
        in_k = s.course == k
        counts = {w: int((g[w] & in_k).sum()) for w in ("L1", "L2", "T1", "T2")}
        assert counts == ({"L1": 7, "L2": 7, "T1": 4, "T2": 4} if k % 2 == 0
                          else {"L1": 8, "L2": 8, "T1": 5, "T2": 5})
    walls_l = np.flatnonzero(g["L1"] | g["L2"])
    walls_t = np.flatnonzero(g["T1"] | g["T2"])
    # plan overlap of every L brick with every T brick (any course): never positive
    ov = np.minimum(hi[walls_l, None, :2], hi[None, walls_t, :2]) - \
        np.maximum(lo[walls_l, None, :2], lo[None, walls_t, :2])
    assert not ((ov > TOL).all(axis=2)).any()
    # the L walls span the full length in every course, the T walls only the inside
    for k in range(9):
        sel = (s.course == k) & g["L1"]
        assert lo[sel, 0].min() == pytest.approx(-0.3675) and hi[sel, 0].max() == pytest.approx(0.3675)
        sel = (s.course == k) & g["T1"]
        assert lo[sel, 1].min() >= -0.2125 - TOL and hi[sel, 1].max() <= 0.2125 + TOL
    for wall, axis in (("L1", 0), ("L2", 0), ("T1", 1), ("T2", 1)):
        for k in range(8):
            assert min_offset(joints(s, k, wall, axis), joints(s, k + 1, wall, axis)) >= 0.050 - TOL
    ref = build_box_model("II")
    assert np.allclose(np.array(s.bounding_box()), np.array(ref.bounding_box()))
    roof = s.course < 0
    assert np.array_equal(s.position[roof], ref.position[ref.course < 0])
    assert_sound(s)


def test_facade_unbonded_wings_butt_in_every_course():
    """connection 'unbonded': the facade runs through both corners in every course (5 whole
    bricks, or a half, 4 whole and a half), each wing butts against its back face in every
    course in the band of a strong corner; no facade brick overlaps a wing brick in plan, the
    wings' joints stay half a brick from the course below's, and the scene is sound."""
    s = build_facade("small", 5, 6, left=Wing(3, "unbonded"), right=Wing(3, "unbonded"))
    lo, hi = lo_hi(s)
    fac = np.flatnonzero(s.group == s.group_names.index("facade"))
    wing = np.flatnonzero(s.group != s.group_names.index("facade"))
    ov = np.minimum(hi[fac, None, :2], hi[None, wing, :2]) - \
        np.maximum(lo[fac, None, :2], lo[None, wing, :2])
    assert not ((ov > TOL).all(axis=2)).any()
    for k in range(6):
        sel = np.intersect1d(fac, np.flatnonzero(s.course == k))
        assert lo[sel, 0].min() == pytest.approx(-0.2625) and hi[sel, 0].max() == pytest.approx(0.2625)
        for name in ("wing-left", "wing-right"):
            w = (s.course == k) & (s.group == s.group_names.index(name))
            assert lo[w, 1].min() >= 0.025 - TOL
            assert np.allclose(hi[w, 0] - lo[w, 0], 0.050)
    for name in ("wing-left", "wing-right"):
        for k in range(5):
            assert min_offset(joints(s, k, name, 1), joints(s, k + 1, name, 1)) >= 0.050 - TOL
    assert_sound(s)


def test_box_model_corner_option_is_checked():
    with pytest.raises(ValueError, match="corners"):
        build_box_model("II", corners="loose")


def test_box_model_walls_are_staggered():
    """Inside the walls, joints of successive courses are at least 50 mm apart (s/h = 50/35)."""
    s = build_box_model("III")
    for wall, axis in (("L1", 0), ("L2", 0), ("T1", 1), ("T2", 1)):
        for k in range(14):
            assert min_offset(joints(s, k, wall, axis), joints(s, k + 1, wall, axis)) >= 0.050 - TOL


def test_box_model_walls_orientation():
    """L1, L2 (7 bricks, L/H = 735 / 315 = 2.33) face y; T1, T2 (5 bricks, 1.67) face x."""
    s = build_box_model("I")
    lo, hi = lo_hi(s)
    for name, y_side in (("L1", -1), ("L2", 1)):
        sel = s.group == s.group_names.index(name)
        assert np.allclose(hi[sel, 1] - lo[sel, 1], 0.050)  # thickness across y
        assert np.sign(s.position[sel, 1]).tolist() == [y_side] * sel.sum()
    for name, x_side in (("T1", -1), ("T2", 1)):
        sel = s.group == s.group_names.index(name)
        assert np.allclose(hi[sel, 0] - lo[sel, 0], 0.050)
        assert np.sign(s.position[sel, 0]).tolist() == [x_side] * sel.sum()


def test_box_model_roof_rests_on_the_long_walls():
    s = build_box_model("II")
    lo, hi = lo_hi(s)
    top = 9 * 0.035
    beams = np.flatnonzero(s.group == s.group_names.index("roof-beam"))
    assert np.allclose(lo[beams, 2], top)
    assert np.allclose(lo[beams, 1], -0.2625) and np.allclose(hi[beams, 1], 0.2625)  # span L1-L2
    xs = np.sort(s.position[beams, 0])
    assert np.allclose(np.diff(xs), 0.735 / 5)  # evenly spaced
    masses = s.group == s.group_names.index("roof-mass")
    assert np.allclose(lo[masses, 2], top + 0.020)  # on the beams
    # load carried by each long facade: 5 end masses + 2 corner masses = 6 kg (N = 58.8 N)
    on_l2 = (s.position[:, 1] > 0.2125) & (lo[:, 2] >= top - TOL) & (s.group != s.group_names.index("roof-beam"))
    assert s.mass[on_l2].sum() == pytest.approx(6.0)
    assert_sound(s)


def test_bare_box_model_and_custom_courses():
    s = build_box_model(None, courses=4, roof=None)
    assert s.n_blocks == 4 * 22
    assert_sound(s)


# ----------------------------------------------------------------------------- checks
def boxes(*specs) -> Scene:
    """Axis-aligned unit-mass boxes from (size, position) pairs."""
    n = len(specs)
    return Scene(
        size=[s for s, _ in specs], position=[p for _, p in specs], quat=np.tile([1.0, 0, 0, 0], (n, 1)),
        mass=np.ones(n), fixed=np.zeros(n, bool), velocity=np.zeros((n, 3)),
        angular_velocity=np.zeros((n, 3)), group=np.zeros(n), course=np.arange(n),
    )


def test_check_names_overlapping_blocks():
    s = boxes(([0.2, 0.2, 0.1], [0, 0, 0.05]), ([0.2, 0.2, 0.1], [0.15, 0, 0.05]))
    rep = check_scene(s)
    assert len(rep.overlaps) == 1 and "block 0" in rep.overlaps[0] and "block 1" in rep.overlaps[0]
    assert "50.000 mm" in rep.overlaps[0]
    with pytest.raises(SceneError, match="overlap"):
        require_valid(rep)


def test_check_accepts_touching_blocks_and_names_floating_ones():
    s = boxes(([0.2, 0.2, 0.1], [0, 0, 0.05]), ([0.2, 0.2, 0.1], [0.2, 0, 0.05]),
              ([0.1, 0.1, 0.1], [0.1, 0, 0.15]), ([0.1, 0.1, 0.1], [1.0, 0, 0.3]))
    rep = check_scene(s)
    assert rep.overlaps == []
    assert len(rep.floating) == 1 and rep.floating[0].startswith("block 3")
    assert check_scene(s, allow_floating=True).ok


def test_check_warns_about_a_block_that_will_tip():
    # a brick resting on another with 70 % of its length overhanging
    s = boxes(([0.105, 0.05, 0.035], [0, 0, 0.0175]), ([0.105, 0.05, 0.035], [0.0735, 0, 0.0525]))
    rep = check_scene(s)
    assert rep.ok and len(rep.warnings) == 1 and "block 1" in rep.warnings[0]


def test_check_rotated_blocks_on_an_incline():
    """Non-axis-aligned boxes (separating-axis test): a block on a 30 deg incline rests on it;
    pushed 5 mm into it, it overlaps."""
    from dem.quaternion import from_euler_xyz

    q = from_euler_xyz([[30, 0, 0], [30, 0, 0]])
    n = np.array([0, -0.5, np.sqrt(3) / 2])

    def scene(offset):
        return Scene(
            size=[[0.4, 1.0, 0.05], [0.1, 0.1, 0.05]], position=[[0, 0, 0.4], np.array([0, 0, 0.4]) + offset * n],
            quat=q, mass=[10.0, 1.0], fixed=[True, False], velocity=np.zeros((2, 3)),
            angular_velocity=np.zeros((2, 3)), group=[0, 0], course=[-1, -1],
        )

    assert check_scene(scene(0.05)).ok
    rep = check_scene(scene(0.045))
    assert len(rep.overlaps) == 1 and "5.000 mm" in rep.overlaps[0]
    assert check_scene(scene(0.06)).floating  # 10 mm above the incline


def test_check_block_below_table():
    s = boxes(([0.2, 0.2, 0.1], [0, 0, 0.04]))
    rep = check_scene(s)
    assert len(rep.overlaps) == 1 and "below the table" in rep.overlaps[0]


# ----------------------------------------------------------------------------- from a case
def test_case_scene_explicit_blocks_first_then_builders():
    from dem.case import parse_case
    from dem.run.build import scene_from_case

    case = parse_case({
        "name": "mixed",
        "scene": {
            "blocks": [{"size": [0.2, 0.2, 0.1], "position": [2.0, 0.0, 0.05], "mass": 4.0, "group": "probe"}],
            "wall": {"brick": "small", "length": 3, "courses": 2, "origin": [0.0, 0.0, 0.0]},
            "box_model": {"model": "I", "origin": [0.0, 1.5, 0.0], "yaw": 90},
        },
        "material": {"friction": 0.81},
        "run": {"duration": 1.0},
    })
    s = scene_from_case(case)
    assert s.n_blocks == 1 + (3 + 4) + 213
    assert s.group_names[:3] == ["probe", "wall", "L1"]
    assert s.position[0] == pytest.approx([2.0, 0.0, 0.05]) and s.course[0] == -1
    assert (s.group[1:8] == 1).all()
    box = slice(8, None)
    lo, hi = s.position[box] - s.size[box] / 2, s.position[box] + s.size[box] / 2
    # turned by 90 deg: the 735 mm long walls now run along y, centred on (0, 1.5)
    assert hi.max(axis=0)[:2] - lo.min(axis=0)[:2] == pytest.approx([0.525, 0.735])
    assert (lo.min(axis=0)[:2] + hi.max(axis=0)[:2]) / 2 == pytest.approx([0.0, 1.5])


def test_case_field_turns_unbonded_corners_on_and_stays_out_of_the_identity():
    """scene.box_model.corners: unbonded builds the unbonded model; left at 'interlocked' it is
    not in the case's dump, so recorded cases keep their identity (dem.case.identity)."""
    from dem.case import parse_case
    from dem.run.build import scene_from_case

    def case(**box):
        return parse_case({"name": "c", "scene": {"box_model": {"model": "II", **box}},
                           "material": {"friction": 0.81}, "run": {"duration": 1.0}})

    s = scene_from_case(case(corners="unbonded"))
    ref = build_box_model("II", corners="unbonded")
    assert np.array_equal(s.position, ref.position) and np.array_equal(s.size, ref.size)
    assert "corners" not in case().model_dump()["scene"]["box_model"]
    assert case(corners="unbonded").model_dump()["scene"]["box_model"]["corners"] == "unbonded"
    with pytest.raises(Exception, match="corners"):
        case(corners="loose")


def test_case_scene_rejects_overlapping_builders():
    from dem.case import parse_case
    from dem.run.build import scene_from_case

    case = parse_case({
        "name": "clash",
        # a 945 mm wall through the middle of the 735 mm box crosses T1 and T2
        "scene": {"wall": {"length": 9, "courses": 2}, "box_model": {"model": "I"}},
        "material": {"friction": 0.81},
        "run": {"duration": 1.0},
    })
    with pytest.raises(SceneError, match=r"block \d+ \(wall, course \d\) and block \d+ \(T\d, course \d\)"):
        scene_from_case(case)
