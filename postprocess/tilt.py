"""Results of a tilting-table run: mechanism and limit analysis next to the simulated lambda,
and the lean of the wall against the table angle.

``tilt_mechanism`` is handed to the run loop by ``dem run`` (dem_cli.commands.run) and reads the
finished run; ``tilt_results`` does the same from a run directory's frames for ``dem post``
(the collapse replayed with the run loop's detector, dem.collapse.replay; a quasi-static tilt's
collapse is the run's own).  ``classify`` works for any scene: a builder's wall or facade, or
explicit blocks (their courses, stagger and axis derived by postprocess.wall_geometry).
``plot_lean`` writes lean.png for both commands.
"""

from __future__ import annotations

from pathlib import Path

import numpy as np

from dem.output.plotting import agg_pyplot
from postprocess.limit_analysis import in_plane_limit
from postprocess.mechanisms import (CRACK_ANGLE_DEFINITION, collapsed_portion,
                                     in_plane_mechanism, out_of_plane_mechanism)
from postprocess.wall_geometry import WallGeometry, builder_geometry, derive_geometry


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


def wall_geometry(scene, moving, load_dir) -> WallGeometry:
    """The wall whose mechanism is read: the builder's wall (its layout) if the scene has one,
    else the blocks (not fixed) of the groups that hold the moving blocks, their geometry
    derived from the blocks (postprocess.wall_geometry)."""
    wall = wall_layout(scene)
    if wall is not None:
        return builder_geometry(scene, *wall)
    free = ~scene.fixed
    groups = np.unique(scene.group[moving & free] if (moving & free).any() else scene.group[free])
    return derive_geometry(scene, np.isin(scene.group, groups) & free, load_dir)


ISOLATION_GAP = 1e-3  # m: a block is isolated if no other free block comes this close to it


def isolated_blocks(scene) -> np.ndarray:
    """bool [N]: free blocks that touch no other free block (no other's bounding box comes
    within ISOLATION_GAP of theirs; dem.builders.checks.candidate_pairs, a sweep, so large
    scenes cost no N x N table): blocks standing alone on the table, not parts of a wall."""
    from dem.builders.checks import candidate_pairs, vertices

    v = vertices(scene)
    free = ~scene.fixed
    touching = np.zeros(scene.n_blocks, dtype=bool)
    for i, j in candidate_pairs(v.min(axis=1), v.max(axis=1), ISOLATION_GAP):
        if free[i] and free[j]:
            touching[i] = touching[j] = True
    return free & ~touching


def column_order(scene) -> np.ndarray | None:
    """The free blocks bottom to top if they stand as one column (at least two; each block's
    centre over the footprint of the one below, no two side by side: their heights overlap by
    less than half the lower one's), else None.  Fixed blocks (supports) are left out."""
    free = np.flatnonzero(~scene.fixed)
    if len(free) < 2:
        return None
    pos = np.asarray(scene.position, float)
    size = np.asarray(scene.size, float)
    order = free[np.argsort(pos[free, 2])]
    for lo, hi in zip(order[:-1], order[1:]):
        top_lo = pos[lo, 2] + 0.5 * size[lo, 2]
        if pos[hi, 2] - 0.5 * size[hi, 2] < top_lo - 0.5 * size[lo, 2]:
            return None  # side by side, not one on the other
        if np.any(np.abs(pos[hi, :2] - pos[lo, :2]) > 0.5 * size[lo, :2]):
            return None  # off the footprint below
    return order


def column_mechanism(scene, pos0, quat0, pos, quat, moved_mask, load_dir, order) -> dict:
    """A column's mechanism in words a user recognises: sliding / overturning / mixed (the
    share of rotation, in_plane_mechanism's measure) of the whole column ("at the base") or of
    its top k blocks ("at joint j": the bed joint above block j, counted from 1 at the bottom)."""
    normal = np.cross([0.0, 0.0, 1.0], load_dir)
    mech = in_plane_mechanism(scene, pos0, quat0, pos, quat, moved_mask, load_dir, normal)
    moving = moved_mask[order]
    n = len(order)
    lowest = int(np.argmax(moving)) if moving.any() else n
    base = mech["mechanism"]
    if lowest >= n:
        text = "none"
    elif lowest == 0:
        text = f"{base} of the whole column at its base"
    else:
        text = f"{base} of the top {n - lowest} of {n} blocks at joint {lowest}"
    return {"mechanism": text, "motion": base, "joint": lowest, "n_column_blocks": n,
            **{k: mech[k] for k in ("overturning_mass_fraction", "n_moving",
                                     "moving_mass_fraction")}}


