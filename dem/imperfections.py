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

Fixed blocks (supports) stay perfect.  The scene's ``face_offset`` and ``arris`` arrays hold the
realisation (written to the run directory as imperfections.npz by dem.run).
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from dem.scene import Scene

TRUNCATION = 3.0  # standard deviations


@dataclass(frozen=True)
class ImperfectionParams:
    """The numbers of a case's ``imperfections:`` (m), decoupled from the schema."""

    bed_unevenness: float = 0.0
    face_shape: str = "bilinear"
    size_scatter: tuple = (0.0, 0.0, 0.0)
    arris: float = 0.0
    seed: int = 0

    def any(self) -> bool:
        return self.bed_unevenness > 0 or self.arris > 0 or any(s > 0 for s in self.size_scatter)


def streams(seed: int) -> tuple[np.random.Generator, np.random.Generator]:
    """(sizes, faces): the two independent random streams of one seed."""
    a, b = np.random.SeedSequence(int(seed)).spawn(2)
    return np.random.default_rng(a), np.random.default_rng(b)


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
                     nominal_size: np.ndarray | None = None) -> dict:
    """summary.json's ``imperfections``: the parameters and what was drawn (the full arrays go
    to imperfections.npz)."""
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
    return out
