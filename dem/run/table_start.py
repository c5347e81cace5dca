"""The table's start at the beginning of the load phase (dem.table_motion).

With ``loading.start: lab`` the table is at rest before t = 0 and moves at v_0 = A w along d
from t = 0 on.  Over that instant the table's acceleration is infinite, but no finite force
acts on a body long enough to change its momentum (contact forces are bounded by the
Coulomb limit mu N and the elastic springs): a body at rest in the lab stays at rest in the
lab, so relative to the table (the engine's frame: its velocities are relative to the table)
every free block starts with

    v_rel(0+) = v_rel(0-) - v_0 d        m/s,

and its angular velocity is unchanged (a uniform velocity change exerts no torque).  Fixed
blocks move with the table and keep v_rel = 0.  The engine's energy balance counts kinetic
energy relative to the table, so the jump changes it by dK = sum m (|v + dv|^2 - |v|^2) / 2;
that is work done by the change of frame, not by the scheme: it is added to the balance's
initial energy (``energy_initial``) so the residual stays the scheme's.

:func:`apply_table_start` is called once, when the load phase starts after any settling
(dem.run.loop); a resumed run goes on from its checkpoint and does not call it again.
"""

from __future__ import annotations

import numpy as np


def apply_table_start(sim, loading) -> dict | None:
    """Give every free block the loading's initial relative velocity
    (dem.loading.Loading.initial_relative_velocity); returns summary.json's ``table_start``
    (None, and nothing changed, when that velocity is zero: every start but ``lab``)."""
    dv = np.asarray(loading.initial_relative_velocity(), dtype=float)
    if not np.any(dv):
        return None
    n = sim.n_blocks
    free = ~np.asarray(sim.model.fixed_np[:n], dtype=bool)
    vel = sim.state.vel
    k0 = sim.kinetic_energy()
    vel[:n][free] += dv[None, :]
    dk = sim.kinetic_energy() - k0
    sim.energy_initial += dk
    return {"start": "lab", "relative_velocity_m_s": dv.tolist(), "blocks": int(free.sum()),
            "kinetic_energy_added_J": float(dk),
            "note": "every free block took minus the table's velocity jump at t = 0 (relative "
                    "to the table): at rest in the lab as the table started"}
