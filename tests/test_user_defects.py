"""What a new user met on a second day with the tool, one section per defect (1-8), each test
guarding the behaviour that replaced it.  Fast: no test here runs the DEM engine (the runs
they need are planted files)."""

from __future__ import annotations

import json
import math

import numpy as np
import pytest
import yaml
from typer.testing import CliRunner

from dem_cli.app import app
from dem.output.plotting import agg_pyplot

CASES = __import__("pathlib").Path(__file__).resolve().parent.parent / "cases"


def _invoke(*args):
    return CliRunner().invoke(app, [str(a) for a in args])


# ------------------------------------------------------------------------------------------
# defect 1: dem post on an ensemble directory
# ------------------------------------------------------------------------------------------
def _planted_tilt_ensemble(root, lambdas):
    """A `dem ensemble` directory of a tilt case with planted results (what dem.batch writes:
    seed-S/case.json, summary.json; ensemble.json with the seeds)."""
    from dem.case import load_case

    case = load_case(CASES / "analytic" / "block-on-tilt.yaml")
    root.mkdir()
    rows = []
    for i, lam in enumerate(lambdas):
        d = root / f"seed-{i}"
        d.mkdir()
        (d / "case.json").write_text(case.model_dump_json(indent=1))
        col = {"detected": lam is not None, "load_factor": lam,
               "angle_deg": math.degrees(math.atan(lam)) if lam else None}
        (d / "summary.json").write_text(json.dumps(
            {"name": d.name, "status": "ok", "collapse": col,
             "mechanism": {"mechanism": "overturning"}}))
        rows.append({"name": d.name, "seed": i, "status": "pending"})
    (root / "ensemble.json").write_text(json.dumps(
        {"kind": "ensemble", "case": case.name, "seeds": list(range(len(lambdas))),
         "realisations": rows, "aggregate": {}}))


def test_post_of_an_ensemble_reaggregates_it(tmp_path):
    lambdas = [0.41, 0.45, 0.47]
    _planted_tilt_ensemble(tmp_path / "ens", lambdas)
    res = _invoke("post", tmp_path / "ens")
    assert res.exit_code == 0, res.output
    assert "Traceback" not in res.output
    data = json.loads((tmp_path / "ens" / "ensemble.json").read_text())
    stats = data["aggregate"]["statistics"]["lambda"]
    assert stats["n"] == 3 and stats["median"] == float(np.median(lambdas))
    assert data["aggregate"]["mechanisms"] == {"overturning": 3}
    assert (tmp_path / "ens" / "lambda.png").is_file()


def test_post_of_a_directory_that_is_none_of_them_says_so_in_one_line(tmp_path):
    (tmp_path / "x").mkdir()
    (tmp_path / "x" / "notes.txt").write_text("hello")
    res = _invoke("post", tmp_path / "x")
    assert res.exit_code == 2
    assert len(res.output.strip().splitlines()) == 1
    assert "not a run" in res.output and "ensemble" in res.output


def test_post_of_run_directories_of_a_tilt_case_is_not_taken_for_a_sweep(tmp_path):
    _planted_tilt_ensemble(tmp_path / "ens", [0.4, 0.5])
    (tmp_path / "ens" / "ensemble.json").unlink()  # just a folder of tilt runs
    res = _invoke("post", tmp_path / "ens")
    assert res.exit_code == 2, res.output
    assert "Traceback" not in res.output and "not a sweep" in res.output


