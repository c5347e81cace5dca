"""Stepped frequencies on one specimen (dem.table_motion.SteppedSineMotion,
postprocess.stepped).

The table record is continuous through the steps: each step ends at a displacement extreme
(v = 0) and the next starts there, with the offset c_k+1 = c_k + (A_k - A_k+1) s_k; at constant
peak acceleration a is continuous too (-a_p s_k on both sides).  A block that does not move
(squat, mu = 0.8, 1.5 m/s2: sliding at 7.8, tipping at 19.6 m/s2) is a linear system with no
memory, so each step's analysis equals a separate run at that frequency; tolerances: frames
5 ms apart (per-cycle peaks of a sine: 1 - cos(pi f dt) = 1.1e-3 at 3 Hz; the frame-based
accelerometer's two differences: 2 (w dt)^2 / 6 = 3e-3, the same in both records).
"""

from __future__ import annotations

import json

import numpy as np
import pytest

from dem.table_motion import SteppedSineMotion

A_P = 1.5   # m/s2
STEPS = [(2.0, 3), (3.0, 3)]


def _jumps(motion, q, t):
    y = getattr(motion, q)(t)
    return np.abs(np.diff(y))


@pytest.mark.parametrize("steps", [[(2.0, 3), (2.5, 3.3), (3.1, 2)],     # up
                                   [(3.1, 2.2), (2.5, 3), (2.0, 1.7)]])  # down
def test_the_table_record_is_continuous_through_the_steps(steps):
    m = SteppedSineMotion(steps, peak_acceleration=A_P)
    h = 1e-5
    for k in range(1, len(steps)):
        tk = m.t0[k]
        t = np.array([tk - h, tk, tk + h])
        u, v, a = m.displacement(t), m.velocity(t), m.acceleration(t)
        # across a switch: u changes by v h (v = 0 there: by a h^2 / 2), v by a h, a by ~0
        assert abs(u[2] - u[0]) < A_P * h**2 + 1e-15, k
        assert abs(v[1]) < 1e-12 and abs(v[2] - v[0]) < 2.5 * A_P * h, k
        assert abs(a[2] - a[0]) < 1e-3 * A_P, k          # jerk * 2h
        assert m.steps_run()[k - 1]["cycles_run"] >= steps[k - 1][1]
        assert m.steps_run()[k - 1]["cycles_run"] < steps[k - 1][1] + 0.5 + 1e-9
    # each step is the sine of its frequency at the common peak acceleration
    for st in m.steps_run():
        w = 2 * np.pi * st["frequency_hz"]
        assert st["amplitude_m"] * w**2 == pytest.approx(A_P)
    t = np.linspace(1e-6, m.t_end - 1e-6, 200001)
    np.testing.assert_allclose(np.gradient(m.displacement(t), t), m.velocity(t),
                               atol=1e-5 * A_P)
    # the end: at an extreme, at rest
    assert float(m.velocity(m.t_end + 0.1)) == 0.0
    assert float(m.displacement(m.t_end + 1.0)) == pytest.approx(m.u_end)


def test_constant_amplitude_keeps_the_table_centred_and_steps_its_acceleration():
    m = SteppedSineMotion(STEPS, amplitude=0.01)
    assert np.all(m.offset == 0.0)
    t1 = m.t0[1]
    a = m.acceleration(np.array([t1 - 1e-9, t1 + 1e-9]))
    s = m.sign[0]
    np.testing.assert_allclose(a, -0.01 * (2 * np.pi * np.array([2.0, 3.0])) ** 2 * s,
                               rtol=1e-6)


def _case(loading, duration):
    from dem.case import parse_case

    return parse_case({
        "name": "bolted-stepped",
        "scene": {"blocks": [{"size": [0.2, 0.2, 0.1], "position": [0, 0, 0.05],
                              "mass": 4.0}]},
        # kn 5e8 Pa/m: a 3x longer time step; the contact's give m a / (ks area) = 0.8 um
        "material": {"friction": 0.8, "normal_stiffness": 5e8},
        "loading": {"direction": [0, 1, 0], **loading},
        "run": {"duration": duration, "output_interval": 0.005, "vtk": False,
                "snapshot": False}})


