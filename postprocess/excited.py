"""The excited portion of a shaken facade, its upper and lower parts, and the mechanism labels
(thesis Section 4.3: Figs 4.5 - 4.14, 4.20 - 4.25, 4.39, 4.41; REFERENCE.md "Excited portion").

Which bricks move with the facade top
-------------------------------------
For every brick i, over the steady-state window [t0, t1) and relative to the table:
    s_i(t)      displacement of its centre along the excitation direction e (m)
    theta_i(t)  rotation about the facade's rocking axis a = z x e (rad; rotation vector of
                R_i(t) R_i(0)^-1 projected on a; theta > 0 moves the top towards +e)
Both are fitted with c0 + c1 t + R sin(2 pi f t + phi) (postprocess.signal_analysis.harmonic_fit;
the linear term takes out sliding drift), giving phasors X_i and Theta_i at the excitation
frequency (s_i, theta_i: postprocess.block_kinematics.brick_motion).  The reference is the
top-centre instrument's brick (X_ref) for translation and, for rotation, the mean phasor of the
facade bricks of that brick's course (a single brick's rotation is noisy; all bricks of a rigidly
rocking course share it).

A candidate brick (facade and both side walls; every free block in scenes that are not box
models) moves with the facade top when, at the excitation frequency,
  translation:  |X_i| >= max(0.15 |X_ref|, 0.2 mm)  and  |arg(X_i / X_ref)| <= 45 deg,   or
  rotation:     |Theta_i| >= max(0.25 |Theta_ref|, 1e-3 rad) and |arg(Theta_i/Theta_ref)| <= 45 deg,
and it is connected (face contact in the initial layout) through such bricks to the reference.
Why these numbers:
  * both tests, because a rigid body rocking about a hinge line moves its bricks in proportion to
    their height above the hinge (the lowest excited course moves ~1/8 of the top in Model II),
    while every brick of it turns by the same angle: rotation finds the bricks near the hinge,
    translation the ones that slide with the top without turning;
  * floors: elastic joint deformation moves bricks too.  With kn = 5e9 Pa/m the rotational
    stiffness of a 105 x 50 mm bed joint is kn L t^3 / 12 = 5.5e3 N m/rad; the inertial moment of
    the ~3 kg above it at 1.5 m/s2 over 0.15 m is 0.7 N m: 1.2e-4 rad, and ~40 micrometres of
    translation at the top of a 0.3 m wall.  The floors (1e-3 rad, 0.2 mm) are ~5-10 times these,
    so only bricks whose joints open count;
  * ratios 0.15 / 0.25: the thesis' lower part rocks less than the upper part ("slight relative
    rocking") but as a whole; bricks moving at a few percent of the top are not part of it;
  * 45 deg: bricks of one rigid body move in phase (0 deg); 45 deg keeps bricks whose motion has
    at least cos 45 = 71 % correlation with the top and rejects ratcheting/sliding bricks, whose
    first harmonic lags by a quarter cycle or more;
  * connectivity: a rocking portion is one body; it keeps the front wall or a loose brick
    elsewhere from joining because they happen to move in phase.
If the reference itself moves less than the translation floor, there is no excited portion.

Upper and lower parts (the thesis' own definition, Section 4.3.1.1 / 4.3.2.1: "the upper part
contains all bricks, as well as part of the side wall, in the several top layers; the lower part
only contains the bricks in the following layers along the two stepped joint lines"):
  a facade course is COMPLETE when both its end bricks and all but at most one of its bricks are
  excited (one loose interior brick sliding on its own does not make a course "stepped");
  upper part (2) = excited bricks (facade and side walls) in the run of complete courses from the
  top of the facade down (none if the top course is not complete);
  lower part (1) = every other excited brick (the stepped courses below);  0 = not excited.

Mechanism labels (:func:`mechanism_labels`, the thesis' words in Section 4.3):
  response  from the instruments, as the thesis reads them (Section 4.3.1.1, Fig 4.10(c): at
            3.6 Hz "the displacements at corners due to separate motions on bricks are relatively
            larger than the arching deformation ... corner rotation dominates"; Section 4.3.2.2:
            "the deviation between the amplitudes of dsr and ds quantifies the ... rotation of
            the corner bricks"): the rocking is the arching of the facade top, pp(dsr) (centre
            relative to corner a), and the corners' separate motion is pp(ds) at the corners (the
            larger of the two), all peak-to-peak over the steady state.  "global rocking
            dominated" when rocking > separate corner motion, else "corner rotation dominated".
            Where the DEM lets us see more than the thesis could: a corner brick that belongs to
            the excited portion rocks with it, so its motion is not "separate" (it is dropped
            from the separate motion, and the rocking is then pp(ds) of the centre).  "no
            response" when ds and both corners stay below 0.4 mm peak-to-peak (twice the
            translation floor); "corner rotation dominated" when only the corners move.  The
            corner bricks' twist about z (first harmonic and largest excursion, degrees) is
            reported as evidence, not used.
  corners   "B2-like" when excited side-wall bricks (not counting the corner bricks inside the
            facade's thickness) are found in both side walls, "B1-like" in one, "A-like" in none
            (Fig 3.14 and Section 4.3.2.1: B2 = the corners and side walls join the rocking
            portion; A = a horizontal line, corners not involved).  ``line`` says whether the
            portion's lower boundary is "horizontal" (no lower part) or "stepped".

The portion's picture (excited.png) and ParaView file (excited.vtu): postprocess.excited_output.
"""

