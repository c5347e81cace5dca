"""Identification of a model's own frequency response (postprocess.identification): a system of
known frequency and damping, a block on a penalty joint against its closed form, and the
amplitude dependence of a joint that softens."""

from __future__ import annotations

import numpy as np
import pytest
from scipy import linalg, signal

from dem.table_motion import NoiseMotion
from postprocess.identification import (analyze_identification_run, receptance,
                                        transfer_functions)

F_N, ZETA = 5.0, 0.05   # Hz, -: the one-degree-of-freedom system below


def _sdof_under_noise(seed: int = 1):
    """x'' + 2 zeta w_n x' + w_n^2 x = -a_g(t), a_g the tapered white noise of NoiseMotion
    (0.5-20 Hz, RMS 1 m/s2, 120 s), simulated exactly for a piecewise-linear input by
    scipy.signal.lsim, 10 s of decay after the noise (the record ends at rest).  Returns t,
    a_g, the relative displacement x and the absolute acceleration x'' + a_g = -2 zeta w_n x'
    - w_n^2 x."""
    wn = 2.0 * np.pi * F_N
    noise = NoiseMotion(1.0, 0.5, 20.0, 120.0, seed=seed, taper=2.0)
    t = np.arange(0.0, 130.0, 0.005)
    a_g = noise.acceleration(t)
    sys = signal.StateSpace([[0.0, 1.0], [-wn * wn, -2.0 * ZETA * wn]], [[0.0], [-1.0]],
                            [[1.0, 0.0], [-wn * wn, -2.0 * ZETA * wn]], [[0.0], [0.0]])
    _, y, _ = signal.lsim(sys, a_g, t)
    return t, a_g, y[:, 0], y[:, 1]


def test_a_single_degree_of_freedom_system_is_identified_from_white_noise():
    """f_n within 2 %, zeta within 10 % (the issue's tolerances), from the relative displacement
    and from the absolute acceleration, by both estimators (H1 and the ratio of spectra) and
    both methods (half-power bandwidth, SDOF fit).  The half-power rule is first order in zeta:
    the receptance peaks at f_n sqrt(1 - 2 zeta^2) (-0.25 % at zeta = 0.05), inside 2 %."""
    t, a_g, x, a_abs = _sdof_under_noise()
    tf = transfer_functions(t, a_g, {"ds": (x, "relative_displacement"),
                                     "a": (a_abs, "absolute_acceleration")})
    for name in ("ds", "a"):
        for est in ("ratio", "h1"):
            for method in ("sdof_fit", "half_power"):
                m = tf[name]["mode"][est][method]
                assert m is not None, (name, est, method)
                assert m["f_n_hz"] == pytest.approx(F_N, rel=0.02), (name, est, method, m)
                assert m["zeta"] == pytest.approx(ZETA, rel=0.10), (name, est, method, m)
    # a linear system: the coherence is 1 in the band, and the participation of a single mass 1
    h1 = tf["ds"]["h1"]
    band = (h1["f"] > 1.0) & (h1["f"] < 15.0)
    assert h1["coherence"][band].min() > 0.95
    assert tf["ds"]["mode"]["ratio"]["sdof_fit"]["participation"] == pytest.approx(1.0, rel=0.02)


def test_receptance_of_each_frame_is_the_same_for_one_mass():
    """R = H for ds, -H / w^2 for a relative acceleration, (1 - H) / w^2 for an absolute one:
    the three transfer functions of one SDOF system give one receptance."""
    f = np.array([1.0, 4.0, 9.0])
    w = 2 * np.pi * f
    R = -1.0 / ((2 * np.pi * F_N) ** 2 - w**2 + 2j * ZETA * 2 * np.pi * F_N * w)
    np.testing.assert_allclose(receptance(f, -w**2 * R, "relative_acceleration"), R)
    np.testing.assert_allclose(receptance(f, 1 - w**2 * R, "absolute_acceleration"), R)
    with pytest.raises(ValueError, match="kind"):
        receptance(f, R, "velocity")