def lone_wall_labels(oop: dict) -> dict:
    """out_of_plane_mechanism's result for a wall without returns (no facade, no wings): the
    facade labels (A, B1, D, B2, G: thesis Fig. 3-4, facades with wings) do not apply; the
    crack line in words: the whole wall overturning about its base, its top courses about a
    horizontal crack, or a wedge above a diagonal or arched crack."""
    out = {k: v for k, v in oop.items() if k not in ("mechanism", "wing_bricks_joined")}
    n, k, shape = oop["facade_courses"], oop["collapsed_courses"], oop["crack_shape"]
    if oop["mechanism"] == "none":
        text = "none"
    elif shape == "horizontal":
        text = "overturning of the whole wall at its base" if k >= n else \
            f"overturning of the top {k} of {n} courses (horizontal crack)"
    else:
        text = f"overturning of a {shape} wedge, up to {k} of {n} courses deep"
    out["mechanism"] = text
    out["wall_courses"] = out.pop("facade_courses")
    return out


def classify(case, scene, pos0, quat0, pos, quat, load_dir) -> dict:
    """Mechanism from the poses at one frame (see classification_frame), for any scene:

    * blocks standing alone (isolated_blocks: no other free block touches them): kind "block"
      (one moving) or "blocks", mechanism sliding / tipping / mixed from the share of rotation
      in their motion (in_plane_mechanism's measure); no wall labels;
    * a column (column_order: one block on another): kind "column", "overturning of the whole
      column at its base" or "... of the top k of n blocks at joint j" (column_mechanism);
    * a scene with a "facade" group: out of plane, A / B1 / D / B2 / G (out_of_plane_mechanism;
      the courses derived from the blocks where no builder laid them);
    * otherwise the wall (wall_geometry: a builder's, or derived from explicit blocks) is loaded
      in plane when the load is within ~45 deg of its axis: sliding / overturning / mixed with
      the overturning share, the main crack line and its angle (crack_angle_deg, defined in
      crack_angle_definition), and for a bond with a stagger eq 3-1..3-3; else out of plane:
      a wall without returns gets the crack line in words (lone_wall_labels; the facade labels
      are for facades with wings);
    * every scene: the collapsed portion (postprocess.mechanisms.collapsed_portion).
    """
    from dem.collapse import motion_measure

    m = motion_measure(pos0, quat0, pos, quat, 0.5 * np.linalg.norm(scene.size, axis=1))
    moved_mask = m >= MOVING_FRACTION * m.max() if m.max() > 0 else np.zeros(len(m), bool)
    names = list(scene.group_names)
    load_dir = np.asarray(load_dir, float)
    out: dict = {"max_motion_m": float(m.max())}
    if moved_mask.any() and isolated_blocks(scene)[moved_mask].all():
        # lone blocks (no wall): each slides or tips on its own; the share of rotation decides
        # as for a wall's blocks (in_plane_mechanism), the wall labels do not apply
        normal = np.cross([0.0, 0.0, 1.0], load_dir)
        mech = in_plane_mechanism(scene, pos0, quat0, pos, quat, moved_mask, load_dir, normal)
        out["kind"] = "block" if moved_mask.sum() == 1 else "blocks"
        out.update({k: mech[k] for k in ("mechanism", "overturning_mass_fraction", "n_moving",
                                         "moving_mass_fraction")})
        if out["mechanism"] == "overturning":
            out["mechanism"] = "tipping"
    elif column_order(scene) is not None:
        out["kind"] = "column"
        out.update(column_mechanism(scene, pos0, quat0, pos, quat, moved_mask, load_dir,
                                    column_order(scene)))
    elif "facade" in names:
        out["kind"] = "out-of-plane"
        free = ~scene.fixed
        course = scene.course if (scene.course[free] >= 0).all() else \
            derive_geometry(scene, free, load_dir).course
        out.update(out_of_plane_mechanism(scene, pos0, quat0, pos, quat, load_dir,
                                          course=course))
    else:
        geom = wall_geometry(scene, moved_mask, load_dir)
        if not geom.in_plane(load_dir):
            out["kind"] = "out-of-plane"
            out.update(lone_wall_labels(out_of_plane_mechanism(
                scene, pos0, quat0, pos, quat, load_dir, facade_group=geom.group or "facade",
                course=geom.course, facade=geom.members)))
        else:
            out["kind"] = "in-plane"
            normal = np.cross([0.0, 0.0, 1.0], load_dir)
            out.update(in_plane_mechanism(scene, pos0, quat0, pos, quat, moved_mask, load_dir,
                                          normal, geom.stagger, geom.course_height,
                                          course=geom.course))
            crack = out.get("crack")
            out["crack_angle_deg"] = crack["angle_from_vertical_deg"] if crack else None
            out["crack_angle_from_bottom_line_deg"] = \
                crack["angle_from_bottom_line_deg"] if crack else None
            out["crack_angle_definition"] = CRACK_ANGLE_DEFINITION
            if geom.stagger:
                la = in_plane_limit(case.material.friction, geom.s_over_h, geom.l_over_h)
                out["limit_analysis"] = {**la.as_dict(), "s_over_h": geom.s_over_h,
                                         "l_over_h": geom.l_over_h,
                                         "mu": case.material.friction}
        out["geometry"] = geom.as_dict(load_dir)
    portion = collapsed_portion(scene, pos0, quat0, pos, quat)
    portion.pop("mask")
    out["collapsed"] = portion
    return out


