"""Realisation of the imperfections of a case (``imperfections:``, docs/imperfections.md): the
random draws that turn a perfect scene into one imperfect specimen.

One integer seed decides everything: ``numpy.random.SeedSequence(seed)`` is split into two
independent streams, one for the brick sizes (dem.builders.scatter) and one for the face warps,
so that changing one parameter does not redraw the other field.  The same seed gives a
bit-identical scene.  Draws are standard normals truncated at 3 sigma (scipy.stats.truncnorm).

* ``bed_unevenness`` sigma (m): each face of each movable block gets four corner offsets
  z_c sigma (z_c standard normal, |z_c| <= 3) along its outward normal, then the face is moved
  in by its highest corner, o_c = sigma (z_c - max z): the highest corner lies on the nominal box
  face, the others are recessed (o_c <= 0).  So no two blocks of a layout that was flush overlap
  at the start, the separating-axis test of the nominal boxes stays a valid test of contact,
  and the face's shape (the corners relative to each other, what frees rotation) has the
  distribution asked for.  The block keeps its box inertia and mass.  ``face_shape: planar``
  removes each face's twist first, (o_0 - o_1 - o_2 + o_3) / 4 times (1, -1, -1, 1): the face is
  then the corners' best-fit plane, a tilted flat face (its corner variance 3/4 of sigma^2).
* ``arris`` r (m): every movable block's edges are rounded with radius r: its contact patches
  are inset by r (dem.engine.geometry, 5).
* ``size_scatter``: builder bricks only, laid again on their actual sizes
  (:func:`dem.builders.scatter.scatter_sizes`); explicit blocks keep their sizes.
* the as-built fields, builder bricks only, after the size scatter (geometry in
  :mod:`dem.builders.as_built`): ``corner_gap`` and ``head_gap`` (mean, scatter; m) draw one gap
  per corner end and course and per head joint, ``mean + scatter z`` with z a standard normal
  truncated at +-3 and at -mean / scatter (no gap is negative); ``plumb`` offsets each course
  from the one below by ``sigma z`` (x and y of the builder's frame) and leans the structure.

Streams: the as-built fields draw from a third child of the SeedSequence, itself split into one
stream per field (corners, head joints, plumb), so the two streams above are the ones they were
before these fields existed (``SeedSequence.spawn`` gives the same first children however many
are asked for): a committed specimen is rebuilt bit for bit, and switching one as-built field
on redraws none of the others.

Fixed blocks (supports) stay perfect.  The scene's ``face_offset`` and ``arris`` arrays hold the
realisation (written to the run directory as imperfections.npz by dem.run).
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from dem.scene import Scene

TRUNCATION = 3.0  # standard deviations


#: a head joint or corner counts as open in the summaries when its gap is wider than this, m
OPEN_GAP = 1e-6


@dataclass(frozen=True)
class ImperfectionParams:
    """The numbers of a case's ``imperfections:`` (m, degrees), decoupled from the schema."""

    bed_unevenness: float = 0.0
    face_shape: str = "bilinear"
    size_scatter: tuple = (0.0, 0.0, 0.0)
    arris: float = 0.0
    seed: int = 0
    corner_gap: tuple = (0.0, 0.0)  # (mean, scatter), m
    head_gap: tuple = (0.0, 0.0)  # (mean, scatter), m
    plumb_sigma: tuple = (0.0, 0.0)  # m per course, builder frame (x, y)
    plumb_lean: tuple = (0.0, 0.0)  # degrees

    def as_built(self) -> bool:
        return (any(v > 0 for v in self.corner_gap + self.head_gap + self.plumb_sigma)
                or any(v != 0 for v in self.plumb_lean))

    def any(self) -> bool:
        return (self.bed_unevenness > 0 or self.arris > 0 or any(s > 0 for s in self.size_scatter)
                or self.as_built())


def streams(seed: int) -> tuple[np.random.Generator, np.random.Generator]:
    """(sizes, faces): the two independent random streams of one seed."""
    a, b = np.random.SeedSequence(int(seed)).spawn(2)
    return np.random.default_rng(a), np.random.default_rng(b)


