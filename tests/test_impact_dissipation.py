"""Measuring functions of studies/impact_dissipation/ against closed forms (no Taichi; a few
seconds).  The DEM runs themselves are the study's (results/prediction/impact-dissipation)."""

from __future__ import annotations

import math

import numpy as np
import pytest
from scipy.integrate import solve_ivp

from studies.impact_dissipation.physics import (G, amplitude_after_impact, half_cycle_peaks,
                                                housner_r, housner_r_block, impact_ratios,
                                                omega_ratios, rigid_impact_r, rocking_energy)
from studies.impact_dissipation.two_body import two_body_forced, two_body_free, two_body_params


def test_housner_r_known_values():
    assert housner_r(0.0) == 1.0
    # b/h = 1/4: 1 - 1.5 sin^2(atan 0.25) = 1 - 1.5 / 17 (docs/engine.md: 0.912)
    assert housner_r_block(0.1, 0.4) == pytest.approx(1 - 1.5 / 17, rel=1e-12)
    assert housner_r_block(0.1, 0.4) == pytest.approx(0.912, abs=5e-4)
    # the excited portion's b/h = 50/280 (sin^2 alpha = 25 / 809)
    assert housner_r_block(0.05, 0.28) == pytest.approx(1 - 1.5 * 25 / 809, rel=1e-12)


def test_general_impact_reduces_to_housner_and_to_the_two_body_pair():
    b, h, m = 0.05, 0.28, 7.0
    i_g = m * (b * b + h * h) / 12
    assert rigid_impact_r(m, i_g, b / 2, h / 2, b) == pytest.approx(housner_r_block(b, h), rel=1e-12)
    # the locked Table 5.1 pair: r = 1 - M T^2 / (2 I_O) (dem.rocking.analysis)
    from dem.rocking.analysis import centre_of_mass_height, housner_restitution
    P = two_body_params("table-5.1")
    zg = centre_of_mass_height(P)
    i_g = (P.Ic1 + P.m1 * (P.h1 / 2 - zg) ** 2 + P.Ic2 + P.m2 * (P.h1 + P.h2 / 2 - zg) ** 2)
    assert rigid_impact_r(P.mass, i_g, P.thickness / 2, zg, P.thickness) == pytest.approx(
        housner_restitution(P), rel=1e-12)
    # an off-centre body: the impact on the far edge loses more than on the near one
    assert rigid_impact_r(m, i_g, 0.03, 0.1, 0.15) < rigid_impact_r(m, i_g, 0.03, 0.1, 0.05)


def test_rocking_energy_is_the_rise_of_the_centre_of_mass():
    b, h, th = 0.05, 0.28, 0.07
    R, al = 0.5 * math.hypot(b, h), math.atan2(b, h)
    assert rocking_energy(th, b / 2, h / 2, 2.0) == pytest.approx(
        2.0 * G * R * (math.cos(al - th) - math.cos(al)), rel=1e-12)
    assert rocking_energy(-th, b / 2, h / 2) == rocking_energy(th, b / 2, h / 2)
    assert rocking_energy(1e-7, b / 2, h / 2) == pytest.approx(G * b / 2 * 1e-7, rel=1e-5)


def test_amplitude_map():
    c, z, th0 = 0.025, 0.14, 0.08
    assert amplitude_after_impact(th0, 1.0, c, z) == pytest.approx(th0, rel=1e-12)
    th1 = amplitude_after_impact(th0, 0.9, c, z)
    assert rocking_energy(th1, c, z) == pytest.approx(0.81 * rocking_energy(th0, c, z), rel=1e-10)
    # small amplitudes: the amplitude ratio tends to r^2
    assert amplitude_after_impact(1e-6, 0.9, c, z) / 1e-6 == pytest.approx(0.81, rel=1e-4)


def test_half_cycle_peaks_alternating_and_one_sided():
    q = 0.8
    t = np.linspace(0.0, 8.0, 16001)
    k = np.floor(t).astype(int)
    lobes = 0.1 * q ** k * np.sin(np.pi * t)         # alternating sign, one lobe per second
    tp, pk = half_cycle_peaks(t, lobes)
    assert len(pk) == 8
    assert np.allclose(tp, np.arange(8) + 0.5)
    assert np.allclose(pk[1:] / pk[:-1], -q)
    # bounces on one side (returns to 0 without crossing)
    tp, pk = half_cycle_peaks(t, np.abs(lobes))
    assert len(pk) == 8 and np.allclose(pk[1:] / pk[:-1], q)
    # a last lobe that never turned back is not a half cycle; the rattle below the floor is gone
    tp, pk = half_cycle_peaks(t[t < 7.5], np.abs(lobes)[t < 7.5], rel_floor=0.25)
    assert np.allclose(pk, 0.1 * q ** np.arange(7)[0.1 * q ** np.arange(7) > 0.025])


