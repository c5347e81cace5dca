"""Compile the engine's kernel variants once, before the test workers start.

Why: Taichi compiles a kernel on its first launch (~15-80 CPU-s for a stepping kernel, each
compile-time variant its own kernel: dem.engine.step.advance_serial) and writes it to its
offline cache (~/.cache/taichi, or TI_OFFLINE_CACHE_FILE_PATH) only when the process exits.  Two
xdist workers starting on an empty cache therefore each compiled every variant the tests use,
about four minutes each before the first engine test passed.  tests/conftest.py runs this module
in the xdist controller, before the workers start, in one subprocess per core (each compiles its
share of :data:`VARIANTS`, balanced by :data:`COMPILE_CPU_S`, and exits, which writes the
cache); the workers then load the kernels from the cache (LLVM's code generation of the cached
IR, ~1.4 CPU-s a kernel per process, benchmarks/RESULTS.md "Start-up of a short run").

The cache key of a kernel is its source and Taichi's compile settings, the CPU thread count
(``cpu_max_num_threads``, set from ``DEM_THREADS``) among them: a process with another thread
count compiles every kernel again.  tests/conftest.py therefore sets ``DEM_THREADS=1`` for the
whole test session (unless it is set already), so that the warm-up, the workers, the
commands the tests start and the dask workers of the sweep and ensemble tests (which dem.batch
starts with one thread each) all share one set of cached kernels.

Each variant is the smallest scene that reaches it (a one-brick wall of two courses), built as the run
builds a case (dem.run.build) and stepped once: the build compiles the stepping kernel (its
recording launch), probe_contacts and elastic_energy; the step compiles the overlap-reuse
variant (switched on after the build).  A stamp file in Taichi's cache directory records the
kernels' source, Taichi's version and the settings that enter the cache key: with the stamp
current the warm-up is skipped (a fraction of a second); a change of the engine's source or of
those settings warms again.  ``DEM_TEST_NO_WARMUP=1`` skips it (the workers then compile what
they need, as before).  The stamp also records each variant's CPU seconds.

Run by hand: ``python -m tests.warm_kernels [--variant K ...]`` (all variants, or the K-th).
"""

from __future__ import annotations

import argparse
import hashlib
import importlib.metadata
import json
import os
import subprocess
import sys
import tempfile
import time
import warnings
from pathlib import Path

import numpy as np

ROOT = Path(__file__).resolve().parent.parent

# the variants the default tests reach (checked by logging every kernel instantiation, with its
# compile-time arguments, of the warm-up and of the engine tests in one process, and by
# comparing the kernel files of a default run on an empty private cache,
# TI_OFFLINE_CACHE_FILE_PATH, with those of this warm-up: a variant here that no test reaches
# costs a compile for nothing; one missing is compiled by the worker that needs it).  Fields:
# mode "serial" | "parallel" (solver.mode), imperfect (warped faces: bed unevenness),
# overlap (solver.overlap_reuse > 0, warped only), law "linear" | "hyperbolic",
# damping "critical" | "pair" (the pair-damped normal law), scenes (> 1: the batched kernel),
# device (the device arrays on the CPU: always the parallel kernel, dem.engine.simulation).
# Not here, as each adds nothing a variant here does not compile: serial imperfect (the
# overlap variant's build compiles it, before overlap reuse is switched on), parallel with
# two scenes on device arrays (the serial one with device arrays is that kernel), and one
# scene on device arrays (on a device the kernels are the batched ones for one scene too:
# dem.engine.launcher.KernelVariants; on device arrays the stepping kernel is the device's,
# with its broad phase, one step a launch: dem.engine.step_device).  Not here
# either: the parallel kernel on warped faces (lone, batched, batched on device arrays), which
# one default test each reaches (test_resume's parallel kernel, test_batched_runs' device
# arrays): compiled once by that test's worker either way.
VARIANTS = (
    dict(mode="serial", imperfect=True, overlap=True),
    dict(mode="serial", imperfect=True, scenes=2),
    dict(mode="serial"),
    dict(mode="serial", scenes=2),
    dict(mode="serial", law="hyperbolic"),
    dict(mode="serial", damping="pair"),
    dict(mode="serial", scenes=2, device=True),
    dict(mode="parallel"),
    dict(mode="parallel", scenes=2),
)

# the CPU seconds of each variant on an empty cache, each in its own subprocess (its start
# included; the 2-core test VM), only to share the variants out between the subprocesses
# (:func:`lanes`): a stale figure costs balance, never a kernel
COMPILE_CPU_S = (108.5, 25.4, 24.3, 27.4, 25.4, 25.9, 27.9, 15.8, 16.4)

