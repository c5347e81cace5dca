"""The hyperbolic joint closure law (dem.engine.laws, docs/engine.md section 4).

    p(d) = kn0 d / (1 - d/d_max),   kt(d) = kn0 / (1 - d/d_max)^2,
    e(d) = -kn0 d_max (d + d_max ln(1 - d/d_max)),      d(p) = p / (kn0 + p/d_max)

* the law's functions in a kernel against these closed forms (e also against scipy's quad of p,
  and de/dd = p), and their continuation beyond the closure the step is made for;
* a block resting on the table settles by d(m g / A) at two weights; a column of bricks closes
  joint k (k bricks above it) by d(k m g / A);
* a block dropped on the table: its deepest closure and rebound speed against an independent
  integration of the one-degree-of-freedom equation (scipy solve_ivp), and the energy balance
  stays closed as well as with the linear law;
* the critical step uses the tangent at closure_limit x d_max; a joint closing beyond it stops
  the run; the case file checks the new fields.
"""

import numpy as np
import pytest
import taichi as ti
from scipy.integrate import quad, solve_ivp

from dem import ti_runtime
from dem.case import CaseError, parse_case
from dem.engine import laws
from dem.engine.errors import SimulationError
from dem.engine.pair import HYPERBOLIC, PairMaterial, hyperbolic_tangent
from engine_helpers import constant_loads, make_sim

G = 9.81
KN0 = 1.0e8     # Pa/m: a soft seating joint (docs/engine.md: dry-joint closure tests)
DMAX = 1.0e-4   # m


def closure(p, kn0=KN0, dmax=DMAX):
    """Closure (m) of a hyperbolic joint under the pressure p (Pa): the inverse of p(d)."""
    return p / (kn0 + p / dmax)


def energy(d, kn0=KN0, dmax=DMAX):
    """e(d), J/m^2: kn0 d_max^2 (-x - ln(1 - x)), x = d/d_max; below x = 0.1 by the series
    sum_k>=2 x^k / k to 40 terms (the logarithm loses ~1/x of the digits there)."""
    x = np.asarray(d, float) / dmax
    k = np.arange(2, 42)
    series = (x[..., None] ** k / k).sum(axis=-1)
    closed = -x - np.log1p(-np.minimum(x, 0.999))
    return kn0 * dmax**2 * np.where(x < 0.1, series, closed)


nd = ti.types.ndarray


@ti.kernel
def _law(inp: nd(dtype=ti.f64, ndim=2), out: nd(dtype=ti.f64, ndim=2)):
    # inp row: kn0, d_max, d_lim, d  ->  out row: p, e, kt
    for i in range(inp.shape[0]):
        kn0, d_max, d_lim, d = inp[i, 0], inp[i, 1], inp[i, 2], inp[i, 3]
        out[i, 0] = laws.hyperbolic_pressure(kn0, d_max, d_lim, d)
        out[i, 1] = laws.hyperbolic_energy(kn0, d_max, d_lim, d)
        out[i, 2] = hyperbolic_tangent(kn0, d_max, d_lim, d)


def run_law(rows):
    ti_runtime.init()
    inp = np.array(rows, dtype=np.float64)
    out = np.zeros((len(inp), 3))
    _law(inp, out)
    return out


def test_law_functions_match_closed_forms():
    """p, e, kt on [0, d_lim] against the closed forms (e through log1p, exact to round-off; the
    kernel switches from a series to the logarithm at x = 0.05: both sides tested), e against
    the quadrature of p, and p = de/dd by central differences (step 1e-4 d_max: truncation
    ~(h/d_max)^2 kt'' terms, < 1e-6 relative)."""
    d_lim = 0.5 * DMAX
    x = np.array([0.0, 1e-8, 1e-4, 0.01, 0.049, 0.05, 0.051, 0.2, 0.4, 0.5])
    d = x * DMAX
    out = run_law([(KN0, DMAX, d_lim, di) for di in d])
    p_exact = KN0 * d / (1 - x)
    np.testing.assert_allclose(out[:, 0], p_exact, rtol=1e-14, atol=0.0)
    np.testing.assert_allclose(out[:, 2], KN0 / (1 - x) ** 2, rtol=1e-14)
    e_exact = energy(d)
    np.testing.assert_allclose(out[1:, 1], e_exact[1:], rtol=1e-13)
    assert out[0, 1] == 0.0
    for di, ei in zip(d[1:], out[1:, 1]):
        ref, err = quad(lambda s: KN0 * s / (1 - s / DMAX), 0.0, di, epsabs=0.0, epsrel=1e-13)
        assert abs(ei - ref) <= 1e-11 * ref + err
    h = 1e-4 * DMAX
    mid = np.array([0.1, 0.3, 0.45]) * DMAX
    e_pm = run_law([(KN0, DMAX, d_lim, m + s * h) for m in mid for s in (1.0, -1.0)])[:, 1]
    dedd = (e_pm[0::2] - e_pm[1::2]) / (2 * h)
    np.testing.assert_allclose(dedd, KN0 * mid / (1 - mid / DMAX), rtol=1e-6)


