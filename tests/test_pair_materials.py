"""Named materials and joint constants per pair of materials (the pair material record:
dem.engine.pair; the case: dem.case.material).

* the record table: every pair takes the default, pairs with the table the base friction, the
  case's ``pairs`` override field by field; a case without materials gives the table the
  engine had before (brick-brick, brick-table, table-table);
* blocks slide on a tilted table at the closed-form acceleration g (sin theta - mu cos theta)
  of their own pair's friction (a timber block on a brick, a timber block on the table) while a
  brick on the table with the default friction sticks;
* materials reach the blocks from explicit blocks and from builder groups (the box model's
  roof beams);
* ``dem check`` refuses an unknown material name, a builder group that does not exist and a
  built-in name declared again, exit 2 with file:line: field.
"""

from __future__ import annotations

import textwrap

import numpy as np
import pytest
from typer.testing import CliRunner

from dem.case import parse_case
from dem_cli.app import app
from dem.engine.containers import Model
from dem.engine.pair import PAIR_FIELDS, PairMaterial
from dem.run.build import joint_law, scene_from_case
from dem.scene import blocks_to_scene
from engine_helpers import G

CUBE = [0.1, 0.1, 0.1]


def _case(blocks, material, **scene):
    return parse_case({"name": "pairs", "scene": {"blocks": blocks, **scene},
                       "material": material, "run": {"duration": 1.0}})


def _model(case):
    return Model.from_scene(scene_from_case(case, check=False), joint_law(case.material))


def test_record_table_defaults_and_overrides():
    case = _case(
        [{"size": CUBE, "position": [0, 0, 0.05], "mass": 1.0},
         {"size": CUBE, "position": [0.3, 0, 0.05], "mass": 1.0, "material": "timber"},
         {"size": CUBE, "position": [0.6, 0, 0.05], "mass": 1.0, "material": "steel"}],
        {"friction": 0.81, "base_friction": 1.5, "normal_stiffness": 5e9, "damping": 0.5,
         "materials": ["timber", "steel"],
         "pairs": [{"between": ["timber", "brick"], "friction": 0.5},
                   {"between": ["steel", "timber"], "friction": 0.4, "normal_stiffness": 1e9},
                   {"between": ["timber", "table"], "friction": 0.6},
                   {"between": ["brick", "timber"], "damping": 0.2}]})
    m = _model(case)
    assert m.material_names == ["brick", "timber", "steel", "table"]
    assert m.material[:3].tolist() == [0, 1, 2] and m.material[3] == 3
    rec = m.pair_material
    assert rec("brick", "brick") == PairMaterial(0.81, 5e9, 2e9, 0.5)
    assert rec("steel", "steel") == PairMaterial(0.81, 5e9, 2e9, 0.5)
    assert rec("brick", "table") == rec("steel", "table") == PairMaterial(1.5, 5e9, 2e9, 0.5)
    assert rec("table", "table").mu == 0.0
    # later entries win field by field: [brick, timber] keeps the 0.5 of [timber, brick]
    assert rec("timber", "brick") == rec("brick", "timber") == PairMaterial(0.5, 5e9, 2e9, 0.2)
    # a pair's own kn: its ks is 0.4 of it (the material gives no shear_stiffness)
    assert rec("timber", "steel") == PairMaterial(0.4, 1e9, 4e8, 0.5)
    assert rec("timber", "table").mu == 0.6
    assert np.array_equal(m.mat_pair_np, np.swapaxes(m.mat_pair_np, 0, 1))
    # the record's fields by name, in the row's order
    assert PAIR_FIELDS == ("mu", "kn", "ks", "zeta", "law", "d_max", "d_lim", "damping",
                           "beta")
    # the step is made for the stiffest pair
    assert m.stiffest() == (5e9, 2e9, 0.5)


