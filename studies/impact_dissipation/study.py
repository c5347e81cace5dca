"""Impact dissipation of the DEM's rocking bodies against Housner and the two-body model
(issue 13 item 6).

    python -m studies impact-dissipation --out results/prediction/impact-dissipation

Runs (a) free rocking of single blocks, (b) the Model II y excited portion built of bricks,
(c) the two-body model (dem.rocking) with Housner's impact law and with the DEM's measured
restitution, (d) the dependence on the contact damping ratio (``--parts`` picks some; the others
keep their entries of an existing summary.json), and writes summary.json and
impact-dissipation.png under ``--out``; ``--tables`` prints the README's tables from it.  No run
directories or frames: the rotation histories go to /tmp/impact_dissipation_histories.npz only.

Closed forms (units SI: m, kg, s, rad; energies J)
-------------------------------------------------
Rigid body rocking on a rigid base about a bottom edge (planar).  Seen from the pivot O about
which it rocks, its centre of mass G lies at a horizontal distance c (towards the body) and a
height z.  Tilted by theta (>= 0, G moving towards the vertical over O) its rocking energy is

    E(theta) = M g (z cos theta + c sin theta - z)                                  [J]

(= M g R (cos(alpha - theta) - cos alpha) for a uniform block, R = |OG|, tan alpha = c / z).
Released at rest from theta0 it returns to theta = 0 with kinetic energy E(theta0); the next
excursion (about the other edge, distance c', height z) reaches theta1 with E'(theta1) = r^2
E(theta0), r = omega+ / omega- the impact's restitution (ratio of angular velocities).

Housner (1963) for a plastic impact on the new edge O', a distance b from O: angular momentum
about O' is conserved, I_G omega- + M (G - O') x v_G- = I_O' omega+, so

    r = (I_O - M b c) / I_O',   I_O = I_G + M (c^2 + z^2),  I_O' = I_G + M ((b - c)^2 + z^2)

which for a uniform rectangle (c = b/2, I_O = I_O' = M (b^2 + h^2) / 3) is

    r = 1 - M b^2 / (2 I_O) = 1 - 1.5 sin^2 alpha,   tan alpha = b / h,

and the energy kept per impact is r^2.  At small amplitudes E is nearly linear in theta
(E ~ M g c theta), so the amplitude ratio of successive half cycles is ~ r^2 (8.5 % lost per
impact for r = 0.957); the exact amplitude map is :func:`amplitude_after_impact`.

What is measured
----------------
From a rotation history theta(t) (rad) the half-cycle peaks are the extremes of |theta| between
impacts (:func:`half_cycle_peaks`: local maxima of |theta| separated by returns close to 0).  Per
impact k -> k+1: the amplitude ratio A_{k+1} / A_k and the energy ratio E(A_{k+1}) / E(A_k) with
each lobe's own pivot (c, z), whose square root is the equivalent restitution r_eq
(:func:`impact_ratios`).  For single blocks also the angular velocity just before and after each
impact (:func:`omega_ratios`), read at |theta| = d and carried to theta = 0 with the rigid-body
energy equation, omega(0)^2 = omega(d)^2 + 2 E(d) / I_O.

The two-body model (dem.rocking) is run with its own impact map: ``restitution: housner`` (the
plastic Moreau / Housner impact of the two parts) or a number e, which keeps the plastic velocity
direction and e^2 of the kinetic energy, so e = r_eq transfers the DEM's measured energy loss per
impact to it (dem/rocking/impacts.py).

DEM settings: the shake cases' material (friction 0.81, base_friction 1.5) and the defaults of
dem.case.Material / SolverSpec (kn = 5e9 Pa/m, ks = 0.4 kn, damping 0.5 of critical, dt = 0.3 of
critical); only part (d) changes the damping ratio.
"""

from __future__ import annotations

import argparse
import json
import math
import os
import time
from pathlib import Path

import numpy as np

G = 9.81
SHAKE_MATERIAL = {"friction": 0.81, "base_friction": 1.5}   # cases/shake/*: the shake cases
BRICK = (0.105, 0.05, 0.035)        # small brick L x W x H, m
BRICK_DENSITY = 0.336 / (0.105 * 0.05 * 0.035)   # kg/m3 (1829)


# ------------------------------------------------------------------------------------------
# closed forms
# ------------------------------------------------------------------------------------------
def housner_r(alpha):
    """Housner's restitution of a uniform rectangular block, r = 1 - 1.5 sin^2 alpha (-);
    alpha = atan(b / h) in rad."""
    return 1.0 - 1.5 * np.sin(alpha) ** 2


def housner_r_block(b: float, h: float) -> float:
    """r of a uniform block of width b and height h (m) rocking in the plane of b."""
    return float(housner_r(math.atan2(b, h)))