from __future__ import annotations

from dataclasses import dataclass, field

import numpy as np
from scipy.sparse import coo_matrix
from scipy.sparse.csgraph import connected_components

from postprocess.block_kinematics import brick_motion
from postprocess.signal_analysis import cycle_extrema, harmonic_fit

TRANS_RATIO, TRANS_FLOOR = 0.15, 2e-4      # -, m
ROT_RATIO, ROT_FLOOR = 0.25, 1e-3          # -, rad
PHASE_MAX_DEG = 45.0
CONTACT_TOL = 1e-3                         # m, face contact in the initial layout
NO_RESPONSE_PP = 2 * TRANS_FLOOR           # m


@dataclass
class ExcitedPortion:
    excited: np.ndarray          # [N] bool
    part: np.ndarray             # [N] int: 0 not excited, 1 lower, 2 upper
    candidates: np.ndarray       # [N] bool
    by_translation: np.ndarray   # [N] bool (before the connectivity filter)
    by_rotation: np.ndarray      # [N] bool
    trans_amp: np.ndarray        # [N] m, |X_i|
    trans_phase_deg: np.ndarray  # [N] arg(X_i / X_ref)
    rot_amp: np.ndarray          # [N] rad, |Theta_i|
    rot_phase_deg: np.ndarray    # [N]
    ref_block: int
    ref_trans_amp: float
    ref_rot_amp: float
    mass: float                  # kg, excited bricks
    facade: str | None = None
    side_walls: tuple = ()
    upper_courses: list = field(default_factory=list)
    side_counts: dict = field(default_factory=dict)     # side wall -> excited non-corner bricks
    corner_bricks_excited: int = 0
    scene_mass: np.ndarray | None = None
    course: np.ndarray | None = None
    note: str = ""

    def summary(self) -> dict:
        n_top = None
        if self.facade is not None and self.course is not None and self.excited.any():
            top = int(self.course[self.candidates].max())
            n_top = int(top - self.course[self.excited].min() + 1)
        m = self.scene_mass if self.scene_mass is not None else np.zeros(len(self.part))
        return {
            "n_excited": int(self.excited.sum()),
            "n_upper": int((self.part == 2).sum()),
            "n_lower": int((self.part == 1).sum()),
            "mass_kg": self.mass,
            "mass_upper_kg": float(m[self.part == 2].sum()),
            "mass_lower_kg": float(m[self.part == 1].sum()),
            "excited_courses_from_top": n_top,
            "upper_courses": [int(c) + 1 for c in self.upper_courses],   # 1 = bottom course
            "side_wall_bricks": self.side_counts,
            "corner_bricks_excited": self.corner_bricks_excited,
            "upper_blocks": np.flatnonzero(self.part == 2).tolist(),
            "lower_blocks": np.flatnonzero(self.part == 1).tolist(),
            "reference_block": self.ref_block,
            "reference_translation_amplitude_m": self.ref_trans_amp,
            "reference_rotation_amplitude_rad": self.ref_rot_amp,
            "mean_rotation_amplitude_rad": {
                nm: float(self.rot_amp[self.part == k].mean()) if (self.part == k).any() else None
                for nm, k in (("upper", 2), ("lower", 1))},
            "thresholds": {"translation_ratio": TRANS_RATIO, "translation_floor_m": TRANS_FLOOR,
                           "rotation_ratio": ROT_RATIO, "rotation_floor_rad": ROT_FLOOR,
                           "phase_max_deg": PHASE_MAX_DEG},
            "note": self.note,
        }


