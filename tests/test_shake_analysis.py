"""Analysis of shaking-table runs (thesis Chapter 4): amplification, lag, spectrum,
integration, hysteresis, kinetic energy, the excited portion, ``dem sweep`` and ``dem post``.

Synthetic signals carry known amplitudes and phases; the real runs are a single block (seconds of
wall time).  Tolerances come from the sampling and integration errors stated with each test.
"""

from __future__ import annotations

import json
import math
from pathlib import Path

import numpy as np
import pytest
import yaml
from scipy.spatial.transform import Rotation
from typer.testing import CliRunner

from dem import quaternion
from dem.builders import build_box_model
from dem.case import parse_case
from dem_cli.app import app
from postprocess import excited as ex
from postprocess import shake as sh
from postprocess import signal_analysis as sa
from postprocess.block_kinematics import kinetic_energy_blocks
from postprocess.shake_signals import ShakeSignals
from postprocess.sweep import effective_range

F, A = 2.4, 0.006  # Hz, m


def _sig(t, u, ds, a_abs=None, ds_corner=None, a_corner=None, f=F, t_end=None):
    """ShakeSignals for synthetic histories (table displacement u, relative ds, absolute a)."""
    exc = {"displacement": u, "velocity": np.gradient(u, t),
           "acceleration": np.gradient(np.gradient(u, t), t)}
    return ShakeSignals(t=t, f=f, t_end=t_end or t[-1] + 1e-9, direction=np.array([0, 1.0, 0]),
                        axis="y", excitation=exc, ds_centre=ds, ds_corner=ds_corner,
                        a_centre=a_abs, a_corner=a_corner, blocks={"centre": 0})


# ---------------------------------------------------------------------------------------------
# synthetic signals
# ---------------------------------------------------------------------------------------------
def test_steady_amplification_and_lag_of_a_known_response():
    """ds = R sin(wt - phi) after an 'impulsive' overshoot (the thesis: amplitudes climb to a peak,
    then settle lower), with a sliding drift.  Amplification R/A and lag phi must come out of the
    steady state only; the absolute quantities follow the phasor sum |1 + (R/A) e^-i phi|."""
    w = 2 * np.pi * F
    t = np.arange(0, 30 / F, 0.002)
    R, phi = 1.7 * A, np.radians(50.0)
    bump = 1.0 + 1.0 * np.exp(-(((t - 1.5) / 0.5) ** 2))      # doubles cycles 2 - 5
    u = A * np.sin(w * t)
    ds = R * bump * np.sin(w * t - phi) + 0.002 * t / t[-1]    # + 2 mm of sliding
    # absolute acceleration of the centre: u'' + ds'' (analytic, without the drift)
    steady = R * np.sin(w * t - phi)
    a_abs = -w**2 * (u + steady)
    res, arr = sh.analyze_signals(_sig(t, u, ds, a_abs))
    win = arr["window"]
    assert win.t0 >= 2.0, "the window must start after the overshoot (bump < 25 % after 2.1 s)"
    q = res["quantities"]
    # sampling error of a per-cycle peak at 500 Hz: 1 - cos(pi f dt) = 1.1e-4; the drift adds
    # 2 mm / 30 cycles per cycle, i.e. at most 0.07 mm / 20 mm pp = 0.4 % to the pp of ds
    assert q["ds"]["amplification"] == pytest.approx(1.7, rel=5e-3)
    assert q["ds"]["lag_deg"] == pytest.approx(50.0, abs=0.2)
    assert q["ds"]["lag_s"] == pytest.approx(50.0 / (360 * F), abs=0.2 / (360 * F))
    absolute = abs(1 + 1.7 * np.exp(-1j * phi))
    assert q["a"]["amplification"] == pytest.approx(absolute, rel=2e-3)
    assert q["da"]["amplification"] == pytest.approx(absolute, rel=2e-3)
    lag_abs = np.degrees(-np.angle(1 + 1.7 * np.exp(-1j * phi)))
    assert q["da"]["lag_deg"] == pytest.approx(lag_abs, abs=0.2)
    # whole-record peak-to-peak would read the overshoot: the steady window is what matters
    naive = (ds.max() - ds.min()) / (2 * A)
    assert naive > 2.5


