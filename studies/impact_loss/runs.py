"""One free-rocking block's run and its impact ratios (studies.impact_loss)."""

from __future__ import annotations

import math
import time

import numpy as np

from studies.impact_dissipation.physics import housner_r_block, omega_ratios

G = 9.81
B, DEPTH, DENSITY = 0.1, 0.1, 2000.0      # m, m, kg/m3: the rocking-block case's block
FRICTION = 0.8

#: the normal dashpots compared (material.normal_damping): today's default, 0.5 of critical
#: released point by point; the pair's no-tension rule at 0.75 of critical (the value chosen,
#: docs/engine.md section 6); the stiffness-proportional dashpot with the pair's rule, at the
#: damping time that gives the same r at h/b = 4 for this block
LAWS = {
    "critical": {},
    "pair": {"normal_damping": "pair", "damping": 0.75},
    "stiffness": {"normal_damping": "stiffness", "damping_time": 7.5e-4},
}


def material(law: str) -> dict:
    """The case's ``material:`` of a law."""
    return {"friction": FRICTION, **LAWS[law]}


def rocking_block(h_over_b: float, mat: dict, frac: float = 0.5, duration: float | None = None,
                  every: float = 1e-4, impacts: int = 3, b: float = B) -> dict:
    """Free rocking of the block of width b (m) and slenderness h/b with the given
    ``material:``; returns the impact ratios (omega+/omega- and over Housner's), the step and
    the CPU time."""
    from scipy.spatial.transform import Rotation

    from dem.case import parse_case
    from dem.engine import Simulation
    from dem.run.build import joint_law, step_options
    from dem.scene import blocks_to_scene

    h = b * h_over_b
    alpha = math.atan2(b, h)
    th0 = frac * alpha
    rot = Rotation.from_euler("y", th0)
    centre = np.array([b / 2, 0, 0]) + rot.apply([-b / 2, 0, h / 2])  # pivot on the +x edge
    case = parse_case({"name": "impact-loss", "scene": {"blocks": [
        {"size": [b, DEPTH, h], "position": centre.tolist(),
         "rotation": [0, math.degrees(th0), 0], "density": DENSITY}]},
        "material": mat, "run": {"duration": 1.0}})
    t0 = time.process_time()
    sim = Simulation(blocks_to_scene(case.scene.blocks), joint_law(case.material),
                     step_options(case.solver), gravity=(0.0, 0.0, -G))
    R = 0.5 * math.hypot(b, h)
    p = math.sqrt(3 * G / (4 * R))
    if duration is None:  # the first impacts: quarter cycles shrink with the amplitude
        duration = (impacts + 1) * 4.0 / p
    loads = lambda t: (np.tile([0.0, 0.0, -G], (len(t), 1)), np.zeros((len(t), 3)))  # noqa: E731
    n_every = max(1, int(round(every / sim.dt)))
    t0_run = time.process_time()
    qs, ws = [sim.state.quat[0].copy()], [sim.state.omega[0].copy()]
    while sim.t < duration - 0.5 * sim.dt:
        sim.advance(n_every, loads)
        qs.append(sim.state.quat[0].copy())
        ws.append(sim.state.omega[0].copy())
    cpu_run = time.process_time() - t0_run
    q, w = np.array(qs), np.array(ws)
    theta = 2 * np.arctan2(q[:, 2], q[:, 0])
    c, z = b / 2, h / 2
    ratios = omega_ratios(theta, w[:, 1], c, z, (b * b + h * h) / 3.0, 0.05 * th0)[:impacts]
    r_h = housner_r_block(b, h)
    return {"h_over_b": h_over_b, "b_m": b, "alpha_rad": alpha, "theta0_rad": th0,
            "material": mat, "dt_s": sim.dt, "steps": sim.step_count,
            "simulated_s": sim.t, "housner_r": r_h, "r": ratios,
            "r_over_housner": [x / r_h for x in ratios],
            "cpu_s": time.process_time() - t0, "cpu_run_s": cpu_run}
