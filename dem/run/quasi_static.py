"""Load phase of a quasi-static tilt: the angle at which static equilibrium is lost.

The constant-rate tilt reads lambda while the wall moves (at 2 deg/s it reads 3.5 % low in plane
and 12 % low out of plane, results/tilt/FINDINGS.md).  Here the table angle is the control
variable (thesis Chapter 3: "the table was tilted slowly"; the static answer is what limit
analysis predicts), as 3DEC / UDEC find static solutions:

1. advance the angle by ``increment`` (turned over ``ramp_time`` s, smoothstep), then relax with
   Cundall local damping alpha (a force -alpha |F| sign(v) per component: it removes motion and
   leaves every static equilibrium as it is) until the unbalanced-force ratio R (sum of
   |F_i| + |T_i| / r_i over the sum of the weights, dem.engine.Simulation.unbalanced_force_ratio)
   is below ``tolerance`` and every block is at rest (|v| + r |omega| below
   ``collapse.onset_speed``) at ``CALM_CHECKS`` looks in a row;
2. equilibrium is lost at an angle when, while relaxing, a block moves ``collapse.stop`` (the
   motion measure of dem.collapse, from the poses at the start of the relaxation: the motion
   kept growing) or finds no new equilibrium within ``collapse.after`` s of moving
   ``collapse.confirm`` (the constant-rate detector's rule, dem.collapse), or ``max_relax_time`` passes with R above the tolerance and a block moved more
   than ``REST_MOTION`` x confirm (less: in equilibrium, whatever R and the speeds say).  A
   relaxation in which a block moved ``collapse.confirm`` or more and then came to rest (R below
   the tolerance, every block at rest) found a new equilibrium: the blocks re-seated on warped
   beds (a 3-brick column with 0.3 mm unevenness snaps through 4 mm at the top
   at 1.4-2.1 deg and stands until 25 deg); the angle is in equilibrium (``why``:
   "re-seated").  Where no new equilibrium comes, the relaxation is put back (Simulation.snapshot
   / restore: state, clock, time step) to where the motion first reached ``collapse.confirm``
   and the angle fails there, so the search goes on exactly as before this rule: a later trial
   depends on the clock and time step an earlier failed trial left (save_point keeps neither),
   and near the limit that moved a wall's lambda by a bisection step (the calibration's 5 x 5
   wall, seed 0: 0.8044 -> 0.8035 without the put-back).  The look-ahead costs time: its steps
   are counted in ``lookahead_steps``.  Ending the relaxation at a motion of ``collapse.confirm`` (5 mm), as a loss
   of equilibrium, would read that re-seating as the collapse (lambda 0.043 instead of
   ~0.47).  Faster
   rules were tried and removed, each wrong on some Chapter 3 walls: a rise of the block speeds
   (near its limit a wall creeps at mm/s for hundreds of ms while slip spreads, then settles:
   lambda 5 % low on the 5 x 7 wall); a mean speed accelerating by more than 10 % per 0.04 s
   window with growing gains (7 of the 25 walls 0.8-7 % low, the poor/poor facade 0.267 against
   0.280); advances doubling up to 4 deg while the lean per degree stays elastic (the 9 x 15
   wall with s = 10 mm 2.1 % low, and no faster on its own).  benchmarks/speed_error.md
   "Quasi-static tilt" has their numbers (commit 3d3558e has their code).
3. the first failing increment is bisected: each trial starts from the saved state of the last
   angle in equilibrium (poses, velocities, contacts with their shear history:
   Simulation.save_point / restore_point) until the bracket is narrower than ``resolution``;
   lambda = tan(theta_eq), theta_eq the last angle in equilibrium (the true limit lies in
   [theta_eq, theta_eq + resolution]);
4. from the state at theta_eq the table turns to the first failing increment's angle and the
   run goes on
   dynamically (no local damping, true masses) for ``collapse.after`` s or until a block moved
   ``collapse.stop``, so that the mechanism shows in the frames; where no block has moved
   ``collapse.stop`` by then, the table turns on by ``increment`` every ``collapse.after`` s
   until one has (a wall that creeps past its limit).  The mechanism is read from the motion
   after theta_eq (postprocess.tilt.tilt_mechanism), not from the start: the joints' seating
   and creep while the wall was in equilibrium are not the collapse.

Density scaling is not used: the relaxation runs at the true masses and the critical step.
Frames: one at the start, one at every angle found in equilibrium, then every
``run.output_interval`` of the dynamic part.
"""

