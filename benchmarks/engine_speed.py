"""Engine throughput on the resting 9 x 15 stretcher-bond wall, and how it scales.

    python benchmarks/engine_speed.py            # full table (a few minutes)
    python benchmarks/engine_speed.py --quick    # threads/modes on the 142-block wall only
    python benchmarks/engine_speed.py --stages   # cost of each stage on the 142-block wall
    python benchmarks/engine_speed.py --stages --imperfections 1e-4 --face-shape planar bilinear
    python benchmarks/engine_speed.py --stages --case CASE.yaml --imperfections 1e-4 --load-time 1
    python benchmarks/engine_speed.py --launch   # cost of a kernel launch, and of a parallel loop
    python benchmarks/engine_speed.py --scaling --threads 1 2   # serial vs parallel by size

Prints, for 1 and 2 threads and both kernels (serial multi-step, parallel per step):
brick-steps per second (median of --repeats runs of --steps steps, after a warm-up) by the wall
clock and per CPU-second of the process (the second is what to compare on a shared machine:
other jobs stretch the wall clock, not the CPU time; for the serial kernel both are the same on
an idle machine), contact pairs and points; the kernel compile time cold (empty offline cache)
and warm (cache filled); and, for walls of ~142 / 300 / 500 / 800 / 1600 / 3200 bricks
(SCALING), throughput of both kernels (where the parallel one starts to win:
PARALLEL_MIN_BODIES) and the bytes held by the engine's arrays (memory proportional to the
number of blocks).  Every figure comes from a fresh process so the thread count and the cache
state are what they say.

--stages times the stages alone on the wall after 500 steps (one thread, CPU time, each stage
function called in a serialized loop over all pairs or bodies, --repeats x 20 runs, median and
minimum): the separating-axis test with the axis choice, the whole narrow phase (box_contact),
the contact stage (narrow phase + joint law + shear history) per pair, the integrate stage per
body, and the whole serial step; the contact stage and the step without patch reuse
(solver.patch_reuse = 0) and with 1e-7 m (dem.engine.coherence).

--stages --imperfections BED_M [--face-shape planar bilinear] [--seed S] [--case CASE.yaml]
[--load-time T] does the same for the perfect scene and, in the same process, the scene with
``imperfections: {bed_unevenness: BED_M, face_shape: ..., seed: S}`` (each built from its case by
dem.run.build.build: the 9 x 15 wall of ``WALL_CASE``, or CASE.yaml's scene, material and
loading; solver on one thread, serial kernel), the imperfect ones settled as the run loop does
(dem.run.settle), then T s under the case's loading (default: 500 steps).  All stages of all
scenes are timed interleaved (median of --repeats x 20 runs, CPU time), so the ratios
warped / perfect come from one run on one machine state; the contact and integrate stages run
on copies of the snapshot put back before every timed run.  Besides the stages above: the
face frame + incident face + four rectangle clips alone (what the overlap reuse keeps:
dem.engine.coherence).  (The comparisons with frozen copies of older engine code, the planar
patch before geometry.planar_gap and its gap evaluation, are gone: git keeps them.)  A census
kernel (``census``, on the engine's geometry.face_contact up to its gap clip) counts touching
pairs, points, the face pairs that are whole (no vertex of the overlap polygon with gap <= 0:
the last clip cuts nothing, as flat_patch's ``whole``), planar / twisted pairs and the largest
difference between the gap and its affine form; ``_critical_step`` says which block and which
mode set dt_crit (dem.engine.timestep's bound split into its terms), and
``_rotating`` how many of the free rotation's five factors call sin / cos.
"""

import argparse
import json
import os
import subprocess
import sys
import tempfile
import time

# ~bricks: (length, courses)
WALLS = {50: (5, 10), 200: (10, 19), 800: (20, 38), 1600: (28, 57), 3200: (40, 76)}
SCALING = {142: (9, 15), 300: (14, 22), 500: (18, 28), 800: (20, 38), 1600: (28, 57),
           3200: (40, 76)}


def _measure(length, courses, mode, steps, repeats, patch_reuse=None):
    """Runs inside the child process."""
    t0 = time.perf_counter()
    import numpy as np

    from dem.builders import build_wall
    from dem.case import Material, SolverSpec
    from dem.run.build import joint_law, step_options
    from dem.engine import Simulation

    scene = build_wall("small", length=length, courses=courses)
    t_import = time.perf_counter() - t0
    sim = Simulation(scene, joint_law(Material(friction=0.81)),
                     step_options(SolverSpec(mode=mode) if patch_reuse is None else
                                  SolverSpec(mode=mode, patch_reuse=patch_reuse)))
    g = np.array([0.0, 0.0, -9.81])
    loads = lambda t: (np.tile(g, (len(t), 1)), np.zeros((len(t), 3)))  # noqa: E731
    sim.advance(min(steps, 500), loads)  # warm-up (settling, caches)
    rates, cpu_rates = [], []
    for _ in range(repeats):
        t1, c1 = time.perf_counter(), time.process_time()
        sim.advance(steps, loads)
        rates.append(steps * sim.n_blocks / (time.perf_counter() - t1))
        cpu_rates.append(steps * sim.n_blocks / (time.process_time() - c1))
    c = sim.contacts
    nbytes = sum(obj.nbytes() for obj in (sim.model, sim.state, c, sim.control))
    return {
        "blocks": sim.n_blocks, "mode": sim.mode, "pairs": c.n_pairs,
        "contact_points": int(c.npts[: c.n_pairs].sum()), "dt": sim.dt,
        "brick_steps_per_s": float(np.median(rates)), "rates": rates,
        "brick_steps_per_cpu_s": float(np.median(cpu_rates)),
        "compile_s": sim.compile_seconds, "import_s": t_import, "array_bytes": int(nbytes),
    }


_KERNELS = None