def aabb(scene):
    """Axis-aligned bounds (lo, hi) [N,3] of the blocks in their initial pose."""
    from dem.builders.checks import vertices

    c = vertices(scene)
    return c.min(axis=1), c.max(axis=1)


def face_contacts(scene, idx, tol: float = CONTACT_TOL) -> np.ndarray:
    """Adjacency [n,n] (bool) of blocks ``idx`` that share a face in the initial layout."""
    lo, hi = aabb(scene)
    lo, hi = lo[idx], hi[idx]
    gap = np.maximum(lo[:, None, :] - hi[None, :, :], lo[None, :, :] - hi[:, None, :])  # <0 overlap
    touch = (gap <= tol).all(axis=2)
    face = (gap < -tol).sum(axis=2) >= 2
    adj = touch & face
    np.fill_diagonal(adj, False)
    return adj


def group_mask(scene, name):
    """[N] bool: the blocks of group ``name`` (none if the scene has no such group)."""
    if name is None or name not in scene.group_names:
        return np.zeros(scene.n_blocks, bool)
    return scene.group == scene.group_names.index(name)


def corner_bricks(scene, facade, side_walls, e, axis) -> np.ndarray:
    """[N] bool: side-wall bricks reaching into the facade's thickness band (along e) and facade
    bricks reaching into a side wall's band (along the wall)."""
    lo, hi = aabb(scene)
    out = np.zeros(scene.n_blocks, bool)
    fac = group_mask(scene, facade)
    if not fac.any():
        return out
    ecoord_lo, ecoord_hi = lo @ np.abs(e), hi @ np.abs(e)
    band = (ecoord_lo[fac].min(), ecoord_hi[fac].max())
    for sw in side_walls:
        m = group_mask(scene, sw)
        inside = (ecoord_hi > band[0] + CONTACT_TOL) & (ecoord_lo < band[1] - CONTACT_TOL)
        out |= m & inside
        if m.any():
            a_lo, a_hi = lo @ np.abs(axis), hi @ np.abs(axis)
            sband = (a_lo[m].min(), a_hi[m].max())
            out |= fac & (a_hi > sband[0] + CONTACT_TOL) & (a_lo < sband[1] - CONTACT_TOL)
    return out


def find_excited(t, s, theta, f, ref_block, candidates, ref_rot_blocks, adjacency_of):
    """The criteria of the module docstring on motions s, theta [T,N] over the window samples t.

    Returns (excited, by_translation, by_rotation, phasors dict).  ``adjacency_of(idx)`` gives
    the face-contact adjacency of the candidate blocks ``idx``.
    """
    X = harmonic_fit(t, s, f)
    Th = harmonic_fit(t, theta, f)
    Xr = X[ref_block]
    Tr = Th[ref_rot_blocks].mean() if len(ref_rot_blocks) else Th[ref_block]
    N = s.shape[1]
    with np.errstate(divide="ignore", invalid="ignore"):
        ph_x = np.degrees(np.angle(X / Xr)) if abs(Xr) > 0 else np.full(N, 180.0)
        ph_t = np.degrees(np.angle(Th / Tr)) if abs(Tr) > 0 else np.full(N, 180.0)
    by_t = candidates & (np.abs(X) >= max(TRANS_RATIO * abs(Xr), TRANS_FLOOR)) \
        & (np.abs(ph_x) <= PHASE_MAX_DEG)
    by_r = candidates & (np.abs(Th) >= max(ROT_RATIO * abs(Tr), ROT_FLOOR)) \
        & (np.abs(ph_t) <= PHASE_MAX_DEG)
    if abs(Tr) < ROT_FLOOR:
        by_r[:] = False  # the reference does not rock: no rotation reference
    ok = by_t | by_r
    excited = np.zeros(N, bool)
    if abs(Xr) >= TRANS_FLOOR and ok[ref_block]:
        idx = np.flatnonzero(ok)
        adj = adjacency_of(idx)
        r, c = np.nonzero(adj)
        g = coo_matrix((np.ones(len(r)), (r, c)), shape=(len(idx), len(idx)))
        _, lab = connected_components(g, directed=False)
        k = int(np.flatnonzero(idx == ref_block)[0])
        excited[idx[lab == lab[k]]] = True
    return excited, by_t, by_r, {"X": X, "Theta": Th, "X_ref": Xr, "Theta_ref": Tr,
                                 "phase_x": ph_x, "phase_t": ph_t}


