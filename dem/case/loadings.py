"""``loading:`` of a case file: tilt (constant rate or quasi-static), shake, stepped shake, sine
sweep, band-limited noise, record, none.

The loads against time they give are dem.loading's.
"""

from __future__ import annotations

import math
from typing import Annotated, Literal, Union

from pydantic import Field, field_validator, model_serializer, model_validator

from dem.case.base import Vec3, StrictModel


class CollapseSpec(StrictModel):
    """When a tilt run counts as collapsed and stops (see dem.collapse for the rule)."""

    enabled: bool = Field(default=True, description="detect collapse and stop the run after it")
    onset_speed: float = Field(
        default=1e-3, gt=0.0, description="m/s: blocks slower than this are at rest (onset)"
    )
    confirm: float = Field(
        default=5e-3, gt=0.0,
        description="motion (m) from the settled pose that confirms collapse, unless every block "
                    "comes to rest again before stop / after (a re-seating)")
    after: float = Field(default=1.0, ge=0.0, description="s to run on after confirmation")
    stop: float = Field(default=0.03, gt=0.0, description="stop earlier once a block moved this, m")

    @model_validator(mode="after")
    def _ordered(self) -> "CollapseSpec":
        if not self.confirm < self.stop:
            raise ValueError("need confirm < stop")
        return self


class QuasiStaticSpec(StrictModel):
    """How a quasi-static tilt finds the angle at which equilibrium is lost (dem.run.quasi_static).

    The angle advances by ``increment``; after each advance the scene relaxes with Cundall local
    damping (``local_damping``: it does not change a static equilibrium, it only removes the
    motion) until the unbalanced-force ratio (sum over blocks of |net force| + |net torque| /
    radius, over the sum of their weights) is below ``tolerance`` with every block at rest;
    equilibrium is lost when a block moves ``collapse.confirm`` while relaxing and no new
    equilibrium follows within ``collapse.after`` s (one that does is a re-seating on warped
    beds), or when ``max_relax_time`` passes without that and a block moved more than a tenth of
    ``collapse.confirm`` (less: in equilibrium).  The first failing increment is bisected down to
    ``resolution``; lambda = tan(last angle in equilibrium).  Then the run goes on dynamically
    (no local damping) at the first failing increment's angle for ``collapse.after`` s or until
    a block moved ``collapse.stop``, to show the mechanism; if no block has moved that much
    by then, the table turns on by ``increment`` every ``collapse.after`` s until one has.
    """

    increment: float = Field(default=1.0, gt=0.0, le=10.0, description="degrees per advance")
    resolution: float = Field(default=0.05, gt=0.0, description="bisection width, degrees")
    tolerance: float = Field(
        default=1e-3, gt=0.0, lt=1.0,
        description="unbalanced-force ratio of equilibrium, -: an angle up to about this much "
        "load factor above a sliding limit can pass (benchmarks/quasi_static_tilt.py: 1e-3 "
        "reads lambda within 0.2 %; 1e-4 is below the floor some walls' joint vibrations give)")
    local_damping: float = Field(default=0.8, gt=0.0, lt=1.0,
                                 description="Cundall local damping while relaxing, -")
    ramp_time: float = Field(default=0.005, ge=0.0,
                             description="s over which each advance turns the table (smoothstep)")
    max_relax_time: float = Field(
        default=3.0, gt=0.0,
        description="s of relaxation before an angle counts as failed (3 s: the warped-bed walls "
        "seat over 1.5-2 s near their limit, and 1 s read them up to 9 % low; benchmarks/"
        "speed_error.md 'Quasi-static tilt of imperfect walls')")


