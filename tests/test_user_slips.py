"""What a plausible slip of a new user still got through, and the states a user could not see:
one test per class of defect, each failing on the code before its fix.  Fast: the validation
path (dem check) and planted run directories; no test here runs the DEM engine."""

from __future__ import annotations

import json
import math
import time

import pytest
import yaml
from typer.testing import CliRunner

from dem_cli.app import app

CASES = __import__("pathlib").Path(__file__).resolve().parent.parent / "cases"


def _invoke(*args, env=None):
    return CliRunner().invoke(app, [str(a) for a in args], env=env)


def _case(tmp_path, name="case.yaml", **changes):
    """A one-block case (0.1 x 0.1 x 0.2 m, 2000 kg/m3) on the table, shaken 2 cycles at 2 Hz,
    with ``changes`` merged at the top level."""
    data = {"name": "slip",
            "scene": {"blocks": [{"size": [0.1, 0.1, 0.2], "position": [0, 0, 0.1],
                                  "mass": 4.0}]},
            "material": {"friction": 0.6},
            "loading": {"type": "shake", "direction": [1, 0, 0], "frequency": 2.0,
                        "peak_acceleration": 1.0, "cycles": 2},
            "run": {"duration": 1.5, "output_interval": 0.05, "vtk": False}}
    data.update(changes)
    path = tmp_path / name
    path.write_text(yaml.safe_dump(data))
    return path


# ------------------------------------------------------------------------------------------
# every point of a sweep or an ensemble is checked as a case, before anything runs
# ------------------------------------------------------------------------------------------
def test_a_sweep_point_the_check_would_refuse_is_refused_before_anything_runs(tmp_path):
    """1e5 Hz with a step of ~2e-5 s: a period of 1e-5 s, shorter than 20 steps (dem check
    refuses it for a case); the sweep used to run it and call it ok."""
    res = _invoke("sweep", _case(tmp_path), "--out", tmp_path / "sw",
                  "--frequencies", "2,1e5")
    assert res.exit_code == 2, res.output
    assert "f100000.000Hz" in res.output and "shorter than 20 time steps" in res.output
    assert "nothing was run" in res.output
    assert not (tmp_path / "sw").exists()


def test_an_ensemble_realisation_is_checked_as_a_case(tmp_path):
    """A run too short for its shake (refused by dem check) is refused for every realisation
    before the cluster starts."""
    path = _case(tmp_path, run={"duration": 0.3, "output_interval": 0.05},
                 scene={"wall": {"length": 2, "courses": 2}},
                 imperfections={"bed_unevenness": 1e-4})
    res = _invoke("ensemble", path, "--out", tmp_path / "ens", "-n", "2")
    assert res.exit_code == 2, res.output
    assert "realisation seed-0" in res.output and "run.duration" in res.output
    assert not (tmp_path / "ens").exists()


@pytest.mark.parametrize("rng, n", [("1:1000:0.01", 99_901), ("1.8:36:0.2", 172)])
def test_a_range_with_too_many_points_is_refused_naming_the_count_and_the_override(
        tmp_path, rng, n):
    res = _invoke("sweep", _case(tmp_path), "--out", tmp_path / "sw", "--range", rng)
    assert res.exit_code == 2, res.output
    assert f"{n:,} frequencies" in res.output and f"--max-points {n}" in res.output


def test_a_range_says_how_many_points_it_gives(tmp_path):
    from dem.run.sweep import parse_frequencies

    assert len(parse_frequencies(None, "1.8:3.6:0.2")) == 10
    # a refused point stops the sweep after the note on the range
    res = _invoke("sweep", _case(tmp_path), "--out", tmp_path / "sw", "--range", "1.8:3.6:0.2",
                  "--frequencies", "1e5")
    assert "10 frequencies, 1.8 - 3.6 Hz" in res.output and res.exit_code == 2