def as_built_streams(seed: int) -> tuple[np.random.Generator, ...]:
    """(corners, head joints, plumb): the as-built fields' streams, from the seed's third child
    (module docstring); independent of :func:`streams` and of each other."""
    third = np.random.SeedSequence(int(seed)).spawn(3)[2]
    return tuple(np.random.default_rng(s) for s in third.spawn(3))


def draw_gaps(rng: np.random.Generator, mean: float, scatter: float, n: int) -> np.ndarray:
    """n gaps (m): mean + scatter z, z standard normal truncated at +-TRUNCATION and at
    -mean / scatter (no negative gap); mean for every joint when scatter is 0 (no draw)."""
    if scatter <= 0 or n == 0:
        return np.full(n, float(mean))
    from scipy.stats import truncnorm

    lower = max(-TRUNCATION, -mean / scatter)
    return mean + scatter * truncnorm.rvs(lower, TRUNCATION, size=n, random_state=rng)


def apply_as_built(part: Scene, params: ImperfectionParams, rngs, course_height: float,
                   yaw: int, reach: float) -> tuple[Scene, dict]:
    """One builder part as built (dem.builders.as_built): head gaps, then corner gaps, then the
    courses out of plumb, each drawn from its own stream of ``rngs`` (:func:`as_built_streams`,
    shared by the parts of one scene in order).  ``course_height`` (m) and ``yaw`` (degrees)
    are the builder's; ``reach`` (m) is how far a butting end may stand from the through wall
    (the builder's min_piece).  Returns the new part and what was drawn: {"corner_gaps",
    "head_gaps": arrays (m), "offsets": [courses, 2] (m, builder frame)}."""
    from dem.builders import as_built as ab

    rng_corner, rng_head, rng_plumb = rngs
    drawn: dict = {}
    if any(v > 0 for v in params.head_gap):
        joints = ab.head_joints(part)
        g = draw_gaps(rng_head, *params.head_gap, len(joints))
        cuts = [(b, ax, +1, x / 2) for (b, _, ax), x in zip(joints, g)]
        cuts += [(c, ax, -1, x / 2) for (_, c, ax), x in zip(joints, g)]
        part = ab.cut_ends(part, cuts)
        drawn["head_gaps"] = g
    if any(v > 0 for v in params.corner_gap):
        ends = ab.corner_ends(part, reach)
        g = draw_gaps(rng_corner, *params.corner_gap, len(ends))
        part = ab.cut_ends(part, [(b, ax, side, x) for (b, ax, side), x in zip(ends, g)])
        drawn["corner_gaps"] = g
    if any(v > 0 for v in params.plumb_sigma) or any(v != 0 for v in params.plumb_lean):
        n = int(part.course.max()) + 1 if (part.course >= 0).any() else 0
        z = None
        if any(v > 0 for v in params.plumb_sigma) and n > 1:
            z = truncated_normal(rng_plumb, (n - 1, 2))
        off = ab.course_offsets(n, params.plumb_sigma, params.plumb_lean, course_height, z)
        part = ab.shift_courses(part, off, yaw)
        drawn["offsets"] = off
    return part, drawn


def as_built_summary(params: ImperfectionParams, drawn: list[dict]) -> dict:
    """summary.json's ``imperfections.as_built``: what the as-built fields drew over the
    builder parts (``drawn``: :func:`apply_as_built`'s records): the number of corner ends and
    head joints, how many are open (wider than OPEN_GAP), the largest and mean gap; the largest
    step between successive courses and the top course's offset from the bottom one."""
    out: dict = {}
    for key, name, mean_sc in (("corner_gaps", "corner_gap", params.corner_gap),
                               ("head_gaps", "head_gap", params.head_gap)):
        if not any(v > 0 for v in mean_sc):
            continue
        g = np.concatenate([d[key] for d in drawn if key in d] or [np.zeros(0)])
        out[name] = {"mean_m": mean_sc[0], "scatter_m": mean_sc[1], "n_joints": int(g.size),
                     "n_open": int((g > OPEN_GAP).sum()),
                     "largest_m": float(g.max()) if g.size else 0.0,
                     "drawn_mean_m": float(g.mean()) if g.size else 0.0}
    offs = [d["offsets"] for d in drawn if "offsets" in d]
    if offs:
        steps = [np.abs(np.diff(o, axis=0)).max() if len(o) > 1 else 0.0 for o in offs]
        tops = [o[-1] - o[0] for o in offs]
        top = max(tops, key=lambda v: float(np.hypot(*v)))
        out["plumb"] = {"sigma_m": list(params.plumb_sigma), "lean_deg": list(params.plumb_lean),
                        "largest_course_step_m": float(max(steps)),
                        "top_offset_m": [float(v) for v in top]}
    return out