def _kernels():
    """The timing and diagnostic kernels of --stages, made once per process (after ti.init).

    ``warped`` (compile time) selects the imperfect kernels' code, as
    dem.engine.step.advance_serial(..., warped=True, ...) does; the perfect wall's figures use
    False, as before.
    ``_overlap`` is dem.engine.geometry.face_contact up to the four rectangle clips (the patch
    before the gap clip: what the overlap reuse keeps, dem.engine.coherence), so that the census
    can evaluate the gap at the overlap's vertices; it reads, never writes, the containers."""
    global _KERNELS
    if _KERNELS is not None:
        return _KERNELS
    from types import SimpleNamespace

    import taichi as ti

    from dem.engine import coherence, geometry, step
    from dem.engine.containers import ContactArgs, ControlArgs, ModelArgs, StateArgs
    from dem.engine.mathutil import vec3

    @ti.kernel
    def sat(reps: ti.i32, n_pairs: ti.i32, model: ModelArgs, state: StateArgs,
            contacts: ContactArgs) -> ti.f64:
        acc = 0.0
        ti.loop_config(serialize=True)
        for _ in range(reps):
            for p in range(n_pairs):
                i, j = contacts.pairs[p][0], contacts.pairs[p][1]
                hmin = ti.min(model.half[i].min(), model.half[j].min())
                ov = geometry.sat_overlaps(state.pos[i], state.rot[i], model.half[i],
                                           state.pos[j], state.rot[j], model.half[j])
                axis, smallest = geometry.choose_axis(ov, contacts.code[p], 1e-3 * hmin, 1e-3 * hmin)
                acc += axis + smallest
        return acc

    @ti.kernel
    def narrow(reps: ti.i32, n_pairs: ti.i32, model: ModelArgs, state: StateArgs,
               contacts: ContactArgs, warped: ti.template()) -> ti.f64:
        acc = 0.0
        ti.loop_config(serialize=True)
        for _ in range(reps):
            for p in range(n_pairs):
                i, j = contacts.pairs[p][0], contacts.pairs[p][1]
                hmin = ti.min(model.half[i].min(), model.half[j].min())
                px = geometry.point_buffer()
                py = geometry.point_buffer()
                pz = geometry.point_buffer()
                dep = geometry.point_buffer()
                w = geometry.point_buffer()
                axis, n, n_points, shrink, centroid, _whole = geometry.box_contact(
                    state.pos[i], state.rot[i], model.half[i], state.pos[j], state.rot[j],
                    model.half[j], contacts.code[p], 1e-3 * hmin, hmin * hmin, model, warped,
                    i, j, px, py, pz, dep, w)
                for q in range(n_points):
                    acc += px[q] + py[q] + pz[q] + dep[q] * w[q]
                acc += axis + n[0] + shrink + centroid[2]
        return acc

    @ti.kernel
    def contact(reps: ti.i32, n_pairs: ti.i32, dt: ti.f64, model: ModelArgs, state: StateArgs,
                contacts: ContactArgs, control: ControlArgs, warped: ti.template()):
        ti.loop_config(serialize=True)
        for _ in range(reps):
            for p in range(n_pairs):
                step.contact_stage(p, dt, model, state, contacts, control, warped, False)

    @ti.kernel
    def integrate(reps: ti.i32, n_bodies: ti.i32, dt: ti.f64, model: ModelArgs,
                  state: StateArgs, contacts: ContactArgs, control: ControlArgs):
        ti.loop_config(serialize=True)
        for _ in range(reps):
            for b in range(n_bodies):
                step.integrate_stage(b, 0, dt, model, state, contacts, control, False)

    @ti.func
    def _overlap(p, model: ti.template(), state: ti.template(), contacts: ti.template(),
                 xs: ti.template(), ys: ti.template(), xt: ti.template(), yt: ti.template()):
        """Pair p's face patch before the gap clip, at its stored axis (contacts.code):
        the polygon (xs, ys, npoly; npoly = 0 for no face contact) and what the gap needs, by
        the engine's own functions (the overlap reuse's coherence.warped_faces and
        rectangle_clips)."""
        i, j = contacts.pairs[p][0], contacts.pairs[p][1]
        code = contacts.code[p]
        rb, ib, k, sg, n, u1, u2, c, e1, e2, m, sm, nI, b1, b2, ci, imperfect = \
            coherence.warped_faces(ti.max(code, 0), i, j, model, state)
        npoly = 0
        if code >= 0 and code < 6:
            geometry.incident_corners(c, u1, u2, ci, b1, b2, xs, ys)
            npoly = coherence.rectangle_clips(e1, e2, 4, xs, ys, xt, yt)
        hR = model.half[rb]
        oR = model.face_offset[rb, geometry.face_index(k, sg)]
        oI = model.face_offset[ib, geometry.face_index(m, sm)]
        return (npoly, imperfect, c, n, u1, u2, nI, ci, hR[(k + 1) % 3], hR[(k + 2) % 3],
                state.rot[ib], model.half[ib], m, oR, oI)

    @ti.func
    def _gap(x, y, cc, u1, u2, inv1, inv2, oR, d1, d2, invI1, invI2, oI, d0, gx, gy):
        """The warped gap d(x, y) as geometry.warped_patch evaluates it (m)."""
        r = cc + x * u1 + y * u2
        return d0 + gx * x + gy * y + geometry.bilinear(oR, x * inv1, y * inv2) \
            + geometry.bilinear(oI, r.dot(d1) * invI1, r.dot(d2) * invI2)

    @ti.func
    def _gap_frame(RI, hI, m, hR1, hR2, c, ci):
        m1 = (m + 1) % 3
        m2 = (m + 2) % 3
        d1 = vec3(RI[0, m1], RI[1, m1], RI[2, m1])
        d2 = vec3(RI[0, m2], RI[1, m2], RI[2, m2])
        return d1, d2, 1.0 / hR1, 1.0 / hR2, 1.0 / hI[m1], 1.0 / hI[m2], c - ci

    @ti.kernel
    def census(n_pairs: ti.i32, model: ModelArgs, state: StateArgs, contacts: ContactArgs,
               out: ti.types.ndarray(ndim=2)):
        """Per pair: code, imperfect pair, twisted pair, vertices of the overlap polygon,
        vertices with d <= 0 (the gap clip cuts them: not whole), points of the last step,
        |n_z| of the normal, and for planar warped pairs the largest difference (m) at the
        overlap's vertices between the gap and its affine form (geometry.planar_gap)."""
        ti.loop_config(serialize=True)
        for p in range(n_pairs):
            xs = geometry.point_buffer()
            ys = geometry.point_buffer()
            xt = geometry.point_buffer()
            yt = geometry.point_buffer()
            npoly, imp_pair, c, n, u1, u2, nI, ci, hR1, hR2, RI, hI, m, oR, oI = _overlap(
                p, model, state, contacts, xs, ys, xt, yt)
            d0, gx, gy = geometry.affine_gap(c, u1, u2, n, nI, ci)
            twisted = 0
            n_open = 0
            fit_err = 0.0
            if npoly > 0:
                if imp_pair > 0:
                    tw = ti.abs(0.25 * (oR[0] - oR[1] - oR[2] + oR[3])) + ti.abs(
                        0.25 * (oI[0] - oI[1] - oI[2] + oI[3]))
                    if tw > geometry.TWIST_FLOOR:
                        twisted = 1
                    d1, d2, inv1, inv2, invI1, invI2, cc = _gap_frame(RI, hI, m, hR1, hR2, c, ci)
                    a, bx, by = geometry.planar_gap(cc, u1, u2, inv1, inv2, oR, d1, d2, invI1,
                                                        invI2, oI, d0, gx, gy)
                    for q in range(npoly):
                        d = _gap(xs[q], ys[q], cc, u1, u2, inv1, inv2, oR, d1, d2, invI1, invI2,
                                 oI, d0, gx, gy)
                        if d <= 0.0:
                            n_open += 1
                        if twisted == 0:
                            fit_err = ti.max(fit_err, ti.abs(a + bx * xs[q] + by * ys[q] - d))
                else:
                    for q in range(npoly):
                        if d0 + gx * xs[q] + gy * ys[q] <= 0.0:
                            n_open += 1
            out[p, 0] = contacts.code[p]
            out[p, 1] = imp_pair
            out[p, 2] = twisted
            out[p, 3] = npoly
            out[p, 4] = n_open
            out[p, 5] = contacts.npts[p]
            out[p, 6] = ti.abs(contacts.normal[p][2])
            out[p, 7] = fit_err

    @ti.kernel
    def overlap(reps: ti.i32, n_pairs: ti.i32, model: ModelArgs, state: StateArgs,
                contacts: ContactArgs) -> ti.f64:
        """The face frame, incident face and four rectangle clips of every face pair."""
        acc = 0.0
        ti.loop_config(serialize=True)
        for _ in range(reps):
            for p in range(n_pairs):
                xs = geometry.point_buffer()
                ys = geometry.point_buffer()
                xt = geometry.point_buffer()
                yt = geometry.point_buffer()
                npoly, imp_pair, c, n, u1, u2, nI, ci, hR1, hR2, RI, hI, m, oR, oI = _overlap(
                    p, model, state, contacts, xs, ys, xt, yt)
                acc += npoly + xs[0] + ys[1] + ci[2] + oR[0] + oI[0]
        return acc

    _KERNELS = SimpleNamespace(sat=sat, narrow=narrow, contact=contact, integrate=integrate,
                               census=census, overlap=overlap)
    return _KERNELS