# ------------------------------------------------------------------------------------------
# environment variables
# ------------------------------------------------------------------------------------------
@pytest.mark.parametrize("name, value", [("DEM_THREADS", "0"), ("DEM_THREADS", "-1"),
                                         ("DEM_THREADS", "abc"), ("DEM_MAX_BLOCKS", "abc"),
                                         ("DEM_MAX_BLOCKS", "0"), ("DEM_ARCH", "gpu"),
                                         ("DEM_TRACEBACK", "0"),
                                         ("DEM_STEPS_PER_LAUNCH", "0"),
                                         ("DEM_STEPS_PER_LAUNCH", "16")])
def test_a_bad_environment_variable_is_one_line_naming_it(tmp_path, name, value):
    res = _invoke("check", CASES / "analytic" / "block-on-tilt.yaml", env={name: value})
    assert res.exit_code == 2, res.output
    lines = res.output.strip().splitlines()
    assert len(lines) == 1 and name in lines[0] and repr(value) in lines[0]


def test_every_variable_the_docs_name_is_checked():
    """The variables dem reads (grep DEM_ in dem/) are those dem.environment checks."""
    import re

    from dem import environment

    root = CASES.parent / "dem"
    read = set()
    for f in root.rglob("*.py"):
        read |= set(re.findall(r"environ(?:\.get)?\(?\[?\"(DEM_[A-Z_]+)\"", f.read_text()))
        read |= set(re.findall(r"int_variable\(\"(DEM_[A-Z_]+)\"", f.read_text()))
    checked = set(environment.FLAGS) | {name for name, _, _ in environment.INTEGERS} | \
        {"DEM_ARCH"}
    assert read and read <= checked, read - checked


# ------------------------------------------------------------------------------------------
# a shake longer than the run
# ------------------------------------------------------------------------------------------
def test_a_shake_the_run_cuts_short_is_refused(tmp_path):
    """50 cycles at 2 Hz take 25 s; a 0.5 s run shakes 1 of them."""
    path = _case(tmp_path, loading={"type": "shake", "direction": [1, 0, 0], "frequency": 2.0,
                                    "peak_acceleration": 1.0, "cycles": 50},
                 run={"duration": 0.5, "output_interval": 0.05})
    res = _invoke("check", path)
    assert res.exit_code == 2, res.output
    assert "run.duration" in res.output and "shakes 1 of them" in res.output


def test_a_shake_cut_in_its_last_fraction_of_a_cycle_warns(tmp_path):
    """2.5 cycles at 2 Hz end at 1.25 s; a 1.1 s run has all 2 full cycles."""
    path = _case(tmp_path, loading={"type": "shake", "direction": [1, 0, 0], "frequency": 2.0,
                                    "peak_acceleration": 1.0, "cycles": 2.5},
                 run={"duration": 1.1, "output_interval": 0.05})
    res = _invoke("check", path)
    assert res.exit_code == 0, res.output
    assert "warning:" in res.output and "fraction of a cycle" in res.output


def test_a_stepped_shake_the_run_cuts_short_is_refused(tmp_path):
    steps = [{"frequency": 2.0, "cycles": 3}, {"frequency": 3.0, "cycles": 3}]
    path = _case(tmp_path, loading={"type": "stepped_shake", "direction": [1, 0, 0],
                                    "peak_acceleration": 1.0, "steps": steps},
                 run={"duration": 1.0, "output_interval": 0.05})
    res = _invoke("check", path)
    assert res.exit_code == 2, res.output
    assert "run.duration" in res.output and "step 0 (2 Hz)" in res.output


def test_the_shipped_shakes_are_not_cut():
    from dem.case import load_case
    from dem.validate import shake_cut

    n = 0
    for f in sorted(CASES.rglob("*.yaml")):
        data = yaml.safe_load(f.read_text())
        if not isinstance(data, dict) or "rocking" in data \
                or "shake" not in str(data.get("loading", {})):
            continue
        case = load_case(f)
        assert shake_cut(case.loading, case.run.duration, lambda loc: str(f)) == ([], []), f
        n += 1
    assert n >= 10


