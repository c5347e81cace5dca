"""Engine throughput on the resting 9 x 15 stretcher-bond wall (issue 2), and how it scales.

    python benchmarks/engine_speed.py            # full table (a few minutes)
    python benchmarks/engine_speed.py --quick    # threads/modes on the 142-block wall only
    python benchmarks/engine_speed.py --stages   # cost of each stage on the 142-block wall

Prints, for 1 and 2 threads and both kernels (serial multi-step, parallel per step):
brick-steps per second (median of --repeats runs of --steps steps, after a warm-up) by the wall
clock and per CPU-second of the process (the second is what to compare on a shared machine:
other jobs stretch the wall clock, not the CPU time; for the serial kernel both are the same on
an idle machine), contact pairs and points; the kernel compile time cold (empty offline cache)
and warm (cache filled); and, for walls of ~50 / 200 / 800 / 1600 / 3200 bricks, throughput of
both kernels (where the parallel one starts to win: PARALLEL_MIN_BODIES) and the bytes held by
the engine's arrays (memory proportional to the number of blocks).  Every figure comes from a
fresh process so the thread count and the cache state are what they say.

--stages times the stages alone on the wall after 500 steps (one thread, CPU time, each stage
function called in a serialized loop over all pairs or bodies, --repeats x 20 runs, median and
minimum): the separating-axis test with the axis choice, the whole narrow phase (box_contact),
the contact stage (narrow phase + joint law + shear history) per pair, the integrate stage per
body, and the whole serial step.
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


def _measure(length, courses, mode, steps, repeats):
    """Runs inside the child process."""
    t0 = time.perf_counter()
    import numpy as np

    from dem.builders import build_wall
    from dem.case import Material, SolverSpec
    from dem.engine import Simulation

    scene = build_wall("small", length=length, courses=courses)
    t_import = time.perf_counter() - t0
    sim = Simulation(scene, Material(friction=0.81), SolverSpec(mode=mode))
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
    nbytes = sum(a.nbytes for obj in (sim.model, sim.state, c) for a in vars(obj).values()
                 if hasattr(a, "nbytes"))
    return {
        "blocks": sim.n_blocks, "mode": sim.mode, "pairs": c.n_pairs,
        "contact_points": int(c.npts[: c.n_pairs].sum()), "dt": sim.dt,
        "brick_steps_per_s": float(np.median(rates)), "rates": rates,
        "brick_steps_per_cpu_s": float(np.median(cpu_rates)),
        "compile_s": sim.compile_seconds, "import_s": t_import, "array_bytes": int(nbytes),
    }


def _stages(repeats):
    """Runs inside the child process: per-stage cost (see the module docstring)."""
    import copy

    import numpy as np
    import taichi as ti

    from dem.builders import build_wall
    from dem.case import Material, SolverSpec
    from dem.engine import Simulation, geometry, step

    sim = Simulation(build_wall("small", length=9, courses=15), Material(friction=0.81),
                     SolverSpec(mode="serial"))
    g = np.array([0.0, 0.0, -9.81])
    loads = lambda t: (np.tile(g, (len(t), 1)), np.zeros((len(t), 3)))  # noqa: E731
    sim.advance(500, loads)
    nd = ti.types.ndarray
    vec3 = ti.math.vec3

    @ti.kernel
    def sat(reps: ti.i32, n_pairs: ti.i32, half: nd(dtype=vec3, ndim=1),
            pos: nd(dtype=vec3, ndim=1), rot: nd(dtype=ti.math.mat3, ndim=1),
            pairs: nd(dtype=ti.math.ivec2, ndim=1), codes: nd(dtype=ti.i32, ndim=1)) -> ti.f64:
        acc = 0.0
        ti.loop_config(serialize=True)
        for _ in range(reps):
            for p in range(n_pairs):
                i, j = pairs[p][0], pairs[p][1]
                hmin = ti.min(half[i].min(), half[j].min())
                ov = geometry.sat_overlaps(pos[i], rot[i], half[i], pos[j], rot[j], half[j])
                code, smallest = geometry.choose_axis(ov, codes[p], 1e-3 * hmin)
                acc += code + smallest
        return acc

    @ti.kernel
    def narrow(reps: ti.i32, n_pairs: ti.i32, half: nd(dtype=vec3, ndim=1),
               pos: nd(dtype=vec3, ndim=1), rot: nd(dtype=ti.math.mat3, ndim=1),
               pairs: nd(dtype=ti.math.ivec2, ndim=1), codes: nd(dtype=ti.i32, ndim=1)) -> ti.f64:
        acc = 0.0
        ti.loop_config(serialize=True)
        for _ in range(reps):
            for p in range(n_pairs):
                i, j = pairs[p][0], pairs[p][1]
                hmin = ti.min(half[i].min(), half[j].min())
                px = geometry.VP(0.0)
                py = geometry.VP(0.0)
                pz = geometry.VP(0.0)
                dep = geometry.VP(0.0)
                w = geometry.VP(0.0)
                code, n, npts, shrink, centroid = geometry.box_contact(
                    pos[i], rot[i], half[i], pos[j], rot[j], half[j], codes[p], 1e-3 * hmin,
                    hmin * hmin, px, py, pz, dep, w)
                for q in range(npts):
                    acc += px[q] + py[q] + pz[q] + dep[q] * w[q]
                acc += code + n[0] + shrink + centroid[2]
        return acc

    @ti.kernel
    def contact(reps: ti.i32, n_pairs: ti.i32, dt: ti.f64, energy: nd(dtype=ti.f64, ndim=1),
                half: nd(dtype=vec3, ndim=1), inv_mass: nd(dtype=ti.f64, ndim=1),
                material: nd(dtype=ti.i32, ndim=1), mat_pair: nd(dtype=ti.math.vec4, ndim=2),
                pos: nd(dtype=vec3, ndim=1), vel: nd(dtype=vec3, ndim=1),
                omega: nd(dtype=vec3, ndim=1), rot: nd(dtype=ti.math.mat3, ndim=1),
                pairs: nd(dtype=ti.math.ivec2, ndim=1), code: nd(dtype=ti.i32, ndim=1),
                npts: nd(dtype=ti.i32, ndim=1), normal: nd(dtype=vec3, ndim=1),
                loc: nd(dtype=vec3, ndim=2), shear: nd(dtype=vec3, ndim=2),
                point: nd(dtype=vec3, ndim=2), depth: nd(dtype=ti.f64, ndim=2),
                area: nd(dtype=ti.f64, ndim=2), fn: nd(dtype=ti.f64, ndim=2),
                ft: nd(dtype=vec3, ndim=2), wrench: nd(dtype=vec3, ndim=2)):
        ti.loop_config(serialize=True)
        for _ in range(reps):
            for p in range(n_pairs):
                step.contact_stage_pair(p, dt, half, inv_mass, material, mat_pair, pos, vel,
                                        omega, rot, pairs, code, npts, normal, loc, shear,
                                        point, depth, area, fn, ft, wrench, energy)

    @ti.kernel
    def integrate(reps: ti.i32, n_bodies: ti.i32, dt: ti.f64, g: vec3,
                  params: nd(dtype=ti.f64, ndim=1), flags: nd(dtype=ti.i32, ndim=1),
                  energy: nd(dtype=ti.f64, ndim=1), mass: nd(dtype=ti.f64, ndim=1),
                  inv_mass: nd(dtype=ti.f64, ndim=1), inv_inertia: nd(dtype=vec3, ndim=1),
                  radius: nd(dtype=ti.f64, ndim=1), pos: nd(dtype=vec3, ndim=1),
                  quat: nd(dtype=ti.math.vec4, ndim=1), vel: nd(dtype=vec3, ndim=1),
                  angmom: nd(dtype=vec3, ndim=1), omega: nd(dtype=vec3, ndim=1),
                  rot: nd(dtype=ti.math.mat3, ndim=1), force: nd(dtype=vec3, ndim=1),
                  torque: nd(dtype=vec3, ndim=1), wrench: nd(dtype=vec3, ndim=2),
                  adj_ptr: nd(dtype=ti.i32, ndim=1), adj: nd(dtype=ti.i32, ndim=1),
                  ref_pos: nd(dtype=vec3, ndim=1), ref_quat: nd(dtype=ti.math.vec4, ndim=1)):
        ti.loop_config(serialize=True)
        for _ in range(reps):
            for b in range(n_bodies):
                step.integrate_stage_body(b, dt, g, vec3(0.0), params, mass, inv_mass,
                                          inv_inertia, radius, pos, quat, vel, angmom, omega,
                                          rot, force, torque, wrench, adj_ptr, adj, ref_pos,
                                          ref_quat, flags, energy)

    m, c = sim.model, copy.deepcopy(sim.contacts)
    st = copy.deepcopy(sim.state)
    P, B = c.n_pairs, m.n_bodies
    energy, flags, params = np.zeros(8), np.zeros(4, np.int32), sim.params.copy()
    runs = {  # name: (per, reps, launch)
        "sat": (P, 400, lambda r: sat(r, P, m.half, st.pos, st.rot, c.pairs, c.code)),
        "narrow": (P, 200, lambda r: narrow(r, P, m.half, st.pos, st.rot, c.pairs, c.code)),
        "contact": (P, 100, lambda r: contact(
            r, P, sim.dt, energy, m.half, m.inv_mass, m.material, m.mat_pair, st.pos, st.vel,
            st.omega, st.rot, c.pairs, c.code, c.npts, c.normal, c.loc, c.shear, c.point,
            c.depth, c.area, c.fn, c.ft, c.wrench)),
        "integrate": (B, 300, lambda r: integrate(
            r, B, sim.dt, g, params, flags, energy, m.mass, m.inv_mass, m.inv_inertia,
            m.radius, st.pos, st.quat, st.vel, st.angmom, st.omega, st.rot, st.force,
            st.torque, c.wrench, c.adj_ptr, c.adj, c.ref_pos, c.ref_quat)),
        "step": (1, 200, lambda r: sim.advance(r, loads)),
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
    return out


def run_child(length, courses, mode, threads, steps, repeats, cache_dir=None):
    call = f"_measure({length}, {courses}, {mode!r}, {steps}, {repeats})"
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
    args = ap.parse_args()
    print(f"# engine_speed  python {sys.version.split()[0]}, {os.cpu_count()} cores, "
          f"{time.strftime('%Y-%m-%d %H:%M')}")
    if args.stages:
        r = _child(f"_stages({args.repeats})", 1)
        print(f"\n## Stages on the 9 x 15 wall ({r['pairs']} pairs, {r['bodies']} bodies; "
              "1 thread, CPU time)")
        print("| stage | median | min |")
        print("|---|---|---|")
        for name, what, unit, scale in (
                ("sat", "separating axes + axis choice", "ns/pair", 1e9),
                ("narrow", "narrow phase (box_contact)", "ns/pair", 1e9),
                ("contact", "contact stage (narrow phase + law + history)", "ns/pair", 1e9),
                ("integrate", "integrate stage", "ns/body", 1e9),
                ("step", "serial step", "us", 1e6)):
            med, low = r[name]
            print(f"| {what} | {med * scale:.0f} {unit} | {low * scale:.0f} {unit} |")
        return
    print("\n## 9 x 15 stretcher wall at rest (142 blocks)")
    print("| threads | kernel | brick-steps/s (median) | min - max | per CPU-s | pairs "
          "| contact points |")
    print("|---|---|---|---|---|---|---|")
    for threads in (1, 2):
        for mode in ("serial", "parallel"):
            r = run_child(9, 15, mode, threads, args.steps, args.repeats)
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