def test_a_mode_above_the_band_is_said_not_invented():
    """The receptance of a 5 Hz system seen through a 0.5-4 Hz band rises to the band's top:
    no half-power points, so no mode, and the sentence says the mode lies above the band."""
    from postprocess.identification import half_power, rising_to_band_edge

    f = np.linspace(0.5, 4.0, 200)
    w, wn = 2 * np.pi * f, 2 * np.pi * F_N
    R = -1.0 / (wn * wn - w * w + 2j * ZETA * wn * w)
    assert half_power(f, R) is None
    assert "above the band" in rising_to_band_edge(f, R, (0.5, 4.0))
    f2 = np.linspace(1.0, 10.0, 400)
    w2 = 2 * np.pi * f2
    R2 = -1.0 / (wn * wn - w2 * w2 + 2j * ZETA * wn * w2)
    assert rising_to_band_edge(f2, R2, (1.0, 10.0)) is None


# ---------------------------------------------------------------------------------------------
# a block on a penalty joint (the DEM)
# ---------------------------------------------------------------------------------------------
B, D, H, MASS = 0.1, 0.1, 0.2, 4.0      # m (along x, along y, height), kg
KN, G = 1.0e7, 9.81                     # Pa/m, m/s2
KS = 0.4 * KN                           # Pa/m: the default shear stiffness (docs/engine.md)


def rocking_sliding_frequency(kn=KN, ks=KS) -> float:
    """The lower natural frequency (Hz) of a rigid block b x d x h of mass m on a Winkler base
    (normal stiffness kn, shear ks per unit area: docs/engine.md section 4, the penalty joint),
    rocking about y and sliding along x, before uplift.

    Coordinates: x the base's horizontal displacement, theta the rotation about the base
    centre.  The centre of mass (height h_c = h / 2) moves by x + h_c theta.
      kinetic energy   T = m (x' + h_c theta')^2 / 2 + I_c theta'^2 / 2,  I_c = m (b^2 + h^2) / 12
      potential energy V = k_x x^2 / 2 + k_theta theta^2 / 2
    with k_x = ks b d (the shear springs of the base area) and the rotational stiffness of the
    Winkler base minus the overturning of the weight raised on the tilted base:
      k_theta = kn d b^3 / 12 - m g h_c   (N m/rad; the integral of kn x^2 over the base).
    So M q'' + K q = 0 with M = [[m, m h_c], [m h_c, m h_c^2 + I_c]], K = diag(k_x, k_theta);
    the natural frequencies are the square roots of the generalised eigenvalues of (K, M) over
    2 pi.  For the block here the first mode is the rocking one (5.67 Hz; uncoupled rocking
    about the base centre would give 5.96 Hz, the sliding spring lowers it 5 %), the second
    (30.8 Hz) the sliding."""
    hc = H / 2
    k_theta = kn * D * B**3 / 12 - MASS * G * hc
    k_x = ks * B * D
    i_c = MASS * (B * B + H * H) / 12
    M = np.array([[MASS, MASS * hc], [MASS * hc, MASS * hc * hc + i_c]])
    w2 = linalg.eigh(np.diag([k_x, k_theta]), M, eigvals_only=True)
    return float(np.sqrt(w2[0]) / (2 * np.pi))


def _block_case(loading: dict, material: dict | None = None, duration: float = 9.0):
    from dem.case import parse_case

    return parse_case({
        "name": "block-on-penalty-joint",
        "scene": {"blocks": [{"size": [B, D, H], "position": [0, 0, H / 2], "mass": MASS}]},
        "material": {"friction": 0.8, "normal_stiffness": KN, "damping": 0.02,
                     **(material or {})},
        "loading": loading,
        "run": {"duration": duration, "output_interval": 0.005, "vtk": False,
                "snapshot": False}})


SWEEP = {"type": "sweep", "direction": [1, 0, 0], "f0": 2.0, "f1": 12.0, "duration": 8.0}