def _stages(repeats, patch_reuse=1e-7):
    """Runs inside the child process: per-stage cost (see the module docstring)."""
    import copy

    import numpy as np

    from dem.builders import build_wall
    from dem.case import Material, SolverSpec
    from dem.run.build import joint_law, step_options
    from dem.engine import Simulation

    sim = Simulation(build_wall("small", length=9, courses=15),
                     joint_law(Material(friction=0.81)),
                     step_options(SolverSpec(mode="serial", patch_reuse=0.0)))
    g = np.array([0.0, 0.0, -9.81])
    loads = lambda t: (np.tile(g, (len(t), 1)), np.zeros((len(t), 3)))  # noqa: E731
    sim.advance(500, loads)

    k = _kernels()
    sat, narrow, contact, integrate = k.sat, k.narrow, k.contact, k.integrate

    from dem.engine.containers import Control
    m, c = sim.model, copy.deepcopy(sim.contacts)
    st = copy.deepcopy(sim.state)
    ctl = Control(sim.skin, 50.0, 0.0)
    ctl.loads[0, 0, 0] = g       # step 0, scene 0: (gravity, base acceleration 0)
    # the same contact stage with patch reuse (dem.engine.coherence): the poses do not change
    # between the timed calls, so every closed patch is reused, and a step with it
    ctl_reuse = Control(sim.skin, 50.0, 0.0, patch_reuse)
    ctl_reuse.loads[0, 0, 0] = g
    c_reuse = copy.deepcopy(sim.contacts)
    sim_reuse = Simulation(build_wall("small", length=9, courses=15),
                           joint_law(Material(friction=0.81)),
                           step_options(SolverSpec(mode="serial", patch_reuse=patch_reuse)))
    sim_reuse.advance(500, loads)
    P, B = c.n_pairs, m.n_bodies
    runs = {  # name: (per, reps, launch)
        "sat": (P, 400, lambda r: sat(r, P, m.args, st.args, c.args)),
        "narrow": (P, 200, lambda r: narrow(r, P, m.args, st.args, c.args, False)),
        "contact": (P, 100, lambda r: contact(r, P, sim.dt, m.args, st.args, c.args, ctl.args,
                                              False)),
        "contact_reuse": (P, 100, lambda r: contact(r, P, sim.dt, m.args, st.args, c_reuse.args,
                                                    ctl_reuse.args, False)),
        "integrate": (B, 300, lambda r: integrate(r, B, sim.dt, m.args, st.args, c.args,
                                                  ctl.args)),
        "step": (1, 200, lambda r: sim.advance(r, loads)),
        "step_reuse": (1, 200, lambda r: sim_reuse.advance(r, loads)),
    }
    out = {}
    for name, (per, reps, launch) in runs.items():
        launch(1)  # compile
        times = []
        for _ in range(20 * repeats):
            c0 = time.process_time()
            launch(reps)
            times.append((time.process_time() - c0) / reps / per)
        out[name] = (float(np.median(times)), float(np.min(times)))
    out["pairs"], out["bodies"] = P, B
    out["kept"] = int((sim_reuse.contacts.patch_shape[:P, 0, 3] > 0).sum())
    return out


