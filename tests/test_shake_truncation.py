"""The first N cycles of a longer shaking run analysed as an N-cycle run (the
prediction's 10-against-50-cycles check without new simulations).  The table's sine has no ramp
or taper and the settle phase ends before the clock starts, so an N-cycle run and the first N
cycles of a longer one are the same computation: bit for bit in the frames (a real run of an
imperfect, settling wall below), and postprocess.shake.analyze_run(cycles=N) of the longer run
reads what the N-cycle run reads (up to the resampling grid of jittered frames)."""

from __future__ import annotations

import numpy as np
import pytest

from dem.case import parse_case
from postprocess import shake as sh
from postprocess import shake_signals as ss

F = 2.8


def _sig(cycles=10, dt=0.002, margin=1.0):
    t = np.arange(0, cycles / F + margin, dt)
    u = 0.005 * np.sin(2 * np.pi * F * t)
    exc = {"displacement": u, "velocity": np.gradient(u, t), "acceleration": -u}
    return ss.ShakeSignals(t=t, f=F, t_end=cycles / F, direction=np.array([0, 1.0, 0]),
                           axis="y", excitation=exc, ds_centre=0.3 * u, a_centre=-u,
                           blocks={"centre": 0})


def test_truncate_keeps_the_first_cycles_and_sets_t_end():
    sig = _sig()
    cut = ss.truncate(sig, 4)
    assert cut.t_end == pytest.approx(4 / F)
    assert cut.t[-1] <= 4 / F + 0.001 and cut.t[-1] > 4 / F - 0.002
    assert np.array_equal(cut.ds_centre, sig.ds_centre[: len(cut.t)])
    assert np.array_equal(cut.excitation["acceleration"],
                          sig.excitation["acceleration"][: len(cut.t)])
    assert cut.ds_corner is None and cut.a_front is None
    assert ss.truncate(sig, 10).t_end == sig.t_end                  # all of it: allowed
    for bad in (0, -1, 10.5):
        with pytest.raises(ss.ShakeAnalysisError, match=f"cycles = {bad:g}"):
            ss.truncate(sig, bad)
    frames = {"t": np.arange(0, 5.0, 0.02), "pos": np.zeros((250, 3, 3)), "names": np.arange(3)}
    fr = ss.truncate_frames(frames, 1.0)
    assert fr["t"][-1] == pytest.approx(1.02) and len(fr["pos"]) == len(fr["t"]) == 52
    assert fr["names"] is frames["names"] and ss.truncate_frames(None, 1.0) is None


def _wall(cycles):
    """A small imperfect wall (3 x 4 small bricks, warped beds: it settles before the shaking)
    rocking slightly at 3 m/s2, 2.8 Hz; frames every 2 ms (the analysis' resampling grid then
    moves by less than a microsecond between the two records)."""
    return parse_case({
        "name": f"truncation-{cycles}", "scene": {"facade": {"brick": "small", "length": 3,
                                                             "courses": 4}},
        "material": {"friction": 0.81, "base_friction": 1.5},
        "loading": {"type": "shake", "direction": [0, 1, 0], "frequency": F,
                    "peak_acceleration": 3.0, "cycles": cycles},
        "run": {"duration": cycles / F + 0.3, "output_interval": 0.002, "vtk": False,
                "snapshot": False},
        "imperfections": {"bed_unevenness": 1e-4, "face_shape": "planar", "seed": 3}})


def test_the_first_cycles_of_a_longer_run_are_the_shorter_run(tmp_path):
    """2 and 3 cycles of the same imperfect wall: the frames up to 2 / f are equal bit for bit
    (the settling included), and the 3-cycle run analysed over its first 2 cycles gives the
    2-cycle run's ds amplification and lag (measured: 3e-5 relative), the same standing verdict
    and excited bricks.  (On Model II with 0.2 mm planar beds, 2 and 4 cycles against 4 and 10,
    the instruments were bit-equal too and ds agreed to 2e-5.)"""
    from dem.run import run_case

    runs = {}  # 12 blocks: the serial kernel whatever the thread count (one Taichi per process)
    for n in (2, 3):
        res = run_case(_wall(n), tmp_path / f"c{n}")
        assert res.summary["status"] == "ok"
        runs[n] = tmp_path / f"c{n}"
    a, b = (dict(np.load(runs[n] / "frames.npz")) for n in (2, 3))
    assert a["t"][0] == 0.0 and np.array_equal(a["t"][:2], b["t"][:2])
    k = int(np.searchsorted(a["t"], 2 / F, side="right"))
    assert k > 300
    for key in ("t", "pos", "quat", "vel", "base_disp"):
        assert np.array_equal(a[key][:k], b[key][:k]), key
    full = sh.analyze_run(runs[2], plots=False, write=False)
    short = sh.analyze_run(runs[3], cycles=2)
    assert short["excitation"]["cycles"] == 2 and short["excitation"]["recorded_cycles"] == 3
    assert not (runs[3] / "analysis.json").exists()                 # nothing written
    assert short["steady_state"] == full["steady_state"]
    assert short["amplification"]["ds"] == pytest.approx(full["amplification"]["ds"], rel=1e-3)
    assert short["lag"]["ds"]["s"] == pytest.approx(full["lag"]["ds"]["s"], abs=1e-3)
    fa, sa_ = (r["axes"][r["primary_axis"]] for r in (full, short))
    assert sa_["collapse_suspected"] is fa["collapse_suspected"] is False
    assert sa_["excited_portion"]["n_excited"] == fa["excited_portion"]["n_excited"]
    with pytest.raises(ss.ShakeAnalysisError, match="cycles = 4"):
        sh.analyze_run(runs[3], cycles=4)