def _hyperbolic_tangent(kn0: float, d_max: float) -> float:
    """The hyperbolic joint's tangent stiffness under the block's weight (docs/engine.md 4.2):
    closure d0 = p / (kn0 + p / d_max) under p = m g / (b d), k_t = kn0 / (1 - d0 / d_max)^2
    (Pa/m): small rotations about that closure see k_t."""
    p = MASS * G / (B * D)
    d0 = p / (kn0 + p / d_max)
    return kn0 / (1.0 - d0 / d_max) ** 2


@pytest.mark.parametrize("law", ["linear", "hyperbolic"])
def test_a_block_on_a_penalty_joint_rocks_at_its_closed_form_frequency(tmp_path, law):
    """A DEM run of the block under a low-level sweep (0.03 m/s2, 2-12 Hz in 8 s: its rocking
    stays below a third of the uplift angle, d0 / (b / 2) = m g / (kn b d) / (b / 2) =
    7.8e-3 rad) identifies the first mode within 2 % of :func:`rocking_sliding_frequency`
    (measured +0.15 %); ``dem post`` writes identification.json / .png and ``dem summary``
    shows f_n and zeta.  The hyperbolic joint (kn0 = 1e7 Pa/m, d_max = 1 mm) rocks at the
    closed form with kn its tangent stiffness under the weight, 1.94 kn0 (ks = 0.4 kn0 stays):
    7.63 Hz, measured +0.06 % (the sweep to 16 Hz)."""
    from typer.testing import CliRunner

    from dem_cli.app import app
    from dem.run import run_case

    material, sweep, f_closed = {}, dict(SWEEP), rocking_sliding_frequency()
    if law == "hyperbolic":
        material = {"normal_law": "hyperbolic", "max_closure": 1e-3, "closure_limit": 0.8}
        sweep["f1"] = 16.0
        f_closed = rocking_sliding_frequency(_hyperbolic_tangent(KN, 1e-3), KS)
    run_case(_block_case({**sweep, "peak_acceleration": 0.03}, material), tmp_path / "run")
    res = analyze_identification_run(tmp_path / "run", plots=False, write=False)
    assert res["f_n_hz"] == pytest.approx(f_closed, rel=0.02), res["method"]
    assert res["method"].startswith("sdof_fit")
    assert 0.0 < res["zeta"] < 0.2
    out = CliRunner().invoke(app, ["post", str(tmp_path / "run")])
    assert out.exit_code == 0, out.output
    assert "first mode f_n" in out.output
    assert (tmp_path / "run" / "identification.png").stat().st_size > 1000
    out = CliRunner().invoke(app, ["summary", "--format", "csv", str(tmp_path / "run")])
    header, row = out.output.strip().splitlines()[-2:]
    cols = dict(zip(header.split(","), row.split(",")))
    assert float(cols["f_n (Hz)"]) == pytest.approx(res["f_n_hz"])
    assert float(cols["zeta (-)"]) == pytest.approx(res["zeta"])


def test_doubling_the_level_past_uplift_lowers_the_identified_frequency(tmp_path):
    """The same block and sweep at 0.2 and 0.4 m/s2: at 0.2 the rocking reaches about the
    uplift angle theta_u = d0 / (b / 2) = m g / (kn b d) / (b / 2) = 7.8e-3 rad at the peaks,
    at 0.4 beyond it; a heel that lifts off narrows the contact and the rocking stiffness
    (kn d c^3 / 12 over the width c still in contact) falls, so the joint softens with the
    amplitude and f_n drops (measured: 5.64 -> 5.11 Hz, -9 %; docs/identification.md).  Lower
    by more than the identification's 2 % at least; both at or below the linear value (the
    closed form + 2 %).  The stress-dependent hyperbolic joint softens far less before uplift
    (0.06 -> 0.12 m/s2: -0.3 %, docs/identification.md): the opening is what softens here."""
    from dem.run import run_case

    f = {}
    for ap in (0.2, 0.4):
        run_case(_block_case({**SWEEP, "peak_acceleration": ap}), tmp_path / f"a{ap}")
        f[ap] = analyze_identification_run(tmp_path / f"a{ap}", plots=False,
                                           write=False)["f_n_hz"]
    assert f[0.4] < 0.98 * f[0.2], f
    assert f[0.2] < 1.02 * rocking_sliding_frequency(), f