def test_law_continues_along_the_tangent_beyond_the_step_limit():
    """Beyond d_lim: p = p(d_lim) + kt(d_lim)(d - d_lim), e = e(d_lim) + p(d_lim) s + kt s^2/2
    (s = d - d_lim), kt frozen: the stiffness the step was made for is never exceeded."""
    d_lim = 0.5 * DMAX
    s = np.array([0.0, 0.1, 0.5, 0.9]) * DMAX  # up to 1.4 d_max: finite, no pole
    out = run_law([(KN0, DMAX, d_lim, d_lim + si) for si in s])
    p_lim, kt_lim = KN0 * d_lim / 0.5, KN0 / 0.25
    np.testing.assert_allclose(out[:, 0], p_lim + kt_lim * s, rtol=1e-14)
    np.testing.assert_allclose(out[:, 1], energy(d_lim) + p_lim * s + 0.5 * kt_lim * s**2,
                               rtol=1e-12)
    np.testing.assert_allclose(out[:, 2], kt_lim, rtol=1e-15)


def _hyper(**extra):
    return {"normal_stiffness": KN0, "normal_law": "hyperbolic", "max_closure": DMAX, **extra}


@pytest.mark.parametrize("mass", [4.0, 20.0])
def test_block_on_the_table_settles_by_the_closed_form_closure(mass):
    """A 0.2 x 0.2 x 0.1 m block rests on the table: p = m g / A = 981 Pa (x = d/d_max =
    0.09) and 4905 Pa (x = 0.33), d = p / (kn0 + p/d_max).  The patch bears uniformly, where the
    quadrature is exact, and the damped settling (zeta = 0.5, period ~6 ms) has died out after
    0.3 s: the centre's height is h/2 - d to round-off (z ~ 0.05 m, 1e-17 m; 1e-12 m allowed,
    1e-7 of d)."""
    size = 0.2
    sim = make_sim([{"size": [size, size, 0.1], "position": [0, 0, 0.05], "mass": mass}],
                   friction=0.8, **_hyper(closure_limit=0.8))
    sim.advance(int(round(0.3 / sim.dt)), constant_loads())
    d = 0.05 - sim.state.pos[0, 2]
    expect = closure(mass * G / size**2)
    assert abs(d - expect) < 1e-12, (d, expect)
    # the linear law at kn0 would have closed by p/kn0: the law is not linear here
    assert abs(mass * G / size**2 / KN0 - expect) > 0.08 * expect


def test_column_of_bricks_closes_each_joint_by_the_load_above_it():
    """Six small bricks (105 x 50 x 35 mm, 0.336 kg) stacked: the joint under brick i carries
    the n - i bricks above and including it, p_k = k m g / A with k = 1 (top) ... 6 (table),
    x = 0.05 ... 0.26.  Closure of joint k = h - (z_above - z_below) (table joint: h/2 - z_0)
    against d(p_k) after 1.1 s of settling (the contact damping is stiffness-proportional, so
    the column's lowest mode is damped least: measured 5e-6 of d left at 0.3 s, 1e-7 at 0.45 s,
    4e-12 at 1.05 s); tolerance 1e-12 m (4e-8 of the smallest closure)."""
    n, m, h = 6, 0.336, 0.035
    area = 0.105 * 0.05
    blocks = [{"size": [0.105, 0.05, h], "position": [0, 0, (k + 0.5) * h], "mass": m}
              for k in range(n)]
    sim = make_sim(blocks, friction=0.8, **_hyper())
    sim.advance(int(round(1.1 / sim.dt)), constant_loads())
    z = sim.state.pos[:n, 2]
    closures = np.concatenate([[h / 2 - z[0]], h - np.diff(z)])  # joint under brick 0 .. n-1
    loads = (n - np.arange(n)) * m * G / area
    np.testing.assert_allclose(closures, closure(loads), rtol=0.0, atol=1e-12)
    assert closures[0] > 4 * closures[-1]  # stiffening: 6 x the load, < 6 x the closure
    assert closures[0] < 6 * closures[-1]


