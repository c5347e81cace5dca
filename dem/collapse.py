"""Collapse detection for tilting-table runs (thesis Chapter 3: the tilt stops "as soon as
collapse was initiated"; lambda = tan(angle at incipient collapse)).

Motion measure of block i relative to the table (a bound on how far any of its points moved):
    M_i(t) = |x_i(t) - x_i(0)| + r_i * angle(q_i(0) -> q_i(t))        (m), r_i = half diagonal
Joints deform elastically by micrometres, so millimetre motions mean blocks are moving.

Speed measure: V_i = |v_i| + r_i |omega_i| (m/s, bounds the speed of any point of the block).

Rule (checked at every output frame):
  * collapse is *confirmed* at the first frame where max_i M_i >= ``confirm`` (default 5 mm):
    motion large enough not to be elastic and sustained long enough to build up (a block that
    slips a little and stops never reaches it);
  * the *collapsing blocks* are those with M_i >= confirm / 2 at that frame;
  * the collapse *onset* is the last frame before confirmation at which every collapsing block
    was at rest, V_i <= ``onset_speed`` (default 1 mm/s; quasi-static elastic motion is um/s);
    the collapse angle and load factor lambda = tan(angle) are taken there.  This reads
    "incipient collapse" instead of the angle at which the collapse became visible, and it is
    not fooled by an earlier slip that stopped (a displacement threshold would be).  For sliding
    at 2 deg/s the speed reaches 1 mm/s about 0.1 s (0.2 deg) after the true onset.
  * the run goes on for ``after`` seconds (default 1 s) or until max M reaches ``stop``
    (default 30 mm), so that the mechanism shows, then stops.
"""

from __future__ import annotations

from dataclasses import dataclass, field

import numpy as np


def motion_measure(pos0, quat0, pos, quat, radius) -> np.ndarray:
    """M_i (m) for every block: displacement plus radius times rotation angle."""
    c = np.clip(np.abs(np.sum(quat * quat0, axis=-1)), 0.0, 1.0)
    return np.linalg.norm(pos - pos0, axis=-1) + radius * 2.0 * np.arccos(c)


@dataclass
class CollapseDetector:
    pos0: np.ndarray
    quat0: np.ndarray
    radius: np.ndarray
    onset_speed: float = 1e-3
    confirm: float = 5e-3
    after: float = 1.0
    stop: float = 0.03
    history: list = field(default_factory=list)   # (t, angle, M [N], V [N])
    confirmed_at: int | None = None

    @classmethod
    def for_scene(cls, scene, settings) -> "CollapseDetector":
        """A detector for a scene (its initial poses, radius = half diagonal of each block) with
        the thresholds of ``settings`` (a case's ``loading.collapse``: onset_speed, confirm,
        after, stop)."""
        return cls(scene.position.copy(), scene.quat.copy(),
                   0.5 * np.linalg.norm(scene.size, axis=1), settings.onset_speed,
                   settings.confirm, settings.after, settings.stop)

    def update(self, t: float, angle: float, pos, quat, vel, omega) -> bool:
        """Feed one frame; returns True when the run should stop."""
        m = motion_measure(self.pos0, self.quat0, pos, quat, self.radius)
        v = np.linalg.norm(vel, axis=-1) + self.radius * np.linalg.norm(omega, axis=-1)
        self.history.append((t, angle, m, v))
        if self.confirmed_at is None and m.max() >= self.confirm:
            self.confirmed_at = len(self.history) - 1
        if self.confirmed_at is None:
            return False
        t_conf = self.history[self.confirmed_at][0]
        return m.max() >= self.stop or t - t_conf >= self.after

    def result(self) -> dict:
        """Collapse summary (angles in degrees, times in s, block indices in case order)."""
        if self.confirmed_at is None:
            last = self.history[-1] if self.history else (0.0, 0.0, np.zeros(0))
            return {"detected": False, "max_motion_m": float(last[2].max(initial=0.0)),
                    "last_angle_deg": float(last[1])}
        t_c, a_c, m_c, _ = self.history[self.confirmed_at]
        moving = np.flatnonzero(m_c >= 0.5 * self.confirm)
        k_on = 0
        for k in range(self.confirmed_at - 1, -1, -1):
            if self.history[k][3][moving].max() <= self.onset_speed:
                k_on = k
                break
        t_on, a_on = self.history[k_on][:2]
        m_end = self.history[-1][2]
        moved_end = np.flatnonzero(m_end >= 0.5 * self.confirm)
        return {
            "detected": True,
            "onset_time_s": float(t_on),
            "angle_deg": float(a_on),
            "load_factor": float(np.tan(np.radians(a_on))),
            "confirm_time_s": float(t_c),
            "confirm_angle_deg": float(a_c),
            "confirm_load_factor": float(np.tan(np.radians(a_c))),
            "first_moving_blocks": moving.tolist(),
            "moved_blocks": moved_end.tolist(),
            "n_moved": int(len(moved_end)),
            "thresholds": {"onset_speed_m_s": self.onset_speed, "confirm_m": self.confirm,
                           "stop_m": self.stop},
        }


def replay(detector: CollapseDetector, t, angle, pos, quat, vel, omega) -> dict:
    """Feed the frames of a finished run (t [T], angle [T] in deg, pos/vel/omega [T,N,3],
    quat [T,N,4]) to a fresh detector; returns its result (what the run loop wrote)."""
    for k in range(len(t)):
        detector.update(float(t[k]), float(angle[k]), pos[k], quat[k], vel[k], omega[k])
    return detector.result()
