"""Mechanisms from kinematics for any scene, and what a tilt run shows.

A wall given as explicit blocks has no builder layout: its courses, course height, stagger and
axis are derived from the blocks (postprocess.wall_geometry) and must give the builder's numbers;
the mechanism of a planted motion must then read the same for the two.  Real runs: a stack of n
identical blocks overturns as one at tan = b / (n h); the explicit-block copies of the thesis'
small-brick walls slide at L/H = 3 and overturn at L/H = 0.6 (results/tilt: the builder walls
do the same, and a run of explicit blocks in builder order is the builder's run, bit for bit).
"""

from __future__ import annotations

import json
from types import SimpleNamespace

import numpy as np
import pytest
from scipy.spatial.transform import Rotation

from dem import quaternion
from dem.builders import Wing, build_facade, build_wall
from dem.case import BlockSpec, TiltLoading, parse_case
from dem_cli.commands.run import RUN_ANALYSES, result_line
from dem.loading import Tilt
from dem.output.snapshot import table_to_lab
from dem.run import run_case
from dem.scene import blocks_to_scene, scene_to_blocks
from postprocess.limit_analysis import elastic_tipping_factor
from postprocess.mechanisms import CRACK_ANGLE_DEFINITION, collapsed_portion
from postprocess.tilt import classify, lean_series, plot_lean, top_blocks, wall_layout
from postprocess.wall_geometry import builder_geometry, derive_geometry

CASE = SimpleNamespace(material=SimpleNamespace(friction=0.81))
# constant-rate tilts: said explicitly where the schema has the choice (its default is quasi-static)
RATE = {"method": "constant_rate"} if "method" in TiltLoading.model_fields else {}


def blocks_of(scene, keep_groups: bool = False) -> list[dict]:
    """The blocks of a builder scene as a case's explicit blocks (same order)."""
    return scene_to_blocks(scene, groups=keep_groups)


def explicit(scene, keep_groups: bool = False):
    return blocks_to_scene([BlockSpec(**b) for b in blocks_of(scene, keep_groups)])


# --- geometry derived from the blocks -----------------------------------------------------------

@pytest.mark.parametrize("kw", [
    {"brick": "small", "length": 3, "courses": 3},
    {"brick": "small", "length": 2, "courses": 10},
    {"brick": "small", "length": 9, "courses": 15, "stagger": 0.01},
    {"brick": "small", "length": 9, "courses": 15, "stagger": 0.035},
    {"brick": "large", "length": 5, "courses": 6, "bond": "english"},
    {"brick": "small", "length": 5, "courses": 5, "yaw": 90},
])
def test_geometry_derived_from_blocks_is_the_builders(kw):
    sc = build_wall(**kw)
    b = builder_geometry(sc, *wall_layout(sc))
    d = derive_geometry(explicit(sc))
    assert d.source == "blocks" and d.has_axis
    assert np.array_equal(d.course, b.course)
    assert np.allclose(d.along, b.along, atol=1e-12)
    for attr in ("course_height", "stagger", "length", "height", "l_over_h", "s_over_h"):
        assert getattr(d, attr) == pytest.approx(getattr(b, attr), rel=1e-9), attr


def test_stack_geometry_courses_without_stagger():
    blocks = [BlockSpec(size=[0.1, 0.05, 0.1], position=[0.0, 0.0, 0.05 + 0.1 * k], density=2000)
              for k in range(4)]
    g = derive_geometry(blocks_to_scene(blocks), load_dir=[1.0, 0.0, 0.0])
    assert g.course.tolist() == [0, 1, 2, 3]
    assert g.stagger is None and g.course_height == pytest.approx(0.1)
    assert g.l_over_h == pytest.approx(0.25) and g.in_plane([1.0, 0.0, 0.0])
    assert not g.in_plane([0.0, 1.0, 0.0])  # its long side is x: a y load is out of plane
    # a square footprint has no axis of its own: the load direction is taken, in plane
    sq = blocks_to_scene([BlockSpec(size=[0.1, 0.1, 0.4], position=[0, 0, 0.2], density=2000)])
    g = derive_geometry(sq, load_dir=[0.0, -1.0, 0.0])
    assert not g.has_axis and g.in_plane([0.0, -1.0, 0.0])


