"""Loads versus time, in the table's frame (pure numpy; the kernels receive sampled values).

Every loading gives, for an array of times t (s):
    gravity(t)       [K,3]  m/s^2  gravity as seen in the table frame
    base_accel(t)    [K,3]  m/s^2  acceleration of the table; each block feels -m a_base
    base_disp(t)     [K,3]  m      displacement of the table (reported with the frames)
    base_vel(t)      [K,3]  m/s    velocity of the table

Tilt (DESIGN.md "Model only what a scene needs"): the table turns by theta(t) about a
horizontal axis; instead of moving the table, gravity turns the other way:
g_table = R(axis, theta)^T g.  theta(t) = min(start + rate t, max_angle), optionally in steps
with holds and after a smooth approach to the start angle (see dem.case.TiltLoading).
Record: any sampled table acceleration (dem.case.RecordLoading), integrated from rest.
Shake: the table moves by u(t) d along the direction d (used as given), with the sinusoidal
u(t) = A sin(2 pi f t) of dem.table_motion (shared with the two-body model): a(t) = u''(t) while
it shakes (0 <= t < T = cycles / f); after T, a = 0 and the table keeps its final velocity
(u, v the exact integrals of the applied a(t); see dem.table_motion for why it is not stopped).
The velocity jump to A w at t = 0 is not applied as an impulse: the blocks, in the table frame,
feel only -m a(t) (``start: table-frame``, the default).  ``start: lab`` applies it: at t = 0
every free block takes the velocity -A w d relative to the table (:meth:`Loading.
initial_relative_velocity`, applied once after settling by dem.run.table_start); ``start: ramp``
raises the amplitude smoothly so that there is no jump (dem.table_motion).  ``distortion`` adds
the table's own third harmonic and reversal spikes to the sine
(dem.table_motion.DistortedSineMotion).
Stepped shake (SteppedShake): the frequency steps through a list on one specimen
(dem.table_motion.SteppedSineMotion), base quantities along d as for the shake.  Sine sweep
(Sweep) and band-limited white noise (Noise): dem.table_motion.SweepMotion / NoiseMotion along
d, started and ended at rest by tapers (no velocity jump: nothing for the blocks to take).
A shake whose period is shorter than 20 time steps, or a record that ends before the run with
the table still moving, is refused by dem.validate.
"""

from __future__ import annotations

import numpy as np
from scipy.spatial.transform import Rotation

from dem.case import (Case, NoiseLoading, NoLoading, RecordLoading, ShakeLoading,
                      SteppedShakeLoading, SweepLoading, TiltLoading)
from dem.table_motion import DistortedSineMotion, SineMotion

AXES = {"x": (1.0, 0.0, 0.0), "y": (0.0, 1.0, 0.0), "-x": (-1.0, 0.0, 0.0), "-y": (0.0, -1.0, 0.0)}


class Loading:
    kind = "none"
    # a loading does not change once made (its value decides its loads); HeldTilt, turned by a
    # controller between advances, says otherwise (dem.run.batched.shared_loads reads this)
    immutable = True

    def __init__(self, g0):
        self.g0 = np.asarray(g0, dtype=float)

    def gravity(self, t: np.ndarray) -> np.ndarray:
        return np.tile(self.g0, (len(np.atleast_1d(t)), 1))

    def base_accel(self, t: np.ndarray) -> np.ndarray:
        return np.zeros((len(np.atleast_1d(t)), 3))

    def base_disp(self, t: np.ndarray) -> np.ndarray:
        return np.zeros((len(np.atleast_1d(t)), 3))

    def base_vel(self, t: np.ndarray) -> np.ndarray:
        return np.zeros((len(np.atleast_1d(t)), 3))

    def initial_relative_velocity(self) -> np.ndarray:
        """[3] m/s: the velocity every free block takes relative to the table at t = 0, when
        the loading starts (after settling): minus the table's velocity jump at t = 0, which a
        body at rest in the lab keeps through that instant (``start: lab``); zero otherwise."""
        return np.zeros(3)

    def records_table_velocity(self) -> bool:
        """Whether the instruments also record the table's velocity (``table_vel``): for the
        lab and ramp starts and stepped shakes, whose table velocity is not the plain sine's (a
        default shake's instruments.npz keeps its fields)."""
        return False

    def __call__(self, t: np.ndarray):
        """(gravity [K,3], base acceleration [K,3]) at times t: the engine's load callback."""
        return self.gravity(t), self.base_accel(t)

    def describe(self) -> dict:
        return {"type": self.kind}