def _drop_reference(mass, area, h0, zeta, t_end):
    """Independent integration of the block dropped from h0 (m) above the table: z the closure
    (> 0 in contact), m z'' = m g - A p(z) - c(z) z' with c = 2 zeta sqrt(kt(z) A m) (the
    engine's damping: zeta of critical at the tangent stiffness), the contact force never
    pulling.  Returns (deepest closure, rebound speed at the first separation)."""
    v0 = np.sqrt(2 * G * h0)

    def rhs(t, y):
        z, v = y
        if z <= 0.0:
            return [v, G]
        p = KN0 * z / (1 - z / DMAX)
        kt = KN0 / (1 - z / DMAX) ** 2
        f = area * p + 2 * zeta * np.sqrt(kt * area * mass) * v
        return [v, G - max(f, 0.0) / mass]

    def leave(t, y):
        return y[0] + 1e-15 if t > 1e-6 else 1.0
    leave.terminal, leave.direction = True, -1
    sol = solve_ivp(rhs, (0, t_end), [0.0, v0], rtol=1e-11, atol=1e-15, max_step=2e-6,
                    events=leave, dense_output=True)
    tt = np.linspace(0, sol.t[-1], 20001)
    return sol.sol(tt)[0].max(), -sol.y[1, -1]


@pytest.mark.parametrize("zeta", [0.0, 0.3])
def test_dropped_block_against_an_independent_integration(zeta):
    """A 2 kg block (0.1 m cube) dropped from 0.2 mm: deepest closure and rebound speed
    against solve_ivp of the same one-degree-of-freedom law.  Tolerance: the explicit step's
    error, O(omega dt) ~ 0.03 at safety 0.3 on the tangent at the deepest closure; 2 % on the
    depth, 3 % on the rebound speed (measured: depth 0.005 % at zeta 0, 0.37 % at 0.3; rebound
    0.16 % and 1.6 %; deepest closure 0.71 and 0.53 d_max).  With zeta = 0 the rebound speed equals
    the impact speed (no dissipation) in both."""
    mass, size, h0 = 2.0, 0.1, 2e-4
    case = parse_case({"name": "drop", "scene": {"blocks": [
        {"size": [size] * 3, "position": [0, 0, 0.05 + h0], "mass": mass}],
        "allow_floating": True}, "material": {"friction": 0.8, **_hyper(damping=zeta,
                                                                            closure_limit=0.9)},
        "run": {"duration": 1.0}})
    from dem.engine import Simulation
    from dem.run.build import joint_law, step_options
    from dem.scene import blocks_to_scene
    sim = Simulation(blocks_to_scene(case.scene.blocks), joint_law(case.material),
                     step_options(case.solver))
    loads = constant_loads()
    # fall to contact, then step through the impact
    t_fall = np.sqrt(2 * h0 / G)
    deepest, vz_out, touched = 0.0, None, False
    while sim.t < t_fall + 0.05:
        sim.advance(1, loads)
        d = 0.05 - sim.state.pos[0, 2]
        deepest = max(deepest, d)
        touched = touched or d > 0
        if touched and d < 0 and sim.state.vel[0, 2] > 0:
            vz_out = sim.state.vel[0, 2]
            break
    d_ref, v_ref = _drop_reference(mass, size**2, h0, zeta, 0.05)
    assert vz_out is not None
    assert abs(deepest - d_ref) < 0.02 * d_ref, (deepest, d_ref)
    assert abs(vz_out - v_ref) < 0.03 * v_ref, (vz_out, v_ref)
    if zeta == 0.0:
        assert abs(v_ref - np.sqrt(2 * G * h0)) < 1e-6 * v_ref


def _drop_balance(material, safety):
    """Largest |energy residual| and largest elastic energy (J) of a 2 kg block dropped from
    0.2 mm, stepped through its first impacts (0.02 s) at solver.safety ``safety``."""
    case = parse_case({"name": "drop", "scene": {"blocks": [
        {"size": [0.1] * 3, "position": [0, 0, 0.05 + 2e-4], "mass": 2.0}],
        "allow_floating": True}, "material": {"friction": 0.8, **material},
        "run": {"duration": 1.0}, "solver": {"safety": safety}})
    from dem.engine import Simulation
    from dem.run.build import joint_law, step_options
    from dem.scene import blocks_to_scene
    sim = Simulation(blocks_to_scene(case.scene.blocks), joint_law(case.material),
                     step_options(case.solver))
    worst = peak = 0.0
    while sim.t < 0.02:
        sim.advance(1, constant_loads())
        e = sim.energy_report()
        worst = max(worst, abs(e["residual"]))
        peak = max(peak, e["elastic"])
    return worst, peak


