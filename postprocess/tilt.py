"""Results of a tilting-table run: mechanism and limit analysis next to the simulated lambda.

``tilt_mechanism`` is handed to the run loop by ``dem run`` (dem.commands.run) and reads the
finished run; ``tilt_results`` does the same from a run directory's frames for ``dem post``
(the collapse replayed with the run loop's detector, dem.collapse.replay).
"""

from __future__ import annotations

import numpy as np

from postprocess.limit_analysis import in_plane_limit
from postprocess.mechanisms import in_plane_mechanism, out_of_plane_mechanism


def wall_layout(scene) -> tuple[str, dict] | None:
    """(group, layout) of the wall a builder laid in the scene (dem.scene.Scene.layout: the unit
    vector along the wall, stagger s, course height h, length L and height H in m, L/H, s/h), or
    None (explicit blocks, or a facade)."""
    for group, lay in scene.layout.items():
        if lay.get("kind") == "wall":
            return group, lay
    return None


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
    wall = wall_layout(scene)
    if wall is None:
        out["kind"] = "blocks"
        out["n_moving"] = int(moved_mask.sum())
        return out
    in_plane = abs(load_dir @ np.asarray(wall[1]["along"])) > 0.7
    if not in_plane:
        out["kind"] = "out-of-plane"
        out.update(out_of_plane_mechanism(scene, pos0, quat0, pos, quat, load_dir,
                                          facade_group=wall[0]))
        return out
    out["kind"] = "in-plane"
    geom = wall[1]
    normal = np.cross([0.0, 0.0, 1.0], load_dir)
    out.update(in_plane_mechanism(scene, pos0, quat0, pos, quat, moved_mask, load_dir, normal,
                                  geom["stagger"], geom["course_height"]))
    la = in_plane_limit(case.material.friction, geom["s_over_h"], geom["l_over_h"])
    out["limit_analysis"] = {**la.as_dict(), "s_over_h": geom["s_over_h"],
                             "l_over_h": geom["l_over_h"], "mu": case.material.friction}
    return out


def tilt_mechanism(case, scene, frames: dict, summary: dict) -> dict:
    """``{"mechanism": ...}`` of a tilt run whose summary says a collapse was detected (else
    ``{}``): the mechanism read at the classification frame (see classification_frame).
    ``frames``: the arrays of frames.npz (t, pos, quat)."""
    if not (summary.get("collapse") or {}).get("detected"):
        return {}
    from dem.loading import loading_from_case

    pos, quat = frames["pos"], frames["quat"]
    k = classification_frame(scene, pos, quat)
    mech = classify(case, scene, pos[0], quat[0], pos[k], quat[k],
                    loading_from_case(case).load_direction)
    mech["frame_time_s"] = float(frames["t"][k])
    return {"mechanism": mech}


def tilt_results(case, scene, frames: dict) -> dict:
    """Collapse (the run loop's detector, replayed on the frames) and mechanism of a tilt run,
    from the arrays of its frames.npz (t, tilt_angle, pos, quat, vel, omega)."""
    from dem.collapse import CollapseDetector, replay

    det = CollapseDetector.for_scene(scene, case.loading.collapse)
    out = {"collapse": replay(det, frames["t"], frames["tilt_angle"], frames["pos"],
                              frames["quat"], frames["vel"], frames["omega"])}
    out.update(tilt_mechanism(case, scene, frames, out))
    return out


def analyze_tilt_run(run_dir) -> dict:
    """Collapse and mechanism of a tilt run directory, recomputed from its frames.npz and
    case.json (:func:`tilt_results`: the run loop's detector replayed, the same mechanism
    analysis); written to analysis.json."""
    from pathlib import Path

    from dem.output.atomic import write_json
    from postprocess.block_kinematics import angular_velocity
    from postprocess.shake_signals import ShakeAnalysisError, load_run

    run_dir = Path(run_dir)
    case, scene = load_run(run_dir)
    path = run_dir / "frames.npz"
    if not path.is_file():
        raise ShakeAnalysisError(f"{path}: missing")
    with np.load(path) as fr:
        frames = {k: fr[k] for k in fr.files}
    if "tilt_angle" not in frames:
        raise ShakeAnalysisError(f"{path}: no tilt_angle array (not a tilt run?)")
    if "vel" not in frames:
        frames["vel"] = np.gradient(frames["pos"], frames["t"], axis=0)
    if "omega" not in frames:
        frames["omega"] = angular_velocity(frames["t"], frames["quat"])
    res = tilt_results(case, scene, frames)
    out = {"kind": "tilt", "case": case.name, "collapse": res["collapse"],
           "mechanism": res.get("mechanism")}
    write_json(run_dir / "analysis.json", out, indent=1, strict=True)
    return out
