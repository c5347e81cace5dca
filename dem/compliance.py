"""What the joint stiffness does to a tilt's load factor: the elastic offset of tipping, and the
stiffness that keeps it below a bound (``material.normal_stiffness: rigid``).

A penalty joint lets a block (or a column of blocks) rotate on its base before it tips.  With the
heel lifted, the pressure under a base of width b (along the load) and depth a is triangular over
a width w from the toe; moment equilibrium of a column of height H (centre of mass at H/2,
density rho) and the elastic toe give (docs/engine.md section 5)

    tan(theta_tip) = b / H - Delta,    Delta = (6 rho g b cos(theta) / (kn H))^(1/3)

so the relative offset of the rigid-block value b / H is

    Delta / (b / H) = (6 rho g H^2 cos(theta) / (kn b^2))^(1/3)          (cos(theta) <= 1 below)

and the stiffness that keeps it at most eps is kn = 6 rho g H^2 / (eps^3 b^2).  It grows with
the column's slenderness H / b squared: a lone small brick needs ~1e11 Pa/m for 0.5 %, a
525 mm high, 50 mm thick wall tipping about its base ~1e14 Pa/m.  Only the base joint of a
column is counted (the joints above carry less and add less), so this is an estimate.

Two estimates, each the largest over the scene: single blocks (H = the block's height), and
columns (every block resting on the table with all the blocks whose footprints overlap its own
above it: H = their top, rho = their mass over their volume).  b is the block's width along the
load direction when there is one (a tilt's), else its smaller horizontal edge.  The column
estimate is pessimistic for bonded walls (a running bond makes the whole wall one column of one
brick's width; the mechanisms of an in-plane wall stand on several bricks).
Units: m, kg, Pa/m, m/s^2.
"""

from __future__ import annotations

import numpy as np

from dem.builders.checks import vertices

RIGID_OFFSET = 0.005   # material.normal_stiffness: rigid keeps the relative offset at most this


def _candidates(scene, direction=None) -> dict[str, list[tuple[float, float, float]]]:
    """(b, H, rho) of every single block and of every column standing on the table."""
    lo, hi = _aabb(scene)
    vol = np.prod(scene.size, axis=1)
    rho = scene.mass / vol
    ext = hi - lo
    if direction is None:
        b = np.minimum(ext[:, 0], ext[:, 1])
    else:
        d = np.abs(np.asarray(direction, dtype=float)[:2])
        d = d / np.linalg.norm(d)
        b = d[0] * ext[:, 0] + d[1] * ext[:, 1]
    movable = ~scene.fixed
    blocks = [(float(b[i]), float(ext[i, 2]), float(rho[i])) for i in np.flatnonzero(movable)]
    tol = 1e-6
    columns = []
    for i in np.flatnonzero((lo[:, 2] < tol) & movable):
        over = ((lo[:, 0] < hi[i, 0] - tol) & (hi[:, 0] > lo[i, 0] + tol)
                & (lo[:, 1] < hi[i, 1] - tol) & (hi[:, 1] > lo[i, 1] + tol) & movable)
        H = float(hi[over, 2].max() - lo[i, 2])
        columns.append((float(b[i]), H, float(scene.mass[over].sum() / vol[over].sum())))
    return {"block": blocks, "column": columns or blocks}


def _aabb(scene) -> tuple[np.ndarray, np.ndarray]:
    c = vertices(scene)
    return c.min(axis=1), c.max(axis=1)


def _worst(cands):
    return max(cands, key=lambda c: c[2] * c[1] ** 2 / c[0] ** 2)


def elastic_offset(scene, kn: float, g: float = 9.81, direction=None) -> dict:
    """The largest relative elastic offsets of a tipping load factor in the scene at joint
    stiffness ``kn`` (Pa/m): ``block`` (single blocks) and ``column`` (table-standing columns),
    each with the b, H (m) and rho (kg/m^3) that give it."""
    out = {"normal_stiffness_Pa_m": kn,
           "direction": None if direction is None else [float(x) for x in direction],
           "definition": "(6 rho g H^2 / (kn b^2))^(1/3): the fraction by which the base joint's "
                         "compliance lowers the rigid tipping load factor b/H of a block or a "
                         "column, largest over the scene (dem/compliance.py)"}
    for kind, cands in _candidates(scene, direction).items():
        b, H, rho = _worst(cands)
        out[kind] = {"relative": (6.0 * rho * g * H * H / (kn * b * b)) ** (1.0 / 3.0),
                     "width_m": b, "height_m": H, "density_kg_m3": rho}
    return out


def rigid_stiffness(scene, g: float = 9.81, eps: float = RIGID_OFFSET, direction=None) -> float:
    """kn (Pa/m) that keeps the relative elastic offset of every single block at ``eps``
    (``material.normal_stiffness: rigid``)."""
    b, H, rho = _worst(_candidates(scene, direction)["block"])
    return 6.0 * rho * g * H * H / (eps ** 3 * b * b)