# ------------------------------------------------------------------------------------------
# gravity
# ------------------------------------------------------------------------------------------
def test_upward_gravity_is_refused(tmp_path):
    res = _invoke("check", _case(tmp_path, gravity=[0, 0, 9.81]))
    assert res.exit_code == 2, res.output
    assert "gravity" in res.output and "does not point down" in res.output


@pytest.mark.parametrize("g, text", [(9810.0, "1e+03 g"), (0.0, "no gravity")])
def test_an_implausible_gravity_warns(tmp_path, g, text):
    res = _invoke("check", _case(tmp_path, gravity=g))
    assert res.exit_code == 0, res.output
    assert "IMPLAUSIBLE" in res.output and "gravity" in res.output and text in res.output


def test_a_tilt_without_gravity_is_refused(tmp_path):
    path = _case(tmp_path, gravity=0.0,
                 loading={"type": "tilt", "axis": "x", "rate": 2.0, "max_angle": 40.0})
    res = _invoke("check", path)
    assert res.exit_code == 2, res.output
    assert "gravity" in res.output and "tilt without gravity" in res.output


# ------------------------------------------------------------------------------------------
# YAML aliases
# ------------------------------------------------------------------------------------------
def test_nested_aliases_are_refused_quickly(tmp_path):
    """Seven levels of ten aliases stand for 10^7 values: the old duplicate-key walk visited
    each of them (~ 100 s); one visit per node is milliseconds."""
    lines = ["a: &a [x, x, x, x, x, x, x, x, x, x]"]
    for k, name in enumerate("bcdefg"):
        prev = "abcdefg"[k]
        lines.append(f"{name}: &{name} [" + ", ".join([f"*{prev}"] * 10) + "]")
    path = tmp_path / "alias.yaml"
    path.write_text("\n".join(lines + ["name: x"]) + "\n")
    t0 = time.perf_counter()
    res = _invoke("check", path)
    assert time.perf_counter() - t0 < 20.0
    assert res.exit_code == 2, res.output
    assert "aliases" in res.output and len(res.output.strip().splitlines()) == 1


@pytest.mark.parametrize("text", ["name: &a\n  - *a\n", "name: x\nscene: &s {blocks: [*s]}\n"])
def test_a_recursive_anchor_is_refused_in_one_line(tmp_path, text):
    path = tmp_path / "rec.yaml"
    path.write_text(text)
    res = _invoke("check", path)
    assert res.exit_code == 2, res.output
    assert "RecursionError" not in res.output and "recursive" in res.output
    assert len(res.output.strip().splitlines()) == 1


def test_a_yaml_syntax_error_is_one_line(tmp_path):
    path = tmp_path / "bad.yaml"
    path.write_text("name: x\nscene: [\nmaterial: 1\n")
    res = _invoke("check", path)
    assert res.exit_code == 2
    assert len(res.output.strip().splitlines()) == 1, res.output
    assert "not valid YAML" in res.output


# ------------------------------------------------------------------------------------------
# --show-defaults
# ------------------------------------------------------------------------------------------
def test_show_defaults_prints_valid_yaml_on_stdout():
    res = CliRunner().invoke(app, ["check", str(CASES / "analytic" / "block-on-tilt.yaml"),
                                   "--show-defaults"])
    assert res.exit_code == 0, res.output
    data = yaml.safe_load(res.stdout)
    assert isinstance(data, dict) and data["name"] == "block-on-tilt"
    assert "ok:" in res.stderr


# ------------------------------------------------------------------------------------------
# fields accepted, then without effect
# ------------------------------------------------------------------------------------------
def test_size_scatter_on_explicit_blocks_is_refused(tmp_path):
    res = _invoke("check", _case(tmp_path, imperfections={"size_scatter": [0.001, 0, 0]}))
    assert res.exit_code == 2, res.output
    assert "imperfections.size_scatter" in res.output and "builder" in res.output


def test_a_pair_of_a_material_no_block_has_warns(tmp_path):
    path = _case(tmp_path, material={"friction": 0.6, "materials": ["timber"],
                                     "pairs": [{"between": ["timber", "brick"],
                                                "friction": 0.4}]})
    res = _invoke("check", path)
    assert res.exit_code == 0, res.output
    assert "material.pairs[0].between[0]" in res.output and "'timber'" in res.output