class Tilt(Loading):
    kind = "tilt"

    def __init__(self, g0, axis, rate_deg: float, max_angle_deg: float, start_angle_deg=0.0,
                 step_deg: float | None = None, hold_s: float = 0.0, start_time_s: float = 0.0):
        super().__init__(g0)
        a = np.asarray(AXES[axis] if isinstance(axis, str) else axis, dtype=float)
        self.axis = a / np.linalg.norm(a)
        self.rate = float(rate_deg)
        self.max_angle = float(max_angle_deg)
        self.start_angle = float(start_angle_deg)
        self.step = step_deg
        self.hold = float(hold_s)
        self.start_time = float(start_time_s)

    @property
    def load_direction(self) -> np.ndarray:
        """Unit vector of the lateral load in the table frame: axis x z."""
        return np.cross(self.axis, [0.0, 0.0, 1.0])

    def angle(self, t) -> np.ndarray:
        """Tilt angle (degrees) at times t: ramps at ``rate``, in steps with holds if asked."""
        t = np.atleast_1d(np.asarray(t, dtype=float))
        ts = np.maximum(t - self.start_time, 0.0)  # time since the start angle was reached
        if self.step is None or self.hold == 0.0:
            rise = self.rate * ts
        else:
            period = self.step / self.rate + self.hold
            n = np.floor(ts / period)
            rise = n * self.step + np.minimum(self.rate * (ts - n * period), self.step)
        angle = self.start_angle + rise
        if self.start_time > 0.0:
            s = np.clip(t / self.start_time, 0.0, 1.0)
            angle = np.where(t < self.start_time, self.start_angle * s * s * (3 - 2 * s), angle)
        return np.minimum(angle, self.max_angle)

    def gravity(self, t):
        theta = np.radians(self.angle(t))
        rot = Rotation.from_rotvec(-theta[:, None] * self.axis[None, :])
        return rot.apply(self.g0)

    def describe(self):
        return {"type": "tilt", "axis": self.axis.tolist(), "rate_deg_per_s": self.rate,
                "max_angle_deg": self.max_angle, "start_angle_deg": self.start_angle,
                "step_deg": self.step, "hold_s": self.hold, "start_time_s": self.start_time,
                "load_direction": self.load_direction.tolist()}


class HeldTilt(Tilt):
    """A tilt whose angle is set by a controller (the quasi-static tilt, dem.run.quasi_static):
    ``turn(t0, a1, ramp)`` turns the table from its angle at t0 to a1 over ``ramp`` s
    (smoothstep), then holds it."""

    immutable = False  # turned between advances

    def __init__(self, g0, axis, max_angle_deg: float, start_angle_deg: float = 0.0):
        super().__init__(g0, axis, 0.0, max_angle_deg, start_angle_deg)
        self._t0, self._a0, self._a1, self._ramp = 0.0, self.start_angle, self.start_angle, 0.0

    def turn(self, t0: float, a1: float, ramp: float) -> None:
        self._a0 = float(self.angle(t0)[0])
        self._t0, self._a1, self._ramp = float(t0), float(a1), float(ramp)

    def angle(self, t) -> np.ndarray:
        t = np.atleast_1d(np.asarray(t, dtype=float))
        if self._ramp <= 0.0:
            return np.full(t.shape, self._a1)
        s = np.clip((t - self._t0) / self._ramp, 0.0, 1.0)
        return self._a0 + (self._a1 - self._a0) * s * s * (3 - 2 * s)

    def describe(self):
        out = super().describe()
        out.update({"method": "quasi_static", "rate_deg_per_s": None})
        return out


