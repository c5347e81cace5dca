"""The table's waveform distortion (dem.table_motion.DistortedSineMotion, ``loading.distortion``).

The nominal sine u0 = A sin(w t), a0 = -a_p sin(w t) (a_p = A w^2) gets a third harmonic,
a = -a_p [sin(w t) - h sin(3 w t)] (peak a_p (1 + h) at the fundamental's peaks), and a
half-sine acceleration pulse of peak s a_p and duration tau at every velocity reversal
t_k = (pi/2 + k pi) / w, in the direction of the acceleration there.  The motion's docstring
derives its velocity and displacement in closed form; here they are checked against numerical
integrals of the acceleration (scipy's quad, to its own error estimate), against the
differentiated displacement, and the plain sine is checked to be untouched bit for bit.
"""

from __future__ import annotations

import numpy as np
import pytest
from scipy.integrate import quad

from dem.table_motion import DistortedSineMotion, SineMotion

F, AP = 2.8, 1.53                        # Hz, m/s2 (Model II y's group 3 level)
W = 2 * np.pi * F
A = AP / W**2                            # m
H, S, TAU = 0.2, 0.5, 0.01               # -, -, s
CYCLES = 4.0
STARTS = [("table-frame", None), ("lab", None), ("ramp", 1.5)]
BLOCK = {"size": [0.2, 0.2, 0.1], "position": [0, 0, 0.05], "mass": 4.0}


def _reversals(t_end: float) -> np.ndarray:
    """The nominal motion's velocity reversals (displacement extremes) before t_end, s."""
    k = np.arange(int(2 * F * t_end) + 1)
    t = (np.pi / 2 + k * np.pi) / W
    return t[t < t_end]


def _quad(fun, a: float, b: float, breaks) -> tuple[float, float]:
    """Integral of fun over [a, b] split at the breaks inside (pulse edges: a kink each)."""
    edges = [a, *sorted(x for x in breaks if a < x < b), b]
    parts = [quad(fun, x0, x1, epsabs=1e-13, epsrel=1e-12, limit=200)
             for x0, x1 in zip(edges[:-1], edges[1:])]
    return sum(p[0] for p in parts), sum(p[1] for p in parts)


@pytest.mark.parametrize("start,ramp", STARTS)
def test_velocity_and_displacement_are_the_integrals_of_the_acceleration(start, ramp):
    m = DistortedSineMotion(A, F, CYCLES, start, ramp, third_harmonic=H, spike_peak=S,
                            spike_duration=TAU)
    rev = _reversals(m.t_end)
    breaks = [*rev, *(rev + TAU), m.t_ramp] + ([m.t_end] if m.t_end else [])
    acc = lambda x: float(m.acceleration(np.array([x]))[0])      # noqa: E731
    vel = lambda x: float(m.velocity(np.array([x]))[0])          # noqa: E731
    v0 = float(m.velocity(np.array([0.0]))[0])
    # inside a pulse, between pulses, at a pulse's end, after the shaking
    for t in (0.9 * rev[0], rev[0] + 0.3 * TAU, rev[1] + TAU, 0.5 * (rev[2] + rev[3]),
              m.t_end + 0.2):
        dv, err_v = _quad(acc, 0.0, t, breaks)
        assert float(m.velocity(np.array([t]))[0]) - v0 == pytest.approx(dv, abs=10 * err_v
                                                                            + 1e-13)
        du, err_u = _quad(vel, 0.0, t, breaks)
        assert float(m.displacement(np.array([t]))[0]) == pytest.approx(du, abs=10 * err_u
                                                                        + 1e-13)


