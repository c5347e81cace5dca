"""The DEM runs of the study: free rocking of a single block, of a stack, and of the Model II y
excited portion built of bricks.
"""

from __future__ import annotations

import json
import math
import time
from pathlib import Path

import numpy as np

from studies.impact_dissipation.physics import (amplitude_after_impact, BRICK_DENSITY, G,
                                                half_cycle_peaks, housner_r_block, impact_ratios,
                                                omega_ratios, rigid_impact_r, rocking_energy,
                                                SHAKE_MATERIAL)
from studies.impact_dissipation.two_body import two_body_params


# ------------------------------------------------------------------------------------------
# DEM runs
# ------------------------------------------------------------------------------------------
def _gravity_loads(g=G):
    gv = np.array([0.0, 0.0, -g])
    return lambda t: (np.tile(gv, (len(t), 1)), np.zeros((len(t), 3)))


def _simulation(scene, damping: float | None = None, kn: float | None = None,
                friction: float | None = None):
    """Engine for a scene with the shake cases' material (defaults otherwise); ``friction``
    replaces both friction coefficients."""
    from dem.case import parse_case
    from dem.engine import Simulation
    from dem.run.build import joint_law, step_options

    mat = dict(SHAKE_MATERIAL)
    if damping is not None:
        mat["damping"] = damping
    if kn is not None:
        mat["normal_stiffness"] = kn
    if friction is not None:
        mat["friction"] = mat["base_friction"] = friction
    case = parse_case({"name": "impact", "scene": {"blocks": [
        {"size": [0.1, 0.1, 0.1], "position": [0, 0, 0.05], "mass": 1.0}]},
        "material": mat, "run": {"duration": 1.0}})
    return Simulation(scene, joint_law(case.material), step_options(case.solver),
                      gravity=(0.0, 0.0, -G)), case.material


def _record(sim, duration: float, every: float, ids=None):
    """Step under gravity for ``duration`` s, sampling every ``every`` s: t, quat, omega of ids."""
    ids = np.arange(sim.n_blocks) if ids is None else np.asarray(ids)
    n_every = max(1, int(round(every / sim.dt)))
    loads = _gravity_loads()
    ts, qs, ws = [sim.t], [sim.state.quat[ids].copy()], [sim.state.omega[ids].copy()]
    while sim.t < duration - 0.5 * sim.dt:
        sim.advance(n_every, loads)
        ts.append(sim.t)
        qs.append(sim.state.quat[ids].copy())
        ws.append(sim.state.omega[ids].copy())
    return np.array(ts), np.array(qs), np.array(ws)


def run_block(b: float, h: float, depth: float, frac: float = 0.5, damping: float | None = None,
              kn: float | None = None, duration: float = 1.0, every: float = 2e-4) -> dict:
    """Free rocking of one uniform block (width b along x, height h, depth along y; m; brick
    density) on the table, released at rest from frac * alpha about its +x bottom edge.
    Returns the history, the peaks, the ratios and Housner's prediction."""
    from scipy.spatial.transform import Rotation

    from dem.scene import blocks_to_scene
    from dem.case import BlockSpec

    alpha = math.atan2(b, h)
    th0 = frac * alpha
    rot = Rotation.from_euler("y", th0)
    centre = np.array([b / 2, 0, 0]) + rot.apply([-b / 2, 0, h / 2])
    blk = BlockSpec(size=[b, depth, h], position=centre.tolist(),
                    rotation=[0, math.degrees(th0), 0], density=BRICK_DENSITY)
    t0 = time.process_time()
    sim, _ = _simulation(blocks_to_scene([blk]), damping, kn)
    compile_cpu = time.process_time() - t0
    t, q, w = _record(sim, duration, every)
    cpu = time.process_time() - t0
    theta = 2 * np.arctan2(q[:, 0, 2], q[:, 0, 0])
    omega = w[:, 0, 1]
    tp, pk = half_cycle_peaks(t, theta)
    c, z = b / 2, h / 2
    ratios = impact_ratios(pk, (c, z))
    i_o_m = (b * b + h * h) / 3.0
    wr = omega_ratios(theta, omega, c, z, i_o_m, 0.05 * th0)
    r_h = housner_r_block(b, h)
    a_h = amplitude_after_impact(th0, r_h, c, z) / th0
    return {"b_m": b, "h_m": h, "depth_m": depth, "b_over_h": b / h, "alpha_rad": alpha,
            "theta0_rad": th0, "release_fraction_of_alpha": frac,
            "damping": sim.joints.damping, "kn_pa_m": sim.joints.normal_stiffness,
            "dt_s": sim.dt, "housner_r": r_h, "housner_first_amplitude_ratio": a_h,
            "housner_energy_ratio": r_h ** 2, **ratios,
            "omega_ratio": wr, "mean_omega_ratio": float(np.mean(wr)) if wr else None,
            "t_peaks_s": tp.tolist(), "cpu_s": cpu, "compile_cpu_s": compile_cpu,
            "_t": t, "_theta": theta}