def reference_frame(frames: dict, collapse: dict) -> int:
    """Index of the frame the collapse motion is measured from: for a quasi-static tilt the
    last frame at or before the dynamic continuation's start (``dynamic_from_s``: the state of
    the last angle in equilibrium, dem.run.quasi_static); for a constant-rate tilt the frame of
    the detector's reference (``reference_time_s``: the first frame, or the new equilibrium
    after the last re-seating of warped beds, dem.collapse), else the first frame.  The motion a
    wall made while it was still in equilibrium (elastic lean, joints seating, creep of warped
    beds: up to 1 cm at the top of the calibration's L/H = 0.6 wall with 0.1 mm beds) is not
    its collapse mechanism."""
    if collapse.get("method") == "quasi_static":
        t0 = collapse.get("dynamic_from_s")
    else:  # the detector's reference: the first frame, or the last re-seating (dem.collapse)
        t0 = collapse.get("reference_time_s") or None
    if t0 is None:
        return 0
    t = np.asarray(frames["t"])
    return max(0, int(np.searchsorted(t, t0 + 1e-12, side="right")) - 1)


def tilt_mechanism(case, scene, frames: dict, summary: dict) -> dict:
    """``{"mechanism": ...}`` of a tilt run whose summary says a collapse was detected (else
    ``{}``): the mechanism of the motion from the reference frame (:func:`reference_frame`) to
    the classification frame (:func:`classification_frame`, counted from the reference).
    ``frames``: the arrays of frames.npz (t, pos, quat)."""
    collapse = summary.get("collapse") or {}
    if not collapse.get("detected"):
        return {}
    from dem.loading import loading_from_case

    j = reference_frame(frames, collapse)
    pos, quat = frames["pos"][j:], frames["quat"][j:]
    k = classification_frame(scene, pos, quat)
    mech = classify(case, scene, pos[0], quat[0], pos[k], quat[k],
                    loading_from_case(case).load_direction)
    mech["reference_time_s"] = float(frames["t"][j])
    mech["frame_time_s"] = float(frames["t"][j + k])
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
    if getattr(case.loading, "method", "constant_rate") == "quasi_static":
        # the search for the loss of equilibrium (dem.run.quasi_static) is not in the frames:
        # its result stays the run's; the mechanism is read again
        import json

        try:
            col = json.loads((run_dir / "summary.json").read_text()).get("collapse")
        except (OSError, ValueError):
            col = None
        col = col or {"detected": False}
        res = {"collapse": col, **tilt_mechanism(case, scene, frames, {"collapse": col})}
    else:
        res = tilt_results(case, scene, frames)
    out = {"kind": "tilt", "case": case.name, "collapse": res["collapse"],
           "mechanism": res.get("mechanism")}
    write_json(run_dir / "analysis.json", out, indent=1, strict=True)
    return out


def top_blocks(scene) -> np.ndarray:
    """bool [N]: the highest blocks (not fixed) at the start, whose tops lie within half the
    smallest block height of the highest top (the top course of a wall, the top of a stack)."""
    from dem.builders.checks import vertices

    free = ~scene.fixed
    z = vertices(scene)[:, :, 2]
    top, height = z.max(axis=1), z.max(axis=1) - z.min(axis=1)
    if not free.any():
        return free
    return free & (top >= top[free].max() - 0.5 * height[free].min())


