"""Settle phase: an imperfect scene comes to rest under gravity before it is loaded.

Warped faces (dem.imperfections) are recessed from the nominal box faces, so an imperfect
specimen is built with gaps: each block stands on the highest corners of its beds, millimetres
above where it will come to rest (~3 sigma per bed).  Dropped into the load phase as it is, the
wall would still be falling when the tilt or the shaking starts.  The settle phase lets it come
to rest first:

* the loads are those of the loading at t = 0 (gravity of the start angle of a tilt, no base
  acceleration), with Cundall local damping ``ALPHA`` (a force -alpha |F| sign(v) per component of
  each block's force and torque, as 3DEC / UDEC use for static solutions: it removes motion and
  leaves every static equilibrium where it is, so the settled pose is a true equilibrium of the
  undamped model);
* it ends when every block is at rest (|v| + r |omega| below ``REST_SPEED``) and the
  unbalanced-force ratio (dem.engine.Simulation.unbalanced_force_ratio) is below ``TOLERANCE``
  at ``CALM_CHECKS`` looks ``CHECK_STEPS`` steps apart, or after ``MAX_TIME`` s (then summary.json
  says it did not come to rest);
* the local damping is then switched back to the case's ``solver.local_damping`` and the clock
  restarts at t = 0: the loading (and every output time) starts after settling.

The energy sums run through it (the settling's local-damping dissipation is in
``dissipated_local_damping``), so the run's energy check covers it.  A perfect scene (no
imperfections) is not settled: it starts at rest in its built pose (nothing to settle: its
faces touch flat).
"""

from __future__ import annotations

import numpy as np

from dem.run.steps import Advance, Steps, drive

ALPHA = 0.8          # local damping while settling (3DEC's default 0.8)
REST_SPEED = 1e-5    # m/s: a block at rest (|v| + r |omega|)
TOLERANCE = 1e-4     # unbalanced-force ratio at rest
CHECK_STEPS = 200    # steps between two looks
CALM_CHECKS = 3      # looks in a row at rest
MAX_TIME = 5.0       # s: give up (reported) after this


class RestLoads:
    """The settling's loads (dem.run.steps.LoadFn): gravity ``g0`` (m/s^2, table frame) and no
    base acceleration at every time.  A value, not a closure: the settling scenes of an engine
    with equal gravity share one evaluation a chunk (dem.run.batched.shared_loads compares the
    load functions' pickled states)."""

    immutable = True

    def __init__(self, g0):
        self.g0 = np.asarray(g0, dtype=float)

    def __call__(self, t):
        return np.tile(self.g0, (len(t), 1)), np.tile(np.zeros(3), (len(t), 1))


def settle(sim, loading, local_damping: float, max_steps: int | None = None,
           on_look=None) -> dict:
    """Bring the scene to rest (module docstring); returns summary.json's ``settling``.
    ``on_look()`` is called at every look (progress display).  The scene advances alone
    (:func:`settle_steps`, driven by dem.run.steps.drive)."""
    return drive(settle_steps(sim, loading, local_damping, max_steps, on_look))


def settle_steps(sim, loading, local_damping: float, max_steps: int | None = None,
                 on_look=None) -> Steps:
    """:func:`settle` as a steppable phase (dem.run.steps): yields its advances, returns
    summary.json's ``settling``."""
    g0 = loading.gravity(np.array([0.0]))[0]
    loads = RestLoads(g0)
    n = sim.n_blocks
    movable = ~sim.model.fixed_np[:n]
    pos0 = sim.read_state("pos").pos[:n].copy()
    radius = sim.model.radius_np[:n]
    sim.set_local_damping(ALPHA)
    calm = 0
    speed = ratio = None  # not looked at yet (a step limit before the first look)
    steps0 = sim.step_count
    while sim.t < MAX_TIME:
        k = CHECK_STEPS
        if max_steps is not None:
            k = min(k, max_steps - sim.step_count)
            if k <= 0:
                break
        yield Advance(sim, k, loads)
        st = sim.read_state("vel", "omega")
        speed = float((np.linalg.norm(st.vel[:n], axis=1)
                       + radius * np.linalg.norm(st.omega[:n], axis=1))[movable].max(initial=0.0))
        # the ratio (the contacts' wrenches: on a device, most of what a look copies back) only
        # where it can decide: a block still moving makes the look not calm whatever it is
        ratio = None
        if speed < REST_SPEED:
            ratio = sim.unbalanced_force_ratio(g0)
        calm = calm + 1 if ratio is not None and ratio < TOLERANCE else 0
        if on_look is not None:
            on_look()
        if calm >= CALM_CHECKS:
            break
    if speed is not None and ratio is None:  # the last look's ratio, for the summary (no step
        ratio = sim.unbalanced_force_ratio(g0)  # was taken since that look)
    sim.set_local_damping(local_damping)
    energy = sim.energy_report()
    moved = sim.read_state("pos").pos[:n] - pos0
    drop = -moved[:, 2]
    elapsed = sim.restart_clock()
    return {"at_rest": calm >= CALM_CHECKS, "time_s": elapsed, "steps": sim.step_count - steps0,
            "largest_settlement_m": float(drop[movable].max(initial=0.0)),
            "largest_displacement_m": float(np.linalg.norm(moved, axis=1)[movable].max(initial=0.0)),
            "final_speed_m_s": speed, "final_unbalanced_force_ratio": ratio,
            "energy_residual_J": energy["residual"], "work_gravity_J": energy["work_gravity"],
            "local_damping": ALPHA, "criteria": {"rest_speed_m_s": REST_SPEED,
                                                 "unbalanced_force_ratio": TOLERANCE,
                                                 "looks": CALM_CHECKS, "max_time_s": MAX_TIME}}
