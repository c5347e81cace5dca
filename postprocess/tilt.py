"""Results of a tilting-table run: mechanism and limit analysis next to the simulated lambda.

Called by the run loop at the end of a tilt run (``dem.runner``) and usable on saved frames.
"""

from __future__ import annotations

import numpy as np

from postprocess.limit_analysis import in_plane_limit
from postprocess.mechanisms import in_plane_mechanism, out_of_plane_mechanism


def wall_geometry(case) -> dict | None:
    """Stagger s, course height h, length L and height H (m) of a case's built wall, or None."""
    spec = case.scene.wall
    if spec is None:
        return None
    from dem.builders.bricks import brick as as_brick

    b = as_brick(spec.brick)
    unit, _, h = b.dims(spec.laying)
    s = spec.stagger if spec.stagger is not None else unit / 2
    if spec.bond == "english":
        s = unit / 4  # quarter-brick lap of English bond
    return {"stagger": s, "course_height": h, "length": spec.length * unit,
            "height": spec.courses * h, "l_over_h": spec.length * unit / (spec.courses * h),
            "s_over_h": s / h}


CLASSIFY_MOTION = 0.01  # m: mechanisms are read when a block has first moved this much
MOVING_FRACTION = 0.3  # a block belongs to the collapsing portion if it moved this fraction of the
                       # largest motion at that frame


def classification_frame(scene, pos, quat, level: float = CLASSIFY_MOTION) -> int:
    """Index of the first frame at which some block moved ``level`` (incipient collapse: the
    mechanism has formed but not yet spread), or the last frame."""
    from dem.collapse import motion_measure

    r = 0.5 * np.linalg.norm(scene.size, axis=1)
    for k in range(len(pos)):
        if motion_measure(pos[0], quat[0], pos[k], quat[k], r).max() >= level:
            return k
    return len(pos) - 1


def classify(case, scene, pos0, quat0, pos, quat, load_dir) -> dict:
    """Mechanism (in plane or out of plane) from the poses at one frame (see
    classification_frame) and, for walls loaded in plane, eq 3-1..3-3."""
    from dem.collapse import motion_measure

    m = motion_measure(pos0, quat0, pos, quat, 0.5 * np.linalg.norm(scene.size, axis=1))
    moved_mask = m >= MOVING_FRACTION * m.max() if m.max() > 0 else np.zeros(len(m), bool)
    names = list(scene.group_names)
    load_dir = np.asarray(load_dir, float)
    out: dict = {"max_motion_m": float(m.max())}
    if "facade" in names:
        out["kind"] = "out-of-plane"
        out.update(out_of_plane_mechanism(scene, pos0, quat0, pos, quat, load_dir))
        return out
    geom = wall_geometry(case)
    if geom is None:
        out["kind"] = "blocks"
        out["n_moving"] = int(moved_mask.sum())
        return out
    in_plane = abs(load_dir[0]) > 0.7  # builder walls run along x
    if not in_plane:
        out["kind"] = "out-of-plane"
        out.update(out_of_plane_mechanism(scene, pos0, quat0, pos, quat, load_dir,
                                          facade_group=spec_group(case)))
        return out
    out["kind"] = "in-plane"
    normal = np.cross([0.0, 0.0, 1.0], load_dir)
    out.update(in_plane_mechanism(scene, pos0, quat0, pos, quat, moved_mask, load_dir, normal,
                                  geom["stagger"], geom["course_height"]))
    la = in_plane_limit(case.material.friction, geom["s_over_h"], geom["l_over_h"])
    out["limit_analysis"] = {**la.as_dict(), "s_over_h": geom["s_over_h"],
                             "l_over_h": geom["l_over_h"], "mu": case.material.friction}
    return out


def tilt_results(case, scene, t, angle, pos, quat, vel, omega) -> dict:
    """Collapse (dem.collapse rule, replayed on the frames) and mechanism of a tilt run.

    Used by the run loop for summary.json and by ``dem post``: the same frames give the same
    answer.  Arrays: t [T], angle [T] (deg), pos/vel/omega [T,N,3], quat [T,N,4].
    """
    from dem.collapse import CollapseDetector
    from dem.loading import loading_from_case

    cs = case.loading.collapse
    det = CollapseDetector(pos[0], quat[0], 0.5 * np.linalg.norm(scene.size, axis=1),
                           cs.onset_speed, cs.confirm, cs.after, cs.stop)
    for k in range(len(t)):
        det.update(float(t[k]), float(angle[k]), pos[k], quat[k], vel[k], omega[k])
    out = {"collapse": det.result()}
    if out["collapse"]["detected"]:
        k = classification_frame(scene, pos, quat)
        mech = classify(case, scene, pos[0], quat[0], pos[k], quat[k],
                        loading_from_case(case).load_direction)
        mech["frame_time_s"] = float(t[k])
        out["mechanism"] = mech
    return out


def spec_group(case) -> str:
    """Group name of a case's built wall (a lone wall tilted out of plane is a facade)."""
    return case.scene.wall.group if case.scene.wall is not None else "wall"
