"""Collapse detection for tilting-table runs (thesis Chapter 3: the tilt stops "as soon as
collapse was initiated"; lambda = tan(angle at incipient collapse)).

Reference pose: the first frame the detector is fed, i.e. the pose when the loading starts.  For
an imperfect scene that is the *settled* pose (dem.run.settle runs before the recording starts):
settling turns bricks on their warped beds by degrees, which is not the collapse (a
3-brick column on 0.3 mm beds turns 2.6-2.9 deg while settling).  For a perfect scene the first frame is the built pose, as before.

Motion measure of block i relative to the table (a bound on how far any of its points moved):
    M_i(t) = |x_i(t) - x_ref,i| + r_i * angle(q_ref,i -> q_i(t))     (m), r_i = half diagonal
Joints deform elastically by micrometres, so millimetre motions mean blocks are moving.

Speed measure: V_i = |v_i| + r_i |omega_i| (m/s, bounds the speed of any point of the block).

Rule (checked at every output frame).  Collapse means a *mechanism*: motion that keeps growing,
or no new equilibrium.  A scene with free play (warped beds: a 3-brick column
with 0.3 mm unevenness snaps through 4 mm at the top at 1.4-2.1 deg, then stands until 25 deg)
re-seats without collapsing, and a fixed displacement threshold cannot tell the two apart:
  * a *candidate* is the first frame where max_i M_i >= ``confirm`` (default 5 mm);
  * the candidate is *dismissed as a re-seating* when, before max M reaches ``stop`` and within
    ``after`` s of the candidate, every block is at rest (V_i <= ``onset_speed``) at every frame
    for ``REST_TIME`` s: a new equilibrium.  The reference moves to that resting frame (the
    re-seating is listed in ``reseats``) and the watch starts again;
  * otherwise the collapse is *confirmed* at the candidate frame: max M reached ``stop``
    (default 30 mm; the motion kept growing) or ``after`` s (default 1 s) passed without a
    new equilibrium.  The run stops there, which is when it stopped before the re-seating rule
    (confirmation at ``confirm``, then ``after`` s or ``stop``), so a collapse that never comes
    to rest gives the same frames as before;
  * the *collapsing blocks* are those with M_i >= confirm / 2 at the candidate frame;
  * the collapse *onset* is the last frame before confirmation, and not before the reference,
    at which every collapsing block was at rest, V_i <= ``onset_speed`` (default 1 mm/s;
    quasi-static elastic motion is um/s); the collapse angle and load factor lambda = tan(angle)
    are taken there.  This reads "incipient collapse" instead of the angle at which the collapse
    became visible, and it is not fooled by an earlier slip that stopped.  For sliding at
    2 deg/s the speed reaches 1 mm/s about 0.1 s (0.2 deg) after the true onset.  The true onset
    lies between the onset frame and the next one (``onset_bracket_deg``);
  * an onset that cannot be resolved is reported as such (``onset_resolved: false``,
    ``load_factor`` and ``angle_deg`` null, ``onset_note`` says why), never as lambda = 0: no
    frame at rest between the reference and the confirmation, or the collapsing blocks were
    at rest only in the loading's first frame (the collapse began within the first frame
    interval: the scene was unstable at the start angle, or the frames are too far apart for
    the rate, e.g. 20 deg a frame at 2000 deg/s).
"""

from __future__ import annotations

from dataclasses import dataclass, field

import numpy as np

REST_TIME = 0.1  # s: a new equilibrium is every block at rest (V <= onset_speed) at every frame
                 # over this long (a rocking or bouncing block passes through V = 0 only for an
                 # instant; at 2 deg/s the table turns 0.2 deg meanwhile)


def motion_measure(pos0, quat0, pos, quat, radius) -> np.ndarray:
    """M_i (m) for every block: displacement plus radius times rotation angle."""
    c = np.clip(np.abs(np.sum(quat * quat0, axis=-1)), 0.0, 1.0)
    return np.linalg.norm(pos - pos0, axis=-1) + radius * 2.0 * np.arccos(c)


