"""As-built free play (imperfections.corner_gap, head_gap, plumb; scene.box_model.corners:
unbonded is in test_builders.py): the geometry as drawn, the defaults that change nothing,
the seeded streams, the errors, and two closed forms run through the engine.

Closed forms:

* a brick on a table tilted by theta about y, tan(theta) > mu, slides with the Coulomb
  acceleration a = g (sin theta - mu cos theta) (tests/test_engine_physics.py checks it within
  2 %), so it meets a fixed neighbour a head gap g_h away at t* = sqrt(2 g_h / a) and then rests
  against it, pressed by m a: the head joint closes by m a / (kn A_head) = 0.1 micrometre;
* a column of n bricks each offset by delta from the one below (a lean) tips as one about its
  leeward base edge when tan(theta) = (t/2 - e) / h_cg, e = (n - 1) delta / 2 the centre of
  mass' offset towards the load and h_cg = n h / 2 (each upper part of k bricks would need
  (t - (k + 1) delta) / (k h), more); with kn = 1e12 Pa/m the base joint's elastic offset is
  de = (6 rho g t cos / (kn n h))^(1/3) = 0.0033 and the onset criterion fires within
  [rigid - 2 de, rigid + 0.2 deg] (the bounds and their reasons: tests/test_tilt_mechanisms.py,
  test_stack_of_blocks_overturns_as_one_at_b_over_nh).
"""

from __future__ import annotations

import math

import numpy as np
import pytest

from dem.builders import build_box_model, build_facade, build_wall, check_scene
from dem.builders import as_built as ab
from dem.case import CaseError, parse_case
from dem.imperfections import (ImperfectionParams, apply_as_built, as_built_streams,
                               draw_gaps, streams)
from dem.run.build import as_built_record, scene_from_case

G = 9.81
SMALL_L, SMALL_T, SMALL_H = 0.105, 0.050, 0.035


def case_of(scene: dict, imperfections: dict | None = None, **extra):
    data = {"name": "as-built", "scene": scene, "material": {"friction": 0.81},
            "run": {"duration": 1.0}, **extra}
    if imperfections is not None:
        data["imperfections"] = imperfections
    return parse_case(data)


def lo_hi(s):
    return s.position - 0.5 * s.size, s.position + 0.5 * s.size


def same_scene(a, b) -> bool:
    return all(np.array_equal(getattr(a, f), getattr(b, f))
               for f in ("size", "position", "quat", "mass", "face_offset", "arris"))


# ------------------------------------------------------------------ defaults and streams
@pytest.mark.parametrize("scene", [
    {"box_model": {"model": "II"}},
    {"facade": {"length": 5, "courses": 5, "left": {"length": 3, "connection": "poor"},
                "right": {"length": 3}}},
    {"wall": {"length": 5, "courses": 5}},
])
def test_zero_as_built_fields_build_todays_scene_bit_for_bit(scene):
    """Fields given at zero are the fields left out; with today's imperfections (sizes, faces)
    switched on as well, the same seed gives the same specimen whether or not the as-built
    fields are named."""
    zero = {"corner_gap": {"mean": 0.0, "scatter": 0.0}, "head_gap": {"mean": 0.0},
            "plumb": {"sigma": [0.0, 0.0], "lean": [0.0, 0.0]}}
    assert same_scene(scene_from_case(case_of(scene)), scene_from_case(case_of(scene, zero)))
    old = {"bed_unevenness": 1e-4, "size_scatter": [2e-4, 1e-4, 1e-4], "seed": 4}
    assert same_scene(scene_from_case(case_of(scene, old)),
                      scene_from_case(case_of(scene, {**old, **zero})))
    assert "corner_gap" not in case_of(scene, zero).model_dump()["imperfections"]