def run_stack(theta0: float = 0.02, damping: float | None = None, friction: float | None = None,
              duration: float = 1.0, every: float = 2e-4) -> dict:
    """The two-block stack of results/two-body/README.md section 7 (tests/test_rocking_vs_dem.py):
    Table 5.1's Model II parts as explicit blocks 50 x 300 x 140 mm (6.05 and 9.41 kg), turned
    together by theta0 (rad) about the +x bottom edge and released at rest.  Friction: the shake
    material unless ``friction`` is given (the doc used 2 everywhere).  Measured on the lower
    block's rotation, energies with the locked pair's (c, z) = (T/2, z_G)."""
    from dem.case import BlockSpec
    from dem.rocking.analysis import centre_of_mass_height, housner_restitution
    from dem.scene import blocks_to_scene

    T, H1, H2, M1, M2, L = 0.05, 0.14, 0.14, 6.05, 9.41, 0.3

    def block(h, zc, m):
        cx, cz = -T / 2, zc
        x = T / 2 + cx * math.cos(theta0) + cz * math.sin(theta0)
        z = -cx * math.sin(theta0) + cz * math.cos(theta0)
        return BlockSpec(size=[T, L, h], position=[x, 0.0, z],
                         rotation=[0.0, math.degrees(theta0), 0.0], mass=m)

    scene = blocks_to_scene([block(H1, H1 / 2, M1), block(H2, H1 + H2 / 2, M2)])
    t0 = time.process_time()
    sim, _ = _simulation(scene, damping, friction=friction)
    t, q, _ = _record(sim, duration, every)
    cpu = time.process_time() - t0
    th = np.arcsin(np.clip(2.0 * (q[:, :, 0] * q[:, :, 2] - q[:, :, 3] * q[:, :, 1]), -1, 1))
    P = two_body_params("table-5.1")
    tp, pk = half_cycle_peaks(t, th[:, 0])
    ratios = impact_ratios(pk, (T / 2, centre_of_mass_height(P)))
    r_h = housner_restitution(P)
    zg = centre_of_mass_height(P)
    return {"theta0_rad": theta0, "damping": sim.joints.damping,
            "friction": friction if friction is not None else SHAKE_MATERIAL,
            "dt_s": sim.dt, "housner_r": r_h,
            "housner_first_amplitude_ratio": amplitude_after_impact(theta0, r_h, T / 2, zg) / theta0,
            **ratios, "t_peaks_s": tp.tolist(),
            "max_relative_rotation_rad": float(np.abs(th[:, 1] - th[:, 0]).max()),
            "cpu_s": cpu, "_t": t, "_theta": th[:, 0]}


MODEL_II_CASE = "cases/shake/model-ii/group-3-y-1.53.yaml"
EXCITED_ANALYSIS = "results/shake/model-ii-y-amplified/f2.800Hz/analysis.json"


