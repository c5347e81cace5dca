"""Physics tests of the two-body rocking model (dem.rocking).

Every expected value comes from an independent closed form (Housner 1963 for one block, static
moment balances) or an independent computation (Newton-Euler with constraint forces in maximal
coordinates; a ten-line Housner integrator).  Tolerances: round-off (1e-9 relative) where the
comparison is algebraic; the integrator's measured error otherwise (event times converge to
~1e-9 s, energy to ~1e-9 relative with rtol = 1e-10, see results/two-body/README.md), with a margin.
"""

from __future__ import annotations

import math

import numpy as np
import pytest
from scipy.integrate import solve_ivp

from dem.rocking import analysis as an
from dem.rocking.energy import energy, energy_arrays
from dem.rocking.equations import evaluate, make_rhs
from dem.rocking.integrate import Settings, integrate_rocking
from dem.rocking.maximal import constrained_acc_maximal
from dem.rocking.params import RockingParams
from dem.rocking.patterns import pattern_name
from dem.table_motion import SineMotion, TableMotion

T = 0.05
MODEL_II = dict(thickness=T, h1=0.14, m1=6.05, h2=0.14, m2=9.41)
MODEL_III = dict(thickness=T, h1=0.175, m1=6.72, h2=0.21, m2=14.11)


def uniform(h1=0.14, h2=0.14, rho=43.0, **kw):
    """Two parts of the same mass per unit height: locked, they are one uniform rectangle."""
    return RockingParams(thickness=T, h1=h1, m1=rho * h1, h2=h2, m2=rho * h2, **kw)


ALL_MODES = [  # (b, c, tau): 1A 1B 2A 2B 3A 3B 4A 4B, sliding or sticking top
    (1, 1, 1), (-1, -1, -1), (1, -1, 1), (-1, 1, -1), (1, 0, 1), (-1, 0, -1), (0, 1, 1),
    (0, -1, -1), (1, 1, 0), (1, -1, 0), (1, 0, 0), (0, 1, 0),
]


def random_state(rng, b, c, tau):
    th1 = b * rng.uniform(0.01, 0.2) if b else 0.0
    phi = c * rng.uniform(0.01, 0.2) if c else 0.0
    w1 = rng.normal() if b else 0.0
    wphi = rng.normal() if c else 0.0
    if tau == 0 and c == 0:
        w1 = 0.0          # a stuck top in Pattern 3: the wall cannot move
    if tau == 0 and b == 0:
        wphi = 0.0
    return (th1, phi, w1, wphi)


@pytest.mark.parametrize("load_point", ["corner", "centre"])
@pytest.mark.parametrize("b,c,tau", ALL_MODES)
def test_lagrangian_equations_match_newton_euler(b, c, tau, load_point):
    """The closed-form Lagrangian EOMs equal Newton-Euler with contact constraints (KKT)."""
    P = RockingParams(**MODEL_II, top_load=58.8, top_friction=0.81, load_point=load_point)
    rng = np.random.default_rng(abs(hash((b, c, tau, load_point))) % 2**32)
    for _ in range(5):
        y = random_state(rng, b, c, tau)
        th2 = y[0] + y[1]
        sig = 1 if th2 > 0 else -1
        mode = (b, c, tau, sig)
        a = 3.0 * rng.normal()
        e = evaluate(P, mode, y, a)
        acc, lam = constrained_acc_maximal(P, mode, y, a, e.F)
        scale = max(1.0, abs(acc[2]), abs(acc[5]))
        assert abs(acc[2] - e.dd1) < 1e-9 * scale
        assert abs(acc[5] - e.dd2) < 1e-9 * scale
        # the lock multipliers are the corner normal forces at the - corner
        if c == 0:
            assert abs(e.iface[1] - lam["if_n-"]) < 1e-9 * max(1.0, abs(lam["if_n-"]))
        if b == 0:
            assert abs(e.base[1] - lam["base_z-"]) < 1e-9 * max(1.0, abs(lam["base_z-"]))