def truncated_normal(rng: np.random.Generator, shape) -> np.ndarray:
    """Standard normals truncated at +-TRUNCATION."""
    # imported here: scipy.stats costs ~ 1 CPU-s to import, which every `dem run` paid at
    # start-up, imperfect or not
    from scipy.stats import truncnorm

    return truncnorm.rvs(-TRUNCATION, TRUNCATION, size=shape, random_state=rng)


TWIST_MODE = np.array([1.0, -1.0, -1.0, 1.0])  # the corner pattern of a face's twist


def face_offsets(n_blocks: int, sigma: float, rng: np.random.Generator,
                 shape: str = "bilinear") -> np.ndarray:
    """[n, 6, 4] corner offsets (m) of warped faces: sigma z - sigma max(z) per face; for
    ``shape == "planar"`` the twist of z is removed before the shift (module docstring)."""
    if sigma <= 0:
        return np.zeros((n_blocks, 6, 4))
    z = truncated_normal(rng, (n_blocks, 6, 4))
    if shape == "planar":
        z = z - twist(z)[..., None] * TWIST_MODE
    elif shape != "bilinear":
        raise ValueError(f"face shape must be 'bilinear' or 'planar', got {shape!r}")
    return sigma * (z - z.max(axis=2, keepdims=True))


def apply_faces(scene: Scene, params: ImperfectionParams) -> Scene:
    """The scene with the face warps and arrises of ``params`` on its movable blocks (in place:
    the scene's face_offset and arris arrays are replaced)."""
    _, rng_faces = streams(params.seed)
    movable = ~scene.fixed
    off = np.zeros((scene.n_blocks, 6, 4))
    off[movable] = face_offsets(int(movable.sum()), params.bed_unevenness, rng_faces,
                                params.face_shape)
    scene.face_offset = off
    scene.arris = np.where(movable, float(params.arris), 0.0)
    return scene


def twist(face_offset: np.ndarray) -> np.ndarray:
    """Twist of faces (m): (o_0 - o_1 - o_2 + o_3) / 4, the bilinear term's coefficient (the part
    of a warp that no plane fits; docs/imperfections.md)."""
    o = np.asarray(face_offset)
    return 0.25 * (o[..., 0] - o[..., 1] - o[..., 2] + o[..., 3])


def realised_summary(scene: Scene, params: ImperfectionParams,
                     nominal_size: np.ndarray | None = None,
                     as_built: dict | None = None) -> dict:
    """summary.json's ``imperfections``: the parameters and what was drawn (the full arrays go
    to imperfections.npz); ``as_built``: :func:`as_built_summary`'s block, kept under that key
    (only where an as-built field is set: other summaries are unchanged)."""
    movable = ~scene.fixed
    out = {"seed": int(params.seed), "bed_unevenness_m": params.bed_unevenness,
           "face_shape": params.face_shape,
           "size_scatter_m": list(params.size_scatter), "arris_m": params.arris,
           "file": "imperfections.npz"}
    if params.bed_unevenness > 0 and movable.any():
        off = scene.face_offset[movable]
        tw = twist(off)
        out["faces"] = {"largest_recess_m": float(-off.min()),
                        "corner_offset_std_m": float(off.std()),
                        "twist_mean_abs_m": float(np.abs(tw).mean())}
    if nominal_size is not None and any(s > 0 for s in params.size_scatter):
        dev = scene.size - nominal_size
        out["sizes"] = {"largest_deviation_m": float(np.abs(dev).max()),
                        "deviation_std_m": [float(x) for x in dev[movable].std(axis=0)]}
    if as_built:
        out["as_built"] = as_built
    return out