def test_without_materials_the_table_is_the_one_before():
    """Blocks without a material are 'brick' (index 0), the table index 1: mat_pair[..., :4] is
    the (mu, kn, ks, zeta) table Model.from_scene built before named materials, the law slots
    zero (linear): the same numbers reach the same operations."""
    case = _case([{"size": CUBE, "position": [0, 0, 0.05], "mass": 1.0}],
                 {"friction": 0.7, "base_friction": 0.9, "shear_stiffness": 1e9})
    m = _model(case)
    old = np.zeros((2, 2, 4))
    old[0, 0] = (0.7, 5e9, 1e9, 0.5)
    old[0, 1] = old[1, 0] = (0.9, 5e9, 1e9, 0.5)
    old[1, 1] = (0.0, 5e9, 1e9, 0.5)
    assert m.material.tolist() == [0, 1]
    assert np.array_equal(m.mat_pair[..., :4], old)
    assert not m.mat_pair[..., 4:].any()


def test_blocks_slide_with_their_own_pair_friction():
    """Table tilted by 20 deg (gravity turned about y: tan 20 = 0.364).  A timber block on a
    brick (pair friction 0.2) and a timber block on the table (pair 0.3) slide at
    a = g (sin 20 - mu cos 20) = 1.511 and 0.588 m/s^2; the brick under the first, on the table
    with the default friction 0.81, sticks.  The acceleration is measured as the change of
    velocity from 0.1 to 0.2 s: the penalty shear spring lets a block gain ~3e-4 m/s before it
    slips (its elastic loading, ~0.3 ms), a constant offset of the velocity that the difference
    removes (it would add ~0.6 % to the distance slid).  Tolerance 0.2 % (measured 0.03 % on the
    brick, whose top tilts a little as the load moves over it, 1e-8 on the table; a pair's
    friction off by 0.01 moves a by 6 % and 16 %).  The brick's base: within 1e-5 m and
    1e-4 m/s of rest (its elastic shear displacement is below 1e-6 m; slipping at a timber
    pair's friction it would move at ~0.1 m/s; measured 9e-7 m, 1e-5 m/s)."""
    from dem.engine import Simulation
    from dem.run.build import step_options

    theta = np.radians(20.0)
    case = _case(
        [{"size": CUBE, "position": [0, 0, 0.05], "mass": 1.0},
         {"size": CUBE, "position": [0, 0, 0.15], "mass": 1.0, "material": "timber"},
         {"size": CUBE, "position": [-0.4, 0, 0.05], "mass": 1.0, "material": "timber"}],
        {"friction": 0.81, "materials": ["timber"],
         "pairs": [{"between": ["timber", "brick"], "friction": 0.2},
                   {"between": ["timber", "table"], "friction": 0.3}]})
    g = G * np.array([np.sin(theta), 0.0, -np.cos(theta)])
    sim = Simulation(blocks_to_scene(case.scene.blocks), joint_law(case.material),
                     step_options(case.solver), gravity=g)
    loads = lambda t: (np.tile(g, (len(t), 1)), np.zeros((len(t), 3)))  # noqa: E731
    sim.advance(int(round(0.1 / sim.dt)), loads)
    t1, v1 = sim.t, sim.state.vel[:3, 0].copy()
    sim.advance(int(round(0.1 / sim.dt)), loads)
    t2, v2 = sim.t, sim.state.vel[:3, 0].copy()
    a = (v2 - v1) / (t2 - t1)
    expect = lambda mu: G * (np.sin(theta) - mu * np.cos(theta))  # noqa: E731
    # the brick under the sliding block rocks a little as the load moves over it (its centre
    # moves); its base does not slide
    r = -sim.state.rot[0] @ np.array([0.0, 0.0, 0.05])
    base_x = sim.state.pos[0, 0] + r[0]
    base_v = (sim.state.vel[0] + np.cross(sim.state.omega[0], r))[0]
    assert abs(base_v) < 1e-4 and abs(base_x) < 1e-5, (base_x, base_v)
    assert abs((a[1] - a[0]) / expect(0.2) - 1) < 2e-3, (a, expect(0.2))
    assert abs(a[2] / expect(0.3) - 1) < 2e-3, (a, expect(0.3))