class TiltLoading(StrictModel):
    """The table turns about a horizontal axis (pseudo-static collapse, thesis Chapter 3).

    Modelled in the table's frame: gravity turns, the table stays.  With the right-hand rule about
    ``axis`` a positive angle theta gives gravity g_t = -g cos(theta) z + g sin(theta) (axis x z),
    so about +x blocks are pushed towards -y, about +y towards +x; the load factor is
    lambda = tan(theta).  Where the pivot edge is does not matter in this frame: the fictitious
    forces of the rotation (of order rate^2 * size, < 1e-5 g at 2 deg/s) are neglected.
    ``method``: "constant_rate": the angle rises at ``rate``; with ``step`` it rises by ``step``
    degrees, then holds for ``hold`` seconds, and so on; it stays at ``max_angle`` once reached;
    collapse as dem.collapse detects it.  "quasi_static": the angle advances by increments, each
    followed by relaxation to equilibrium, until equilibrium is lost (``quasi_static``).
    """

    type: Literal["tilt"]
    axis: Union[Literal["x", "y", "-x", "-y"], Vec3] = Field(
        description="table rotation axis (horizontal): x, y, -x, -y or a vector"
    )
    method: Literal["constant_rate", "quasi_static"] = Field(
        default="quasi_static",
        description="quasi_static (the default, and what a tilt without a rate gets): "
        "increments, each relaxed to equilibrium, then bisection of the first that fails "
        "(`quasi_static`); constant_rate (what a tilt with a rate gets): the angle rises at "
        "`rate`")
    rate: float | None = Field(default=None, gt=0.0,
                               description="tilt rate while turning, degrees per second "
                               "(constant_rate)")
    quasi_static: QuasiStaticSpec = Field(default_factory=QuasiStaticSpec)
    max_angle: float = Field(default=60.0, gt=0.0, le=90.0, description="degrees")
    start_angle: float = Field(default=0.0, ge=0.0, le=90.0, description="degrees at t = 0")
    start_time: float = Field(
        default=0.0, ge=0.0,
        description="s to bring the table smoothly (smoothstep) from 0 to start_angle; 0 = the "
        "table starts at start_angle (a sudden load: right for a block released on an incline, "
        "a shock for a wall)",
    )
    step: float | None = Field(default=None, gt=0.0, description="degrees per step (with holds)")
    hold: float = Field(default=0.0, ge=0.0, description="s held after every step")
    collapse: CollapseSpec = Field(default_factory=CollapseSpec)

    @model_validator(mode="before")
    @classmethod
    def _method_from_rate(cls, data):
        """A tilt that gives a rate and no method is a constant-rate tilt (every case file
        written before the quasi-static tilt existed); without a rate it is quasi-static."""
        if isinstance(data, dict) and "method" not in data and data.get("rate") is not None:
            data = {**data, "method": "constant_rate"}
        return data

    @field_validator("axis")
    @classmethod
    def _horizontal(cls, v):
        if isinstance(v, list):
            if abs(v[2]) > 1e-12 or math.hypot(v[0], v[1]) == 0.0:
                raise ValueError(f"axis must be a non-zero horizontal vector, got {v}")
        return v

    @model_validator(mode="after")
    def _start_below_max(self) -> "TiltLoading":
        if self.start_angle > self.max_angle:
            raise ValueError("start_angle must not exceed max_angle")
        if self.method == "constant_rate" and self.rate is None:
            raise ValueError("rate: a constant_rate tilt needs a rate (degrees per second); or "
                             "give method: quasi_static")
        if self.method == "quasi_static" and (self.rate is not None or self.step is not None):
            raise ValueError("rate / step: they apply to method: constant_rate; a quasi_static "
                             "tilt advances by quasi_static.increment")
        return self


StartMode = Literal["table-frame", "lab", "ramp"]
START_DESCRIPTION = (
    "how the table starts (dem.table_motion): table-frame (the default): the shake in the "
    "table's frame, the table moving at A w from t = 0, the blocks never feel the jump from rest; "
    "lab: the table at rest before t = 0, so at t = 0 every block takes a velocity -A w relative "
    "to it along the direction (an impulse; a real table started from rest); ramp: the "
    "amplitude rises smoothly over ramp_cycles cycles (displacement, velocity and acceleration "
    "continuous from rest), then holds")
RAMP_DESCRIPTION = ("cycles over which a ramp start raises the amplitude (quintic taper), -; "
                    "only with start: ramp; they count among the (first step's) cycles")


