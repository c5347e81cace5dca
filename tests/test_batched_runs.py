"""K cases in one engine (dem.run.batched, ``dem sweep / dem ensemble --batch K``): each
point of a batch is the run it would have been alone, written into its own directory; a point
that fails does not end its batch-mates; a signal stops every point with its restart point, and
a rerun resumes each point from its own (or starts it over).

Bounds.  A scene of an engine of several scenes runs the same arithmetic on its own slice of the
engine's arrays as a lone scene, so its trajectory is the lone one to round-off: the bound is
tests/engine_helpers.py's ROUND_OFF_POS_M / ROUND_OFF_QUAT (two compilations of the same
arithmetic may differ at the last bit; measured: identical on the 2-core test VM).  The
summary's numbers are functions of that trajectory (energies: sums over ~1e4 steps of products
of it; the sweep's amplification: a ratio of frame amplitudes of ~1 mm): a position error of
1e-15 m moves them by ~1e-12 relative, so rel = 1e-9 leaves three orders of headroom and is
three orders below a logic error (one step's load missed or another point's load applied: the
points differ in frequency; g dt^2 / A ~ 4e-9 m / 1e-3 m ~ 4e-6 relative).
"""

from __future__ import annotations

import json
import math
import os
import signal

import numpy as np
import pytest
from typer.testing import CliRunner

import dem.batch
import dem.run.write
from dem.case import Case
from dem_cli.app import app
from dem_cli.commands.exit_codes import ExitCode
from dem.engine.residency import DEVICE_CHUNK
from dem.run.batched import (BatchInputError, cuda_present, engine_groups,
                             run_cases_in_one_engine)
from dem.run.record import FRAMES_A_REQUEST
from dem.run.resume import RESTART_FILE
from dem.run.settle import CHECK_STEPS
from dem.run.sweep import realisation_cases
from dem.run.write import RunWriter
from tests.engine_helpers import ROUND_OFF_POS_M, ROUND_OFF_QUAT
from tests.test_resume import STACK
from tests.test_shake_analysis import BLOCK, SLIDER, case_file, sequential_batch

REL = 1e-9  # summary numbers (module docstring)
ABS_J = 1e-12  # energies near zero (the residual): 1e-9 of the ~1e-3 J of work done

# the run-time facts of a summary, not results of the simulation
NOT_RESULTS = {"wall_seconds", "cpu_seconds", "compile_seconds", "brick_steps_per_second",
               "machine", "batch", "units", "name", "resumed", "resume"}


def _arrays(path) -> dict:
    with np.load(path) as z:
        return {k: z[k] for k in z.files}


def _numbers(data, prefix=""):
    """{dotted path: number} of every number in a JSON-like dict (bools and text left out)."""
    out = {}
    if isinstance(data, dict):
        for k, v in data.items():
            out.update(_numbers(v, f"{prefix}.{k}" if prefix else str(k)))
    elif isinstance(data, (list, tuple)):
        for i, v in enumerate(data):
            out.update(_numbers(v, f"{prefix}[{i}]"))
    elif isinstance(data, (int, float)) and not isinstance(data, bool):
        out[prefix] = data
    return out


def assert_same_run(a, b) -> None:
    """Run directories ``a`` and ``b`` hold the same run to round-off (module docstring)."""
    fa, fb = _arrays(a / "frames.npz"), _arrays(b / "frames.npz")
    assert fa.keys() == fb.keys()
    np.testing.assert_array_equal(fa["t"], fb["t"])
    for k in ("pos", "base_disp"):
        np.testing.assert_allclose(fa[k], fb[k], rtol=0, atol=ROUND_OFF_POS_M, err_msg=k)
    np.testing.assert_allclose(fa["quat"], fb["quat"], rtol=0, atol=ROUND_OFF_QUAT)
    sa, sb = (json.loads((d / "summary.json").read_text()) for d in (a, b))
    assert sa["status"] == sb["status"] and sa["steps"] == sb["steps"]
    assert sa["dt"] == sb["dt"]
    na = _numbers({k: v for k, v in sa.items() if k not in NOT_RESULTS})
    nb = _numbers({k: v for k, v in sb.items() if k not in NOT_RESULTS})
    assert na.keys() == nb.keys()
    for k in na:
        assert na[k] == pytest.approx(nb[k], rel=REL, abs=ABS_J), k