def test_as_built_streams_leave_the_size_and_face_streams_as_they_were():
    """The as-built fields draw from the seed's third child: the sizes and faces of a specimen
    do not change when they are switched on (a committed study's specimens are rebuilt as they
    were), and each as-built field has a stream of its own."""
    for seed in (0, 7):
        a, b = streams(seed)
        c, d = (np.random.default_rng(s) for s in np.random.SeedSequence(seed).spawn(2))
        assert np.array_equal(a.random(5), c.random(5)) and np.array_equal(b.random(5), d.random(5))
    r = [g.random(3) for g in as_built_streams(3)]
    assert not np.allclose(r[0], r[1]) and not np.allclose(r[1], r[2])
    scene = {"box_model": {"model": "II"}}
    old = {"bed_unevenness": 1e-4, "size_scatter": [2e-4, 1e-4, 1e-4], "seed": 4}
    ref = scene_from_case(case_of(scene, old))
    for extra in ({"plumb": {"sigma": [3e-4, 3e-4]}}, {"corner_gap": {"mean": 1e-3, "scatter": 5e-4}},
                  {"head_gap": {"mean": 2e-4, "scatter": 1e-4}}):
        s = scene_from_case(case_of(scene, {**old, **extra}))
        assert np.array_equal(s.face_offset, ref.face_offset)
        if "plumb" in extra:  # plumb moves whole courses: sizes as drawn
            assert np.array_equal(s.size, ref.size)
    # corner gaps drawn the same with or without head gaps and plumb
    c1 = as_built_record(case_of(scene, {"corner_gap": {"mean": 1e-3, "scatter": 5e-4}}))
    c2 = as_built_record(case_of(scene, {"corner_gap": {"mean": 1e-3, "scatter": 5e-4},
                                         "head_gap": {"mean": 2e-4, "scatter": 1e-4},
                                         "plumb": {"sigma": [3e-4, 0.0]}}))
    assert c1["corner_gap"] == c2["corner_gap"]


def test_gaps_are_never_negative_and_have_the_asked_mean():
    """mean + scatter z, z truncated at -3 and at -mean / scatter: never negative; at mean =
    scatter the truncation at -1 sigma raises the mean by scatter phi(1) / (1 - Phi(-1))."""
    from scipy.stats import norm

    g = draw_gaps(np.random.default_rng(0), 1e-3, 1e-3, 20000)
    assert g.min() >= 0.0 and g.max() <= 4e-3
    expected = 1e-3 + 1e-3 * (norm.pdf(-1) - norm.pdf(3)) / (norm.cdf(3) - norm.cdf(-1))
    assert g.mean() == pytest.approx(expected, rel=3 * g.std() / np.sqrt(g.size) / expected)
    assert np.array_equal(draw_gaps(None, 5e-4, 0.0, 4), np.full(4, 5e-4))


# ------------------------------------------------------------------ geometry as drawn
def test_head_gaps_open_every_joint_and_keep_the_bond():
    """Each head joint of a 5 x 5 wall opens by its drawn gap, half taken off each brick: the
    joint's centre stays at its nominal place (no drift along the course), the course's ends
    stay, and the scene is sound (no overlap, nothing floating)."""
    ref = build_wall("small", 5, 5)
    joints = ab.head_joints(ref)
    assert len(joints) == 3 * 4 + 2 * 5  # 3 courses of 5 bricks, 2 of [half, 4, half]
    params = ImperfectionParams(head_gap=(5e-4, 2e-4), seed=1)
    s, drawn = apply_as_built(ref, params, as_built_streams(1), SMALL_H, 0, 0.15 * SMALL_L)
    lo0, hi0 = lo_hi(ref)
    lo, hi = lo_hi(s)
    for (b, c, ax), g in zip(joints, drawn["head_gaps"]):
        assert lo[c, ax] - hi[b, ax] == pytest.approx(g, abs=1e-12)
        assert 0.5 * (lo[c, ax] + hi[b, ax]) == pytest.approx(hi0[b, ax], abs=1e-12)
    assert lo[:, 0].min() == lo0[:, 0].min() and hi[:, 0].max() == hi0[:, 0].max()
    assert np.allclose(s.mass / ref.mass, s.size[:, 0] / ref.size[:, 0])
    rep = check_scene(s, overlap_tolerance=1e-9)
    assert rep.ok and not rep.warnings, rep.format()