def portion_scene(root: Path, free: str = "upper", side_walls: bool = True):
    """The Model II box (perfect bricks, built from the shake case) around the DEM's own excited
    portion of L1 under y shaking (results/shake, 4.0 m/s2, 2.8 Hz: 30 upper + 13 lower bricks).

    ``free = "upper"``: the upper part (top 4 courses of L1 + 2 side-wall bricks at each end) is
    free, every other brick fixed; ``"portion"``: upper and lower parts free.  The roof (beams,
    1 kg masses, corner masses) is removed.  ``side_walls=False`` also removes the side walls'
    bricks of the upper part's courses (the facade top then has free ends).

    Returns (scene, free ids, upper ids, lower ids, props) with props of the free body: mass
    (kg), centre of mass (m), I_G about x (kg m2), the outer / inner bottom edges (y, z) and the
    centre of mass seen from each edge (c, z), thickness and height (m)."""
    import yaml

    from dem.case import parse_case
    from dem.run.build import scene_from_case
    from dem.scene import Scene

    case = parse_case(yaml.safe_load((root / MODEL_II_CASE).read_text()))
    sc = scene_from_case(case, imperfect=False)
    ep = json.loads((root / EXCITED_ANALYSIS).read_text())["axes"]["y"]["excited_portion"]
    upper, lower = list(ep["upper_blocks"]), list(ep["lower_blocks"])
    names = np.array(sc.group_names)[sc.group]
    bricks = np.isin(names, ["L1", "L2", "T1", "T2"])
    z_up = float((sc.position[upper, 2] - sc.size[upper, 2] / 2).min())
    keep = bricks.copy()
    if not side_walls:
        side = np.isin(names, ["T1", "T2"]) & (sc.position[:, 2] > z_up)
        keep &= ~side
        upper = [i for i in upper if not side[i]]
    free_ids = np.array(sorted(upper if free == "upper" else upper + lower))
    sc.fixed = bricks.copy()
    sc.fixed[free_ids] = False
    idx = np.flatnonzero(keep)
    remap = -np.ones(sc.n_blocks, dtype=int)
    remap[idx] = np.arange(len(idx))
    sub = Scene(size=sc.size[idx], position=sc.position[idx], quat=sc.quat[idx],
                mass=sc.mass[idx], fixed=sc.fixed[idx], velocity=sc.velocity[idx],
                angular_velocity=sc.angular_velocity[idx], group=sc.group[idx],
                course=sc.course[idx], group_names=sc.group_names)
    fr = remap[free_ids]
    m, pos, s = sub.mass[fr], sub.position[fr], sub.size[fr]
    M = float(m.sum())
    G_ = (m[:, None] * pos).sum(0) / M
    l1 = names[idx] == "L1"
    y_out = float((sub.position[l1, 1] - sub.size[l1, 1] / 2).min())
    y_in = float((sub.position[l1, 1] + sub.size[l1, 1] / 2).max())
    z_base = float((pos[:, 2] - s[:, 2] / 2).min())
    i_own = m * (s[:, 1] ** 2 + s[:, 2] ** 2) / 12.0          # about x, each brick's centre
    i_g = float(i_own.sum() + (m * ((pos[:, 1] - G_[1]) ** 2 + (pos[:, 2] - G_[2]) ** 2)).sum())
    props = {"free": free, "side_walls": side_walls, "mass_kg": M, "n_bricks": int(len(fr)),
             "centre_of_mass_m": G_.tolist(), "I_G_kg_m2": i_g,
             "y_outer_m": y_out, "y_inner_m": y_in, "z_base_m": z_base,
             "pivot_outer_cz_m": [G_[1] - y_out, G_[2] - z_base],
             "pivot_inner_cz_m": [y_in - G_[1], G_[2] - z_base],
             "thickness_m": y_in - y_out, "height_m": float((pos[:, 2] + s[:, 2] / 2).max()) - z_base}
    ups = remap[np.array(upper)]
    lows = remap[np.array(lower)]
    return sub, fr, ups, lows, props


def tilt_portion(sc, ids, pivot, theta: float) -> None:
    """Turn the blocks ``ids`` rigidly by theta (rad) about the x axis through ``pivot`` (theta
    > 0: the top towards -y, outwards for L1), in place."""
    from scipy.spatial.transform import Rotation

    from dem import quaternion

    rot = Rotation.from_rotvec([theta, 0.0, 0.0])
    for i in ids:
        sc.position[i] = pivot + rot.apply(sc.position[i] - pivot)
    sc.quat[ids] = quaternion.from_rotation(rot * quaternion.rotation(sc.quat[ids]))


def release_rate(props: dict, theta_max: float) -> float:
    """Outward angular velocity (rad/s) about the outer bottom edge that lifts the rigid body to
    theta_max from upright: omega0^2 = 2 E(theta_max) / I_O."""
    c, z = props["pivot_outer_cz_m"]
    M, i_g = props["mass_kg"], props["I_G_kg_m2"]
    return math.sqrt(2.0 * float(rocking_energy(theta_max, c, z, M)) / (i_g + M * (c * c + z * z)))