def rigid_impact_r(mass: float, i_g: float, c: float, z: float, b: float) -> float:
    """Plastic impact on the new edge O' a distance b (m) from the old pivot O, for a rigid body
    of mass M (kg), centroidal moment of inertia I_G (kg m2) about the rocking axis, and centre
    of mass at (c, z) (m) from O (c towards O'): r = (I_O - M b c) / I_O'."""
    i_o = i_g + mass * (c * c + z * z)
    i_o2 = i_g + mass * ((b - c) ** 2 + z * z)
    return (i_o - mass * b * c) / i_o2


def rocking_energy(theta, c: float, z: float, mass: float = 1.0, g: float = G):
    """E(theta) = M g (z cos theta + c sin theta - z), J (per kg with mass = 1): the rise of the
    centre of mass of a body tilted by theta >= 0 (rad) about its pivot, G at (c, z) from it."""
    th = np.abs(np.asarray(theta, dtype=float))
    return mass * g * (z * np.cos(th) + c * np.sin(th) - z)


def amplitude_after_impact(theta0: float, r: float, c0: float, z0: float,
                           c1: float | None = None, z1: float | None = None) -> float:
    """Amplitude (rad) reached after an impact of restitution r, released from theta0 at rest
    about a pivot with G at (c0, z0), rocking next about a pivot with G at (c1, z1) (default the
    same): solves E1(theta1) = r^2 E0(theta0) by bisection on [0, atan(c1/z1)]."""
    c1 = c0 if c1 is None else c1
    z1 = z0 if z1 is None else z1
    target = r * r * float(rocking_energy(theta0, c0, z0))
    lo, hi = 0.0, math.atan2(c1, z1)   # E1 increases on [0, alpha1]
    if target >= float(rocking_energy(hi, c1, z1)):
        return hi
    for _ in range(200):
        mid = 0.5 * (lo + hi)
        if float(rocking_energy(mid, c1, z1)) < target:
            lo = mid
        else:
            hi = mid
    return 0.5 * (lo + hi)


# ------------------------------------------------------------------------------------------
# measuring on a history
# ------------------------------------------------------------------------------------------
def half_cycle_peaks(t, theta, rel_floor: float = 0.02, return_frac: float = 0.3):
    """Half-cycle amplitudes of a rocking history: (t_peak, theta_peak) of the extremes of
    |theta| between impacts.

    A lobe ends at a sign change of theta or when |theta| falls below ``return_frac`` of the
    lobe's largest value (a return to the upright position without crossing it: a bounce on
    the same side); after such a return the next lobe starts once |theta| grows again.  Its
    peak is the largest |theta| in it.  Peaks below ``rel_floor`` of the largest are dropped
    (the rattle at rest), and so is a last lobe that never turned back.  theta in rad, t in s."""
    t = np.asarray(t, dtype=float)
    th = np.asarray(theta, dtype=float)
    a = np.abs(th)
    if len(a) == 0:
        return np.zeros(0), np.zeros(0)
    floor = rel_floor * a.max()
    peaks = []
    i_best, best, waiting, sign = None, 0.0, False, 0

    def close():
        if i_best is not None and best > floor:
            peaks.append(i_best)

    for i in range(len(a)):
        s = int(np.sign(th[i]))
        if s != 0 and sign != 0 and s != sign:          # crossed the upright position
            close()
            i_best, best, waiting = i, a[i], False
        elif waiting:
            if i > 0 and a[i] > a[i - 1]:               # rising again: a new lobe
                i_best, best, waiting = i, a[i], False
        else:
            if i_best is None or a[i] > best:
                i_best, best = i, a[i]
            elif a[i] < return_frac * best:             # came back without crossing
                close()
                i_best, best, waiting = None, 0.0, True
        if s != 0:
            sign = s
    if i_best is not None and not waiting and a[-1] < 0.9 * best and i_best not in peaks:
        close()
    idx = np.array(peaks, dtype=int)
    return t[idx], th[idx]


def impact_ratios(peaks, pivot_pos: tuple[float, float], pivot_neg: tuple[float, float] | None = None
                  ) -> dict:
    """Per-impact ratios from successive half-cycle peaks (rad, signed).

    ``pivot_pos`` = (c, z) of the centre of mass seen from the pivot of the theta > 0 lobes (m),
    ``pivot_neg`` the same for theta < 0 (default: the same).  Returns lists ``amplitude_ratio``
    (A_{k+1} / A_k), ``energy_ratio`` (E(A_{k+1}) / E(A_k)) and ``r_eq`` (its square root), and
    their means; ``r_eq_same_side``: (E(A_{k+2}) / E(A_k))^(1/4) for peaks two impacts apart on
    the same side (one pivot only: the mean r of the two impacts between them)."""
    pivot_neg = pivot_pos if pivot_neg is None else pivot_neg
    peaks = np.asarray(peaks, dtype=float)
    amp, ene = [], []
    for p0, p1 in zip(peaks[:-1], peaks[1:]):
        c0, z0 = pivot_pos if p0 > 0 else pivot_neg
        c1, z1 = pivot_pos if p1 > 0 else pivot_neg
        amp.append(abs(p1) / abs(p0))
        ene.append(float(rocking_energy(p1, c1, z1) / rocking_energy(p0, c0, z0)))
    # two impacts apart, the same side and pivot: independent of the other pivot's geometry
    same = []
    for p0, p2 in zip(peaks[:-2], peaks[2:]):
        if np.sign(p0) == np.sign(p2):
            c0, z0 = pivot_pos if p0 > 0 else pivot_neg
            same.append(float((rocking_energy(p2, c0, z0) / rocking_energy(p0, c0, z0)) ** 0.25))
    amp, ene, same = np.array(amp), np.array(ene), np.array(same)
    r = np.sqrt(ene)
    mean = lambda x: float(np.mean(x)) if len(x) else None  # noqa: E731
    return {"peaks_rad": peaks.tolist(), "amplitude_ratio": amp.tolist(),
            "energy_ratio": ene.tolist(), "r_eq": r.tolist(), "r_eq_same_side": same.tolist(),
            "mean_amplitude_ratio": mean(amp), "mean_energy_ratio": mean(ene),
            "mean_r_eq": mean(r), "mean_r_eq_same_side": mean(same)}


