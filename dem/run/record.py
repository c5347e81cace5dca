"""Record phase: frames, virtual instruments and VTK frames, each on its own time schedule.

Frames (frames.npz) are taken at the first step at or after every multiple of
``run.output_interval``, instrument samples likewise for ``run.instrument_interval`` (time-based,
so a change of dt during the run keeps the schedule; taken inside the engine's launches:
:class:`InstrumentProbe`), a VTK frame at every ``run.vtk_every``-th frame.  Every recorded
frame is also handed to the frame listeners (the collapse detector of a tilt run), so what a
listener saw is exactly what frames.npz holds.
"""

from __future__ import annotations

import math
from pathlib import Path
from typing import Callable

import numpy as np

from dem.case import Case
from dem.instruments import InstrumentRecorder, thesis_instruments
from dem.loading import Loading, Record, Shake, Tilt
from dem.output import atomic
from dem.scene import Scene
from dem.signals import deferred
from dem.units import FRAMES_UNITS, npz_units

FRAME_KEYS = ("t", "pos", "quat", "vel", "omega", "base_disp")
# the State fields a frame and an instrument sample read (Simulation.read_state: on a device,
# copied to the host only where stale, never back)
RECORDED = ("pos", "quat", "vel", "omega")


class FrameRecorder:
    """Frames in memory, flushed to ``frames.npz`` atomically."""

    def __init__(self, out_dir: Path | None):
        self.out_dir = out_dir
        self.cols: dict[str, list] = {k: [] for k in FRAME_KEYS}
        self.extra: dict[str, list] = {}

    def add(self, t, pos, quat, vel, omega, base_disp, **extra) -> None:
        self.cols["t"].append(float(t))
        self.cols["pos"].append(np.array(pos))
        self.cols["quat"].append(np.array(quat))
        self.cols["vel"].append(np.array(vel))
        self.cols["omega"].append(np.array(omega))
        self.cols["base_disp"].append(np.array(base_disp, dtype=float).reshape(3))
        for k, v in extra.items():
            self.extra.setdefault(k, []).append(v)

    @property
    def n_frames(self) -> int:
        return len(self.cols["t"])

    def arrays(self) -> dict[str, np.ndarray]:
        out = {k: np.asarray(v) for k, v in self.cols.items()}
        out.update({k: np.asarray(v) for k, v in self.extra.items()})
        return out

    def write(self) -> None:
        """frames.npz, uncompressed: it is rewritten whole at every checkpoint, and the
        states of moving blocks barely compress (Model II, 944 frames: 21.3 MB plain, 20.0 MB
        compressed, 50 times slower to write, ~1 s a checkpoint; benchmarks/checkpoint_cost.py)."""
        if self.out_dir is None or not self.cols["t"]:
            return
        arrays = self.arrays()
        arrays["units"] = npz_units(arrays, FRAMES_UNITS)  # (key, unit) rows: dem.units
        atomic.save_npz(self.out_dir / "frames.npz", arrays, compressed=False)


def thesis_instrument_axis(loading: Loading) -> str:
    """The axis ("x", "y" or "xy") the thesis' instrument layout follows for a loading: the
    shaking direction, the axes a record really moves (components above 30 % of the largest),
    else y."""
    if isinstance(loading, Shake):
        d = np.abs(loading.direction)
    elif isinstance(loading, Record):
        d = np.abs(loading.acc).max(axis=0)
        d = np.where(d >= 0.3 * d.max(), d, 0.0)
    else:
        d = np.array([0.0, 1.0, 0.0])
    return "xy" if d[0] > 1e-9 and d[1] > 1e-9 else ("x" if d[0] > d[1] else "y")


def choose_instruments(case: Case, scene: Scene, loading: Loading) -> InstrumentRecorder | None:
    """``run.instruments``: "thesis" places the thesis' instruments (dem.instruments), "none"
    none, "auto" the thesis' ones on a shaken scene with the box models' wall groups (L1, L2,
    T1, T2), else none."""
    choice = case.run.instruments
    if choice == "auto":
        boxy = {"L1", "L2", "T1", "T2"} <= set(scene.group_names)
        choice = "thesis" if boxy and isinstance(loading, (Shake, Record)) else "none"
    if choice != "thesis":
        return None
    return InstrumentRecorder(thesis_instruments(scene, thesis_instrument_axis(loading)), scene,
                              table_velocity=loading.records_table_velocity())


def steps_to(sim, t_target: float) -> int:
    """Steps from the engine's time to the first step at or after ``t_target`` (at least 1)."""
    return max(1, int(math.ceil((t_target - sim.t) / sim.dt - 1e-9)))


def next_multiple(t: float, interval: float) -> float:
    return (math.floor(t / interval + 1e-9) + 1) * interval


