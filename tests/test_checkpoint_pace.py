"""Checkpoints paced by their cost (dem.run.write.CheckpointPace): a run checkpoints every
CHECKPOINT_SECONDS of wall time, and the runs that share a process (the points of a batch, one
engine that stops while each writes) no more often than keeps their checkpoints together under
CHECKPOINT_SHARE of the wall time."""

from __future__ import annotations

import json
from types import SimpleNamespace

import pytest

import dem.run.loop
from dem.case import Case
from dem.run.batched import run_cases_in_one_engine
from dem.run.write import CHECKPOINT_SECONDS, CHECKPOINT_SHARE, CheckpointPace, RunWriter
from tests.test_resume import STACK


class FakeClock:
    """A wall clock the test moves (s)."""

    def __init__(self):
        self.now = 0.0

    def __call__(self) -> float:
        return self.now


def _writer(tmp_path, name: str, pace: CheckpointPace, clock: FakeClock, write_s: float):
    """A RunWriter into tmp_path/name whose frames.npz takes ``write_s`` seconds to write."""
    def write():
        clock.now += write_s

    recording = SimpleNamespace(frames=SimpleNamespace(write=write))
    out = tmp_path / name
    out.mkdir()
    return RunWriter(out, None, None, recording, pace)


def _checkpointed(writer, clock, at: float) -> bool:
    """Whether ``writer`` writes a checkpoint when its run asks at time ``at``."""
    clock.now = at
    before = writer.last_flush
    writer.checkpoint({}, SimpleNamespace(step_count=1, t=0.1), 1.0)
    return writer.last_flush != before


def test_a_lone_run_checkpoints_every_checkpoint_seconds():
    """One run whose checkpoint takes 0.1 s: its rounds take well under the share."""
    pace = CheckpointPace(FakeClock())
    assert pace.interval() == CHECKPOINT_SECONDS
    pace.record("run", 0.1)
    assert 0.1 / CHECKPOINT_SHARE < CHECKPOINT_SECONDS and pace.interval() == CHECKPOINT_SECONDS


def test_the_points_of_a_batch_checkpoint_no_more_often_than_their_share(tmp_path):
    """64 points whose checkpoints take 0.2 s each (Model II near a 50-cycle run's end): once
    each has written one, the next comes after 64 x 0.2 / CHECKPOINT_SHARE seconds, not after
    CHECKPOINT_SECONDS; a point that ended no longer counts."""
    clock = FakeClock()
    pace = CheckpointPace(clock)
    writers = [_writer(tmp_path, f"p{g}", pace, clock, 0.2) for g in range(64)]
    for w in writers:  # the first round, each asking later than the pace's interval then
        assert _checkpointed(w, clock, clock.now + CHECKPOINT_SECONDS + 1.0)
    interval = 64 * 0.2 / CHECKPOINT_SHARE
    assert interval > CHECKPOINT_SECONDS and pace.interval() == pytest.approx(interval)
    first = writers[0]
    assert not _checkpointed(first, clock, first.last_flush + CHECKPOINT_SECONDS + 1.0)
    assert not _checkpointed(first, clock, first.last_flush + 0.99 * interval)
    assert _checkpointed(first, clock, first.last_flush + 1.01 * interval)
    assert json.loads((tmp_path / "p0" / "summary.json").read_text())["steps"] == 1
    for w in writers[1:]:  # the others end: the survivor's rounds take 0.2 s
        w.pace.leave(w)
    assert pace.interval() == CHECKPOINT_SECONDS


def test_a_batch_shares_one_pace_and_a_lone_run_has_its_own(tmp_path, monkeypatch):
    """run_cases_in_one_engine hands every point's writer the one pace of its engine."""
    paces = []

    class Noting(RunWriter):
        def __init__(self, *args, **kwargs):
            super().__init__(*args, **kwargs)
            paces.append(self.pace)

    monkeypatch.setattr(dem.run.loop, "RunWriter", Noting)
    data = {k: v for k, v in STACK.items() if k != "imperfections"}  # no settling
    data["run"] = {**data["run"], "duration": 0.02}
    data["loading"] = {**data["loading"], "cycles": 0.1}
    cases = [(f"p{g}", Case.model_validate({**data, "name": f"p{g}"})) for g in range(2)]
    recs = run_cases_in_one_engine(cases, [tmp_path / n for n, _ in cases])
    assert [r["status"] for r in recs] == ["ok", "ok"]
    assert len(paces) == 2 and paces[0] is paces[1]
    dem.run.loop.run_case(cases[0][1], tmp_path / "lone")
    assert len(paces) == 3 and paces[2] is not paces[0]