def omega_ratios(theta, omega, c: float, z: float, i_o_over_m: float, d: float,
                 g: float = G) -> list[float]:
    """omega+ / omega- at every sign change of theta (a single uniform block, pivots symmetric):
    omega read where |theta| = d (rad) just before and just after, carried to theta = 0 with
    omega(0)^2 = omega(d)^2 + 2 E(d) / I_O (E per kg with (c, z), I_O / M = ``i_o_over_m``, m2)."""
    th = np.asarray(theta, dtype=float)
    w = np.asarray(omega, dtype=float)
    lift = 2.0 * float(rocking_energy(d, c, z, 1.0, g)) / i_o_over_m
    out = []
    for k in np.flatnonzero(np.sign(th[:-1]) * np.sign(th[1:]) < 0):
        s = np.sign(th[k])
        # last sample before the crossing with |theta| >= d, first after with |theta| >= d
        j0 = k
        while j0 > 0 and abs(th[j0]) < d:
            j0 -= 1
        j1 = k + 1
        while j1 < len(th) - 1 and abs(th[j1]) < d:
            j1 += 1
        if abs(th[j0]) < d or abs(th[j1]) < d or np.sign(th[j1]) == s:
            continue
        wb = np.interp(d, [abs(th[j0 + 1]), abs(th[j0])], [w[j0 + 1], w[j0]])
        wa = np.interp(d, [abs(th[j1 - 1]), abs(th[j1])], [w[j1 - 1], w[j1]])
        out.append(float(math.sqrt(wa * wa + lift) / math.sqrt(wb * wb + lift)))
    return out


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


# ------------------------------------------------------------------------------------------
# two-body model
# ------------------------------------------------------------------------------------------
def two_body_params(masses="table-5.1", top_load=0.0, top_friction=0.0, top_contact="sliding"):
    from dem.rocking.params import RockingParams

    m1, m2 = (6.05, 9.41) if masses == "table-5.1" else masses
    return RockingParams(thickness=0.05, h1=0.14, m1=m1, h2=0.14, m2=m2, top_load=top_load,
                         top_friction=top_friction, top_contact=top_contact)


def two_body_free(P, initial, restitution="housner", duration: float = 1.5,
                  measure: str = "whole") -> dict:
    """Free motion of the two-body model from ``initial`` = (theta1, theta2, omega1, omega2)
    (absolute; rad, rad/s), no table motion, its own impact map.  ``measure = "whole"``: the
    half cycles of theta_eq = d / (H1 + H2), d = H1 sin theta1 + H2 sin theta2, energies with the
    locked pair's (c, z) = (T/2, z_G); ``"upper"``: those of theta2 with Part 2's (T/2, H2/2)."""
    from dem.rocking.analysis import centre_of_mass_height, housner_restitution
    from dem.rocking.integrate import Settings, integrate_rocking
    from dem.table_motion import TableMotion

    res = integrate_rocking(P, TableMotion(), Settings(duration=duration, output_interval=2e-4,
                                                       restitution=restitution), tuple(initial))
    if measure == "upper":
        th = np.asarray(res.theta2)
        cz = (P.thickness / 2, P.h2 / 2)
    else:
        th = (P.h1 * np.sin(res.theta1) + P.h2 * np.sin(res.theta2)) / P.height
        cz = (P.thickness / 2, centre_of_mass_height(P))
    tp, pk = half_cycle_peaks(res.t, th)
    out = impact_ratios(pk, cz)
    out.update({"restitution": restitution, "housner_restitution_locked": housner_restitution(P),
                "housner_r_part2": housner_r_block(P.thickness, P.h2),
                "m1_kg": P.m1, "m2_kg": P.m2, "initial": list(initial), "measure": measure,
                "status": res.status, "impacts_base": res.stats["impacts_base"],
                "impacts_interface": res.stats["impacts_interface"],
                "_t": np.asarray(res.t), "_theta": th})
    return out