WALL_CASE = {"name": "wall-9x15", "scene": {"wall": {"brick": "small", "length": 9, "courses": 15}},
             "material": {"friction": 0.81}, "run": {"duration": 1.0}}


def _variant_case(case_path, bed, shape, seed, patch_reuse):
    """The 9 x 15 wall (case_path None) or a case file, with ``imperfections:`` replaced by
    bed_unevenness = bed (0: none), face_shape, seed, and the solver on one thread, serial
    kernel, solver.patch_reuse = patch_reuse."""
    from dem.case import parse_case
    from dem.case.document import load_case
    from dem.case.imperfections import Imperfections

    case = parse_case(dict(WALL_CASE)) if case_path is None else load_case(case_path)
    imp = Imperfections(bed_unevenness=bed, face_shape=shape, seed=seed) if bed > 0 else \
        Imperfections()
    solver = case.solver.model_copy(update={"threads": 1, "mode": "serial",
                                            "patch_reuse": patch_reuse})
    return case.model_copy(update={"imperfections": imp, "solver": solver})


def _restore(dst, src):
    """Copy every array of container src into container dst (in place: the argpacks keep
    pointing at dst's arrays)."""
    for name, arr in dst.arrays().items():
        arr[...] = getattr(src, name)


def _rotating(sim):
    """Mean number (0-5) per movable body of the free rotation's five factors whose angle
    reaches TINY_ANGLE at the present angular velocity (dem.engine.step.free_rotation: those
    call sin and cos, the others skip them)."""
    import numpy as np

    from dem.engine.mathutil import TINY_ANGLE

    n = sim.n_blocks
    mov = sim._movable[:n]
    wb = np.einsum("bji,bj->bi", sim.state.rot[:n], sim.state.omega[:n])[mov]  # R^T omega
    phi = np.abs(sim.dt * wb)
    count = 2 * (0.5 * phi[:, 0] >= TINY_ANGLE) + 2 * (0.5 * phi[:, 1] >= TINY_ANGLE) + (
        phi[:, 2] >= TINY_ANGLE)
    return float(count.mean()) if len(count) else 0.0


def _critical_step(sim):
    """Which block and which mode set the critical step: dem.engine.timestep's bound split into
    its terms (translation along each body axis; rotation about it: kn bending of the faces
    normal to the other two axes, ks torsion of the faces normal to it, ks shear of the side
    faces), with the face areas the simulation uses (capped for light large-faced blocks)."""
    import numpy as np

    from dem.engine.timestep import critical_time_step

    m, j = sim.model, sim.joints
    size, mass, inertia = 2 * m.half_np, m.mass_np, m.inertia_np
    kn, ks, zeta = j.normal_stiffness, j.shear_stiffness, j.damping
    fa = sim._face_area
    full = np.stack([size[:, 1] * size[:, 2], size[:, 0] * size[:, 2],
                     size[:, 0] * size[:, 1]], axis=1)
    frac = fa / np.maximum(full, 1e-300)[:, :, None]
    area, fsum = fa.sum(axis=2), frac.sum(axis=2)
    terms = {}
    for a in range(3):
        b, c = (a + 1) % 3, (a + 2) % 3
        la, lb, lc = size[:, a], size[:, b], size[:, c]
        terms[f"translation along body axis {a}"] = 2 * (kn * area[:, a] + ks * (
            area[:, b] + area[:, c])) / mass
        parts = {"kn bending": kn * fsum[:, c] * la * lb**3 / 12.0
                 + kn * fsum[:, b] * la * lc**3 / 12.0,
                 "ks torsion": ks * area[:, a] * (lb**2 + lc**2) / 12.0,
                 "ks shear of the side faces": ks * (area[:, c] * lc**2 + area[:, b] * lb**2) / 4.0}
        for name, v in parts.items():
            terms[f"rotation about body axis {a} ({name})"] = 2 * v / inertia[:, a]
    # a rotation's terms add up: group them back per axis to find the block's bound
    w2_axis = []
    for a in range(3):
        w2_axis.append(terms[f"translation along body axis {a}"])
        w2_axis.append(sum(v for n, v in terms.items() if n.startswith(f"rotation about body axis {a}")))
    w2 = np.max(np.stack(w2_axis), axis=0)
    factor = np.sqrt(1 + zeta**2) - zeta
    mov = sim._movable
    dt_b = np.where(mov, 2.0 / np.sqrt(np.maximum(w2, 1e-300)) * factor, np.inf)
    group = lambda b: sim.scene.group_names[sim.scene.group[b]] if b < sim.n_blocks else "?"  # noqa: E731

    def describe(b):
        k = int(np.argmax([w[b] for w in w2_axis]))
        a = k // 2
        if k % 2 == 0:
            mode = f"translation along its {1e3 * size[b, a]:.0f} mm axis"
        else:
            rot = {n: float(v[b]) for n, v in terms.items()
                   if n.startswith(f"rotation about body axis {a}")}
            top = max(rot, key=rot.get)
            share = rot[top] / sum(rot.values())
            mode = (f"rotation about its {1e3 * size[b, a]:.0f} mm axis, "
                    f"{top.split('(')[1].rstrip(')')} {100 * share:.0f} %")
        whole = critical_time_step(size[b:b + 1], mass[b:b + 1], inertia[b:b + 1],
                                   np.ones(1, bool), kn, ks, zeta)
        return {"block": int(b), "group": group(b), "size_mm": [round(1e3 * s, 1) for s in size[b]],
                "mass_kg": float(mass[b]), "dt_crit": float(dt_b[b]), "mode": mode,
                "area_cap_m2": float(sim.area_cap[b]), "dt_crit_whole_faces": whole}

    b = int(np.argmin(dt_b))
    uncapped = np.where(np.isfinite(sim.area_cap), np.inf, dt_b)
    bu = int(np.argmin(uncapped))
    return {"dt": float(sim.dt), "dt_crit": float(sim.dt_crit), "safety": float(sim.options.safety),
            "check": float(dt_b[b] / sim.dt_crit), "critical": describe(b),
            "critical_uncapped": describe(bu), "dt_changes": sim.dt_changes}