def _check_start(start: str, ramp_cycles: float | None, cycles: float, cycles_name: str) -> None:
    if start == "ramp" and ramp_cycles is None:
        raise ValueError("ramp_cycles: start: ramp needs ramp_cycles (the cycles over which the "
                         "amplitude rises)")
    if start != "ramp" and ramp_cycles is not None:
        raise ValueError(f"ramp_cycles: only with start: ramp (start is {start})")
    if ramp_cycles is not None and ramp_cycles > cycles:
        raise ValueError(f"ramp_cycles: {ramp_cycles:g} is more than {cycles_name} = "
                         f"{cycles:g} (the ramp's cycles count among them)")


def _omit_start_defaults(model, data):
    if isinstance(data, dict):
        if model.start == "table-frame":
            data.pop("start", None)
        if model.ramp_cycles is None:
            data.pop("ramp_cycles", None)
    return data


def _shake_direction(v):
    """A shake's direction must be a finite non-zero vector (ShakeLoading, SteppedShakeLoading)."""
    if math.sqrt(sum(x * x for x in v)) == 0.0 or any(not math.isfinite(x) for x in v):
        raise ValueError(f"direction must be a finite non-zero vector, got {v}")
    return v


def _horizontal_direction(v):
    """A sweep's or a noise's direction: a finite non-zero horizontal vector."""
    _shake_direction(v)
    if abs(v[2]) > 1e-12:
        raise ValueError(f"direction must be horizontal (z = 0), got {v}")
    return v


def _one_amplitude(amplitude, peak_acceleration) -> None:
    """Exactly one of a displacement amplitude (m) and a peak acceleration (m/s2)."""
    if (amplitude is None) == (peak_acceleration is None):
        raise ValueError("give exactly one of amplitude (m) or peak_acceleration (m/s2)")


class ReversalSpike(StrictModel):
    """A half-sine pulse of the table's acceleration at every velocity reversal of the sine
    (dem.table_motion.DistortedSineMotion)."""

    peak: float = Field(gt=0.0, le=10.0,
                        description="peak of each pulse over the nominal peak acceleration "
                        "a_p, -")
    duration: float = Field(gt=0.0, description="duration of each pulse, s (at most half a "
                            "period of the shake)")


class Distortion(StrictModel):
    """What a servo-hydraulic table adds to a commanded sine (derived, with the displacement
    and velocity, in dem.table_motion.DistortedSineMotion): a third harmonic in the phase that
    sharpens the peaks, a = -a_p [sin(w t) - h sin(3 w t)] (peak a_p (1 + h)), and a half-sine
    acceleration pulse of peak s a_p and duration tau starting at every velocity reversal
    (displacement extreme) in the direction of the acceleration there."""

    third_harmonic: float = Field(default=0.0, ge=0.0, le=1.0,
                                  description="h: the third harmonic's acceleration over the "
                                  "fundamental's, in the phase that sharpens the peaks, -")
    reversal_spike: ReversalSpike | None = Field(
        default=None, description="the pulse at every velocity reversal (none by default)")

    @model_validator(mode="after")
    def _something(self) -> "Distortion":
        if self.third_harmonic == 0.0 and self.reversal_spike is None:
            raise ValueError("third_harmonic / reversal_spike: a distortion needs a third "
                             "harmonic > 0 or a reversal spike (leave distortion out for the "
                             "plain sine)")
        return self


DISTORTION_DESCRIPTION = (
    "the table's waveform distortion (dem.table_motion.DistortedSineMotion): a third harmonic "
    "and reversal spikes added to the sine; absent (the default): the plain sine")