# --- planted motions: explicit blocks read like the builder's wall -------------------------------

def _planted(scene, kind, angle=0.08):
    """Poses after the portion above a stepped crack at the bond angle (from the leeward bottom
    brick, rising windward) slid 20 mm, or overturned ``angle`` rad about the leeward toe."""
    pos0, quat0 = scene.position.copy(), scene.quat.copy()
    x_lee = (pos0[:, 0] + 0.5 * scene.size[:, 0]).max()
    course = np.round((pos0[:, 2] - 0.0175) / 0.035)
    moving = pos0[:, 0] - 0.5 * scene.size[:, 0] >= x_lee - 0.105 - course * 0.035 * 1.5 - 1e-9
    pos, quat = pos0.copy(), quat0.copy()
    if kind == "sliding":
        pos[moving, 0] += 0.02
    else:
        rot = Rotation.from_rotvec([0.0, angle, 0.0])
        toe = np.array([x_lee, 0.0, 0.0])
        pos[moving] = toe + rot.apply(pos0[moving] - toe)
        quat[moving] = quaternion.from_rotation(rot * quaternion.rotation(quat0[moving]))
    return pos0, quat0, pos, quat, moving


@pytest.mark.parametrize("kind", ["sliding", "overturning"])
def test_planted_in_plane_mechanism_same_for_explicit_blocks(kind):
    sc = build_wall("small", 5, 7)
    ex = explicit(sc)
    pos0, quat0, pos, quat, moving = _planted(sc, kind)
    load = [1.0, 0.0, 0.0]
    a = classify(CASE, sc, pos0, quat0, pos, quat, load)
    b = classify(CASE, ex, pos0, quat0, pos, quat, load)
    assert a["kind"] == b["kind"] == "in-plane"
    assert a["mechanism"] == b["mechanism"] == kind
    assert b["geometry"]["source"] == "blocks" and a["geometry"]["source"] == "builder"
    for key in ("overturning_mass_fraction", "n_moving", "courses_involved", "crack_angle_deg",
                "overturning_columns"):
        assert a[key] == pytest.approx(b[key]), key
    assert b["limit_analysis"]["lambda_c"] == pytest.approx(a["limit_analysis"]["lambda_c"])
    # the crack follows the bond: tan(alpha_c) = s/h = 1.5 (thesis: crack angle = stagger angle)
    assert b["crack_angle_deg"] == pytest.approx(np.degrees(np.arctan(1.5)), abs=4.0)
    assert b["crack_angle_from_bottom_line_deg"] == pytest.approx(90.0 - b["crack_angle_deg"])
    assert b["crack_angle_definition"] == CRACK_ANGLE_DEFINITION
    # the collapsed portion is the planted one, the bottom brick at the toe included
    assert b["collapsed"]["blocks"] == np.flatnonzero(moving).tolist()
    assert b["collapsed"]["mass_fraction"] == pytest.approx(sc.mass[moving].sum() / sc.mass.sum())


def test_planted_facade_mechanisms_same_for_explicit_blocks():
    """A facade with wings given as explicit blocks (its groups named facade / wing-left /
    wing-right, no courses): the courses are derived, the labels are the builder's."""
    sc = build_facade("large", 5, 9, left=Wing(3, "strong"), right=Wing(3, "strong"))
    ex = explicit(sc, keep_groups=True)
    assert (ex.course == -1).all()
    g = np.array([sc.group_names[i] for i in sc.group])
    rules = {"A": (g == "facade") & (sc.course >= 6),
             "B2": ((g == "facade") & (sc.course >= 6)) | ((g != "facade") & (sc.course >= 7))}
    for label, sel in rules.items():
        quat = np.tile([1.0, 0.0, 0.0, 0.0], (sc.n_blocks, 1))
        quat[sel] = quaternion.from_rotation(Rotation.from_rotvec([0.02, 0.0, 0.0]))
        a = classify(CASE, sc, sc.position, sc.quat, sc.position, quat, [0.0, -1.0, 0.0])
        b = classify(CASE, ex, sc.position, sc.quat, sc.position, quat, [0.0, -1.0, 0.0])
        assert a["mechanism"] == b["mechanism"] == label
        assert a["crack_depth_per_column"] == b["crack_depth_per_column"]
        assert b["collapsed"]["n_blocks"] == int(sel.sum())