def lean_series(scene, pos, load_dir) -> np.ndarray:
    """Lean [T] (m) of a tilt run: the displacement relative to the table (frames are in the
    table frame) of the top blocks (:func:`top_blocks`, mass-weighted mean), its horizontal
    component along the load direction."""
    sel = top_blocks(scene)
    d = np.asarray(load_dir, float) * [1.0, 1.0, 0.0]
    d /= np.linalg.norm(d)
    w = scene.mass[sel] / scene.mass[sel].sum()
    return ((np.asarray(pos)[:, sel] - np.asarray(pos)[0, sel]) @ d) @ w


def plot_lean(run_dir, collapse: dict | None = None) -> Path:
    """lean.png of a tilt run directory: the lean (:func:`lean_series`) against the table angle,
    linear (mm) and on a log scale (the elastic lean before the collapse is micrometres), with
    the collapse marked at the angle lambda is read at (``collapse``: the summary's
    ``collapse`` block; default: summary.json's).  Written atomically; returns its path.
    Called by ``dem run`` after the run and by ``dem post``."""
    import json

    plt = agg_pyplot()

    from dem.loading import loading_from_case
    from dem.output.atomic import savefig
    from postprocess.shake_signals import ShakeAnalysisError, load_run

    run_dir = Path(run_dir)
    case, scene = load_run(run_dir)
    if collapse is None:
        try:
            collapse = json.loads((run_dir / "summary.json").read_text()).get("collapse")
        except (OSError, ValueError):
            collapse = None
    try:
        with np.load(run_dir / "frames.npz") as fr:
            pos, angle = fr["pos"], fr["tilt_angle"]
    except (OSError, KeyError, ValueError) as err:
        raise ShakeAnalysisError(f"{run_dir / 'frames.npz'}: no tilt frames ({err})") from None
    lean_mm = 1e3 * lean_series(scene, pos, loading_from_case(case).load_direction)
    fig, (ax, axl) = plt.subplots(2, 1, figsize=(7.0, 6.5), sharex=True)
    for a in (ax, axl):
        a.plot(angle, lean_mm if a is ax else np.where(lean_mm != 0, np.abs(lean_mm), np.nan), "-",
               color="C0", lw=1.2, marker="." if len(angle) < 200 else None)
        a.grid(True, alpha=0.3)
    axl.set_yscale("log")
    ax.set_ylabel("lean (mm)")
    axl.set_ylabel("|lean| (mm), log scale")
    axl.set_xlabel("table angle (deg)")
    if collapse and collapse.get("detected") and collapse.get("angle_deg") is not None:
        for a in (ax, axl):
            a.axvline(collapse["angle_deg"], color="C3", ls="--", lw=1.0,
                      label=f"collapse: {collapse['angle_deg']:.2f} deg, "
                            f"lambda = {collapse['load_factor']:.3f}")
        ax.legend(loc="upper left", fontsize=9)
    elif collapse and collapse.get("detected") and collapse.get("onset_bracket_deg"):
        lo, hi = collapse["onset_bracket_deg"]  # the onset could not be resolved (dem.collapse)
        for a in (ax, axl):
            a.axvspan(lo, hi, color="C3", alpha=0.15,
                      label=f"collapse onset unresolved: {lo:.2f}-{hi:.2f} deg")
        ax.legend(loc="upper left", fontsize=9)
    n_top = int(top_blocks(scene).sum())
    ax.set_title(f"{case.name}: lean of the top ({n_top} block{'s' * (n_top != 1)}) along the "
                 f"load, relative to the table", fontsize=10)
    from postprocess.decisive import lean_notes  # the closed form, the elastic offset

    ref_deg, notes = lean_notes(run_dir)
    if ref_deg is not None:
        for a in (ax, axl):
            a.axvline(ref_deg, color="k", ls=":", lw=1.0, label=f"closed form: {ref_deg:.2f} deg")
        ax.legend(loc="upper left", fontsize=9)
    if notes:
        import textwrap

        lines = [w for n in notes for w in textwrap.wrap(n, 110)]
        fig.text(0.01, 0.005, "\n".join(lines), fontsize=7, va="bottom")
        fig.set_size_inches(7.0, 6.5 + 0.13 * len(lines))
        fig.tight_layout(rect=(0, 0.13 * len(lines) / (6.5 + 0.13 * len(lines)), 1, 1))
    else:
        fig.tight_layout()
    path = run_dir / "lean.png"
    savefig(fig, path, dpi=110)
    plt.close(fig)
    return path