def test_double_integration_recovers_the_table_displacement():
    """da of the table's acceleration is the table's displacement (the initial velocity A w is
    an integration constant the method must remove).  Trapezoid error at 500 Hz:
    (w dt)^2 / 12 = 7e-5; 4 cycles (no high-pass) and 30 cycles (with it)."""
    w = 2 * np.pi * F
    for cycles in (4, 30):
        t = np.arange(0, cycles / F + 1e-9, 0.002)
        a = -A * w**2 * np.sin(w * t)
        d = sa.drift_free_integral(a, t, F, t[-1], 2)
        v = sa.drift_free_integral(a, t, F, t[-1], 1)
        assert np.abs(d - A * np.sin(w * t)).max() < 1e-3 * A, cycles
        assert np.abs(v - A * w * np.cos(w * t)).max() < 1e-3 * A * w, cycles


def test_spectrum_of_a_pure_sine_has_one_peak_at_its_frequency():
    t = np.arange(0, 20 / F, 0.002)
    rng = np.random.default_rng(1)
    y = 3e-3 * np.sin(2 * np.pi * F * t + 0.3) + 1e-3 * t + 3e-5 * rng.standard_normal(len(t))
    win = sa.SteadyWindow(0, 20, F, "test", "y")
    pk = sa.spectral_peaks(*sa.spectrum(t, y, win))
    assert pk["single_peak"]
    # 20 whole cycles: F sits on bin 20 up to the rounding of the window to whole samples
    # (relative 1 / n_samples = 2.4e-4), where the Hann window reads its amplitude exactly
    assert pk["dominant_frequency_hz"] == pytest.approx(F, rel=1 / 4166)
    assert pk["peaks"][0][1] == pytest.approx(3e-3, rel=0.02)
    # negative control: a third harmonic of 30 % is a second peak
    y3 = y + 0.9e-3 * np.sin(2 * np.pi * 3 * F * t)
    pk3 = sa.spectral_peaks(*sa.spectrum(t, y3, win))
    assert not pk3["single_peak"]
    assert np.allclose(sorted(p[0] for p in pk3["peaks"]), [F, 3 * F], rtol=1 / 4166)


def test_hysteresis_loop_energy_of_a_viscous_oscillator():
    """Linear oscillator in the table frame: m a_abs = -(k x + c x'), so F = m a_abs traced
    against x encloses -closed integral F dx = pi c w X^2 per cycle (the dissipated energy)."""
    k, c = 4000.0, 30.0
    w = 2 * np.pi * F
    t = np.arange(0, 10 / F + 0.01, 0.002)
    X = 4e-3
    x = X * np.sin(w * t - 0.7)
    F_ = -(k * x + c * X * w * np.cos(w * t - 0.7))
    win = sa.SteadyWindow(1, 10, F, "test", "x")
    E = sa.loop_energy(t, F_, x, F, win)
    assert len(E) == 9
    # trapezoid rule on the loop at 500 Hz: error ~ (w dt)^2 / 12 = 8e-5
    assert np.allclose(E, np.pi * c * w * X**2, rtol=1e-3)


def test_kinetic_energy_from_block_frames_and_eq_4_4():
    """A block translating y = Y sin wt: both eq 4-4 and the blocks give 1/2 m (w Y)^2 at the
    peaks.  A block rocking theta = T sin wt about x (no translation): the blocks give
    1/2 I_xx (w T)^2 from the orientations alone (central differences, error (w dt)^2 / 6)."""
    scene = build_box_model("II")
    b = 0
    w = 2 * np.pi * F
    t = np.arange(0, 6 / F, 0.005)
    T = len(t)
    n = scene.n_blocks
    pos = np.repeat(scene.position[None], T, axis=0)
    quat = np.repeat(scene.quat[None], T, axis=0)
    vel = np.zeros((T, n, 3))
    Y = 5e-3
    vel[:, b, 1] = Y * w * np.cos(w * t)
    pos[:, b, 1] += Y * np.sin(w * t)
    m = scene.mass[b]
    e_blocks = kinetic_energy_blocks(t, vel, quat, scene, [b])
    assert e_blocks.max() == pytest.approx(0.5 * m * (w * Y) ** 2, rel=1e-3)
    e44 = sa.kinetic_energy_eq44(pos[:, b, 1] - pos[0, b, 1], F, m)
    assert e44.max() == pytest.approx(0.5 * m * (w * Y) ** 2, rel=1e-3)
    # pure rotation about x
    Th = 0.02
    quat[:, b] = quaternion.from_rotation(
        Rotation.from_rotvec(np.outer(Th * np.sin(w * t), [1.0, 0, 0])))
    e_rot = kinetic_energy_blocks(t, np.zeros((T, n, 3)), quat, scene, [b])
    Ixx = scene.inertia()[b, 0]
    assert e_rot.max() == pytest.approx(0.5 * Ixx * (w * Th) ** 2, rel=(w * 0.005) ** 2 / 3)