def in_process_run_batch(calls=None):
    """dem.batch.run_batch in this process: the groups of ``batch`` cases through
    dem.run.batched (as a worker's dem.batch._run_group does, with this process's Taichi)."""

    def run(cases, out_root, scheduler=None, n_workers=None, max_steps=None, post=None,
            on_done=None, analyses=(), drain=None, batch=None, arch="cpu"):
        if calls is not None:
            calls.append(batch)
        recs = []
        size = batch or 1
        for k in range(0, len(cases), size):
            group = cases[k:k + size]
            for rec in run_cases_in_one_engine(group, [out_root / n for n, _ in group],
                                               max_steps=max_steps, analyses=analyses,
                                               arch=arch, post=post):
                on_done(rec)
                recs.append(rec)
        return recs
    return run


def test_a_batched_sweep_equals_the_same_sweep_run_point_by_point(tmp_path, monkeypatch):
    """The shaken block (moving with the table) at 6 and 8 Hz: one engine for the two points,
    each with its own frequency and amplitude, against the two runs alone.  Each
    point's frames, summary and sweep record agree to round-off; summary.json says batch."""
    case = case_file(tmp_path, BLOCK)
    args = ["sweep", str(case), "--frequencies", "6,8", "--cycles", "2", "--margin", "0.05"]
    monkeypatch.setattr(dem.batch, "run_batch", sequential_batch())
    r = CliRunner().invoke(app, [*args, "--out", str(tmp_path / "alone")])
    assert r.exit_code == 0, r.output
    calls = []
    monkeypatch.setattr(dem.batch, "run_batch", in_process_run_batch(calls))
    r = CliRunner().invoke(app, [*args, "--out", str(tmp_path / "batched"), "--batch", "2"])
    assert r.exit_code == 0, r.output
    assert calls == [2] and "--batch 2" in r.output
    alone, batched = (json.loads((tmp_path / d / "sweep.json").read_text())["points"]
                      for d in ("alone", "batched"))
    assert [p["frequency_hz"] for p in batched] == [6.0, 8.0]
    for pa, pb in zip(alone, batched):
        assert_same_run(tmp_path / "alone" / pa["dir"], tmp_path / "batched" / pb["dir"])
        assert pb["amplification"]["da"] == pytest.approx(pa["amplification"]["da"], rel=REL)
    # the points differ (their own loads): the table amplitude a_p / (2 pi f)^2
    assert batched[0]["amplitude_m"] == pytest.approx(batched[1]["amplitude_m"] * (8 / 6) ** 2)
    for k, p in enumerate(batched):
        summ = json.loads((tmp_path / "batched" / p["dir"] / "summary.json").read_text())
        assert summ["batch"]["n_scenes"] == 2 and summ["batch"]["index"] == k
        assert summ["batch"]["dt_s"] == summ["dt"] and summ["batch"]["arch"] == "cpu"
        assert "?" not in summ["units"].values()