@pytest.mark.parametrize("b,c,tau", [(1, 1, 1), (1, -1, -1), (-1, 1, 1), (1, 0, 1), (-1, 0, -1),
                                     (0, 1, 1), (0, -1, -1)])
def test_fast_rhs_equals_reference(b, c, tau):
    P = RockingParams(**MODEL_III, top_load=58.8, top_friction=0.81)
    rng = np.random.default_rng(7)
    for _ in range(5):
        y = random_state(rng, b, c, tau)
        sig = 1 if y[0] + y[1] > 0 else -1
        mode = (b, c, tau, sig)
        a = rng.normal()
        e = evaluate(P, mode, y, a, want_forces=False)
        f = make_rhs(P, mode, lambda t: a)(0.0, y)
        assert np.allclose(f, [y[2], y[3], e.dd1, e.dd2 - e.dd1], rtol=1e-12, atol=1e-12)


def test_locked_uniform_pair_is_housners_equation():
    """I_O th'' = -M g R sin(alpha - th) - M a R cos(alpha - th) (Housner 1963), theta > 0."""
    P = uniform(locked=True)
    M, H = P.mass, P.height
    R, al = 0.5 * math.hypot(T, H), math.atan(T / H)
    IO = M * (T * T + H * H) / 3
    for th, w, a in [(0.01, 0.3, 1.0), (0.1, -1.0, -2.0), (0.3, 0.0, 0.5)]:
        e = evaluate(P, (1, 0, 1, 1), (th, 0.0, w, 0.0), a)
        housner = (-M * 9.81 * R * math.sin(al - th) - M * a * R * math.cos(al - th)) / IO
        assert e.dd1 == pytest.approx(housner, rel=1e-12)
        mirrored = evaluate(P, (-1, 0, -1, -1), (-th, 0.0, -w, 0.0), -a)
        assert mirrored.dd1 == pytest.approx(-housner, rel=1e-12)


def test_uplift_threshold_closed_form_uniform_block():
    """Housner: a block lifts when |a| > g tan(alpha) = g T / H; thesis eq. 5-4 with N = 0."""
    P = uniform()
    assert an.uplift_threshold(P) == pytest.approx(9.81 * T / P.height, rel=1e-12)
    assert an.thesis_uplift_threshold(P) == pytest.approx(9.81 * T / P.height, rel=1e-12)


@pytest.mark.parametrize("params", [
    dict(MODEL_II, top_load=0.0, top_friction=0.81),
    dict(MODEL_II, top_load=58.8, top_friction=0.81),
    dict(MODEL_III, top_load=58.8, top_friction=0.81),
    dict(MODEL_II, top_load=58.8, top_friction=0.81, load_point="centre"),
])
def test_uplift_from_rest_at_the_closed_form_threshold(params):
    """Rest -> Pattern 3 exactly when |a| first exceeds the static moment balance."""
    P = RockingParams(**params)
    thr = an.uplift_threshold(P)
    f = 2.8
    below = integrate_rocking(P, SineMotion(0.99 * thr / (2 * math.pi * f) ** 2, f, 3), Settings(duration=1.2))
    assert set(below.pattern) == {"rest"} and not below.events
    above = integrate_rocking(P, SineMotion(1.01 * thr / (2 * math.pi * f) ** 2, f, 3), Settings(duration=0.2))
    first = above.events[0]
    # a(t) = -peak sin(w t) reaches -thr at w t = asin(thr / peak): Pattern 3A (top towards +x)
    t_expected = math.asin(1 / 1.01) / (2 * math.pi * f)
    assert first["before"] == "rest" and first["after"] == "3A"
    assert first["t"] == pytest.approx(t_expected, abs=2e-6)  # NUDGE = 1e-6 s after the root


