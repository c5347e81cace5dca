"""The diagnosis' grid experiments (studies/diagnosis/grid.py, experiments.py; E3/E5/E6):
a variant changes only what its patch names, a finished row counts only under its fingerprint,
and the report counts the rocking runs by the library's verdict."""

from __future__ import annotations

import json

import pytest

from studies.diagnosis import grid as G
from studies.kit import child as kit_child
from studies.diagnosis.experiments import GRIDS
from studies.prediction.plan import load_frozen, sweep_case
from studies.prediction.protocol import DEFAULT_FROZEN


def test_merge_patch_nested_none_and_no_mutation():
    base = {"loading": {"peak_acceleration": 1.53, "amplitude": None, "frequency": 2.8},
            "material": {"friction": 0.81, "pairs": []}}
    out = G.merge_patch(base, {"loading": {"amplitude": 0.005, "peak_acceleration": None},
                               "material": {"pairs": [{"between": ["a", "b"]}]}})
    assert out["loading"] == {"peak_acceleration": None, "amplitude": 0.005, "frequency": 2.8}
    assert out["material"] == {"friction": 0.81, "pairs": [{"between": ["a", "b"]}]}
    assert base["loading"]["peak_acceleration"] == 1.53 and base["material"]["pairs"] == []


def _leaves(d, prefix=()):
    for k, v in d.items():
        if isinstance(v, dict):
            yield from _leaves(v, prefix + (k,))
        else:
            yield prefix + (k,), v


@pytest.mark.parametrize("key", sorted(GRIDS))
def test_a_variant_changes_only_what_it_names(key):
    """Every leaf of the variant's case equals the first prediction's case except the patched
    leaves (and the name); the patched ones hold the patch's values."""
    params = load_frozen(DEFAULT_FROZEN)["parameters"]
    grid = GRIDS[key]
    base = dict(_leaves(sweep_case(grid.sweep, params).model_dump(mode="json")))
    for v in grid.variants:
        case = G.variant_case(grid, v, params)
        got = dict(_leaves(case.model_dump(mode="json")))
        patched = dict(_leaves(v.patch))
        for path, value in got.items():
            if path == ("name",):
                assert value == f"diag-{key}-{v.name}"
            elif path in patched:
                want = patched[path]
                if isinstance(value, list) and value and isinstance(value[0], dict):
                    # a list of models: the patch's keys, the rest at their defaults
                    value = [{k: x[k] for k in w} for x, w in zip(value, want)]
                assert value == want, path
            else:
                assert value == base.get(path), (v.name, path)
        assert set(patched) <= set(got)
        if v.patch:
            assert G.fingerprint(grid, case) != G.fingerprint(
                grid, sweep_case(grid.sweep, params))


def test_e5_holds_the_amplitude_and_e3_the_start():
    params = load_frozen(DEFAULT_FROZEN)["parameters"]
    e5 = G.variant_case(GRIDS["e5"], GRIDS["e5"].variants[0], params)
    assert e5.loading.amplitude == 0.005 and e5.loading.peak_acceleration is None
    starts = [G.variant_case(GRIDS["e3"], v, params).loading.start for v in GRIDS["e3"].variants]
    assert starts == ["lab", "ramp"]


def _row(seed, f, ds, phase_deg, status="ok"):
    return {"seed": seed, "frequency_hz": f, "run_status": status,
            "amplification": {"ds": ds}, "lag_s": {"ds": phase_deg / (360.0 * f)}}


def test_a_judged_run_carries_its_corner_bricks_motion_where_recorded():
    row = _row(0, 2.5, 2.0, 140.0)
    assert G.judged(row)["corner_twist_deg"] is None and G.judged(row)["corner_pp_m"] is None
    row["mechanism"] = {"corner_twist_h1_deg": [0.2, 0.6],
                        "pp_corner_m": {"corner_a": 1e-3, "corner_b": 3e-3}}
    j = G.judged(row)
    assert j["corner_twist_deg"] == pytest.approx(0.4)
    assert j["corner_pp_m"] == pytest.approx(2e-3)


