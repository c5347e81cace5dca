"""What a checkpoint costs (dem.run.write: every CHECKPOINT_SECONDS of wall time a run rewrites
frames.npz whole, and restart.npz where it can resume, dem.run.resume), at the size both reach at
the end of the prediction's longest run, set against the time between checkpoints.

    python benchmarks/checkpoint_cost.py [--case cases/shake/model-ii/group-3-y-1.53.yaml]
                                         [--duration 29.8] [--repeats 5] [--batch 1,16,64]

The case's scene is built (dem.run.build.build) and its recording filled as a run of
``--duration`` s would leave it (frames every run.output_interval, instrument samples every
run.instrument_interval: the 50-cycle 1.8 Hz Model II run, 27.8 s + 1 s margin + settling ~
29.8 s, gives ~1490 frames and ~14 900 samples; the frames are the built state with random
perturbations, which compress as little as a real run's: Model II at 2.8 Hz, 944 frames, 21.3 MB
raw, 20.0 MB compressed).
Then, --repeats times, interleaved: frames.npz written compressed (np.savez_compressed, as
before 2026-11-26) and plain (np.savez, now), and the restart point built and written (wall
clock through dem.output.atomic: fsync and rename; median and largest).  Prints sizes, times and
each one's share of the run's wall time at one checkpoint per CHECKPOINT_SECONDS.  The run
itself is not timed: the shares are what a checkpoint takes from the stepping, which stops
while it writes.  Then, for batches of K such runs in one engine (``--batch``: the engine stops
while each point writes its own files), a round's time (K x the plain frames' and the restart
point's medians) and its share of the wall time, every CHECKPOINT_SECONDS and at the interval
dem.run.write.CheckpointPace sets (at most CHECKPOINT_SHARE).
"""

from __future__ import annotations

import argparse
import statistics
import sys
import tempfile
import time
from pathlib import Path

import numpy as np

ROOT = Path(__file__).resolve().parents[1]
sys.path.insert(0, str(ROOT))


def main(argv=None) -> int:
    ap = argparse.ArgumentParser(description=__doc__,
                                 formatter_class=argparse.RawDescriptionHelpFormatter)
    ap.add_argument("--case", default=str(ROOT / "cases/shake/model-ii/group-3-y-1.53.yaml"))
    ap.add_argument("--duration", type=float, default=29.8)
    ap.add_argument("--repeats", type=int, default=5)
    ap.add_argument("--batch", default="1,16,64", help="the batch sizes K of the last table")
    args = ap.parse_args(argv)

    from dem.case import load_case
    from dem.output import atomic
    from dem.run.build import build
    from dem.run.record import Recording
    from dem.run.resume import RESTART_FILE, restart_arrays, write_restart
    from dem.run.write import CHECKPOINT_SECONDS, CheckpointPace, initial_summary

    case = load_case(args.case)
    built = build(case)
    sim, st = built.sim, built.sim.state
    n_frames = int(args.duration / case.run.output_interval) + 1
    n_samples = int(args.duration / case.run.instrument_interval) + 1
    times = {"frames.npz compressed (before)": [], "frames.npz plain (now)": [],
             "restart.npz (build + write)": []}
    sizes = {}
    with tempfile.TemporaryDirectory() as tmp:
        out = Path(tmp)
        rec = Recording(case, built.scene, built.loading, sim, out)
        rng = np.random.default_rng(0)
        for _ in range(n_frames):  # moving blocks: mantissas that do not compress, as a run's
            rec.frames.add(0.0, st.pos + 1e-4 * rng.standard_normal(st.pos.shape),
                           st.quat + 1e-5 * rng.standard_normal(st.quat.shape),
                           1e-3 * rng.standard_normal(st.vel.shape),
                           1e-2 * rng.standard_normal(st.omega.shape), np.zeros(3))
        if rec.instruments is not None:
            for k in range(n_samples):
                rec.instruments.sample(k * case.run.instrument_interval, st.pos, st.quat, st.vel,
                                       st.omega, np.zeros(3), np.zeros(3))
        summary = initial_summary(case, built.scene, built.loading, sim)
        for _ in range(args.repeats):
            for name, compressed in (("frames.npz compressed (before)", True),
                                     ("frames.npz plain (now)", False)):
                t0 = time.perf_counter()
                atomic.save_npz(out / "frames.npz", rec.frames.arrays(), compressed=compressed)
                times[name].append(time.perf_counter() - t0)
                sizes[name] = (out / "frames.npz").stat().st_size
            t0 = time.perf_counter()
            write_restart(out, restart_arrays(case, sim, rec, summary))
            times["restart.npz (build + write)"].append(time.perf_counter() - t0)
            sizes["restart.npz (build + write)"] = (out / RESTART_FILE).stat().st_size
    print(f"case {args.case}: {built.scene.n_blocks} blocks, {n_frames} frames, "
          f"{n_samples if rec.instruments is not None else 0} instrument samples "
          f"({args.duration:g} s of run)")
    print(f"| file | size (MB) | median (ms) | largest (ms) | share of the wall time at one "
          f"checkpoint per {CHECKPOINT_SECONDS:g} s |")
    print("|---|---|---|---|---|")
    for name, ts in times.items():
        med = statistics.median(ts)
        print(f"| {name} | {sizes[name] / 1e6:.1f} | {med * 1e3:.0f} | {max(ts) * 1e3:.0f} | "
              f"{100 * med / CHECKPOINT_SECONDS:.2f} % |")
    point = statistics.median(times["frames.npz plain (now)"]) + \
        statistics.median(times["restart.npz (build + write)"])
    print(f"\n| points K | a round (s) | share every {CHECKPOINT_SECONDS:g} s | paced interval (s) "
          f"| paced share |")
    print("|---|---|---|---|---|")
    for k in (int(x) for x in args.batch.split(",")):
        pace = CheckpointPace()
        for g in range(k):
            pace.record(g, point)
        every = pace.interval()
        print(f"| {k} | {k * point:.2f} | {100 * k * point / CHECKPOINT_SECONDS:.1f} % | "
              f"{every:.0f} | {100 * k * point / every:.1f} % |")
    return 0


if __name__ == "__main__":
    sys.exit(main())