# ---------------------------------------------------------------------------------------------
# the excited portion on a real box-model scene
# ---------------------------------------------------------------------------------------------
def _planted_motion(scene, lower, upper, th1, th2, f, t, seed=0, decoys=True):
    """Frames of a two-part rocking of facade L1 (y < 0) out of plane along +y: the lower part
    turns by th1(t) about the hinge line at the bottom of course 1, the upper part by th2(t)
    more about the line at the bottom of course 5 (carried by the lower part); rotation axis
    a = z x y = -x, so positive angles move the top towards +y.  Noise on every block."""
    rng = np.random.default_rng(seed)
    w = 2 * np.pi * f
    T, n = len(t), scene.n_blocks
    h = 0.035
    y_face = scene.position[scene.group == scene.group_names.index("L1"), 1].mean()
    p1, p2 = np.array([0, y_face, 1 * h]), np.array([0, y_face, 5 * h])
    ax = np.array([-1.0, 0, 0])
    R1 = Rotation.from_rotvec(np.outer(th1 * np.sin(w * t - 0.4), ax))
    R2 = Rotation.from_rotvec(np.outer(th2 * np.sin(w * t - 0.4), ax))
    pos = np.repeat(scene.position[None], T, axis=0).copy()
    rotv = np.zeros((T, n, 3))
    for i in np.flatnonzero(lower):
        pos[:, i] = R1.apply(scene.position[i] - p1) + p1
        rotv[:, i] = R1.as_rotvec()
    for i in np.flatnonzero(upper):
        pos[:, i] = R1.apply(R2.apply(scene.position[i] - p2) + p2 - p1) + p1
        rotv[:, i] = (R1 * R2).as_rotvec()
    if decoys:
        g = scene.group_names.index
        # T2 bricks away from the facade slide 1.5 mm a quarter cycle behind the top
        far = (scene.group == g("T2")) & (scene.position[:, 1] > 0.1) & (scene.course >= 6)
        pos[:, far, 1] += 1.5e-3 * np.sin(w * t - 0.4 - np.pi / 2)[:, None]
        # a loose T1 brick low down moves in phase with the top but touches nothing that moves
        loose = np.flatnonzero((scene.group == g("T1")) & (scene.course == 2))[1]
        pos[:, loose, 1] += 3e-3 * np.sin(w * t - 0.4)
        # the front wall L2 rocks in phase at 40 % (it is not the instrumented facade)
        front = scene.group == g("L2")
        pos[:, front, 1] += 0.4 * 3e-3 * (scene.position[front, 2] / 0.315)[None] \
            * np.sin(w * t - 0.4)[:, None]
    pos += 15e-6 * rng.standard_normal(pos.shape)
    rotv += 1e-4 * rng.standard_normal(rotv.shape)
    quat = quaternion.from_rotation(Rotation.from_rotvec(rotv.reshape(-1, 3))).reshape(T, n, 4)
    return {"t": t, "pos": pos, "quat": quat}


def _masks(scene):
    g = scene.group_names.index
    L1 = scene.group == g("L1")
    T = (scene.group == g("T1")) | (scene.group == g("T2"))
    x, y, c = scene.position[:, 0], scene.position[:, 1], scene.course
    return L1, T, x, y, c


