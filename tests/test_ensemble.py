"""Ensembles of imperfect realisations: exact statistics on planted results,
``dem ensemble`` end to end (resume, a failed realisation, bad options), ``dem sweep
--realisations``."""

from __future__ import annotations

import json
import math

import numpy as np
import pytest
import yaml
from typer.testing import CliRunner

from dem_cli.app import app
from postprocess.ensemble import aggregate, realisation_scalars, statistics


def test_statistics_of_a_planted_set_are_exact():
    """1..10: median 5.5; numpy's linear quantiles 1 + 0.1 x 9 = 1.9 and 1 + 0.9 x 9 = 9.1;
    mean 5.5; population std sqrt(mean of squares - 5.5^2) = sqrt(38.5 - 30.25)."""
    st = statistics([3, 1, 2, 10, 9, 8, 7, 6, 5, 4, float("nan"), None])
    assert st == {"n": 10, "median": 5.5, "q10": pytest.approx(1.9, abs=1e-15),
                  "q90": pytest.approx(9.1, abs=1e-15), "mean": 5.5,
                  "std": pytest.approx(math.sqrt(8.25), rel=1e-15)}
    assert statistics([])["n"] == 0 and statistics([])["median"] is None


def test_aggregate_counts_mechanisms_failures_and_survivals():
    rows = [{"status": "ok", "lambda": 0.5, "mechanism": "D", "survived": False, "seed": 0},
            {"status": "ok", "lambda": 0.7, "mechanism": "B2", "survived": False, "seed": 1},
            {"status": "ok", "lambda": 0.6, "mechanism": "D", "survived": True, "seed": 2},
            {"status": "failed", "seed": 3}, {"status": "pending", "seed": 4}]
    agg = aggregate(rows)
    assert agg["n_realisations"] == 5 and agg["n_ok"] == 3 and agg["n_failed"] == 1
    assert agg["n_pending"] == 1
    assert agg["mechanisms"] == {"B2": 1, "D": 2}
    assert agg["survived"] == 1 and agg["collapsed"] == 2
    assert agg["statistics"]["lambda"]["median"] == 0.6
    assert "seed" not in agg["statistics"]


def test_realisation_scalars_of_tilt_and_shake_records():
    tilt = {"status": "ok", "summary": {"collapse": {"detected": True, "load_factor": 0.42,
                                                     "angle_deg": 22.8},
                                        "mechanism": {"mechanism": "A"}}}
    assert realisation_scalars(tilt) == {"status": "ok", "lambda": 0.42, "angle_deg": 22.8,
                                         "mechanism": "A", "survived": False}
    shake = {"status": "ok", "summary": {},
             "post": {"analysis_status": "ok", "amplification": {"ds": 2.0, "da": None},
                      "lag": {"ds": {"s": 0.13}}, "excited": {"n_excited": 46},
                      "collapse_suspected": False}}
    assert realisation_scalars(shake) == {"status": "ok", "amplification_ds": 2.0,
                                          "lag_ds_s": 0.13, "excited_bricks": 46,
                                          "survived": True}


def stack_case(tmp_path, **imp):
    path = tmp_path / "case.yaml"
    path.write_text(yaml.safe_dump({
        "name": "stack",
        "scene": {"blocks": [{"size": [0.1, 0.1, 0.2], "position": [0, 0, 0.1],
                              "density": 2000.0}]},
        "material": {"friction": 0.8, "normal_stiffness": "rigid"},
        "loading": {"type": "tilt", "axis": "x", "method": "quasi_static", "start_angle": 20.0,
                    "quasi_static": {"max_relax_time": 0.3}},
        "run": {"duration": 20.0, "vtk": False, "snapshot": False},
        "imperfections": {"arris": 2e-3, "bed_unevenness": 2e-4, "face_shape": "planar", **imp},
    }))
    return path


def shaken_stack_case(tmp_path):
    """stack_case's block and imperfections shaken (2 Hz, 1 m/s2, 2 cycles): a case a sweep
    takes (every point is checked as a case before a sweep runs)."""
    path = stack_case(tmp_path)
    data = yaml.safe_load(path.read_text())
    data["loading"] = {"type": "shake", "direction": [0, 1, 0], "frequency": 2.0,
                       "peak_acceleration": 1.0, "cycles": 2}
    data["run"] = {"duration": 2.0, "output_interval": 0.01, "vtk": False, "snapshot": False}
    path.write_text(yaml.safe_dump(data))
    return path


