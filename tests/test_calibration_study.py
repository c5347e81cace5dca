"""The Chapter 3 calibration study (studies/calibration/): the cases it
builds (the candidate's imperfections on the quasi-static specimen, friction untouched), a smoke
point end to end and its resume (a finished point starts nothing; an unfinished one reruns only
its unfinished realisations), and the scoring on hand-made ensembles with known answers."""

from __future__ import annotations

import json

import pytest
import yaml

import dem.engine as engine
from dem.case import load_case
from studies.calibration import cli as cal_cli
from studies.calibration import points as cal_points
from studies.calibration import report as cal_report
from studies.calibration import scoring as cal_scoring
from studies.calibration import select as cal_select
from studies.calibration import specimens as cal_specimens
from studies.kit import child as dem_child

CAND = {"bed_unevenness": 1.0e-4, "face_shape": "planar", "size_scatter": [3e-4, 2e-4, 1e-4],
        "arris": 5e-4}


# ---- case construction ---------------------------------------------------------------------------
def test_specimens_are_the_small_brick_tilt_walls_cheapest_first():
    specs = cal_specimens.specimens()
    assert specs and all("small" in n for n in specs)
    assert not any("large" in n for n in specs)  # held out
    assert {"ip-small-5x5", "ip-small-5x25", "oop-small-5x15-strong-strong"} <= set(specs)
    assert specs["ip-small-5x5"]["l_over_h"] == 3.0  # 5 x 105 / (5 x 35)
    assert specs["ip-small-5x7"]["l_over_h"] == 2.14
    assert specs["ip-small-5x25"]["l_over_h"] == 0.6
    order = list(specs)  # the L = 5 series (the invariants) first, each group cheapest first
    assert order[:5] == ["ip-small-5x5", "ip-small-5x7", "ip-small-5x15", "ip-small-5x20",
                         "ip-small-5x25"]
    assert order[-1] == "oop-small-10x21-strong-strong"


@pytest.mark.parametrize("specimen", ["ip-small-5x5", "oop-small-5x15-strong-strong"])
def test_specimen_case_applies_the_candidate_and_leaves_friction_alone(specimen):
    spec = cal_specimens.specimens()[specimen]
    base = load_case(spec["path"])
    case = cal_specimens.specimen_case(spec["path"], CAND, "x")
    imp = case.imperfections
    assert (imp.bed_unevenness, imp.face_shape, imp.size_scatter, imp.arris) == \
        (1.0e-4, "planar", [3e-4, 2e-4, 1e-4], 5e-4)
    assert case.material == base.material  # friction and joint stiffness are not parameters
    assert case.material.friction == 0.81
    assert base.loading.method == "constant_rate" and base.loading.rate == 2.0
    assert case.loading.method == "quasi_static" and case.loading.rate is None
    assert case.loading.axis == base.loading.axis and case.loading.max_angle == \
        base.loading.max_angle
    assert case.scene == base.scene
    assert case.run.vtk is False


def test_candidates_file_and_the_perfect_reference():
    cands = cal_specimens.load_candidates()
    assert list(cands)[:2] == ["perfect", "bed-0.1-planar"]
    assert cal_select.is_perfect(cands["perfect"]) and cal_specimens.realisations_for(cands["perfect"], 20) == 1
    assert not cal_select.is_perfect(cands["bed-0.1-planar"])
    assert cal_specimens.realisations_for(cands["bed-0.1-planar"], 20) == 20
    for name, params in cands.items():  # every candidate makes a valid case
        cal_specimens.specimen_case(cal_specimens.specimens()["ip-small-5x5"]["path"], params, name)


def test_a_candidate_may_not_tune_friction(tmp_path):
    f = tmp_path / "c.yaml"
    f.write_text(yaml.safe_dump({"cheat": {"bed_unevenness": 1e-4, "friction": 0.6}}))
    with pytest.raises(ValueError, match="friction"):
        cal_specimens.load_candidates(f)


