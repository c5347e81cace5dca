"""A real tilting-table run end to end: collapse detected, run stopped, lambda and mechanism
reported next to the limit analysis."""

import json

import numpy as np

from dem.case import parse_case
from dem_cli.commands.run import RUN_ANALYSES
from dem.run import run_case


def test_small_wall_tilt_run_stops_after_collapse(tmp_path):
    """3 x 3 small-brick wall, mu 0.81, rough table: the limit analysis gives overturning 0.75
    (frictionless lower bound) and sliding along the bond 0.81; the wall must collapse between
    the two (the thesis: friction on the crack raises the real value above the frictionless
    bound), at tilt angles 36.9 .. 39.0 deg.  Starting at 33 deg at 4 deg/s keeps the run short;
    at 4 deg/s lambda is within 1 % of its slow-rate value (results/tilt, rate study)."""
    case = parse_case({
        "name": "tilt-3x3",
        "scene": {"wall": {"brick": "small", "length": 3, "courses": 3}},
        "material": {"friction": 0.81, "base_friction": 1.5},
        "loading": {"type": "tilt", "axis": "y", "rate": 4.0, "start_angle": 33.0,
                    "start_time": 0.5, "max_angle": 45.0, "collapse": {"after": 0.2}},
        "run": {"duration": 4.0, "output_interval": 0.005, "vtk": False, "snapshot": False},
    })
    res = run_case(case, tmp_path, analyses=RUN_ANALYSES)
    s = json.loads((tmp_path / "summary.json").read_text())
    col = s["collapse"]
    assert col["detected"]
    assert 0.75 - 0.01 <= col["load_factor"] <= 0.81 + 0.02
    # stopped soon after the collapse was confirmed, well before the 4 s asked for
    assert s["sim_time"] <= col["confirm_time_s"] + 0.2 + 0.01
    assert s["sim_time"] < 3.0
    mech = s["mechanism"]
    assert mech["kind"] == "in-plane" and mech["mechanism"] in ("sliding", "mixed", "overturning")
    la = mech["limit_analysis"]
    assert abs(la["lambda_sliding"] - 0.81) < 1e-3
    assert col["n_moved"] == len(col["moved_blocks"]) > 0
    # the frames saved match what the summary says
    frames = np.load(tmp_path / "frames.npz")
    assert abs(frames["t"][-1] - s["sim_time"]) < 1e-9
    assert abs(frames["tilt_angle"][-1] - (33.0 + 4.0 * (s["sim_time"] - 0.5))) < 1e-6
    assert res.summary["collapse"]["detected"]


def test_an_analysis_that_raises_does_not_lose_the_run(tmp_path):
    """The run loop hands the finished frames to the analyses of the command; one that raises is
    recorded in summary.json, and every file is still written."""
    case = parse_case({
        "name": "block-at-rest",
        "scene": {"blocks": [{"size": [0.2, 0.2, 0.1], "position": [0, 0, 0.05], "mass": 4.0}]},
        "material": {"friction": 0.5},
        "run": {"duration": 0.02, "output_interval": 0.01, "vtk": False, "snapshot": False},
    })

    def boom(case, scene, frames, summary):
        raise RuntimeError("analysis bug")

    res = run_case(case, tmp_path, analyses=(boom,))
    s = json.loads((tmp_path / "summary.json").read_text())
    assert s["status"] == "ok" and res.summary["status"] == "ok"
    assert s["analysis_errors"] == {"boom": "RuntimeError: analysis bug"}
    assert (tmp_path / "frames.npz").is_file()