def run_portion(root: Path, free: str = "upper", start: str = "tilt", side_walls: bool = True,
                frac: float = 0.5, damping: float | None = None, duration: float = 1.2,
                every: float = 5e-4) -> dict:
    """Free rocking of part of the Model II y excited portion (``portion_scene``), the rest of
    the box fixed, no roof.  ``start = "tilt"``: released at rest, turned rigidly outwards by
    frac * alpha_eq about the outer bottom edge of the free body (alpha_eq = atan(c / z) seen
    from that edge); ``"kick"``: upright, with the rigid outward rotation rate about that edge
    that would lift it to frac * alpha_eq.  Records the mass-weighted rotation of the free
    bricks about x (rad, > 0 outwards) and the mean rotation of the upper and lower parts."""
    from scipy.spatial.transform import Rotation

    from dem.builders import check_scene, require_valid

    sc, fr, ups, lows, props = portion_scene(root, free, side_walls)
    c, z = props["pivot_outer_cz_m"]
    alpha = math.atan2(c, z)
    th_max = frac * alpha
    pivot = np.array([0.0, props["y_outer_m"], props["z_base_m"]])
    watch = np.array(sorted(set(fr.tolist()) | set(ups.tolist()) | set(lows.tolist())))
    q_up = sc.quat[watch].copy()
    w0 = release_rate(props, th_max)
    # the far edge of the seat: the innermost bottom edge of the free bricks, upright (the
    # side-wall bricks reach 105-158 mm inside the facade's outer face)
    b_far = float((sc.position[fr, 1] + sc.size[fr, 1] / 2).max()) - props["y_outer_m"]
    if start == "tilt":
        tilt_portion(sc, fr, pivot, th_max)
    else:
        omega = np.array([w0, 0.0, 0.0])
        for i in fr:
            sc.angular_velocity[i] = omega
            sc.velocity[i] = np.cross(omega, sc.position[i] - pivot)
    require_valid(check_scene(sc, overlap_tolerance=1e-7, allow_floating=True))
    t0 = time.process_time()
    sim, _ = _simulation(sc, damping)
    compile_cpu = time.process_time() - t0
    t, q, w = _record(sim, duration, every, watch)
    cpu = time.process_time() - t0
    rel = Rotation.from_quat(q.reshape(-1, 4)[:, [1, 2, 3, 0]]) * \
        Rotation.from_quat(np.tile(q_up[:, [1, 2, 3, 0]], (len(t), 1))).inv()
    rv = rel.as_rotvec().reshape(len(t), len(watch), 3)[:, :, 0]
    col = {int(b): k for k, b in enumerate(watch)}
    kf = [col[int(b)] for b in fr]
    m = sc.mass[fr]
    theta = (rv[:, kf] * m).sum(1) / m.sum()
    th_up = rv[:, [col[int(b)] for b in ups]].mean(1)
    th_lo = rv[:, [col[int(b)] for b in lows]].mean(1)
    tp, pk = half_cycle_peaks(t, theta)
    ratios = impact_ratios(pk, tuple(props["pivot_outer_cz_m"]), tuple(props["pivot_inner_cz_m"]))
    # equivalent rigid body: Housner's plastic impact with the free body's own mass distribution
    b = props["thickness_m"]
    ci, zi = props["pivot_inner_cz_m"]
    r_out_in = rigid_impact_r(props["mass_kg"], props["I_G_kg_m2"], c, z, b)   # outer -> inner
    r_in_out = rigid_impact_r(props["mass_kg"], props["I_G_kg_m2"], ci, zi, b)
    # the far edge of the seat: the innermost bottom edge of the free bricks (the side-wall
    # bricks reach 105-158 mm inside the facade's outer face)
    return {"start": start, "damping": sim.joints.damping, "dt_s": sim.dt, **props,
            "alpha_eq_rad": alpha, "theta0_rad": th_max, "release_fraction_of_alpha": frac,
            "omega0_rad_s": w0 if start == "kick" else 0.0,
            "housner_r_outer_to_inner": r_out_in, "housner_r_inner_to_outer": r_in_out,
            "housner_r_uniform_block": housner_r_block(b, props["height_m"]),
            "housner_r_facade_edges_mean": math.sqrt(max(r_out_in, 0.0) * max(r_in_out, 0.0)),
            "seat_width_far_m": b_far,
            "housner_r_far_edge": rigid_impact_r(props["mass_kg"], props["I_G_kg_m2"], c, z, b_far),
            "housner_first_amplitude_ratio": amplitude_after_impact(th_max, r_out_in, c, z, ci, zi)
            / th_max,
            **ratios, "t_peaks_s": tp.tolist(),
            "max_rotation_upper_rad": float(np.abs(th_up).max()),
            "max_rotation_lower_rad": float(np.abs(th_lo).max()) if len(lows) else None,
            "cpu_s": cpu, "compile_cpu_s": compile_cpu,
            "_t": t, "_theta": theta, "_theta_upper": th_up, "_theta_lower": th_lo}