# ---- a smoke point and its resume --------------------------------------------------------------
@pytest.mark.slow  # ~3 min of dem ensemble children (among the suite's slowest); the
# default run keeps the calibration's end-to-end child run in test_held_out_smoke_run_...
def test_smoke_point_runs_then_resumes_without_rerunning(tmp_path, monkeypatch):
    cfile = tmp_path / "candidates.yaml"
    cfile.write_text(yaml.safe_dump({"smoke": CAND}))
    out = tmp_path / "cal"
    argv = ["--out", str(out), "--candidates-file", str(cfile), "--specimens", "ip-small-5x5",
            "--realisations", "2", "--max-steps", "300"]
    assert cal_cli.main(argv) == 0
    point = out / "smoke" / "ip-small-5x5" / "ensemble.json"
    data = json.loads(point.read_text())
    cal = data["calibration"]
    assert cal["finished"] and cal["seeds"] == [0, 1] and cal["max_steps"] == 300
    assert cal["friction"] == 0.81 and cal["parameters"] == CAND
    assert cal["cpu_seconds"] > 0
    assert [r["status"] for r in data["realisations"]] == ["ok", "ok"]
    assert data["imperfections"]["bed_unevenness"] == 1e-4
    runs = out / "runs" / "smoke" / "ip-small-5x5"
    assert (runs / "seed-1" / "summary.json").is_file()
    assert not list(point.parent.glob("*.npz"))  # the committed side holds no frames
    summary = json.loads((out / "summary.json").read_text())
    assert summary["points"]["smoke"]["ip-small-5x5"]["smoke"] is True
    assert "pending" in (out / "README.md").read_text()  # the other specimens

    # a rerun of a finished point starts nothing and writes nothing
    launches = []

    def no_launch(*a, **k):
        launches.append(a)
        raise AssertionError("a finished point was run again")

    mtime = point.stat().st_mtime_ns
    seed_mtime = (runs / "seed-0" / "summary.json").stat().st_mtime_ns
    monkeypatch.setattr(dem_child.subprocess, "Popen", no_launch)
    assert cal_cli.main(argv) == 0
    assert launches == [] and point.stat().st_mtime_ns == mtime
    monkeypatch.undo()

    # an unfinished point is handed back to dem ensemble, which keeps its finished realisations
    data["calibration"]["finished"] = False
    point.write_text(json.dumps(data))
    assert cal_cli.main(argv) == 0
    again = json.loads(point.read_text())
    assert again["calibration"]["finished"] and again["calibration"]["sessions"] == 2
    assert all(r.get("reused") for r in again["realisations"])
    assert (runs / "seed-0" / "summary.json").stat().st_mtime_ns == seed_mtime


# ---- scoring on hand-made ensembles --------------------------------------------------------------
def _ensemble(lams, mechs, otf=None, kind="in-plane", lh=3.0, n=None, friction=0.81):
    """An ensemble.json as run_point writes it, with the given per-realisation results."""
    n = len(lams) if n is None else n
    rows = [{"name": f"seed-{i}", "seed": i, "status": "ok", "lambda": lam, "mechanism": m}
            for i, (lam, m) in enumerate(zip(lams, mechs))]
    from postprocess.ensemble import aggregate

    extras = {f"seed-{i}": {"overturning_mass_fraction": f, "engine_seconds": 10.0}
              for i, f in enumerate(otf or [0.0] * len(lams))}
    return {"realisations": rows, "aggregate": {**aggregate(rows), "n_realisations": n},
            "calibration": {"n_realisations": n, "finished": len(lams) == n, "kind": kind,
                            "l_over_h": lh, "friction": friction, "cpu_seconds": 12.0 * n,
                            "max_steps": None, "extras": extras}}


def _pt(*a, **k):
    return cal_scoring.point_summary(_ensemble(*a, **k))