def test_a_point_that_fails_does_not_end_its_batch_mates(tmp_path, monkeypatch):
    """``dem sweep --batch 2`` with the points packed 2 to an engine as on a GPU (in this
    process, on the CPU: in_process_run_batch): 3 and 10 Hz share an engine, 12 Hz gets the
    last, smaller one.  The frictionless block slides at up to 2 A w relative to the table
    (tests/test_shake_analysis.py, SLIDER): 0.63 m/s at 10 Hz and 0.75 at 12 Hz, above
    solver.max_speed = 0.4, reached when A w (1 - cos w t) = 0.4, within the first cycle (the
    table itself, A w = 0.31 and 0.38 m/s, stays below it: dem check passes the points); those
    points fail alone; the 3 Hz point runs its 2 cycles to the end in the same engine as the
    10 Hz one and gives the lone run's analysis (sliding: ds amplification pi)."""
    case = case_file(tmp_path, SLIDER)
    out = tmp_path / "sweep"
    monkeypatch.setattr(dem.batch, "run_batch", in_process_run_batch())
    r = CliRunner().invoke(app, ["sweep", str(case), "--out", str(out), "--frequencies",
                                 "3,10,12", "--margin", "0", "--workers", "1", "--batch", "2"])
    assert r.exit_code == ExitCode.RUN_FAILED, r.output
    pts = {p["frequency_hz"]: p for p in json.loads((out / "sweep.json").read_text())["points"]}
    for f in (10.0, 12.0):
        assert pts[f]["status"] == "failed" and "max_speed" in pts[f]["error"]
    assert pts[3.0]["status"] == "ok"
    assert pts[3.0]["amplification"]["ds"] == pytest.approx(np.pi, rel=0.01)
    ok, bad, last = (json.loads((out / pts[f]["dir"] / "summary.json").read_text())
                     for f in (3.0, 10.0, 12.0))
    assert ok["status"] == "ok" and ok["sim_time"] == pytest.approx(2 / 3.0, abs=2 * ok["dt"])
    assert bad["status"] == "failed" and bad["sim_time"] < 1 / 10.0
    assert (ok["batch"]["n_scenes"], bad["batch"]["n_scenes"], last["batch"]["n_scenes"]) == \
        (2, 2, 1)
    assert (out / pts[10.0]["dir"] / "frames.npz").is_file()  # the failed run is written


def _sigterm_after_checkpoints(monkeypatch, n: int) -> None:
    """A checkpoint at every frame; after the n-th (of all points together) the process gets a
    SIGTERM, as from ``timeout`` or a batch scheduler."""
    monkeypatch.setattr(dem.run.write, "CHECKPOINT_SECONDS", -1.0)
    monkeypatch.setattr(dem.run.write, "CHECKPOINT_SHARE", math.inf)  # never paced apart
    calls = [0]
    original = RunWriter.checkpoint

    def checkpoint(self, *args):
        original(self, *args)
        calls[0] += 1
        if calls[0] == n:
            os.kill(os.getpid(), signal.SIGTERM)

    monkeypatch.setattr(RunWriter, "checkpoint", checkpoint)


def test_a_sigterm_stops_every_point_and_a_rerun_resumes_each_from_its_own(tmp_path,
                                                                          monkeypatch):
    """Two realisations of the settling, sliding stack (tests/test_resume.py) in one engine.
    A SIGTERM (received by the main thread, the scheduler's) ends both runs 'interrupted' with
    their restart points; the rerun resumes seed 3 from its restart point and starts seed 4
    over (its restart point removed); both then equal the batch that was never stopped."""
    from dem.signals import stop_on_signals

    cases = realisation_cases(Case.model_validate(STACK), 2, 3)
    names = [n for n, _ in cases]
    whole = run_cases_in_one_engine(cases, [tmp_path / "whole" / n for n in names])
    assert [r["status"] for r in whole] == ["ok", "ok"]
    cut = [tmp_path / "cut" / n for n in names]
    with monkeypatch.context() as m:
        _sigterm_after_checkpoints(m, 5)
        with stop_on_signals(), pytest.raises(KeyboardInterrupt) as info:
            run_cases_in_one_engine(cases, cut)
    assert getattr(info.value, "signame", None) == "SIGTERM"
    steps = []
    for d in cut:
        summ = json.loads((d / "summary.json").read_text())
        assert summ["status"] == "interrupted" and "SIGTERM" in summ["error"]
        assert summ["batch"]["n_scenes"] == 2
        steps.append(int(_arrays(d / RESTART_FILE)["sim.step_count"]))
    assert all(0 < s < whole[0]["summary"]["steps"] for s in steps)
    (cut[1] / RESTART_FILE).unlink()
    again = run_cases_in_one_engine(cases, cut)
    assert [r["status"] for r in again] == ["ok", "ok"]
    (entry,) = again[0]["summary"]["resumed"]
    assert entry["step"] == steps[0]
    assert "resumed" not in again[1]["summary"]
    for d, n in zip(cut, names):
        assert_same_run(tmp_path / "whole" / n, d)
        assert not (d / RESTART_FILE).exists()