def _hyperbolic_column(tmp_path, max_closure):
    data = yaml.safe_load((CASES / "joint" / "hyperbolic-column.yaml").read_text())
    data["material"]["max_closure"] = max_closure
    path = tmp_path / "hc.yaml"
    path.write_text(yaml.safe_dump(data))
    return path


def test_a_hyperbolic_max_closure_larger_than_a_brick_is_refused(tmp_path):
    res = _invoke("check", _hyperbolic_column(tmp_path, 0.05))
    assert res.exit_code == 2, res.output
    assert "material.max_closure" in res.output and "smallest block dimension" in res.output


def test_a_hyperbolic_max_closure_the_static_load_closes_past_the_limit_is_refused(tmp_path):
    """Nine bricks of 0.336 kg on 0.105 x 0.05 m: p = 9 x 0.336 x 9.81 / 0.00525 = 5650 Pa at
    the base; with d_max = 1 um, d = p / (kn0 + p / d_max) = 0.98 d_max > 0.8 d_max.  The
    smallest d_max that holds: p (1 - 0.8) / (0.8 kn0) = 1.41e-5 m."""
    res = _invoke("check", _hyperbolic_column(tmp_path, 1e-6))
    assert res.exit_code == 2, res.output
    p = 9 * 0.336 * 9.81 / (0.105 * 0.05)
    assert f"{p:.3g} Pa" in res.output
    assert f"max_closure >= {p * 0.2 / (0.8 * 1e8):.3g} m" in res.output


def test_the_shipped_hyperbolic_column_passes():
    res = _invoke("check", CASES / "joint" / "hyperbolic-column.yaml")
    assert res.exit_code == 0 and "warning" not in res.output, res.output


# ------------------------------------------------------------------------------------------
# large explicit scenes
# ------------------------------------------------------------------------------------------
def test_a_scene_listing_too_many_blocks_is_refused_before_validation(tmp_path, monkeypatch):
    """The limit is checked on the parsed file, before 25 000 blocks are validated one by one
    (and the file is parsed once: the later readers reuse it)."""
    import dem.case.document as document

    calls = []
    real = document.Case.model_validate
    monkeypatch.setattr(document.Case, "model_validate",
                        classmethod(lambda cls, d: calls.append(1) or real(d)))
    path = tmp_path / "big.yaml"
    block = "  - {size: [0.2, 0.1, 0.05], position: [0, 0, 0.025], mass: 2.0}\n"
    path.write_text("name: big\nscene:\n blocks:\n" + block * 30
                    + "material: {friction: 0.6}\nrun: {duration: 0.1, output_interval: 0.01}\n")
    res = _invoke("check", path, "--max-blocks", "20")
    assert res.exit_code == 2, res.output
    assert "30 blocks listed, above the limit of 20" in res.output
    assert not calls


def test_a_case_file_is_parsed_once(tmp_path, monkeypatch):
    import dem.case_errors as ce

    n = []
    real = ce.compose
    monkeypatch.setattr(ce, "compose", lambda text: n.append(1) or real(text))
    path = _case(tmp_path)
    res = _invoke("check", path)
    assert res.exit_code == 0, res.output
    assert len(n) <= 1


# ------------------------------------------------------------------------------------------
# write errors: one line, 2 for a path that cannot be written, 1 for a fault while writing
# ------------------------------------------------------------------------------------------
def _planted_run(root, status="ok", frames=3, extra=None):
    """A run directory as dem run leaves it: case.json (a tilt of one block), frames.npz,
    summary.json (``status``, with ``extra`` merged)."""
    import numpy as np

    from dem.case import load_case

    case = load_case(CASES / "analytic" / "block-on-tilt.yaml")
    root.mkdir()
    (root / "case.json").write_text(case.model_dump_json(indent=1))
    n = len(case.scene.blocks)
    t = np.linspace(0.0, 0.2, frames)
    pos = np.tile(np.array([b.position for b in case.scene.blocks], float), (frames, 1, 1))
    pos[:, :, 0] += np.linspace(0.0, 0.01, frames)[:, None]
    np.savez(root / "frames.npz", t=t, pos=pos,
             quat=np.tile([1.0, 0.0, 0.0, 0.0], (frames, n, 1)), base_disp=np.zeros((frames, 3)),
             tilt_angle=np.linspace(0.0, 0.4, frames))
    (root / "summary.json").write_text(json.dumps({"name": case.name, "status": status,
                                                   **(extra or {})}))
    return root