@pytest.mark.parametrize("corners", ["interlocked", "unbonded"])
def test_corner_gaps_set_back_the_butting_bricks_of_every_corner_and_course(corners):
    """Model II: one butting end per corner and course (4 x 9); each stands its drawn gap
    further from the through wall's face than the layout left it (2.5 mm or flush); nothing
    else moves."""
    ref = build_box_model("II", corners=corners)
    ends = ab.corner_ends(ref, 0.15 * SMALL_L)
    assert len(ends) == 4 * 9
    params = ImperfectionParams(corner_gap=(1e-3, 5e-4), seed=2)
    s, drawn = apply_as_built(ref, params, as_built_streams(2), SMALL_H, 0, 0.15 * SMALL_L)
    g = drawn["corner_gaps"]
    assert g.min() >= 0 and len(g) == 36
    lo0, hi0 = lo_hi(ref)
    lo, hi = lo_hi(s)
    moved = np.zeros(ref.n_blocks, bool)
    for (b, ax, side), x in zip(ends, g):
        face0, face = (hi0[b, ax], hi[b, ax]) if side > 0 else (lo0[b, ax], lo[b, ax])
        assert face0 - face == pytest.approx(side * x, abs=1e-12)
        moved[b] = True
        # the butting brick's wall runs along ax; the through wall's bricks along the other axis
        assert ref.size[b, ax] > ref.size[b, 1 - ax]
    assert np.array_equal(lo[~moved], lo0[~moved]) and np.array_equal(hi[~moved], hi0[~moved])
    rep = check_scene(s, overlap_tolerance=1e-9)
    assert rep.ok and not rep.warnings, rep.format()


def test_facade_corners_are_found_for_every_connection():
    """A facade with wings: one butting end per corner and course, whichever wall runs
    through (facade in even courses, wings in odd ones; unbonded: the facade in every one)."""
    for conn in ("poor", "good", "strong", "unbonded"):
        s = build_facade("small", 5, 6, left={"length": 3, "connection": conn},
                         right={"length": 3, "connection": conn})
        ends = ab.corner_ends(s, 0.15 * SMALL_L)
        assert len(ends) == 2 * 6, conn
        names = [s.group_names[s.group[b]] for b, _, _ in ends]
        for (b, _, _), name in zip(ends, names):
            assert (name == "facade") == (s.course[b] % 2 == 1 and conn != "unbonded")


def test_plumb_moves_whole_courses_by_the_walk_and_the_lean():
    """Course k moves by sum of its steps plus k h tan(lean), turned by the builder's yaw; the
    roof moves with the top course; sizes are unchanged."""
    ref = build_box_model("II", yaw=90)
    params = ImperfectionParams(plumb_sigma=(3e-4, 1e-4), plumb_lean=(0.2, -0.1), seed=5)
    s, drawn = apply_as_built(ref, params, as_built_streams(5), SMALL_H, 90, 0.15 * SMALL_L)
    off = drawn["offsets"]
    steps = np.diff(off - np.arange(9)[:, None] * SMALL_H * np.tan(np.radians([0.2, -0.1])),
                    axis=0)
    assert np.all(np.abs(steps) <= 3 * np.array([3e-4, 1e-4]) + 1e-15)
    assert off[0].tolist() == [0.0, 0.0]
    d = s.position - ref.position
    for k in range(9):
        sel = ref.course == k
        # yaw 90: the builder's x is the table's y, its y the table's -x
        assert np.allclose(d[sel, 0], -off[k, 1], atol=1e-15)
        assert np.allclose(d[sel, 1], off[k, 0], atol=1e-15)
    assert np.allclose(d[ref.course < 0, :2], [-off[-1, 1], off[-1, 0]], atol=1e-15)
    assert np.array_equal(s.size, ref.size) and np.all(d[:, 2] == 0)
    assert check_scene(s, overlap_tolerance=1e-9).ok