def test_energy_balance_is_closed_to_the_scheme_error():
    """The stored energy is the integral of the force (laws.hyperbolic_energy), so the balance
    kinetic + elastic - initial - work + dissipation (summary.json energy.residual) is closed up
    to the explicit scheme's error, which is first order in dt.  A block dropped on the table
    without damping (zeta = 0: every joule is kinetic, elastic or gravity's), sampled every step
    through its impacts (deepest closure x = d/d_max = 0.71): the largest |residual| falls by
    4 when dt falls by 4 (measured 0.0267 -> 0.0066 of the peak elastic energy), where a stored
    energy that were not the force's integral (kn0 d^2/2 would miss half of it at x = 0.71)
    would stay.  At the default safety it is below the linear law's on the same drop (kn = 1e9 Pa/m,
    measured 0.092 of its peak elastic energy)."""
    hyp = _hyper(damping=0.0, closure_limit=0.9)
    w_03, peak_03 = _drop_balance(hyp, 0.3)
    w_0075, peak_0075 = _drop_balance(hyp, 0.075)
    assert 3.0 < w_03 / w_0075 < 5.0, (w_03, w_0075)
    assert w_0075 < 0.01 * peak_0075
    w_lin, peak_lin = _drop_balance({"normal_stiffness": 1e9, "damping": 0.0}, 0.3)
    assert w_03 / peak_03 < w_lin / peak_lin, (w_03 / peak_03, w_lin / peak_lin)


def test_critical_step_uses_the_tangent_at_the_closure_limit():
    """The step of a hyperbolic scene equals that of the linear law at kn0 / (1 - c)^2, c the
    closure_limit (timestep.py bounds omega^2 by kn; PairMaterial.stable_stiffness)."""
    block = [{"size": [0.105, 0.05, 0.035], "position": [0, 0, 0.0175], "mass": 0.336}]
    for c in (0.5, 0.8):
        hyp = make_sim(block, friction=0.8, **_hyper(closure_limit=c))
        lin = make_sim(block, friction=0.8, normal_stiffness=KN0 / (1 - c) ** 2,
                       shear_stiffness=0.4 * KN0)
        assert hyp.dt == lin.dt
        rec = hyp.model.pair_material("brick", "table")
        assert rec.law == HYPERBOLIC and rec.d_max == DMAX and rec.d_lim == c * DMAX
        assert rec.stable_stiffness() == pytest.approx(KN0 / (1 - c) ** 2, rel=1e-15)


def test_a_joint_closing_beyond_the_limit_stops_the_run():
    """A load whose closure d(p) lies beyond closure_limit x d_max: the run stops with an error
    naming the closure and the field, instead of running on a law it was not made for."""
    p = 1.5 * KN0 * DMAX  # d(p) = 0.6 d_max > 0.5 d_max
    size = 0.1
    sim = make_sim([{"size": [size] * 3, "position": [0, 0, 0.05], "mass": p * size**2 / G}],
                   friction=0.8, **_hyper())
    with pytest.raises(SimulationError, match="closure_limit"):
        sim.advance(int(round(0.2 / sim.dt)), constant_loads())
    assert closure(p) == pytest.approx(0.6 * DMAX)


def test_a_capped_law_goes_on_along_its_tangent_beyond_the_limit():
    """The same load with ``beyond_closure_limit: tangent``: the run goes on, and the block
    settles where the capped law p(d_lim) + kt(d_lim)(d - d_lim) carries it: d_lim = d_max/2,
    p(d_lim) = kn0 d_max, kt(d_lim) = 4 kn0, so d = d_max/2 + (p - kn0 d_max) / (4 kn0) =
    0.625 d_max (the uncapped law: 0.6 d_max).  The patch bears uniformly (exact quadrature) and
    the damped settling has died out by 0.3 s, as in the settling test above: 1e-12 m allowed
    (1e-8 of d).  summary.json's deepest closure is the engine's deepest_penetration."""
    p = 1.5 * KN0 * DMAX
    size = 0.1
    sim = make_sim([{"size": [size] * 3, "position": [0, 0, 0.05], "mass": p * size**2 / G}],
                   friction=0.8, **_hyper(beyond_closure_limit="tangent"))
    sim.advance(int(round(0.3 / sim.dt)), constant_loads())
    d = 0.05 - sim.state.pos[0, 2]
    expect = 0.5 * DMAX + (p - KN0 * DMAX) / (4.0 * KN0)
    assert abs(d - expect) < 1e-12, (d / DMAX, expect / DMAX)
    assert abs(closure(p) - expect) > 0.02 * DMAX  # the cap, not the hyperbolic law, holds it
    assert sim.deepest_penetration()[0] >= d - 1e-12  # the overshoot of the release included