def test_point_summary_median_band_and_pending():
    p = _pt([0.80, 0.81, 0.82, 0.79, 0.83], ["sliding"] * 4 + ["mixed"])
    assert p["status"] == "finished" and p["lambda_median"] == pytest.approx(0.81)
    assert p["lambda_q10"] == pytest.approx(0.794) and p["lambda_q90"] == pytest.approx(0.826)
    assert p["modal_mechanism"] == "sliding" and p["mechanisms"] == {"mixed": 1, "sliding": 4}
    pending = _pt([0.80, 0.81], ["sliding"] * 2, n=20)
    assert pending["status"] == "pending" and "lambda_median" not in pending
    assert cal_scoring.point_summary(None)["status"] == "pending"


def test_sliding_invariant_passes_within_3_percent_and_fails_outside():
    ok = {"ip-small-5x5": _pt([0.83, 0.82, 0.83], ["sliding"] * 3)}  # +2.1 %
    assert cal_scoring.check_sliding(ok)["status"] == "pass"
    low = {"ip-small-5x5": _pt([0.77, 0.78, 0.78], ["sliding"] * 3)}  # -3.7 %
    res = cal_scoring.check_sliding(low)
    assert res["status"] == "fail" and res["relative_error"] == pytest.approx(0.78 / 0.81 - 1)
    tipping = {"ip-small-5x5": _pt([0.81] * 3, ["mixed"] * 3)}  # right lambda, wrong mechanism
    assert cal_scoring.check_sliding(tipping)["status"] == "fail"
    assert cal_scoring.check_sliding({"ip-small-5x5": _pt([0.81], ["sliding"], n=20)})["status"] == \
        "pending"


def _series(mechs, otfs):
    lhs = {"ip-small-5x5": 3.0, "ip-small-5x7": 2.14, "ip-small-5x15": 1.0,
           "ip-small-5x20": 0.75, "ip-small-5x25": 0.6}
    return {n: _pt([0.6] * 3, [m] * 3, [f] * 3, lh=lh)
            for (n, lh), m, f in zip(lhs.items(), mechs, otfs)}


def test_mechanism_sequence_kept_or_broken():
    good = _series(["sliding", "mixed", "mixed", "overturning", "overturning"],
                   [0.0, 0.3, 0.6, 0.9, 0.94])
    assert cal_scoring.check_sequence(good)["status"] == "pass"
    assert cal_scoring.check_in_plane_mechanisms(good)["status"] == "pass"
    # L/H = 0.75 mixed after L/H = 1 overturning: the sequence is broken
    bad = _series(["sliding", "mixed", "overturning", "mixed", "overturning"],
                  [0.0, 0.3, 0.9, 0.6, 0.94])
    res = cal_scoring.check_sequence(bad)
    assert res["status"] == "fail" and any("0.75" in p for p in res["problems"])
    # the L/H = 3 wall tipping is a broken sequence even if the order is monotone
    tip = _series(["mixed"] * 3 + ["overturning"] * 2, [0.3, 0.3, 0.6, 0.9, 0.94])
    assert cal_scoring.check_sequence(tip)["status"] == "fail"
    unfinished = dict(good, **{"ip-small-5x20": _pt([0.5], ["mixed"], lh=0.75, n=20)})
    assert cal_scoring.check_sequence(unfinished)["status"] == "pending"


def test_no_wings_and_stagger_checks():
    oop = {"oop-small-5x15-strong-strong": _pt([0.4] * 3, ["B2"] * 3, kind="out-of-plane")}
    assert cal_scoring.check_no_wings_lowest(oop)["status"] == "n/a"
    high = dict(oop, **{"oop-small-5x15-no-wings": _pt([0.45] * 3, ["A"] * 3,
                                                       kind="out-of-plane")})
    assert cal_scoring.check_no_wings_lowest(high)["status"] == "fail"
    low = dict(oop, **{"oop-small-5x15-no-wings": _pt([0.2] * 3, ["A"] * 3,
                                                      kind="out-of-plane")})
    assert cal_scoring.check_no_wings_lowest(low)["status"] == "pass"
    assert cal_scoring.check_oop_mechanisms(oop)["status"] == "pass"
    wrong = {"oop-small-5x15-strong-strong": _pt([0.4] * 3, ["A"] * 3, kind="out-of-plane")}
    assert cal_scoring.check_oop_mechanisms(wrong)["status"] == "fail"
    rising = {f"ip-small-9x15-s{s}": _pt([lam] * 3, ["mixed"] * 3, lh=1.8)
              for s, lam in (("10", 0.53), ("35", 0.57), ("52.5", 0.63))}
    assert cal_scoring.check_stagger_trend(rising)["status"] == "pass"
    falling = dict(rising, **{"ip-small-9x15-s52.5": _pt([0.55] * 3, ["mixed"] * 3, lh=1.8)})
    assert cal_scoring.check_stagger_trend(falling)["status"] == "fail"