def test_finished_rows_need_the_fingerprint_and_an_ok_run():
    data = {"variants": {"v": {"fingerprint": "abc", "rows": [
        _row(0, 2.8, 2.0, 140.0), _row(1, 2.8, 0.2, 12.0, status="pending")]}}}
    assert list(G.finished(data, "v", "abc")) == [(0, 2.8)]
    assert G.finished(data, "v", "other") == {}
    assert G.finished(data, "w", "abc") == {}


def test_report_counts_rocking_runs(tmp_path, monkeypatch):
    monkeypatch.setattr(G, "RESULTS", tmp_path)
    grid = G.Grid(key="ex", title="t", hypothesis="h", sweep="model-ii-y",
                  variants=(G.Variant("v", "a variant", {"loading": {"start": "lab"}}),),
                  frequencies=(2.8,), seeds=(0, 1, 2), cycles=10.0)
    grid.out.mkdir(parents=True)
    (grid.out / "points.json").write_text(json.dumps({"variants": {"v": {
        "fingerprint": "x", "rows": [
            dict(_row(0, 2.8, 2.4, 140.0), survival={"verdict": "local collapse", "n_fallen": 2}),
            dict(_row(1, 2.8, 0.2, 12.0), survival={"verdict": "standing", "n_fallen": 0}),
            _row(2, 2.8, 1.5, 60.0)]}}}))
    s = G.report(grid, log=lambda *_: None)
    cell = s["variants"]["v"]["cells"][0]
    assert (cell["runs"], cell["rocking"]) == (3, 1)
    assert [j["branch"] for j in cell["seeds"]] == ["rocking", "quasi-static", "between"]
    assert cell["median_ds"] == pytest.approx(1.5)
    assert cell["survival"] == {"local collapse": 1, "standing": 1}
    # the baseline: the first prediction's committed rows of seeds 0-2 at 2.8 Hz
    assert s["variants"][G.BASELINE]["cells"][0]["runs"] == 3
    assert (grid.out / "branches.png").stat().st_size > 0


# ---- E2: the stepped specimen ------------------------------------------------------------------
def test_e2_specimen_is_the_predictions_case_with_a_stepped_table():
    from studies.diagnosis import e2

    params = load_frozen(DEFAULT_FROZEN)["parameters"]
    base = sweep_case("model-ii-y", params)
    case = e2.specimen_case("model-ii-y", 2, params)
    ld = case.loading
    assert ld.type == "stepped_shake" and ld.peak_acceleration == base.loading.peak_acceleration
    assert [s.frequency for s in ld.steps] == list(e2.DOWN + e2.UP)
    assert case.imperfections.seed == 2 and case.material == base.material
    # the steps' own durations, cycles / f, plus the margin
    want = sum(e2.CYCLES_PER_STEP / f for f in e2.DOWN + e2.UP) + e2.MARGIN_S
    assert case.run.duration == pytest.approx(want, rel=1e-12)


def test_e2_step_rows_and_verdicts(tmp_path, monkeypatch):
    from studies.diagnosis import e2

    def step(k, f, pas, ds, phase):
        return {"frequency_hz": f, "pass": pas, "t_start_s": 10.0 * k,
                "t_end_s": 10.0 * (k + 1), "amplification": {"ds": ds},
                "lag": {"ds": {"s": phase / (360.0 * f)}}}
    analysis = {"steps": [step(0, 4.4, "down", 3.0, 140.0), step(1, 2.8, "down", 2.5, 130.0),
                          step(2, 2.4, "down", 0.2, 10.0), step(3, 2.8, "up", 0.2, 12.0),
                          step(4, 3.2, "up", 4.0, 130.0)]}
    # two bricks fell: at 15 s (inside the second step) and at 45 s (inside the fifth)
    rows = e2.step_rows(analysis, fall_times=[45.0, 15.0])
    assert [r["branch"] for r in rows] == ["rocking", "rocking", "quasi-static", "quasi-static",
                                           "rocking"]
    assert [r["fallen_by_end"] for r in rows] == [0, 1, 1, 1, 2]
    monkeypatch.setattr(e2, "OUT", tmp_path)
    rows[1]["fallen_by_end"] = 0      # say the second step stayed whole
    (tmp_path / "points.json").write_text(json.dumps({"specimens": {"model-ii-y-seed-0": {
        "sweep": "model-ii-y", "seed": 0, "run_status": "ok", "steps": rows,
        "survival": {"verdict": "local collapse", "first_fall_time_s": 25.0}}}}))
    v = e2.report(log=lambda *_: None)["verdicts"]["model-ii-y-seed-0"]
    # the ruin's rocking at 3.2 Hz going up does not count
    assert v["rocking_going_down_hz"] == [4.4, 2.8] and v["lowest_rocking_down_hz"] == 2.8
    assert v["rocking_going_up_hz"] == [] and v["survival"] == "local collapse"
    assert v["steps_with_bricks_down"] == [[2.4, "down"], [2.8, "up"], [3.2, "up"]] or \
        v["steps_with_bricks_down"] == [(2.4, "down"), (2.8, "up"), (3.2, "up")]
    assert (tmp_path / "passes.png").stat().st_size > 0


