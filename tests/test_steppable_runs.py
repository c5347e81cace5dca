"""Steppable runs (dem.run.steps): a run is a generator of "advance my scene by n steps"
requests, driven alone by dem.run.steps.drive (run_case) or with its batch-mates by one loop
(dem.run.batched.drive_together), with no threads.

Exact checks: the requests are the only steps a run takes, so a run driven by hand through its
requests is the same run as run_case, bit for bit (the same calls in the same order); a batch
starts no thread."""

from __future__ import annotations

import threading

import numpy as np

from dem.case import parse_case
from dem.run.batched import run_cases_in_one_engine
from dem.run.loop import run_case, run_case_steps
from dem.run.steps import Advance
from tests.test_shake_analysis import BLOCK


def _case(frequency: float = 2.0):
    data = {**BLOCK, "run": {**BLOCK["run"], "duration": 1.0},
            "loading": {**BLOCK["loading"], "frequency": frequency, "cycles": 2}}
    return parse_case(data)


def test_a_run_driven_through_its_requests_is_run_case_bit_for_bit(tmp_path):
    """Driven by hand (each Advance done by its sim), the generator's run gives run_case's
    frames exactly, and its requests add up to every step the scene took."""
    steps = run_case_steps(_case(), tmp_path / "by-hand")
    asked, sims = 0, set()
    try:
        request = next(steps)
        while True:
            assert isinstance(request, Advance) and request.n_steps > 0
            request.sim.advance(request.n_steps, request.loads)
            asked += request.n_steps
            sims.add(id(request.sim))
            request = next(steps)
    except StopIteration as done:
        by_hand = done.value
    alone = run_case(_case(), tmp_path / "alone")
    assert len(sims) == 1 and asked == by_hand.summary["steps"] > 0
    assert by_hand.summary["steps"] == alone.summary["steps"]
    for a, b in ((by_hand.t, alone.t), (by_hand.pos, alone.pos), (by_hand.vel, alone.vel)):
        assert np.array_equal(a, b)


def test_a_batch_runs_its_points_in_the_calling_thread(tmp_path, monkeypatch):
    """Two points in one engine: no thread is started (the loop drives both generators), both
    runs end ok with the steps of their own durations."""
    started = []
    monkeypatch.setattr(threading.Thread, "start", lambda self: started.append(self.name))
    cases = [("f2", _case(2.0)), ("f3", _case(3.0))]
    records = run_cases_in_one_engine(cases, [tmp_path / "f2", tmp_path / "f3"])
    assert started == []
    assert [r["status"] for r in records] == ["ok", "ok"], records
    steps = [r["summary"]["steps"] for r in records]
    assert steps[0] == steps[1] > 0  # the same duration and the engine's one step