from __future__ import annotations

import math

import numpy as np

from dem.collapse import motion_measure
from dem.run.steps import Advance

CHECK_STEPS = 100  # steps between two looks at R and the motion while relaxing
CALM_CHECKS = 3    # equilibrium: R below the tolerance and every block at rest at this many
                   # looks in a row (R alone can dip below it while a wall swings through)
REST_MOTION = 0.1  # at max_relax_time, blocks that moved less than this x confirm (0.5 mm) in the
                   # relaxation are in equilibrium whatever R and the speeds say: R has a floor
                   # of ~1e-4 on some walls and ~1e-2 on the box models (nanometre joint
                   # vibrations, light blocks that rattle at mm/s without going anywhere); a
                   # sliding limit exceeded by 0.03 deg moves 0.5 mm in 1 s of relaxation (about
                   # 4.5 mm in the default max_relax_time, 3 s: the warped-bed walls seat by
                   # 1.5-3 mm over 1.5-2 s near their limit, which 1 s read as a failure)


class QuasiStaticTilt:
    def __init__(self, case, scene, loading, sim, recording, on_progress=None,
                 max_steps: int | None = None):
        self.spec = case.loading.quasi_static
        self.collapse = case.loading.collapse
        self.max_angle = case.loading.max_angle
        self.t_limit = case.run.duration
        self.step_limit = max_steps  # smoke runs: stop the search there
        self.loading, self.sim, self.recording = loading, sim, recording
        self.radius = 0.5 * np.linalg.norm(scene.size, axis=1)
        self.n = scene.n_blocks
        self.on_progress = on_progress
        self.relaxations = 0
        self.relax_steps = 0
        self.angles: list[dict] = []  # every angle tried: angle, equilibrium, R, time, steps
        self.undecided = False  # run.duration or the step limit ran out during a relaxation
        self.lookahead_steps = 0  # steps spent looking for a re-seating that did not come

    # -- one angle -----------------------------------------------------------------------
    def relax(self, angle: float) -> tuple[bool, float, float]:
        """Turn to ``angle`` and relax; returns (in equilibrium, R, largest motion in m), its
        advances yielded (a steppable phase: dem.run.steps).  When
        run.duration or the step limit runs out first, the angle is undecided:
        ``self.undecided`` is set and the search ends there."""
        sim, sp = self.sim, self.spec
        st = sim.read_state("pos", "quat")
        pos0, quat0 = st.pos[: self.n].copy(), st.quat[: self.n].copy()
        t0, steps0 = sim.t, sim.step_count
        self.loading.turn(t0, angle, sp.ramp_time)
        sim.set_local_damping(sp.local_damping)
        ok, ratio, moved, why = False, math.inf, 0.0, "max_relax_time"
        calm = 0
        failed_at = None  # (snapshot, R, motion) where the motion first reached confirm
        while True:
            yield Advance(sim, self._chunk(CHECK_STEPS), self.loading)
            ratio = sim.unbalanced_force_ratio(self.loading.gravity(np.array([sim.t]))[0])
            st = sim.read_state("pos", "quat")  # after the advance (on a device: copied now)
            moved = float(motion_measure(pos0, quat0, st.pos[: self.n], st.quat[: self.n],
                                         self.radius).max())
            if moved >= self.collapse.confirm and failed_at is None:
                # look ahead for a new equilibrium (a re-seating); without one the relaxation
                # is put back to this point, so that the search goes on exactly as it did when
                # confirm ended the relaxation (perfect walls: results unchanged bit for bit)
                failed_at = (sim.snapshot(), ratio, moved, sim.t)
            if moved >= self.collapse.stop:
                why = "moved"  # the motion kept growing: a mechanism
                break
            if failed_at is not None and sim.t - failed_at[3] >= self.collapse.after:
                why = "moved"  # no new equilibrium within collapse.after (dem.collapse)
                break
            turned = sim.t - t0 >= sp.ramp_time
            at_rest = self._speed() < self.collapse.onset_speed
            calm = calm + 1 if turned and ratio < sp.tolerance and at_rest else 0
            if calm >= CALM_CHECKS:
                # a block that moved confirm or more and came to rest again re-seated on its
                # beds (free play of warped beds): a new equilibrium, not a mechanism
                ok = True
                why = "re-seated" if moved >= self.collapse.confirm else "equilibrium"
                break
            if self._out_of_time():
                why, self.undecided = "out of time", True
                break
            if sim.t - t0 >= sp.max_relax_time:
                if moved < REST_MOTION * self.collapse.confirm:
                    ok, why = True, "at rest"
                break
        lookahead = None
        if not ok and failed_at is not None:  # no new equilibrium: a loss of equilibrium
            lookahead = {"lookahead_s": sim.t, "lookahead_motion_m": moved}
            steps_end = sim.step_count
            snap, ratio, moved, _ = failed_at
            sim.restore(snap)
            lookahead["lookahead_s"] -= sim.t
            self.lookahead_steps += steps_end - sim.step_count
            why, self.undecided = "moved", False
        self.relaxations += 1
        self.relax_steps += sim.step_count - steps0
        self.angles.append({"angle_deg": angle, "equilibrium": ok, "why": why,
                            "unbalanced_ratio": ratio, "motion_m": moved,
                            "speed_m_s": self._speed(),
                            "relax_time_s": sim.t - t0, **(lookahead or {})})
        if self.on_progress is not None:
            self.on_progress(angle)
        return ok, ratio, moved

    def _stopped_note(self) -> str:
        return ("run.duration or the step limit ran out before equilibrium was lost (raise "
                "run.duration: a quasi-static tilt simulates a few seconds per wall)")

    def _chunk(self, k: int) -> int:
        """k steps, or fewer to stop exactly at the step limit."""
        if self.step_limit is None:
            return k
        return max(1, min(k, self.step_limit - self.sim.step_count))

    def _out_of_time(self) -> bool:
        """run.duration of simulated time, or the step limit of a smoke run, is spent."""
        return self.sim.t >= self.t_limit or (self.step_limit is not None
                                              and self.sim.step_count >= self.step_limit)

    def _speed(self) -> float:
        """Largest block speed bound |v| + r |omega|, m/s."""
        st = self.sim.read_state("vel", "omega")
        return float((np.linalg.norm(st.vel[: self.n], axis=1)
                      + self.radius * np.linalg.norm(st.omega[: self.n], axis=1)).max())

    # -- the search ----------------------------------------------------------------------
    def run(self) -> dict:
        """The search, then the dynamic continuation; returns summary.json's ``collapse``.  A
        steppable phase (dem.run.steps): its advances are yielded (``yield from``)."""
        sp, sim, rec = self.spec, self.sim, self.recording
        start = float(self.loading.start_angle)
        ok, ratio, _ = yield from self.relax(start)
        if not ok:
            return self._result(False, None, start, ratio, self._stopped_note() if
                                self.undecided else "no equilibrium at the start angle")
        rec.frame()
        eq, eq_ratio, saved = start, ratio, sim.save_point()
        fail = None
        while fail is None and eq < self.max_angle and not self._out_of_time():
            trial = min(eq + sp.increment, self.max_angle)
            ok, ratio, _ = yield from self.relax(trial)
            if ok:
                eq, eq_ratio, saved = trial, ratio, sim.save_point()
                rec.frame()
            elif not self.undecided:
                fail = first_fail = trial
        if fail is None:
            note = "max_angle reached in equilibrium" if eq >= self.max_angle else \
                self._stopped_note()
            return self._result(False, None, eq, eq_ratio, note)
        while fail - eq > sp.resolution and not self._out_of_time():
            sim.restore_point(saved)
            mid = 0.5 * (eq + fail)
            ok, ratio, _ = yield from self.relax(mid)
            if self.undecided:
                break
            if ok:
                eq, eq_ratio, saved = mid, ratio, sim.save_point()
                rec.frame()
            else:
                fail = mid
        sim.restore_point(saved)
        return (yield from self._continue_dynamically(eq, fail, eq_ratio, first_fail))

    def _continue_dynamically(self, eq: float, fail: float, eq_ratio: float,
                              to_angle: float) -> dict:
        """From the state at ``eq``, the table turns to ``to_angle`` (the first increment that
        failed, so that the mechanism develops in a short time) and the run goes on for
        ``collapse.after`` s or until a block moved ``collapse.stop``.  Where no block has moved
        ``collapse.stop`` by then (a wall that creeps just past its limit: the warped-bed walls
        of the calibration moved 0.3-4 mm in that second, too little to show a mechanism), the
        table keeps turning by ``increment`` every ``collapse.after`` s, as the test's table kept
        turning, until a block moved ``collapse.stop``, ``max_angle`` is reached or run.duration
        runs out.  ``dynamic_turns`` counts those extra turns and ``dynamic_end_angle_deg`` is
        the angle the run ended at."""
        sim, rec, col = self.sim, self.recording, self.collapse
        sim.set_local_damping(0.0)
        self.loading.turn(sim.t, to_angle, self.spec.ramp_time)
        st = sim.read_state("pos", "quat")
        pos0, quat0 = st.pos[: self.n].copy(), st.quat[: self.n].copy()
        t0 = sim.t
        first_moving = None
        rec.frames_from(t0)
        angle, turns, window_end = to_angle, 0, t0 + col.after
        m = np.zeros(self.n)
        while True:
            while sim.t < window_end and not self._out_of_time():
                yield Advance(sim, self._chunk(rec.steps_to_next(window_end)), self.loading)
                rec.after_advance(last=sim.t >= window_end)
                st = sim.read_state("pos", "quat")  # after the advance
                m = motion_measure(pos0, quat0, st.pos[: self.n], st.quat[: self.n],
                                   self.radius)
                if first_moving is None and m.max() >= col.confirm:
                    first_moving = np.flatnonzero(m >= 0.5 * col.confirm)
                if m.max() >= col.stop:
                    break
            if m.max() >= col.stop or col.after <= 0.0 or angle >= self.max_angle \
                    or self._out_of_time():
                break
            angle = min(angle + self.spec.increment, self.max_angle)  # keep turning
            self.loading.turn(sim.t, angle, self.spec.ramp_time)
            turns += 1
            window_end = sim.t + col.after
        rec.frame_at_stop()
        st = sim.read_state("pos", "quat")
        m = motion_measure(pos0, quat0, st.pos[: self.n], st.quat[: self.n], self.radius)
        moved = np.flatnonzero(m >= 0.5 * col.confirm)
        out = self._result(True, fail, eq, eq_ratio, None)
        out.update({"first_moving_blocks": [] if first_moving is None else first_moving.tolist(),
                    "moved_blocks": moved.tolist(), "n_moved": int(len(moved)),
                    "dynamic_from_s": t0, "dynamic_angle_deg": to_angle,
                    "dynamic_turns": turns, "dynamic_end_angle_deg": angle,
                    "dynamic_max_motion_m": float(m.max())})
        return out

    def _result(self, detected: bool, fail, eq: float, eq_ratio: float, note) -> dict:
        sp = self.spec
        out = {"detected": detected, "method": "quasi_static",
               "angle_deg": eq, "load_factor": math.tan(math.radians(eq)),
               "failed_angle_deg": fail,
               "resolution_deg": (fail - eq) if fail is not None else None,
               "unbalanced_ratio_at_angle": eq_ratio,
               "criterion": {"tolerance": sp.tolerance, "local_damping": sp.local_damping,
                             "increment_deg": sp.increment, "resolution_deg": sp.resolution,
                             "max_relax_time_s": sp.max_relax_time,
                             "confirm_m": self.collapse.confirm},
               "relaxations": self.relaxations, "relax_steps": self.relax_steps,
               "lookahead_steps": self.lookahead_steps,
               "angles": self.angles}
        if not detected:
            out.update({"last_angle_deg": eq, "note": note})
        return out