def test_e2_command_runs_only_the_specimens_asked_for(monkeypatch):
    """--sweep / --seed choose the specimens (two processes can share E2); an unknown one is
    refused before anything runs, naming it."""
    from typer.testing import CliRunner

    from studies.diagnosis import e2
    from studies.diagnosis.cli import app

    calls = []
    monkeypatch.setattr(e2, "run", lambda **kw: calls.append(kw))
    monkeypatch.setattr(e2, "report", lambda **kw: {})
    res = CliRunner().invoke(app, ["e2", "--sweep", "model-iii-y", "--seed", "2"])
    assert res.exit_code == 0, res.output
    assert calls == [{"sweeps": ("model-iii-y",), "seeds": (2,), "stop_at": None}]
    res = CliRunner().invoke(app, ["e2"])
    assert calls[-1] == {"sweeps": e2.SWEEPS, "seeds": e2.SEEDS, "stop_at": None}
    res = CliRunner().invoke(app, ["e2", "--sweep", "model-iv-y", "--seed", "5"])
    assert res.exit_code != 0 and len(calls) == 2
    assert "model-iv-y" in res.output and "5" in res.output


# ---- E1: the frequency fingerprint --------------------------------------------------------------
@pytest.mark.parametrize("r, phase", [(0.3, 5.0), (0.7, 20.0), (0.9, 60.0)])
def test_e1_natural_frequency_inverts_the_base_excited_oscillator(r, phase):
    """A = r^2 / (1 - r^2) (undamped, Chopra 3.6) of f = r f_n below resonance gives back f_n;
    a run lagging by 90 deg or more (above resonance, or rocking) gives none."""
    from studies.diagnosis.e1 import natural_frequency

    fn, f = 7.0, 7.0 * r
    row = _row(0, f, r * r / (1.0 - r * r), phase)
    assert natural_frequency(row) == pytest.approx(fn, rel=1e-12)
    assert natural_frequency(_row(0, f, 2.5, 140.0)) is None


def test_e1_fingerprint_ratios_and_verdict():
    from studies.diagnosis import e1

    def rows(fn):            # three seeds at 2.0 Hz on the low branch of f_n
        r = e1.FREQUENCY / fn
        return [_row(s, e1.FREQUENCY, r * r / (1 - r * r), 10.0) for s in range(3)]
    thesis = e1.fingerprint_of({s: rows(3.0 * f) for s, f in e1.THESIS_FC.items()})
    assert thesis["fingerprint"] == "passes"
    for v in thesis["ratios"].values():
        assert v["dem"] == pytest.approx(v["thesis"], rel=1e-12)
    off = e1.fingerprint_of({**{s: rows(3.0 * f) for s, f in e1.THESIS_FC.items()},
                             "model-iii-y": rows(3.0 * 2.0)})     # III / II = 2.0 / 2.8
    assert off["fingerprint"] == "fails"
    assert e1.fingerprint_of({"model-ii-y": rows(8.0)})["fingerprint"] == "pending"


