"""The two top contacts of the two-body model: ``sliding`` (the thesis' load N fixed in
space with friction mu N) and ``co-moving`` (N a mass N/g moving with the bearing top corner).

References are independent closed forms: static moment balances (uplift), Housner (1963) for one
block, Makris & Vassiliou (2013, EESD 42(3)) for a rocking frame (a column capped by a beam that
moves with its top), and Newton-Euler in maximal coordinates with the beam as a third body.
Tolerances: 1e-9 relative where the comparison is algebraic (round-off of a 2x2 solve), the
integrator's measured error otherwise (energy drift ~2e-9 with rtol 1e-10, see
results/two-body/README.md), with a margin.
"""

from __future__ import annotations

import json
import math

import numpy as np
import pytest

from dem.rocking import analysis as an
from dem.rocking.energy import energy_arrays
from dem.rocking.equations import evaluate, make_rhs
from dem.rocking.integrate import Settings, integrate_rocking
from dem.rocking.maximal import constrained_acc_maximal
from dem.rocking.params import RockingParams
from dem.table_motion import SineMotion, TableMotion

T, G = 0.05, 9.81
MODEL_II = dict(thickness=T, h1=0.14, m1=6.05, h2=0.14, m2=9.41)
MODEL_III = dict(thickness=T, h1=0.175, m1=6.72, h2=0.21, m2=14.11)
N_TESTS = 58.8  # N: the thesis' top load


def co(**kw):
    return RockingParams(**kw, top_contact="co-moving")


def uniform_column(m_top, locked=True, load_point="corner"):
    """A uniform column (two parts of equal mass per height) with a top mass m_top (kg)."""
    return co(thickness=T, h1=0.14, m1=43.0 * 0.14, h2=0.14, m2=43.0 * 0.14,
              top_load=m_top * G, locked=locked, load_point=load_point)


MODES = [(1, 1), (-1, -1), (1, -1), (-1, 1), (1, 0), (-1, 0), (0, 1), (0, -1)]


@pytest.mark.parametrize("load_point", ["corner", "centre"])
@pytest.mark.parametrize("b,c", MODES)
def test_comoving_equations_match_newton_euler_with_the_beam_as_a_body(b, c, load_point):
    """Lagrangian with the beam's kinetic energy = Newton-Euler of three bodies (the beam a point
    mass held at the load point by a hinge), all patterns, both bearing corners; and the fast
    right-hand side is the same equations."""
    P = co(**MODEL_II, top_load=N_TESTS, top_friction=0.81, load_point=load_point)
    assert P.Fmax == 0.0 and P.mN == pytest.approx(N_TESTS / G)
    rng = np.random.default_rng(abs(hash((b, c, load_point))) % 2**32)
    for sig in (1, -1):
        th1 = b * rng.uniform(0.01, 0.2) if b else 0.0
        phi = c * rng.uniform(0.01, 0.2) if c else 0.0
        y = (th1, phi, rng.normal() if b else 0.0, rng.normal() if c else 0.0)
        a = 3.0 * rng.normal()
        e = evaluate(P, (b, c, 1, sig), y, a)
        acc, lam = constrained_acc_maximal(P, (b, c, 1, sig), y, a, 0.0)
        scale = max(1.0, abs(acc[2]), abs(acc[5]))
        assert abs(acc[2] - e.dd1) < 1e-9 * scale and abs(acc[5] - e.dd2) < 1e-9 * scale
        if c == 0:
            assert e.iface[1] == pytest.approx(lam["if_n-"], rel=1e-9, abs=1e-9)
        if b == 0:
            assert e.base[1] == pytest.approx(lam["base_z-"], rel=1e-9, abs=1e-9)
        f = make_rhs(P, (b, c, 1, sig), lambda t: a)(0.0, y)
        assert np.allclose(f, [y[2], y[3], e.dd1, e.dd2 - e.dd1], rtol=1e-12, atol=1e-12)