def test_excited_portion_recovers_planted_upper_and_lower_parts():
    scene = build_box_model("II")
    L1, T, x, y, c = _masks(scene)
    upper = (L1 & (c >= 5)) | (T & (c >= 5) & (y < -0.1))
    lower = L1 & (c >= 1) & (c <= 4) & (np.abs(x) <= 0.06 + 0.08 * (c - 1))
    assert all((lower & (c == k)).any() for k in range(1, 5))
    t = np.arange(0, 10 / 2.8, 0.01)
    frames = _planted_motion(scene, lower, upper, 0.008, 0.012, 2.8, t)
    ref = int(np.flatnonzero(L1 & (c == 7))[np.argmin(np.abs(x[L1 & (c == 7)]))])
    # the reference (the transducer's centre brick) also slides 2 mm over the record
    frames["pos"][:, ref, 1] += 2e-3 * t / t[-1]
    portion = ex.excited_portion(scene, frames, 2.8, 1 / 2.8, 10 / 2.8, [0, 1, 0], ref,
                                 facade="L1", side_walls=("T1", "T2"))
    want = np.where(upper, 2, np.where(lower, 1, 0))
    wrong = np.flatnonzero(portion.part != want)
    assert wrong.size == 0, [(int(i), scene.group_names[scene.group[i]], int(c[i]),
                              int(portion.part[i]), int(want[i])) for i in wrong]
    s = portion.summary()
    assert (s["n_upper"], s["n_lower"]) == (int(upper.sum()), int(lower.sum())) == (38, 14)
    assert s["upper_courses"] == [6, 7, 8, 9]  # 1-based, as the thesis counts
    assert s["excited_courses_from_top"] == 8
    assert s["mass_kg"] == pytest.approx(scene.mass[upper | lower].sum())
    # the lowest lower-part bricks move ~0.1 mm: found by their rotation, not their translation
    low = np.flatnonzero(lower & (c == 1))
    assert portion.by_rotation[low].all() and not portion.by_translation[low].any()
    lab = ex.corner_label(portion)
    assert lab["corners"] == "B2-like" and lab["line"] == "stepped"
    assert lab["side_wall_bricks"] == {"T1": 4, "T2": 4}


def test_excited_portion_of_a_horizontal_line_is_a_like():
    """Only the top four facade courses rock, on a horizontal joint, corners at rest."""
    scene = build_box_model("II")
    L1, T, x, y, c = _masks(scene)
    upper = L1 & (c >= 5)
    none = np.zeros(scene.n_blocks, bool)
    t = np.arange(0, 8 / 2.0, 0.01)
    frames = _planted_motion(scene, none, upper, 0.0, 0.015, 2.0, t, seed=3)
    ref = int(np.flatnonzero(L1 & (c == 7))[np.argmin(np.abs(x[L1 & (c == 7)]))])
    portion = ex.excited_portion(scene, frames, 2.0, 0.5, 4.0, [0, 1, 0], ref,
                                 facade="L1", side_walls=("T1", "T2"))
    assert np.array_equal(portion.excited, upper)
    assert (portion.part[upper] == 2).all()
    lab = ex.corner_label(portion)
    assert lab["corners"] == "A-like" and lab["line"] == "horizontal"
    assert lab["side_wall_bricks"] == {"T1": 0, "T2": 0}


# ---------------------------------------------------------------------------------------------
# real runs
# ---------------------------------------------------------------------------------------------
BLOCK = {
    "name": "block-on-shaking-table",
    "scene": {"blocks": [{"size": [0.2, 0.2, 0.1], "position": [0, 0, 0.05], "mass": 4.0}]},
    "material": {"friction": 0.8},
    "loading": {"type": "shake", "direction": [0, 1, 0], "frequency": 2.0,
                "peak_acceleration": 1.5, "cycles": 4},
    "run": {"duration": 2.0, "output_interval": 0.005, "vtk": False, "snapshot": False},
}


@pytest.fixture(scope="module")
def bolted_run(tmp_path_factory):
    """A squat block (b/h = 2, mu = 0.8) under 1.5 m/s2: it neither slides (mu g = 7.8 m/s2) nor
    rocks (g b/h = 19.6 m/s2), so it moves with the table, as if bolted."""
    from dem.run import run_case

    out = tmp_path_factory.mktemp("bolted")
    res = run_case(parse_case(BLOCK), out)
    assert res.summary["status"] == "ok"
    return out


