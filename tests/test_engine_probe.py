"""Probes (Simulation.set_probe): bodies' states copied inside a launch at chosen steps,
so that an instrument sample no longer ends the launch of every scene of an engine.  A probed
row must be the state the scene has at that step count, as a run that stops there reads it;
probing must not change the trajectory; a launch with more probed steps than slots, a failing
scene and a frozen one must lose nothing and take nothing false."""

from __future__ import annotations

import json

import numpy as np
import pytest

from dem.case import Case
from dem.engine.containers import PROBES_PER_SCENE
from dem.engine.errors import InputError
from dem.engine.simulation import Engine
from dem.engine.residency import DEVICE_CHUNK
from dem.instruments import InstrumentRecorder, thesis_instruments
from dem.run.loop import run_case
from tests.test_batched_runs import SMALL_BOX
from tests.test_engine_batch import JOINTS, assert_same, options, shake, wall


class StepProbe:
    """Probe ``bodies`` after the step counts ``steps`` (the protocol of Simulation.set_probe)."""

    def __init__(self, bodies, steps):
        self.bodies = np.asarray(bodies)
        self.steps = sorted(steps)
        self.taken: list[tuple[int, float, np.ndarray]] = []

    def plan(self, clock, step, k):
        return [c for c in self.steps if step < c <= step + k]

    def take(self, step, t, rows):
        self.taken.append((step, t, rows))


def _rows(sim, bodies) -> np.ndarray:
    st = sim.read_state("pos", "quat", "vel", "omega")
    return np.hstack([st.pos[bodies], st.quat[bodies], st.vel[bodies], st.omega[bodies]])


BODIES = [0, 3, 7, 11]
# single steps, two probes in consecutive steps, 41 probes in a row (more than a launch's
# slots: the launch is cut), and probes across a launch's end (the serial kernel's 2000 steps,
# the device path's chunks: dem.engine.residency.DEVICE_CHUNK)
STEPS = {"serial": [1, 5, 17, 18, *range(100, 141), 1999, 2000, 2001, 2600],
         "parallel": [1, 5, 17, 18, *range(100, 141), DEVICE_CHUNK - 1, DEVICE_CHUNK,
                      DEVICE_CHUNK + 1, DEVICE_CHUNK + 344]}


@pytest.mark.parametrize("mode,device", [("serial", False), ("parallel", False),
                                         ("parallel", True)])
def test_probed_rows_are_the_states_at_those_steps(mode, device):
    """Two walls shaken differently in one engine, one probed: each row equals the state the
    same engine reaches when it is advanced to that step count and read, bit for bit; the
    final states are the same as without the probe."""
    loads = [shake(4.0, 7.0), shake(6.0, 8.0, axis=1)]
    probed = Engine([wall() for _ in loads], JOINTS, options(mode=mode), device_arrays=device)
    stops = Engine([wall() for _ in loads], JOINTS, options(mode=mode), device_arrays=device)
    steps = STEPS[mode]
    n_steps = steps[-1] + 100
    probe = StepProbe(BODIES, steps)
    probed.simulations[0].set_probe(probe)
    probed.advance(n_steps, loads)
    assert [s for s, _, _ in probe.taken] == steps  # every one, in order, once
    a = stops.simulations[0]
    for step, t, rows in probe.taken:
        stops.advance(step - a.step_count, loads)
        assert a.step_count == step and t == a.t
        assert np.array_equal(rows, _rows(a, BODIES)), step
    stops.advance(n_steps - a.step_count, loads)
    for x, y in zip(probed.simulations, stops.simulations):
        assert_same(x, y)
    assert probed.n_chunks < stops.n_chunks  # the probes did not end the launches


def test_a_failing_scene_gives_no_row_of_its_failing_step_and_its_mate_goes_on():
    """A wall shaken far above max_speed fails in the batch: its probes stop before the failing
    step (that state is not a result); its batch-mate's probes all come."""
    loads = [shake(4.0, 300.0), shake(6.0, 8.0, axis=1)]
    engine = Engine([wall() for _ in loads], JOINTS, options(max_speed=0.5))
    every = [StepProbe(BODIES, range(1, 1501)) for _ in loads]
    for sim, probe in zip(engine.simulations, every):
        sim.set_probe(probe)
    engine.advance(1500, loads)
    bad, good = engine.simulations
    assert bad.failure is not None and good.failure is None
    assert 1 < bad.step_count < 1500
    assert [s for s, _, _ in every[0].taken] == list(range(1, bad.step_count))
    assert [s for s, _, _ in every[1].taken] == list(range(1, 1501))