# what the kernels' code and their compilation depend on: a change re-runs the warm-up
SOURCES = ("dem/engine", "dem/ti_runtime.py", "dem/ti_import.py", "tests/warm_kernels.py")

STAMP = "dem_test_warm_kernels.json"


def describe(v: dict) -> str:
    return ", ".join(f"{k}={val}" for k, val in v.items())


def case_of(v: dict):
    """The case of variant ``v``: a 2 x 1 wall of small bricks (two blocks, one joint)."""
    from dem.case import parse_case

    material = {"friction": 0.6}
    if v.get("law") == "hyperbolic":
        material.update(normal_law="hyperbolic", max_closure=1.0e-3)
    if v.get("damping") == "pair":
        material.update(normal_damping="pair")
    solver = {"mode": v["mode"]}
    if v.get("overlap"):
        solver["overlap_reuse"] = 1.0e-7
    doc = {"name": "warm", "scene": {"wall": {"brick": "small", "length": 1, "courses": 2}},
           "material": material, "solver": solver, "loading": {"type": "none"},
           "run": {"duration": 0.01}}
    if v.get("imperfect"):
        doc["imperfections"] = {"bed_unevenness": 1.0e-4, "face_shape": "planar", "seed": 0}
    return parse_case(doc)


def warm(v: dict) -> None:
    """Build variant ``v``'s engine and take one step."""
    from dem.engine import Simulation  # noqa: F401 - first: it imports Taichi (dem.run.build)
    from dem.engine.simulation import Engine
    from dem.run.build import build, case_joint_law, scene_from_case, step_options

    case = case_of(v)
    n = int(v.get("scenes", 1))
    if n == 1 and not v.get("device"):
        engine = build(case).sim.engine  # with solver.overlap_reuse switched on, as a run does
    else:
        scene = scene_from_case(case)
        engine = Engine([scene] * n, case_joint_law(case, scene), step_options(case.solver),
                        device_arrays=bool(v.get("device")))
    engine.advance(1, [_at_rest] * n)


def _at_rest(t):
    """Gravity, no table acceleration (a LoadFn: dem.loading)."""
    return np.tile([0.0, 0.0, -9.81], (len(t), 1)), np.zeros((len(t), 3))


def cache_dir() -> Path | None:
    """Taichi's offline cache directory as ti.init will use it (TI_OFFLINE_CACHE_FILE_PATH,
    else Taichi's default), None where the offline cache is off (TI_OFFLINE_CACHE=0)."""
    if os.environ.get("TI_OFFLINE_CACHE", "") == "0":
        return None
    path = os.environ.get("TI_OFFLINE_CACHE_FILE_PATH")
    if not path:
        import dem  # noqa: F401 - first: it turns Taichi's import banner off

        with warnings.catch_warnings():  # Taichi's import warns (locale) outside pytest's capture
            warnings.simplefilter("ignore")
            from taichi.lang import impl

        path = impl.default_cfg().offline_cache_file_path
    return Path(path)


def fingerprint() -> str:
    """A hash of the kernels' sources, the variants, Taichi's version and the Taichi
    settings read from the environment (``TI_*``, the arch, the thread count: each enters
    the kernels' cache key)."""
    h = hashlib.sha256()
    for entry in SOURCES:
        p = ROOT / entry
        for f in sorted(p.rglob("*.py")) if p.is_dir() else [p]:
            h.update(f.relative_to(ROOT).as_posix().encode())
            h.update(f.read_bytes())
    h.update(repr(VARIANTS).encode())
    h.update(importlib.metadata.version("taichi").encode())
    env = sorted((k, v) for k, v in os.environ.items()
                 if k.startswith(("TI_", "DEM_ARCH", "DEM_TI_", "DEM_THREADS")))
    h.update(repr(env).encode())
    return h.hexdigest()


def _stamp() -> Path | None:
    where = cache_dir()
    return None if where is None else where / STAMP


def needed() -> bool:
    """Whether the warm-up has work to do: the offline cache is on and its stamp is not that
    of the current kernels (:func:`fingerprint`)."""
    stamp = _stamp()
    if stamp is None:
        return False
    try:
        return json.loads(stamp.read_text())["fingerprint"] != fingerprint()
    except (OSError, ValueError, KeyError):
        return True