def test_free_rocking_period_and_restitution_match_housner():
    """Locked uniform pair, N = 0, released from theta0 = alpha/2 at rest."""
    P = uniform(locked=True)
    al = math.atan(T / P.height)
    th0 = 0.5 * al
    exact, linear = an.free_rocking_quarter_period(P, th0)
    res = integrate_rocking(P, TableMotion(), Settings(duration=1.2, restitution=1.0), (th0, th0, 0, 0))
    imp = [e for e in res.events if e["kind"] == "impact_base"]
    assert len(imp) >= 3
    assert imp[0]["t"] == pytest.approx(exact, rel=1e-6)
    assert imp[0]["t"] == pytest.approx(linear, rel=0.01)         # Housner's linearised formula
    # with e = 1 the free-rocking period (two impacts) is 4 quarter periods
    assert imp[2]["t"] - imp[0]["t"] == pytest.approx(4 * exact, rel=1e-6)
    # plastic impact: energy ratio r^2, r = 1 - 3/2 sin^2(alpha)
    res = integrate_rocking(P, TableMotion(), Settings(duration=0.5), (th0, th0, 0, 0))
    e0 = next(e for e in res.events if e["kind"] == "impact_base")
    r = 1 - 1.5 * math.sin(al) ** 2
    assert e0["ke_after"] / e0["ke_before"] == pytest.approx(r * r, rel=1e-9)
    assert e0["after"] == "3B"


def test_restitution_of_a_nonuniform_locked_pair():
    """r = 1 - M T^2 / (2 I_O) for the composite (angular momentum about the new corner)."""
    P = RockingParams(**MODEL_III, locked=True)
    res = integrate_rocking(P, TableMotion(), Settings(duration=0.5), (0.05, 0.05, 0, 0))
    e0 = next(e for e in res.events if e["kind"] == "impact_base")
    IO = P.IO1 + P.IO2 + P.m2 * (P.h1 ** 2 + P.h1 * P.h2)
    r = 1 - P.mass * T * T / (2 * IO)
    assert e0["ke_after"] / e0["ke_before"] == pytest.approx(r * r, rel=1e-9)


def test_vanishing_upper_mass_leaves_housners_block():
    """m2 -> 0 (not locked): Part 1 rocks as Housner's block of height H1."""
    P = RockingParams(thickness=T, h1=0.14, m1=6.05, h2=0.14, m2=6.05e-7)
    al1 = math.atan(T / 0.14)
    th0 = 0.5 * al1
    res = integrate_rocking(P, TableMotion(), Settings(duration=0.3), (th0, th0, 0, 0))
    base = next(e for e in res.events if e["kind"] == "impact_base")
    ref = an.free_rocking_quarter_period(RockingParams(thickness=T, h1=0.07, m1=1.0, h2=0.07,
                                                        m2=1.0, locked=True), th0)[0]
    assert base["t"] == pytest.approx(ref, rel=1e-4)   # perturbation O(m2/m1) = 1e-7
    r = 1 - 1.5 * math.sin(al1) ** 2
    assert base["ke_after"] / base["ke_before"] == pytest.approx(r * r, rel=1e-4)


def _housner_reference(A, f, t_end):
    """A minimal independent Housner integrator (uniform block T x 0.28 m): impact times."""
    H = 0.28
    exc = SineMotion(A, f, 50)
    al, R = math.atan(T / H), 0.5 * math.hypot(T, H)
    p2 = 3 * 9.81 / (4 * R)
    r = 1 - 1.5 * math.sin(al) ** 2
    t = math.asin(9.81 * math.tan(al) / exc.peak_acceleration) / exc.omega
    y, s, out = [0.0, 0.0], 1, []
    while t < t_end:
        def rhs(tt, yy, s=s):
            return [yy[1], -p2 * (math.sin(s * al - yy[0]) + exc.acceleration_at(tt) / 9.81 * math.cos(s * al - yy[0]))]

        def hit(tt, yy, s=s):
            return s * yy[0]
        hit.terminal, hit.direction = True, -1
        sol = solve_ivp(rhs, (t, t_end), [y[0] + s * 1e-15, y[1]], events=[hit], rtol=1e-11,
                        atol=1e-13, max_step=0.005)
        if sol.status != 1:
            break
        t, y, s = sol.t_events[0][0], [0.0, r * sol.y_events[0][0][1]], -s
        out.append(t)
    return np.array(out)