@pytest.mark.slow
def test_dem_ensemble_runs_resumes_and_reports_a_failed_realisation(tmp_path):
    case = stack_case(tmp_path)
    out = tmp_path / "ens"
    out.mkdir()
    (out / "seed-6").write_text("in the way")  # the realisation of seed 6 cannot be written
    runner = CliRunner()
    res = runner.invoke(app, ["ensemble", str(case), "--out", str(out), "--realisations", "3",
                              "--seed", "5", "--workers", "2"])
    assert res.exit_code == 1, res.output
    data = json.loads((out / "ensemble.json").read_text())
    rows = {r["name"]: r for r in data["realisations"]}
    assert rows["seed-6"]["status"] == "failed" and rows["seed-6"]["error"]
    assert rows["seed-5"]["status"] == "ok" and rows["seed-7"]["status"] == "ok"
    # tipping of the 0.1 x 0.2 m block, arris 2 mm: tan = (0.1 - 0.004) / 0.2 = 0.48, lowered
    # a little by the warped bed (the block tips on its lowest corners)
    for name in ("seed-5", "seed-7"):
        assert 0.40 < rows[name]["lambda"] < 0.49
    assert rows["seed-5"]["lambda"] != rows["seed-7"]["lambda"]  # different specimens
    assert data["aggregate"]["n_failed"] == 1 and data["aggregate"]["n_ok"] == 2
    assert (out / "lambda.png").is_file()
    # a rerun keeps the two finished realisations and computes the failed one
    (out / "seed-6").unlink()
    res = runner.invoke(app, ["ensemble", str(case), "--out", str(out), "--realisations", "3",
                              "--seed", "5", "--workers", "1"])
    assert res.exit_code == 0, res.output
    data = json.loads((out / "ensemble.json").read_text())
    rows = {r["name"]: r for r in data["realisations"]}
    assert rows["seed-5"].get("reused") and rows["seed-7"].get("reused")
    assert not rows["seed-6"].get("reused") and rows["seed-6"]["status"] == "ok"
    lam = [r["lambda"] for r in data["realisations"]]
    assert data["aggregate"]["statistics"]["lambda"]["median"] == float(np.median(lam))


@pytest.mark.parametrize("args, message", [
    (["--realisations", "0"], "--realisations must be >= 1"),
    (["--realisations", "2", "--seed", "-1"], "--seed must be >= 0"),
    (["--realisations", "2", "--workers", "0"], "--workers must be >= 1"),
])
def test_bad_ensemble_options_exit_2_naming_the_option(tmp_path, args, message):
    res = CliRunner().invoke(app, ["ensemble", str(stack_case(tmp_path)), "--out",
                                   str(tmp_path / "o"), *args])
    assert res.exit_code == 2
    assert message in res.output


def test_a_smoke_run_capped_by_max_steps_is_never_taken_for_a_finished_one(tmp_path):
    """summary.json records the step cap (--max-steps) as step_limit; resuming an ensemble or a
    sweep takes a realisation or a point as finished only if it ran with the same cap, so a
    capped smoke run left in the output directory is rerun by the full study.  A run directory
    from before the field existed (no step_limit) counts as uncapped."""
    from dem.case import load_case
    from dem_cli.commands.ensemble import finished_realisation
    from dem_cli.commands.sweep import finished_point
    from dem.engine import RESULTS_REVISION

    case = load_case(stack_case(tmp_path))
    run = tmp_path / "seed-0"
    run.mkdir()
    (run / "case.json").write_text(case.model_dump_json())
    (run / "analysis.json").write_text("{}")
    summary = {"status": "ok", "steps": 50, "step_limit": 50, "results_revision": RESULTS_REVISION}
    (run / "summary.json").write_text(json.dumps(summary))
    assert finished_realisation(case, run, shake=False) is None
    assert finished_realisation(case, run, shake=False, max_steps=50) is not None
    assert finished_point(case, run) is None
    assert finished_point(case, run, max_steps=50) is not None
    del summary["step_limit"]
    (run / "summary.json").write_text(json.dumps(summary))
    assert finished_realisation(case, run, shake=False) is not None
    assert finished_point(case, run) is not None


def test_a_run_of_an_engine_whose_results_moved_is_not_resumed(tmp_path):
    """summary.json records dem.engine.RESULTS_REVISION; a realisation or a point finished by an
    engine of another revision (or before the field existed) is run again, not mixed in."""
    from dem.case import load_case
    from dem_cli.commands.ensemble import finished_realisation
    from dem_cli.commands.sweep import finished_point
    from dem.engine import RESULTS_REVISION

    case = load_case(stack_case(tmp_path))
    run = tmp_path / "seed-0"
    run.mkdir()
    (run / "case.json").write_text(case.model_dump_json())
    (run / "analysis.json").write_text("{}")
    for rev, reused in [(RESULTS_REVISION, True), (RESULTS_REVISION - 1, False), (None, False)]:
        summary = {"status": "ok", "steps": 50, "step_limit": None}
        if rev is not None:
            summary["results_revision"] = rev
        (run / "summary.json").write_text(json.dumps(summary))
        assert (finished_realisation(case, run, shake=False) is not None) is reused
        assert (finished_point(case, run) is not None) is reused


def test_a_signal_stops_dem_sweep_realisations_instead_of_starting_the_next(tmp_path,
                                                                            monkeypatch):
    """A SIGTERM that stops one realisation's sweep must not let ``dem sweep --realisations``
    go on to the next (a study's stop would not stop it): the interrupt ends the loop, exit 1,
    and no ensemble statistics are written from a partial set."""
    from dem_cli.commands import sweep as cmd
    from dem_cli.commands.exit_codes import ExitCode
    from dem.signals import Interrupted

    calls = []

    def fake_run_sweep(case_path, out, *args, case=None, reraise_interrupt=False, **kw):
        calls.append((out.name, reraise_interrupt))
        if len(calls) == 2:                     # the signal arrives in the second realisation
            if reraise_interrupt:
                raise Interrupted("SIGTERM")
            return ExitCode.RUN_FAILED
        return ExitCode.OK

    monkeypatch.setattr(cmd, "run_sweep", fake_run_sweep)
    code = cmd.run_sweep_realisations(shaken_stack_case(tmp_path), tmp_path / "sw", "2,3", None,
                                      5.0, 1.0, None, 1, None, 4, 0)
    assert code == ExitCode.RUN_FAILED
    assert calls == [("seed-0", True), ("seed-1", True)]    # seed-2, seed-3 never started
    assert not (tmp_path / "sw" / "ensemble.json").exists()