@pytest.mark.parametrize("gamma", [0.0, 0.1, 1.0, 10.0])
def test_rocking_frame_equation_of_makris_and_vassiliou(gamma):
    """Uniform column, co-moving top mass m_N = gamma M on its corner, theta > 0:
    theta'' = -p^2 (1 + 2 gamma)/(1 + 3 gamma) [sin(alpha - theta) + a/g cos(alpha - theta)],
    p^2 = 3 g / (4 R) (Makris & Vassiliou 2013; gamma = 0 is Housner 1963)."""
    P0 = uniform_column(0.0)
    P = uniform_column(gamma * P0.mass)
    H = P.height
    R, al = 0.5 * math.hypot(T, H), math.atan(T / H)
    p2 = 3 * G / (4 * R)
    for th, w, a in [(0.01, 0.3, 1.0), (0.1, -1.0, -2.0), (0.3, 0.0, 0.5)]:
        e = evaluate(P, (1, 0, 1, 1), (th, 0.0, w, 0.0), a)
        ref = -p2 * (1 + 2 * gamma) / (1 + 3 * gamma) * (math.sin(al - th) + a / G * math.cos(al - th))
        assert e.dd1 == pytest.approx(ref, rel=1e-12)


@pytest.mark.parametrize("gamma", [0.1, 1.0, 10.0])
def test_rocking_frame_lifts_at_g_T_over_H_whatever_the_mass(gamma):
    """Closed form exactly g T / H; simulated onset bracketed: rest at 0.99 x, 3A at 1.01 x."""
    P = uniform_column(gamma * uniform_column(0.0).mass)
    thr = an.uplift_threshold(P)
    assert thr == pytest.approx(G * T / P.height, rel=1e-12)
    _bracket(P, thr, "3A")


@pytest.mark.parametrize("gamma", [0.1, 1.0, 10.0])
def test_rocking_frame_restitution_of_makris_and_vassiliou(gamma):
    """Plastic impact of the frame (base corner and beam corner switch together):
    r = (1 - 3/2 sin^2 alpha + 3 gamma cos 2 alpha) / (1 + 3 gamma)."""
    P = uniform_column(gamma * uniform_column(0.0).mass)
    al = math.atan(T / P.height)
    r = (1 - 1.5 * math.sin(al) ** 2 + 3 * gamma * math.cos(2 * al)) / (1 + 3 * gamma)
    assert an.housner_restitution(P) == pytest.approx(r, rel=1e-12)
    res = integrate_rocking(P, TableMotion(), Settings(duration=0.5), (0.5 * al, 0.5 * al, 0, 0))
    e0 = next(e for e in res.events if e["kind"] == "impact_base")
    assert e0["ke_after"] / e0["ke_before"] == pytest.approx(r * r, rel=1e-9)
    assert res.stats["impacts_top"] >= 1


def test_single_block_limits_are_housner():
    """N -> 0: the co-moving model is the sliding one without load (Housner for a uniform locked
    pair); m2 -> 0 with N -> 0: Part 1 alone, Housner's block of height H1."""
    P0 = uniform_column(0.0)
    assert P0.mN == 0.0 and an.uplift_threshold(P0) == pytest.approx(G * T / P0.height, rel=1e-12)
    Ps = RockingParams(thickness=T, h1=0.14, m1=6.02, h2=0.14, m2=6.02, locked=True)
    y = (0.05, 0.0, 0.4, 0.0)
    assert evaluate(P0, (1, 0, 1, 1), y, 1.3).dd1 == evaluate(Ps, (1, 0, 1, 1), y, 1.3).dd1
    # a vanishing co-moving load is a vanishing perturbation of Housner's block (O(m_N / M))
    Pe = uniform_column(1e-9)
    assert evaluate(Pe, (1, 0, 1, 1), y, 1.3).dd1 == pytest.approx(
        evaluate(Ps, (1, 0, 1, 1), y, 1.3).dd1, rel=1e-8)
    # m2 -> 0, N -> 0, free to separate: Part 1 rocks as Housner's block (quarter period)
    P = co(thickness=T, h1=0.14, m1=6.05, h2=0.14, m2=6.05e-7, top_load=6.05e-7 * G)
    al1 = math.atan(T / 0.14)
    res = integrate_rocking(P, TableMotion(), Settings(duration=0.3), (0.5 * al1, 0.5 * al1, 0, 0))
    base = next(e for e in res.events if e["kind"] == "impact_base")
    ref = an.free_rocking_quarter_period(RockingParams(thickness=T, h1=0.07, m1=1.0, h2=0.07,
                                                        m2=1.0, locked=True), 0.5 * al1)[0]
    assert base["t"] == pytest.approx(ref, rel=1e-4)   # perturbation O(m2/m1) = 1e-7