def test_explicit_wall_loaded_out_of_plane_reads_as_a_lone_wall():
    """A wall without returns overturning whole about its base: the crack line in words (the
    facade labels A / B1 / D / B2 / G are for facades with wings)."""
    sc = build_wall("small", 5, 9)
    ex = explicit(sc)
    rot = Rotation.from_rotvec([0.03, 0.0, 0.0])  # about +x: the top moves to -y
    quat = quaternion.from_rotation(rot * quaternion.rotation(sc.quat))
    pos = rot.apply(sc.position - [0.0, -0.025, 0.0]) + [0.0, -0.025, 0.0]
    res = classify(CASE, ex, sc.position, sc.quat, pos, quat, [0.0, -1.0, 0.0])
    assert res["kind"] == "out-of-plane"
    assert res["mechanism"] == "overturning of the whole wall at its base"
    assert res["geometry"]["load_angle_to_axis_deg"] == pytest.approx(90.0)
    assert res["collapsed"]["n_blocks"] == sc.n_blocks


def test_collapsed_portion_reads_rotation_as_well_as_displacement():
    """A column overturning about its toe: the bottom block moves least but turns as much as
    the top one, so it is in the portion; a resting neighbour is not."""
    blocks = [BlockSpec(size=[0.1, 0.05, 0.1], position=[0.0, 0.0, 0.05 + 0.1 * k], density=2000)
              for k in range(4)]
    blocks.append(BlockSpec(size=[0.1, 0.05, 0.1], position=[-0.2, 0.0, 0.05], density=2000))
    sc = blocks_to_scene(blocks)
    rot = Rotation.from_rotvec([0.0, 0.05, 0.0])
    toe = np.array([0.05, 0.0, 0.0])
    pos, quat = sc.position.copy(), sc.quat.copy()
    pos[:4] = toe + rot.apply(sc.position[:4] - toe)
    quat[:4] = quaternion.from_rotation(rot * quaternion.rotation(sc.quat[:4]))
    d = np.linalg.norm(pos - sc.position, axis=1)
    assert d[0] < 0.3 * d.max()  # displacement alone would leave the bottom block out
    res = collapsed_portion(sc, sc.position, sc.quat, pos, quat)
    assert res["blocks"] == [0, 1, 2, 3] and res["mass_fraction"] == pytest.approx(0.8)


def test_a_lone_block_slides_or_tips_and_gets_no_wall_label():
    """cases/analytic/block-on-tilt.yaml's blocks, apart on the table: the slender one turning
    about its toe reads "tipping", the squat one translated reads "sliding", kind "block" (the
    facade labels A / B1 ... of a one-block "wall" meant nothing); a stack of the same blocks
    is a wall and still reads overturning."""
    blocks = [BlockSpec(size=[0.2, 0.2, 0.1], position=[0.0, 0.0, 0.05], mass=4.0),
              BlockSpec(size=[0.1, 0.1, 0.4], position=[1.0, 0.0, 0.2], density=2000)]
    sc = blocks_to_scene(blocks)
    load = np.array([0.0, -1.0, 0.0])  # tilt about +x: gravity gains a -y component
    rot = Rotation.from_rotvec([0.1, 0.0, 0.0])  # about +x: the top moves to -y
    toe = np.array([1.0, -0.05, 0.0])
    pos, quat = sc.position.copy(), sc.quat.copy()
    pos[1] = toe + rot.apply(sc.position[1] - toe)
    quat[1] = quaternion.from_rotation(rot * quaternion.rotation(sc.quat[1:2]))[0]
    res = classify(CASE, sc, sc.position, sc.quat, pos, quat, load)
    assert res["kind"] == "block" and res["mechanism"] == "tipping"
    assert res["collapsed"]["blocks"] == [1]
    pos, quat = sc.position.copy(), sc.quat.copy()
    pos[0] += 0.02 * load
    res = classify(CASE, sc, sc.position, sc.quat, pos, quat, load)
    assert res["kind"] == "block" and res["mechanism"] == "sliding"
    stack = blocks_to_scene([BlockSpec(size=[0.1, 0.1, 0.4], position=[0.0, 0.0, 0.2 + 0.4 * k],
                                       density=2000) for k in range(2)])
    toe = np.array([0.0, -0.05, 0.0])
    pos = toe + rot.apply(stack.position - toe)
    quat = quaternion.from_rotation(rot * quaternion.rotation(stack.quat))
    res = classify(CASE, stack, stack.position, stack.quat, pos, quat, load)
    assert res["kind"] != "block" and res["mechanism"] != "tipping"