def test_a_block_moving_with_the_table_has_absolute_amplification_one_and_no_lag(bolted_run):
    res = sh.analyze_run(bolted_run)
    amp, q = res["amplification"], res["axes"]["y"]["quantities"]
    # frame-based accelerometer: two central differences at 5 ms attenuate a sine by
    # 2 (w dt)^2 / 6 = 1.3e-3; per-cycle peaks from samples: 1 - cos(pi f dt) = 5e-4
    for name in ("a", "da", "va"):
        assert amp[name] == pytest.approx(1.0, abs=5e-3), name
        assert abs(q[name]["lag_s"]) < 1e-3, name   # a fifth of a frame interval
    # relative to the table it does not move: the shear spring's elastic give is
    # m a / (ks area) = 4 * 1.5 / (2e9 * 0.04) = 0.08 um against A = 9.5 mm
    assert amp["ds"] < 1e-3 and amp["vs"] < 1e-3
    assert res["axes"]["y"]["excited_portion"]["n_excited"] == 0
    # spectrum of the real run: one peak, at the excitation frequency (bin = f / n_cycles)
    n = res["steady_state"]["n_cycles"]
    assert q["da"]["single_peak"] and q["a"]["single_peak"]
    assert q["da"]["dominant_frequency_hz"] == pytest.approx(2.0, abs=0.5 * 2.0 / n)
    written = json.loads((bolted_run / "analysis.json").read_text())
    assert written["amplification"]["da"] == pytest.approx(amp["da"])
    for png in ("time_histories.png", "spectrum.png", "hysteresis.png", "energy.png"):
        assert (bolted_run / png).stat().st_size > 1000


def test_dem_post_rebuilds_the_analysis_of_a_run(bolted_run):
    (bolted_run / "analysis.json").unlink(missing_ok=True)  # whether or not a test wrote it
    r = CliRunner().invoke(app, ["post", str(bolted_run)])
    assert r.exit_code == 0, r.output
    assert json.loads((bolted_run / "analysis.json").read_text())["kind"] == "shake"
    r = CliRunner().invoke(app, ["post", str(bolted_run / "nowhere")])
    assert r.exit_code == 2


def case_file(tmp_path, data, name="case.yaml"):
    p = tmp_path / name
    p.write_text(yaml.safe_dump(data))
    return p


def test_dem_sweep_rejects_bad_input_with_exit_2(tmp_path):
    bad = json.loads(json.dumps(BLOCK))
    bad["loading"]["frequency"] = -1.0
    r = CliRunner().invoke(app, ["sweep", str(case_file(tmp_path, bad)), "--out",
                                 str(tmp_path / "o"), "--frequencies", "2"])
    assert r.exit_code == 2 and "loading.frequency" in r.output
    tilt = json.loads(json.dumps(BLOCK))
    tilt["loading"] = {"type": "tilt", "axis": "x", "rate": 2.0}
    r = CliRunner().invoke(app, ["sweep", str(case_file(tmp_path, tilt, "t.yaml")), "--out",
                                 str(tmp_path / "o"), "--frequencies", "2"])
    assert r.exit_code == 2 and "shake" in r.output
    ok = case_file(tmp_path, BLOCK, "ok.yaml")
    for args in (["--range", "3:2:0.1"], ["--frequencies", "2,x"], []):
        r = CliRunner().invoke(app, ["sweep", str(ok), "--out", str(tmp_path / "o"), *args])
        assert r.exit_code == 2, args
    assert not (tmp_path / "o" / "sweep.json").exists()


# A frictionless block keeps the absolute velocity it started with: the table's, u'(0) = A w
# (u = A sin wt; in the table frame it starts at rest).  Absolutely it moves at a constant
# velocity (a = 0, and da = 0 once the integration constants are removed); relative to the table
# ds = A w t - A sin wt, which only grows (ds' = A w (1 - cos wt) >= 0): per cycle its positive
# minus negative amplitude is the growth over one period, 2 pi A, so the thesis' amplification
# is pi, while its first harmonic is -u (ratio 1, lag 180 deg).  With the amplitude fixed at 5 mm
# the speed relative to the table peaks at 2 A w: 0.19 m/s at 3 Hz, 0.25 at 4 Hz, 0.63 at 10 Hz,
# so with solver.max_speed = 0.4 m/s the 10 Hz point fails in its first cycle (the table itself
# moves at A w = 0.31 m/s, below max_speed: dem check, which every point passes first, cannot
# tell that the block will slide at twice that).
SLIDER = {
    "name": "frictionless-block",
    "scene": {"blocks": [{"size": [0.2, 0.2, 0.1], "position": [0, 0, 0.05], "mass": 4.0}]},
    "material": {"friction": 0.0},
    "loading": {"type": "shake", "direction": [0, 1, 0], "frequency": 3.0, "amplitude": 0.005,
                "cycles": 2},
    "run": {"duration": 1.0, "output_interval": 0.005, "vtk": False, "snapshot": False},
    "solver": {"max_speed": 0.4},
}