@pytest.mark.parametrize("start,ramp", STARTS)
def test_the_derivatives_of_the_displacement_are_the_velocity_and_acceleration(start, ramp):
    """Central differences of u and v on a 20 us grid, away from the pulse edges (where a has
    a kink): their error is (dt^2 / 6) u''' ~ 1e-7 of v, (dt^2 / 6) a'' ~ 1e-5 of a."""
    m = DistortedSineMotion(A, F, CYCLES, start, ramp, third_harmonic=H, spike_peak=S,
                            spike_duration=TAU)
    dt = 2e-5
    t = np.arange(0.0, m.t_end, dt)[1:-1]
    rev = _reversals(m.t_end)
    clear = np.all(np.abs(t[:, None] - np.concatenate([rev, rev + TAU])[None, :]) > 2 * dt,
                   axis=1)
    u, v, a = m.displacement(t), m.velocity(t), m.acceleration(t)
    dudt = (m.displacement(t + dt) - m.displacement(t - dt)) / (2 * dt)
    dvdt = (m.velocity(t + dt) - m.velocity(t - dt)) / (2 * dt)
    assert np.abs(dudt - v).max() < 1e-6 * np.abs(v).max()
    assert np.abs(dvdt - a)[clear].max() < 1e-4 * np.abs(a).max()
    assert np.abs(u).max() < 1.3 * A        # bounded: no drift while it shakes


def test_the_third_harmonic_sharpens_the_peaks_to_one_plus_h():
    m = DistortedSineMotion(A, F, CYCLES, third_harmonic=H)
    rev = _reversals(m.t_end)
    peaks = m.acceleration(rev)
    # at the fundamental's peaks, exactly -a_p (1 + h) sin(w t_k)
    assert peaks == pytest.approx(-AP * (1 + H) * np.sin(W * rev), rel=1e-12)
    t = np.linspace(0.0, m.t_end, 200_001)[:-1]
    assert np.abs(m.acceleration(t)).max() == pytest.approx(AP * (1 + H), rel=1e-12)
    assert m.distorted_peak_acceleration == pytest.approx(AP * (1 + H), rel=1e-12)
    # the displacement term of the integral: -(h A / 9) sin(3 w t)
    assert m.displacement(t) == pytest.approx(A * (np.sin(W * t) - H / 9 * np.sin(3 * W * t)),
                                              abs=1e-15)


def test_a_spike_starts_at_every_reversal_and_adds_to_the_peak():
    m = DistortedSineMotion(A, F, CYCLES, spike_peak=S, spike_duration=TAU)
    plain = SineMotion(A, F, CYCLES)
    t = np.linspace(0.0, m.t_end, 400_001)[:-1]
    extra = m.acceleration(t) - plain.acceleration(t)
    rev = _reversals(m.t_end)
    # the nominal displacement's extremes are the reversals
    assert np.abs(plain.displacement(rev)) == pytest.approx(A, rel=1e-12)
    def within(lo, hi):
        return np.any((t[:, None] > lo[None, :]) & (t[:, None] < hi[None, :]), axis=1)

    edge = 1e-9   # s: at a pulse's end sin(pi) is rounding, not zero
    assert np.all(extra[~within(rev - edge, rev + TAU + edge)] == 0.0)
    assert np.all(extra[within(rev + edge, rev + TAU - edge)] != 0.0)
    crest = rev + TAU / 2
    # in the direction of the nominal acceleration at the reversal, peak s a_p
    assert (m.acceleration(crest) - plain.acceleration(crest)) == pytest.approx(
        S * AP * np.sign(plain.acceleration(rev)), rel=1e-12)
    assert m.distorted_peak_acceleration == pytest.approx(
        AP * (np.cos(W * TAU / 2) + S), rel=1e-4)


def test_the_lab_start_takes_the_distorted_velocity():
    m = DistortedSineMotion(A, F, CYCLES, "lab", third_harmonic=H, spike_peak=S,
                            spike_duration=TAU)
    delta = 2 * S * AP * TAU / np.pi
    assert m.velocity_jump == pytest.approx(A * W * (1 - H / 3) + delta / 2, rel=1e-12)
    assert float(m.displacement(np.array([0.0]))[0]) == 0.0
    assert DistortedSineMotion(A, F, CYCLES, third_harmonic=H).velocity_jump == 0.0