def _imperfect_stages(repeats, bed, shapes, seed=0, case_path=None, load_time=0.0,
                      patch_reuse=1e-7):
    """Runs inside the child process: the stages of --stages on the perfect scene and on the
    same scene with warped faces (bed_unevenness ``bed``, each face shape of ``shapes``, seeded),
    each built from its case (dem.run.build.build), the imperfect ones settled as the run loop
    does (dem.run.settle), then ``load_time`` s under the case's loading (else 500 steps), all
    timed interleaved in this one process (the ratios are from the same run); plus the census
    of the contacts (kernel ``census``) and the critical step."""
    import copy

    import numpy as np

    from dem.engine.containers import Control
    from dem.run.build import build
    from dem.run.settle import settle

    variants, runs = {}, {}
    labels = [("perfect", None)] + [(s, s) for s in (shapes if bed else [])]
    for label, shape in labels:
        info = {}
        for tol in ((0.0, patch_reuse) if shape is None else (0.0,)):
            case = _variant_case(case_path, bed if shape else 0.0, shape or "bilinear", seed, tol)
            built = build(case)
            sim = built.sim
            c0 = time.process_time()
            if case.imperfections.any():
                s = settle(sim, built.loading, case.solver.local_damping)
                info["settling"] = {"at_rest": s["at_rest"], "time_s": s["time_s"],
                                    "steps": s["steps"], "cpu_s": time.process_time() - c0,
                                    "largest_settlement_m": s["largest_settlement_m"]}
            steps = int(round(load_time / sim.dt)) if load_time > 0 else 500
            sim.advance(steps, built.loading)
            if tol == 0.0:
                info.update(sim=sim, loading=built.loading, name=case.name,
                            loaded_steps=steps)
            else:
                info["sim_reuse"] = sim
        variants[label] = info

    k = _kernels()
    out = {}
    for label, shape in labels:
        info = variants[label]
        sim, loading = info["sim"], info["loading"]
        warped = shape is not None
        m = sim.model
        st, c = copy.deepcopy(sim.state), copy.deepcopy(sim.contacts)
        g, a = loading(np.array([sim.t]))
        ctl = Control(sim.skin, 50.0, 0.0)
        ctl.loads[0, 0, 0], ctl.loads[0, 0, 1] = g[0], a[0]   # step 0, scene 0
        # the contact and integrate stages write (history, wrenches, poses): each gets its own
        # copies, put back to the snapshot before every timed launch (untimed), so that no
        # stage sees a state another one moved
        c_con, st_int, c_int = (copy.deepcopy(x) for x in (c, st, c))
        reset_con = lambda c_con=c_con, c=c: _restore(c_con, c)  # noqa: E731
        reset_int = lambda st_int=st_int, c_int=c_int, st=st, c=c: (  # noqa: E731
            _restore(st_int, st), _restore(c_int, c))
        P, B = c.n_pairs, m.n_bodies
        cen = np.zeros((P, 8))
        k.census(P, m.args, st.args, c.args, cen)
        code, imp, tw, npoly, n_open, npts, nz, fit = cen.T
        touch = npts > 0
        face = touch & (code >= 0) & (code < 6)
        whole = face & (n_open == 0)
        planar = face & (imp > 0) & (tw == 0)
        bed_j = face & (nz > 0.9)
        depth = np.concatenate([c.depth[p, : c.npts[p]] for p in range(P)]) if P else np.zeros(0)
        res = {"name": info["name"], "blocks": sim.n_blocks, "pairs": int(P), "bodies": int(B),
               "touching": int(touch.sum()), "points": int(npts.sum()),
               "points_per_touching": float(npts[touch].mean()) if touch.any() else 0.0,
               "overlap_vertices_per_face_pair": float(npoly[face].mean()) if face.any() else 0.0,
               "face_touching": int(face.sum()), "whole": int(whole.sum()),
               "bed_touching": int(bed_j.sum()), "bed_whole": int((whole & bed_j).sum()),
               "imperfect_planar": int(planar.sum()),
               "imperfect_twisted": int((face & (imp > 0) & (tw > 0)).sum()),
               "planar_whole": int((planar & whole).sum()),
               "edge_touching": int((touch & (code >= 6)).sum()),
               "fit_err_max_m": float(fit[planar].max()) if planar.any() else 0.0,
               "depth_median_m": float(np.median(depth)) if len(depth) else 0.0,
               "rotating_factors_per_body": _rotating(sim),
               "loaded_steps": info["loaded_steps"], "settling": info.get("settling"),
               "timestep": _critical_step(sim)}
        out[label] = res
        runs[(label, "sat")] = (P, 400, lambda r, P=P, m=m, st=st, c=c:
                                k.sat(r, P, m.args, st.args, c.args))
        runs[(label, "overlap")] = (P, 200, lambda r, P=P, m=m, st=st, c=c:
                                    k.overlap(r, P, m.args, st.args, c.args))
        runs[(label, "narrow")] = (P, 200, lambda r, P=P, m=m, st=st, c=c, w=warped:
                                   k.narrow(r, P, m.args, st.args, c.args, w))
        runs[(label, "contact")] = (P, 100, lambda r, P=P, m=m, st=st, c=c_con, ctl=ctl,
                                    w=warped, dt=sim.dt: k.contact(r, P, dt, m.args, st.args,
                                                                   c.args, ctl.args, w),
                                    reset_con)
        runs[(label, "integrate")] = (B, 300, lambda r, B=B, m=m, st=st_int, c=c_int, ctl=ctl,
                                      dt=sim.dt: k.integrate(r, B, dt, m.args, st.args, c.args,
                                                             ctl.args), reset_int)
        runs[(label, "step")] = (1, 200, lambda r, sim=sim, ld=loading: sim.advance(r, ld))
        if not warped:
            c2 = copy.deepcopy(c)
            ctl_r = Control(sim.skin, 50.0, 0.0, patch_reuse)
            sim_r = info["sim_reuse"]
            runs[(label, "narrow_warped_kernel")] = (P, 200, lambda r, P=P, m=m, st=st, c=c:
                                                     k.narrow(r, P, m.args, st.args, c.args,
                                                              True))
            runs[(label, "contact_reuse")] = (P, 100, lambda r, P=P, m=m, st=st, c=c2,
                                              ctl=ctl_r, dt=sim.dt:
                                              k.contact(r, P, dt, m.args, st.args, c.args,
                                                        ctl.args, False))
            runs[(label, "step_reuse")] = (1, 200, lambda r, sim=sim_r, ld=loading:
                                           sim.advance(r, ld))
            res["kept"] = int((sim_r.contacts.patch_shape[: sim_r.contacts.n_pairs, 0, 3]
                               > 0).sum())
    runs = {key: run + (None,) * (4 - len(run)) for key, run in runs.items()}
    for per, reps, launch, reset in runs.values():
        launch(1)  # compile (or load from the offline cache)
    times = {key: [] for key in runs}
    for _ in range(20 * repeats):  # interleaved: the machine's load hits every stage alike
        for key, (per, reps, launch, reset) in runs.items():
            if reset is not None:
                reset()
            c0 = time.process_time()
            launch(reps)
            times[key].append((time.process_time() - c0) / reps / per)
    for (label, name), ts in times.items():
        per = runs[(label, name)][0]
        out[label].setdefault("stages", {})[name] = (float(np.median(ts)), float(np.min(ts)),
                                                     per)
    for label, _shape in labels:  # the step timing ran on: dt changes then
        out[label]["timestep_end"] = _critical_step(variants[label]["sim"])
    return out