# ------------------------------------------------------------------------------------------
# defect 2: --resume drops the killed run's analysis and says what it does
# ------------------------------------------------------------------------------------------
def test_resume_drops_the_stopped_runs_analysis_and_says_where_it_goes_on(tmp_path,
                                                                          monkeypatch):
    import dem.run.write
    from dem.case import load_case
    from dem.run import run_case
    from dem.run.write import RunWriter

    data = {
        "name": "one-brick-shaken",
        "scene": {"blocks": [{"size": [0.2, 0.1, 0.05], "position": [0, 0, 0.025],
                              "density": 2000.0}]},
        "material": {"friction": 0.5},
        # half a cycle: the whole shake within the 0.1 s run (a shake cut is refused)
        "loading": {"type": "shake", "direction": [0, 1, 0], "frequency": 5.0,
                    "peak_acceleration": 2.0, "cycles": 0.5},
        "run": {"duration": 0.1, "output_interval": 0.01, "vtk": False, "snapshot": False},
    }
    path = tmp_path / "brick.yaml"
    path.write_text(yaml.safe_dump(data))
    out = tmp_path / "cut"
    with monkeypatch.context() as m:  # a checkpoint at every frame, stopped after the 3rd
        m.setattr(dem.run.write, "CHECKPOINT_SECONDS", -1.0)
        m.setattr(dem.run.write, "CHECKPOINT_SHARE", math.inf)  # never paced apart
        calls, original = [0], RunWriter.checkpoint

        def checkpoint(self, *args):
            calls[0] += 1
            if calls[0] > 3:
                raise KeyboardInterrupt
            original(self, *args)

        m.setattr(RunWriter, "checkpoint", checkpoint)
        with pytest.raises(KeyboardInterrupt):
            run_case(load_case(path), out)
    stopped_at = json.loads((out / "summary.json").read_text())["sim_time"]
    # what `dem post` of the stopped run leaves (its analysis of the run so far)
    (out / "analysis.json").write_text(json.dumps({"run_status": "interrupted"}))
    (out / "time_histories.png").write_bytes(b"png")
    r = _invoke("run", path, "--out", out, "--resume", "--no-progress")
    assert r.exit_code == 0, r.output
    assert "resuming from t = " in r.output
    said = float(r.output.split("resuming from t = ")[1].split()[0])
    assert 0 < said <= stopped_at  # the last checkpoint, at or before the stop
    assert not (out / "analysis.json").exists() and not (out / "time_histories.png").exists()
    assert json.loads((out / "summary.json").read_text())["status"] == "ok"
    # a finished run cannot be resumed: said, and it starts over
    r = _invoke("run", path, "--out", out, "--resume", "--no-progress")
    assert r.exit_code == 0, r.output
    assert "cannot resume: the run in" in r.output and "starting over" in r.output


# ------------------------------------------------------------------------------------------
# defect 3: absurd but well-formed input
# ------------------------------------------------------------------------------------------
def _brick_case(tmp_path, density=2000.0, loading=None, extra_block=None):
    blocks = [{"size": [0.2, 0.1, 0.05], "position": [0, 0, 0.025], "density": density}]
    blocks += extra_block or []
    data = {"name": "brick", "scene": {"blocks": blocks}, "material": {"friction": 0.6},
            "loading": loading or {"type": "none"},
            "run": {"duration": 0.5, "output_interval": 0.01, "vtk": False}}
    path = tmp_path / "case.yaml"
    path.write_text(yaml.safe_dump(data))
    return path


@pytest.mark.parametrize("density", [1e-6, 1.8e6])
def test_an_impossible_density_is_refused(tmp_path, density):
    """Sizes in mm with masses in g give 1e-6 kg/m3; the reverse 1.8e6 kg/m3: lighter than air
    or denser than osmium is no material."""
    res = _invoke("check", _brick_case(tmp_path, density))
    assert res.exit_code == 2, res.output
    assert "density" in res.output and "impossible" in res.output


@pytest.mark.parametrize("density", [50.0, 11_000.0])
def test_an_implausible_density_warns_loudly(tmp_path, density):
    res = _invoke("check", _brick_case(tmp_path, density))
    assert res.exit_code == 0, res.output
    assert "warning:" in res.output and "IMPLAUSIBLE" in res.output and "density" in res.output