def test_dem_sweep_survives_a_failed_point_and_dem_post_reaggregates(tmp_path):
    case = case_file(tmp_path, SLIDER)
    out = tmp_path / "sweep"
    r = CliRunner().invoke(app, ["sweep", str(case), "--out", str(out), "--frequencies", "3,4",
                                 "--range", "10:10:1", "--margin", "0", "--workers", "2",
                                 "--max-steps", "400000"])
    assert r.exit_code == 1, r.output
    assert "FAILED" in r.output and "10 Hz" in r.output
    data = json.loads((out / "sweep.json").read_text())
    pts = {p["frequency_hz"]: p for p in data["points"]}
    assert sorted(pts) == [3.0, 4.0, 10.0]
    assert pts[10.0]["status"] == "failed" and "max_speed" in pts[10.0]["error"]
    assert [x["frequency_hz"] for x in data["failed"]] == [10.0]
    for f in (3.0, 4.0):
        p = pts[f]
        assert p["status"] == "ok" and p["amplitude_m"] == pytest.approx(0.005)
        # 2 cycles: the steady state is cycle 2; peaks sampled at 5 ms: 1 - cos(pi f dt) < 2e-3
        assert p["amplification"]["ds"] == pytest.approx(math.pi, rel=0.01)
        assert p["h1_amplitude_ratio"]["ds"] == pytest.approx(1.0, abs=0.01)
        assert abs(abs(p["lag"]["ds"]["deg"]) - 180.0) < 1.0
        assert p["amplification"]["a"] < 0.01 and p["amplification"]["da"] < 0.01
        assert (out / p["dir"] / "analysis.json").is_file()
    assert data["aggregate"]["n_valid"] == 2
    # dem post rebuilds sweep.json from the run directories; the failure stays reported
    (out / "sweep.json").unlink()
    r = CliRunner().invoke(app, ["post", str(out)])
    assert r.exit_code == 1, r.output
    again = json.loads((out / "sweep.json").read_text())
    assert sorted(p["frequency_hz"] for p in again["points"]) == [3.0, 4.0, 10.0]
    assert [p["status"] for p in sorted(again["points"], key=lambda p: p["frequency_hz"])] == \
        ["ok", "ok", "failed"]


def sequential_batch(after_each=None, calls=None):
    """dem.batch.run_batch in this process: a sequential loop over dem.run.run_case that, like
    the real one with one worker, checks ``drain`` before each case (dem.batch.Drained).
    ``after_each(out_root)`` runs after each case; ``calls`` collects the drain checks given."""
    from dem.batch import Drained
    from dem.run import run_case

    def run(cases, out_root, scheduler=None, n_workers=None, max_steps=None, post=None,
            on_done=None, drain=None):
        if calls is not None:
            calls.append(drain)
        recs = []
        for k, (name, case) in enumerate(cases):
            if drain is not None and drain():
                raise Drained([n for n, _ in cases[k:]])
            d = str(out_root / name)
            res = run_case(case, d, max_steps=max_steps)
            rec = {"name": name, "status": "ok", "out_dir": d, "summary": res.summary,
                   "post": post(case, res, d)}
            on_done(rec)
            recs.append(rec)
            if after_each is not None:
                after_each(out_root)
        return recs
    return run