def test_summary_block_records_what_was_drawn():
    imp = {"corner_gap": {"mean": 1e-3, "scatter": 5e-4}, "head_gap": {"mean": 2e-4},
           "plumb": {"sigma": [0.0, 3e-4], "lean": [0.0, 0.1]}, "seed": 1}
    rec = as_built_record(case_of({"box_model": {"model": "II"}}, imp))
    assert rec["corner_gap"]["n_joints"] == 36 and rec["corner_gap"]["n_open"] == 36
    assert rec["head_gap"]["n_joints"] == 162 and rec["head_gap"]["largest_m"] == 2e-4
    assert rec["plumb"]["top_offset_m"][1] == pytest.approx(
        8 * SMALL_H * math.tan(math.radians(0.1)), abs=8 * 3 * 3e-4)
    from dem.units import summary_units

    assert "?" not in summary_units({"imperfections": {"as_built": rec}}).values()


# ------------------------------------------------------------------ bad input
@pytest.mark.parametrize("imp,field", [
    ({"corner_gap": {"mean": -1e-3}}, "imperfections.corner_gap.mean"),
    ({"head_gap": {"scatter": -1e-4}}, "imperfections.head_gap.scatter"),
    ({"corner_gap": {"mean": 0.02}}, "imperfections.corner_gap"),
    ({"head_gap": {"mean": 5e-3, "scatter": 2e-3}}, "imperfections.head_gap"),
    ({"plumb": {"sigma": [-1e-4, 0.0]}}, "imperfections.plumb.sigma"),
    ({"plumb": {"sigma": [0.0, 5e-3]}}, "imperfections.plumb.sigma.1"),
    ({"plumb": {"lean": [0.0, 10.0]}}, "imperfections.plumb.lean"),
])
def test_bad_as_built_input_names_the_field(imp, field, tmp_path):
    import yaml
    from typer.testing import CliRunner

    from dem_cli.app import app

    f = tmp_path / "c.yaml"
    f.write_text(yaml.safe_dump({"name": "c", "scene": {"box_model": {"model": "II"}},
                                 "material": {"friction": 0.81}, "run": {"duration": 1.0},
                                 "imperfections": imp}))
    res = CliRunner().invoke(app, ["check", str(f)])
    assert res.exit_code == 2 and field in res.output, res.output


def test_as_built_fields_need_builder_bricks():
    with pytest.raises(CaseError, match="imperfections.head_gap.*scene.wall"):
        parse_case({"name": "c", "scene": {"blocks": [{"size": [0.1, 0.05, 0.035],
                                                "position": [0, 0, 0.0175], "mass": 0.3}]},
            "material": {"friction": 0.81}, "run": {"duration": 1.0},
            "imperfections": {"head_gap": {"mean": 1e-4}}})


# ------------------------------------------------------------------ closed forms
def test_a_brick_with_a_head_gap_slides_the_gap_then_rests_on_its_neighbour():
    """Two small bricks on the table with a 2 mm head joint, the +x one fixed, gravity tilted
    45 deg towards +x, mu = 0.5: the free brick moves a t^2 / 2 until it has slid the gap, at
    t* = sqrt(2 g_h / a) (within 2 %, the Coulomb rate's tolerance in test_engine_physics), then
    rests against its neighbour, g_h from where it started to within 1 micrometre (the joints'
    elastic offsets: 0.13 um head compression, 0.11 um bed shear)."""
    from engine_helpers import constant_loads, record

    from dem.engine import Simulation
    from dem.run.build import joint_law, step_options

    gap, mu, theta = 2e-3, 0.5, math.radians(45.0)
    ref = build_wall("small", 2, 1)
    params = ImperfectionParams(head_gap=(gap, 0.0))
    scene, drawn = apply_as_built(ref, params, as_built_streams(0), SMALL_H, 0, 0.15 * SMALL_L)
    assert drawn["head_gaps"].tolist() == [gap]
    scene.fixed[1] = True
    case = case_of({"wall": {"length": 2, "courses": 1}})
    case.material.friction = mu
    g = (G * math.sin(theta), 0.0, -G * math.cos(theta))
    sim = Simulation(scene, joint_law(case.material), step_options(case.solver), gravity=g)
    t, pos, _, _ = record(sim, constant_loads(g), 0.15, 0.0005)
    x = pos[:, 0, 0] - pos[0, 0, 0]
    a = G * (math.sin(theta) - mu * math.cos(theta))
    t_star = math.sqrt(2 * gap / a)
    k = int(np.argmax(x > gap - 1e-6))
    assert t[k] == pytest.approx(t_star, rel=0.02)
    free = (t > 0.02) & (t < 0.8 * t_star)
    accel = 2.0 * np.polyfit(t[free], x[free], 2)[0]
    assert accel == pytest.approx(a, rel=0.02)
    assert abs(x[-1] - gap) < 1e-6
    assert np.abs(x[t > t_star + 0.05] - gap).max() < 1e-5  # it stays there