def test_view_into_a_directory_that_cannot_be_written_is_one_line_exit_2(tmp_path,
                                                                        monkeypatch):
    """A read-only file system (EROFS; a chmod would not stop root): refused before drawing,
    so no matplotlib warning about an animation never rendered."""
    import errno
    import tempfile

    run = _planted_run(tmp_path / "run")

    def read_only(*a, **k):
        raise OSError(errno.EROFS, "Read-only file system")

    monkeypatch.setattr(tempfile, "TemporaryFile", read_only)
    import warnings

    with warnings.catch_warnings(record=True) as w:
        warnings.simplefilter("always")
        res = _invoke("view", run, "--out", tmp_path / "ro", "--frames", "2")
    assert res.exit_code == 2, res.output
    assert res.output.strip().splitlines() == [
        f"error: --out {tmp_path / 'ro'}: cannot write here (Read-only file system)"]
    assert not [x for x in w if "Animation" in str(x.message)]


def test_summary_csv_into_a_missing_directory_is_one_line_exit_2(tmp_path):
    run = _planted_run(tmp_path / "run")
    res = _invoke("summary", run, "--csv", tmp_path / "nodir" / "rows.csv")
    assert res.exit_code == 2, res.output
    assert "does not exist" in res.stderr and ".tmp" not in res.stderr
    assert len(res.stderr.strip().splitlines()) == 1


def test_summary_csv_on_a_full_disk_is_one_line_exit_1(tmp_path, monkeypatch):
    import errno

    import dem.output.atomic as atomic

    def full(path, text):
        raise OSError(errno.ENOSPC, "No space left on device", str(path.parent / ".r.1.tmp.csv"))

    monkeypatch.setattr(atomic, "write_text", full)
    res = _invoke("summary", _planted_run(tmp_path / "run"), "--csv", tmp_path / "rows.csv")
    assert res.exit_code == 1, res.output
    assert "No space left on device" in res.stderr and ".tmp" not in res.stderr
    assert "unexpected" not in res.stderr


def test_an_unreachable_scheduler_fails_fast_and_writes_nothing(tmp_path):
    t0 = time.perf_counter()
    res = _invoke("sweep", _case(tmp_path), "--out", tmp_path / "sw", "--frequencies", "2",
                  "--scheduler", "tcp://127.0.0.1:1")
    assert time.perf_counter() - t0 < 15.0
    assert res.exit_code == 2, res.output
    assert "--scheduler" in res.output and "unexpected" not in res.output
    assert not (tmp_path / "sw").exists()


# ------------------------------------------------------------------------------------------
# interrupted is not finished
# ------------------------------------------------------------------------------------------
def test_view_stopped_by_sigterm_says_so_and_leaves_no_temporary_file(tmp_path, monkeypatch):
    import os
    import signal

    from dem.output import animation
    from dem.output.atomic import atomic_path

    def drawing_killed(path, *a, **k):
        with atomic_path(path) as tmp:
            tmp.write_bytes(b"GIF89a")
            os.kill(os.getpid(), signal.SIGTERM)
            time.sleep(5)  # the signal lands here

    monkeypatch.setattr(animation, "write_animation", drawing_killed)
    run = _planted_run(tmp_path / "run")
    before = sorted(p.name for p in run.iterdir())
    res = _invoke("view", run, "--frames", "2")
    assert res.exit_code == 1, res.output
    assert "interrupted by SIGTERM" in res.output
    assert sorted(p.name for p in run.iterdir()) == before