def test_a_sigterm_between_requests_of_a_device_batch_and_its_rerun(tmp_path, monkeypatch):
    """A SIGTERM on device arrays, where the run loop asks for FRAMES_A_REQUEST frames at a
    time and its checkpoints come between requests (dem.run.record.LaunchProbe): a SIGTERM
    after the first request of both points ends them 'interrupted' with that request's frames
    and the state where they stopped; the rerun resumes both from their restart points and they
    equal the device batch never stopped, frames (taken inside the launches) and summary."""
    from dem.signals import stop_on_signals

    # perfect (no settling, no warped faces: the device kernel's variant the warm-up compiles),
    # 0.6 cycles at 10 Hz in 0.07 s, a frame every 5 ms; two points at two peak accelerations
    data = json.loads(json.dumps({k: v for k, v in STACK.items() if k != "imperfections"}))
    data["loading"]["frequency"] = 10.0
    data["run"].update(duration=0.07, output_interval=0.005)
    cases = []
    for k, peak in enumerate((6.0, 7.0)):
        case = json.loads(json.dumps(data))
        case["name"], case["loading"]["peak_acceleration"] = f"peak{k}", peak
        cases.append((case["name"], Case.model_validate(case)))
    names = [n for n, _ in cases]
    whole = run_cases_in_one_engine(cases, [tmp_path / "whole" / n for n in names],
                                    device_arrays=True)
    assert [r["status"] for r in whole] == ["ok", "ok"]
    cut = [tmp_path / "cut" / n for n in names]
    with monkeypatch.context() as m:
        _sigterm_after_checkpoints(m, 2)
        with stop_on_signals(), pytest.raises(KeyboardInterrupt):
            run_cases_in_one_engine(cases, cut, device_arrays=True)
    for d, n in zip(cut, names):
        summ = json.loads((d / "summary.json").read_text())
        assert summ["status"] == "interrupted"
        t = _arrays(d / "frames.npz")["t"]  # the first request's frames, then where it stopped
        whole_t = _arrays(tmp_path / "whole" / n / "frames.npz")["t"]
        assert np.array_equal(t[:FRAMES_A_REQUEST + 1], whole_t[:FRAMES_A_REQUEST + 1])
        assert t[-1] == summ["sim_time"] < whole_t[-1]
    again = run_cases_in_one_engine(cases, cut, device_arrays=True)
    assert [r["status"] for r in again] == ["ok", "ok"]
    for d, n, rec in zip(cut, names, again):
        assert len(rec["summary"]["resumed"]) == 1
        assert_same_run(tmp_path / "whole" / n, d)


