"""studies/kit (what every study shares) and the one entry point ``python -m studies``."""

from __future__ import annotations

import importlib
import json
import re
import subprocess
import sys
import time

import pytest
import typer.main
from typer.testing import CliRunner

from studies.__main__ import STUDIES, app
from studies.kit import child, session
from studies.kit.cli import spread_lists
from studies.kit.provenance import ROOT
from studies.kit.records import merge_json, read_json


def test_command_echo_leaves_defaults_out_and_spreads_lists():
    assert session.command("resonance", seeds=(3, 3), cycles=(20.0, 20.0)) == \
        "python -m studies resonance"
    assert session.command("qs-validation", out="results/x", candidate=("c", "perfect"),
                           rates=([2.0, 1.0, 0.25], [2.0, 1.0, 0.5]), max_steps=None,
                           specimens=None) == \
        "python -m studies qs-validation --out results/x --candidate c --rates 2 1 0.25"


def test_the_cpu_ledger_adds_up_over_sessions_and_keys(tmp_path):
    path = tmp_path / "cpu.json"
    session.add_cpu(path, "a", 1.5)
    session.add_cpu(path, "b", 2.0)
    assert session.add_cpu(path, "a", 0.25) == {"a": 1.75, "b": 2.0}
    assert json.loads(path.read_text()) == {"a": 1.75, "b": 2.0}
    assert read_json(tmp_path / "missing.json") is None


def test_merge_json_under_the_lock_keeps_both_writers(tmp_path):
    """Two processes adding to one record at once (the prediction's --seeds split) lose
    nothing: each read-change-write holds the lock."""
    path = tmp_path / "points.json"
    code = ("import sys, time; from studies.kit.records import merge_json\n"
            "def add(d, k=sys.argv[1]):\n"
            "    v = d.get(k, 0); time.sleep(0.01); d[k] = v + 1\n"
            f"for _ in range(20): merge_json({str(path)!r}, add)\n")
    procs = [subprocess.Popen([sys.executable, "-c", code, key], cwd=ROOT)
             for key in ("x", "x")]
    assert all(p.wait(timeout=120) == 0 for p in procs)
    assert read_json(path) == {"x": 40}
    assert merge_json(path, lambda d: {"y": 1}) == {"y": 1}      # a returned dict replaces


def test_should_stop_on_a_drain_file_or_at_the_stop_time(tmp_path, monkeypatch):
    monkeypatch.setattr(child, "_STOP", [False])
    drain = tmp_path / "DRAIN"
    assert not session.should_stop(drain)
    drain.touch()
    assert session.should_stop(drain)
    past = time.strftime("%H:%M", time.gmtime(time.time() - 120))
    said = []
    assert session.should_stop(stop_at=past, log=said.append) and said
    assert child.stopped()            # the stop time requests the stop: later checks agree


def test_a_stop_time_past_midnight_lies_ahead():
    """--stop-at 00:05 given at 23:49 UTC is 16 minutes ahead, not passed; 23:45 given at 23:49
    has passed; the nearest occurrence within 12 hours either way counts."""
    day = 86400.0 * 20000  # a UTC midnight
    at_2349 = day + 23 * 3600.0 + 49 * 60.0
    assert session.stop_deadline("00:05", now=at_2349) == day + 86400.0 + 5 * 60.0
    assert session.stop_deadline("23:45", now=at_2349) == day + 23 * 3600.0 + 45 * 60.0
    assert session.stop_deadline("11:00", now=day + 600.0) == day + 11 * 3600.0
    with pytest.raises(ValueError, match="HH:MM"):
        session.stop_deadline("25:00", now=day)


def test_one_entry_point_lists_every_study_and_hands_over_the_arguments():
    runner = CliRunner()
    res = runner.invoke(app, ["--help"])
    assert res.exit_code == 0
    for name in STUDIES:
        assert name in res.output
    # the study's own parser gets what follows its name: a missing frozen set exits 2
    res = runner.invoke(app, ["prediction", "--frozen", str(ROOT / "no-such.yaml"), "--report"])
    assert res.exit_code == 2
    for module, _ in STUDIES.values():      # every subcommand's module has main(argv)
        mod = __import__(module, fromlist=["main"])
        assert callable(mod.main)


@pytest.mark.parametrize("name", sorted(STUDIES))
def test_every_study_command_answers_help_through_the_entry_point(name):
    """``python -m studies NAME --help``: exit 0, the study's own usage line and the first words
    of its command's help (the study's docstring: Typer's, not a second parser's)."""
    res = CliRunner().invoke(app, [name, "--help"])
    assert res.exit_code == 0, res.output
    text = " ".join(res.output.split())
    assert f"Usage: python -m studies {name}" in text
    mod = importlib.import_module(STUDIES[name][0])
    first = " ".join(typer.main.get_command(mod.app).help.split()[:6])
    assert first.replace("\\[", "[") in text


def test_no_study_parses_its_options_with_argparse():
    """One command-line dialect: every study's options are a Typer command."""
    offenders = [str(p.relative_to(ROOT)) for p in (ROOT / "studies").rglob("*.py")
                 if re.search(r"^\s*(import argparse|from argparse)", p.read_text(), re.M)]
    assert offenders == []