class ShakeLoading(StrictModel):
    """Sinusoidal table displacement u(t) = A * direction * sin(2 pi f t) for ``cycles`` cycles.

    ``direction`` is used as given (not normalised): [1, 1, 0] moves x and y each by the amplitude
    (the thesis' diagonal tests).  Give the amplitude A (m) or the peak acceleration
    a_p = A (2 pi f)^2 (m/s2).  After the last cycle a = 0 and the table keeps its final velocity (see dem.table_motion).  The
    motion itself is dem.table_motion.SineMotion; the two-body model's case format uses this
    class too (dem.rocking.schema.ShakeLoading adds that its direction must be horizontal).
    """

    type: Literal["shake"]
    direction: Vec3 = Field(description="displacement direction, multiplied by the amplitude")
    frequency: float = Field(gt=0.0, description="Hz")
    amplitude: float | None = Field(default=None, gt=0.0, description="displacement amplitude, m")
    peak_acceleration: float | None = Field(default=None, gt=0.0, description="m/s2")
    cycles: float = Field(default=50.0, gt=0.0, description="number of cycles")
    start: StartMode = Field(default="table-frame", description=START_DESCRIPTION)
    ramp_cycles: float | None = Field(default=None, gt=0.0, description=RAMP_DESCRIPTION)
    distortion: Distortion | None = Field(default=None, description=DISTORTION_DESCRIPTION)

    @field_validator("direction")
    @classmethod
    def _nonzero(cls, v):
        return _shake_direction(v)

    @model_validator(mode="after")
    def _one_of(self) -> "ShakeLoading":
        _one_amplitude(self.amplitude, self.peak_acceleration)
        _check_start(self.start, self.ramp_cycles, self.cycles, "cycles")
        spike = self.distortion.reversal_spike if self.distortion is not None else None
        if spike is not None and spike.duration > 0.5 / self.frequency:
            raise ValueError(f"distortion.reversal_spike.duration: {spike.duration:g} s is more "
                             f"than half a period at {self.frequency:g} Hz "
                             f"({0.5 / self.frequency:.4g} s): the pulses would overlap")
        return self

    @model_serializer(mode="wrap")
    def _omit_default_start(self, handler):
        """A shake with the default start and no distortion is written as before either
        existed (case.json of every shipped run stays the same, byte for byte)."""
        data = _omit_start_defaults(self, handler(self))
        if isinstance(data, dict) and self.distortion is None:
            data.pop("distortion", None)
        return data

    def motion(self, scale: float = 1.0):
        """The table motion along the direction (dem.table_motion: SineMotion, or
        DistortedSineMotion with a distortion), the displacement amplitude times ``scale``."""
        from dem.table_motion import DistortedSineMotion, SineMotion

        A = self.displacement_amplitude * scale
        if self.distortion is None:
            return SineMotion(A, self.frequency, self.cycles, self.start, self.ramp_cycles)
        return DistortedSineMotion(A, self.frequency, self.cycles, self.start, self.ramp_cycles,
                                   **self.distortion_arguments())

    def distortion_arguments(self) -> dict:
        """The distortion as DistortedSineMotion's keyword arguments ({} without one)."""
        if self.distortion is None:
            return {}
        spike = self.distortion.reversal_spike
        return {"third_harmonic": self.distortion.third_harmonic,
                "spike_peak": 0.0 if spike is None else spike.peak,
                "spike_duration": None if spike is None else spike.duration}

    @property
    def displacement_amplitude(self) -> float:
        """A, m: the amplitude given, or the one of the peak acceleration given."""
        if self.amplitude is not None:
            return self.amplitude
        return self.peak_acceleration / (2.0 * math.pi * self.frequency) ** 2

    @property
    def axis_amplitude(self) -> float:
        """Displacement amplitude along the direction, m (= A * |direction|)."""
        return self.displacement_amplitude * math.sqrt(sum(x * x for x in self.direction))