def _bracket(P, thr, first_after):
    """Below 0.99 thr: rest for 3 cycles; above 1.01 thr: lifts into ``first_after`` when a(t)
    first reaches -thr (a(t) = -peak sin(w t))."""
    f = 2.8
    below = integrate_rocking(P, SineMotion(0.99 * thr / (2 * math.pi * f) ** 2, f, 3), Settings(duration=1.2))
    assert set(below.pattern) == {"rest"} and not below.events
    above = integrate_rocking(P, SineMotion(1.01 * thr / (2 * math.pi * f) ** 2, f, 3), Settings(duration=0.2))
    first = above.events[0]
    assert first["before"] == "rest" and first["after"] == first_after
    assert first["t"] == pytest.approx(math.asin(1 / 1.01) / (2 * math.pi * f), abs=2e-6)


@pytest.mark.parametrize("top_contact", ["sliding", "co-moving"])
@pytest.mark.parametrize("model", ["II", "III"])
def test_uplift_threshold_of_each_top_contact_brackets_the_simulated_onset(model, top_contact):
    """Closed forms (docs/rocking_model.md section 4): sliding (g M T/2 + N T + mu N H)/(M z_G),
    co-moving (g M T/2 + N T)/(M z_G + m_N H); the simulation leaves rest between 0.99 and 1.01 x."""
    P = RockingParams(**(MODEL_II if model == "II" else MODEL_III), top_load=N_TESTS,
                      top_friction=0.81, top_contact=top_contact)
    M, zG, H = P.mass, an.centre_of_mass_height(P), P.height
    if top_contact == "sliding":
        ref = (G * M * T / 2 + N_TESTS * T + 0.81 * N_TESTS * H) / (M * zG)
    else:
        ref = (G * M * T / 2 + N_TESTS * T) / (M * zG + N_TESTS / G * H)
    thr = an.uplift_thresholds(P)
    assert thr["whole"] == pytest.approx(ref, rel=1e-12) and thr["first_pattern"] == "3"
    _bracket(P, thr["governing"], "3A")


def test_comoving_upper_part_lifts_first_when_its_threshold_is_lower():
    """A heavy squat Part 1 under a slender Part 2: Pattern 4 governs,
    (g m2 T/2 + N T)/(m2 H2/2 + m_N H2) < the whole wall's; onset bracketed, into 4A."""
    P = co(thickness=T, h1=0.05, m1=50.0, h2=0.3, m2=2.0, top_load=5.0)
    thr = an.uplift_thresholds(P)
    ref = (G * 2.0 * T / 2 + 5.0 * T) / (2.0 * 0.15 + 5.0 / G * 0.3)
    assert thr["first_pattern"] == "4" and thr["upper"] == pytest.approx(ref, rel=1e-12)
    _bracket(P, thr["governing"], "4A")


@pytest.mark.parametrize("init", [(0.02, 0.05), (0.02, -0.03), (0.01, 0.0)])
def test_comoving_energy_conserved_through_impacts_with_restitution_one(init):
    """e = 1, no base motion: E = KE (beam included) + V constant through base, interface and
    beam (top-corner switch) impacts."""
    P = co(**MODEL_II, top_load=N_TESTS)
    res = integrate_rocking(P, TableMotion(), Settings(duration=2.0, restitution=1.0), (*init, 0, 0))
    assert res.stats["impacts_base"] >= 4 and res.stats["impacts_interface"] >= 4
    assert res.stats["impacts_top"] >= 4
    ke, v = energy_arrays(P, res.theta1, res.theta2, res.omega1, res.omega2,
                          res.mode[:, 0], res.mode[:, 1], res.mode[:, 3])
    E = ke + v
    # measured drift <= 5e-9 (rtol 1e-10); a plastic impact loses >= 5 % here
    assert np.max(np.abs(E - E[0])) < 1e-7 * E[0]