def test_list_options_take_several_values_and_bad_options_exit_2(tmp_path, capsys):
    """``--rates 2 1 0.25`` (argparse's nargs spelling) reaches Typer as a repeated option; an
    unknown option or a refused value exits 2 with the reason on stderr, and nothing runs."""
    assert spread_lists(["--rates", "2", "1", "--out", "x", "--specimens", "a"],
                        ("--rates", "--specimens")) == \
        ["--rates", "2", "--rates", "1", "--out", "x", "--specimens", "a"]
    assert spread_lists(["--rates=2", "--rates"], ("--rates",)) == ["--rates=2", "--rates"]
    from studies.qs_validation import study as qv

    out = tmp_path / "v"
    assert qv.main(["--out", str(out), "--rates", "2", "-1", "0.5"]) == 2
    assert "--rates" in capsys.readouterr().err
    assert qv.main(["--out", str(out), "--no-such-option"]) == 2
    assert "--no-such-option" in capsys.readouterr().err
    assert not out.exists()


def test_help_shows_bracketed_text_of_a_docstring():
    """A docstring's ``[m, m, m]`` is text, not Rich markup (studies.kit.cli.text)."""
    res = CliRunner().invoke(app, ["prediction", "--help"])
    assert res.exit_code == 0 and "[m, m, m]" in res.output


# ---- a study's shape (studies.kit.study) --------------------------------------------------------
def _block_case(friction=0.5):
    from dem.case import parse_case

    return parse_case({"name": "b", "scene": {"blocks": [{"size": [0.2, 0.2, 0.1],
                                                          "position": [0.0, 0.0, 0.05],
                                                          "mass": 4.0}]},
                       "material": {"friction": friction}, "run": {"duration": 0.1}})


def test_the_fingerprint_hashes_the_case_identity_then_the_plan_in_its_form():
    """The two forms the committed records were written with, from their definitions: sha256
    of the case's identity, then ``json.dumps([*plan, revision])`` or ``|a|b|revision``."""
    import hashlib

    from dem.case.identity import identity_json
    from dem.engine import RESULTS_REVISION
    from studies.kit import study as kit

    case = _block_case()

    def digest(tail: str) -> str:
        h = hashlib.sha256(identity_json(case).encode())
        h.update(tail.encode())
        return h.hexdigest()[:16]
    assert kit.fingerprint(case, [2.8, 3.2], [0, 1], 10) == \
        digest(json.dumps([[2.8, 3.2], [0, 1], 10, RESULTS_REVISION]))
    assert kit.fingerprint(case, 20, None, form="bars") == digest(f"|20|None|{RESULTS_REVISION}")
    assert kit.fingerprint(case) == digest(json.dumps([RESULTS_REVISION]))
    # another case, another plan part, or cycles written 10.0 rather than 10: another point
    assert kit.fingerprint(_block_case(0.6), [2.8], [0], 10) != kit.fingerprint(case, [2.8],
                                                                                 [0], 10)
    assert kit.fingerprint(case, [2.8], [0], 10.0) != kit.fingerprint(case, [2.8], [0], 10)
    with pytest.raises(ValueError, match="form"):
        kit.fingerprint(case, form="yaml")


def test_the_paths_are_this_checkouts():
    from studies.kit import study as kit

    assert kit.ROOT == ROOT and (ROOT / "studies" / "kit" / "study.py").is_file()
    assert kit.results_dir("diagnosis", "e4") == ROOT / "results" / "diagnosis" / "e4"
    assert kit.runs_dir("x") == ROOT / "runs" / "x"


def test_the_loop_skips_finished_points_stops_on_the_drain_file_and_keeps_the_ledger(tmp_path,
                                                                                       monkeypatch):
    """A point whose ``todo`` is empty is skipped without a child; each run's CPU seconds go to
    ``<out>/cpu.json`` under its ledger key and its records are written after it with the
    child's result; the drain file ends the session before the next point."""
    from studies.kit import study as kit

    calls, recorded = [], []
    monkeypatch.setattr(child, "run_dem",
                        lambda args, log: (calls.append(args), (0, 1.5, 2.0))[1])

    class Toy(kit.Study):
        runs = tmp_path / "runs"

        def points(self):
            for i in range(4):
                yield kit.Point(name=f"p{i}", case=_block_case(0.5 + 0.1 * i), plan=(i,),
                                out=tmp_path / "out", runs=self.runs, ledger="toy", seed=i)

        def todo(self, p):
            return None if p.seed == 0 else ["go"]

        def command(self, p, todo, drain):
            if p.seed == 2:
                (self.runs / "DRAIN").write_text("")
            return ["run", str(p.case_file), "--out", str(p.run_dir)]

        def record(self, p, result, log=print):
            recorded.append((p.name, result))
            return "finished"

    states = kit.run(Toy(), log=lambda *_: None)
    assert [(p.name, s) for p, s in states] == [("p0", "skipped"), ("p1", "finished"),
                                                ("p2", "finished")]
    assert [c[2] for c in calls] == ["--out", "--out"] and recorded == [("p1", (0, 1.5, 2.0)),
                                                                ("p2", (0, 1.5, 2.0))]
    assert [c[1] for c in calls] == [str(tmp_path / "runs" / "p1.yaml"),
                                     str(tmp_path / "runs" / "p2.yaml")]
    assert not (tmp_path / "runs" / "p0.yaml").exists()    # nothing to do: no case written
    assert not (tmp_path / "runs" / "p3.yaml").exists()
    assert read_json(tmp_path / "out" / "cpu.json") == {"toy": 3.0}
