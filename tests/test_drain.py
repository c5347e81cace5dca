"""Draining a long batch (dem.batch, "Draining"): once the drain check says stop, no new run
starts, the runs in flight finish and are kept, and the caller learns which never started.  A
signal stops at once and loses what the runs in flight did since their last checkpoint (they
resume from it: tests/test_resume.py); draining is how a session ends a multi-hour study without
throwing away any of it."""

from __future__ import annotations

import json

import pytest
from typer.testing import CliRunner

from dem.batch import Drained, run_batch
from dem.case import load_case
from dem_cli.app import app
from dem_cli.commands.exit_codes import ExitCode
from dem.run.sweep import realisation_cases
from tests.test_ensemble import shaken_stack_case, stack_case
from tests.test_shake_analysis import BLOCK, case_file, sequential_batch


def test_a_drained_batch_finishes_the_runs_in_flight_and_starts_no_new_one(tmp_path):
    """Two workers, four cases: both first cases are in flight when the first one lands and the
    drain check turns true; the second still finishes and is reported, the last two never start
    (no output directory)."""
    cases = realisation_cases(load_case(stack_case(tmp_path)), 4, 0)
    seen = []
    with pytest.raises(Drained) as info:
        run_batch(cases, tmp_path / "runs", n_workers=2, max_steps=50,
                  on_done=lambda rec: seen.append(rec), drain=lambda: len(seen) >= 1)
    assert sorted(r["name"] for r in seen) == ["seed-0", "seed-1"]
    assert all(r["status"] == "ok" for r in seen)
    assert info.value.not_started == ["seed-2", "seed-3"]
    assert not (tmp_path / "runs" / "seed-2").exists()
    assert not (tmp_path / "runs" / "seed-3").exists()


def test_dem_sweep_drained_keeps_the_finished_point_exits_1_and_a_rerun_resumes(tmp_path,
                                                                               monkeypatch):
    import dem.batch

    calls = []
    # the user drains after the first point
    monkeypatch.setattr(dem.batch, "run_batch",
                        sequential_batch(lambda root: (root / "DRAIN").touch(), calls))
    case = case_file(tmp_path, BLOCK)
    out = tmp_path / "sweep"
    out.mkdir()
    (out / "DRAIN").touch()                     # left by an earlier drain: removed at the start
    args = ["sweep", str(case), "--out", str(out), "--frequencies", "2,3", "--cycles", "3",
            "--margin", "0.1"]
    r = CliRunner().invoke(app, args)
    assert r.exit_code == ExitCode.RUN_FAILED, r.output
    assert "left by an earlier drain" in r.output
    assert "drained" in r.output and "1 not started: 3 Hz" in r.output
    pts = {p["frequency_hz"]: p["status"] for p in
           json.loads((out / "sweep.json").read_text())["points"]}
    assert pts == {2.0: "ok", 3.0: "pending"}
    assert calls[0] is not None                 # the CLI drains on OUT/DRAIN by default
    r = CliRunner().invoke(app, args)           # the rerun clears DRAIN, keeps 2 Hz, runs 3 Hz
    assert r.exit_code == ExitCode.OK, r.output
    assert "already finished" in r.output
    pts = {p["frequency_hz"]: p["status"] for p in
           json.loads((out / "sweep.json").read_text())["points"]}
    assert pts == {2.0: "ok", 3.0: "ok"}


def test_a_drain_ends_the_loop_over_realisations(tmp_path, monkeypatch):
    from dem_cli.commands import sweep as cmd

    calls = []

    def fake_run_sweep(case_path, out, *args, case=None, reraise_interrupt=False,
                       drain_file=None, **kw):
        calls.append((out.name, drain_file))
        if len(calls) == 2:
            raise Drained(["f3.000Hz"])
        return ExitCode.OK

    monkeypatch.setattr(cmd, "run_sweep", fake_run_sweep)
    drain = tmp_path / "sw" / "DRAIN"
    code = cmd.run_sweep_realisations(shaken_stack_case(tmp_path), tmp_path / "sw", "2,3", None,
                                      5.0, 1.0, None, 1, None, 4, 0, drain)
    assert code == ExitCode.RUN_FAILED
    assert calls == [("seed-0", drain), ("seed-1", drain)]   # seed-2, seed-3 never started
    assert not (tmp_path / "sw" / "ensemble.json").exists()