def test_sweep_at_constant_peak_acceleration_exits_0_and_aggregates(tmp_path, monkeypatch):
    """All points ok -> exit 0; constant peak acceleration: the amplitude follows 1/f^2.  The
    batch runs in this process (dem.batch.run_batch replaced by a sequential loop over
    dem.run.run_case), to keep the test to seconds; the dask path is the test above."""
    import dem.batch

    monkeypatch.setattr(dem.batch, "run_batch", sequential_batch())
    case = case_file(tmp_path, BLOCK)
    out = tmp_path / "sweep"
    r = CliRunner().invoke(app, ["sweep", str(case), "--out", str(out), "--range", "2:4:1",
                                 "--cycles", "3", "--margin", "0.1"])
    assert r.exit_code == 0, r.output
    data = json.loads((out / "sweep.json").read_text())
    assert data["constant"] == "peak_acceleration" and data["failed"] == []
    for p in data["points"]:
        f = p["frequency_hz"]
        assert p["amplitude_m"] == pytest.approx(1.5 / (2 * math.pi * f) ** 2)
        assert p["duration_s"] == pytest.approx(3 / f + 0.1)
        assert p["amplification"]["da"] == pytest.approx(1.0, abs=0.01)
    agg = data["aggregate"]
    # a block that moves with the table has no resonance: no characteristic frequency, a reason
    assert agg["n_valid"] == 3 and agg["characteristic_frequency_hz"] is None
    assert agg["characteristic_frequency_note"].startswith("no clear peak")
    assert (out / "sweep.png").is_file()


def test_effective_range_two_groups_and_half_power():
    """Model II y-like curve: inside ~2, outside < 0.5 -> the two groups; a smooth curve without
    a gap falls back to half power."""
    f = [1.8, 2.0, 2.4, 2.8, 3.2, 3.6]
    er = effective_range(
        f, [0.35, 0.42, 1.9, 2.2, 1.8, 0.4])
    assert er["characteristic_frequency_hz"] == 2.8
    assert er["effective_range_hz"] == [2.4, 3.2] and er["rule"].startswith("two groups")
    smooth = [1.0, 1.3, 1.6, 2.0, 1.6, 1.3]
    er = effective_range(f, smooth)
    assert er["effective_range_hz"] == [2.4, 3.2] and "sqrt" in er["rule"]


def test_dem_post_recomputes_a_tilt_run_from_its_frames(tmp_path):
    """A squat block (mu = 0.5) on a table tilting from 25 deg at 2 deg/s slides at
    atan(0.5) = 26.57 deg; dem post replays the collapse detection over frames.npz and must find
    what the run loop found."""
    from dem_cli.commands.run import RUN_ANALYSES
    from dem.run import run_case

    case = parse_case({
        "name": "block-sliding-on-tilt",
        "scene": {"blocks": [{"size": [0.2, 0.2, 0.1], "position": [0, 0, 0.05], "mass": 4.0}]},
        "material": {"friction": 0.5},
        "loading": {"type": "tilt", "axis": "x", "rate": 2.0, "start_angle": 25.0,
                    "max_angle": 40.0},
        "run": {"duration": 4.0, "output_interval": 0.01, "vtk": False, "snapshot": False},
    })
    res = run_case(case, tmp_path, analyses=RUN_ANALYSES)
    assert res.summary["collapse"]["detected"]
    r = CliRunner().invoke(app, ["post", str(tmp_path)])
    assert r.exit_code == 0, r.output
    post = json.loads((tmp_path / "analysis.json").read_text())
    assert post["kind"] == "tilt" and post["collapse"]["detected"]
    # the replay differs from the run loop only by the angular velocity, taken here from the
    # recorded orientations (the block slides without turning): same frame, same angle
    assert post["collapse"]["angle_deg"] == pytest.approx(res.summary["collapse"]["angle_deg"],
                                                          abs=0.05)
    assert post["collapse"]["angle_deg"] == pytest.approx(math.degrees(math.atan(0.5)), abs=0.5)
    assert post["mechanism"] == json.loads(json.dumps(res.summary["mechanism"]))