def _print_imperfect(r, bed, seed, where, load_time, repeats):
    labels = list(r)
    p0 = r["perfect"]
    print(f"\n## Stages, perfect against warped faces: {where} ({p0['blocks']} blocks; "
          f"bed_unevenness {bed:g} m, seed {seed}; one thread, CPU time, median of "
          f"{20 * repeats} interleaved runs in one process)")
    load = (f"{load_time:g} s under the case's loading" if load_time > 0 else
            "500 steps at rest")
    print(f"Imperfect scenes settled first (dem.run.settle), then {load}; stages timed on that "
          f"snapshot, the step going on from it.\n")
    print("| | " + " | ".join(labels) + " |")
    print("|---|" + "---|" * len(labels))

    def row(name, fn):
        print(f"| {name} | " + " | ".join(fn(r[lab]) for lab in labels) + " |")

    row("pairs in the neighbour list", lambda x: str(x["pairs"]))
    row("touching pairs (points > 0)", lambda x: str(x["touching"]))
    row("contact points (per touching pair)",
        lambda x: f"{x['points']} ({x['points_per_touching']:.2f})")
    row("overlap polygon vertices per touching face pair",
        lambda x: f"{x['overlap_vertices_per_face_pair']:.2f}")
    row("touching face pairs whole (no vertex cut by the gap clip)",
        lambda x: f"{x['whole']} / {x['face_touching']} ({100 * x['whole'] / max(x['face_touching'], 1):.0f} %)")
    row("of them beds and table (|n_z| > 0.9): whole",
        lambda x: f"{x['bed_whole']} / {x['bed_touching']}")
    row("imperfect face pairs: planar path (whole) / twisted (vertex) path",
        lambda x: f"{x['imperfect_planar']} ({x['planar_whole']}) / {x['imperfect_twisted']}")
    row("edge-edge contacts", lambda x: str(x["edge_touching"]))
    row("median point depth", lambda x: f"{x['depth_median_m'] * 1e6:.2f} um")
    row("planar pairs: largest |gap - affine fit| at a vertex",
        lambda x: f"{x['fit_err_max_m']:.1e} m" if x["imperfect_planar"] else "-")
    row("patches kept by reuse 1e-7 m", lambda x: str(x["kept"]) if "kept" in x else "-")
    row("settling: simulated s, steps, CPU s",
        lambda x: (f"{x['settling']['time_s']:.2f} s, {x['settling']['steps']}, "
                   f"{x['settling']['cpu_s']:.0f} s" + ("" if x["settling"]["at_rest"]
                                                      else " (not at rest)"))
        if x["settling"] else "-")
    row("dt (dt_crit) at the snapshot", lambda x: f"{x['timestep']['dt']:.4g} s "
        f"({x['timestep']['dt_crit']:.4g})")
    row("dt (dt_crit) after the step timing", lambda x: f"{x['timestep_end']['dt']:.4g} s "
        f"({x['timestep_end']['dt_crit']:.4g})")
    row("critical block", lambda x: (f"{x['timestep_end']['critical']['block']} "
                                     f"{x['timestep_end']['critical']['group']}: "
                                     f"{x['timestep_end']['critical']['mode']}"))
    row("uncapped (bricks): dt_crit, block",
        lambda x: (f"{x['timestep_end']['critical_uncapped']['dt_crit']:.4g} s, "
                   f"{x['timestep_end']['critical_uncapped']['block']} "
                   f"{x['timestep_end']['critical_uncapped']['group']}: "
                   f"{x['timestep_end']['critical_uncapped']['mode']}"))
    row("critical block: dt_crit capped / with whole faces; safety", lambda x: (
        f"{x['timestep_end']['critical']['dt_crit']:.4g} / "
        f"{x['timestep_end']['critical']['dt_crit_whole_faces']:.4g} s; "
        f"{x['timestep_end']['safety']:g}"))
    row("rotation factors calling sin/cos, per body (of 5)",
        lambda x: f"{x['rotating_factors_per_body']:.2f}")
    row("dt changes (t, new dt, blocks)", lambda x: "; ".join(
        f"{d['t']:.3f} s {d['new_dt']:.3g} s {d['blocks']}"
        for d in x["timestep_end"]["dt_changes"]) or "none")

    print("\nStage cost: per pair (or body), and per step in brackets (x pairs or bodies); "
          "ratio = per step, warped / perfect (reuse off)\n")
    imp = [lab for lab in labels if lab != "perfect"]
    print("| stage | " + " | ".join(labels + [f"{lab} / perfect" for lab in imp]) + " |")
    print("|---|" + "---|" * (len(labels) + len(imp)))
    stages = (("sat", "separating axes + axis choice", "ns/pair"),
              ("overlap", "face frame + incident face + 4 rectangle clips", "ns/pair"),
              ("narrow", "narrow phase (box_contact; warped kernel on warped scenes)", "ns/pair"),
              ("narrow_warped_kernel", "narrow phase, warped kernel", "ns/pair"),
              ("contact", "contact stage (narrow + law + history)", "ns/pair"),
              ("contact_reuse", "contact stage, patch reuse 1e-7 m", "ns/pair"),
              ("integrate", "integrate stage", "ns/body"),
              ("step", "serial step (patch reuse off for perfect)", "us"),
              ("step_reuse", "serial step, patch reuse 1e-7 m (the default)", "us"))
    for name, what, unit in stages:
        cells, per_step = [], {}
        for lab in labels:
            st = r[lab]["stages"].get(name)
            if st is None:
                cells.append("-")
                continue
            med, _low, per = st
            per_step[lab] = med * per
            cells.append(f"{med * 1e6:.1f} us" if unit == "us" else
                         f"{med * 1e9:.0f} {unit} ({med * per * 1e6:.1f} us)")
        ref = per_step.get("perfect")
        ratios = [f"{per_step[lab] / ref:.2f}" if lab in per_step and ref else "-" for lab in imp]
        print(f"| {what} | " + " | ".join(cells + ratios) + " |")