# --- what a tilt run shows --------------------------------------------------------------------

def test_result_line_of_a_tilt_names_lambda_angle_mechanism_and_collapsed_blocks():
    s = {"status": "ok", "n_blocks": 25, "sim_time": 2.6, "loading": {"type": "tilt"},
         "collapse": {"detected": True, "angle_deg": 25.32, "load_factor": 0.4731, "n_moved": 20},
         "mechanism": {"mechanism": "overturning", "collapsed": {"n_blocks": 19}}}
    line = result_line(s)
    assert "\n" not in line
    assert line == ("result: ok; load factor 0.473 at 25.32 deg, mechanism overturning, "
                    "19 of 25 blocks collapsed; t = 2.6 s")
    s.pop("mechanism")  # no mechanism analysis: the detector's count
    assert "20 of 25 blocks collapsed" in result_line(s)


def test_table_to_lab_is_the_tilt_that_turns_gravity():
    """The lab frame drawn in final.png: gravity (0, 0, -g) seen from the tilted table is what
    dem.loading.Tilt applies, and the table's side the load points to goes down."""
    for axis, angle in (("y", 30.0), ("x", 12.0), ("-y", 40.0)):
        tilt = Tilt([0.0, 0.0, -9.81], axis, 1.0, 90.0, start_angle_deg=angle)
        g_table = tilt.gravity(np.array([0.0]))[0]
        # a vector fixed on the table (g_table) turned to the lab is the lab's gravity
        _, _, g_lab = table_to_lab(np.zeros((1, 3)), np.array([[1.0, 0, 0, 0]]),
                                   g_table[None, :], angle, tilt.axis)
        assert np.allclose(g_lab[0], [0.0, 0.0, -9.81], atol=1e-9)
        _, _, p = table_to_lab(np.zeros((1, 3)), np.array([[1.0, 0, 0, 0]]),
                               tilt.load_direction[None, :], angle, tilt.axis)
        assert p[0, 2] == pytest.approx(-np.sin(np.radians(angle)))


def _tilt_case(name, blocks, material, start, rate, snapshot=False):
    return parse_case({
        "name": name, "scene": {"blocks": blocks}, "material": material,
        "loading": {"type": "tilt", "axis": "y", **RATE, "rate": rate, "start_angle": start,
                    "start_time": 0.5, "max_angle": 45.0, "collapse": {"after": 0.2}},
        "run": {"duration": 6.0, "output_interval": 0.005, "vtk": False,
                "snapshot": snapshot}})


