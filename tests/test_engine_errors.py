"""Bad input gets a clear error naming the problem; failed runs keep their frames."""

import json

import numpy as np
import pytest

from dem.case import CaseError, parse_case
from dem.engine import CapacityError, InputError, InstabilityError
from dem.run import run_case
from engine_helpers import constant_loads, make_sim, stretcher_wall


def _case(blocks, **extra):
    data = {"name": "bad", "scene": {"blocks": blocks}, "material": {"friction": 0.5},
            "run": {"duration": 0.05, "output_interval": 0.005}}
    data.update(extra)
    return data


@pytest.mark.parametrize("field,value,needle", [
    ("size", [0.1, -0.1, 0.1], r"scene\.blocks\[0\]\.size: every edge length must be > 0"),
    ("size", [0.1, 0.0, 0.1], r"scene\.blocks\[0\]\.size: every edge length must be > 0"),
    ("mass", 0.0, r"scene\.blocks\[0\].*mass must be > 0"),
    ("mass", -2.0, r"scene\.blocks\[0\].*mass must be > 0"),
])
def test_non_positive_sizes_and_masses_are_rejected(field, value, needle):
    blk = {"size": [0.1, 0.1, 0.1], "position": [0, 0, 0.05], "mass": 1.0}
    blk[field] = value
    with pytest.raises(CaseError, match=needle):
        parse_case(_case([blk]))


def test_initial_overlap_names_the_pair():
    blocks = [{"size": [0.1, 0.1, 0.1], "position": [0, 0, 0.05], "mass": 1.0},
              {"size": [0.1, 0.1, 0.1], "position": [0.095, 0, 0.05], "mass": 1.0}]
    with pytest.raises(InputError, match=r"block 0 and block 1 overlap by 5\.000 mm"):
        make_sim(blocks)


def test_block_sunk_into_table_is_named():
    with pytest.raises(InputError, match=r"block 0 and the table overlap by 2\.000 mm"):
        make_sim([{"size": [0.1, 0.1, 0.1], "position": [0, 0, 0.048], "mass": 1.0}])


def test_time_step_above_critical_is_rejected():
    blk = [{"size": [0.1, 0.1, 0.1], "position": [0, 0, 0.05], "mass": 1.0}]
    dt_crit = make_sim(blk).dt_crit
    with pytest.raises(InputError, match=r"solver\.dt = .* above the critical time step"):
        make_sim(blk, solver={"dt": 1.5 * dt_crit})
    make_sim(blk, solver={"dt": 0.9 * dt_crit})  # below it: accepted


def test_neighbour_list_overflow_stops_loudly():
    with pytest.raises(CapacityError, match="neighbour list overflow.*max_pairs_per_block"):
        make_sim(stretcher_wall(9, 15), solver={"max_pairs_per_block": 2})


def test_nan_state_stops_and_names_step_and_block():
    sim = make_sim([{"size": [0.1, 0.1, 0.1], "position": [0, 0, 0.05], "mass": 1.0},
                    {"size": [0.1, 0.1, 0.1], "position": [1, 0, 0.05], "mass": 1.0}])
    sim.advance(10, constant_loads())
    sim.state.vel[1, 0] = np.nan
    with pytest.raises(InstabilityError, match=r"block 1 became NaN/inf at step 11") as err:
        sim.advance(10, constant_loads())
    assert err.value.block == 1 and err.value.step == 11


def test_runaway_run_fails_and_keeps_frames(tmp_path):
    """A block thrown faster than solver.max_speed: the run stops, names step and block, and
    frames.npz / summary.json hold everything up to the failure."""
    blocks = [{"size": [0.1, 0.1, 0.1], "position": [0, 0, 0.05], "mass": 1.0},
              {"size": [0.1, 0.1, 0.1], "position": [1, 0, 3.0], "mass": 1.0,
               "velocity": [0, 0, -9.0]}]
    case = parse_case(_case(blocks, solver={"max_speed": 10.0}, run={
        "duration": 1.0, "output_interval": 0.01}))
    case.scene.allow_floating = True
    with pytest.raises(InstabilityError, match=r"block 1 moves faster than solver\.max_speed"):
        run_case(case, tmp_path)
    frames = np.load(tmp_path / "frames.npz")
    summary = json.loads((tmp_path / "summary.json").read_text())
    assert summary["status"] == "failed" and "block 1" in summary["error"]
    # falling from 9 m/s, 10 m/s is reached after ~0.1 s: frames up to the failure are there
    assert 0.05 < frames["t"][-1] < 0.2
    assert frames["pos"].shape == (len(frames["t"]), 2, 3)
    assert frames["pos"][-1, 1, 2] < 3.0 - 0.5