def test_e1_corner_motion_compares_model_i_with_model_ii_seed_medians():
    """Medians over seeds of the corner bricks' mean twist and peak-to-peak ds, Model I y over
    Model II y; rows at another frequency, failed rows and rows without the record are left
    out."""
    from studies.diagnosis import e1

    def row(seed, tw, pp, f=e1.FREQUENCY, status="ok"):
        return {"seed": seed, "frequency_hz": f, "run_status": status,
                "mechanism": {"corner_twist_h1_deg": tw,
                              "pp_corner_m": None if pp is None else
                              {"corner_a": pp, "corner_b": pp}}}
    rows = {"model-i-y": [row(0, [0.5, 0.7], 3e-3), row(1, [0.9, 0.9], 4e-3),
                          row(2, [0.2, 0.4], 2e-3), row(3, [9.0, 9.0], 9.0, f=2.8),
                          row(4, [9.0, 9.0], 9.0, status="failed")],
            "model-ii-y": [row(0, [0.3, 0.3], 1e-3), row(1, None, None),
                           row(2, [0.5, 0.5], 3e-3)]}
    cm = e1.corner_motion_of(rows)
    assert cm["models"]["model-i-y"] == {"runs": 3, "median_twist_h1_deg": pytest.approx(0.6),
                                         "median_pp_corner_m": pytest.approx(3e-3)}
    assert cm["models"]["model-ii-y"]["runs"] == 2
    r = cm["model-i-y / model-ii-y"]
    assert r["median_twist_h1_deg"] == pytest.approx(0.6 / 0.4)
    assert r["median_pp_corner_m"] == pytest.approx(3e-3 / 2e-3)
    assert e1.corner_motion_of({})["model-i-y / model-ii-y"]["median_twist_h1_deg"] is None


def test_run_order_is_seed_then_variant_then_grid(tmp_path, monkeypatch):
    """Within a seed, one variant on every grid before the next variant (E1: one candidate on
    every model first), so that a cut session leaves whole candidates of a seed."""
    calls = []
    monkeypatch.setattr(G, "RESULTS", tmp_path / "results")
    monkeypatch.setattr(G, "RUNS", tmp_path / "runs")
    monkeypatch.setattr(kit_child, "run_dem", lambda args, log: (
        calls.append((args[1].split("/")[-2], args[1].split("/")[-1], args[args.index("--seed")
                                                                          + 1])), (0, 0.0, 0.0))[1])
    va, vb = (G.Variant("a", "a", {"loading": {"start": "lab"}}),
              G.Variant("b", "b", {"loading": {"start": "ramp", "ramp_cycles": 1.0}}))
    grids = [G.Grid(key=k, title="t", hypothesis="h", sweep="model-ii-y", variants=(va, vb),
                    frequencies=(2.8,), seeds=(0, 1), cycles=2.0) for k in ("g1", "g2")]
    G.run(grids, log=lambda *_: None)
    assert calls == [("g1", "a.yaml", "0"), ("g2", "a.yaml", "0"), ("g1", "b.yaml", "0"),
                     ("g2", "b.yaml", "0"), ("g1", "a.yaml", "1"), ("g2", "a.yaml", "1"),
                     ("g1", "b.yaml", "1"), ("g2", "b.yaml", "1")]