class FrequencyStep(StrictModel):
    """One step of a stepped shake: a frequency, its cycles and, optionally, a level of its own
    (a kick-start, a protocol of rising intensity, a continuation in amplitude)."""

    frequency: float = Field(gt=0.0, description="Hz")
    cycles: float = Field(gt=0.0, description="cycles at this frequency (run on to the next "
                          "displacement extreme: at most half a period more)")
    amplitude: float | None = Field(default=None, gt=0.0,
                                    description="displacement amplitude of this step, m "
                                    "(default: the loading's level)")
    peak_acceleration: float | None = Field(default=None, gt=0.0,
                                            description="peak acceleration of this step, m/s2 "
                                            "(default: the loading's level)")

    @model_validator(mode="after")
    def _one_level(self) -> "FrequencyStep":
        if self.amplitude is not None and self.peak_acceleration is not None:
            raise ValueError("give at most one of amplitude (m) or peak_acceleration (m/s2) "
                             "for a step")
        return self

    @model_serializer(mode="wrap")
    def _omit_unset_level(self, handler):
        """A step without a level of its own is written as before steps could have one."""
        data = handler(self)
        if isinstance(data, dict):
            for key in ("amplitude", "peak_acceleration"):
                if data.get(key) is None:
                    data.pop(key, None)
        return data

    @property
    def level(self) -> tuple[str, float] | None:
        """("amplitude", m) or ("peak_acceleration", m/s2) of this step, None: the loading's."""
        if self.amplitude is not None:
            return ("amplitude", self.amplitude)
        if self.peak_acceleration is not None:
            return ("peak_acceleration", self.peak_acceleration)
        return None


class SteppedShakeLoading(StrictModel):
    """A sine whose frequency steps through ``steps`` on one specimen, never settled again
    between steps (the table motion: dem.table_motion.SteppedSineMotion).

    The steps run in the order given: rising frequencies are an up pass, falling a down pass
    (give both in one list for an up-and-down run).  Every step has the same
    ``peak_acceleration`` (m/s2; amplitude a_p / (2 pi f)^2) or the same ``amplitude`` (m),
    unless it gives a level of its own (``steps[k].peak_acceleration`` or ``.amplitude``): a
    kick-start (two cycles above the rocking threshold, then the test level), a protocol of
    rising intensity, a continuation in amplitude at one frequency; the loading's level may
    then be left out if every step has its own.
    Each step runs its cycles, then on to the next displacement extreme (table velocity zero),
    where the next step starts from that extreme: the velocity is continuous, and at constant
    peak acceleration the acceleration too (the displacement keeps an offset, a shift of the
    table); the last step ends at an extreme with the table at rest.  ``start`` applies to the
    first step, as for a shake.  ``direction`` as for a shake (used as given).
    """

    type: Literal["stepped_shake"]
    direction: Vec3 = Field(description="displacement direction, multiplied by the amplitude")
    steps: list[FrequencyStep] = Field(min_length=1, description="frequencies and cycles, in "
                                       "the order run")
    amplitude: float | None = Field(default=None, gt=0.0,
                                    description="displacement amplitude of every step, m")
    peak_acceleration: float | None = Field(default=None, gt=0.0,
                                            description="peak acceleration of every step, m/s2")
    start: StartMode = Field(default="table-frame", description=START_DESCRIPTION)
    ramp_cycles: float | None = Field(default=None, gt=0.0, description=RAMP_DESCRIPTION)

    @field_validator("direction")
    @classmethod
    def _nonzero(cls, v):
        return _shake_direction(v)

    @model_validator(mode="before")
    @classmethod
    def _no_distortion(cls, data):
        """The waveform distortion is a shake's (dem.table_motion.DistortedSineMotion); a
        stepped shake refuses it by name rather than as an unknown field."""
        if isinstance(data, dict) and "distortion" in data:
            raise ValueError("distortion: the table's waveform distortion is implemented for "
                             "type: shake only, not for a stepped shake")
        return data

    @model_validator(mode="after")
    def _one_of(self) -> "SteppedShakeLoading":
        common = [x for x in (self.amplitude, self.peak_acceleration) if x is not None]
        # one common level, or none when every step gives its own
        if len(common) > 1 or (not common and any(s.level is None for s in self.steps)):
            _one_amplitude(self.amplitude, self.peak_acceleration)
        _check_start(self.start, self.ramp_cycles, self.steps[0].cycles, "steps[0].cycles")
        return self

    @property
    def frequencies(self) -> list[float]:
        return [s.frequency for s in self.steps]

    def motion(self, scale: float = 1.0):
        """The table motion (dem.table_motion.SteppedSineMotion) along the direction, with the
        displacement amplitude times ``scale``."""
        from dem.table_motion import SteppedSineMotion

        levels = [s.level for s in self.steps]
        return SteppedSineMotion(
            [(s.frequency, s.cycles) for s in self.steps],
            amplitude=None if self.amplitude is None else self.amplitude * scale,
            peak_acceleration=None if self.peak_acceleration is None
            else self.peak_acceleration * scale,
            start=self.start, ramp_cycles=self.ramp_cycles,
            levels=None if all(lv is None for lv in levels) else
            [None if lv is None else (lv[0], lv[1] * scale) for lv in levels])


