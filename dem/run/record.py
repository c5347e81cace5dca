"""Record phase: frames, virtual instruments and VTK frames, each on its own time schedule.

Frames (frames.npz) are taken at the first step at or after every multiple of
``run.output_interval``, instrument samples likewise for ``run.instrument_interval`` (time-based,
so a change of dt during the run keeps the schedule; taken inside the engine's launches:
:class:`LaunchProbe`), a VTK frame at every ``run.vtk_every``-th frame.  On an engine that
takes them inside its launches (a device), the frames of a load phase in time are taken there
too, up to the end of each of the run loop's requests (:meth:`Recording.steps_to_next`).
Every recorded frame is also handed to the frame listeners (the collapse detector of a tilt
run), so what a listener saw is exactly what frames.npz holds.
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
# frames a request of a load phase in time, where the engine takes them inside its launches
# (Simulation.frames_in_launches: a device): the run loop looks between requests (stop signals,
# progress, checkpoints), so 10 frames (0.2 s of a shake at run.output_interval = 0.02 s, ~14 000
# Model II steps) keep it looking every few seconds on a GPU while a frame no longer ends the
# chunk of every scene of the engine
FRAMES_A_REQUEST = 10
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


class LaunchProbe:
    """What the recording takes inside the engine's launches (Simulation.set_probe), so that an
    engine of many scenes does not end its launch for every scene's every sample and frame.

    * The instruments' samples (from the load phase on): each is the state of the instruments'
      blocks at the step the run loop would have stopped at for it (the first step at or after
      the next multiple of ``run.instrument_interval``, counted from the last sample as
      :func:`steps_to` counts it).
    * With ``frames`` (a load phase in time that asked for several frames a request, on an
      engine that takes them inside its launches: Simulation.frames_in_launches), the frames
      before the end of the run loop's request (:meth:`Recording.steps_to_next`), each at the
      step the run loop would have stopped at for it (counted from the last frame as
      :func:`steps_to` counts it), with every block of the scene (the instruments' first);
      the frame at the request's end
      is the run loop's (:meth:`Recording.after_advance`), as ever.  A frame is a copy of the
      state at a step, so frames.npz is the same bit for bit however it was taken.

    :meth:`take` books the schedule at once (the next launch's :meth:`plan` starts from it)
    and keeps the rows; :meth:`flush` records them (the engine calls it while its next chunk
    runs, and before an advance returns: dem.engine.launcher.Launcher.flush_probes).
    """

    def __init__(self, recording: "Recording", frames: bool):
        self.recording = recording
        self.frames = frames
        blocks = recording.instruments.blocks if recording.instruments is not None else None
        # the instruments' blocks first, then (frames) every other block: a sample needs the
        # first n_sampled rows only (the engine then copies back no more: Launcher.take_probes)
        sampled = np.unique(blocks) if blocks is not None else np.zeros(0, dtype=int)
        self.n_sampled = len(sampled)
        self.bodies = sampled
        if frames:
            self.bodies = np.concatenate([sampled, np.setdiff1d(np.arange(recording.n),
                                                                sampled)])
        row_of = np.full(max(recording.n, int(self.bodies.max(initial=-1)) + 1), -1)
        row_of[self.bodies] = np.arange(len(self.bodies))  # body -> its row
        self.sample_rows = None if blocks is None else row_of[blocks]  # instrument -> row
        self.frame_rows = row_of[:recording.n] if frames else None  # block b's row
        # the request's frames: counted from from_step, up to (not at) end_step
        self.from_step = self.end_step = 0
        # the steps of the last plan, by kind (take tells a sample from a frame)
        self.sample_steps: set[int] = set()
        self.frame_steps: set[int] = set()
        # taken and booked, not recorded yet: (t, rows, a sample, a frame) in step order
        self.kept: list[tuple[float, np.ndarray, bool, bool]] = []

    def plan(self, clock, step: int, k: int) -> list[int]:
        """The step counts in step + 1 ... step + k at which a sample or a frame falls
        (Simulation's probe protocol), without changing the schedule: a launch may stop
        before them."""
        rec = self.recording
        self.sample_steps = set() if self.sample_rows is None else set(
            _schedule(clock, step, clock.time(step), rec.next_sample,
                      rec.run.instrument_interval, step + k + 1))
        self.frame_steps = set() if not self.frames else set(
            c for c in _schedule(clock, self.from_step, clock.time(self.from_step),
                                 rec.next_frame, rec.run.output_interval,
                                 min(step + k + 1, self.end_step)) if c > step)
        return sorted(self.sample_steps | self.frame_steps)

    def rows(self, step: int) -> int:
        """The rows of :attr:`bodies` that step count ``step`` (planned by the last plan)
        needs: a frame's every block, a sample's instruments' blocks."""
        return len(self.bodies) if step in self.frame_steps else self.n_sampled

    def take(self, step: int, t: float, rows: np.ndarray) -> None:
        """The state of step count ``step`` (time t, s): rows [bodies, 13] of pos, quat, vel,
        omega of :attr:`bodies` (kept, not copied), a sample, a frame or both: the next sample
        and frame booked, the rows kept for :meth:`flush`."""
        rec = self.recording
        sample, frame = step in self.sample_steps, step in self.frame_steps
        if sample:
            rec.next_sample = next_multiple(t, rec.run.instrument_interval)
        if frame:
            rec.next_frame = next_multiple(t, rec.run.output_interval)
            self.from_step = step
        self.kept.append((t, rows, sample, frame))

    def flush(self) -> None:
        """Record what :meth:`take` kept, in step order: the samples to the instruments, the
        frames to the recording."""
        rec = self.recording
        kept, self.kept = self.kept, []
        for t, rows, sample, frame in kept:
            with deferred():  # one sample and frame, whole (see Recording.frame)
                if sample:
                    r = rows[self.sample_rows]
                    # the table's motion at the samples' times, computed with their rows, for
                    # the samples of many launches at once (dem.instruments.InstrumentRecorder)
                    rec.instruments.sample_blocks(t, r[:, 0:3], r[:, 3:7], r[:, 7:10],
                                                  r[:, 10:13], rec.loading.base_disp,
                                                  rec.loading.base_vel)
                if frame:
                    f = rows[self.frame_rows]  # in block order
                    rec.frame_of(t, f[:, 0:3], f[:, 3:7], f[:, 7:10], f[:, 10:13])


def _schedule(clock, c: int, t_c: float, t_next: float, interval: float, before: int):
    """The steps after step c (time t_c) at which a schedule of ``interval`` whose next time is
    ``t_next`` takes its state, as a run loop that stops at each would find them (each the first
    step at or after its time, :func:`steps_to` from the last), up to step ``before``
    (excluded)."""
    while True:
        c += max(1, int(math.ceil((t_next - t_c) / clock.dt - 1e-9)))
        if c >= before:
            return
        t_c = clock.time(c)
        if t_c >= t_next - 1e-9 * clock.dt:
            yield c
            t_next = next_multiple(t_c, interval)


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
        st = self.sim.read_state(*RECORDED)
        n = self.n
        self._record(self.sim.t, st.pos[:n], st.quat[:n], st.vel[:n], st.omega[:n])

    def frame_of(self, t: float, pos, quat, vel, omega) -> None:
        """Record the frame of time t (s) from the scene's blocks' rows (a frame taken inside a
        launch: :class:`LaunchProbe`, which holds back a stop signal meanwhile and books the
        next frame when it takes the rows)."""
        self._record(t, pos, quat, vel, omega)

    def _record(self, t: float, pos, quat, vel, omega) -> None:
        loading = self.loading
        extra = {}
        if isinstance(loading, Tilt):
            extra["tilt_angle"] = float(loading.angle(t)[0])
        base = loading.base_disp(np.array([t]))[0]
        if self.vtk is not None and self.frames.n_frames % self.run.vtk_every == 0:
            self.vtk.add_frame(t, pos, quat, vel, base,
                               contacts=self.sim.active_contact_points() if self.run.contacts
                               else None)
        self.frames.add(t, pos, quat, vel, omega, base, **extra)
        for listen in self.listeners:
            listen(t, extra.get("tilt_angle", 0.0), pos, quat, vel, omega)

    def sample(self) -> None:
        with deferred():  # one sample, whole (see frame)
            self._sample()

    def _sample(self) -> None:
        sim, loading = self.sim, self.loading
        st = sim.read_state(*RECORDED)
        tt = np.array([sim.t])
        self.instruments.sample(sim.t, st.pos, st.quat, st.vel, st.omega,
                                loading.base_disp(tt)[0], loading.base_vel(tt)[0])

    def steps_to_next(self, t_end: float, frames: int = 1) -> int:
        """Steps to the next frame or the end, whichever comes first (the load phase's
        requests); with ``frames`` > 1, to the ``frames``-th next frame or the end, where the
        engine takes the frames between inside its launches (Simulation.frames_in_launches,
        and no VTK frame needs the contacts, which a probe does not copy).  The instrument
        samples between are taken inside the engine's launches (:class:`LaunchProbe`,
        installed here: from the load phase on, not while settling); so are those frames."""
        sim = self.sim
        many = frames > 1 and sim.frames_in_launches and not (self.vtk is not None
                                                              and self.run.contacts)
        if sim.probe is None and (self.instruments is not None or many):
            sim.set_probe(LaunchProbe(self, frames=many))
        if not many or not sim.probe.frames:
            return steps_to(sim, min(self.next_frame, t_end))
        # the request ends at the frames-th frame (or the end), each step found as the run
        # loop would find it stopping at every frame (steps_to from the last one)
        probe, clock, c = sim.probe, sim.clock, sim.step_count
        t_c, t_next = clock.time(c), self.next_frame
        for _ in range(frames):
            c += max(1, int(math.ceil((min(t_next, t_end) - t_c) / clock.dt - 1e-9)))
            t_c = clock.time(c)
            if t_c >= t_end - 1e-12 * t_end:  # the run's end (dem.run.stop.StopRule.at_end)
                break
            if t_c >= t_next - 1e-9 * clock.dt:
                t_next = next_multiple(t_c, self.run.output_interval)
        probe.from_step, probe.end_step = sim.step_count, c
        return c - sim.step_count

    def after_advance(self, last: bool) -> bool:
        """Take what is due at the engine's time (the samples, and the frames before the
        request's end where the engine can, are taken in the launches: :class:`LaunchProbe`);
        True when a frame was recorded."""
        sim = self.sim
        t = self.frames.cols["t"]
        if t and t[-1] >= sim.t:  # taken inside the launch (a step limit cut the request there)
            return True
        if sim.t >= self.next_frame - 1e-9 * sim.dt or last:
            self.next_frame = next_multiple(sim.t, self.run.output_interval)
            self.frame()
            return True
        return False

    def frame_at_stop(self) -> None:
        """The state where the run stopped, so frames.npz ends at summary's sim_time."""
        if not self.frames.cols["t"] or self.sim.t > self.frames.cols["t"][-1]:
            self.frame()