@dataclass
class CollapseDetector:
    pos0: np.ndarray | None   # reference poses; None: the first frame fed (the settled pose)
    quat0: np.ndarray | None
    radius: np.ndarray
    onset_speed: float = 1e-3
    confirm: float = 5e-3
    after: float = 1.0
    stop: float = 0.03
    history: list = field(default_factory=list)   # (t, angle, M [N], V [N])
    confirmed_at: int | None = None
    candidate_at: int | None = None  # first frame with max M >= confirm since the reference
    ref_index: int = 0               # frame of the reference pose
    rest_since: float | None = None  # time of the first frame of the current spell at rest
    reseats: list = field(default_factory=list)  # re-seatings dismissed (module docstring)

    @classmethod
    def for_scene(cls, scene, settings) -> "CollapseDetector":
        """A detector for a scene (radius = half diagonal of each block; the reference pose is
        the first frame fed, see the module docstring) with the thresholds of ``settings`` (a
        case's ``loading.collapse``: onset_speed, confirm, after, stop)."""
        return cls(None, None, 0.5 * np.linalg.norm(scene.size, axis=1), settings.onset_speed,
                   settings.confirm, settings.after, settings.stop)

    def update(self, t: float, angle: float, pos, quat, vel, omega) -> bool:
        """Feed one frame; returns True when the run should stop."""
        if self.pos0 is None:
            self.pos0, self.quat0 = np.array(pos, dtype=float), np.array(quat, dtype=float)
            self.ref_index = len(self.history)
        m = motion_measure(self.pos0, self.quat0, pos, quat, self.radius)
        v = np.linalg.norm(vel, axis=-1) + self.radius * np.linalg.norm(omega, axis=-1)
        self.history.append((t, angle, m, v))
        k = len(self.history) - 1
        if self.confirmed_at is None:
            if self.candidate_at is None and m.max() >= self.confirm:
                self.candidate_at, self.rest_since = k, None
            if self.candidate_at is not None:
                t_cand = self.history[self.candidate_at][0]
                if m.max() >= self.stop or t - t_cand >= self.after:
                    self.confirmed_at = self.candidate_at
                elif v.max(initial=0.0) <= self.onset_speed:
                    if self.rest_since is None:
                        self.rest_since = t
                    if t - self.rest_since >= REST_TIME:
                        self._reseat(k, pos, quat)
                else:
                    self.rest_since = None
        if self.confirmed_at is None:
            return False
        t_conf = self.history[self.confirmed_at][0]
        return m.max() >= self.stop or t - t_conf >= self.after

    def _reseat(self, k: int, pos, quat) -> None:
        """The candidate came to a new equilibrium: a re-seating, not a collapse; measure from
        frame ``k`` on."""
        t_c, a_c, m_c, _ = self.history[self.candidate_at]
        t, a, m, _ = self.history[k]
        self.reseats.append({"candidate_time_s": float(t_c), "candidate_angle_deg": float(a_c),
                             "rest_time_s": float(t), "rest_angle_deg": float(a),
                             "max_motion_m": float(m.max()),
                             "blocks": np.flatnonzero(m_c >= 0.5 * self.confirm).tolist()})
        self.pos0, self.quat0 = np.array(pos, dtype=float), np.array(quat, dtype=float)
        self.ref_index, self.candidate_at, self.rest_since = k, None, None

    def result(self) -> dict:
        """Collapse summary (angles in degrees, times in s, block indices in case order)."""
        extra = {"reference_time_s": float(self.history[self.ref_index][0])
                 if self.history else 0.0, "reseats": self.reseats}
        if self.confirmed_at is None:
            last = self.history[-1] if self.history else (0.0, 0.0, np.zeros(0))
            return {"detected": False, "max_motion_m": float(last[2].max(initial=0.0)),
                    "last_angle_deg": float(last[1]), **extra}
        t_c, a_c, m_c, _ = self.history[self.confirmed_at]
        moving = np.flatnonzero(m_c >= 0.5 * self.confirm)
        k_on = None
        for k in range(self.confirmed_at - 1, self.ref_index - 1, -1):
            if self.history[k][3][moving].max() <= self.onset_speed:
                k_on = k
                break
        note = None
        if k_on is None:
            note = ("the collapsing blocks were never at rest between the reference pose and "
                    "the confirmation: the onset cannot be resolved")
        elif k_on == 0:
            note = ("the collapsing blocks were at rest only at the first frame: the collapse "
                    "began within the first frame interval (unstable at the start angle, or "
                    "frames too far apart for the tilt rate); the onset cannot be resolved")
        resolved = note is None
        k_lo = self.ref_index if k_on is None else k_on
        bracket = [float(self.history[k_lo][1]),
                   float(self.history[min(k_lo + 1, self.confirmed_at)][1])]
        t_on, a_on = self.history[k_on][:2] if resolved else (None, None)
        m_end = self.history[-1][2]
        moved_end = np.flatnonzero(m_end >= 0.5 * self.confirm)
        return {
            "detected": True,
            "onset_resolved": resolved,
            "onset_note": note,
            "onset_time_s": None if t_on is None else float(t_on),
            "angle_deg": None if a_on is None else float(a_on),
            "load_factor": None if a_on is None else float(np.tan(np.radians(a_on))),
            "onset_bracket_deg": bracket,
            "confirm_time_s": float(t_c),
            "confirm_angle_deg": float(a_c),
            "confirm_load_factor": float(np.tan(np.radians(a_c))),
            "first_moving_blocks": moving.tolist(),
            "moved_blocks": moved_end.tolist(),
            "n_moved": int(len(moved_end)),
            "thresholds": {"onset_speed_m_s": self.onset_speed, "confirm_m": self.confirm,
                           "stop_m": self.stop, "after_s": self.after,
                           "rest_time_s": REST_TIME},
            **extra,
        }


def replay(detector: CollapseDetector, t, angle, pos, quat, vel, omega) -> dict:
    """Feed the frames of a finished run (t [T], angle [T] in deg, pos/vel/omega [T,N,3],
    quat [T,N,4]) to a fresh detector; returns its result (what the run loop wrote)."""
    for k in range(len(t)):
        detector.update(float(t[k]), float(angle[k]), pos[k], quat[k], vel[k], omega[k])
    return detector.result()