def two_body_forced(P, f: float, peak_acc: float, restitution="housner", cycles: float = 20,
                    margin: float = 1.0) -> dict:
    """Model II y in the two-body model under a sine of peak acceleration ``peak_acc`` (m/s2) at
    f (Hz) for ``cycles`` cycles + ``margin`` s: status, uplift, steady amplitude of the top
    displacement d (mean of the per-cycle max / min over the last half of the cycles, m) and its
    amplification (P - N) / (2 A), A the table's displacement amplitude."""
    from dem.rocking.analysis import cycle_amplitudes
    from dem.rocking.integrate import Settings, RockingError, integrate_rocking
    from dem.table_motion import SineMotion

    w = 2 * math.pi * f
    A = peak_acc / (w * w)
    exc = SineMotion(A, f, cycles)
    dur = cycles / f + margin
    t0 = time.process_time()
    try:
        res = integrate_rocking(P, exc, Settings(duration=dur, output_interval=1e-3,
                                                 restitution=restitution), (0, 0, 0, 0))
    except RockingError as err:
        res = err.partial
    cpu = time.process_time() - t0
    d = P.h1 * np.sin(res.theta1) + P.h2 * np.sin(res.theta2)
    moved = bool(np.any(np.abs(d) > 1e-9))
    uplift = next((e["t"] for e in res.events if e["kind"].startswith("leave")), None)
    out = {"f_hz": f, "peak_acc_m_s2": peak_acc, "amplitude_m": A, "restitution": restitution,
           "status": res.status, "t_end_s": float(res.t[-1]) if len(res.t) else 0.0,
           "uplift_s": uplift, "max_abs_d_m": float(np.abs(d).max()) if len(d) else 0.0,
           "impacts": int(res.stats["impacts_base"] + res.stats["impacts_interface"]),
           "cpu_s": cpu, "steady_P_m": None, "steady_N_m": None, "amplification": None}
    if res.status == "ok":
        period = 1.0 / f
        idx, mx, mn = cycle_amplitudes(res.t, d, period, cycles / f)
        half = idx >= cycles // 2
        if half.any():
            Pm, Nm = float(mx[half].mean()), float(mn[half].mean())
            out.update({"steady_P_m": Pm, "steady_N_m": Nm,
                        "amplification": (Pm - Nm) / (2 * A) if moved else 0.0})
    return out


# ------------------------------------------------------------------------------------------
# the study
# ------------------------------------------------------------------------------------------
def _strip(d):
    if isinstance(d, dict):
        return {k: _strip(v) for k, v in d.items() if not k.startswith("_")}
    if isinstance(d, list):
        return [_strip(v) for v in d]
    if isinstance(d, (np.floating, np.integer)):
        d = d.item()
    if isinstance(d, float) and math.isfinite(d) and d != 0.0:
        return float(f"{d:.6g}")
    return d


def compact_json(obj, indent: int = 0) -> str:
    """JSON with every list of scalars and every dict of scalars on one line (the summary stays
    readable and small)."""
    flat = lambda o: all(not isinstance(v, (dict, list)) for v in  # noqa: E731
                         (o.values() if isinstance(o, dict) else o))
    pad, pad1 = " " * indent, " " * (indent + 1)
    if isinstance(obj, (dict, list)) and (flat(obj) or not obj):
        return json.dumps(obj)
    if isinstance(obj, dict):
        items = [f"{pad1}{json.dumps(k)}: {compact_json(v, indent + 1)}" for k, v in obj.items()]
        return "{\n" + ",\n".join(items) + "\n" + pad + "}"
    if isinstance(obj, list):
        items = [pad1 + compact_json(v, indent + 1) for v in obj]
        return "[\n" + ",\n".join(items) + "\n" + pad + "]"
    return json.dumps(obj)


def housner_sequence(theta0: float, r: float, c: float, z: float, n: int) -> np.ndarray:
    """Amplitudes (rad) of n half cycles of a rigid block with restitution r released from
    theta0 (symmetric pivots, G at (c, z) from each)."""
    out = [theta0]
    for _ in range(n - 1):
        out.append(amplitude_after_impact(out[-1], r, c, z))
    return np.array(out)