def test_a_tilt_stopped_by_a_signal_is_not_reported_as_no_collapse(tmp_path):
    run = _planted_run(tmp_path / "run", status="interrupted",
                       extra={"error": "stopped by SIGTERM", "sim_time": 0.2})
    res = _invoke("post", run)
    assert "collapse False" not in res.output, res.output
    assert "did not finish" in res.output and "stopped by SIGTERM at t = 0.2 s" in res.output


def test_post_and_summary_of_a_run_in_progress_say_running_with_pid_and_time(tmp_path):
    import fcntl
    import os

    run = _planted_run(tmp_path / "run", status="running", extra={"sim_time": 0.125})
    lock = run / "run.lock"
    lock.write_text(f"{os.getpid()}\n")
    with open(lock, "rb") as fh:
        fcntl.flock(fh.fileno(), fcntl.LOCK_EX)
        post = _invoke("post", run)
        summ = _invoke("summary", run, "--format", "csv")
        (run / "summary.json").unlink()
        early = _invoke("post", run)
    text = f"running, pid {os.getpid()}, t = 0.125 s"
    assert text in post.output, post.output
    assert text in summ.output, summ.output
    assert "never started" not in early.output and f"pid {os.getpid()}" in early.output
    assert "before its first checkpoint" in early.output and early.exit_code == 2


def test_runs_of_a_stopped_batch_are_marked_stopped_and_their_locks_released(tmp_path):
    """What the workers of a local cluster leave when the client is stopped: summary.json
    'running' (the last checkpoint) and a run.lock nobody holds."""
    from dem_cli.commands.sweep import mark_stopped_runs, resume_notes

    out = tmp_path / "ens"
    out.mkdir()
    for name, t in (("seed-0", 0.5), ("seed-1", 1.25)):
        d = out / name
        d.mkdir()
        (d / "summary.json").write_text(json.dumps({"status": "running", "sim_time": t}))
        (d / "run.lock").write_text("999999\n")
        (d / "restart.npz").write_bytes(b"")
    assert resume_notes(out, ["seed-0", "seed-1"]) == ["seed-0 from t = 0.5 s",
                                                       "seed-1 from t = 1.25 s"]
    texts = mark_stopped_runs(out, ["seed-0", "seed-1"], "SIGTERM")
    assert texts == ["seed-0 at t = 0.5 s", "seed-1 at t = 1.25 s"]
    for name in ("seed-0", "seed-1"):
        summ = json.loads((out / name / "summary.json").read_text())
        assert summ["status"] == "interrupted" and "SIGTERM" in summ["error"]
        assert not (out / name / "run.lock").exists()


# ------------------------------------------------------------------------------------------
# mechanism names that fit the scene
# ------------------------------------------------------------------------------------------
def _column(n=3):
    from dem.case import BlockSpec
    from dem.scene import blocks_to_scene

    return blocks_to_scene([BlockSpec(size=[0.105, 0.05, 0.035],
                                      position=[0.0, 0.0, 0.0175 + 0.035 * k], mass=0.336)
                            for k in range(n)])


def _turned(scene, blocks, angle, toe):
    """Poses with ``blocks`` turned by ``angle`` rad about +x through ``toe``."""
    from scipy.spatial.transform import Rotation

    from dem import quaternion

    rot = Rotation.from_rotvec([angle, 0.0, 0.0])
    pos, quat = scene.position.copy(), scene.quat.copy()
    pos[blocks] = toe + rot.apply(scene.position[blocks] - toe)
    quat[blocks] = quaternion.from_rotation(rot * quaternion.rotation(scene.quat[blocks]))
    return pos, quat