def split_parts(scene, excited, facade, side_walls, axis):
    """Part per block (0 / 1 lower / 2 upper) and the upper courses (module docstring)."""
    part = np.where(excited, 1, 0)
    fac = group_mask(scene, facade)
    if not fac.any() or (scene.course[fac] < 0).all():
        return np.where(excited, 2, 0), []
    along = scene.position @ axis
    upper = []
    for c in range(int(scene.course[fac].max()), -1, -1):
        inc = np.flatnonzero(fac & (scene.course == c))
        if inc.size == 0:
            break
        ends = inc[[np.argmin(along[inc]), np.argmax(along[inc])]]
        if excited[ends].all() and excited[inc].sum() >= inc.size - 1:
            upper.append(c)
        else:
            break
    if upper:
        c_low = min(upper)
        side = np.zeros(scene.n_blocks, bool)
        for sw in side_walls:
            side |= group_mask(scene, sw)
        up = excited & (fac | side) & (scene.course >= c_low)
        part[up] = 2
    return part, upper


def excited_portion(scene, frames, f, t0, t1, direction, ref_block, facade=None, side_walls=()):
    """Find the excited portion of a run (module docstring) from frames (t, pos, quat)."""
    t = np.asarray(frames["t"], float)
    pos, quat = np.asarray(frames["pos"], float), np.asarray(frames["quat"], float)
    e = np.asarray(direction, float)
    e = e / np.linalg.norm(e)
    axis = np.cross([0.0, 0.0, 1.0], e)
    axis = axis / np.linalg.norm(axis)
    s, theta = brick_motion(pos, quat, e, axis)
    m = (t >= t0 - 1e-12) & (t < t1 - 1e-12)
    if m.sum() < 8:
        raise ValueError(f"only {int(m.sum())} frames in the steady window [{t0:.3f}, {t1:.3f}) s: "
                         "record frames more often (run.output_interval)")
    fac = group_mask(scene, facade)
    if fac.any():
        cand = fac.copy()
        for sw in side_walls:
            cand |= group_mask(scene, sw)
        cand &= ~scene.fixed
        ref_course = scene.course[ref_block]
        ref_rot = np.flatnonzero(fac & (scene.course == ref_course)) if ref_course >= 0 else []
    else:
        cand = ~scene.fixed
        ref_rot = []
    excited, by_t, by_r, ph = find_excited(t[m], s[m], theta[m], f, ref_block, cand, ref_rot,
                                           lambda idx: face_contacts(scene, idx))
    part, upper = split_parts(scene, excited, facade, side_walls, axis)
    corners = corner_bricks(scene, facade, side_walls, e, axis)
    side_counts = {sw: int((excited & group_mask(scene, sw) & ~corners).sum())
                   for sw in side_walls}
    note = "" if excited.any() else (
        f"the reference block moves {abs(ph['X_ref']) * 1e3:.3f} mm at f "
        f"(floor {TRANS_FLOOR * 1e3:.1f} mm): no excited portion")
    return ExcitedPortion(
        excited=excited, part=part, candidates=cand, by_translation=by_t, by_rotation=by_r,
        trans_amp=np.abs(ph["X"]), trans_phase_deg=ph["phase_x"], rot_amp=np.abs(ph["Theta"]),
        rot_phase_deg=ph["phase_t"], ref_block=int(ref_block),
        ref_trans_amp=float(abs(ph["X_ref"])),
        ref_rot_amp=float(abs(ph["Theta_ref"])), mass=float(scene.mass[excited].sum()),
        facade=facade, side_walls=tuple(side_walls), upper_courses=sorted(upper),
        side_counts=side_counts, corner_bricks_excited=int((excited & corners).sum()),
        scene_mass=scene.mass, course=scene.course, note=note)