def test_no_distortion_is_the_plain_sine_bit_for_bit():
    """The distortion is added to the sine's own arrays: with none, the same numbers; and a
    shake case without ``distortion`` builds the plain SineMotion and writes no such field."""
    from dem.case.identity import identity_json
    from dem.loading import loading_from_case

    t = np.linspace(-0.1, CYCLES / F + 0.3, 20_001)
    for start, ramp in STARTS:
        plain = SineMotion(A, F, CYCLES, start, ramp)
        zero = DistortedSineMotion(A, F, CYCLES, start, ramp)
        for q in ("displacement", "velocity", "acceleration"):
            assert np.array_equal(getattr(zero, q)(t), getattr(plain, q)(t)), (start, q)
    case = _shake_case(None)
    ld = loading_from_case(case)
    assert type(ld.motion) is SineMotion and not ld.records_table_velocity()
    assert "distortion" not in case.model_dump()["loading"]
    assert "distortion" not in identity_json(case)


def _shake_case(distortion: dict | None, frequency: float = F):
    from dem.case import parse_case

    ld = {"type": "shake", "direction": [0, 1, 0], "frequency": frequency,
          "peak_acceleration": AP, "cycles": CYCLES}
    if distortion is not None:
        ld["distortion"] = distortion
    return parse_case({"name": "s", "scene": {"blocks": [BLOCK]}, "material": {"friction": 0.6},
                       "loading": ld, "run": {"duration": 2.0}})


def test_a_distorted_case_drives_the_distorted_motion():
    from dem.loading import loading_from_case

    case = _shake_case({"third_harmonic": H, "reversal_spike": {"peak": S, "duration": TAU}})
    ld = loading_from_case(case)
    assert isinstance(ld.motion, DistortedSineMotion) and ld.records_table_velocity()
    t = np.linspace(0.0, 1.0, 1001)
    ref = DistortedSineMotion(A, F, CYCLES, third_harmonic=H, spike_peak=S, spike_duration=TAU)
    assert np.array_equal(ld.base_accel(t)[:, 1], ref.acceleration(t))
    assert ld.describe()["distortion"]["third_harmonic"] == H


@pytest.mark.parametrize("distortion,message", [
    ({"reversal_spike": {"peak": S, "duration": 0.2}},
     "distortion.reversal_spike.duration: 0.2 s is more than half a period"),
    ({"third_harmonic": -0.1}, "third_harmonic"),
    ({}, "a distortion needs a third harmonic > 0 or a reversal spike"),
    ({"reversal_spike": {"peak": S}}, "duration"),
])
def test_a_bad_distortion_is_refused_by_name(distortion, message):
    from dem.case import CaseError

    with pytest.raises((CaseError, ValueError), match=message.replace(".", r"\.")):
        _shake_case(distortion)


def test_the_stepped_shake_and_the_two_body_model_refuse_a_distortion_by_name(tmp_path):
    import yaml
    from typer.testing import CliRunner

    from dem_cli.app import app

    case = _shake_case(None).model_dump(mode="json")
    case["loading"] = {"type": "stepped_shake", "direction": [0, 1, 0], "peak_acceleration": AP,
                       "steps": [{"frequency": F, "cycles": 2}], "distortion":
                       {"third_harmonic": H}}
    path = tmp_path / "stepped.yaml"
    path.write_text(yaml.safe_dump(case))
    r = CliRunner().invoke(app, ["check", str(path)])
    assert r.exit_code == 2, r.output
    assert "distortion: the table's waveform distortion is implemented for type: shake only" \
        in r.output
    from dem.rocking.schema import ShakeLoading as RockingShake

    with pytest.raises(ValueError, match="distortion: .* not implemented in the two-body"):
        RockingShake.model_validate({"type": "shake", "direction": [0, 1, 0], "frequency": F,
                                     "amplitude": A, "distortion": {"third_harmonic": H}})