def _launch_cost(repeats):
    """Runs inside the child process: microseconds per launch of the stepping kernels with no
    work (n_steps = 0 / n_pairs = 0 and no bodies), through Taichi's own call and through the
    cached launch context, and per parallel loop of a trivial kernel (the thread pool's
    dispatch)."""
    import numpy as np
    import taichi as ti

    from dem.builders import build_wall
    from dem.case import Material, SolverSpec
    from dem.run.build import joint_law, step_options
    from dem.engine import Simulation, step
    from dem.engine.launch import CachedLaunch

    sim = Simulation(build_wall("small", length=9, courses=15),
                     joint_law(Material(friction=0.81)),
                     step_options(SolverSpec(mode="serial")))
    packs = sim.containers()

    def per_call(fn, n=300):
        fn()
        times = []
        for _ in range(5 * repeats):
            t0 = time.perf_counter()
            for _ in range(n):
                fn()
            times.append((time.perf_counter() - t0) / n * 1e6)
        return float(np.median(times))

    out = {}
    flags = (False, False, False, False, False)  # warped, hyperbolic, overlap, batched,
    #                                              pair_damping: a plain wall
    out["serial, Taichi call"] = per_call(lambda: step.advance_serial(0, 0, 1e-5, *packs, *flags))
    fast = CachedLaunch(step.advance_serial, (0, 0, 1e-5), *packs, *flags)
    out["serial, cached launch"] = per_call(lambda: fast(0, 0, 1e-5), 3000)
    # the parallel kernel with no pairs still integrates the bodies: give it none by launching
    # the probe kernel (one parallel loop over 0 pairs) instead
    depth = np.zeros(1)
    out["probe (1 parallel loop, 0 pairs), Taichi call"] = per_call(
        lambda: step.probe_contacts(0, 0, depth, depth, *packs[:3], False, False))
    probe = CachedLaunch(step.probe_contacts, (0, 0), depth, depth, *packs[:3], False, False)
    out["probe (1 parallel loop, 0 pairs), cached launch"] = per_call(lambda: probe(0, 0), 3000)
    a = np.zeros(64)

    @ti.kernel
    def loops(n: ti.i32, x: ti.types.ndarray(ndim=1)):
        for i in range(n):
            x[i] += 1.0
        for i in range(n):
            x[i] += 1.0

    @ti.kernel
    def serial_loops(n: ti.i32, x: ti.types.ndarray(ndim=1)):
        ti.loop_config(serialize=True)
        for i in range(n):
            x[i] += 1.0
        ti.loop_config(serialize=True)
        for i in range(n):
            x[i] += 1.0

    two = CachedLaunch(loops, (8,), a)
    ser = CachedLaunch(serial_loops, (8,), a)
    out["2 parallel loops of 8 iterations, cached launch"] = per_call(lambda: two(8), 3000)
    out["2 serialized loops of 8 iterations, cached launch"] = per_call(lambda: ser(8), 3000)
    return out


def run_child(length, courses, mode, threads, steps, repeats, cache_dir=None, patch_reuse=None):
    call = f"_measure({length}, {courses}, {mode!r}, {steps}, {repeats}, {patch_reuse!r})"
    return _child(call, threads, cache_dir)


def _child(call, threads, cache_dir=None):
    env = dict(os.environ, DEM_THREADS=str(threads))
    if cache_dir is not None:
        env["TI_OFFLINE_CACHE_FILE_PATH"] = cache_dir
    code = (f"import json, sys; sys.path.insert(0, {os.path.dirname(__file__)!r}); "
            f"import engine_speed; print('RESULT', json.dumps(engine_speed.{call}))")
    out = subprocess.run([sys.executable, "-c", code], env=env, capture_output=True, text=True)
    for line in out.stdout.splitlines():
        if line.startswith("RESULT "):
            return json.loads(line[7:])
    raise RuntimeError(out.stderr[-2000:])


