"""Survival of a run: standing, local collapse or collapse.

The shaking analysis' standing check (the instrumented centre moved less than its thickness,
postprocess.shake) cannot see corner bricks or top courses fall, which the thesis records
(Model I y at 1.8 Hz, 12 mm: "final collapse ... rapid rotation of the top bricks at both
corners", thesis line 752; Model II x at 2.5 Hz: "collapse started from the top of the facade on
the 16th cycle", line 979).  This module reads every brick from the frames (frames.npz: pos
[T, N, 3] in m, quat [T, N, 4]) and the scene (its group = wall, course, size).

**A brick has fallen** (left its course) at the first frame where either

* it *dropped*: its centre is lower than at the first frame by more than its height,
  z_i(0) - z_i(t) > h_i, h_i = the vertical extent of the block at the first frame,
  sum_k |R_i(0)[z, k]| L_ik (m);  a brick that stays in its course never drops by its own height
  (the joints close by micrometres, warped beds by fractions of a millimetre); or
* it *turned past toppling*: the vertical through its centre of mass no longer meets its own
  bed (the face that was lowest at the first frame), so that, standing alone on that bed, it
  would fall over.  In the body frame, with gravity direction g_b = R_i(t)^T (0, 0, -1) and the
  bed's outward normal along body axis k (sign s), the line from the centre along g_b meets the
  bed's plane at p = g_b (L_k / 2) / (s g_b[k]); the brick has toppled when s g_b[k] <= 0 (turned
  by 90 deg or more) or |p_j| > L_j / 2 for an axis j != k.  About its long edge a small brick
  (0.105 x 0.05 x 0.035 m, on its bed) topples past atan(0.05 / 0.035) = 55 deg, about its short
  edge past atan(0.105 / 0.035) = 71.6 deg: the rigid-block tipping angle atan(b / h).

Each fallen brick is reported by wall (its scene group, e.g. L1, T2, facade), corner (the other
walls it touches at the first frame: its bounding box within ``CORNER_GAP`` of a free block of
another group; none for a brick inside a wall), course (the scene's course index, -1 where the
scene has none), the time of the fall (s) and, for a shaking run, the cycle of the excitation it
fell in (1 for the first; None after the shaking ended).

**The verdict**: *standing* when no brick fell; *collapse* when in some wall at least
``COLLAPSE_SHARE`` of its free bricks fell (the wall as a whole is gone: a facade that
overturned); otherwise *local collapse* (how many bricks, where).  ``COLLAPSE_SHARE`` = 0.5 is
this harness' choice, not a thesis value: the thesis calls the loss of the top corner bricks
"final collapse" of the test (line 752), which here reads local collapse with its bricks named,
so that a study can apply its own rule to the list.

Sweeps (postprocess.sweep) and ensembles (postprocess.ensemble) aggregate the verdicts.
"""

from __future__ import annotations

from pathlib import Path

import numpy as np

VERDICTS = ("standing", "local collapse", "collapse")
COLLAPSE_SHARE = 0.5  # a wall with at least this share of its free bricks fallen has collapsed
CORNER_GAP = 5e-3     # m: a brick is at a corner when it comes this close to another wall's brick
                      # (the facade builder leaves 2.5 mm between a facade end and its wing)
MAX_LISTED = 50       # fallen bricks listed one by one in the compact record (the rest counted)


def vertical_extent(size, quat) -> np.ndarray:
    """h_i (m) [N]: vertical extent of each block (edge lengths ``size`` [N, 3], orientation
    ``quat`` [N, 4], w x y z, body -> table)."""
    from dem import quaternion

    r = quaternion.matrices(np.asarray(quat, float))
    return np.einsum("nk,nk->n", np.abs(r[:, 2, :]), np.asarray(size, float))