def test_a_block_that_does_not_move_gives_each_step_the_analysis_of_a_separate_run(tmp_path):
    from dem.run import run_case
    from postprocess.shake import analyze_run
    from postprocess.stepped import analyze_stepped_run

    stepped = _case({"type": "stepped_shake", "peak_acceleration": A_P,
                     "steps": [{"frequency": f, "cycles": n} for f, n in STEPS]}, 2.7)
    run_case(stepped, tmp_path / "stepped")
    res = analyze_stepped_run(tmp_path / "stepped")
    assert (tmp_path / "stepped" / "stepped.json").is_file()
    assert (tmp_path / "stepped" / "stepped.png").stat().st_size > 1000
    assert [s["pass"] for s in res["steps"]] == ["up", "up"]
    from typer.testing import CliRunner

    from dem_cli.app import app

    r = CliRunner().invoke(app, ["post", str(tmp_path / "stepped")])
    assert r.exit_code == 0 and "stepped.json: 2 steps: 2 Hz up" in r.output, r.output
    # the recorded table displacement is continuous through the switch
    with np.load(tmp_path / "stepped" / "frames.npz") as z:
        u = z["base_disp"][:, 1]
    assert np.abs(np.diff(u)).max() < 1.01 * 0.005 * A_P / (2 * np.pi * 2.0)  # <= v_max dt
    for (f, n), step in zip(STEPS, res["steps"]):
        run_case(_case({"type": "shake", "frequency": f, "peak_acceleration": A_P,
                        "cycles": n}, n / f + 0.05), tmp_path / f"f{f}")
        alone = analyze_run(tmp_path / f"f{f}", plots=False, write=False)
        for name in ("a", "va", "da"):
            assert step["amplification"][name] == pytest.approx(
                alone["amplification"][name], abs=3e-3), (f, name)
            assert step["lag"][name]["s"] == pytest.approx(alone["lag"][name]["s"],
                                                            abs=1e-3), (f, name)
        assert step["amplification"]["ds"] < 1e-3 and alone["amplification"]["ds"] < 1e-3
        assert step["relative_to_table"]["amplification"]["a_rel"] < 1e-2


@pytest.mark.parametrize("change,message", [
    ({"steps": []}, "loading.steps: List should have at least 1 item"),
    ({"steps": [{"frequency": 0.0, "cycles": 3}]}, "loading.steps[0].frequency: Input should be"),
    ({"steps": [{"frequency": 2.0}]}, "loading.steps[0].cycles: missing required field"),
    ({"amplitude": 0.01}, "give exactly one of amplitude"),
    ({"start": "ramp", "ramp_cycles": 5}, "ramp_cycles: 5 is more than steps[0].cycles = 3"),
    ({"steps": [{"frequency": 2.0, "cycles": 3}, {"frequency": 5000.0, "cycles": 3}]},
     "loading.steps[1].frequency: 5000 Hz has a period"),
    # amplitude 2 m at 10 Hz: 126 m/s, beyond any table (dem.validate.table_plausibility)
    ({"peak_acceleration": None, "amplitude": 2.0,
      "steps": [{"frequency": 2.0, "cycles": 3}, {"frequency": 10.0, "cycles": 3}]},
     "loading.steps[1]: the table would move at up to 126 m/s"),
])
def test_dem_check_names_a_bad_stepped_field(tmp_path, change, message):
    import yaml
    from typer.testing import CliRunner

    from dem_cli.app import app

    case = _case({"type": "stepped_shake", "peak_acceleration": A_P,
                  "steps": [{"frequency": f, "cycles": n} for f, n in STEPS]}, 2.7).model_dump()
    case["loading"].update(change)
    path = tmp_path / "case.yaml"
    path.write_text(yaml.safe_dump(case))
    r = CliRunner().invoke(app, ["check", str(path)])
    assert r.exit_code == 2, r.output
    assert f"{path}:" in r.output and message in r.output, r.output


def test_the_start_applies_to_the_first_step():
    """A ramp start raises the first step's amplitude as a ramped shake does (u, v, a from rest);
    a lab start's velocity jump is the first step's A_0 w_0."""
    from dem.table_motion import SineMotion

    ramped = SteppedSineMotion(STEPS, peak_acceleration=A_P, start="ramp", ramp_cycles=2)
    alone = SineMotion(A_P / (2 * np.pi * 2.0) ** 2, 2.0, ramped.cycles_run[0], "ramp", 2)
    t = np.linspace(0.0, ramped.t0[1] - 1e-6, 2001)
    for q in ("displacement", "velocity", "acceleration"):
        np.testing.assert_allclose(getattr(ramped, q)(t), getattr(alone, q)(t), atol=1e-15,
                                   err_msg=q)
    assert float(ramped.velocity(0.0)) == 0.0 and float(ramped.acceleration(0.0)) == 0.0
    # after the ramp the first step is the held sine, so the switch joins as without a ramp
    plain = SteppedSineMotion(STEPS, peak_acceleration=A_P)
    later = np.linspace(ramped.t0[1] - 0.2, ramped.t_end + 0.1, 501)
    np.testing.assert_allclose(ramped.acceleration(later), plain.acceleration(later),
                               atol=1e-9 * A_P)
    lab = SteppedSineMotion(STEPS, peak_acceleration=A_P, start="lab")
    assert lab.velocity_jump == pytest.approx(A_P / (2 * np.pi * 2.0))
    assert plain.velocity_jump == 0.0