def test_a_column_built_out_of_plumb_tips_at_its_leaning_centre_of_mass(tmp_path):
    """A one-brick column of 4 courses (the builder's wall of length 1: whole bricks and pairs
    of half bricks) leaning out of plane by delta = 2 mm per course towards the load (lean
    atan(delta / h)), tilted about x: it tips as one at tan = (t/2 - 1.5 delta) / (2 h) =
    0.314 where the plumb column tips at (t/2) / (2 h) = 0.357 (module docstring)."""
    from dem_cli.commands.run import RUN_ANALYSES
    from dem.run import run_case
    from postprocess.limit_analysis import elastic_tipping_factor

    n, delta = 4, 2e-3
    lean = -math.degrees(math.atan(delta / SMALL_H))  # top towards -y, the downhill side
    rigid = (SMALL_T / 2 - (n - 1) * delta / 2) / (n * SMALL_H / 2)
    assert (SMALL_T - 3 * delta) / (3 * SMALL_H) > rigid  # the base joint governs
    case = parse_case({
        "name": "leaning-column", "scene": {"wall": {"length": 1, "courses": n}},
        "material": {"friction": 0.81, "base_friction": 1.5, "normal_stiffness": 1e12},
        "imperfections": {"plumb": {"lean": [0.0, lean]}},
        "loading": {"type": "tilt", "axis": "x", "rate": 2.0,
                    "start_angle": math.degrees(math.atan(rigid)) - 2.0, "start_time": 0.2,
                    "max_angle": 45.0, "collapse": {"after": 0.2}},
        "run": {"duration": 3.0, "output_interval": 0.005, "vtk": False, "snapshot": False}})
    s = scene_from_case(case)
    top = s.course == n - 1
    assert s.position[top, 1] == pytest.approx(-(n - 1) * delta, abs=1e-12)
    res = run_case(case, tmp_path, analyses=RUN_ANALYSES)
    col = res.summary["collapse"]
    assert col["detected"]
    rho = 0.336 / (SMALL_L * SMALL_T * SMALL_H)
    de = (SMALL_T / (n * SMALL_H)) - elastic_tipping_factor(SMALL_T, n * SMALL_H, rho, 1e12)
    assert 0.002 < de < 0.005
    upper = math.tan(math.atan(rigid) + math.radians(0.2))
    assert rigid - 2 * de <= col["load_factor"] <= upper, (col["load_factor"], rigid, de)


# ------------------------------------------------------------------ Chapter 3 invariants
#: the upper ends of the documented ranges (docs/imperfections.md, "As built")
HEAD_GAP = {"mean": 5e-4, "scatter": 3e-4}
PLUMB = {"sigma": [5e-4, 5e-4], "lean": [0.4, 0.4]}
FEATURES = {"head_gap": {"head_gap": HEAD_GAP}, "plumb": {"plumb": PLUMB},
            "both": {"head_gap": HEAD_GAP, "plumb": PLUMB, "corner_gap": {"mean": 2e-3,
                                                                          "scatter": 1e-3}}}