def test_stack_of_blocks_overturns_as_one_at_b_over_nh(tmp_path):
    """n = 4 blocks b x d x h = 0.1 x 0.05 x 0.1 m (2000 kg/m3), mu = 0.8 > b/(n h) = 0.25:
    the stack tips as one about the leeward toe at tan = b/(n h) (each upper part of k blocks
    would need b/(k h), more).  kn = 1e12 Pa/m: the base joint's elastic offset (docs/engine.md
    section 5) is de = (6 rho g b cos / (kn n h))^(1/3) = 0.0031.  The onset criterion (1 mm/s)
    fires on the elastic lean, which speeds up as the limit nears: away from it the lean is
    phi = (4/27) de^3 / delta^2 (delta = b/(n h) - tan), so the top (H = n h = 0.4 m) moves at
    H (8/27) (de/delta)^3 sec^2 x rate, 1 mm/s at delta ~ 1.6 de at 2 deg/s (measured: 1.3 de).
    The onset can be late by at most the 0.1 s (0.2 deg) the tipping takes to reach 1 mm/s.
    So lambda in [b/(n h) - 2 de, b/(n h) + 0.2 deg]."""
    n, b, h, rho = 4, 0.1, 0.1, 2000.0
    blocks = [{"size": [b, 0.05, h], "position": [0.0, 0.0, h * (k + 0.5)], "density": rho}
              for k in range(n)]
    rigid = b / (n * h)
    case = _tilt_case("stack", blocks, {"friction": 0.8, "normal_stiffness": 1e12},
                      start=np.degrees(np.arctan(rigid)) - 2.0, rate=2.0, snapshot=True)
    res = run_case(case, tmp_path, analyses=RUN_ANALYSES)
    s = res.summary
    col, mech = s["collapse"], s["mechanism"]
    assert col["detected"]
    elastic = elastic_tipping_factor(b, n * h, rho, 1e12)
    de = rigid - elastic
    assert 0.002 < de < 0.004
    upper = np.tan(np.arctan(rigid) + np.radians(0.2))
    assert rigid - 2 * de <= col["load_factor"] <= upper, (col["load_factor"], rigid, elastic)
    assert mech["kind"] == "column"
    assert mech["mechanism"] == "overturning of the whole column at its base"
    assert mech["overturning_mass_fraction"] == pytest.approx(1.0)
    assert mech["collapsed"]["blocks"] == list(range(n))
    assert mech["collapsed"]["mass_fraction"] == pytest.approx(1.0)
    assert mech["n_column_blocks"] == n and mech["joint"] == 0
    assert f"mechanism overturning of the whole column at its base, {n} of {n} blocks " \
        f"collapsed" in result_line(s)
    # the run's pictures: final.png with the table tilted, lean.png with the collapse marked
    assert (tmp_path / "final.png").stat().st_size > 0
    path = plot_lean(tmp_path)
    assert path == tmp_path / "lean.png" and path.stat().st_size > 0
    fr = np.load(tmp_path / "frames.npz")
    assert top_blocks(res.scene).tolist() == [False] * (n - 1) + [True]
    lean = lean_series(res.scene, fr["pos"], [1.0, 0.0, 0.0])
    k_on = int(np.searchsorted(fr["t"], col["onset_time_s"]))
    assert abs(lean[k_on]) < 1e-3 < lean[-1]  # at rest (elastic lean) until the collapse


def test_explicit_block_wall_slides_at_l_over_h_3(tmp_path):
    """The small-brick wall 3 bricks x 3 courses (L/H = 3, s/h = 1.5, mu = 0.81) as explicit
    blocks: the top courses slide on the bottom one (thesis Fig 3.12: L/H = 3 pure sliding;
    results/tilt size-small-3x3: sliding, 7 blocks), between the limit analysis' overturning
    0.75 and sliding 0.81 (friction on the crack raises it above the frictionless bound)."""
    case = _tilt_case("explicit-3x3", blocks_of(build_wall("small", 3, 3)),
                      {"friction": 0.81, "base_friction": 1.5}, start=33.0, rate=4.0)
    s = run_case(case, tmp_path, analyses=RUN_ANALYSES).summary
    mech = s["mechanism"]
    assert s["collapse"]["detected"] and 0.74 <= s["collapse"]["load_factor"] <= 0.83
    assert mech["kind"] == "in-plane" and mech["geometry"]["source"] == "blocks"
    assert mech["mechanism"] == "sliding" and mech["overturning_mass_fraction"] < 0.2
    assert mech["geometry"]["l_over_h"] == pytest.approx(3.0)
    assert mech["limit_analysis"]["lambda_sliding"] == pytest.approx(0.81, abs=1e-3)
    assert 0 < mech["collapsed"]["n_blocks"] < 10