def test_a_batch_is_k_to_an_engine_on_a_gpu_and_one_on_the_cpu():
    """engine_groups: on a GPU the runs in order, K to an engine, the last smaller; on the CPU
    one run to an engine whatever K (an engine of K on one core is slower per scene-step than
    K lone engines); every run in exactly one group, in order."""
    for n in range(0, 14):
        for k in range(1, 7):
            gpu, cpu = engine_groups(n, k, "cuda"), engine_groups(n, k, "cpu")
            for groups in (gpu, cpu):
                assert [i for g in groups for i in g] == list(range(n))
            assert [len(g) for g in gpu] == [k] * (n // k) + ([n % k] if n % k else [])
            assert [len(g) for g in cpu] == [1] * n
            # the CPU proxy of a GPU batch (DEM_DEVICE_ARRAYS=1) is grouped as on a GPU
            assert engine_groups(n, k, "cpu", device_arrays=True) == gpu
    with pytest.raises(BatchInputError, match="--batch"):
        engine_groups(3, 0, "cuda")
    with pytest.raises(BatchInputError, match="--arch"):
        engine_groups(3, 2, "tpu")


def test_run_batch_hands_the_workers_the_engine_groups(tmp_path, monkeypatch):
    """dem.batch.run_batch with ``batch`` submits one task per group of engine_groups: on the
    CPU each run alone (the task of a run without --batch), on a single-threaded worker; on a
    GPU, or with DEM_DEVICE_ARRAYS=1, K to a group task; the records come back one per case, in
    order (the cluster replaced by one that runs each task at once)."""
    import dask.distributed

    submitted = []

    class Future:
        def __init__(self, value):
            self.value = value

        def result(self):
            return self.value

    class Client:
        def __init__(self, *args, **kwargs):
            pass

        def submit(self, fn, *args, key=None, pure=None):
            return Future(fn(*args))

        def close(self):
            pass

    class Cluster:
        def __init__(self, n_workers, **kwargs):
            self.n_workers = n_workers

        def close(self):
            pass

    def run_group(names, case_jsons, out_dirs, threads, max_steps, post, analyses, arch):
        submitted.append((list(names), threads, arch))
        return [{"name": n, "status": "ok", "out_dir": d} for n, d in zip(names, out_dirs)]

    def run_one(name, case_json, out_dir, threads, max_steps, post, analyses):
        submitted.append((name, threads, "cpu, alone"))
        return {"name": name, "status": "ok", "out_dir": out_dir}

    monkeypatch.setattr(dask.distributed, "Client", Client)
    monkeypatch.setattr(dask.distributed, "LocalCluster", Cluster)
    monkeypatch.setattr(dask.distributed, "as_completed", lambda: _Completed())
    monkeypatch.setattr(dem.batch, "_run_group", run_group)
    monkeypatch.setattr(dem.batch, "_run_one", run_one)
    case = Case.model_validate(BLOCK)
    cases = [(f"p{i}", case) for i in range(5)]
    names = [n for n, _ in cases]
    recs = dem.batch.run_batch(cases, tmp_path, n_workers=2, batch=5)
    assert [r["name"] for r in recs] == names
    # on the CPU each run alone, as without --batch, on a single-threaded worker: the lone
    # serial kernel (one thread, auto mode)
    assert submitted == [(n, 1, "cpu, alone") for n in names]
    submitted.clear()
    monkeypatch.setenv("DEM_DEVICE_ARRAYS", "1")
    dem.batch.run_batch(cases, tmp_path, n_workers=2, batch=2)
    assert [s[0] for s in submitted] == [names[0:2], names[2:4], names[4:5]]
    monkeypatch.delenv("DEM_DEVICE_ARRAYS")
    submitted.clear()
    recs = dem.batch.run_batch(cases, tmp_path, n_workers=1, batch=2, arch="cuda")
    assert [r["name"] for r in recs] == names
    assert [s[0] for s in submitted] == [names[0:2], names[2:4], names[4:5]]
    assert {s[2] for s in submitted} == {"cuda"}


class _Completed:
    """dask.distributed.as_completed for futures that are already done: each in turn, and
    those added while iterating."""

    def __init__(self):
        self.items = []

    def add(self, fut):
        self.items.append(fut)

    def __iter__(self):
        while self.items:
            yield self.items.pop(0)


def test_cases_with_different_solver_options_are_refused_naming_the_field(tmp_path):
    data = json.loads(json.dumps(BLOCK))
    a = Case.model_validate(data)
    data["solver"] = {"max_speed": 2.0}
    b = Case.model_validate(data)
    with pytest.raises(BatchInputError, match="solver.max_speed"):
        run_cases_in_one_engine([("a", a), ("b", b)], [tmp_path / "a", tmp_path / "b"])
    assert not (tmp_path / "a").exists()


def test_bad_batch_and_arch_options_exit_2_before_anything_runs(tmp_path):
    case = case_file(tmp_path, BLOCK)
    base = ["sweep", str(case), "--out", str(tmp_path / "s"), "--frequencies", "2"]
    r = CliRunner().invoke(app, [*base, "--batch", "0"])
    assert r.exit_code == ExitCode.BAD_INPUT and "--batch must be >= 1" in r.output
    r = CliRunner().invoke(app, [*base, "--arch", "tpu"])
    assert r.exit_code == ExitCode.BAD_INPUT and "--arch must be one of cpu, cuda" in r.output
    if not cuda_present():
        r = CliRunner().invoke(app, ["ensemble", str(case), "--out", str(tmp_path / "e"), "-n",
                                     "2", "--batch", "2", "--arch", "cuda"])
        assert r.exit_code == ExitCode.BAD_INPUT
        assert "CUDA was asked for and is not available" in r.output


# a small box model (18 blocks) with the thesis' instruments and imperfect beds: each point
# settles (~3300 steps), starts in the lab frame (the host writes the velocities) and records
# frames and 1 kHz instrument samples
SMALL_BOX = {
    "name": "small-box",
    "scene": {"box_model": {"length": 2, "width": 2, "courses": 3, "roof": None}},
    "material": {"friction": 0.81, "base_friction": 1.5},
    "loading": {"type": "shake", "direction": [0, 1, 0], "frequency": 5.0,
                "peak_acceleration": 2.0, "cycles": 1, "start": "lab"},
    "run": {"duration": 0.2, "output_interval": 0.005, "instrument_interval": 0.001,
            "instruments": "thesis", "vtk": False, "snapshot": False},
    "solver": {"mode": "parallel"},
    "imperfections": {"bed_unevenness": 2e-5, "face_shape": "planar", "seed": 0},
}


def _device_and_numpy_runs(cases, tmp_path, **kwargs) -> dict:
    """Run ``cases`` in one engine twice, with device arrays (into tmp_path / "True") and with
    numpy's (tmp_path / "False"), every point ok; returns the engines by device_arrays."""
    engines = {}
    for dev in (True, False):
        recs = run_cases_in_one_engine(cases, [tmp_path / str(dev) / n for n, _ in cases],
                                       resume=False, device_arrays=dev,
                                       on_engine=lambda e, d=dev: engines.__setitem__(d, e),
                                       **kwargs)
        assert [r["status"] for r in recs] == ["ok", "ok"], recs
    return engines


def _same_recordings(a, b, name) -> None:
    """frames.npz and instruments.npz of run directories a and b equal, array by array."""
    for f in ("frames.npz", "instruments.npz"):
        fa, fb = _arrays(a / f), _arrays(b / f)
        assert fa.keys() == fb.keys()
        for k in fa:
            assert np.array_equal(fa[k], fb[k]), (name, f, k)


def test_a_batch_with_device_arrays_on_the_cpu_records_what_the_numpy_path_records(tmp_path):
    """The device path's data movement (dem.engine.device; read-only accessors that copy only
    the stale fields asked for, writers that send everything back) changes no output: two
    settling, lab-started, instrumented points record the same frames and instrument samples as
    with the host's numpy arrays, bit for bit (the same parallel kernel; the energy sums, added
    with atomics on a device, are left out)."""
    cases = []
    for seed in range(2):
        data = json.loads(json.dumps(SMALL_BOX))
        data["name"], data["imperfections"]["seed"] = f"seed{seed}", seed
        cases.append((data["name"], Case.model_validate(data)))
    engines = _device_and_numpy_runs(cases, tmp_path, max_steps=5000)
    assert engines[True].on_device and not engines[False].on_device
    stats = engines[True].transfer_stats()
    assert stats["device_to_host"]["copies"] > 0
    for name, _ in cases:
        a, b = (tmp_path / str(dev) / name for dev in (True, False))
        _same_recordings(a, b, name)
        assert len(_arrays(a / "frames.npz")["t"]) >= 5
        sa, sb = (json.loads((d / "summary.json").read_text()) for d in (a, b))
        assert sa["steps"] == sb["steps"] == 5000
        assert sa["settling"]["steps"] == sb["settling"]["steps"] < 5000
        # the data moved over many chunks: at least one a settling look and one a device chunk
        # of the load phase (its frames are taken inside the launches)
        settled = sa["settling"]["steps"]
        assert stats["chunks"] >= settled // CHECK_STEPS + (5000 - settled) // DEVICE_CHUNK
        assert sa["table_start"] == sb["table_start"]
        assert (sa["n_pairs"], sa["n_contact_points"]) == (sb["n_pairs"], sb["n_contact_points"])


def _perfect_small_boxes(**run) -> list:
    """Two perfect (unsettled) small boxes shaken at 5 and 7 Hz, a frame and an instrument
    sample every 5 ms (on the same steps), ``run`` fields changed: (name, Case) pairs."""
    cases = []
    for k, frequency in enumerate((5.0, 7.0)):
        data = json.loads(json.dumps(SMALL_BOX))
        data["name"], data["loading"]["frequency"] = f"point{k}", frequency
        data["run"]["instrument_interval"] = data["run"]["output_interval"]
        data["run"].update(run)
        data.pop("imperfections")
        cases.append((data["name"], Case.model_validate(data)))
    return cases


def test_a_device_takes_the_frames_inside_its_launches(tmp_path):
    """On a device a frame does not end the chunk of every scene: the run loop asks for
    FRAMES_A_REQUEST frames at a time and the engine copies the frames between into its probe
    buffer (dem.run.record.LaunchProbe).  Two perfect (unsettled) points of the small box,
    shaken for 0.1 s with a frame and an instrument sample every 5 ms (on the same steps; a
    sample every 1 ms would fill the probe's slots first): frames.npz and instruments.npz are
    those of the host's numpy path, which ends its advance at every frame, bit for bit; and the
    device's engine ran its chunk length's chunks and one a request, fewer than one a frame."""
    cases = _perfect_small_boxes(duration=0.1)  # two requests of FRAMES_A_REQUEST frames
    engines = _device_and_numpy_runs(cases, tmp_path)
    sim = engines[True].simulations[0]
    assert sim.frames_in_launches and not engines[False].simulations[0].frames_in_launches
    assert len(sim.probe.bodies) == sim.n_blocks and sim.probe.frames
    n_frames = []
    for name, _ in cases:
        a, b = (tmp_path / str(dev) / name for dev in (True, False))
        _same_recordings(a, b, name)
        n_frames.append(len(_arrays(a / "frames.npz")["t"]))
    assert min(n_frames) == 21  # t = 0, 0.005, ..., 0.1
    # the device's chunks: its chunk length's and one more a request of FRAMES_A_REQUEST
    # frames (a frame an advance would end a chunk every ~340 steps)
    steps = sim.step_count
    requests = -(-(min(n_frames) - 1) // FRAMES_A_REQUEST)
    assert engines[True].transfer_stats()["chunks"] <= -(-steps // DEVICE_CHUNK) + requests
    assert engines[False].launcher.n_chunks >= min(n_frames) - 1  # the host: one a frame


def test_a_step_limit_on_a_frame_taken_inside_a_launch_records_it_once(tmp_path):
    """--max-steps may end a request at a frame the engine took inside its launch: the run's
    last frame is then that one, not a second copy of it (the numpy path, which stops at every
    frame, records it once)."""
    cases = _perfect_small_boxes()
    probe = tmp_path / "probe"
    run_cases_in_one_engine(cases, [probe / n for n, _ in cases], max_steps=1200,
                            resume=False, device_arrays=False)
    frames = _arrays(probe / "point0" / "frames.npz")["t"]
    dt = json.loads((probe / "point0" / "summary.json").read_text())["batch"]["dt_s"]
    limit = int(round(frames[2] / dt))  # the third frame's step: inside the first request
    assert 0 < limit < 1200 and FRAMES_A_REQUEST > 3
    _device_and_numpy_runs(cases, tmp_path, max_steps=limit)
    for name, _ in cases:
        a, b = (tmp_path / str(dev) / name for dev in (True, False))
        _same_recordings(a, b, name)
        t = _arrays(a / "frames.npz")["t"]
        assert len(t) == 3 and len(np.unique(t)) == 3
