"""The numbers that decide a tilt's result, shown with it, so that a user sees how far
the answer is from rigid-block theory and why: the closed form of lone
rigid blocks (postprocess/lone_block.py) with the run's error in the result line and
summary.json ``reference``, and the joint's elastic offset with the way to remove it."""

from __future__ import annotations

import json
import math
import re

import numpy as np
import pytest

from dem.case import parse_case
from dem_cli.commands.run import result_line
from dem.run.build import scene_from_case
from postprocess.limit_analysis import elastic_tipping_factor
from postprocess.decisive import decisive_numbers
from postprocess.lone_block import lone_block_limits


def _case(blocks, mu=0.5, axis="y", **extra):
    return parse_case({"name": "t", "scene": {"blocks": blocks, **extra},
                       "material": {"friction": mu},
                       "loading": {"type": "tilt", "axis": axis}, "run": {"duration": 1.0}})


def _limits(case, kn=None):
    from dem.loading import loading_from_case

    scene = scene_from_case(case, check=False)
    return lone_block_limits(case, scene, loading_from_case(case).load_direction, kn)


def test_closed_form_of_lone_blocks_slides_at_mu_and_tips_at_b_over_h():
    squat = {"size": [0.2, 0.3, 0.1], "position": [0, 0, 0.05], "density": 2000}
    slender = {"size": [0.1, 0.3, 0.4], "position": [1.0, 0, 0.2], "density": 2000}
    # about +y the load is along +x: b is the x extent; the slender block (0.1/0.4) goes first
    ref = _limits(_case([squat, slender], mu=0.5, axis="y"))
    assert ref["mode"] == "tipping" and ref["block"] == 1
    assert ref["load_factor"] == pytest.approx(0.1 / 0.4, rel=1e-15)
    assert ref["angle_deg"] == pytest.approx(math.degrees(math.atan(0.25)), rel=1e-15)
    assert [r["mode"] for r in ref["blocks"]] == ["sliding", "tipping"]
    # about x the load is along -y: b is the y extent (0.3): the slender block (0.3/0.4 > mu)
    # and the squat one both slide at mu
    ref = _limits(_case([squat, slender], mu=0.5, axis="x"))
    assert ref["mode"] == "sliding" and ref["load_factor"] == 0.5
    # with a joint stiffness the tipping value drops by the toe's elastic offset
    # tan = b/h - (6 rho g b cos / (kn h))^(1/3), independently solved here by brentq
    from scipy.optimize import brentq

    kn = 5e9
    ref = _limits(_case([slender], mu=0.8, axis="y"), kn=kn)
    def f(t):
        return math.tan(t) - 0.25 + (6 * 2000 * 9.81 * 0.1 * math.cos(t) / (kn * 0.4)) ** (1 / 3)

    assert ref["elastic_load_factor"] == pytest.approx(math.tan(brentq(f, 0.01, 0.5)), rel=1e-10)
    assert elastic_tipping_factor(0.1, 0.4, 2000.0, kn) < 0.25


def test_no_closed_form_for_a_wall_a_rotated_block_or_an_imperfect_one():
    a = {"size": [0.2, 0.1, 0.1], "position": [0, 0, 0.05], "density": 2000}
    b = {"size": [0.2, 0.1, 0.1], "position": [0, 0, 0.15], "density": 2000}   # on a
    assert _limits(_case([a, b])) is None
    turned = {**a, "rotation": [0, 0, 30]}
    assert _limits(_case([turned])) is None
    imperfect = parse_case({"name": "t", "scene": {"blocks": [a]}, "material": {"friction": 0.5},
                            "loading": {"type": "tilt", "axis": "y"}, "run": {"duration": 1.0},
                            "imperfections": {"arris": 1e-3}})
    assert _limits(imperfect) is None


def test_the_result_line_shows_the_closed_form_and_the_error(view_runs):
    """The tilt run of tests/view_runs.py: a squat block (b/h = 2) with mu = 0.5 slides at 0.5;
    its summary.json holds the reference and the result line prints it with the error of the
    run's lambda, computed here from the two numbers."""
    s = json.loads((view_runs["tilt"] / "summary.json").read_text())
    ref = s["reference"]
    assert ref["load_factor"] == 0.5 and ref["mode"] == "sliding"
    line = result_line(s)
    assert "closed form 0.500 (sliding" in line
    err = float(re.search(r"error ([+-][0-9.]+) %", line).group(1))
    assert err == pytest.approx(100 * (s["collapse"]["load_factor"] / 0.5 - 1), abs=0.006)
    assert abs(err) < 0.2    # the quasi-static search's tolerance (1e-3 in force ratio)
    assert "elastic offset" not in line  # a sliding block: the joint's offset does not matter
    # the criterion lambda was read with: the quasi-static search's tolerance and bisection
    col = s["collapse"]
    assert (f"unbalanced-force ratio < {col['criterion']['tolerance']:g}), the first failing "
            f"one {col['resolution_deg']:g} deg above") in line


def test_a_tipping_result_names_the_elastic_offset_the_rigid_option_and_its_cost():
    """A tipping block at the default kn (cases/analytic/block-on-tilt.yaml's slender block,
    b/h = 0.25, offset ~7 %): the line gives the elastic value, the offset, 'rigid' and the
    cost in steps, (offset / 0.5 %)^(3/2) (steps ~ kn^(1/2), offset ~ kn^(-1/3))."""
    from dem.case import load_case
    from dem.compliance import elastic_offset
    from dem.loading import loading_from_case
    from pathlib import Path

    path = Path(__file__).resolve().parents[1] / "cases" / "analytic" / "block-on-tilt.yaml"
    case = load_case(path)
    scene = scene_from_case(case)
    kn = 5e9
    offset = elastic_offset(scene, kn, 9.81, loading_from_case(case).load_direction)
    summary = {"joints": {"normal_stiffness_Pa_m": kn, "chosen": "case file",
                          "elastic_offset": offset},
               "collapse": {"detected": True, "load_factor": float(np.tan(np.radians(12.36)))},
               "reference": _limits(case, kn=kn), "loading": {"type": "tilt"}}
    texts = decisive_numbers(summary)
    assert len(texts) == 2  # no criterion text: the summary has none
    assert texts[0].startswith("closed form 0.250 (tipping")
    el = elastic_tipping_factor(0.1, 0.4, 2000.0, kn)
    assert f"{el:.3f} with the joint's elastic offset" in texts[0]
    r = offset["block"]["relative"]
    assert f"up to {100 * r:.1f} %" in texts[1] and "normal_stiffness: rigid" in texts[1]
    assert f"~{(r / 0.005) ** 1.5:.0f}x the steps" in texts[1]
    # with 'rigid' chosen nothing is left to say about the offset
    summary["joints"]["chosen"] = "rigid (elastic offset of every block <= 0.5 %)"
    assert not any("elastic offset of tipping" in t for t in decisive_numbers(summary))


def test_lean_png_gets_the_closed_form_and_the_notes(view_runs):
    """lean.png (postprocess.tilt.plot_lean, drawn by dem run) marks the closed form's angle,
    atan(mu) for the sliding block, and prints the result line's notes under the plots."""
    from postprocess.decisive import lean_notes

    angle, notes = lean_notes(view_runs["tilt"])
    assert angle == pytest.approx(math.degrees(math.atan(0.5)), rel=1e-12)
    s = json.loads((view_runs["tilt"] / "summary.json").read_text())
    assert notes == decisive_numbers(s) and notes[1].startswith("closed form 0.500")
    assert (view_runs["tilt"] / "lean.png").is_file()