def test_dem_check_warns_of_an_implausible_stepped_table(tmp_path):
    """500 m/s2 (51 g) at every step, and a stroke of 3.2 m at 2 Hz: warned, not refused."""
    import yaml
    from typer.testing import CliRunner

    from dem_cli.app import app

    case = _case({"type": "stepped_shake", "peak_acceleration": 500.0,
                  "steps": [{"frequency": f, "cycles": n} for f, n in STEPS]}, 2.7).model_dump()
    path = tmp_path / "case.yaml"
    path.write_text(yaml.safe_dump(case))
    r = CliRunner().invoke(app, ["check", str(path)])
    assert r.exit_code == 0, r.output
    assert "loading.steps[0]: IMPLAUSIBLE: peak table acceleration 500 m/s2" in r.output, r.output
    assert "loading.steps[0]: IMPLAUSIBLE: table displacement amplitude 3.17 m" in r.output


@pytest.mark.parametrize("into_second", [0.5, 2.0])
def test_a_run_stopped_in_a_step_gives_the_steps_it_reached(tmp_path, into_second):
    """A stepped run that ended early (stopped, killed, or its duration shorter than the
    steps): the steps it finished are analysed as in a full run; a step it reached by a cycle
    or more is analysed on that part and says where the record ends; one it did not is named,
    not analysed (it used to crash the analysis on an empty record)."""
    from dem.run import run_case
    from postprocess.stepped import analyze_stepped_run, steps_line

    (f1, n1), (f2, n2) = STEPS
    case = _case({"type": "stepped_shake", "peak_acceleration": A_P,
                  "steps": [{"frequency": f, "cycles": n} for f, n in STEPS]},
                 n1 / f1 + into_second / f2)    # ends into_second cycles into the second step
    run_case(case, tmp_path / "cut")
    res = analyze_stepped_run(tmp_path / "cut", plots=True)
    first, second = res["steps"]
    assert "not_analysed" not in first and "record_ends_s" not in first
    assert first["amplification"]["ds"] < 1e-3
    if into_second < 1.0:
        assert second["amplification"] == {} and "record ends" in second["not_analysed"]
        assert steps_line(res).endswith(f"{f2:g} Hz up not reached")
    else:
        # analysed (two cycles: too short for a steady window, said as for any short step)
        assert "not_analysed" not in second and second["record_ends_s"] < second["t_end_s"]
        assert second["amplification"].get("ds", 0.0) < 1e-3 or "error" in second


def test_a_stepped_run_is_reported_as_a_shake_is(tmp_path):
    """dem run's result line says the displacement is relative to the table (the blocks'
    positions are in the table's frame), dem post warns of a step whose steady window holds
    fewer than 3 cycles (as it warns of a shake's: 3 cycles a step leave 2 after the first is
    dropped), and dem summary shows the largest step amplification and its frequency."""
    import yaml
    from typer.testing import CliRunner

    from dem_cli.app import app

    case = _case({"type": "stepped_shake", "peak_acceleration": A_P,
                  "steps": [{"frequency": f, "cycles": n} for f, n in STEPS]}, 2.7)
    path = tmp_path / "stepped.yaml"
    path.write_text(yaml.safe_dump(case.model_dump(mode="json")))
    run_dir = tmp_path / "run"
    r = CliRunner().invoke(app, ["run", str(path), "--out", str(run_dir)])
    assert r.exit_code == 0, r.output
    assert "relative to the table" in r.output.strip().splitlines()[-1], r.output
    r = CliRunner().invoke(app, ["post", str(run_dir)])
    assert r.exit_code == 0, r.output
    warned = [ln for ln in r.output.splitlines() if ln.startswith("warning:")
              and "steady window holds only 2 cycle(s)" in ln]
    assert [("2 Hz" in w, "3 Hz" in w) for w in warned] == [(True, False), (False, True)], \
        r.output
    res = json.loads((run_dir / "stepped.json").read_text())
    peak = max(res["steps"], key=lambda s: s["amplification"]["ds"])
    r = CliRunner().invoke(app, ["summary", "--format", "csv", str(run_dir)])
    header, row = r.output.strip().splitlines()[-2:]
    cols = dict(zip(header.split(","), row.split(",")))
    assert float(cols["amplification ds (-)"]) == peak["amplification"]["ds"]
    assert float(cols["frequency (Hz)"]) == peak["frequency_hz"]


def test_steps_at_one_frequency_are_neither_an_up_nor_a_down_pass():
    """A kick-start or an amplitude continuation changes the level, not the frequency."""
    from postprocess.stepped import passes

    assert passes([2.8, 2.8]) == ["same", "same"]
    assert passes([2.0, 2.8, 2.8, 2.4]) == ["up", "up", "same", "down"]