def corner_twist(frames, scene, blocks, f, t0, t1) -> dict:
    """Rotation of the corner bricks about z over the window: first-harmonic amplitude and the
    largest excursion from the start of the run (degrees)."""
    blocks = [b for b in blocks if b is not None]
    t = np.asarray(frames["t"], float)
    quat = np.asarray(frames["quat"], float)[:, blocks]
    _, tw = brick_motion(np.zeros(quat.shape[:2] + (3,)), quat, np.array([1.0, 0, 0]),
                         np.array([0.0, 0.0, 1.0]))
    m = (t >= t0 - 1e-12) & (t < t1 - 1e-12)
    P = harmonic_fit(t[m], tw[m], f)
    return {"blocks": [int(b) for b in blocks],
            "h1_amplitude_deg": np.degrees(np.abs(np.atleast_1d(P))).tolist(),
            "max_abs_deg": np.degrees(np.abs(tw[m]).max(axis=0)).tolist()}


def mechanism_labels(quantities: dict, q: dict, sig, win, portion: ExcitedPortion | None,
                     twist: dict | None = None) -> dict:
    """Dynamic mechanism labels (module docstring) of one axis of a shaken box model."""
    def pp(y):
        if y is None:
            return None
        mx, mn = cycle_extrema(sig.t, y, sig.f, win.first_cycle, win.end_cycle)
        return float(np.nanmean(mx) - np.nanmean(mn))

    out: dict = {}
    pp_ds, pp_dsr = pp(sig.ds_centre), pp(q.get("dsr"))
    corners = {r: pp(y) for r, y in (("corner_a", sig.ds_corner), ("corner_b", sig.ds_corner_b))
               if y is not None}
    in_portion = {r: bool(portion is not None and r in sig.blocks
                          and portion.excited[sig.blocks[r]]) for r in corners}
    out["pp_ds_m"], out["pp_dsr_m"] = pp_ds, pp_dsr
    out["pp_corner_m"] = corners
    out["corner_in_excited_portion"] = in_portion
    if pp_dsr is None or not corners:
        out["response"] = None
    elif max([pp_ds, *corners.values()]) < NO_RESPONSE_PP:
        out["response"] = "no response"
    elif pp_ds < NO_RESPONSE_PP:
        out["response"] = "corner rotation dominated"
    else:
        # a corner brick inside the rocking portion rocks with it: its motion is not separate
        rock = pp_ds if in_portion.get("corner_a") else pp_dsr
        sep = max([v for r, v in corners.items() if not in_portion[r]], default=0.0)
        out["rocking_m"], out["corner_separate_m"] = rock, sep
        out["response"] = ("global rocking dominated" if rock > sep
                           else "corner rotation dominated")
    if twist is not None:
        out["corner_twist"] = twist
    if portion is not None and portion.facade is not None:
        out.update(corner_label(portion))
    return out


def corner_label(portion: ExcitedPortion) -> dict:
    """B2-like / B1-like / A-like from the excited side-wall bricks, and the line shape."""
    if not portion.excited.any():
        return {"corners": None, "line": None, "side_wall_bricks": portion.side_counts,
                "corner_bricks_excited": 0}
    n_sides = sum(1 for v in portion.side_counts.values() if v > 0)
    return {"corners": {0: "A-like", 1: "B1-like"}.get(n_sides, "B2-like"),
            "line": "stepped" if (portion.part == 1).any() else "horizontal",
            "side_wall_bricks": portion.side_counts,
            "corner_bricks_excited": portion.corner_bricks_excited}