def test_score_candidate_fails_on_one_broken_invariant_and_waits_on_a_pending_one():
    pts = _series(["sliding", "mixed", "mixed", "overturning", "overturning"],
                  [0.0, 0.3, 0.6, 0.9, 0.94])
    pts["ip-small-5x5"] = _pt([0.81] * 3, ["sliding"] * 3)
    assert cal_scoring.score_candidate(pts)["invariants_pass"] is True
    pts["ip-small-5x5"] = _pt([0.70] * 3, ["sliding"] * 3)  # slides 14 % below mu
    assert cal_scoring.score_candidate(pts)["invariants_pass"] is False
    pts["ip-small-5x5"] = _pt([0.81], ["sliding"], n=20)
    assert cal_scoring.score_candidate(pts)["invariants_pass"] is None
    fam = {r["l_over_h"]: r for r in cal_scoring.score_candidate(pts)["famive"]}
    assert fam[3.0]["status"] == "pending"
    assert fam[1.0]["famive"] == 0.65 and fam[1.0]["median"] == pytest.approx(0.6)


def test_grid_estimate_scales_the_perfect_cpu_by_the_measured_ratio():
    def point(cpu, n):
        return {"status": "finished", "cpu_seconds": cpu, "n_realisations": n}

    cands = {"perfect": {}, "bed": {"bed_unevenness": 1e-4}}
    specs = {"a": {}, "b": {}}
    pts = {"perfect": {"a": point(10.0, 1), "b": point(30.0, 1)},
           "bed": {"a": point(400.0, 20), "b": {"status": "pending"}}}
    est = cal_report.estimate(pts, specs, cands, 20)
    assert est["imperfect_over_perfect"] == pytest.approx(2.0)  # 20 s against 10 s
    assert est["cpu_seconds_per_realisation"] == pytest.approx({"a": 20.0, "b": 60.0})
    assert est["how"]["b"].startswith("perfect x 2.00")
    # 20 realisations of each specimen for "bed", one perfect run each
    assert est["grid_cpu_seconds"] == pytest.approx(20 * 20 + 20 * 60 + 10 + 30)
    assert est["finished_cpu_seconds"] == pytest.approx(10 + 30 + 400)


def test_a_collapse_of_one_block_alone_is_flagged():
    data = _ensemble([0.80, 0.034, 0.79], ["mixed", "sliding", "mixed"], lh=2.14)
    data["calibration"]["extras"]["seed-1"]["n_moving"] = 1
    data["calibration"]["extras"]["seed-0"]["n_moving"] = 18
    p = cal_scoring.point_summary(data)
    assert p["lone_block"] == [["seed-1", 0.034]]
    assert p["lambda_median"] == pytest.approx(0.79)  # still counted


def test_a_point_from_an_older_engine_is_not_reused(monkeypatch):
    """The resume fingerprint includes dem.engine.RESULTS_REVISION: after a change that moves
    results (e.g. the planar-warp path fix) a finished point is run again, not mixed in."""
    spec = cal_specimens.specimens()["ip-small-5x5"]
    case = cal_specimens.specimen_case(spec["path"], CAND, "x")
    now = cal_specimens.fingerprint(case, 20, None)
    assert cal_specimens.fingerprint(case, 20, None) == now
    monkeypatch.setattr(engine, "RESULTS_REVISION", engine.RESULTS_REVISION - 1)
    assert cal_specimens.fingerprint(case, 20, None) != now