@pytest.mark.parametrize("motion", [{"amplitude": 10.0}, {"peak_acceleration": 1e4}])
def test_an_impossible_table_motion_is_refused(tmp_path, motion):
    """10 m at 2 Hz: v = 2 pi f A = 126 m/s; 1e4 m/s2 at 2 Hz: v = a / (2 pi f) = 796 m/s."""
    path = _brick_case(tmp_path, loading={"type": "shake", "direction": [0, 1, 0],
                                          "frequency": 2.0, "cycles": 2, **motion})
    res = _invoke("check", path)
    assert res.exit_code == 2, res.output
    assert "m/s" in res.output and "impossible" in res.output
    v = (motion.get("amplitude") or motion.get("peak_acceleration", 0) / (2 * np.pi * 2.0) ** 2) \
        * 2 * np.pi * 2.0
    assert f"{v:.3g} m/s" in res.output


def test_a_table_far_above_any_shaking_table_warns(tmp_path):
    """8 g at 2 Hz: A = a / (2 pi f)^2 = 0.50 m, v = 6.2 m/s: possible, but no table does it."""
    path = _brick_case(tmp_path, loading={"type": "shake", "direction": [0, 1, 0],
                                          "frequency": 2.0, "cycles": 1,  # 0.5 s: the run's
                                          "peak_acceleration": 8 * 9.80665})
    res = _invoke("check", path)
    assert res.exit_code == 0, res.output
    assert "IMPLAUSIBLE" in res.output and "8 g" in res.output


def test_a_block_far_from_all_others_warns(tmp_path):
    """Two bricks side by side and a third 1000 km away (a user's case)."""
    near = {"size": [0.2, 0.1, 0.05], "position": [0.3, 0, 0.025], "density": 2000.0}
    far = {"size": [0.2, 0.1, 0.05], "position": [1e6, 0, 0.025], "density": 2000.0}
    res = _invoke("check", _brick_case(tmp_path, extra_block=[near, far]))
    assert res.exit_code == 0, res.output
    assert "IMPLAUSIBLE" in res.output and "block 2" in res.output and "nearest" in res.output
    assert "scene.blocks[2]" in res.output


def _rocking_case(tmp_path, text=None, **loading):
    base = (CASES / "rocking" / "model-ii-2.8hz.yaml").read_text()
    data = yaml.safe_load(base)
    if loading:
        data["loading"] = {"type": "shake", "direction": [0, 1, 0], "cycles": 2, **loading}
    data["run"] = {"duration": 0.5, "output_interval": 0.002}
    path = tmp_path / "rocking.yaml"
    path.write_text(text if text is not None else yaml.safe_dump(data))
    return path


def test_a_two_body_case_at_an_impossible_frequency_is_refused(tmp_path):
    """2.8e5 Hz at 4.69 mm: v = 2 pi f A = 8.3 km/s (such a case once printed 'nan mm', exit 0)."""
    path = _rocking_case(tmp_path, frequency=2.8e5, amplitude=0.00469)
    for cmd in (["check", path], ["rocking", path, "--out", tmp_path / "o"]):
        res = _invoke(*cmd)
        assert res.exit_code == 2, res.output
        assert "impossible" in res.output and "m/s" in res.output
    assert not (tmp_path / "o").exists()