def main():
    ap = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawTextHelpFormatter)
    ap.add_argument("--steps", type=int, default=3000)
    ap.add_argument("--repeats", type=int, default=5)
    ap.add_argument("--quick", action="store_true")
    ap.add_argument("--stages", action="store_true")
    ap.add_argument("--launch", action="store_true")
    ap.add_argument("--scaling", action="store_true")
    ap.add_argument("--threads", type=int, nargs="+", default=[1, 2])
    ap.add_argument("--sizes", type=int, nargs="+", default=list(SCALING), choices=list(SCALING),
                    help="walls of --scaling, by their number of bricks")
    ap.add_argument("--patch-reuse", type=float, default=None,
                    help="solver.patch_reuse of the --quick and --scaling runs (m; 0 = off; "
                    "default: the case default); "
                    "--stages times the contact stage and a step with 1e-7 m beside 0")
    ap.add_argument("--imperfections", type=float, default=None, metavar="BED_M",
                    help="--stages: also time the scene with imperfections: {bed_unevenness: "
                    "BED_M, face_shape: each of --face-shape, seed: --seed}, settled first, "
                    "interleaved with the perfect scene in one process")
    ap.add_argument("--face-shape", nargs="+", choices=("planar", "bilinear"),
                    default=["planar"], help="face shapes of --imperfections (default planar)")
    ap.add_argument("--seed", type=int, default=0, help="seed of --imperfections")
    ap.add_argument("--case", default=None,
                    help="--stages --imperfections: the scene, solver and loading of this case "
                    "file (default the 9 x 15 wall at rest)")
    ap.add_argument("--load-time", type=float, default=0.0,
                    help="--stages with --case: simulated seconds under the case's loading "
                    "before the stages are timed (default 0: 500 steps)")
    args = ap.parse_args()
    print(f"# engine_speed  python {sys.version.split()[0]}, {os.cpu_count()} cores, "
          f"{time.strftime('%Y-%m-%d %H:%M')}")
    if args.stages and (args.imperfections is not None or args.case is not None):
        bed = args.imperfections or 0.0
        case = os.path.abspath(args.case) if args.case else None
        r = _child(f"_imperfect_stages({args.repeats}, {bed!r}, {args.face_shape!r}, "
                   f"{args.seed}, {case!r}, {args.load_time!r})", 1)
        where = args.case or "9 x 15 wall"
        _print_imperfect(r, bed, args.seed, where, args.load_time, args.repeats)
        print("\n```json\n" + json.dumps(r, indent=1, default=str) + "\n```")
        return
    if args.stages:
        r = _child(f"_stages({args.repeats})", 1)
        print(f"\n## Stages on the 9 x 15 wall ({r['pairs']} pairs, {r['bodies']} bodies; "
              f"1 thread, CPU time; patch reuse 1e-7 m keeps {r['kept']} patches)")
        print("| stage | median | min |")
        print("|---|---|---|")
        for name, what, unit, scale in (
                ("sat", "separating axes + axis choice", "ns/pair", 1e9),
                ("narrow", "narrow phase (box_contact)", "ns/pair", 1e9),
                ("contact", "contact stage (narrow phase + law + history)", "ns/pair", 1e9),
                ("contact_reuse", "contact stage, patch reuse 1e-7 m", "ns/pair", 1e9),
                ("integrate", "integrate stage", "ns/body", 1e9),
                ("step", "serial step", "us", 1e6),
                ("step_reuse", "serial step, patch reuse 1e-7 m", "us", 1e6)):
            med, low = r[name]
            print(f"| {what} | {med * scale:.0f} {unit} | {low * scale:.0f} {unit} |")
        return
    if args.launch:
        for threads in args.threads:
            r = _child(f"_launch_cost({args.repeats})", threads)
            print(f"\n## Launch cost, {threads} thread(s) (us per launch, median)")
            print("| launch | us |")
            print("|---|---|")
            for name, us in r.items():
                print(f"| {name} | {us:.1f} |")
        return
    if args.scaling:
        print("\n## Serial kernel against parallel kernel by wall size (brick-steps/s, wall "
              "clock; per CPU-s in brackets)")
        print("| bricks | pairs | serial | " + " | ".join(f"parallel, {t} thr" for t in args.threads)
              + " | best parallel / serial |")
        print("|---|---|---|" + "---|" * len(args.threads) + "---|")
        for target in args.sizes:
            length, courses = SCALING[target]
            steps = max(100, args.steps * 150 // target)
            ser = run_child(length, courses, "serial", 1, steps, args.repeats,
                            patch_reuse=args.patch_reuse)
            par = [run_child(length, courses, "parallel", t, steps, args.repeats,
                             patch_reuse=args.patch_reuse) for t in args.threads]
            best = max(p["brick_steps_per_s"] for p in par) / ser["brick_steps_per_s"]
            print(f"| {ser['blocks']} | {ser['pairs']} | {ser['brick_steps_per_s']:.3g} "
                  f"({ser['brick_steps_per_cpu_s']:.3g}) | " + " | ".join(
                      f"{p['brick_steps_per_s']:.3g} ({p['brick_steps_per_cpu_s']:.3g})"
                      for p in par) + f" | {best:.2f} |", flush=True)
        return
    print("\n## 9 x 15 stretcher wall at rest (142 blocks)")
    print("| threads | kernel | brick-steps/s (median) | min - max | per CPU-s | pairs "
          "| contact points |")
    print("|---|---|---|---|---|---|---|")
    for threads in (1, 2):
        for mode in ("serial", "parallel"):
            r = run_child(9, 15, mode, threads, args.steps, args.repeats,
                          patch_reuse=args.patch_reuse)
            print(f"| {threads} | {mode} | {r['brick_steps_per_s']:.3g} | "
                  f"{min(r['rates']):.3g} - {max(r['rates']):.3g} | "
                  f"{r['brick_steps_per_cpu_s']:.3g} | {r['pairs']} | {r['contact_points']} |",
                  flush=True)
    with tempfile.TemporaryDirectory() as cache:
        cold = run_child(9, 15, "serial", 2, 10, 1, cache)
        warm = run_child(9, 15, "serial", 2, 10, 1, cache)
    print(f"\nkernel compile (serial kernel + probes): cold {cold['compile_s']:.1f} s, "
          f"warm (offline cache) {warm['compile_s']:.1f} s; importing the package "
          f"{warm['import_s']:.1f} s")
    if args.quick:
        return
    print("\n## Scaling with wall size (2 threads)")
    print("| bricks | kernel | brick-steps/s | per CPU-s | pairs | engine arrays (MB) "
          "| bytes/block |")
    print("|---|---|---|---|---|---|---|")
    for target, (length, courses) in WALLS.items():
        steps = max(100, args.steps * 150 // target)
        for mode in ("serial", "parallel"):
            r = run_child(length, courses, mode, 2, steps, 3)
            print(f"| {r['blocks']} | {mode} | {r['brick_steps_per_s']:.3g} | "
                  f"{r['brick_steps_per_cpu_s']:.3g} | {r['pairs']} | "
                  f"{r['array_bytes'] / 1e6:.2f} | {r['array_bytes'] / r['blocks']:.0f} |",
                  flush=True)


if __name__ == "__main__":
    main()
