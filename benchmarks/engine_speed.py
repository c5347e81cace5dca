"""Engine throughput on the resting 9 x 15 stretcher-bond wall (issue 2), and how it scales.

    python benchmarks/engine_speed.py            # full table (a few minutes)
    python benchmarks/engine_speed.py --quick    # threads/modes on the 142-block wall only
    python benchmarks/engine_speed.py --stages   # cost of each stage on the 142-block wall
    python benchmarks/engine_speed.py --launch   # cost of a kernel launch, and of a parallel loop
    python benchmarks/engine_speed.py --scaling --threads 1 2   # serial vs parallel by size

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
body, and the whole serial step; the contact stage and the step without patch reuse
(solver.patch_reuse = 0) and with 1e-7 m (dem.engine.coherence).
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


def _stages(repeats, patch_reuse=1e-7):
    """Runs inside the child process: per-stage cost (see the module docstring)."""
    import copy

    import numpy as np
    import taichi as ti

    from dem.builders import build_wall
    from dem.case import Material, SolverSpec
    from dem.run.build import joint_law, step_options
    from dem.engine import Simulation, geometry, step

    sim = Simulation(build_wall("small", length=9, courses=15),
                     joint_law(Material(friction=0.81)),
                     step_options(SolverSpec(mode="serial", patch_reuse=0.0)))
    g = np.array([0.0, 0.0, -9.81])
    loads = lambda t: (np.tile(g, (len(t), 1)), np.zeros((len(t), 3)))  # noqa: E731
    sim.advance(500, loads)

    from dem.engine.containers import ContactArgs, ControlArgs, ModelArgs, StateArgs

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
               contacts: ContactArgs) -> ti.f64:
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
                    model.half[j], contacts.code[p], 1e-3 * hmin, hmin * hmin, model, False,
                    i, j, px, py, pz, dep, w)
                for q in range(n_points):
                    acc += px[q] + py[q] + pz[q] + dep[q] * w[q]
                acc += axis + n[0] + shrink + centroid[2]
        return acc

    @ti.kernel
    def contact(reps: ti.i32, n_pairs: ti.i32, dt: ti.f64, model: ModelArgs, state: StateArgs,
                contacts: ContactArgs, control: ControlArgs):
        ti.loop_config(serialize=True)
        for _ in range(reps):
            for p in range(n_pairs):
                step.contact_stage(p, dt, model, state, contacts, control, False)

    @ti.kernel
    def integrate(reps: ti.i32, n_bodies: ti.i32, dt: ti.f64, model: ModelArgs,
                  state: StateArgs, contacts: ContactArgs, control: ControlArgs):
        ti.loop_config(serialize=True)
        for _ in range(reps):
            for b in range(n_bodies):
                step.integrate_stage(b, 0, dt, model, state, contacts, control)

    from dem.engine.containers import Control
    m, c = sim.model, copy.deepcopy(sim.contacts)
    st = copy.deepcopy(sim.state)
    ctl = Control(sim.skin, 50.0, 0.0)
    ctl.loads[0, 0] = g
    # the same contact stage with patch reuse (dem.engine.coherence): the poses do not change
    # between the timed calls, so every closed patch is reused, and a step with it
    ctl_reuse = Control(sim.skin, 50.0, 0.0, patch_reuse)
    ctl_reuse.loads[0, 0] = g
    c_reuse = copy.deepcopy(sim.contacts)
    sim_reuse = Simulation(build_wall("small", length=9, courses=15),
                           joint_law(Material(friction=0.81)),
                           step_options(SolverSpec(mode="serial", patch_reuse=patch_reuse)))
    sim_reuse.advance(500, loads)
    P, B = c.n_pairs, m.n_bodies
    runs = {  # name: (per, reps, launch)
        "sat": (P, 400, lambda r: sat(r, P, m.args, st.args, c.args)),
        "narrow": (P, 200, lambda r: narrow(r, P, m.args, st.args, c.args)),
        "contact": (P, 100, lambda r: contact(r, P, sim.dt, m.args, st.args, c.args, ctl.args)),
        "contact_reuse": (P, 100, lambda r: contact(r, P, sim.dt, m.args, st.args, c_reuse.args,
                                                    ctl_reuse.args)),
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
    out["serial, Taichi call"] = per_call(lambda: step.advance_serial(0, 0, 1e-5, *packs))
    fast = CachedLaunch(step.advance_serial, (0, 0, 1e-5), *packs)
    out["serial, cached launch"] = per_call(lambda: fast(0, 0, 1e-5), 3000)
    # the parallel kernel with no pairs still integrates the bodies: give it none by launching
    # the probe kernel (one parallel loop over 0 pairs) instead
    depth = np.zeros(1)
    out["probe (1 parallel loop, 0 pairs), Taichi call"] = per_call(
        lambda: step.probe_contacts(0, depth, depth, *packs[:3]))
    probe = CachedLaunch(step.probe_contacts, (0,), depth, depth, *packs[:3])
    out["probe (1 parallel loop, 0 pairs), cached launch"] = per_call(lambda: probe(0), 3000)
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
    ap.add_argument("--sizes", type=int, nargs="+", default=list(SCALING))
    ap.add_argument("--patch-reuse", type=float, default=None,
                    help="solver.patch_reuse of the --quick and --scaling runs (m; 0 = off; "
                    "default: the case default); "
                    "--stages times the contact stage and a step with 1e-7 m beside 0")
    args = ap.parse_args()
    print(f"# engine_speed  python {sys.version.split()[0]}, {os.cpu_count()} cores, "
          f"{time.strftime('%Y-%m-%d %H:%M')}")
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