def test_summary_says_how_deep_the_capped_law_went(tmp_path):
    """summary.json's hyperbolic_closure: the deepest closure over d_max and whether it passed
    closure_limit.  The capped block above (a 0.1 m cube loaded to 1.5 kn0 d_max, settled at
    0.625 d_max on the cap's tangent) reports a fraction of at least 0.625 and beyond: true; a
    light block (p = 0.2 kn0 d_max, d = 0.167 d_max) reports under 0.5 and beyond: false."""
    from dem.run import run_case

    out = {}
    for name, load in (("heavy", 1.5), ("light", 0.2)):
        mass = load * KN0 * DMAX * 0.1**2 / G
        case = parse_case({"name": name, "scene": {"blocks": [
            {"size": [0.1] * 3, "position": [0, 0, 0.05], "mass": mass}]},
            "material": {"friction": 0.8, **_hyper(beyond_closure_limit="tangent")},
            "run": {"duration": 0.3, "output_interval": 0.1}})
        out[name] = run_case(case, tmp_path / name).summary["hyperbolic_closure"]
    heavy, light = out["heavy"], out["light"]
    assert heavy["beyond_closure_limit"] and heavy["deepest_closure_fraction"] >= 0.625 - 1e-9
    assert heavy["law_beyond_it"] == "tangent" and heavy["closure_limit"] == 0.5
    assert not light["beyond_closure_limit"]
    assert closure(0.2 * KN0 * DMAX) / DMAX <= light["deepest_closure_fraction"] < 0.5


def _case(material):
    return {"name": "x", "scene": {"blocks": [{"size": [0.1] * 3, "position": [0, 0, 0.05],
                                               "mass": 1.0}]},
            "material": {"friction": 0.6, **material}, "run": {"duration": 1.0}}


@pytest.mark.parametrize("material, message", [
    ({"normal_law": "hyperbolic"}, "needs max_closure"),
    ({"max_closure": 1e-4}, "applies to normal_law: hyperbolic only"),
    ({"normal_law": "hyperbolic", "max_closure": 1e-4, "normal_stiffness": "rigid"},
     "'rigid' applies to the linear law only"),
    ({"normal_law": "hyperbolic", "max_closure": 1e-4, "closure_limit": 1.0}, "less than 1"),
    ({"normal_law": "hyperbolic", "max_closure": -1e-4}, "greater than 0"),
    ({"normal_law": "cubic"}, "'linear' or 'hyperbolic'"),
    ({"beyond_closure_limit": "tangent"}, "applies to normal_law: hyperbolic only"),
    ({"normal_law": "hyperbolic", "max_closure": 1e-4, "beyond_closure_limit": "go"},
     "'stop' or 'tangent'"),
])
def test_case_file_checks_the_law_fields(material, message):
    with pytest.raises(CaseError, match=message):
        parse_case(_case(material))


def test_record_of_a_hyperbolic_pair():
    """The case's fields reach the record by name (PairMaterial), the linear default has law 0
    and no closures."""
    from dem.run.build import joint_law
    j = joint_law(parse_case(_case(_hyper(closure_limit=0.6))).material)
    assert (j.normal_law, j.max_closure, j.closure_limit) == ("hyperbolic", DMAX, 0.6)
    lin = PairMaterial(0.6, 5e9, 2e9, 0.5)
    assert (lin.law, lin.d_max, lin.d_lim, lin.stable_stiffness()) == (0, 0.0, 0.0, 5e9)


@pytest.mark.slow
def test_hyperbolic_kernels_cold_compile_without_narrowing():
    """The serial kernel compiled for the hyperbolic law and its energy kernel, compiled with an
    empty offline cache in a fresh process: no lossy assignment and no f32 in the f64 engine (as
    tests/test_engine_launch.py checks the default kernels).  One stepping kernel: the parallel
    and imperfect-face variants run the same law functions (a cold compile costs ~1-2 min of
    CPU each on the 2-core machine)."""
    from engine_helpers import assert_cold_compile_is_f64

    assert_cold_compile_is_f64('friction=0.6, normal_law="hyperbolic", normal_stiffness=1e8, '
                               'max_closure=1e-4', modes=("serial",))
