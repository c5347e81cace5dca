"""Bad case files: ``dem check`` exits 2 with a message naming the field path and the line."""

from __future__ import annotations

import textwrap

import pytest
from typer.testing import CliRunner

from dem_cli.app import app

GOOD = """\
name: ok
scene:
  blocks:
    - {size: [0.2, 0.2, 0.1], position: [0.0, 0.0, 0.05], mass: 4.0}
material: {friction: 0.5}
loading: {type: shake, direction: [1, 0, 0], frequency: 2.0, amplitude: 0.01, cycles: 5}
run: {duration: 2.5, output_interval: 0.01}
"""


def check(tmp_path, text: str, name: str = "case.yaml"):
    path = tmp_path / name
    path.write_text(textwrap.dedent(text))
    result = CliRunner().invoke(app, ["check", str(path)])
    return result.exit_code, result.output, str(path)


def test_good_case_passes(tmp_path):
    code, out, _ = check(tmp_path, GOOD)
    assert code == 0, out
    assert "1 blocks" in out and "4.000 kg" in out and "bounding box" in out


@pytest.mark.parametrize(
    "edit,line,path,words",
    [
        # missing field: run.duration removed -> points at the line of 'run'
        (("duration: 2.5, ", ""), 7, "run.duration", "missing required field"),
        # negative size
        (("size: [0.2, 0.2, 0.1]", "size: [0.2, -0.2, 0.1]"), 4, "scene.blocks[0].size", "> 0"),
        # unknown key
        (("mass: 4.0}", "mass: 4.0, colour: red}"), 4, "scene.blocks[0].colour", "unknown key"),
        # wrong unit type: a string with a unit where a number is expected
        (("amplitude: 0.01", "amplitude: 10 mm"), 6, "loading.amplitude", "'10 mm'"),
        # value out of range in a tagged union (no 'shake' tag in the path)
        (("frequency: 2.0", "frequency: -2.0"), 6, "loading.frequency", "greater than 0"),
        # an unknown loading type
        (("type: shake", "type: wobble"), 6, "loading", "tilt"),
    ],
)
def test_bad_field_exits_2_naming_field_and_line(tmp_path, edit, line, path, words):
    old, new = edit
    assert old in GOOD
    code, out, file = check(tmp_path, GOOD.replace(old, new, 1))
    assert code == 2, out
    assert f"{file}:{line}: {path}:" in out
    assert words in out
    assert ".shake." not in out


def test_unit_type_error_states_the_unit(tmp_path):
    code, out, _ = check(tmp_path, GOOD.replace("frequency: 2.0", "frequency: 2 Hz"))
    assert code == 2 and "loading.frequency" in out and "Hz" in out and "plain number" in out


def test_unreadable_yaml(tmp_path):
    code, out, file = check(tmp_path, "name: x\nscene: {blocks: [\n  {size: [1, 1, 1]\n")
    assert code == 2
    assert "not valid YAML" in out and file in out


def test_yaml_that_is_not_a_mapping(tmp_path):
    code, out, _ = check(tmp_path, "- just\n- a list\n")
    assert code == 2 and "mapping" in out


def test_missing_file(tmp_path):
    result = CliRunner().invoke(app, ["check", str(tmp_path / "nope.yaml")])
    assert result.exit_code == 2 and "cannot read" in result.output


def test_duplicate_key(tmp_path):
    code, out, _ = check(tmp_path, GOOD + "name: again\n")
    assert code == 2 and "duplicate key 'name'" in out and "line 8" in out


def test_builder_field_errors(tmp_path):
    text = """\
    name: w
    scene:
      wall: {brick: medium, length: 0, courses: 5}
    material: {friction: 0.81}
    run: {duration: 1.0}
    """
    code, out, file = check(tmp_path, text)
    assert code == 2
    assert f"{file}:3: scene.wall.brick:" in out and "'small' or 'large'" in out
    assert f"{file}:3: scene.wall.length: Input should be greater than or equal to 1" in out


def test_corner_lap_larger_than_the_wall(tmp_path):
    text = """\
    name: f
    scene:
      facade:
        length: 5
        courses: 5
        left: {length: 3, connection: 0.08}
    material: {friction: 0.81}
    run: {duration: 1.0}
    """
    code, out, _ = check(tmp_path, text)
    assert code == 2 and "scene.facade" in out and "left.connection" in out and "0.05" in out


def test_empty_scene(tmp_path):
    code, out, _ = check(tmp_path, "name: e\nscene: {}\nmaterial: {friction: 0.5}\nrun: {duration: 1}\n")
    assert code == 2 and "scene: " in out and "no blocks" in out


def test_overlapping_and_floating_blocks_exit_2_naming_them(tmp_path):
    text = GOOD.replace(
        "    - {size: [0.2, 0.2, 0.1], position: [0.0, 0.0, 0.05], mass: 4.0}\n",
        "    - {size: [0.2, 0.2, 0.1], position: [0.0, 0.0, 0.05], mass: 4.0}\n"
        "    - {size: [0.2, 0.2, 0.1], position: [0.1, 0.0, 0.05], mass: 4.0}\n"
        "    - {size: [0.2, 0.2, 0.1], position: [2.0, 0.0, 0.5], mass: 4.0}\n",
    )
    code, out, _ = check(tmp_path, text)
    assert code == 2
    assert "overlap: block 0 (blocks) and block 1 (blocks) overlap by 100.000 mm" in out
    assert "floating: block 2 (blocks)" in out
    # allowed explicitly
    code, out, _ = check(tmp_path, text.replace("  blocks:\n", "  allow_floating: true\n  blocks:\n")
                         .replace("position: [0.1, 0.0, 0.05]", "position: [0.2, 0.0, 0.05]"))
    assert code == 0, out