def test_forced_rocking_matches_an_independent_housner_integrator():
    P = uniform(locked=True)
    A, f = 3.0e-3, 4.0          # peak 1.89 m/s2 = 1.08 g tan(alpha): steady rocking
    res = integrate_rocking(P, SineMotion(A, f, 50), Settings(duration=3.0))
    ours = np.array([e["t"] for e in res.events if e["kind"] == "impact_base"])
    ref = _housner_reference(A, f, 3.0)
    n = min(len(ours), len(ref))
    assert n >= 5 and abs(len(ours) - len(ref)) <= 1
    assert np.max(np.abs(ours[:n] - ref[:n])) < 1e-6


@pytest.mark.parametrize("params", [dict(top_load=0.0), dict(top_load=58.8, top_friction=0.0)])
def test_energy_conserved_through_impacts_with_restitution_one(params):
    """No base motion, e = 1, no friction (N conservative): E = KE + V stays constant."""
    P = RockingParams(**MODEL_II, **params)
    res = integrate_rocking(P, TableMotion(), Settings(duration=2.0, restitution=1.0), (0.02, 0.05, 0, 0))
    assert res.stats["impacts_base"] >= 2 and res.stats["impacts_interface"] >= 2
    ke, v = energy_arrays(P, res.theta1, res.theta2, res.omega1, res.omega2,
                          res.mode[:, 0], res.mode[:, 1], res.mode[:, 3])
    E = ke + v
    # measured drift ~3e-10 (rtol 1e-10); 1e-7 leaves margin and still catches any wrong
    # impact map (a Housner impact of this wall loses ~8 % per impact)
    assert np.max(np.abs(E - E[0])) < 1e-7 * E[0]


def test_top_friction_only_dissipates():
    P = RockingParams(**MODEL_II, top_load=20.0, top_friction=0.3)
    res = integrate_rocking(P, TableMotion(), Settings(duration=2.0), (0.05, 0.12, 0, 0))
    ke, v = energy_arrays(P, res.theta1, res.theta2, res.omega1, res.omega2,
                          res.mode[:, 0], res.mode[:, 1], res.mode[:, 3])
    E = ke + v
    assert np.all(np.diff(E) <= 1e-9 * E[0])
    assert E[-1] < 0.5 * E[0]


@pytest.mark.parametrize("factor,stuck", [(1.02, True), (0.98, False)])
def test_top_friction_holds_a_tilted_wall_per_static_balance(factor, stuck):
    """Released tilted (Pattern 3A) the wall stays if mu N exceeds the static requirement

    F_req = [M g (T/2 cos th - z_G sin th) + N (T cos th - H sin th)] / (H cos th + T sin th),
    the moment balance about the pivot with N and the friction at the raised top corner.
    """
    N, th = 58.8, 0.02
    base = RockingParams(**MODEL_II, top_load=N)
    zG, H, M = an.centre_of_mass_height(base), base.height, base.mass
    F_req = (M * 9.81 * (T / 2 * math.cos(th) - zG * math.sin(th))
             + N * (T * math.cos(th) - H * math.sin(th))) / (H * math.cos(th) + T * math.sin(th))
    P = RockingParams(**MODEL_II, top_load=N, top_friction=factor * F_req / N)
    res = integrate_rocking(P, TableMotion(), Settings(duration=0.3), (th, th, 0, 0))
    if stuck:
        assert np.all(res.theta1 == th) and np.all(res.top_stick)
    else:
        assert res.theta1[-1] < th and not res.top_stick[-1]


def test_mirror_symmetry():
    """Mirroring the excitation mirrors the response: theta -> -theta, A <-> B."""
    class Mirrored(SineMotion):
        def acceleration_at(self, t):
            return -super().acceleration_at(t)

        def acceleration(self, t):
            return -super().acceleration(t)

    P = RockingParams(**MODEL_II)
    A, f = 2.0 / (2 * math.pi * 2.8) ** 2, 2.8
    r1 = integrate_rocking(P, SineMotion(A, f, 50), Settings(duration=3.0))
    r2 = integrate_rocking(P, Mirrored(A, f, 50), Settings(duration=3.0))
    swap = str.maketrans("AB", "BA")
    assert len(r1.events) == len(r2.events) >= 4
    assert [e["after"].translate(swap) for e in r1.events] == [e["after"] for e in r2.events]
    assert np.allclose(r1.theta1, -r2.theta1, atol=1e-9)
    assert np.allclose(r1.theta2, -r2.theta2, atol=1e-9)