class KeepingProbe(StepProbe):
    """A StepProbe that keeps what it takes until its ``flush()`` (as
    dem.run.record.LaunchProbe does), noting the engine's stepping launches at each."""

    def __init__(self, engine, bodies, steps):
        super().__init__(bodies, steps)
        self.launcher = engine.launcher
        self.kept: list[tuple[int, int]] = []  # (step, launches when taken)
        self.flushed: list[tuple[int, int, int]] = []  # (step, ... taken, ... flushed)

    def take(self, step, t, rows):
        super().take(step, t, rows)
        self.kept.append((step, self.launcher.n_launches))

    def flush(self):
        n = self.launcher.n_launches
        self.flushed += [(step, taken, n) for step, taken in self.kept]
        self.kept = []


def _until(load, t_max):
    """``load`` that raises for a time past t_max (s)."""
    def loads(t):
        if t[-1] > t_max:
            raise RuntimeError("past t_max")
        return load(t)
    return loads


@pytest.mark.parametrize("mode,device", [("serial", False), ("parallel", True)])
def test_a_probe_records_a_chunk_while_the_next_runs_and_all_before_an_advance_returns(
        mode, device):
    """A probe's flush (Launcher.flush_probes) comes once the next chunk's launches are
    queued, so that on a device the recording's Python runs while the GPU steps; the last
    chunk's at the advance's end, so that its caller finds every probed step recorded, and
    also where the advance stops on an error (a load function's, raised while the second
    chunk's launches run: the first chunk's steps are recorded, none taken after)."""
    engine = Engine([wall()], JOINTS, options(mode=mode), device_arrays=device)
    chunk = engine.control.loads.shape[0]
    steps = [5, chunk + 5, 2 * chunk + 5, 3 * chunk]  # one in each of the three chunks
    probe = KeepingProbe(engine, BODIES, steps)
    engine.simulations[0].set_probe(probe)
    engine.advance(3 * chunk, [shake(4.0, 1.0)])
    assert engine.launcher.n_chunks == 3 and probe.kept == []
    assert [s for s, _, _ in probe.flushed] == steps
    for step, taken, flushed in probe.flushed:
        if step <= 2 * chunk:  # during the next chunk, its launches queued
            assert flushed > taken, step
        else:  # at the advance's end
            assert flushed == taken, step
    stopped = Engine([wall()], JOINTS, options(mode=mode), device_arrays=device)
    probe = KeepingProbe(stopped, BODIES, steps)
    stopped.simulations[0].set_probe(probe)
    with pytest.raises(RuntimeError, match="past t_max"):  # the third chunk's loads
        stopped.advance(3 * chunk, [_until(shake(4.0, 1.0), (2 * chunk + 0.5) * stopped.dt)])
    assert probe.kept == [] and [s for s, _, _ in probe.flushed] == steps[:1]


def test_set_probe_refuses_bodies_it_cannot_take_and_none_removes_it():
    engine = Engine([wall(), wall()], JOINTS, options())
    sim = engine.simulations[1]
    with pytest.raises(InputError, match=f"at most {PROBES_PER_SCENE} bodies"):
        sim.set_probe(StepProbe(range(PROBES_PER_SCENE + 1), [1]))
    n = sim.n_blocks + 1  # the bricks and the table
    with pytest.raises(InputError, match=f"0 ... {n - 1}"):
        sim.set_probe(StepProbe([n], [1]))
    probe = StepProbe([2], [3])
    sim.set_probe(probe)
    assert engine.control.probe_body[1, 0] == engine.model.scene_bodies[1][0] + 2
    sim.set_probe(None)
    assert (engine.control.probe_body == -1).all()
    engine.advance(10, [shake(4.0, 1.0)] * 2)
    assert probe.taken == []


def test_instrument_samples_are_the_frames_states_where_their_times_meet(tmp_path):
    """A run whose instruments sample at the frames' interval: every sample is what the
    instruments read from the frame of the same time (the same step), bit for bit, for
    displacement and velocity (the acceleration differences the previous sample)."""
    data = json.loads(json.dumps(SMALL_BOX))
    data["run"]["instrument_interval"] = data["run"]["output_interval"]
    data.pop("imperfections")  # no settling: the probes run from the first step
    case = Case.model_validate(data)
    res = run_case(case, tmp_path / "run")
    ins = np.load(tmp_path / "run" / "instruments.npz")
    frames = np.load(tmp_path / "run" / "frames.npz")
    assert len(ins["t"]) == len(frames["t"]) >= 40 and np.array_equal(ins["t"], frames["t"])
    recorder = InstrumentRecorder(thesis_instruments(res.scene, "y"), res.scene)
    assert [i.name for i in recorder.instruments] == list(ins["names"])
    for k, t in enumerate(frames["t"]):  # the table's motion does not enter disp and vel
        recorder.sample(t, frames["pos"][k], frames["quat"][k], frames["vel"][k],
                        frames["omega"][k], np.zeros(3), np.zeros(3))
    again = recorder.arrays()
    assert np.array_equal(again["disp"], ins["disp"]) and np.array_equal(again["vel"], ins["vel"])
