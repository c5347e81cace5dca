"""The engine's time step: chosen at the start from the critical step of every scene, shortened
when a contact patch outgrows the area assumed for it, taken from a restart point.

The scenes of an engine share one step (the smallest of their critical steps x safety: one
kernel launch steps them all); each scene keeps its own clock (dem.engine.timestep.Clock: t
counted from an anchor, so a change of dt never moves t).  :class:`StepSize` owns the engine's
side: ``clock`` (dt, dt_crit and the per-body area caps and face areas behind dt_crit; its
anchors are unused) and the stiffness the bound is made for; each shortening is logged in every
scene's ``dt_changes`` (summary.json).  The bound itself and the caps are pure functions of
dem.engine.timestep.
"""

from __future__ import annotations

import numpy as np

from dem.engine.errors import InputError, SimulationError
from dem.engine.timestep import Clock, critical_time_step, face_area_caps, full_face_areas


class StepSize:
    """The time step of an engine of the scenes of ``models`` (dem.engine.containers.Model,
    one per scene; ``model`` their concatenation), with ``joints`` (one JointLaw per scene) and
    the StepOptions ``options`` (safety, a fixed dt)."""

    def __init__(self, models, joints, model, options):
        self.model = model
        self.options = options
        self.movable = ~model.fixed_np
        self.clock = Clock()
        # the stiffest pair of materials in use (one pair: the material's kn, ks, zeta; the
        # hyperbolic law: its tangent at the largest closure the step is made for)
        stiff = [m.stiffest() for m in models]
        self.kn, self.ks, self.zeta = (max(x[k] for x in stiff) for k in range(3))
        # the largest damping time of a stiffness-proportional dashpot (s; 0: none)
        self.beta = max(m.largest_beta() for m in models)
        # per scene, the closure its hyperbolic pairs may reach before the run stops (None:
        # linear, or a capped law that goes on along its tangent: JointLaw.beyond_closure_limit);
        # the step is made for the stiffest tangent of them all, so each scene's own limit holds
        # in the batch
        self.closure_limits = [
            None if getattr(j, "beyond_closure_limit", "stop") == "tangent" else m.closure_limit()
            for m, j in zip(models, joints)]

    @property
    def dt(self) -> float:
        return self.clock.dt

    def start(self, patch: np.ndarray) -> None:
        """The first step, from each body's largest contact patch at the start (``patch``, m^2):
        face areas in the critical-step bound, capped for light blocks with large faces (a
        contact patch larger than its cap later lifts the cap and recomputes dt:
        :meth:`check_caps`); a fixed solver.dt is checked against the bound."""
        options = self.options
        self.clock.face_area, self.clock.area_cap = face_area_caps(
            2 * self.model.half_np, self.model.mass_np, self.model.inertia_np, self.movable,
            self.kn, self.ks, options.safety, patch)
        self.clock.dt_crit = self.critical_step()
        if options.dt is not None:
            if options.dt > self.clock.dt_crit:
                raise InputError(
                    f"solver.dt = {options.dt:.3g} s is above the critical time step "
                    f"{self.clock.dt_crit:.3g} s of this scene (stiffest block, kn = "
                    f"{self.kn:.3g} Pa/m); use solver.dt <= "
                    f"{options.safety * self.clock.dt_crit:.3g} s or leave it out")
            self.clock.dt = float(options.dt)
        else:
            self.clock.dt = (float(options.safety * self.clock.dt_crit)
                             if np.isfinite(self.clock.dt_crit) else 1e-4)

    def critical_step(self) -> float:
        m = self.model
        return critical_time_step(2 * m.half_np, m.mass_np, m.inertia_np, self.movable,
                                  self.kn, self.ks, self.zeta, self.clock.face_area,
                                  beta=self.beta)

    def set_dt(self, new: float, sims, why: dict | None = None) -> None:
        """Change the time step of every scene (``sims``): each clock is re-anchored at its
        present step (its t does not move); ``why`` (a dict) is logged in each scene's
        ``dt_changes`` with the old and new step."""
        old = self.clock.dt
        record = None if why is None else {**why, "old_dt": old, "new_dt": new}
        for sim in sims:
            sim.clock.anchor(sim.t, sim.step_count)
            sim.clock.dt = new
            if record is not None:
                sim.dt_changes.append(record)
        self.clock.dt = new

    def adopt_dt(self, dt: float, sims) -> None:
        """A scene restored from a restart point taken with ``dt``: the engine takes the smaller
        of the two steps (several scenes share one)."""
        if dt < self.clock.dt:
            self.set_dt(float(dt), sims)

    def check_caps(self, engine) -> None:
        """Raise the area cap of any body whose contact patch outgrew it, and shorten dt.

        Caps are never below the smallest cap whose bound is within 0.5 / safety^2 of the
        full-face one (dem.engine.timestep.face_area_caps), so the step in use was still stable;
        the new cap is twice the patch that exceeded the old one (the whole faces, no cap, once
        that reaches the block's largest face)."""
        area_cap = self.clock.area_cap
        capped = np.isfinite(area_cap)
        if not capped.any():
            return
        if not engine.residency.patches_over_caps(engine.n_pair_slots(), area_cap,
                                                  engine.variants.batched):
            return  # no patch near its cap: the areas need not come to the host
        # the patches' areas, and the pairs (the device's broad phase may have rewritten them)
        engine.host("contacts", write=False, fields=("area", "npts", "pairs"))
        patch = np.zeros(self.model.n_bodies)
        over_any = False
        for g, sim in enumerate(engine.simulations):
            c = sim.contacts_on_host
            n = c.n_pairs
            if n == 0 or not engine.control.active[g]:
                continue
            b0 = int(self.model.scene_bodies[g][0])
            pairs = c.pairs[:n] + b0
            watch = np.flatnonzero(capped[pairs[:, 0]] | capped[pairs[:, 1]])
            if len(watch) == 0:
                continue
            mask = np.arange(c.area.shape[1])[None, :] < c.npts[watch, None]
            area = (c.area[watch] * mask).sum(axis=1)
            limit = np.minimum(area_cap[pairs[watch, 0]], area_cap[pairs[watch, 1]])
            over = area > limit
            if not over.any():
                continue
            over_any = True
            for side in (0, 1):
                np.maximum.at(patch, pairs[watch[over], side], area[over])
        if not over_any:
            return
        bodies = np.flatnonzero((patch > 0) & capped)
        full = full_face_areas(2 * self.model.half_np[bodies])
        new_cap = 2.0 * patch[bodies]
        new_cap = np.where(new_cap >= full.max(axis=(1, 2)), np.inf, new_cap)
        area_cap[bodies] = new_cap
        self.clock.face_area[bodies] = np.minimum(full, new_cap[:, None, None])
        old = self.clock.dt
        self.clock.dt_crit = self.critical_step()
        first = engine.simulations[0]
        if self.options.dt is not None:
            if self.options.dt > self.clock.dt_crit:
                raise SimulationError(
                    f"at t = {first.t:.4f} s block(s) {bodies.tolist()} made a contact patch "
                    f"larger than assumed: the critical step is now {self.clock.dt_crit:.3g} s, "
                    f"below solver.dt = {self.options.dt:.3g} s; leave solver.dt out (automatic) "
                    f"or lower it")
            return
        new = float(self.options.safety * self.clock.dt_crit)
        if new < old:
            self.set_dt(new, engine.simulations,
                        {"t": first.t, "step": first.step_count, "blocks": bodies.tolist(),
                         "new_area_cap_m2": [float(x) for x in new_cap]})