class SweepLoading(StrictModel):
    """A sine sweep of the table along ``direction`` (a model's frequency response, as a
    shaking-table laboratory measures it between tests): the frequency rises from ``f0`` to
    ``f1`` (Hz), linearly (``law: linear``, Hz/s) or logarithmically (``law: log``, equal time
    per octave), over ``duration`` s or at ``rate`` (linear: Hz/s; log: octaves per minute),
    at constant ``peak_acceleration`` (m/s2) or constant ``amplitude`` (m).  The table starts
    and ends at rest: the amplitude rises over the first ``taper_cycles`` cycles and falls over
    the last (quintic, as a shake's ``start: ramp``).  The motion and its equations:
    dem.table_motion.SweepMotion; docs/identification.md.  ``direction`` as for a shake (used
    as given; horizontal).
    """

    type: Literal["sweep"]
    direction: Vec3 = Field(description="displacement direction, multiplied by the amplitude")
    f0: float = Field(gt=0.0, description="start frequency, Hz")
    f1: float = Field(gt=0.0, description="end frequency, Hz (> f0)")
    law: Literal["linear", "log"] = Field(default="linear",
                                          description="linear (Hz/s) or log (octaves/min)")
    duration: float | None = Field(default=None, gt=0.0, description="s (or give rate)")
    rate: float | None = Field(default=None, gt=0.0,
                               description="linear: Hz/s; log: octaves per minute (or give "
                               "duration)")
    amplitude: float | None = Field(default=None, gt=0.0, description="displacement amplitude, m")
    peak_acceleration: float | None = Field(default=None, gt=0.0, description="m/s2")
    taper_cycles: float = Field(default=2.0, gt=0.0,
                                description="cycles (at f0 at the start, at f1 at the end) "
                                "over which the amplitude rises from and falls to rest")

    @field_validator("direction")
    @classmethod
    def _nonzero(cls, v):
        return _horizontal_direction(v)

    @model_validator(mode="after")
    def _consistent(self) -> "SweepLoading":
        if not self.f1 > self.f0:
            raise ValueError(f"f1: {self.f1:g} Hz must be above f0 = {self.f0:g} Hz (a sweep "
                             f"rises from f0 to f1)")
        _one_amplitude(self.amplitude, self.peak_acceleration)
        if (self.duration is None) == (self.rate is None):
            raise ValueError("duration / rate: give exactly one of duration (s) or rate "
                             "(linear: Hz/s; log: octaves per minute)")
        tapers = self.taper_cycles / self.f0 + self.taper_cycles / self.f1
        if not self.sweep_duration > tapers:
            raise ValueError(f"duration: the sweep lasts {self.sweep_duration:.3g} s, not more "
                             f"than its tapers (taper_cycles / f0 + taper_cycles / f1 = "
                             f"{tapers:.3g} s)")
        return self

    @property
    def sweep_duration(self) -> float:
        """T, s: ``duration``, or (f1 - f0) / rate (linear), log2(f1 / f0) / rate min (log)."""
        if self.duration is not None:
            return self.duration
        if self.law == "linear":
            return (self.f1 - self.f0) / self.rate
        return 60.0 * math.log2(self.f1 / self.f0) / self.rate

    def motion(self):
        """dem.table_motion.SweepMotion along the direction."""
        from dem.table_motion import SweepMotion

        return SweepMotion(self.f0, self.f1, self.sweep_duration, self.law, self.amplitude,
                           self.peak_acceleration, self.taper_cycles)