def test_analyze_run_on_a_planted_box_model_run_directory(tmp_path):
    """The whole pipeline on disk for a box model without instruments.npz: Fig 4.4 instruments
    read from the planted frames, amplification and lag of the known first harmonic, the parts,
    the labels (the corner bricks rock inside the portion: global rocking, B2-like), the VTU."""
    import pyvista as pv

    from dem.case import load_case
    from dem.loading import loading_from_case

    src = load_case(Path(__file__).resolve().parents[1] / "cases" / "shake" / "model-ii"
                    / "group-3-y-1.53.yaml")
    data = src.model_dump()
    data["loading"].update(frequency=2.8, cycles=10)
    data["run"]["duration"] = 10 / 2.8
    case = parse_case(data)
    scene = build_box_model("II")
    L1, T, x, y, c = _masks(scene)
    upper = (L1 & (c >= 5)) | (T & (c >= 5) & (y < -0.1))
    lower = L1 & (c >= 1) & (c <= 4) & (np.abs(x) <= 0.06 + 0.08 * (c - 1))
    t = np.arange(0, 10 / 2.8 + 1e-9, 0.005)
    fr = _planted_motion(scene, lower, upper, 0.008, 0.012, 2.8, t, decoys=False)
    fr["vel"] = np.gradient(fr["pos"], t, axis=0)
    fr["base_disp"] = loading_from_case(case).base_disp(t)
    np.savez(tmp_path / "frames.npz", **fr)
    (tmp_path / "case.json").write_text(case.model_dump_json())
    (tmp_path / "summary.json").write_text(json.dumps({"status": "ok"}))
    res = sh.analyze_run(tmp_path)
    ax = res["axes"]["y"]
    assert ax["source"] == "frames.npz" and ax["facade"] == "L1"
    # instrument point: outer face of the course-8 centre brick, z = 0.2625 m; linearised
    # planted motion 0.008 (z - 0.035) + 0.012 (z - 0.175), phase 0.4 rad behind the table
    A_tab = 1.53 / (2 * np.pi * 2.8) ** 2
    h1 = (0.008 * (0.2625 - 0.035) + 0.012 * (0.2625 - 0.175)) / A_tab
    assert ax["quantities"]["ds"]["h1_amplitude_ratio"] == pytest.approx(h1, rel=0.01)
    assert ax["quantities"]["ds"]["lag_deg"] == pytest.approx(np.degrees(0.4), abs=0.5)
    p = ax["excited_portion"]
    assert (p["n_upper"], p["n_lower"]) == (38, 14)
    mech = res["mechanism"]
    assert mech["response"] == "global rocking dominated"
    assert mech["corners"] == "B2-like" and mech["line"] == "stepped"
    assert not ax["collapse_suspected"]
    grid = pv.read(tmp_path / "excited.vtu")
    assert np.array_equal(np.asarray(grid.cell_data["excited_part"]),
                          np.where(upper, 2, np.where(lower, 1, 0)))
    for png in ("time_histories.png", "spectrum.png", "excited.png", "energy.png"):
        assert (tmp_path / png).is_file()


def test_a_record_of_one_sample_is_a_shake_analysis_error():
    """A run stopped in its settle phase leaves one frame: the analysis says so
    (ShakeAnalysisError, which the sweep reports as a failed analysis), not a bare ValueError
    from the time grid."""
    from postprocess.shake_signals import ShakeAnalysisError, uniform_frames

    with pytest.raises(ShakeAnalysisError, match="1 sample"):
        uniform_frames(np.array([0.0]), [np.zeros((1, 3))])
    t = np.array([0.0, 0.01, 0.02])
    tu, (a,) = uniform_frames(t, [np.ones((3, 2))])
    assert np.array_equal(tu, t) and a.shape == (3, 2)


def test_a_point_whose_analysis_failed_is_marked_so():
    """A run that finished but whose analysis failed is a failed point whose error says
    "analysis: ..." (the analysis' own error field used to overwrite the marked one, so it read
    like a failed run)."""
    from postprocess.sweep import point_record

    case = parse_case({"name": "t", "scene": {"blocks": [{"size": [0.1, 0.1, 0.1],
                                                          "position": [0, 0, 0.05],
                                                          "density": 2000.0}]},
                       "material": {"friction": 0.8},
                       "loading": {"type": "shake", "direction": [1, 0, 0], "frequency": 2.0,
                                   "amplitude": 0.001, "cycles": 2},
                       "run": {"duration": 1.0}})
    rec = {"status": "ok", "summary": {"steps": 10},
           "post": {"analysis_status": "failed", "error": "no instruments.npz"}}
    p = point_record(2.0, case, rec, Path("."))
    assert p["status"] == "failed" and p["error"] == "analysis: no instruments.npz"
    ok = point_record(2.0, case, {"status": "ok", "post": {"analysis_status": "ok"}}, Path("."))
    assert ok["status"] == "ok" and "error" not in ok