def toppled(size, quat0, quat) -> np.ndarray:
    """bool [..., N]: has each block turned past toppling on the bed it stood on at ``quat0``
    [N, 4]?  ``quat``: [N, 4] or [T, N, 4] (module docstring: the vertical through the centre
    no longer meets the bed)."""
    from dem import quaternion

    size = np.asarray(size, float)
    quat = np.asarray(quat, float)
    r0 = quaternion.matrices(np.asarray(quat0, float))            # [N, 3, 3]
    down0 = -r0[:, 2, :]                                          # table -z in body axes, [N, 3]
    k = np.argmax(np.abs(down0), axis=1)                          # the bed's axis
    s = np.sign(down0[np.arange(len(k)), k])
    flat = quat.reshape(-1, 4)
    r = quaternion.matrices(flat).reshape(quat.shape[:-1] + (3, 3))
    g = -r[..., 2, :]                                             # gravity in body axes
    g_k = s * np.take_along_axis(g, np.broadcast_to(k[:, None], g.shape[:-1] + (1,)),
                                 axis=-1)[..., 0]
    with np.errstate(divide="ignore", invalid="ignore"):
        p = g * (0.5 * size[np.arange(len(k)), k] / np.where(g_k > 0, g_k, np.inf))[..., None]
    outside = np.abs(p) > 0.5 * size * (1.0 + 1e-12)
    outside[..., np.arange(len(k)), k] = False  # the bed's own axis (p_k = L_k / 2 there)
    return (g_k <= 0) | outside.any(axis=-1)


def corner_of(scene) -> list[str | None]:
    """For each block, the other walls (groups) it touches at its built pose ("T1" or "L1/T2"),
    or None (inside a wall, or fixed)."""
    from dem.builders.checks import candidate_pairs, vertices

    v = vertices(scene)
    free = ~np.asarray(scene.fixed, bool)
    names = list(scene.group_names)
    touch: list[set] = [set() for _ in range(scene.n_blocks)]
    for i, j in candidate_pairs(v.min(axis=1), v.max(axis=1), CORNER_GAP):
        if free[i] and free[j] and scene.group[i] != scene.group[j]:
            touch[i].add(names[scene.group[j]])
            touch[j].add(names[scene.group[i]])
    return ["/".join(sorted(t)) if t else None for t in touch]


def cycle_counter(loading):
    """A function t (s) -> the excitation cycle (1, 2, ...) in which t lies, or None after the
    shaking (or for a loading that is not a cycled shake).  Uses the loading's own
    ``cycle_at(t)`` where it has one (a stepped shake), else its sine motion (dem.table_motion:
    frequency, t_end; the clock starts at the start of the shaking)."""
    if loading is None:
        return lambda t: None
    if hasattr(loading, "cycle_at"):
        return loading.cycle_at
    motion = getattr(loading, "motion", None)
    f = getattr(motion, "frequency", None)
    if f is None:
        return lambda t: None
    t_end = getattr(motion, "t_end", np.inf)

    def cycle(t: float):
        if t < 0.0 or t > t_end:
            return None
        return int(np.floor(t * f)) + 1 if t < t_end else int(np.ceil(t_end * f - 1e-9))
    return cycle