def test_a_nan_in_a_two_body_result_is_a_failed_run(tmp_path, monkeypatch):
    """A NaN anywhere in the state is a failed run (exit 1, summary.json 'failed'), never ok."""
    import dem.rocking.runner as runner

    original = runner.integrate_rocking

    def poisoned(*args, **kw):
        res = original(*args, **kw)
        res.theta2[len(res.theta2) // 2:] = np.nan
        return res

    monkeypatch.setattr(runner, "integrate_rocking", poisoned)
    path = _rocking_case(tmp_path, frequency=2.8, amplitude=0.00469)
    res = _invoke("rocking", path, "--out", tmp_path / "o", "--no-plots")
    assert res.exit_code == 1, res.output
    assert "non-finite" in res.output and "theta2" in res.output
    summ = json.loads((tmp_path / "o" / "summary.json").read_text())
    assert summ["status"] == "failed"


# ------------------------------------------------------------------------------------------
# defect 4: no tracebacks; one writer, one exit-code mapping
# ------------------------------------------------------------------------------------------
def test_schema_out_into_a_missing_directory_exits_2_in_one_line(tmp_path):
    res = _invoke("schema", "--out", tmp_path / "nodir" / "x.json")
    assert res.exit_code == 2
    assert res.exception is None or isinstance(res.exception, SystemExit)
    assert res.output.strip().count("\n") == 0 and "does not exist" in res.output


def test_rocking_on_a_full_disk_fails_cleanly(tmp_path, monkeypatch):
    """ENOSPC on rocking.npz: exit 1, one message, summary.json says failed with write_errors
    (not a 55-line traceback with rocking.npz and no summary.json)."""
    import errno
    import os

    import dem.output.atomic as atomic

    original = atomic.atomic_path

    def full(path):
        if str(path).endswith(".npz"):
            raise OSError(errno.ENOSPC, os.strerror(errno.ENOSPC))
        return original(path)

    monkeypatch.setattr(atomic, "atomic_path", full)
    path = _rocking_case(tmp_path, frequency=2.8, amplitude=0.00469)
    res = _invoke("rocking", path, "--out", tmp_path / "o", "--no-plots")
    assert res.exit_code == 1, res.output
    assert "Traceback" not in res.output and "No space left" in res.output
    summ = json.loads((tmp_path / "o" / "summary.json").read_text())
    assert summ["status"] == "failed" and "rocking.npz" in summ["write_errors"]


# ------------------------------------------------------------------------------------------
# defect 5: one dialect for the two-body cases
# ------------------------------------------------------------------------------------------
def test_two_body_errors_name_file_and_line(tmp_path):
    text = (CASES / "rocking" / "model-ii-2.8hz.yaml").read_text().replace(
        "mass: 6.05", "mass: -6.05")
    path = _rocking_case(tmp_path, text=text)
    line = next(i for i, s in enumerate(text.splitlines(), 1) if "-6.05" in s)
    for cmd in (["check", path], ["rocking", path, "--out", tmp_path / "o"],
                ["run", path, "--out", tmp_path / "o"]):
        res = _invoke(*cmd)
        assert res.exit_code == 2, res.output
        assert f"{path}:{line}: rocking.lower.mass: must be > 0 kg" in res.output
        assert not (tmp_path / "o").exists()  # no empty --out left behind


@pytest.mark.parametrize("bad, message", [
    ("top_load: 58.8", "top_load: .nan"),
    ("top_friction: 0.81", "top_friction: 0.81\n  top_friction: 0.5"),
])
def test_two_body_cases_refuse_nan_and_duplicate_keys(tmp_path, bad, message):
    text = (CASES / "rocking" / "model-ii-2.8hz.yaml").read_text()
    assert bad in text
    path = _rocking_case(tmp_path, text=text.replace(bad, message, 1))
    res = _invoke("check", path)
    assert res.exit_code == 2, res.output
    assert ("finite number" in res.output) or ("duplicate key 'top_friction'" in res.output)
    assert f"{path}:" in res.output


def test_a_case_with_both_rocking_and_scene_says_so(tmp_path):
    text = (CASES / "rocking" / "model-ii-2.8hz.yaml").read_text() + \
        "scene:\n  blocks: [{size: [0.2, 0.1, 0.05], position: [0, 0, 0.025], mass: 2}]\n"
    path = _rocking_case(tmp_path, text=text)
    for cmd in (["check", path], ["run", path, "--out", tmp_path / "o"]):
        res = _invoke(*cmd)
        assert res.exit_code == 2, res.output
        assert "unknown key" not in res.output
        assert "not both" in res.output and "rocking:" in res.output and "scene:" in res.output


def test_schema_has_a_two_body_part_and_one_solver_spec_name(tmp_path):
    out = tmp_path / "r.json"
    res = _invoke("schema", "--rocking", "--out", out)
    assert res.exit_code == 0, res.output
    schema = json.loads(out.read_text())
    assert {"rocking", "loading", "run", "solver"} <= set(schema["properties"])
    assert "RockingSolverSpec" in schema["$defs"] and "SolverSpec" not in schema["$defs"]
    committed = CASES / "rocking" / "rocking.schema.json"
    assert json.loads(committed.read_text()) == schema  # the committed file is up to date


# ------------------------------------------------------------------------------------------
# defect 6: short runs analysed with a caveat; plots of the shaking only, with units
# ------------------------------------------------------------------------------------------
def test_a_two_cycle_run_is_analysed_with_a_caveat_and_plotted_over_the_shaking(tmp_path,
                                                                                 monkeypatch):
    """A brick shaken 2 cycles at 5 Hz (0.4 s), run to 0.6 s: the steady window is one cycle
    (cycle 1 is dropped), so the amplification comes with a warning; the time histories end
    with the shaking (t_end = 0.4 s), the spectrum's axes carry units."""
    import postprocess.shake_plots as sp
    from dem.case import load_case
    from dem.run import run_case
    from postprocess.shake import analyze_run

    data = {"name": "short-shake",
            "scene": {"blocks": [{"size": [0.1, 0.2, 0.3], "position": [0, 0, 0.15],
                                  "density": 2000.0}]},
            "material": {"friction": 0.6},
            "loading": {"type": "shake", "direction": [0, 1, 0], "frequency": 5.0,
                        "peak_acceleration": 1.0, "cycles": 2},
            "run": {"duration": 0.6, "output_interval": 0.002, "vtk": False,
                    "snapshot": False}}
    path = tmp_path / "short.yaml"
    path.write_text(yaml.safe_dump(data))
    out = tmp_path / "run"
    run_case(load_case(path), out)
    figs = {}
    original = sp.savefig

    def keep(fig, p, **kw):
        figs[__import__("pathlib").Path(p).name] = fig
        original(fig, p, **kw)

    monkeypatch.setattr(sp, "savefig", keep)
    monkeypatch.setattr(agg_pyplot(), "close", lambda *a: None)
    res = analyze_run(out)
    assert res["steady_state"]["n_cycles"] == 1
    assert any("steady window holds only 1 cycle" in w for w in res["warnings"])
    written = json.loads((out / "analysis.json").read_text())
    assert written["warnings"] == res["warnings"]
    t_end = 2 / 5.0
    for ax in figs["time_histories.png"].axes:
        for line in ax.lines:
            assert max(line.get_xdata()) <= t_end + 1e-9
        assert ax.get_ylabel()  # every panel says its unit
    labels = [ax.get_ylabel() for ax in figs["spectrum.png"].axes]
    assert labels and all(lab.endswith("(m)") or lab.endswith("(m/s2)") for lab in labels)


# ------------------------------------------------------------------------------------------
# defect 8: start-up (measured in the report; what is checkable without timing)
# ------------------------------------------------------------------------------------------
def test_dem_run_does_not_import_what_a_run_does_not_need():
    """scipy.stats (~ 1 CPU-s to import: dem.imperfections' truncated normal draws) is imported
    only when a scene has imperfections; matplotlib only when a plot is drawn."""
    import subprocess
    import sys

    code = ("import sys, dem_cli.commands.run, dem.validate, dem.run.build; "
            "print(sorted(m for m in ('scipy.stats', 'matplotlib.pyplot', 'dask') "
            "if m in sys.modules))")
    out = subprocess.run([sys.executable, "-c", code], capture_output=True, text=True,
                         check=True).stdout
    assert out.strip().splitlines()[-1] == "[]"


# ------------------------------------------------------------------------------------------
# defect 7: small things
# ------------------------------------------------------------------------------------------
def test_help_has_one_line_per_command_and_no_markup_leftovers():
    import os

    env = {**os.environ, "COLUMNS": "120"}
    top = CliRunner().invoke(app, ["--help"], env=env).output
    panel = top[top.index("Commands"):]
    rows = [ln for ln in panel.splitlines() if ln.startswith("│")]
    names = [r.split()[1] for r in rows if len(r.split()) > 1 and r.split()[1] != "│"]
    assert {"run", "check", "post", "rocking", "schema"} <= set(names)
    assert len(rows) == len(names)  # no continuation lines: one line per command
    for cmd in ("run", "check", "rocking"):
        text = CliRunner().invoke(app, [cmd, "--help"], env=env).output
        assert "``" not in text and "<bool>" not in text


def test_check_says_a_default_kn_is_the_default_and_warns_on_a_large_elastic_offset():
    """The 9 x 15 wall at the default kn: columns' offset 8 % (> 5 %) is a warning."""
    res = _invoke("check", CASES / "tilt" / "in-plane" / "small-9x15-s35.yaml")
    assert res.exit_code == 0, res.output
    assert "(case file)" not in res.output and "kn = 5e+09 Pa/m (default" in res.output
    warn = [ln for ln in res.output.splitlines() if ln.startswith("warning:")
            and "elastic offset" in ln]
    assert warn and "normal_stiffness" in warn[0]


def test_check_estimates_output_without_vtk_and_the_run_time(tmp_path):
    sizes = {}
    for vtk in (True, False):
        path = tmp_path / f"{vtk}.yaml"
        data = yaml.safe_load(_brick_case(tmp_path).read_text())
        data["run"]["vtk"] = vtk
        path.write_text(yaml.safe_dump(data))
        res = _invoke("check", path)
        assert res.exit_code == 0, res.output
        line = next(ln for ln in res.output.splitlines() if ln.startswith("size:"))
        sizes[vtk] = line
        assert "steps, run time about" in line
    from dem.validate import DISK_BYTES_PER_BLOCK, NPZ_BYTES_PER_BLOCK

    def output_bytes(line):
        num, unit = line.split("output about ")[1].split(",")[0].split()
        return float(num) * {"B": 1, "kB": 1e3, "MB": 1e6}[unit]

    ratio = output_bytes(sizes[True]) / output_bytes(sizes[False])
    assert ratio == pytest.approx(DISK_BYTES_PER_BLOCK / NPZ_BYTES_PER_BLOCK, rel=0.01)


@pytest.mark.parametrize("overlap, ok", [(0.8e-4, True), (2e-4, False)])
def test_an_overlap_is_not_also_reported_as_floating(tmp_path, overlap, ok):
    upper = {"size": [0.2, 0.1, 0.05], "position": [0, 0, 0.075 - overlap], "density": 2000.0}
    res = _invoke("check", _brick_case(tmp_path, extra_block=[upper]))
    assert res.exit_code == (0 if ok else 2), res.output
    assert "floating" not in res.output
    assert ("overlap by 0.200 mm" in res.output) == (not ok)


def test_an_imperfection_error_names_its_own_line_and_an_empty_file_says_empty(tmp_path):
    path = _brick_case(tmp_path)
    text = path.read_text() + "imperfections:\n  seed: 1\n  bed_unevenness: 0.02\n"
    path.write_text(text)
    line = text.splitlines().index("  bed_unevenness: 0.02") + 1
    res = _invoke("check", path)
    assert res.exit_code == 2
    assert f"{path}:{line}: imperfections.bed_unevenness:" in res.output
    empty = tmp_path / "empty.yaml"
    empty.write_text("# nothing yet\n")
    res = _invoke("check", empty)
    assert res.exit_code == 2 and "NoneType" not in res.output and "empty" in res.output


def test_ensemble_progress_lines_are_text_not_dict_reprs():
    from dem_cli.commands.ensemble import scalar_text

    text = scalar_text({"status": "ok", "lambda": 0.45123456789012345, "angle_deg": 24.28123,
                        "mechanism": "overturning", "survived": False})
    assert text == "lambda 0.4512 (24.28 deg), mechanism overturning"
    assert scalar_text({"status": "ok", "amplification_ds": 1.23456789, "survived": True}) == \
        "ds amplification 1.23, standing"


def test_taichi_start_banner_is_not_printed():
    import subprocess
    import sys

    r = subprocess.run([sys.executable, "-c", "import dem.ti_runtime as t; t.init()"],
                       capture_output=True, text=True, check=True)
    assert "Starting on arch" not in r.stdout + r.stderr


def test_an_unforeseen_exception_ends_in_one_line_and_the_mapped_exit_code():
    """What no command turned into a message still ends without a traceback (exit 1 for a
    failure, 2 for a ValueError, dem_cli.commands.exit_codes)."""
    import subprocess
    import sys

    for exc, code in (("ZeroDivisionError('boom')", 1), ("ValueError('bad')", 2)):
        src = ("import dem_cli.app as c, dem_cli.commands.post as p\n"
               f"def fail(d):\n    raise {exc}\n"
               "p.post_command = fail\nc.app(['post', '.'])\n")
        r = subprocess.run([sys.executable, "-c", src], capture_output=True, text=True)
        assert r.returncode == code, r.stderr
        assert "Traceback" not in r.stderr and len(r.stderr.strip().splitlines()) == 1


def test_a_quasi_static_tilts_progress_follows_its_table_angle(tmp_path, monkeypatch):
    """A quasi-static tilt (no rate) of a slender block (b/h = 0.25: tips below 14 deg at the
    default kn): the bar counts the table angle in degrees up to the last angle tried, not the
    relaxations' few simulated seconds (it stopped near t = 0.95 s of a 22.5 s total)."""
    import dem.run.loop as loop
    from dem.case import load_case
    from dem.run import run_case

    seen = []

    class Recorder(loop.Progress):
        def __init__(self, enabled, total, name, unit="s", label="t"):
            super().__init__(False, total, name)
            seen.append({"total": total, "unit": unit, "values": []})

        def update(self, value, rate):
            seen[-1]["values"].append(value)

    monkeypatch.setattr(loop, "Progress", Recorder)
    data = {"name": "slender", "scene": {"blocks": [
        {"size": [0.1, 0.1, 0.4], "position": [0, 0, 0.2], "density": 2000.0}]},
        "material": {"friction": 0.5},
        "loading": {"type": "tilt", "axis": "x", "max_angle": 30.0},
        "run": {"duration": 20.0, "output_interval": 0.05, "vtk": False, "snapshot": False}}
    path = tmp_path / "slender.yaml"
    path.write_text(yaml.safe_dump(data))
    res = run_case(load_case(path), tmp_path / "out", progress=True)
    bar = seen[-1]
    assert bar["unit"] == "deg" and bar["total"] == 30.0
    col = res.summary["collapse"]
    assert bar["values"] and max(bar["values"]) >= col["angle_deg"] - 1e-9
    assert max(bar["values"]) <= 30.0


def test_post_of_a_sweep_ensemble_reaggregates_it(tmp_path, monkeypatch):
    """`dem sweep --realisations` directory: each realisation's sweep re-analysed (planted
    here: post_sweep returns the sweep.json as it is), ensemble.json rebuilt from them."""
    import dem_cli.commands.post as post

    root = tmp_path / "sw"
    root.mkdir()
    amps = {"seed-1": {2.0: 1.2, 2.8: 3.0}, "seed-2": {2.0: 1.4, 2.8: 2.0}}
    for name, pts in amps.items():
        (root / name).mkdir()
        (root / name / "sweep.json").write_text(json.dumps({
            "points": [{"frequency_hz": f, "status": "ok", "amplification": {"ds": a},
                        "lag": {"ds": {"s": 0.01}}} for f, a in pts.items()],
            "failed": [], "aggregate": {"characteristic_frequency_hz": 2.8,
                                        "peak_amplification": max(pts.values()),
                                        "effective_range_hz": [2.8, 2.8]}}))
    (root / "ensemble.json").write_text(json.dumps({
        "kind": "sweep-ensemble", "case": "m2", "source": "m2.yaml", "imperfections": {},
        "realisations": [{"name": "seed-1", "seed": 1}, {"name": "seed-2", "seed": 2}]}))

    def planted(d):
        data = json.loads((d / "sweep.json").read_text())
        return data, 0

    monkeypatch.setattr(post, "post_sweep", planted)
    res = _invoke("post", root)
    assert res.exit_code == 0, res.output
    data = json.loads((root / "ensemble.json").read_text())
    assert data["amplification"]["2.8"]["median"] == pytest.approx(2.5)
    assert data["amplification"]["2"]["n"] == 2
    assert data["characteristic_frequency_hz"]["median"] == 2.8
    assert (root / "amplification_band.png").is_file()