def reap(p: subprocess.Popen) -> float | None:
    """None while ``p`` runs; else its CPU seconds (user + system, from the kernel's account of
    the ended child: its compiles and Taichi's cache writing at exit included), with
    ``p.returncode`` set."""
    pid, status, usage = os.wait4(p.pid, os.WNOHANG)
    if pid == 0:
        return None
    p.returncode = os.waitstatus_to_exitcode(status)
    return usage.ru_utime + usage.ru_stime


def lanes(parts: int) -> list[list[int]]:
    """The indices of :data:`VARIANTS` shared out into at most ``parts`` lists of about equal
    :data:`COMPILE_CPU_S` (the longest first, each to the lightest list so far), each list in
    the order of :data:`VARIANTS`."""
    out: list[list[int]] = [[] for _ in range(max(1, min(parts, len(VARIANTS))))]
    load = [0.0] * len(out)
    for k in sorted(range(len(VARIANTS)), key=lambda k: -COMPILE_CPU_S[k]):
        j = load.index(min(load))
        out[j].append(k)
        load[j] += COMPILE_CPU_S[k]
    return [sorted(lane) for lane in out if lane]


def run_parts(parts: int) -> tuple[int, float, list[str], float]:
    """Warm every variant, in ``parts`` subprocesses at once, each warming its share
    (:func:`lanes`) one variant after the other (one Python and Taichi start per core, not per
    variant; Taichi writes a subprocess's kernels to its cache when it exits, and a crash loses
    that subprocess's variants only: the workers compile them); returns (variants, wall
    seconds, the last line of each failure, CPU seconds of the subprocesses).  The stamp is
    written when every subprocess succeeded, with each variant's CPU seconds (the first of a
    subprocess with its start) and each subprocess's (its exit, which writes the cache,
    included)."""
    t0 = time.perf_counter()
    env = dict(os.environ, PYTHONPATH=os.pathsep.join(
        [str(ROOT)] + [p for p in os.environ.get("PYTHONPATH", "").split(os.pathsep) if p]))
    running: list = []  # (its variants, process, its log file)
    for lane in lanes(parts):
        log = tempfile.TemporaryFile("w+")  # not a pipe: a long crash report cannot block
        args = [a for k in lane for a in ("--variant", str(k))]
        running.append((lane, subprocess.Popen(
            [sys.executable, "-m", "tests.warm_kernels", *args],
            cwd=ROOT, env=env, stdout=log, stderr=subprocess.STDOUT, text=True), log))
    errors = []
    cpu, per_lane = {}, []
    while running:
        time.sleep(0.2)
        for lane, p, log in list(running):
            seconds = reap(p)
            if seconds is None:
                continue
            running.remove((lane, p, log))
            per_lane.append({"variants": [describe(VARIANTS[k]) for k in lane],
                             "cpu_seconds": round(seconds, 1)})
            log.seek(0)
            out = log.read().strip()
            log.close()
            for line in out.splitlines():
                try:  # main's line of each variant warmed; anything else is not one
                    rec = json.loads(line)
                    cpu[describe(VARIANTS[rec["variant"]])] = rec["cpu_seconds"]
                except (ValueError, KeyError, IndexError, TypeError):
                    continue
            if p.returncode != 0:
                errors.append(out.splitlines()[-1] if out else f"exit {p.returncode}")
    stamp = _stamp()
    if not errors and stamp is not None:
        stamp.parent.mkdir(parents=True, exist_ok=True)
        stamp.write_text(json.dumps({"fingerprint": fingerprint(), "variants": len(VARIANTS),
                                     "cpu_seconds": cpu, "subprocesses": per_lane}, indent=1))
    return len(VARIANTS), time.perf_counter() - t0, errors, \
        sum(r["cpu_seconds"] for r in per_lane)


def main(argv=None) -> int:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--variant", type=int, action="append",
                    help="warm this variant (index into VARIANTS; repeatable); default: all, "
                         "one after the other in this process")
    args = ap.parse_args(argv)
    for k in args.variant if args.variant is not None else range(len(VARIANTS)):
        t0, c0 = time.perf_counter(), time.process_time()
        warm(VARIANTS[k])
        # one JSON line a variant (run_parts reads them): its CPU seconds in this process
        print(json.dumps({"variant": k, "name": describe(VARIANTS[k]),
                          "wall_seconds": round(time.perf_counter() - t0, 1),
                          "cpu_seconds": round(time.process_time() - c0, 1)}), flush=True)
    return 0


if __name__ == "__main__":
    sys.exit(main())