def test_impact_ratios_recover_the_restitution():
    cp, cn, z = (0.03, 0.18), (0.02, 0.18), 0.18
    peaks = [0.09]
    for k in range(6):           # alternate pivots: + lobes about cp, - lobes about cn
        c0 = cp if peaks[-1] > 0 else cn
        c1 = cn if peaks[-1] > 0 else cp
        a = amplitude_after_impact(abs(peaks[-1]), 0.7, c0[0], z, c1[0], z)
        peaks.append(-math.copysign(a, peaks[-1]))
    out = impact_ratios(peaks, cp, cn)
    assert np.allclose(out["r_eq"], 0.7, rtol=1e-9)
    assert np.allclose(out["r_eq_same_side"], 0.7, rtol=1e-9)
    assert out["mean_amplitude_ratio"] < 0.7      # amplitudes fall faster than r at this size
    # with a wrong inner pivot r_eq is off, the same-side estimate between outer lobes is not
    wrong = impact_ratios(peaks, cp, (0.05, 0.18))
    assert not np.allclose(wrong["r_eq"], 0.7, rtol=1e-3)
    assert np.allclose(wrong["r_eq_same_side"][::2], 0.7, rtol=1e-9)
    assert not np.allclose(wrong["r_eq_same_side"][1::2], 0.7, rtol=1e-3)


def _housner_history(r, b=0.05, h=0.28, frac=0.5, dt=1e-4, n_imp=5):
    """A rigid block rocking freely with restitution r, integrated event by event (Housner)."""
    al, R = math.atan2(b, h), 0.5 * math.hypot(b, h)
    p2 = 3 * G / (4 * R)
    ts, ths, ws = [], [], []
    y, t0 = [frac * al, 0.0], 0.0
    hit = lambda _t, y: y[0]  # noqa: E731
    hit.terminal = True
    for _ in range(n_imp):
        s = 1.0 if (y[0] > 0 or (y[0] == 0 and y[1] > 0)) else -1.0
        sol = solve_ivp(lambda _t, y: [y[1], -p2 * math.sin(s * al - y[0])], [t0, t0 + 5],
                        y, events=hit, rtol=1e-11, atol=1e-13, dense_output=True)
        te = sol.t_events[0][-1] if len(sol.t_events[0]) else sol.t[-1]
        tt = np.arange(math.ceil(t0 / dt) * dt, te, dt)
        yy = sol.sol(tt)
        ts.append(tt)
        ths.append(yy[0])
        ws.append(yy[1])
        y = [0.0, r * sol.y_events[0][-1][1]]
        t0 = te
        y[0] = 1e-15 * math.copysign(1.0, y[1])
    return np.concatenate(ts), np.concatenate(ths), np.concatenate(ws), al


def test_measures_on_a_rigid_rocking_history():
    r = 0.9
    t, th, w, al = _housner_history(r)
    _, pk = half_cycle_peaks(t, th)
    out = impact_ratios(pk, (0.025, 0.14))
    assert len(out["r_eq"]) >= 3
    assert np.allclose(out["r_eq"], r, atol=2e-4)       # sampling of the peaks only
    wr = omega_ratios(th, w, 0.025, 0.14, (0.05 ** 2 + 0.28 ** 2) / 3, 0.05 * 0.5 * al)
    assert len(wr) >= 3 and np.allclose(wr, r, atol=1e-3)


def test_two_body_restitution_number_is_the_energy_ratio():
    """dem.rocking's plastic map on the locked-like pair gives Housner's r of the pair; a number
    e gives e (the transfer of the DEM's measured loss to the reduced model)."""
    from dem.rocking.analysis import housner_restitution
    P = two_body_params("table-5.1")
    plastic = two_body_free(P, (0.02, 0.02, 0.0, 0.0), duration=1.0)
    assert plastic["mean_r_eq"] == pytest.approx(housner_restitution(P), abs=2e-3)
    e = two_body_free(P, (0.02, 0.02, 0.0, 0.0), restitution=0.98, duration=1.0)
    assert e["mean_r_eq"] == pytest.approx(0.98, abs=2e-3)


def test_two_body_stays_at_rest_at_the_thesis_level():
    """1.53 m/s2 is below the thesis' two-body threshold (8.36 m/s2): no motion, whatever the
    impact law."""
    P = two_body_params("table-5.1", 58.8, 0.81, "sliding")
    for law in ("housner", 0.5):
        row = two_body_forced(P, 2.8, 1.53, law, cycles=3)
        assert row["status"] == "ok" and row["max_abs_d_m"] == 0.0 and row["amplification"] == 0.0
