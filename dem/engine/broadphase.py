"""Broad phase: the Verlet neighbour list of box pairs, built on the host.

A pair (i, j) is listed when the two boxes, each inflated by skin/2 on every side, overlap
(separating-axis test over the 15 axes).  The list stays valid while no body has moved by more
than skin/2, where "moved" bounds the displacement of every point of the box:
|x - x_ref| + r * angle(q_ref -> q), r the bounding radius (checked every step inside the kernel).

Candidates come from scipy's cKDTree on the block centres (bounding spheres), in two tiers so
that a few long blocks (roof beams) do not inflate every query; the table (last body) pairs with
every block whose lowest corner is within the skin of z = 0.
"""

from __future__ import annotations

import numpy as np
from scipy.spatial import cKDTree


def _sat_separated(pa, Ra, ha, pb, Rb, hb) -> np.ndarray:
    """Vectorised separating-axis test for M box pairs; True where separated."""
    d = pb - pa
    axes = [Ra[:, :, k] for k in range(3)] + [Rb[:, :, k] for k in range(3)]
    for k in range(3):
        for m in range(3):
            L = np.cross(Ra[:, :, k], Rb[:, :, m])
            nrm = np.linalg.norm(L, axis=1, keepdims=True)
            axes.append(np.where(nrm > 1e-6, L / np.maximum(nrm, 1e-300), 0.0))
    sep = np.zeros(len(d), dtype=bool)
    for L in axes:
        ra = sum(ha[:, k] * np.abs(np.einsum("ij,ij->i", Ra[:, :, k], L)) for k in range(3))
        rb = sum(hb[:, k] * np.abs(np.einsum("ij,ij->i", Rb[:, :, k], L)) for k in range(3))
        dist = np.abs(np.einsum("ij,ij->i", d, L))
        valid = np.einsum("ij,ij->i", L, L) > 0.5
        sep |= valid & (dist > ra + rb)
    return sep


def candidate_pairs(pos: np.ndarray, rot: np.ndarray, half: np.ndarray, radius: np.ndarray,
                    fixed: np.ndarray, table: int, skin: float) -> np.ndarray:
    """Sorted unique pairs (i, j), i < j, of bodies whose skin-inflated boxes overlap.

    pos [B,3], rot [B,3,3], half [B,3], radius [B]; body ``table`` is the table box.
    Pairs of two fixed bodies are left out (no force can act between them).
    """
    blocks = np.array([b for b in range(len(pos)) if b != table])
    pairs = []
    if len(blocks) > 1:
        r = radius[blocks]
        big = r > 2.0 * np.median(r)
        small = blocks[~big]
        if len(small) > 1:
            tree = cKDTree(pos[small])
            found = tree.query_pairs(2.0 * radius[small].max() + skin, output_type="ndarray")
            if len(found):
                pairs.append(small[found])
        for b in blocks[big]:
            others = blocks[blocks != b]
            dist = np.linalg.norm(pos[others] - pos[b], axis=1)
            near = others[dist <= radius[b] + radius[others] + skin]
            if len(near):
                pairs.append(np.column_stack([np.full(len(near), b), near]))
    if pairs:
        pr = np.vstack(pairs)
        pr = np.sort(pr, axis=1)
        pr = np.unique(pr, axis=0)
        i, j = pr[:, 0], pr[:, 1]
        keep = np.linalg.norm(pos[i] - pos[j], axis=1) <= radius[i] + radius[j] + skin
        keep &= ~(fixed[i] & fixed[j])
        pr = pr[keep]
        if len(pr):
            i, j = pr[:, 0], pr[:, 1]
            sep = _sat_separated(pos[i], rot[i], half[i] + 0.5 * skin,
                                 pos[j], rot[j], half[j] + 0.5 * skin)
            pr = pr[~sep]
    else:
        pr = np.zeros((0, 2), dtype=np.int64)
    # table: lowest corner within the skin of the plane z = 0
    zmin = pos[:, 2] - np.einsum("nk,nk->n", np.abs(rot[:, 2, :]), half)
    near_table = np.flatnonzero((zmin <= skin) & ~fixed)
    near_table = near_table[near_table != table]
    tp = np.column_stack([near_table, np.full(len(near_table), table)])
    allp = np.vstack([pr.reshape(-1, 2), tp]).astype(np.int32)
    order = np.lexsort((allp[:, 1], allp[:, 0]))
    return allp[order]