class InstrumentProbe:
    """The instruments' samples taken inside the engine's launches (Simulation.set_probe): the
    run loop then advances from frame to frame, and each sample is the state of the instruments'
    blocks at the step the run loop would have stopped at for it (the first step at or after
    the next multiple of ``run.instrument_interval``, counted from the last sample as
    :func:`steps_to` counts it); one launch covers many samples (so that an engine of many
    scenes does not end its launch for every scene's every sample)."""

    def __init__(self, recording: "Recording"):
        self.recording = recording
        blocks = recording.instruments.blocks
        self.bodies = np.unique(blocks)
        self.rows = np.searchsorted(self.bodies, blocks)  # instrument -> row of the probe

    def plan(self, clock, step: int, k: int) -> list[int]:
        """The step counts in step + 1 ... step + k at which a sample falls (Simulation's
        probe protocol), without changing the schedule: a launch may stop before them."""
        interval = self.recording.run.instrument_interval
        t_next, c, t_c, out = self.recording.next_sample, step, clock.time(step), []
        while True:
            c += max(1, int(math.ceil((t_next - t_c) / clock.dt - 1e-9)))
            if c > step + k:
                return out
            t_c = clock.time(c)
            if t_c >= t_next - 1e-9 * clock.dt:
                out.append(c)
                t_next = next_multiple(t_c, interval)

    def take(self, step: int, t: float, rows: np.ndarray) -> None:
        """The sample of step count ``step`` (time t, s): rows [bodies, 13] of pos, quat, vel,
        omega."""
        rec = self.recording
        r = rows[self.rows]
        with deferred():  # one sample, whole (see Recording.frame)
            # the table's motion at the samples' times, computed with their rows, for the
            # samples of many launches at once (dem.instruments.InstrumentRecorder)
            rec.instruments.sample_blocks(t, r[:, 0:3], r[:, 3:7], r[:, 7:10], r[:, 10:13],
                                          rec.loading.base_disp, rec.loading.base_vel)
            rec.next_sample = next_multiple(t, rec.run.instrument_interval)


class Recording:
    """Everything a run keeps while it runs (frames, instruments, VTK) and when it takes it."""

    def __init__(self, case: Case, scene: Scene, loading: Loading, sim, out: Path | None):
        self.run = case.run
        self.loading = loading
        self.sim = sim
        self.n = scene.n_blocks
        self.frames = FrameRecorder(out)
        self.instruments = choose_instruments(case, scene, loading)
        self.vtk = None
        if out is not None and case.run.vtk:
            from dem.output.vtk import VtkSeries
            self.vtk = VtkSeries(out, scene, write_contacts=case.run.contacts)
        self.listeners: list[Callable[..., None]] = []
        self.next_frame = case.run.output_interval
        self.next_sample = case.run.instrument_interval

    def frames_from(self, t: float) -> None:
        """Take the next frame ``run.output_interval`` after ``t`` (a load phase that does not
        advance in time, the quasi-static tilt, hands the schedule back to the clock)."""
        self.next_frame = t + self.run.output_interval

    def start(self) -> None:
        """The frame (and instrument sample) at the start."""
        self.frame()
        if self.instruments is not None:
            self.sample()

    def frame(self) -> None:
        """Record one frame, whole: a stop signal that arrives meanwhile is raised after it
        (dem.signals.deferred), so frames.npz, the VTK series and the listeners stay in step."""
        with deferred():
            self._frame()

    def _frame(self) -> None:
        sim, n, loading = self.sim, self.n, self.loading
        st, t = sim.read_state(*RECORDED), sim.t
        extra = {}
        if isinstance(loading, Tilt):
            extra["tilt_angle"] = float(loading.angle(t)[0])
        base = loading.base_disp(np.array([t]))[0]
        if self.vtk is not None and self.frames.n_frames % self.run.vtk_every == 0:
            self.vtk.add_frame(t, st.pos[:n], st.quat[:n], st.vel[:n], base,
                               contacts=sim.active_contact_points() if self.run.contacts
                               else None)
        self.frames.add(t, st.pos[:n], st.quat[:n], st.vel[:n], st.omega[:n], base, **extra)
        for listen in self.listeners:
            listen(t, extra.get("tilt_angle", 0.0), st.pos[:n], st.quat[:n], st.vel[:n],
                   st.omega[:n])

    def sample(self) -> None:
        with deferred():  # one sample, whole (see frame)
            self._sample()

    def _sample(self) -> None:
        sim, loading = self.sim, self.loading
        st = sim.read_state(*RECORDED)
        tt = np.array([sim.t])
        self.instruments.sample(sim.t, st.pos, st.quat, st.vel, st.omega,
                                loading.base_disp(tt)[0], loading.base_vel(tt)[0])

    def steps_to_next(self, t_end: float) -> int:
        """Steps to the next frame or the end, whichever comes first (the load phase's
        requests).  The instrument samples between are taken inside the engine's launches
        (:class:`InstrumentProbe`, installed here: from the load phase on, not while settling)."""
        if self.instruments is not None and self.sim.probe is None:
            self.sim.set_probe(InstrumentProbe(self))
        return steps_to(self.sim, min(self.next_frame, t_end))

    def after_advance(self, last: bool) -> bool:
        """Take what is due at the engine's time (the samples are taken in the launches:
        :class:`InstrumentProbe`); True when a frame was recorded."""
        sim = self.sim
        if sim.t >= self.next_frame - 1e-9 * sim.dt or last:
            self.next_frame = next_multiple(sim.t, self.run.output_interval)
            self.frame()
            return True
        return False

    def frame_at_stop(self) -> None:
        """The state where the run stopped, so frames.npz ends at summary's sim_time."""
        if not self.frames.cols["t"] or self.sim.t > self.frames.cols["t"][-1]:
            self.frame()