def test_a_grid_of_another_study_keeps_its_records_in_its_own_folders(tmp_path, monkeypatch):
    """``results_dir`` / ``runs_dir``: the records, CPU ledger, case files, drain file and report
    of the grid go there and nothing to results/diagnosis; a row recorded finished there for the
    point's fingerprint is not run again."""
    calls = []
    monkeypatch.setattr(G, "RESULTS", tmp_path / "diagnosis-results")
    monkeypatch.setattr(G, "RUNS", tmp_path / "diagnosis-runs")
    monkeypatch.setattr(kit_child, "run_dem", lambda args, log: (
        calls.append((args[args.index("--out") + 1], args[args.index("--seed") + 1],
                      args[args.index("--drain-file") + 1])), (0, 2.0, 3.0))[1])
    v = G.Variant("lab", "lab start", {"loading": {"start": "lab"}})
    grid = G.Grid(key="g", title="t", hypothesis="h", sweep="model-ii-y", variants=(v,),
                  frequencies=(2.8,), seeds=(0, 1), cycles=2.0,
                  results_dir=tmp_path / "as_built", runs_dir=tmp_path / "runs")
    assert grid.out == tmp_path / "as_built" / "g" and grid.runs == tmp_path / "runs" / "g"
    fp = G.point(grid, v, load_frozen(DEFAULT_FROZEN)).fingerprint
    grid.out.mkdir(parents=True)
    (grid.out / "points.json").write_text(json.dumps({"variants": {"lab": {
        "fingerprint": fp, "rows": [_row(0, 2.8, 2.0, 140.0)]}}}))
    G.run([grid], log=lambda *_: None)
    assert calls == [(str(tmp_path / "runs" / "g" / "lab"), "1", str(tmp_path / "runs" / "DRAIN"))]
    data = json.loads((grid.out / "points.json").read_text())
    assert data["variants"]["lab"]["fingerprint"] == fp and data["kind"] == "diagnosis-g"
    # the committed finished row of seed 0 is kept over the pending one of this machine
    assert [r["run_status"] for r in data["variants"]["lab"]["rows"]] == ["ok", "pending"]
    assert json.loads((grid.out / "cpu.json").read_text()) == {"g": 2.0}
    assert (tmp_path / "runs" / "g" / "lab.yaml").exists()
    G.report(grid, log=lambda *_: None)
    assert (grid.out / "summary.json").exists()
    assert not (tmp_path / "diagnosis-results").exists()
    assert not (tmp_path / "diagnosis-runs").exists()


def test_e4_and_e2_run_on_the_kit_loop_and_skip_what_is_recorded(tmp_path, monkeypatch):
    """E4: one sweep per (seed, level), seed by seed, a level recorded finished for its
    fingerprint skipped; E2: a specimen recorded finished (with its survival) not run again,
    the others run with --resume and recorded."""
    from studies.diagnosis import e2, e4

    calls = []
    monkeypatch.setattr(kit_child, "run_dem",
                        lambda args, log: (calls.append(args), (0, 1.0, 1.0))[1])
    for mod, key in ((e4, "e4"), (e2, "e2")):
        monkeypatch.setattr(mod, "OUT", tmp_path / "results" / key)
        monkeypatch.setattr(mod, "RUNS", tmp_path / "runs" / key)
    frozen = load_frozen(DEFAULT_FROZEN)
    done = e4.point(e4.ACCELERATIONS[0], frozen)
    e4.OUT.mkdir(parents=True)
    (e4.OUT / "points.json").write_text(json.dumps({"levels": {done.name: {
        "fingerprint": done.fingerprint,
        "rows": [_row(s, f, 0.2, 10.0) for s in e4.SEEDS for f in e4.FREQUENCIES]}}}))
    e4.run(log=lambda *_: None)
    ran = [(a[a.index("--seed") + 1], a[a.index("--out") + 1].rsplit("/", 1)[1]) for a in calls]
    assert ran == [(str(s), e4.level_name(a)) for s in e4.SEEDS for a in e4.ACCELERATIONS[1:]]
    assert json.loads((e4.OUT / "cpu.json").read_text()) == {"e4": float(len(ran))}

    calls.clear()
    finished = e2.specimen_name("model-ii-y", 0)
    fp = e2.fingerprint(e2.specimen_case("model-ii-y", 0, frozen["parameters"]))
    e2.OUT.mkdir(parents=True)
    (e2.OUT / "points.json").write_text(json.dumps({"specimens": {finished: {
        "fingerprint": fp, "run_status": "ok", "survival": {"verdict": "standing"}}}}))
    e2.run(sweeps=("model-ii-y",), seeds=(0, 1), log=lambda *_: None)
    assert [a[:2] + a[3:] for a in calls] == [
        ["run", str(e2.RUNS / "model-ii-y-seed-1.yaml"), str(e2.RUNS / "model-ii-y-seed-1"),
         "--resume", "--no-progress"]]
    rec = json.loads((e2.OUT / "points.json").read_text())["specimens"]
    assert rec[finished]["run_status"] == "ok" and rec["model-ii-y-seed-1"]["run_status"] == \
        "unknown"