def plot_histories(hist: dict, summary: dict, path: Path) -> None:
    """Figure 1: DEM rotation histories against Housner's peaks (a, b) and the damping
    dependence of the per-impact amplitude ratio (d)."""
    import matplotlib
    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    fig, ax = plt.subplots(2, 2, figsize=(13, 8.5))
    a = ax[0, 0]
    for key, lab in (("a:excited-portion-block", "block b/h = 50/280"),
                     ("a:two-block-stack", "two-block stack (0.02 rad)")):
        if key in hist:
            h = hist[key]
            a.plot(h["_t"], np.degrees(h["_theta"]), lw=1, label=f"DEM {lab}")
            pk = np.abs(np.asarray(h["peaks_rad"]))
            if key == "a:excited-portion-block":
                hs = housner_sequence(h["theta0_rad"], h["housner_r"], h["b_m"] / 2, h["h_m"] / 2,
                                      len(pk))
            else:
                P = two_body_params("table-5.1")
                from dem.rocking.analysis import centre_of_mass_height
                hs = housner_sequence(h["theta0_rad"], h["housner_r"], 0.025,
                                      centre_of_mass_height(P), len(pk))
            a.plot(h["t_peaks_s"], np.degrees(hs) * np.sign(h["peaks_rad"]), "kx", ms=5)
    a.plot([], [], "kx", label="Housner's amplitudes (same release)")
    a.set(xlabel="t (s)", ylabel="rotation (deg)", title="(a) single bodies, default material")
    a.legend(fontsize=8)
    a.grid(alpha=0.3)
    b = ax[0, 1]
    for key, lab in (("b:upper-tilt", "upper part, side walls"),
                     ("b:upper-tilt-no-side-walls", "upper part, no side walls"),
                     ("b:portion-kick", "whole portion, kicked")):
        if key in hist:
            b.plot(hist[key]["_t"], np.degrees(hist[key]["_theta"]), lw=1, label=lab)
    if "b:upper-tilt-no-side-walls" in hist:
        h = hist["b:upper-tilt-no-side-walls"]
        c, z = h["pivot_outer_cz_m"]
        hs = housner_sequence(h["theta0_rad"], h["housner_r_outer_to_inner"], c, z, 8)
        tp = np.asarray(h["t_peaks_s"])[:8]
        b.plot(tp, np.degrees(hs[:len(tp)]) * np.sign(h["peaks_rad"][:len(tp)]), "kx",
               label="Housner, no side walls")
    b.set(xlabel="t (s)", ylabel="mean rotation about x (deg, + outwards)",
          title="(b) Model II y excited portion (DEM, rest of the box fixed, no roof)")
    b.legend(fontsize=8)
    b.grid(alpha=0.3)
    d = ax[1, 0]
    dd = summary.get("d_damping")
    if dd:
        zs = dd["zetas"]
        d.plot(zs, [1 - dd["block"][str(z)]["mean_amplitude_ratio"] for z in zs], "o-",
               label="block b/h = 50/280, released at alpha/2")
        d.plot(zs, [1 - dd["stack"][str(z)]["mean_amplitude_ratio"] for z in zs], "s-",
               label="two-block stack, 0.02 rad")
        blk = dd["block"]["0.5"]
        d.axhline(1 - blk["housner_first_amplitude_ratio"], color="C0", ls=":",
                  label="Housner, block at alpha/2")
        d.axhline(1 - dd["stack"]["0.5"]["housner_first_amplitude_ratio"], color="C1", ls=":",
                  label="Housner, stack at 0.02 rad")
        d.axvline(0.5, color="k", lw=0.8, ls="--")
    d.set(xlabel="contact damping ratio zeta", ylabel="amplitude lost per impact",
          title="(d) dependence on the damping ratio (default 0.5)")
    d.legend(fontsize=8)
    d.grid(alpha=0.3)
    e = ax[1, 1]
    c_ = summary.get("c_two_body")
    if c_:
        for k, (sc, ls) in enumerate((("co-moving-1.98", "-"), ("no-load-1.84", "--"))):
            for j, law in enumerate(c_["laws"]):
                rows = c_["runs"][f"{sc}|{law}"]
                f = [r["f_hz"] for r in rows if r["amplification"] is not None]
                A = [r["amplification"] for r in rows if r["amplification"] is not None]
                fc = [r["f_hz"] for r in rows if r["status"] == "collapsed"]
                lab = f"{sc}, {law} ({c_['laws'][law]})"
                e.plot(f, A, ls=ls, marker="o", color=f"C{j}", ms=3, label=lab)
                e.plot(fc, [0.1 * (k + 1)] * len(fc), "x", color=f"C{j}")
    e.set(xlabel="f (Hz)", ylabel="amplification of d (x: overturned)",
          title="(c) two-body model, Model II y, 20 cycles")
    e.legend(fontsize=7)
    e.grid(alpha=0.3)
    fig.tight_layout()
    fig.savefig(path, dpi=110)
    plt.close(fig)