def survival(scene, t, pos, quat, loading=None) -> dict:
    """The survival verdict of a run (module docstring) from its frames: ``t`` [T] (s), ``pos``
    [T, N, 3] (m), ``quat`` [T, N, 4]; ``loading``: the run's dem.loading object (for the cycle
    of each fall), or None."""
    t = np.asarray(t, float)
    pos = np.asarray(pos, float)
    quat = np.asarray(quat, float)
    free = ~np.asarray(scene.fixed, bool)
    n = scene.n_blocks
    h = vertical_extent(scene.size, quat[0])
    drop = pos[0, :, 2][None, :] - pos[:, :, 2]                  # [T, N]
    dropped = drop > h[None, :]
    tipped = toppled(scene.size, quat[0], quat)                   # [T, N]
    fell = (dropped | tipped) & free[None, :]
    ever = fell.any(axis=0)
    first = np.where(ever, np.argmax(fell, axis=0), -1)
    names = list(scene.group_names)
    corners = corner_of(scene) if ever.any() else [None] * n
    cycle = cycle_counter(loading)
    fallen = []
    for i in np.flatnonzero(ever):
        k = int(first[i])
        how = [w for w, m in (("dropped", dropped[k, i]), ("toppled", tipped[k, i])) if m]
        fallen.append({"block": int(i), "wall": names[scene.group[i]], "corner": corners[i],
                       "course": int(scene.course[i]), "time_s": float(t[k]),
                       "cycle": cycle(float(t[k])), "how": "+".join(how),
                       "drop_m": float(drop[k, i])})
    fallen.sort(key=lambda b: (b["time_s"], b["block"]))
    by_wall = {}
    verdict = "standing" if not fallen else "local collapse"
    for g in np.unique(scene.group[free]):
        members = free & (scene.group == g)
        lost = [b for b in fallen if scene.group[b["block"]] == g]
        share = len(lost) / int(members.sum())
        if lost:
            by_wall[names[g]] = {
                "n_fallen": len(lost), "n_bricks": int(members.sum()), "share": share,
                "courses": sorted({b["course"] for b in lost}),
                "n_at_corners": sum(1 for b in lost if b["corner"] is not None),
                "first_time_s": lost[0]["time_s"], "first_cycle": lost[0]["cycle"]}
            if share >= COLLAPSE_SHARE:
                verdict = "collapse"
    return {"verdict": verdict, "n_fallen": len(fallen), "n_free_blocks": int(free.sum()),
            "first_fall_time_s": fallen[0]["time_s"] if fallen else None,
            "first_fall_cycle": fallen[0]["cycle"] if fallen else None,
            "by_wall": by_wall, "fallen": fallen,
            "criteria": {"drop": "centre lower than at the first frame by more than the "
                                 "block's height", "topple": "the vertical through the centre "
                                 "leaves the block's own bed", "collapse_share": COLLAPSE_SHARE,
                         "corner_gap_m": CORNER_GAP}}


#: the box model's roof (dem.builders.box_model: its beams, end masses and corner masses)
ROOF_GROUPS = ("roof-beam", "roof-mass", "corner-mass")


def fallen_parts(result: dict) -> str:
    """What fell, in three words for a box model (``result``: :func:`survival`'s or
    :func:`compact`'s): "standing" (nothing fell), "roof only" (every fallen block is part of
    the roof, ROOF_GROUPS: masses slid off their beams, the masonry standing) or "bricks
    fallen" (a brick of a wall fell).  The laboratory's box models held the rocking branch
    "with at most the roof masses moving"."""
    walls = set(result.get("by_wall") or {})
    if not result.get("n_fallen"):
        return "standing"
    return "roof only" if walls and walls <= set(ROOF_GROUPS) else "bricks fallen"


def compact(result: dict) -> dict:
    """The survival record kept per sweep point or realisation: everything but the fallen list
    beyond its first ``MAX_LISTED`` bricks (``n_fallen`` counts them all)."""
    out = dict(result)
    out["fallen"] = result["fallen"][:MAX_LISTED]
    out["fallen_listed"] = len(out["fallen"])
    return out


def survival_analysis(case, scene, frames: dict, summary: dict) -> dict:
    """Run analysis (the ``analyses`` hook of dem.run.loop.run_case): ``{"survival": ...}``
    for a shaking or record run (a tilt run's end is its collapse: dem.collapse), else {}."""
    from dem.loading import Record, Shake, loading_from_case

    loading = loading_from_case(case)
    if not isinstance(loading, (Shake, Record)):
        return {}
    return {"survival": compact(survival(scene, frames["t"], frames["pos"], frames["quat"],
                                         loading))}


def survival_of_run(run_dir) -> dict:
    """:func:`survival` of a run directory (case.json, frames.npz)."""
    from dem.loading import loading_from_case
    from postprocess.shake_signals import ShakeAnalysisError, load_run

    run_dir = Path(run_dir)
    case, scene = load_run(run_dir)
    path = run_dir / "frames.npz"
    if not path.is_file():
        raise ShakeAnalysisError(f"{path}: missing")
    with np.load(path) as fr:
        t, pos, quat = fr["t"], fr["pos"], fr["quat"]
    return survival(scene, t, pos, quat, loading_from_case(case))


def count_verdicts(verdicts) -> dict:
    """{verdict: count} over a list of verdict strings (None: not analysed, skipped), every
    verdict of VERDICTS present."""
    out = {v: 0 for v in VERDICTS}
    for v in verdicts:
        if v is not None:
            out[v] = out.get(v, 0) + 1
    return out
