"""SELECTION.md's rule as executed by studies.calibration.select (the
freeze).

Synthetic scores: each test plants the check outcomes the rule reads and asserts the choice the
rule's text gives for them."""

from __future__ import annotations

import pytest
import yaml

from studies.calibration import select as sel
from studies.prediction.plan import validate_frozen_data

PERFECT = {"bed_unevenness": 0.0, "face_shape": "planar", "size_scatter": [0.0, 0.0, 0.0],
           "arris": 0.0}


def _params(bed, scatter_arris=False):
    return {"bed_unevenness": bed, "face_shape": "planar",
            "size_scatter": [3e-4, 2e-4, 1e-4] if scatter_arris else [0.0, 0.0, 0.0],
            "arris": 5e-4 if scatter_arris else 0.0}


CANDS = {"perfect": PERFECT, "bed-0.1": _params(1e-4), "bed-0.05": _params(5e-5),
         "bed-0.2": _params(2e-4), "bed-0.1-sa": _params(1e-4, True),
         "bed-0.05-sa": _params(5e-5, True)}


def _cand(thesis=("pass", "pass", "pass"), invariants=("pass", "pass"), pending=(),
          lone=0, n=20):
    """(points, score) of one candidate: thesis statuses in THESIS_CHECKS order, the two
    in-plane invariants' statuses, pending specimen names, lone-block realisations on one
    specimen of n."""
    points = {"a": {"status": "finished", "n_ok": n,
                    "lone_block": [[f"r{i}", 0.1] for i in range(lone)]}}
    for s in pending:
        points[s] = {"status": "pending", "n_ok": 3}
    score = {"invariants": {"sliding-invariant": {"status": invariants[0]},
                            "mechanism-sequence": {"status": invariants[1]},
                            "no-wings-lowest": {"status": "n/a"}},
             "thesis": {k: {"status": v} for k, v in zip(sel.THESIS_CHECKS, thesis)}}
    return points, score


def _select(**spec):
    """spec: candidate -> _cand kwargs; the others absent from CANDS are left out."""
    cands = {c: CANDS[c] for c in spec}
    built = {c: _cand(**kw) for c, kw in spec.items()}
    return sel.select(cands, {c: b[0] for c, b in built.items()},
                      {c: b[1] for c, b in built.items()})


def test_more_thesis_passes_win_and_the_choice_is_decided():
    s = _select(**{"perfect": {}, "bed-0.05": {},
                   "bed-0.1": {"thesis": ("pass", "fail", "pass")}})
    assert s["decided"] and s["chosen"] == "bed-0.05"
    assert s["ranking"] == ["bed-0.05", "bed-0.1"]


@pytest.mark.parametrize("names, chosen", [
    (("bed-0.05", "bed-0.1", "bed-0.2"), "bed-0.1"),        # closest to 0.1 mm on a log scale
    (("bed-0.05", "bed-0.2"), "bed-0.05"),                   # equally far: the smaller
    (("bed-0.1", "bed-0.1-sa"), "bed-0.1-sa"),               # equal bed: scatter + arris
    (("bed-0.05-sa", "bed-0.1"), "bed-0.1"),                 # the bed decides before the variant
])
def test_ties_are_broken_by_rule_3(names, chosen):
    s = _select(**{n: {} for n in names})
    assert s["decided"] and s["chosen"] == chosen


def test_a_failed_invariant_or_lone_blocks_reject_whatever_the_passes():
    s = _select(**{"bed-0.1": {"invariants": ("pass", "fail")},
                   "bed-0.05": {"lone": 3},          # 15 % of 20 realisations
                   "bed-0.2": {"thesis": ("fail", "fail", "pass"), "lone": 2}})  # 10 %: kept
    assert s["candidates"]["bed-0.1"]["status"] == "rejected"
    assert s["candidates"]["bed-0.05"]["status"] == "rejected"
    assert s["chosen"] == "bed-0.2"


def test_a_pending_candidate_that_could_still_outrank_keeps_the_choice_open():
    s = _select(**{"bed-0.1": {"thesis": ("pass", "pass", "fail")},
                   "bed-0.2": {"thesis": ("pass", "pending", "pending"), "pending": ("b",)}})
    assert not s["decided"] and s["chosen"] is None and s["leader"] == "bed-0.1"
    assert s["candidates"]["bed-0.2"]["could_outrank_leader"]
    with pytest.raises(sel.FreezeRefused, match="undecided"):
        sel.freeze(s, CANDS, "/nonexistent/frozen.yaml", "2026-11-24")


def test_a_pending_candidate_that_cannot_outrank_does_not_block_the_choice():
    # bed-0.1-sa already fails one thesis check: at best 2 passes against the leader's 3
    s = _select(**{"bed-0.1": {},
                   "bed-0.1-sa": {"thesis": ("fail", "pending", "pending"), "pending": ("b",)},
                   "bed-0.05": {"thesis": ("pass", "pass", "pending"), "pending": ("b",)}})
    assert s["decided"] and s["chosen"] == "bed-0.1"
    assert not s["candidates"]["bed-0.1-sa"]["could_outrank_leader"]
    # bed-0.05 could tie on passes, and loses the tie to 0.1 mm
    assert not s["candidates"]["bed-0.05"]["could_outrank_leader"]


def test_the_table_names_the_leader_only_when_there_is_one():
    row = lambda s, c: next(l for l in sel.selection_lines(s) if l.startswith(f"| {c} |"))
    s = _select(**{"bed-0.1": {"thesis": ("pass", "pass", "pending"), "pending": ("b",)},
                   "bed-0.2": {"thesis": ("pass", "pending", "pending"), "pending": ("b",)}})
    assert s["leader"] is None
    assert "(could still be chosen)" in row(s, "bed-0.1") and "leader" not in row(s, "bed-0.1")
    s = _select(**{"bed-0.1": {},
                   "bed-0.2": {"thesis": ("fail", "pending", "pending"), "pending": ("b",)}})
    assert "(cannot outrank the leader)" in row(s, "bed-0.2")


def test_a_pending_candidate_that_would_win_the_tie_blocks_the_choice():
    s = _select(**{"bed-0.1": {},
                   "bed-0.1-sa": {"thesis": ("pass", "pass", "pending"), "pending": ("b",)}})
    assert not s["decided"]


def test_the_perfect_set_only_when_every_imperfect_candidate_is_rejected():
    s = _select(**{"perfect": {}, "bed-0.1": {"invariants": ("fail", "pass")},
                   "bed-0.2": {"lone": 5}})
    assert s["decided"] and s["chosen"] == "perfect"
    s = _select(**{"perfect": {}, "bed-0.1": {"invariants": ("fail", "pass")},
                   "bed-0.2": {"pending": ("b",), "thesis": ("pass", "pending", "pass")}})
    assert not s["decided"]


def test_freeze_writes_a_file_the_prediction_accepts_once(tmp_path):
    s = _select(**{"bed-0.1": {}, "bed-0.2": {"thesis": ("pass", "fail", "pass")}})
    path = tmp_path / "frozen.yaml"
    assert sel.freeze(s, CANDS, path, "2026-11-24") is True
    data = yaml.safe_load(path.read_text())
    assert validate_frozen_data(data, str(path)) == CANDS["bed-0.1"]
    assert data["candidate"] == "bed-0.1"
    assert data["derived_in"] == "results/calibration/README.md"
    assert sel.freeze(s, CANDS, path, "2026-11-25") is False       # the same set: unchanged
    other = _select(**{"bed-0.2": {}})
    with pytest.raises(sel.FreezeRefused, match="already holds"):
        sel.freeze(other, CANDS, path, "2026-11-25")