def test_explicit_block_wall_overturns_at_l_over_h_0_6(tmp_path):
    """The small-brick wall 2 bricks x 10 courses (L/H = 0.6) as explicit blocks: the portion
    above the stepped crack from the leeward bottom overturns (thesis: L/H = 0.6 pure overturning
    of the portion above the main crack, at the stagger angle), above the limit analysis'
    frictionless overturning 0.465 less the 4 deg/s rate's few per cent and below sliding."""
    case = _tilt_case("explicit-2x10", blocks_of(build_wall("small", 2, 10)),
                      {"friction": 0.81, "base_friction": 1.5}, start=20.0, rate=4.0)
    s = run_case(case, tmp_path, analyses=RUN_ANALYSES).summary
    mech = s["mechanism"]
    assert s["collapse"]["detected"] and 0.44 <= s["collapse"]["load_factor"] <= 0.6
    assert mech["kind"] == "in-plane" and mech["mechanism"] == "overturning"
    assert mech["overturning_mass_fraction"] > 0.8
    assert mech["geometry"]["l_over_h"] == pytest.approx(0.6)
    assert mech["limit_analysis"]["lambda_overturning"] == pytest.approx(0.465, abs=0.002)
    assert mech["crack_angle_deg"] == pytest.approx(np.degrees(np.arctan(1.5)), abs=10.0)
    assert 0.5 < mech["collapsed"]["mass_fraction"] < 1.0
    saved = json.loads((tmp_path / "summary.json").read_text())["mechanism"]
    assert saved["crack_angle_definition"] == CRACK_ANGLE_DEFINITION


def test_a_quasi_static_mechanism_is_read_from_the_last_equilibrium_not_from_the_start():
    """The warped-bed walls of the calibration crept up to 1 cm while still in equilibrium
    (joints seating and slipping as the load turned); read from the first frame, that creep was
    counted as part of the collapse and could turn an overturning wall 'mixed'.  Here a planted
    creep (the portion above the crack slips 8 mm leeward, no rotation) comes before the
    planted overturning of that portion (0.04 rad: its top moves about 1 cm, the level the
    mechanism is read at): read from the frame at the dynamic continuation's start
    (dynamic_from_s), the mechanism is exactly the planted overturning."""
    from dem.case import load_case
    from dem.run.build import scene_from_case
    from postprocess.tilt import reference_frame, tilt_mechanism

    case = load_case("cases/tilt/in-plane/small-5x7.yaml")
    sc = scene_from_case(case)
    pos0, quat0, pos_o, quat_o, moving = _planted(sc, "overturning", angle=0.04)
    lean = np.zeros_like(pos0)
    lean[moving, 0] = 0.008
    t = np.array([0.0, 1.0, 2.0, 2.5, 2.52])
    pos = np.stack([pos0, pos0 + 0.5 * lean, pos0 + lean, pos0 + lean,
                    pos_o + lean])  # frame 3: the continuation's first (no motion yet)
    quat = np.stack([quat0, quat0, quat0, quat0, quat_o])
    frames = {"t": t, "pos": pos, "quat": quat}
    collapse = {"detected": True, "method": "quasi_static", "dynamic_from_s": 2.2}
    assert reference_frame(frames, collapse) == 2
    assert reference_frame(frames, {**collapse, "method": "constant_rate"}) == 0
    got = tilt_mechanism(case, sc, frames, {"collapse": collapse})["mechanism"]
    planted = classify(case, sc, pos0, quat0, pos_o, quat_o, [1.0, 0.0, 0.0])
    assert planted["mechanism"] == "overturning"
    assert got["mechanism"] == "overturning"
    assert got["overturning_mass_fraction"] == pytest.approx(
        planted["overturning_mass_fraction"], abs=1e-9)
    assert got["n_moving"] == planted["n_moving"]
    assert got["reference_time_s"] == 2.0 and got["frame_time_s"] == 2.52
    # the same frames read from the start: the lean is taken for sliding (what was wrong)
    from_start = tilt_mechanism(case, sc, frames, {"collapse": {**collapse,
                                                                "dynamic_from_s": None}})
    assert from_start["mechanism"]["overturning_mass_fraction"] < \
        planted["overturning_mass_fraction"] - 0.1