class NoiseLoading(StrictModel):
    """Band-limited white noise of the table along ``direction``: a table acceleration of RMS
    ``rms_acceleration`` (m/s2, along the unit direction times |direction|) with a flat
    spectrum on [``f_lo``, ``f_hi``] (Hz), for ``duration`` s, drawn from ``seed`` (the same
    seed, the same motion); started and ended at rest by quintic tapers of ``taper`` s.  The
    synthesis (a random-phase multisine, its displacement bounded): dem.table_motion.NoiseMotion;
    docs/identification.md.  Keep the level low enough to stay below uplift when the model's
    own frequency response is wanted.
    """

    type: Literal["noise"]
    direction: Vec3 = Field(description="direction, multiplied by the acceleration")
    rms_acceleration: float = Field(gt=0.0, description="RMS table acceleration, m/s2")
    f_lo: float = Field(gt=0.0, description="lowest frequency of the band, Hz")
    f_hi: float = Field(gt=0.0, description="highest frequency of the band, Hz (> f_lo)")
    duration: float = Field(gt=0.0, description="s")
    seed: int = Field(default=0, ge=0, description="random seed of the phases")
    taper: float = Field(default=1.0, gt=0.0,
                         description="s over which the motion rises from and falls to rest, at "
                         "each end (several periods of f_lo keep the taper's own low-frequency "
                         "content small)")

    @field_validator("direction")
    @classmethod
    def _nonzero(cls, v):
        return _horizontal_direction(v)

    @model_validator(mode="after")
    def _consistent(self) -> "NoiseLoading":
        if not self.f_hi > self.f_lo:
            raise ValueError(f"f_hi: {self.f_hi:g} Hz must be above f_lo = {self.f_lo:g} Hz")
        if not self.duration > 2.0 * self.taper:
            raise ValueError(f"duration: {self.duration:g} s must exceed the two tapers "
                             f"(2 x taper = {2.0 * self.taper:g} s)")
        if self.f_lo * self.duration < 1.0:
            raise ValueError(f"f_lo: {self.f_lo:g} Hz is below 1 / duration = "
                             f"{1.0 / self.duration:.3g} Hz, the frequency resolution of "
                             f"{self.duration:g} s of noise")
        return self

    def motion(self):
        """dem.table_motion.NoiseMotion (along the direction)."""
        from dem.table_motion import NoiseMotion

        return NoiseMotion(self.rms_acceleration, self.f_lo, self.f_hi, self.duration,
                           self.seed, self.taper)


class RecordLoading(StrictModel):
    """Table acceleration from a record (an earthquake, a pulse), in the table's frame.

    Give either ``file`` (CSV with columns t, ax, ay and optionally az: s and m/s2; a header line
    is allowed; a relative path is relative to the case file) or the arrays ``time``, ``ax``,
    ``ay`` (and ``az``) inline.  Between samples the acceleration is interpolated linearly, outside
    the record it is zero; the table starts at rest and its velocity and displacement are the
    integrals of the acceleration (no baseline correction: a record that does not integrate to
    zero velocity leaves the table drifting, as it would).  ``scale`` multiplies the record.
    """

    type: Literal["record"]
    file: str | None = Field(default=None, description="CSV: t, ax, ay[, az] (s, m/s2)")
    time: list[float] | None = Field(default=None, description="s, strictly increasing")
    ax: list[float] | None = Field(default=None, description="m/s2")
    ay: list[float] | None = Field(default=None, description="m/s2")
    az: list[float] | None = Field(default=None, description="m/s2")
    scale: float = Field(default=1.0, description="factor on the record")

    @model_validator(mode="after")
    def _source(self) -> "RecordLoading":
        if (self.file is None) == (self.time is None):
            raise ValueError("give either file (CSV) or time with ax, ay (inline arrays)")
        if self.time is not None:
            n = len(self.time)
            if n < 2:
                raise ValueError("time needs at least 2 samples")
            for name in ("ax", "ay", "az"):
                arr = getattr(self, name)
                if arr is not None and len(arr) != n:
                    raise ValueError(f"{name} has {len(arr)} samples, time has {n}")
            if self.ax is None and self.ay is None and self.az is None:
                raise ValueError("give at least one of ax, ay, az")
            check_record_time(self.time)
        return self

    def samples(self):
        """(t [K] s, acceleration [K,3] m/s2) with the scale applied; reads the file if given."""
        import numpy as np

        if self.file is not None:
            t, acc = read_record_csv(self.file)
        else:
            t = np.asarray(self.time, dtype=float)
            acc = np.zeros((len(t), 3))
            for k, name in enumerate(("ax", "ay", "az")):
                if getattr(self, name) is not None:
                    acc[:, k] = getattr(self, name)
        return t, self.scale * acc