def test_comoving_housner_impacts_only_dissipate():
    P = co(**MODEL_III, top_load=N_TESTS)
    res = integrate_rocking(P, TableMotion(), Settings(duration=1.5), (0.02, -0.03, 0, 0))
    ke, v = energy_arrays(P, res.theta1, res.theta2, res.omega1, res.omega2,
                          res.mode[:, 0], res.mode[:, 1], res.mode[:, 3])
    E = ke + v
    assert np.all(np.diff(E) <= 1e-8 * E[0]) and E[-1] < 0.5 * E[0]
    assert res.stats["inconsistent_impacts"] == 0 and res.stats["tension_impulses"] == 0


def test_summary_reports_the_thresholds_of_the_chosen_top_contact(tmp_path):
    import yaml

    from dem_cli.commands.rocking import run_rocking_case_file

    case = {"name": "co-moving", "rocking": {
        "thickness": 0.05, "lower": {"height": 0.175, "mass": 6.72},
        "upper": {"height": 0.21, "mass": 14.11}, "top_load": 58.8, "top_friction": 0.81,
        "top_contact": "co-moving"},
        "loading": {"type": "shake", "direction": [0, 1, 0], "frequency": 2.2,
                    "amplitude": 0.00646, "cycles": 3},
        "run": {"duration": 1.5, "output_interval": 0.002}}
    p = tmp_path / "c.yaml"
    p.write_text(yaml.safe_dump(case))
    assert run_rocking_case_file(p, tmp_path / "o", plots=False, echo=lambda *_: None,
                                 err=lambda *_: None) == 0
    s = json.loads((tmp_path / "o" / "summary.json").read_text())
    cf = s["closed_form"]
    P = co(**MODEL_III, top_load=58.8)
    assert cf["top_contact"] == "co-moving" and s["model"]["top_contact"] == "co-moving"
    assert cf["uplift_threshold_m_s2"] == pytest.approx(an.uplift_threshold(P), rel=1e-12)
    assert cf["uplift_threshold_upper_m_s2"] == pytest.approx(an.uplift_threshold(P, "upper"))
    assert cf["housner_restitution_locked"] == pytest.approx(an.housner_restitution(P))
    assert s["first_uplift_time"] is not None          # 1.23 m/s2 > 1.18 m/s2: it rocks
    assert 0 <= s["top_friction_demand"]["flow_max_abs_H_over_V"] < 0.81


def test_dem_sweep_comparison_reads_the_stored_dem_sweep():
    """studies.two_body.vs_dem_sweep (results/two-body/README.md section 9): the DEM's Model II y
    4.0 m/s2 sweep is read from results/shake/ (no DEM run); the two-body model at the same point
    stays at rest with the sliding roof (4.0 < 8.36 m/s2), overturns with the co-moving one at
    2.8 Hz, and the DEM's ds amplification is computed on a co-moving run that rocks to the end."""
    from studies.two_body import vs_dem_sweep as dc

    sw, dem = dc.load_dem()
    assert sw["peak_acceleration_m_s2"] == 4.0 and [r["f"] for r in dem] == [1.8, 2.0, 2.4, 2.8, 3.2, 3.6]
    assert dem[3]["A_ds"] == pytest.approx(1.5916, abs=1e-4)
    assert dc.Z_S == pytest.approx(0.2275)
    sl = dc.run_point(dc.params("sliding"), 2.8, 4.0, 10, 1.0)
    assert sl["uplift"] is None and sl["max_abs_ds"] == 0.0
    co = dc.run_point(dc.params("co-moving"), 2.8, 4.0, 10, 1.0)
    assert co["status"] == "collapsed" and co["t_end"] < 10 / 2.8
    rocks = dc.run_point(dc.params("co-moving"), 5.0, 4.0, 10, 1.0)
    assert rocks["status"] == "ok" and 1.0 < rocks["A_ds"] < 2.0