def markdown_tables(summary: dict) -> str:
    """The README's tables from summary.json (printed by ``--tables``)."""
    f3 = lambda x: "-" if x is None else f"{x:.3f}"  # noqa: E731
    lst = lambda xs, n=6: ", ".join(f"{x:.3f}" for x in xs[:n]) or "-"  # noqa: E731
    out = []
    a = summary.get("a_blocks", {})
    if a:
        out += ["| body | b/h | release (rad) | Housner r | Housner A1/A0 | DEM A_{k+1}/A_k | DEM r_eq "
                "(mean) | DEM omega+/omega- (mean) | CPU (s) |", "|---|---|---|---|---|---|---|---|---|"]
        for k, v in a.items():
            bh = v.get("b_over_h", 0.05 / 0.28)
            out.append(f"| {k} | {bh:.3f} | {v['theta0_rad']:.4f} | {f3(v['housner_r'])} | "
                       f"{f3(v['housner_first_amplitude_ratio'])} | {lst(v['amplitude_ratio'])} | "
                       f"{f3(v['mean_r_eq'])} | {f3(v.get('mean_omega_ratio'))} | {v['cpu_s']:.1f} |")
        out.append("")
    b = summary.get("b_portion", {})
    if b:
        out += ["| DEM run | bricks, mass (kg) | c_out, z (mm) | release | Housner r, facade edges "
                "(out-in, in-out; mean) | Housner r, far edge of the seat (width mm) | "
                "DEM peaks (rad) | DEM A_{k+1}/A_k | DEM r (same side, mean) | max rotation "
                "upper / lower (rad) | CPU (s) |",
                "|---|---|---|---|---|---|---|---|---|---|---|"]
        for k, v in b.items():
            if k == "two_body_free":
                continue
            rel = (f"tilt {v['theta0_rad']:.3f} rad" if v["start"] == "tilt"
                   else f"kick {v['omega0_rad_s']:.3f} rad/s (to {v['theta0_rad']:.3f} rad)")
            c, z = v["pivot_outer_cz_m"]
            lo = v["max_rotation_lower_rad"]
            out.append(f"| {k} | {v['n_bricks']}, {v['mass_kg']:.2f} | {1e3 * c:.1f}, {1e3 * z:.1f} | "
                       f"{rel} | {f3(v['housner_r_outer_to_inner'])}, "
                       f"{f3(v['housner_r_inner_to_outer'])}; {f3(v['housner_r_facade_edges_mean'])} | "
                       f"{f3(v['housner_r_far_edge'])} ({1e3 * v['seat_width_far_m']:.0f}) | "
                       f"{lst(v['peaks_rad'])} | "
                       f"{lst(v['amplitude_ratio'])} | {f3(v['mean_r_eq_same_side'])} | "
                       f"{v['max_rotation_upper_rad']:.3f} / {'-' if lo is None else f'{lo:.4f}'} | "
                       f"{v['cpu_s']:.1f} |")
        out.append("")
        tb = b.get("two_body_free", {})
        if tb:
            out += ["| two-body model (dem.rocking, plastic impacts) | start | locked-pair r | "
                    "peaks (rad) | A_{k+1}/A_k | r_eq |", "|---|---|---|---|---|---|"]
            for k, v in tb.items():
                out.append(f"| {k.replace('|', ', ')} | {v['initial']} | {f3(v['housner_restitution_locked'])} | "
                           f"{lst(v['peaks_rad'])} | {lst(v['amplitude_ratio'])} | {lst(v['r_eq'])} |")
            out.append("")
    c = summary.get("c_two_body", {})
    if c:
        laws = c["laws"]
        out += ["| scenario (peak m/s2) | " + " | ".join(f"{k} (e = {v})" for k, v in laws.items()) + " |",
                "|---|" + "---|" * len(laws)]
        scen = sorted({k.split("|")[0] for k in c["runs"]}, key=lambda s: list(c["runs"]).index(s + "|housner"))
        for sc in scen:
            if all(r["max_abs_d_m"] == 0.0 for law in laws for r in c["runs"][f"{sc}|{law}"]):
                fs = c["frequencies_hz"]
                out.append(f"| {sc} {fs[0]:.1f}-{fs[-1]:.1f} Hz | " + " | ".join(["rest"] * len(laws))
                           + " |")
                continue
            for i, f in enumerate(c["frequencies_hz"]):
                cells = []
                for law in laws:
                    r = c["runs"][f"{sc}|{law}"][i]
                    if r["status"] == "collapsed":
                        cells.append(f"overturns {r['t_end_s']:.2f} s")
                    elif r["max_abs_d_m"] == 0.0:
                        cells.append("rest")
                    else:
                        cells.append(f"A = {r['amplification']:.2f} ({1e3 * r['steady_P_m']:+.1f} / "
                                     f"{1e3 * r['steady_N_m']:+.1f} mm)")
                out.append(f"| {sc} {f:.1f} Hz | " + " | ".join(cells) + " |")
        out.append("")
    d = summary.get("d_damping", {})
    if d:
        out += ["| zeta | point restitution e_n | block b/h = 50/280: A_{k+1}/A_k (mean), r_eq | "
                "two-block stack: A_{k+1}/A_k (mean), r_eq | upper part, side walls: peaks | "
                "upper part, no side walls: A_{k+1}/A_k |", "|---|---|---|---|---|---|"]
        b50 = summary.get("b_portion", {})
        for z in d["zetas"]:
            k = str(z)
            bl, st = d["block"][k], d["stack"][k]
            up = d["upper"].get(k) or (b50.get("upper-tilt") if k == "0.5" else None)
            un = d["upper-no-side-walls"].get(k) or (
                b50.get("upper-tilt-no-side-walls") if k == "0.5" else None)
            out.append(f"| {z} | {d['point_restitution'][k]:.3f} | {bl['mean_amplitude_ratio']:.4f}, "
                       f"{bl['mean_r_eq']:.4f} | {st['mean_amplitude_ratio']:.4f}, {st['mean_r_eq']:.4f} | "
                       f"{lst(up['peaks_rad'], 4) if up else '-'} | "
                       f"{lst(un['amplitude_ratio'], 6) if un else '-'} |")
        blk, stk = d["block"]["0.5"], d["stack"]["0.5"]
        out.append(f"| Housner | - | {blk['housner_first_amplitude_ratio']:.4f}, {blk['housner_r']:.4f} | "
                   f"{stk['housner_first_amplitude_ratio']:.4f}, {stk['housner_r']:.4f} | - | - |")
        out.append("")
    cpu = summary.get("cpu_s", {})
    if cpu:
        out += ["| part | CPU (s) |", "|---|---|"] + [f"| {k} | {v:.1f} |" for k, v in cpu.items()]
    return "\n".join(out)