def test_free_rocking_ends_at_rest():
    """Housner impacts: the accumulation of impacts ends (Zeno lock) and the wall is at rest."""
    P = RockingParams(**MODEL_II, top_load=58.8, top_friction=0.0)
    res = integrate_rocking(P, TableMotion(), Settings(duration=6.0), (0.03, 0.05, 0, 0))
    assert res.status == "ok"
    assert res.pattern[-1] == "rest" and res.theta1[-1] == 0 and res.theta2[-1] == 0
    ke, v = energy(P, tuple(res.mode[-1]), (0.0, 0.0, 0.0, 0.0))
    assert ke == 0 and abs(v) < 1e-12


def test_model_iii_at_2p2_hz_completes():
    """The thesis' solver failed on Model III at 2.2 Hz (6.46 mm).  Without top load the model
    rocks there (1.23 m/s2 > threshold 1.13 m/s2); both must finish all 50 cycles cleanly."""
    for N in (58.8, 0.0):
        P = RockingParams(**MODEL_III, top_load=N, top_friction=0.81)
        res = integrate_rocking(P, SineMotion(6.46e-3, 2.2, 50), Settings(duration=50 / 2.2))
        assert res.status in ("ok", "collapsed")
        assert res.stats["inconsistent_impacts"] == 0 and res.stats["no_consistent_mode"] == 0
        if N == 0.0:
            assert res.stats["impacts_base"] >= 5


def test_pattern_names():
    assert [pattern_name(b, c) for b, c in [(1, 1), (-1, -1), (1, -1), (-1, 1), (1, 0),
                                            (-1, 0), (0, 1), (0, -1), (0, 0)]] == \
        ["1A", "1B", "2A", "2B", "3A", "3B", "4A", "4B", "rest"]


def test_random_configurations_run_cleanly():
    """Robustness: random parts, loads, friction, load points, restitutions, locks, excitations
    and initial tilts; every run ends ok or collapsed, with every event resolved consistently."""
    from dem.rocking.integrate import RockingError

    rng = np.random.default_rng(2016)
    for _ in range(25):
        P = RockingParams(
            thickness=rng.uniform(0.03, 0.1), h1=rng.uniform(0.05, 0.4), m1=rng.uniform(1, 30),
            h2=rng.uniform(0.05, 0.4), m2=rng.uniform(0.5, 30),
            top_load=float(rng.choice([0.0, rng.uniform(1, 80)])),
            top_friction=float(rng.choice([0.0, rng.uniform(0.05, 1.0)])),
            load_point=str(rng.choice(["corner", "centre"])), locked=bool(rng.random() < 0.1))
        thr = min(an.uplift_threshold(P), an.uplift_threshold(P, "upper"))
        f = rng.uniform(1.5, 8)
        exc = SineMotion(rng.uniform(0.8, 2.5) * thr / (2 * math.pi * f) ** 2, f, 10)
        a = rng.uniform(-0.05, 0.05)
        init = (a, a + rng.uniform(-0.03, 0.03), 0, 0) if rng.random() < 0.3 else (0, 0, 0, 0)
        e = rng.choice(["housner", "0.8", "1.0"])
        try:
            res = integrate_rocking(P, exc, Settings(duration=10 / f + 0.5,
                                            restitution=e if e == "housner" else float(e)), init)
        except RockingError as err:  # pragma: no cover - the assertion message is the point
            pytest.fail(f"{P}: {err}")
        assert res.status in ("ok", "collapsed")
        assert res.stats["inconsistent_impacts"] == 0 and res.stats["no_consistent_mode"] == 0
