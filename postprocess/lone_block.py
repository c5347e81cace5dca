"""The closed form of rigid blocks standing alone on a tilting table (one of the numbers that
decide a tilt's result, shown with it: postprocess/decisive.py).

Closed form (statics of one rigid box on a tilted plane; the tipping threshold is Housner's
tan(alpha) = b/h, Housner 1963, BSSA 53(2)).  A box of width b along the load (m) and height h
(m) on its base, Coulomb friction mu_b against the table, under gravity turned by the table
angle theta (load factor lambda = tan(theta), in the table frame a lateral load lambda W at the
centroid, W the weight):

    sliding   when lambda W > mu_b W        ->  lambda = mu_b
    tipping   when lambda W h/2 > W b/2     ->  lambda = b / h     (moment about the toe)

so the block goes at lambda_c = min(mu_b, b/h), sliding if mu_b < b/h.  The first collapse of a
scene of such lone blocks is the smallest lambda_c over them.  A penalty joint of normal
stiffness kn lets a block rotate on its base before it tips; the toe's elastic offset lowers the
tipping value (docs/engine.md section 5, postprocess.limit_analysis.elastic_tipping_factor):

    tan(theta) = b/h - (6 rho g b cos(theta) / (kn h))^(1/3)

and leaves sliding where it is (the shear spring reaches mu N at the same load).  It applies to
scenes whose every free block stands alone (postprocess.tilt.isolated_blocks), unrotated, on
the table (its bottom at z = 0), without imperfections, loaded along the table's x or y axis;
anything else gets no closed form (None).
Units: m, kg/m3, Pa/m, m/s2; angles in degrees.
"""

from __future__ import annotations

import math

import numpy as np


FORMULA = "lone rigid block: lambda = min(mu_base, b/h)"


def lone_block_limits(case, scene, load_dir, kn: float | None = None,
                      g: float = 9.81) -> dict | None:
    """The closed form of the first collapse of a scene of lone blocks (module docstring), or
    None where it does not apply: {"load_factor", "angle_deg", "mode", "block", "formula",
    "blocks": [per block: b_m, h_m, mu, load_factor, mode]}, with "elastic_load_factor" (the
    first collapse with the toe's elastic offset at ``kn``) when ``kn`` is given."""
    from postprocess.limit_analysis import elastic_tipping_factor
    from postprocess.tilt import isolated_blocks

    if case.imperfections.any() or scene.n_blocks == 0:
        return None
    d = np.asarray(load_dir, float)[:2]
    d = d / max(np.linalg.norm(d), 1e-300)
    if not (abs(abs(d[0]) - 1.0) < 1e-9 or abs(abs(d[1]) - 1.0) < 1e-9):
        return None  # an oblique load tips a box about a corner: no closed form here
    free = ~np.asarray(scene.fixed, bool)
    if not free.any() or not isolated_blocks(scene)[free].all():
        return None
    q = np.asarray(scene.quat, float)
    if not np.allclose(np.abs(q[free, 0]), 1.0, atol=1e-12):
        return None  # a rotated block
    size = np.asarray(scene.size, float)
    bottom = np.asarray(scene.position, float)[:, 2] - 0.5 * size[:, 2]
    if np.abs(bottom[free]).max() > 1e-6:
        return None  # not standing on the table
    mu = case.material.mu_base
    rows = []
    for i in np.flatnonzero(free):
        b = float(abs(d[0]) * size[i, 0] + abs(d[1]) * size[i, 1])
        h = float(size[i, 2])
        lam = min(mu, b / h)
        row = {"block": int(i), "b_m": b, "h_m": h, "mu": mu, "load_factor": lam,
               "mode": "sliding" if mu < b / h else "tipping"}
        if kn is not None:
            rho = float(scene.mass[i] / np.prod(size[i]))
            row["elastic_load_factor"] = min(mu, elastic_tipping_factor(b, h, rho, kn, g))
        rows.append(row)
    first = min(rows, key=lambda r: (r["load_factor"], r["block"]))
    out = {"formula": FORMULA, "load_factor": first["load_factor"],
           "angle_deg": math.degrees(math.atan(first["load_factor"])), "mode": first["mode"],
           "block": first["block"], "blocks": rows}
    if kn is not None:
        out["elastic_load_factor"] = min(r["elastic_load_factor"] for r in rows)
        out["normal_stiffness_Pa_m"] = kn
    return out


def reference_limit(case, scene, frames: dict, summary: dict) -> dict:
    """A run analysis (dem_cli.commands.run.RUN_ANALYSES): summary.json ``reference``, the closed
    form of a tilt of lone blocks (:func:`lone_block_limits`) at the run's kn; {} otherwise."""
    if case.loading.type != "tilt":
        return {}
    from dem.loading import loading_from_case

    kn = (summary.get("joints") or {}).get("normal_stiffness_Pa_m")
    g = float(np.linalg.norm(case.gravity_vector()))
    ref = lone_block_limits(case, scene, loading_from_case(case).load_direction, kn, g)
    return {"reference": ref} if ref is not None else {}