def main(argv=None):
    ap = argparse.ArgumentParser(description=__doc__.split("\n")[0])
    ap.add_argument("--out", default="results/prediction/impact-dissipation")
    ap.add_argument("--parts", default="abcd", help="which parts to run (a, b, c, d)")
    ap.add_argument("--portion-duration", type=float, default=1.2)
    ap.add_argument("--tables", action="store_true",
                    help="print the README's tables from OUT/summary.json and stop")
    args = ap.parse_args(argv)
    if args.tables:
        print(markdown_tables(json.loads((Path(args.out) / "summary.json").read_text())))
        return None
    os.environ.setdefault("DEM_THREADS", "1")
    root = Path(__file__).resolve().parents[2]
    out = Path(args.out)
    out.mkdir(parents=True, exist_ok=True)
    summary_path = out / "summary.json"
    summary = json.loads(summary_path.read_text()) if summary_path.exists() else {}
    hist = {}
    cpu = summary.setdefault("cpu_s", {})

    if "a" in args.parts:
        t0 = time.process_time()
        L, W, H = BRICK
        blocks = {
            "brick-on-end-35": (H, W, L, 0.5, 0.6),      # b = 35, h = 105 mm (b/h = 1/3)
            "brick-on-end-50": (W, H, L, 0.5, 0.6),      # b = 50, h = 105 mm
            "excited-portion-block": (0.05, 0.30, 0.28, 0.5, 2.5),   # b/h = 50 / 280
        }
        res = {}
        for name, (b, depth, h, frac, dur) in blocks.items():
            r = run_block(b, h, depth, frac=frac, duration=dur)
            hist["a:" + name] = r
            res[name] = _strip(r)
            print(f"a {name}: b/h {b/h:.3f} Housner r {r['housner_r']:.4f} amp {r['housner_first_amplitude_ratio']:.4f}"
                  f" | DEM amp {r['mean_amplitude_ratio']} r_eq {r['mean_r_eq']} omega {r['mean_omega_ratio']}"
                  f" cpu {r['cpu_s']:.1f}", flush=True)
        for name, kw in (("two-block-stack", {}), ("two-block-stack-friction-2", {"friction": 2.0})):
            r = run_stack(**kw)
            hist["a:" + name] = r
            res[name] = _strip(r)
            print(f"a {name}: Housner r {r['housner_r']:.4f} amp {r['housner_first_amplitude_ratio']:.4f}"
                  f" | DEM amp {np.round(r['amplitude_ratio'], 4)} r_eq {r['mean_r_eq']}"
                  f" cpu {r['cpu_s']:.1f}", flush=True)
        summary["a_blocks"] = res
        cpu["a"] = time.process_time() - t0

    if "b" in args.parts:
        t0 = time.process_time()
        res = {}
        variants = {
            "upper-tilt": dict(free="upper", start="tilt"),
            "upper-tilt-no-side-walls": dict(free="upper", start="tilt", side_walls=False),
            "upper-tilt-quarter": dict(free="upper", start="tilt", frac=0.25),
            "portion-kick": dict(free="portion", start="kick"),
        }
        for name, kw in variants.items():
            r = run_portion(root, duration=args.portion_duration, **kw)
            hist["b:" + name] = r
            res[name] = _strip(r)
            print(f"b {name}: Housner r {r['housner_r_outer_to_inner']:.4f} | DEM peaks "
                  f"{np.round(r['peaks_rad'], 4)} amp {np.round(r['amplitude_ratio'], 3)} "
                  f"r_eq {np.round(r['r_eq'], 3)} same-side {np.round(r['r_eq_same_side'], 3)} up/lo {r['max_rotation_upper_rad']:.4f} / "
                  f"{r['max_rotation_lower_rad']} cpu {r['cpu_s']:.1f}", flush=True)
        # the two-body model's own impact map on the same bodies: the DEM's masses (upper 10.08
        # kg, lower 4.368 kg, H1 = H2 = 140 mm) and Table 5.1's; the upper part tilted alone
        # (Pattern 4 start, as "upper-tilt") and the pair kicked from upright (as "portion-kick")
        tb = {}
        up, pk_ = res["upper-tilt"], res["portion-kick"]
        for label, masses in (("dem-masses", (4.368, 10.08)), ("table-5.1", "table-5.1")):
            P = two_body_params(masses)
            for kind, init, meas in (
                    ("upper-tilt", (0.0, up["theta0_rad"], 0.0, 0.0), "upper"),
                    ("portion-kick", (0.0, 0.0, -pk_["omega0_rad_s"], -pk_["omega0_rad_s"]),
                     "whole")):
                r = two_body_free(P, init, measure=meas)
                hist[f"b:two-body:{label}:{kind}"] = r
                tb[f"{label}|{kind}"] = _strip(r)
                print(f"b two-body {label} {kind}: peaks {np.round(r['peaks_rad'], 4)} amp "
                      f"{np.round(r['amplitude_ratio'], 3)} r_eq {np.round(r['r_eq'], 3)}",
                      flush=True)
        res["two_body_free"] = tb
        summary["b_portion"] = res
        cpu["b"] = time.process_time() - t0

    if "c" in args.parts:
        t0 = time.process_time()
        # the DEM's measured restitutions: a monolithic block of the portion's b/h (part a) and
        # the brick-built upper part in its seat, with and without the side walls (part b)
        laws = {"housner": "housner",
                "dem-block": round(summary["a_blocks"]["excited-portion-block"]["mean_r_eq"], 3),
                "dem-upper-no-side-walls": round(
                    summary["b_portion"]["upper-tilt-no-side-walls"]["mean_r_eq"], 3),
                "dem-upper-side-walls": round(
                    summary["b_portion"]["upper-tilt"]["mean_r_eq_same_side"], 3)}
        freqs = [2.0, 2.2, 2.4, 2.6, 2.8, 3.0, 3.2, 3.4, 3.6, 3.8, 4.0]
        scenarios = {
            "thesis-sliding-1.53": (two_body_params("table-5.1", 58.8, 0.81, "sliding"), 1.53),
            "co-moving-1.53": (two_body_params("table-5.1", 58.8, 0.81, "co-moving"), 1.53),
            "co-moving-1.98": (two_body_params("table-5.1", 58.8, 0.81, "co-moving"), 1.98),
            "no-load-1.84": (two_body_params("table-5.1"), 1.84),
            "co-moving-4.0": (two_body_params("table-5.1", 58.8, 0.81, "co-moving"), 4.0),
        }
        res = {"laws": laws, "frequencies_hz": freqs, "cycles": 20, "runs": {}}
        for sname, (P, acc) in scenarios.items():
            for lname, law in laws.items():
                rows = [two_body_forced(P, f, acc, law, cycles=20) for f in freqs]
                res["runs"][f"{sname}|{lname}"] = rows
                print(sname, lname, [(r['f_hz'], r['status'], r['amplification'] and round(r['amplification'], 2)) for r in rows], flush=True)
        summary["c_two_body"] = res
        cpu["c"] = time.process_time() - t0

    if "d" in args.parts:
        t0 = time.process_time()
        res = {"zetas": [0.1, 0.3, 0.5, 0.7, 0.9], "block": {}, "stack": {}, "upper": {},
               "upper-no-side-walls": {}, "point_restitution": {}}
        for z in res["zetas"]:
            # normal restitution of a point contact with damping ratio z (docs/engine.md)
            res["point_restitution"][str(z)] = math.exp(-math.pi * z / math.sqrt(1 - z * z))
            r = run_block(0.05, 0.28, 0.30, 0.5, damping=z, duration=1.6)
            hist[f"d:block:{z}"] = r
            res["block"][str(z)] = _strip(r)
            r2 = run_stack(damping=z)
            hist[f"d:stack:{z}"] = r2
            res["stack"][str(z)] = _strip(r2)
            print(f"d zeta {z}: block amp {r['mean_amplitude_ratio']:.4f} r_eq {r['mean_r_eq']:.4f}"
                  f" | stack amp {r2['mean_amplitude_ratio']:.4f} r_eq {r2['mean_r_eq']:.4f}",
                  flush=True)
        for z in (0.1, 0.9):
            for key, sw in (("upper", True), ("upper-no-side-walls", False)):
                r = run_portion(root, "upper", "tilt", side_walls=sw, damping=z,
                                duration=args.portion_duration)
                hist[f"d:{key}:{z}"] = r
                res[key][str(z)] = _strip(r)
                print(f"d {key} zeta {z}: peaks {np.round(r['peaks_rad'], 4)} amp "
                      f"{np.round(r['amplitude_ratio'], 3)} same-side "
                      f"{np.round(r['r_eq_same_side'], 3)}", flush=True)
        summary["d_damping"] = res
        cpu["d"] = time.process_time() - t0

    summary_path.write_text(compact_json(_strip(summary)) + "\n")
    if set("abcd") <= set(args.parts):
        plot_histories(hist, summary, out / "impact-dissipation.png")
    np.savez_compressed("/tmp/impact_dissipation_histories.npz",
                        **{k + "|t": v["_t"] for k, v in hist.items()},
                        **{k + "|theta": v["_theta"] for k, v in hist.items()})
    return summary


if __name__ == "__main__":
    main()
