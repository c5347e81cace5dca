"""Stop phase: when the loop ends.

A run stops at ``run.duration``, at the step limit (``max_steps``, smoke runs), or, on a
constant-rate tilt with ``loading.collapse.enabled``, once the collapse detector (dem.collapse)
has seen the collapse confirmed and the run gone on for ``collapse.after`` s or a block moved
``collapse.stop``.  (A quasi-static tilt ends itself: dem.run.quasi_static.)
The detector sees every recorded frame (it listens to the recording), so its result, written to
summary.json as ``collapse``, is the one ``dem post`` gets by replaying frames.npz.  Its reference
pose is the first recorded frame, which the recording takes after an imperfect scene settled
(dem.run.settle): the stop rule is built before settling, so it must not take the scene's built
poses (settling turned the bricks of a 3-brick column by 2.6-2.9 deg, 4-6 mm of
the 5 mm budget, and the collapse was "confirmed" at frame 0).
"""

from __future__ import annotations

from dem.case import Case
from dem.collapse import CollapseDetector
from dem.loading import HeldTilt, Loading, Tilt
from dem.scene import Scene


class StopRule:
    def __init__(self, case: Case, scene: Scene, loading: Loading, max_steps: int | None):
        self.t_end = case.run.duration
        self.step_limit = int(max_steps) if max_steps is not None else None
        self.detector = None
        self.collapse_stop = False
        if isinstance(loading, Tilt) and not isinstance(loading, HeldTilt) and \
                case.loading.collapse.enabled:
            self.detector = CollapseDetector.for_scene(scene, case.loading.collapse)

    def listen(self, t, angle, pos, quat, vel, omega) -> None:
        """Frame listener (dem.run.record.Recording.listeners)."""
        if self.detector is not None and self.detector.update(t, angle, pos, quat, vel, omega):
            self.collapse_stop = True

    def limit_steps(self, sim, k: int) -> int:
        return k if self.step_limit is None else min(k, self.step_limit - sim.step_count)

    def at_end(self, sim) -> bool:
        """The end time or the step limit is reached."""
        return sim.t >= self.t_end - 1e-12 * self.t_end or (
            self.step_limit is not None and sim.step_count >= self.step_limit)

    def results(self) -> dict:
        """What the stop rule adds to summary.json (``collapse`` of a tilt run)."""
        return {"collapse": self.detector.result()} if self.detector is not None else {}