class Shake(Loading):
    """The table shaking along ``direction``: base quantities = SineMotion quantities x direction."""

    kind = "shake"

    def __init__(self, g0, direction, frequency: float, amplitude: float, cycles: float,
                 start: str = "table-frame", ramp_cycles: float | None = None,
                 distortion: dict | None = None):
        super().__init__(g0)
        self.direction = np.asarray(direction, dtype=float)
        if distortion:   # the table's waveform (keyword arguments of DistortedSineMotion)
            self.motion = DistortedSineMotion(amplitude, frequency, cycles, start, ramp_cycles,
                                              **distortion)
        else:
            self.motion = SineMotion(amplitude, frequency, cycles, start, ramp_cycles)

    def initial_relative_velocity(self) -> np.ndarray:
        """-v_jump d, m/s: v_jump = A w for a ``lab`` start (dem.table_motion), else 0."""
        return -self.motion.velocity_jump * self.direction

    def records_table_velocity(self) -> bool:
        return self.motion.start != "table-frame" or isinstance(self, SteppedShake) or \
            isinstance(self.motion, DistortedSineMotion)

    @property
    def t_end(self) -> float:
        """End of the shaking, s (no table acceleration from then on)."""
        return self.motion.t_end

    def _along(self, q) -> np.ndarray:
        return q[:, None] * self.direction[None, :]

    def base_disp(self, t):
        return self._along(self.motion.displacement(np.atleast_1d(t)))

    def base_vel(self, t):
        return self._along(self.motion.velocity(np.atleast_1d(t)))

    def base_accel(self, t):
        return self._along(self.motion.acceleration(np.atleast_1d(t)))

    def describe(self):
        return {"type": "shake", "direction": self.direction.tolist(), **self.motion.describe()}


class SteppedShake(Shake):
    """The table shaking along ``direction`` with stepped frequencies (SteppedSineMotion x
    direction; a Shake for everything that asks for one: instruments, analysis of the axes)."""

    kind = "stepped_shake"

    def __init__(self, g0, direction, motion):
        Loading.__init__(self, g0)
        self.direction = np.asarray(direction, dtype=float)
        self.motion = motion

    def describe(self):
        return {"type": "stepped_shake", "direction": self.direction.tolist(),
                **self.motion.describe()}


class Sweep(SteppedShake):
    """A sine sweep along ``direction`` (dem.table_motion.SweepMotion x direction; a Shake for
    the instruments and the axes, as a stepped shake)."""

    kind = "sweep"

    def records_table_velocity(self) -> bool:
        return True

    def describe(self):
        return {"type": self.kind, "direction": self.direction.tolist(),
                **self.motion.describe()}


class Noise(Sweep):
    """Band-limited white noise along ``direction`` (dem.table_motion.NoiseMotion x
    direction)."""

    kind = "noise"