def test_dem_sweep_carries_the_distortion_and_names_it_where_a_frequency_breaks_it():
    from dem.run.sweep import SweepInputError, sweep_cases

    case = _shake_case({"reversal_spike": {"peak": S, "duration": 0.15}}, frequency=2.0)
    cases = sweep_cases(case, [2.0, 3.0])
    for (_, c), f in zip(cases, (2.0, 3.0)):
        assert c.loading.frequency == f
        assert c.loading.distortion == case.loading.distortion
    # 0.15 s is more than half a period at 3.6 Hz (0.139 s)
    with pytest.raises(SweepInputError, match=r"f3\.600Hz: .*distortion\.reversal_spike\."
                                              r"duration"):
        sweep_cases(case, [2.0, 3.6])


def test_dem_check_takes_the_distorted_peak_for_the_table_plausibility(tmp_path):
    """The plausibility check reads the distorted table's peak ((1 + h) a_p with a harmonic):
    a level 1.1 x below the implausible one passes as a sine and is warned of with 20 %."""
    import yaml
    from typer.testing import CliRunner

    from dem.validate import G_STANDARD, TABLE_ACCELERATION_PLAUSIBLE_G
    from dem_cli.app import app

    below = TABLE_ACCELERATION_PLAUSIBLE_G * G_STANDARD / 1.1
    outputs = []
    for k, dist in enumerate((None, {"third_harmonic": H})):
        case = _shake_case(dist).model_dump(mode="json")
        case["loading"]["peak_acceleration"] = float(below)
        path = tmp_path / f"c{k}.yaml"
        path.write_text(yaml.safe_dump(case))
        outputs.append(CliRunner().invoke(app, ["check", str(path)]).output)
    assert "IMPLAUSIBLE: peak table acceleration" not in outputs[0], outputs[0]
    assert "IMPLAUSIBLE: peak table acceleration" in outputs[1], outputs[1]


def test_a_squat_block_rides_the_distorted_table_and_the_run_records_it():
    """b/h = 2, mu = 0.6: sliding at mu g = 5.9 m/s2, tipping at g b/h = 19.6 m/s2, both above
    the distorted peak (1.53 (1 + 0.2) + 0.5 x 1.53 ~ 2.6 m/s2): the block moves with the table
    (its give on the contact, m a / (ks area) ~ 0.1 um, below 1 um), and the run's table is the
    distorted one (frames' base_disp = u(t) of the motion)."""
    from dem.run import run_case

    case = _shake_case({"third_harmonic": H, "reversal_spike": {"peak": S, "duration": TAU}})
    data = case.model_dump()
    data["loading"]["cycles"] = 2.0
    data["run"].update({"duration": 0.8, "output_interval": 0.002, "vtk": False,
                        "snapshot": False})
    res = run_case(type(case).model_validate(data))
    assert res.summary["status"] == "ok"
    assert res.summary["loading"]["distortion"]["third_harmonic"] == H
    rel = np.linalg.norm(res.pos[:, 0] - res.pos[0, 0], axis=1)
    assert rel.max() < 1e-6
    m = DistortedSineMotion(A, F, 2.0, third_harmonic=H, spike_peak=S, spike_duration=TAU)
    np.testing.assert_allclose(res.base_disp[:, 1], m.displacement(res.t), atol=1e-15)


def test_dem_check_refuses_a_spike_the_time_step_cannot_resolve(tmp_path):
    """A half-sine pulse is half a period of a sine of period 2 tau: as a shake's period must
    span 20 time steps, a pulse must span 10."""
    import yaml
    from typer.testing import CliRunner

    from dem_cli.app import app

    case = _shake_case({"reversal_spike": {"peak": S, "duration": 1e-7}}).model_dump(mode="json")
    path = tmp_path / "c.yaml"
    path.write_text(yaml.safe_dump(case))
    r = CliRunner().invoke(app, ["check", str(path)])
    assert r.exit_code == 2, r.output
    assert "loading.distortion.reversal_spike.duration: a pulse of 1e-07 s spans fewer than 10 " \
        "time steps" in r.output, r.output