def check_record_time(t) -> None:
    import numpy as np

    t = np.asarray(t, dtype=float)
    if not np.all(np.isfinite(t)) or np.any(np.diff(t) <= 0):
        raise ValueError("time must be finite and strictly increasing")


def read_record_csv(path):
    """t [K], acceleration [K,3] from a CSV of t, ax, ay[, az]; raises ValueError naming the
    problem and the row (1-based line of the file): ``pulse.csv:7: 'abc' is not a number``.
    Lines starting with '#' and blank lines are skipped; the first data-like line may be a header
    (non-numeric)."""
    import csv

    import numpy as np

    try:
        with open(path, newline="") as fh:
            lines = list(enumerate(csv.reader(fh), start=1))
    except (OSError, UnicodeDecodeError) as err:
        raise ValueError(f"cannot read {path}: {getattr(err, 'strerror', None) or err}") from None
    except csv.Error as err:
        raise ValueError(f"{path}: not a CSV file: {err}") from None
    rows, ncol, header_seen = [], None, False
    for line, cells in lines:
        cells = [c.strip() for c in cells]
        if not any(cells) or cells[0].startswith("#"):
            continue
        try:
            values = [float(c) for c in cells]
        except ValueError:
            bad = next(c for c in cells if not _is_number(c))
            if not rows and not header_seen:
                header_seen = True  # a header line
                continue
            raise ValueError(f"{path}:{line}: {bad!r} is not a number (columns t, ax, ay[, az]: "
                             "s, m/s2)") from None
        if len(values) not in (3, 4):
            raise ValueError(f"{path}:{line}: {len(values)} columns, need 3 or 4 columns "
                             "(t, ax, ay[, az])")
        if ncol is not None and len(values) != ncol:
            raise ValueError(f"{path}:{line}: {len(values)} columns, the rows above have {ncol}")
        if not all(np.isfinite(values)):
            raise ValueError(f"{path}:{line}: values must be finite, got {', '.join(cells)}")
        if rows and not values[0] > rows[-1][1][0]:
            raise ValueError(f"{path}:{line}: time {values[0]:g} s is not after the previous "
                             f"row's {rows[-1][1][0]:g} s (time must increase strictly)")
        ncol = len(values)
        rows.append((line, values))
    if len(rows) < 2:
        raise ValueError(f"{path}: need at least 2 rows of 3 or 4 columns (t, ax, ay[, az])")
    data = np.array([v for _, v in rows], dtype=float)
    acc = np.zeros((len(data), 3))
    acc[:, : data.shape[1] - 1] = data[:, 1:]
    return data[:, 0], acc


def _is_number(text: str) -> bool:
    try:
        float(text)
        return True
    except ValueError:
        return False


class NoLoading(StrictModel):
    """Free motion from the initial state under gravity (e.g. a block released tilted)."""

    type: Literal["none"]


Loading = Annotated[Union[TiltLoading, ShakeLoading, SteppedShakeLoading, SweepLoading,
                          NoiseLoading, RecordLoading, NoLoading],
                    Field(discriminator="type")]