class Record(Loading):
    """Table acceleration from samples, linear in between and zero outside the record; the
    velocity and displacement are its exact integrals from rest (per interval of length h with
    slope s = (a_k+1 - a_k)/h:  v = v_k + a_k tau + s tau^2/2,  u = u_k + v_k tau + a_k tau^2/2
    + s tau^3/6)."""

    kind = "record"

    def __init__(self, g0, t, acc):
        super().__init__(g0)
        self.t = np.asarray(t, dtype=float)
        self.acc = np.asarray(acc, dtype=float)
        # the table is at rest at t = 0: a record that starts later starts from zero
        if self.t[0] > 0.0:
            self.t = np.concatenate([[0.0], self.t])
            self.acc = np.vstack([np.zeros((1, 3)), self.acc])
        h = np.diff(self.t)[:, None]
        a0, a1 = self.acc[:-1], self.acc[1:]
        dv = 0.5 * (a0 + a1) * h
        self.vel = np.vstack([np.zeros((1, 3)), np.cumsum(dv, axis=0)])
        du = self.vel[:-1] * h + h**2 * (2 * a0 + a1) / 6.0
        self.disp = np.vstack([np.zeros((1, 3)), np.cumsum(du, axis=0)])
        self.t_end = float(self.t[-1])

    def _at(self, t):
        """Interval index k, offset tau (clipped to the record), and t past the end."""
        t = np.atleast_1d(np.asarray(t, dtype=float))
        tc = np.clip(t, self.t[0], self.t_end)
        k = np.clip(np.searchsorted(self.t, tc, side="right") - 1, 0, len(self.t) - 2)
        tau = (tc - self.t[k])[:, None]
        h = (self.t[k + 1] - self.t[k])[:, None]
        slope = (self.acc[k + 1] - self.acc[k]) / h
        return k, tau, slope, np.maximum(t - self.t_end, 0.0)[:, None]

    def base_accel(self, t):
        k, tau, slope, after = self._at(t)
        return np.where(after > 0.0, 0.0, self.acc[k] + slope * tau)

    def base_vel(self, t):
        k, tau, slope, _ = self._at(t)
        return self.vel[k] + self.acc[k] * tau + 0.5 * slope * tau**2

    def base_disp(self, t):
        k, tau, slope, after = self._at(t)
        u = self.disp[k] + self.vel[k] * tau + 0.5 * self.acc[k] * tau**2 + slope * tau**3 / 6.0
        return u + after * self.vel[-1]

    def describe(self):
        return {"type": "record", "samples": len(self.t), "duration_s": self.t_end,
                "peak_acceleration_m_s2": float(np.abs(self.acc).max())}


def loading_from_case(case: Case) -> Loading:
    g0 = case.gravity_vector()
    ld = case.loading
    if isinstance(ld, TiltLoading) and ld.method == "quasi_static":
        return HeldTilt(g0, ld.axis, ld.max_angle, ld.start_angle)
    if isinstance(ld, TiltLoading):
        return Tilt(g0, ld.axis, ld.rate, ld.max_angle, ld.start_angle, ld.step, ld.hold,
                    ld.start_time)
    if isinstance(ld, ShakeLoading):
        return Shake(g0, ld.direction, ld.frequency, ld.displacement_amplitude, ld.cycles,
                     ld.start, ld.ramp_cycles, ld.distortion_arguments())
    if isinstance(ld, SteppedShakeLoading):
        return SteppedShake(g0, ld.direction, ld.motion())
    if isinstance(ld, SweepLoading):
        return Sweep(g0, ld.direction, ld.motion())
    if isinstance(ld, NoiseLoading):
        return Noise(g0, ld.direction, ld.motion())
    if isinstance(ld, RecordLoading):
        return Record(g0, *ld.samples())
    if isinstance(ld, NoLoading):
        return Loading(g0)
    raise TypeError(f"unknown loading {type(ld).__name__}")


def stepped_shake_errors(ld, dt: float, min_steps: int, where) -> list[str]:
    """dem check's errors of a stepped shake (dem.validate): every step's period must span
    ``min_steps`` time steps of ``dt`` (s), as a shake's; ``where(loc)`` gives the
    ``file:line: field`` prefix."""
    out = []
    for k, st in enumerate(ld.steps):
        if 1.0 / st.frequency < min_steps * dt:
            out.append(
                f"{where(('loading', 'steps', k, 'frequency'))}: {st.frequency:g} Hz has a "
                f"period of {1.0 / st.frequency:.3g} s, shorter than {min_steps} time steps "
                f"({min_steps} x {dt:.3g} s): the table motion cannot be resolved (highest "
                f"frequency for this scene: {1.0 / (min_steps * dt):.4g} Hz)")
    return out


