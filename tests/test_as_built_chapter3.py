"""studies.as_built.chapter3 (`python -m studies as-built chapter3`): criterion (i) of the loose
sets, the Chapter 3 tilts with the frozen candidate plus a set's as-built fields.  Nothing runs the
engine: the cases are built and read back, the records are hand-made (the runs themselves are
studies.calibration.points', tested there)."""

from __future__ import annotations

import json

import pytest

from dem.case import load_case
from studies.as_built import chapter3 as ch
from studies.calibration import points as cal_points
from studies.calibration import specimens as cal_specimens
from studies.chapter3 import check as c3
from studies.kit.provenance import ROOT
from studies.kit.study import write_case

CANDIDATE, PARAMS = c3.frozen_candidate(c3.DEFAULT_FROZEN, cal_specimens.load_candidates())
SPECS = cal_specimens.specimens()
WALL, FACADE = "ip-small-5x5", "oop-small-5x15-strong-strong"


def _read_back(case, tmp_path):
    path = write_case(case, tmp_path / f"{case.name}.yaml")
    return load_case(path).model_dump(mode="json")["imperfections"]


@pytest.mark.parametrize("name", ch.ORDER)
def test_a_sets_case_carries_exactly_its_fields_where_they_act(name, tmp_path):
    """Read back from the case file: the facade (strong corners) carries the set's corner gap,
    head gap and plumb exactly, the in-plane wall (no corner) the head gap and plumb only, both
    on top of the frozen candidate's parameters, unchanged, and nothing else."""
    fields = ch.set_fields(name)
    for specimen, expect in ((FACADE, ("corner_gap", "head_gap", "plumb")),
                             (WALL, ("head_gap", "plumb"))):
        imp = _read_back(ch.set_case(name, CANDIDATE, PARAMS, specimen, SPECS[specimen]),
                         tmp_path)
        assert set(imp) == set(PARAMS) | {"seed"} | set(expect), specimen
        assert {k: imp[k] for k in PARAMS} == PARAMS
        for k in expect:
            got = imp[k] if k != "plumb" else {"sigma": imp[k]["sigma"]}  # lean: 0, default
            assert got == fields[k], (specimen, k)
    mean = float(name.removeprefix("loose-").removesuffix("mm")) * 1e-3
    assert fields["corner_gap"] == pytest.approx({"mean": mean, "scatter": mean / 2})


def test_which_fields_act_is_read_from_the_geometry():
    """Corner ends on the facades with wings only (the in-plane walls have none), head joints
    and moving courses on every specimen, the large-brick walls included."""
    fields = ch.set_fields("loose-1mm")
    specs = {**SPECS, **cal_specimens.held_out_specimens()}
    for s, spec in specs.items():
        acting, counts = ch.acting_fields(spec, fields, PARAMS)
        corners = spec["kind"] == "out-of-plane"
        assert ("corner_gap" in acting) is corners and (counts["corner_gap"] > 0) is corners, s
        assert {"head_gap", "plumb"} <= set(acting) and counts["head_gap"] > 0, s


def test_an_in_plane_wall_is_one_case_for_every_set_a_facade_one_per_set():
    """So a wall runs once for the three sets (its records shared), a facade three times."""
    def fp(name, s):
        return cal_points.Ensembles(1).point(
            "o", "r", CANDIDATE, c3.case_params(PARAMS, ch.patches(name, {s: SPECS[s]},
                                                                   PARAMS)[s]),
            s, SPECS[s]).fingerprint
    assert len({fp(n, WALL) for n in ch.ORDER}) == 1
    assert len({fp(n, FACADE) for n in ch.ORDER}) == 3


def _finished(point, shared_from=None):
    cal = {"fingerprint": point.fingerprint, "finished": True, "n_realisations": 1,
           "cpu_seconds": 30.0}
    if shared_from:
        cal["shared_from"] = shared_from
    return {"realisations": [{"seed": 0, "status": "ok", "lambda": 0.8, "mechanism": "sliding"}],
            "aggregate": {"n_ok": 1}, "calibration": cal}


def _write(root, point, data):
    dest = cal_points.point_path(root, CANDIDATE, point.name)
    dest.parent.mkdir(parents=True, exist_ok=True)
    dest.write_text(json.dumps(data))
    return dest


