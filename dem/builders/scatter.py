"""Builder bricks of scattered sizes, laid again as a mason lays them
(docs/imperfections.md).

Builders lay axis-aligned boxes (dem.builders.layout).  :func:`scatter_sizes` gives each movable
block new edge lengths and lays the scene again on them:

1. sizes: each edge gets an independent normal deviation truncated at 3 sigma (the standard
   normals of dem.imperfections.truncated_normal, drawn in block order, so the same random
   stream gives the same scene bit for bit), sigma_L to a block's longest edge, sigma_W to the
   middle one, sigma_H to the shortest: for bricks (L > W > H) their own L, W, H whatever the
   laying.  Mass follows the volume (same density);
2. head joints from the actual lengths: in each course, a block that touched others along x
   (its lo x on their hi x, their y and z extents overlapping) is pushed against them: its lo x
   is the largest new hi x among them, so the joint stays closed whether the bricks before it
   grew or shrank; a block touching nothing from -x keeps its nominal lo x (the course's end
   moves by the sum of its deviations).  Blocks are taken in
   order of nominal lo x, so chains and corners (walls along y abutting walls along x) are laid
   in order.  The same along y, independently;
3. courses on the actual heights below: in order of nominal lo z, a block on the table stays on
   it; any other block rests on the highest new top among the blocks it stood on (nominal hi z
   = its nominal lo z) that still overlap it in plan, the others leave gaps under it (bridging).
   If none overlaps any more it keeps the nominal level shifted by the mean shift of those
   blocks.  This handles roofs as well as courses.

Where a wall along y abuts a wall along x (the corners of facades and box models) the two chains
of step 2 can end in each other: after step 2, blocks of a course that overlap are pushed apart
along the horizontal axis of least overlap (the block laid later moves), until none does.

Fixed blocks (supports) are left as they are.  Units: m, kg.
"""

from __future__ import annotations

import numpy as np

from dem.scene import Scene

EPS = 1e-9  # m: faces closer than this touch


def scatter_sizes(scene: Scene, sigma, rng: np.random.Generator) -> Scene:
    """The scene with its movable blocks' sizes scattered by sigma = [sigma_L, sigma_W, sigma_H]
    (m) and laid again (module docstring); a new Scene, the input unchanged."""
    from dem.imperfections import truncated_normal

    sigma = np.asarray(sigma, dtype=np.float64)
    out = scene.copy()
    if not (sigma > 0).any():
        return out
    n = scene.n_blocks
    movable = ~scene.fixed
    lo0 = scene.position - 0.5 * scene.size
    hi0 = scene.position + 0.5 * scene.size
    # 1. sizes: sigma by edge rank (longest L, middle W, shortest H)
    z = truncated_normal(rng, (n, 3))
    rank = np.argsort(-scene.size, axis=1, kind="stable")  # rank[b, 0]: the longest edge
    dev = np.zeros((n, 3))
    for r in range(3):
        np.put_along_axis(dev, rank[:, r:r + 1], (sigma[r] * z[:, r])[:, None], axis=1)
    dev[~movable] = 0.0
    size = scene.size + dev
    out.mass = scene.mass * np.prod(size / scene.size, axis=1)
    lo = lo0.copy()
    # 2. head joints, along x then along y, within each course
    for ax in (0, 1):
        others = [a for a in range(3) if a != ax]
        order = np.argsort(lo0[:, ax], kind="stable")
        hi_new = lo0[:, ax] + size[:, ax]
        for b in order:
            if not movable[b] or scene.course[b] < 0:
                hi_new[b] = lo[b, ax] + size[b, ax]
                continue
            touching = (np.abs(hi0[:, ax] - lo0[b, ax]) < EPS) & (scene.course == scene.course[b])
            for a in others:
                touching &= (np.minimum(hi0[:, a], hi0[b, a]) - np.maximum(lo0[:, a], lo0[b, a])
                             > EPS)
            start = lo0[b, ax]
            if touching.any():
                start = float(hi_new[touching].max())
            lo[b, ax] = start
            hi_new[b] = start + size[b, ax]
    _push_apart_corners(lo, size, scene.course, movable, lo0)
    # 3. heights: each block on the highest of the blocks it stood on
    hi_z = lo[:, 2] + size[:, 2]
    for b in np.argsort(lo0[:, 2], kind="stable"):
        if not movable[b] or abs(lo0[b, 2]) < EPS:
            hi_z[b] = lo[b, 2] + size[b, 2]
            continue
        below = np.abs(hi0[:, 2] - lo0[b, 2]) < EPS
        if below.any():
            hi_xy = lo[:, :2] + size[:, :2]
            over = below.copy()
            for a in (0, 1):
                over &= (np.minimum(hi_xy[:, a], lo[b, a] + size[b, a])
                         - np.maximum(lo[:, a], lo[b, a]) > EPS)
            if over.any():
                lo[b, 2] = float(hi_z[over].max())
            else:
                lo[b, 2] = lo0[b, 2] + float((hi_z[below] - hi0[below, 2]).mean())
        hi_z[b] = lo[b, 2] + size[b, 2]
    out.size = size
    out.position = lo + 0.5 * size
    return out


def _push_apart_corners(lo, size, course, movable, lo0, passes: int = 10) -> None:
    """Step 2's corner fix-up (module docstring), in place on lo: overlapping blocks of one
    course are pushed apart along x or y, whichever overlaps less; the block with the larger
    nominal lo along that axis moves."""
    n = len(lo)
    for _ in range(passes):
        moved = False
        hi = lo + size
        for b in range(n):
            if course[b] < 0:
                continue
            same = (course == course[b]) & (np.arange(n) > b)
            ov = np.minimum(hi, hi[b]) - np.maximum(lo, lo[b])  # [n, 3] overlap per axis
            hit = same & (ov > EPS).all(axis=1)
            for c in np.flatnonzero(hit):
                ax = 0 if ov[c, 0] <= ov[c, 1] else 1
                first, second = (b, c) if lo0[b, ax] <= lo0[c, ax] else (c, b)
                if movable[second]:
                    lo[second, ax] = lo[first, ax] + size[first, ax]
                elif movable[first]:
                    lo[first, ax] = lo[second, ax] - size[first, ax]
                moved = True
                hi = lo + size
        if not moved:
            return