def test_a_committed_point_of_an_older_engine_is_reported_pending_not_shown(tmp_path,
                                                                            monkeypatch):
    """After a RESULTS_REVISION bump the committed points stay on disk until rerun; the report
    must not show their numbers as this engine's: such a point is pending and ``stale``."""
    spec = cal_specimens.specimens()["ip-small-5x5"]
    specs = {"ip-small-5x5": spec}
    case = cal_specimens.specimen_case(spec["path"], CAND, "cal-c-ip-small-5x5")
    data = _ensemble([0.80] * 20, ["sliding"] * 20)
    data["calibration"]["fingerprint"] = cal_specimens.fingerprint(case, 20, None)
    dest = cal_points.point_path(tmp_path, "c", "ip-small-5x5")
    dest.parent.mkdir(parents=True)
    dest.write_text(json.dumps(data))
    now = cal_report.collect(tmp_path, {"c": CAND}, specs, 20)["c"]["ip-small-5x5"]
    assert now["status"] == "finished" and now["lambda_median"] == pytest.approx(0.80)
    monkeypatch.setattr(engine, "RESULTS_REVISION", engine.RESULTS_REVISION + 1)
    later = cal_report.collect(tmp_path, {"c": CAND}, specs, 20)["c"]["ip-small-5x5"]
    assert later["status"] == "pending" and later["stale"] and "lambda_median" not in later


# ---- the held-out large-brick walls --------------------------------------------------------------
def test_held_out_walls_are_the_three_large_brick_l_over_h_2_5_walls():
    held = cal_specimens.held_out_specimens()
    assert {s: v["thesis_lambda"] for s, v in held.items()} == {
        "ip-large-stretcher-flat-5x6": 0.48, "ip-large-english-5x6": 0.45,
        "ip-large-stretcher-on-edge-5x4": 0.36}
    assert all(v["path"].is_file() and v["l_over_h"] == 2.5 for v in held.values())
    assert not set(held) & set(cal_specimens.specimens())  # never among the calibration specimens


def test_held_out_refused_before_the_freeze(tmp_path, capsys):
    """No committed frozen set: exit 2 naming the file, nothing run or written."""
    out = tmp_path / "cal"
    assert cal_cli.main(["--out", str(out), "--held-out", "--frozen",
                         str(tmp_path / "frozen.yaml")]) == 2
    assert "frozen.yaml" in capsys.readouterr().err
    assert not out.exists()


def test_held_out_summary_band_and_difference(tmp_path):
    """A finished held-out point: median vs the thesis lambda and whether the thesis value lies
    in the 10-90 % band; the others pending, shown without numbers."""
    data = _ensemble([0.50, 0.52, 0.54, 0.56, 0.58], ["sliding"] * 5, lh=2.53)
    data["calibration"]["frozen"] = {"file": "studies/calibration/frozen.yaml", "commit": "abc"}
    dest = cal_points.point_path(tmp_path, cal_specimens.HELD_OUT_DIR, "ip-large-stretcher-flat-5x6")
    dest.parent.mkdir(parents=True)
    dest.write_text(json.dumps(data))
    held = cal_report.held_out_summary(tmp_path)
    p = held["ip-large-stretcher-flat-5x6"]
    assert p["relative_difference"] == pytest.approx(0.54 / 0.48 - 1)
    assert p["thesis_in_band"] is False  # 0.48 below the band's 10 % point
    assert p["frozen"]["commit"] == "abc"
    assert held["ip-large-english-5x6"]["status"] == "pending"
    assert "relative_difference" not in held["ip-large-english-5x6"]
    text = "\n".join(cal_report.held_out_lines(held))
    assert ("| ip-large-stretcher-flat-5x6 | 2.50 | 0.48 | 5/5 | 0.5400 | 0.5080 - 0.5720 | no "
            "| +13 % |") in text
    assert "| ip-large-english-5x6 | 2.50 | 0.45 | 0/- | pending |" in text