def stepped_shake_plausibility(ld, table_plausibility, where) -> tuple[list[str], list[str]]:
    """dem check's (warnings, errors) on a stepped shake's table motion: every step through
    ``table_plausibility(a_p, A, f, where_freq, where)`` (dem.validate: impossible table speeds
    refused, implausible accelerations and strokes warned of) with its own amplitude along the
    direction, and the whole excursion max |u(t)| (the steps' displacement offsets included:
    dem.table_motion.SteppedSineMotion) against the stroke."""
    motion = ld.motion()
    scale = float(np.linalg.norm(ld.direction))
    field = "amplitude" if ld.amplitude is not None else "peak_acceleration"
    warnings, errors = [], []
    for k, st in enumerate(motion.steps_run()):
        w, e = table_plausibility(st["peak_acceleration_m_s2"] * scale, st["amplitude_m"] * scale,
                                  st["frequency_hz"], "", where(("loading", "steps", k)))
        warnings += w
        errors += e
    if not errors:
        t = np.linspace(0.0, motion.t_end, 200 * len(ld.steps) + 1)
        excursion = float(np.abs(motion.displacement(t)).max()) * scale
        w, _ = table_plausibility(0.0, excursion, None, "", where(("loading", field)))
        warnings += w
    return warnings, errors


def sampling_interval(run, scene) -> tuple[float, str]:
    """(s, field) of the samples an identification reads: the instruments' interval where the
    run records instruments (``run.instruments: thesis``, or ``auto`` on a box model: dem.run.
    record.choose_instruments), else the frames' ``run.output_interval``."""
    boxy = scene is not None and {"L1", "L2", "T1", "T2"} <= set(scene.group_names)
    if run.instruments == "thesis" or (run.instruments == "auto" and boxy):
        return run.instrument_interval, "instrument_interval"
    return run.output_interval, "output_interval"


def identification_errors(ld, dt: float, min_steps: int, run, scene, table_plausibility,
                          where) -> tuple[list[str], list[str]]:
    """dem check's (warnings, errors) on a sweep or a noise (dem.validate): the highest
    frequency (f1, f_hi) must span ``min_steps`` time steps of ``dt`` (s) per period, as a
    shake's, and lie below the Nyquist frequency 1 / (2 dt_s) of the samples the
    identification reads (:func:`sampling_interval`); the motion is sampled for its peak
    acceleration, velocity and excursion (``table_plausibility``, dem.validate); a run shorter
    than the motion is warned of (the end of the sweep or noise is cut)."""
    is_sweep = isinstance(ld, SweepLoading)
    top, top_field = (ld.f1, "f1") if is_sweep else (ld.f_hi, "f_hi")
    warnings, errors = [], []
    if 1.0 / top < min_steps * dt:
        errors.append(
            f"{where(('loading', top_field))}: {top:g} Hz has a period of {1.0 / top:.3g} s, "
            f"shorter than {min_steps} time steps ({min_steps} x {dt:.3g} s): the table motion "
            f"cannot be resolved (highest frequency for this scene: "
            f"{1.0 / (min_steps * dt):.4g} Hz)")
    ds, ds_field = sampling_interval(run, scene)
    nyquist = 0.5 / ds
    if top >= nyquist:
        errors.append(
            f"{where(('loading', top_field))}: {top:g} Hz is at or above the Nyquist frequency "
            f"{nyquist:.4g} Hz of the samples the identification reads (run.{ds_field} = "
            f"{ds:g} s): lower {top_field} or sample faster")
    if errors:
        return warnings, errors
    motion = ld.motion()
    scale = float(np.linalg.norm(ld.direction))
    t = np.linspace(0.0, motion.t_end, int(min(2e5, 64 * top * motion.t_end)) + 2)
    a_peak = float(np.abs(motion.acceleration(t)).max()) * scale
    stroke = float(np.abs(motion.displacement(t)).max()) * scale
    v_peak = float(np.abs(motion.velocity(t)).max()) * scale
    field = "peak_acceleration" if is_sweep and ld.peak_acceleration is not None else \
        "amplitude" if is_sweep else "rms_acceleration"
    # the speed check takes amplitude x 2 pi f: the f that gives the motion's peak velocity
    w, e = table_plausibility(a_peak, stroke, v_peak / (2.0 * np.pi * stroke) if stroke else None,
                              "", where(("loading", field)))
    warnings += w
    errors += e
    if run.duration < motion.t_end:
        warnings.append(
            f"{where(('run', 'duration'))}: {run.duration:g} s is shorter than the "
            f"{ld.type}'s {motion.t_end:.4g} s: its end is cut, the table not brought to rest")
    return warnings, errors