def _tilt(name, length, courses, imp, start, tmp_path):
    from dem_cli.commands.run import RUN_ANALYSES
    from dem.run import run_case

    case = parse_case({
        "name": name, "scene": {"wall": {"length": length, "courses": courses}},
        "material": {"friction": 0.81, "base_friction": 1.5},
        "imperfections": {**imp, "seed": 1},
        "loading": {"type": "tilt", "axis": "y", "rate": 4.0, "start_angle": start,
                    "start_time": 0.5, "max_angle": 45.0, "collapse": {"after": 0.2}},
        "run": {"duration": 6.0, "output_interval": 0.005, "vtk": False, "snapshot": False}})
    return run_case(case, tmp_path, analyses=RUN_ANALYSES).summary


@pytest.mark.parametrize("feature", [pytest.param("head_gap", marks=pytest.mark.slow),
                                     pytest.param("plumb", marks=pytest.mark.slow), "both"])
def test_a_5x5_wall_as_built_still_slides_at_mu(feature, tmp_path):
    """The in-plane 5 x 5 small-brick wall (L/H = 3, s/h = 1.5, mu = 0.81) slides at lambda =
    mu (results/tilt: 0.812 perfect, 0.812 calibrated): with open head joints and courses out of
    plumb at the top of their documented ranges it still slides, within 3 % of mu (a single
    wall has no corners: corner_gap draws nothing there, which 'both' checks).  The features one
    by one are behind the slow marker (~20 s each), all three together run by default."""
    s = _tilt(f"5x5-{feature}", 5, 5, FEATURES[feature], 36.0, tmp_path)
    assert s["collapse"]["detected"]
    assert s["collapse"]["load_factor"] == pytest.approx(0.81, rel=0.03)
    assert s["mechanism"]["mechanism"] == "sliding"
    ab_rec = s["imperfections"]["as_built"]
    if feature == "both":
        assert ab_rec["corner_gap"]["n_joints"] == 0


@pytest.mark.slow
@pytest.mark.parametrize("feature", list(FEATURES))
def test_the_in_plane_sequence_against_l_over_h_is_kept(feature, tmp_path):
    """Thesis Fig 3.12 and results/tilt: L/H = 3 slides (3 x 3, lambda in [0.75, 0.83], the
    bounds of tests/test_tilt_mechanisms.py), L/H = 0.6 overturns (2 x 10, lambda in [0.44,
    0.6]), with each as-built feature at the top of its range."""
    s = _tilt(f"3x3-{feature}", 3, 3, FEATURES[feature], 33.0, tmp_path / "a")
    assert s["collapse"]["detected"] and 0.74 <= s["collapse"]["load_factor"] <= 0.83
    assert s["mechanism"]["mechanism"] == "sliding"
    s = _tilt(f"2x10-{feature}", 2, 10, FEATURES[feature], 20.0, tmp_path / "b")
    assert s["collapse"]["detected"] and 0.44 <= s["collapse"]["load_factor"] <= 0.6
    assert s["mechanism"]["mechanism"] == "overturning"


def test_size_deviations_are_not_counted_from_the_gaps():
    """With size scatter and gaps, `dem check`'s largest size deviation is the scatter's (at
    most 3 sigma_L), not the bricks the gaps shortened."""
    from dem.validate import check_case

    imp = {"size_scatter": [3e-4, 2e-4, 1e-4], "corner_gap": {"mean": 2e-3, "scatter": 1e-3},
           "head_gap": {"mean": 5e-4, "scatter": 3e-4}, "seed": 3}
    out = check_case(case_of({"box_model": {"model": "II"}}, imp))
    assert out.ok, out.errors
    assert out.imperfections["sizes"]["largest_deviation_m"] <= 3 * 3e-4 + 1e-12
    assert out.imperfections["as_built"]["corner_gap"]["largest_m"] > 3 * 3e-4
