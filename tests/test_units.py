"""Units on every number: summary.json ``units``, frames.npz and instruments.npz
``units`` (dem/units.py), on the runs of tests/view_runs.py; and the units said are the ones the
numbers are in (checked against quantities computed here from the case: the time step against
the simulated time, the block's rest height, the table angle)."""

from __future__ import annotations

import json

import numpy as np
import pytest

from dem.units import (FRAMES_UNITS, INSTRUMENTS_UNITS, npz_units, numeric_paths,
                       summary_units, unit_of)


@pytest.mark.parametrize("kind", ["tilt", "shake"])
def test_every_number_of_summary_json_has_a_unit(view_runs, kind):
    s = json.loads((view_runs[kind] / "summary.json").read_text())
    units = s["units"]
    paths = numeric_paths(s)
    assert paths and set(paths) == set(units)            # every number, and only numbers
    assert [p for p, u in units.items() if u == "?"] == []
    for key, unit in (("dt", "s"), ("sim_time", "s"), ("skin", "m"), ("wall_seconds", "s"),
                      ("energy.kinetic", "J"), ("energy.work_gravity", "J"),
                      ("max_penetration_m", "m"), ("n_blocks", "-")):
        assert units[key] == unit, key


@pytest.mark.parametrize("kind", ["tilt", "shake"])
def test_frames_npz_names_the_unit_of_every_array(view_runs, kind):
    with np.load(view_runs[kind] / "frames.npz") as z:
        units = dict(z["units"])
        keys = [k for k in z.files if k != "units"]
        t, pos = z["t"], z["pos"]
        tilt = z["tilt_angle"] if "tilt_angle" in z.files else None
    assert set(units) == set(keys) and "?" not in units.values()
    assert (units["t"], units["pos"], units["quat"], units["vel"], units["omega"]) == \
        ("s", "m", "-", "m/s", "rad/s")
    s = json.loads((view_runs[kind] / "summary.json").read_text())
    # the units are the numbers' units: the last frame is at most a few steps after sim_time
    # (both s), the block (0.1 m high) rests with its centre 0.05 m above the table (m)
    assert abs(t[-1] - s["sim_time"]) <= 3 * s["dt"] + s["output_interval"]
    assert pos[0, 0, 2] == pytest.approx(0.05, abs=1e-4)
    if tilt is not None:
        assert units["tilt_angle"] == "deg"
        # lambda = tan(angle in degrees): the table reached the collapse angle of the run
        assert tilt.max() >= s["collapse"]["angle_deg"] - 1e-9
        assert np.tan(np.radians(s["collapse"]["angle_deg"])) == \
            pytest.approx(s["collapse"]["load_factor"], rel=1e-12)


def test_instruments_npz_units_cover_what_the_recorder_writes():
    """The instrument recorder's arrays (dem.instruments) on a one-block scene: every key has
    its unit in the table, the keys of dem/instruments.py's docstring as it says them."""
    from dem.case import parse_case
    from dem.instruments import Instrument, InstrumentRecorder
    from dem.run.build import scene_from_case

    scene = scene_from_case(parse_case({
        "name": "one", "scene": {"blocks": [{"size": [0.2, 0.2, 0.1],
                                             "position": [0, 0, 0.05], "mass": 4.0}]},
        "material": {"friction": 0.5}, "loading": {"type": "none"},
        "run": {"duration": 0.1}}), check=False)
    rec = InstrumentRecorder([Instrument("a", 0, np.array([0.1, 0.0, 0.0]),
                                         np.array([1.0, 0.0, 0.0]), "accelerometer")], scene)
    zero = np.zeros((1, 3))
    q = np.array([[1.0, 0.0, 0.0, 0.0]])
    for t in (0.0, 0.01):
        rec.sample(t, scene.position, q, zero, zero, np.zeros(3), np.zeros(3))
    arrays = rec.arrays()
    rows = dict(npz_units(arrays, INSTRUMENTS_UNITS))
    assert set(rows) == set(arrays) and "?" not in rows.values()
    assert (rows["t"], rows["disp"], rows["vel"], rows["acc"]) == ("s", "m", "m/s", "m/s2")


def test_unit_rules():
    assert unit_of("collapse.angles[].motion_m") == "m"
    assert unit_of("loading.peak_acceleration_m_s2") == "m/s2"
    assert unit_of("joints.normal_stiffness_Pa_m") == "Pa/m"
    assert unit_of("collapse.load_factor") == "-"
    assert unit_of("mechanism.collapsed.blocks[]") == "-"
    assert unit_of("energy.dissipated_friction") == "J"
    assert unit_of("something_new") is None                     # not guessed
    assert summary_units({"something_new": 1.0, "dt": 1e-5}) == {"something_new": "?",
                                                                 "dt": "s"}
    assert dict(npz_units(["t", "pos", "units"], FRAMES_UNITS)) == {"t": "s", "pos": "m"}


@pytest.mark.parametrize("rel", ["analytic/sliding-block-on-tilt.yaml",
                                 "tilt/in-plane/small-9x15-s35.yaml",
                                 "shake/model-ii/group-3-y-1.53.yaml"])
def test_check_show_defaults_prints_the_case_as_it_runs_with_units(rel):
    """``dem check CASE --show-defaults``: the case with every default filled in, as
    YAML that loads back into the same case, the units in the comments."""
    from pathlib import Path

    import yaml
    from typer.testing import CliRunner

    from dem.case import load_case, parse_case
    from dem_cli.app import app

    path = Path(__file__).resolve().parents[1] / "cases" / rel
    res = CliRunner().invoke(app, ["check", str(path), "--show-defaults"])
    assert res.exit_code == 0, res.output
    text = res.stdout[res.stdout.index("# the case as it runs"):]
    assert parse_case(yaml.safe_load(text)) == load_case(path)
    lines = text.splitlines()
    # defaults the file does not give, with their units
    assert any(ln.strip().startswith("damping: 0.5  # viscous contact damping, fraction of "
                                      "critical") for ln in lines)
    assert any(ln.strip().startswith("output_interval: ") and ", s" in ln for ln in lines)
    assert any(ln.strip().startswith("overlap_tolerance: 0.0001  #") and ", m" in ln
               for ln in lines)