def test_box_model_roof_beams_take_their_material():
    case = parse_case({"name": "m2", "scene": {"box_model": {
        "model": "II", "materials": {"roof-beam": "timber", "roof-mass": "steel",
                                     "corner-mass": "steel"}}},
        "material": {"friction": 0.81, "materials": ["timber", "steel"],
                     "pairs": [{"between": ["timber", "brick"], "friction": 0.5}]},
        "run": {"duration": 1.0}})
    scene = scene_from_case(case)
    names = np.array(scene.material_names)[scene.material]
    groups = np.array(scene.group_names)[scene.group]
    assert set(names[groups == "roof-beam"]) == {"timber"}
    assert set(names[np.isin(groups, ["roof-mass", "corner-mass"])]) == {"steel"}
    assert set(names[np.isin(groups, ["L1", "L2", "T1", "T2"])]) == {"brick"}
    m = Model.from_scene(scene, joint_law(case.material))
    assert m.pair_material("timber", "brick").mu == 0.5
    assert m.pair_material("timber", "steel").mu == 0.81


GOOD = """\
name: pairs
scene:
  blocks:
    - {size: [0.2, 0.2, 0.1], position: [0.0, 0.0, 0.05], mass: 4.0, material: timber}
  box_model: {model: II, origin: [2, 0, 0], materials: {roof-beam: timber}}
material:
  friction: 0.81
  materials: [timber, steel]
  pairs:
    - between: [timber, brick]
      friction: 0.5
run: {duration: 1.0}
"""


def _check(tmp_path, text):
    path = tmp_path / "case.yaml"
    path.write_text(textwrap.dedent(text))
    result = CliRunner().invoke(app, ["check", str(path)])
    return result.exit_code, result.output, str(path)


def test_good_case_passes(tmp_path):
    code, out, _ = _check(tmp_path, GOOD)
    assert code == 0, out


@pytest.mark.parametrize("old, new, line, field, words", [
    ("material: timber}", "material: timbr}", 4, "scene.blocks[0].material",
     "unknown material 'timbr'"),
    ("between: [timber, brick]", "between: [timber, brik]", 10, "material.pairs[0].between[1]",
     "unknown material 'brik'"),
    ("{roof-beam: timber}", "{roof-beam: oak}", 5, "scene.box_model.materials.roof-beam",
     "unknown material 'oak'"),
    ("{roof-beam: timber}", "{roof-beams: timber}", 5, "scene.box_model.materials.roof-beams",
     "no group 'roof-beams'"),
    ("[timber, steel]", "[timber, table]", 8, "material.materials[1]", "'table' is built in"),
])
def test_unknown_names_exit_2_with_file_line_and_field(tmp_path, old, new, line, field, words):
    code, out, path = _check(tmp_path, GOOD.replace(old, new, 1))
    assert code == 2, out
    assert f"{path}:{line}: {field}: " in out, out
    assert words in out, out


def test_a_case_without_the_new_fields_dumps_as_before():
    """The new fields stay out of a case's dump while they hold their defaults: case.json,
    summary.json's material and the studies' resume fingerprints and restart points (all
    case.model_dump_json) of every case written before them are unchanged; the dump of a case
    that uses them reads back to the same case."""
    import json

    from dem.case import Case

    old = _case([{"size": CUBE, "position": [0, 0, 0.05], "mass": 1.0}], {"friction": 0.6})
    dump = json.loads(old.model_dump_json())
    assert set(dump["material"]) == {"friction", "normal_stiffness", "shear_stiffness",
                                     "damping", "base_friction"}
    assert "material" not in dump["scene"]["blocks"][0]
    box = parse_case({"name": "m2", "scene": {"box_model": {"model": "II"}},
                      "material": {"friction": 0.81}, "run": {"duration": 1.0}})
    assert "materials" not in json.loads(box.model_dump_json())["scene"]["box_model"]
    new = parse_case({"name": "m2", "scene": {"box_model": {
        "model": "II", "materials": {"roof-beam": "timber"}}},
        "material": {"friction": 0.81, "materials": ["timber"], "normal_law": "hyperbolic",
                     "max_closure": 1e-4, "closure_limit": 0.7,
                     "pairs": [{"between": ["timber", "brick"], "friction": 0.5}]},
        "run": {"duration": 1.0}})
    assert Case.model_validate(json.loads(new.model_dump_json())) == new