def test_a_column_overturning_whole_is_labelled_as_a_column():
    """cases/tilt/column-3-uneven.yaml's column turning about its toe (tilt about +x, load
    -y): 'overturning of the whole column at its base', not a facade's 'D'."""
    from dem.case import load_case
    from postprocess.tilt import classify

    case = load_case(CASES / "tilt" / "column-3-uneven.yaml")
    sc = _column()
    pos, quat = _turned(sc, [0, 1, 2], 0.1, [0.0, -0.025, 0.0])
    res = classify(case, sc, sc.position, sc.quat, pos, quat, [0.0, -1.0, 0.0])
    assert res["kind"] == "column"
    assert res["mechanism"] == "overturning of the whole column at its base"
    pos, quat = _turned(sc, [2], 0.1, [0.0, -0.025, 0.07])
    res = classify(case, sc, sc.position, sc.quat, pos, quat, [0.0, -1.0, 0.0])
    assert res["mechanism"] == "overturning of the top 1 of 3 blocks at joint 2"


def test_ensemble_mechanism_counts_are_text():
    from dem_cli.commands.ensemble import counts_text

    assert counts_text({"B2": 1, "D": 7}) == "7 x D, 1 x B2"
    assert "{" not in counts_text({"overturning of the whole column at its base": 8})


# ------------------------------------------------------------------------------------------
# small things
# ------------------------------------------------------------------------------------------
def test_arch_cuda_without_a_driver_is_one_clean_line():
    import subprocess
    import sys

    from dem.run.batched import cuda_present

    if cuda_present():
        pytest.skip("a CUDA driver is present here")
    r = subprocess.run([sys.executable, "-c", "from dem_cli.commands.sweep import batching; "
                        "batching(None, 'cuda')"], capture_output=True, text=True)
    assert "libcuda" not in r.stderr and "[W " not in r.stderr, r.stderr


def test_an_output_error_never_says_errno_none():
    from dem.output.atomic import OutputError

    assert "Errno None" not in str(OutputError(None, "cannot write the output in x"))
    assert str(OutputError(28, "No space left on device")) == \
        "No space left on device (errno 28)"


@pytest.mark.parametrize("command, name", [("run", "CASE"), ("rocking", "CASE"),
                                           ("post", "DIR"), ("summary", "DIR...")])
def test_usage_lines_name_arguments_in_capitals_and_help_names_no_source_file(command, name):
    res = _invoke(command, "--help")
    usage = next(line for line in res.output.splitlines() if "Usage:" in line)
    assert usage.split()[-1] == name and "{" not in usage
    assert ".py" not in res.output


def test_view_faces_of_one_colour_are_shaded_apart():
    import numpy as np

    from dem.output.animation import FACES, face_shading
    from dem.output.vtk import block_corners

    c = block_corners(np.array([[0.1, 0.1, 0.2]]), np.zeros((1, 3)),
                      np.array([[1.0, 0.0, 0.0, 0.0]]))[0]
    lit = face_shading(np.array([c[list(f)] for f in FACES]))
    assert len(set(np.round(lit, 6))) == 3  # top/bottom, x faces, y faces: three shades


def test_view_says_one_panel(tmp_path):
    res = _invoke("view", _planted_run(tmp_path / "run"), "--frames", "2", "--panels", "1")
    assert res.exit_code == 0, res.output
    assert "(1 panel at" in res.output


def test_summary_names_an_unresolved_onset_and_what_an_ensembles_wall_is(tmp_path):
    run = _planted_run(tmp_path / "run", extra={
        "collapse": {"detected": True, "load_factor": None, "onset_resolved": False},
        "loading": {"type": "tilt"}})
    res = _invoke("summary", run, "--format", "csv")
    assert "onset not resolved" in res.output, res.output
    ens = tmp_path / "ens"
    ens.mkdir()
    for i in range(2):
        _planted_run(ens / f"seed-{i}", extra={"wall_seconds": 10.0,
                                               "collapse": {"detected": True,
                                                            "load_factor": 0.4 + 0.1 * i}})
    (ens / "ensemble.json").write_text(json.dumps(
        {"kind": "ensemble", "case": "block-on-tilt", "seeds": [0, 1],
         "realisations": [{"name": f"seed-{i}", "seed": i, "status": "ok"} for i in range(2)],
         "aggregate": {}}))
    res = _invoke("summary", ens)
    assert "sum over its runs" in " ".join(res.output.split()), res.output