def test_a_case_another_set_finished_is_copied_not_run(tmp_path):
    a, b = tmp_path / "loose-1mm", tmp_path / "loose-2mm"
    study = ch.SharedEnsembles(1, [a])
    params = c3.case_params(PARAMS, ch.patches("loose-2mm", {WALL: SPECS[WALL]}, PARAMS)[WALL])
    point = study.point(b, tmp_path / "runs", CANDIDATE, params, WALL, SPECS[WALL])
    assert study.todo(point)  # nothing anywhere: to run
    _write(a, point, {**_finished(point), "calibration": {
        **_finished(point)["calibration"], "fingerprint": "another-case"}})
    assert study.todo(point)  # the twin is another case: to run
    src = _write(a, point, _finished(point))
    assert not study.todo(point)  # the twin is this case: copied
    copied = json.loads(cal_points.point_path(b, CANDIDATE, WALL).read_text())
    assert copied["realisations"] == _finished(point)["realisations"]
    assert copied["calibration"]["shared_from"].endswith(
        str(src.relative_to(tmp_path))) and not study.todo(point)
    # a copy is never the source of another copy (its CPU is counted once, at its original)
    c = tmp_path / "loose-0.5mm"
    assert ch.SharedEnsembles(1, [b]).todo(
        study.point(c, tmp_path / "runs", CANDIDATE, params, WALL, SPECS[WALL]))
    assert ch.own_cpu(b, CANDIDATE, [WALL]) == 0.0 and ch.own_cpu(a, CANDIDATE, [WALL]) == 30.0


def _check(status):
    return {"verdict": {"status": status, "why": "w"}}


def _score(inv):
    return {"invariants": {"sliding-invariant": {"status": "pass"},
                           "mechanism-sequence": {"status": "fail" if inv is False else "pass"}},
            "invariants_pass": inv}


def test_criterion_i_needs_both_the_5_percent_and_the_invariants():
    assert ch.criterion_i(_check("pass"), _score(True))["status"] == "pass"
    v = ch.criterion_i(_check("pass"), _score(False))
    assert v["status"] == "fail" and "mechanism-sequence" in v["why"]
    assert ch.criterion_i(_check("fail"), _score(True))["status"] == "fail"
    assert ch.criterion_i(_check("fail"), _score(None))["status"] == "fail"
    assert ch.criterion_i(_check("pending"), _score(True))["status"] == "pending"
    assert ch.criterion_i(_check("pass"), _score(None))["status"] == "pending"


def test_with_nothing_run_the_invariants_wait_rather_than_pass(tmp_path):
    """A specimen not run yet still counts for its invariant (pending), so an empty set cannot
    pass (i) by having nothing to judge."""
    data = ch.compare_set("loose-1mm", CANDIDATE, PARAMS, [0], tmp_path)
    assert data["invariants"]["sliding-invariant"]["status"] == "pending"
    assert data["invariants"]["mechanism-sequence"]["status"] == "pending"
    assert data["criterion_i"]["status"] == "pending"
    assert data["specimens"][FACADE]["patch"] == ch.set_fields("loose-1mm")
    assert set(data["specimens"][WALL]["patch"]) == {"head_gap", "plumb"}
    assert data["specimens"][WALL]["same_case"] is False  # not the calibration's case


def test_the_check_without_patches_plans_its_committed_points(monkeypatch):
    """studies.chapter3.check unchanged for the frozen candidate: run_points without patches
    plans, for every specimen, the case whose fingerprint the committed check record carries
    (so every one of them is found finished and skipped), and compare names no patch."""
    monkeypatch.setattr(c3.kit, "run", lambda study, stop_at, log: [])
    study = cal_points.Ensembles(1)
    c3.run_points(c3.DEFAULT_OUT, c3.DEFAULT_RUNS, CANDIDATE, PARAMS, SPECS, 1, study=study)
    planned = list(study.points())
    assert [p.name for p in planned] == list(SPECS)
    for p in planned:
        rec = json.loads(cal_points.point_path(c3.DEFAULT_OUT, CANDIDATE, p.name).read_text())
        assert p.fingerprint == rec["calibration"]["fingerprint"], p.name
        assert not study.todo(p), p.name
    assert c3.case_params(PARAMS, None) == PARAMS
    with pytest.raises(c3.CheckInputError, match="bed_unevenness"):
        c3.case_params(PARAMS, {"bed_unevenness": 2e-4})
    rec = c3.compare(c3.DEFAULT_OUT, c3.DEFAULT_CALIBRATION, CANDIDATE, {WALL: SPECS[WALL]},
                     [0], PARAMS)
    assert "patch" not in rec["specimens"][WALL] and rec["specimens"][WALL]["same_case"] is True
    assert ROOT / "results" / "prediction" / "chapter3-check" == c3.DEFAULT_OUT