def test_held_out_smoke_run_records_the_frozen_commit(tmp_path):
    """With a committed frozen set (a temporary repository), --held-out runs the wall with that
    set and records the freezing commit in the point and the report."""
    import subprocess

    repo = tmp_path / "repo"
    frozen = repo / "studies" / "calibration" / "frozen.yaml"
    frozen.parent.mkdir(parents=True)
    frozen.write_text(yaml.safe_dump({"imperfections": CAND, "candidate": "x"}))
    for args in (["init", "-q"], ["add", "."], ["-c", "user.name=t", "-c", "user.email=t@t",
                                                "commit", "-qm", "freeze"]):
        subprocess.run(["git", "-C", str(repo), *args], check=True, capture_output=True)
    commit = subprocess.run(["git", "-C", str(repo), "rev-parse", "HEAD"], check=True,
                            capture_output=True, text=True).stdout.strip()
    out = tmp_path / "cal"
    assert cal_cli.main(["--out", str(out), "--held-out", "--frozen", str(frozen),
                    "--specimens", "ip-large-stretcher-on-edge-5x4", "--realisations", "1",
                    "--max-steps", "200"]) == 0
    data = json.loads(cal_points.point_path(out, cal_specimens.HELD_OUT_DIR,
                                    "ip-large-stretcher-on-edge-5x4").read_text())
    assert data["calibration"]["frozen"]["commit"] == commit
    assert data["calibration"]["parameters"] == CAND
    assert data["imperfections"]["arris"] == CAND["arris"]
    assert "Held out" in (out / "README.md").read_text()


def test_the_calibration_session_runs_records_and_resumes_on_the_kit(tmp_path, monkeypatch):
    """The calibration command on the kit's loop, with a stand-in for the dem ensemble child:
    a point runs once and is recorded with the child's CPU seconds, the report follows it; a
    second session starts nothing; a point recorded unfinished runs again and its sessions and
    CPU seconds add up."""
    from pathlib import Path

    from studies.kit import child

    calls = []

    def fake_ensemble(args, log):
        run_dir = Path(args[args.index("--out") + 1])
        n = int(args[args.index("--realisations") + 1])
        run_dir.mkdir(parents=True, exist_ok=True)
        (run_dir / "ensemble.json").write_text(json.dumps(_ensemble([0.8] * n,
                                                                    ["sliding"] * n)))
        calls.append(args)
        return 0, 5.0, 6.0
    monkeypatch.setattr(child, "run_dem", fake_ensemble)
    cfile = tmp_path / "candidates.yaml"
    cfile.write_text(yaml.safe_dump({"c": CAND}))
    out = tmp_path / "cal"
    argv = ["--out", str(out), "--candidates-file", str(cfile), "--specimens", "ip-small-5x5",
            "--realisations", "2"]
    assert cal_cli.main(argv) == 0
    point = cal_points.point_path(out, "c", "ip-small-5x5")
    cal = json.loads(point.read_text())["calibration"]
    assert len(calls) == 1 and calls[0][:2] == ["ensemble", str(out / "runs" / "c" /
                                                                "ip-small-5x5.yaml")]
    assert cal["finished"] and (cal["cpu_seconds"], cal["sessions"]) == (5.0, 1)
    case = cal_specimens.specimen_case(cal_specimens.specimens()["ip-small-5x5"]["path"], CAND,
                                       "cal-c-ip-small-5x5")
    assert cal["fingerprint"] == cal_specimens.fingerprint(case, 2, None)
    assert (out / "summary.json").is_file()
    assert cal_cli.main(argv) == 0 and len(calls) == 1          # finished: nothing starts
    data = json.loads(point.read_text())
    data["calibration"]["finished"] = False
    point.write_text(json.dumps(data))
    assert cal_cli.main(argv) == 0 and len(calls) == 2
    cal = json.loads(point.read_text())["calibration"]
    assert (cal["cpu_seconds"], cal["sessions"]) == (10.0, 2)
