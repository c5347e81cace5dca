"""Can Taichi's compute graphs (ti.graph) launch the stepping kernel for less host time than
the engine's cached launch?  (The host's Python of a launch is most of a GPU step's host time:
benchmarks/host_share.py.)

    python benchmarks/graph_launch.py [--args 60] [--dispatches 16] [--json FILE]

A kernel of ``--args`` vector ndarray arguments (the device kernel's 60 slots) and three scalars,
whose body does almost nothing (the launch's cost, not the kernel's), in two sizes: one
statement, and ``BIG`` statements unrolled (a kernel of more IR, the same arguments).  For
each: the host time of a launch by Taichi's own call, by dem.engine.launch.CachedLaunch (a
fresh launch context a call with every ndarray slot set, as on a device), and per dispatch of a
compiled graph of ``--dispatches`` dispatches (``Graph.run``: one Python call, the dispatches'
arguments set in C++), each the median of 5 repeats; on the CPU (x64), with ndarrays.  Prints
one JSON line.  A graph takes no argpack (its arguments are scalars, ndarrays, matrices,
textures) and no template argument, so the device kernel would need its 60 arrays as arguments
of their own (61 of the 64 argument elements) and one kernel a variant.
"""

from __future__ import annotations

import argparse
import importlib.util
import json
import sys
import tempfile
import time
from pathlib import Path

import numpy as np

ROOT = Path(__file__).resolve().parents[1]
sys.path.insert(0, str(ROOT))

BIG = 200  # statements of the larger kernel


def kernel_source(n_args: int, statements: int) -> str:
    """A Taichi kernel module: ``k(s, n, dt, a0, ..., a{n_args - 1})``."""
    args = ", ".join(f"a{i}: ti.types.ndarray(dtype=ti.types.vector(3, ti.f64), ndim=1)"
                     for i in range(n_args))
    body = "".join(f"            a{j % n_args}[i] += dt * a{(j + 1) % n_args}[i]\n"
                   for j in range(statements))
    return ("import taichi as ti\n\n\n@ti.kernel\n"
            f"def k(s: ti.i32, n: ti.i32, dt: ti.f64, {args}):\n"
            "    for i in range(n):\n        if s >= 0:\n" + body)


def load_kernel(path: Path, n_args: int, statements: int):
    path.write_text(kernel_source(n_args, statements))  # Taichi reads a kernel's source file
    spec = importlib.util.spec_from_file_location(path.stem, path)
    mod = importlib.util.module_from_spec(spec)
    spec.loader.exec_module(mod)
    return mod.k


def median_us(f, calls: int, repeats: int = 5) -> float:
    times = []
    for _ in range(repeats):
        t0 = time.perf_counter()
        for _ in range(calls):
            f()
        times.append((time.perf_counter() - t0) / calls)
    return 1e6 * float(np.median(times))


def measure(kernel, arrays, n_args: int, dispatches: int) -> dict:
    import taichi as ti

    from dem.engine.launch import CachedLaunch

    kernel(-1, 100, 1e-5, *arrays)  # compiled before any timing
    cached = CachedLaunch(kernel, (-1, 100, 1e-5), *arrays)
    sym_s = [ti.graph.Arg(ti.graph.ArgKind.SCALAR, f"s{j}", ti.i32) for j in range(dispatches)]
    sym_n = ti.graph.Arg(ti.graph.ArgKind.SCALAR, "n", ti.i32)
    sym_dt = ti.graph.Arg(ti.graph.ArgKind.SCALAR, "dt", ti.f64)
    sym_a = [ti.graph.Arg(ti.graph.ArgKind.NDARRAY, f"a{i}", dtype=ti.types.vector(3, ti.f64),
                          ndim=1) for i in range(n_args)]
    builder = ti.graph.GraphBuilder()
    for j in range(dispatches):
        builder.dispatch(kernel, sym_s[j], sym_n, sym_dt, *sym_a)
    graph = builder.compile()
    values = {f"a{i}": a for i, a in enumerate(arrays)}
    values.update({"n": 100, "dt": 1e-5}, **{f"s{j}": -1 for j in range(dispatches)})
    graph.run(values)  # (idle: s < 0) anything left to compile, before the timing
    return {"taichi_call_us": median_us(lambda: kernel(-1, 100, 1e-5, *arrays), 200),
            "cached_launch_us": median_us(lambda: cached(-1, 100, 1e-5), 2000),
            "cached_launch_fresh_context": bool(cached.device_arrays),
            "cpp_launch_only_us": cpp_launch_us(cached, 2000),
            "graph_per_dispatch_us": median_us(lambda: graph.run(values), 50) / dispatches}


def cpp_launch_us(cached, calls: int, repeats: int = 5) -> float:
    """Taichi's C++ launch alone (on the CPU with the kernel's run: idle here), of contexts
    filled beforehand as CachedLaunch fills them: what a launch costs without its Python."""
    times = []
    for _ in range(repeats):
        ctxs = []
        for _ in range(calls):
            ctx = cached.t_kernel.make_launch_context()
            for slot, pack in cached.argpacks:
                ctx.set_arg_argpack(slot, pack)
            for slot, arr in cached.device_arrays:
                ctx.set_arg_ndarray(slot, arr)
            for k, (v, is_float) in enumerate(zip((-1, 100, 1e-5), cached.kinds)):
                (ctx.set_arg_float if is_float else ctx.set_arg_int)((k,), v)
            ctxs.append(ctx)
        t0 = time.perf_counter()
        for ctx in ctxs:
            cached.prog.launch_kernel(cached.compiled, ctx)
        times.append((time.perf_counter() - t0) / calls)
    return 1e6 * float(np.median(times))


def main() -> int:
    ap = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    ap.add_argument("--args", type=int, default=60)
    ap.add_argument("--dispatches", type=int, default=16)
    ap.add_argument("--json", default=None)
    a = ap.parse_args()
    import taichi as ti

    from dem import ti_runtime

    ti_runtime.init(threads=1)
    arrays = [ti.ndarray(ti.types.vector(3, ti.f64), shape=(100,)) for _ in range(a.args)]
    out = {"bench": "graph_launch", "ndarray_args": a.args, "dispatches": a.dispatches,
           "taichi": ti.__version__, "arch": ti_runtime.settings()["arch"]}
    with tempfile.TemporaryDirectory() as tmp:
        for name, statements in (("small", 1), ("big", BIG)):
            kernel = load_kernel(Path(tmp) / f"graph_kernel_{name}.py", a.args, statements)
            out[name] = {"statements": statements, **measure(kernel, arrays, a.args,
                                                                a.dispatches)}
    line = json.dumps(out)
    print(line)
    if a.json:
        with open(a.json, "a") as f:
            f.write(line + "\n")
    return 0


if __name__ == "__main__":
    sys.exit(main())
