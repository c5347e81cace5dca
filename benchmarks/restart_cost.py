"""What a restart point costs (dem.run.resume): building restart.npz and writing it, at the size
it reaches at the end of the prediction's longest run, against the time between checkpoints.

    python benchmarks/restart_cost.py [--case cases/shake/model-ii/group-3-y-1.53.yaml]
                                      [--samples 14400] [--repeats 7]

The case's scene is built (dem.run.build.build) and the recording of its instruments filled with
``--samples`` samples (the 50-cycle 1.8 Hz Model II run: 28.8 s at run.instrument_interval
2 ms = 14 400); then, --repeats times, restart_arrays (the engine's snapshot and the recording)
and write_restart (uncompressed, atomic: fsync and rename) are timed (wall clock, median and
largest), the file's size printed, and the median set against CHECKPOINT_SECONDS: the share of a
run's wall time that restart points take.  frames.npz, written at the same checkpoints before
restart points existed, is not part of this cost.
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
    ap.add_argument("--samples", type=int, default=14400)
    ap.add_argument("--repeats", type=int, default=7)
    args = ap.parse_args(argv)

    from dem.case import load_case
    from dem.run.build import build
    from dem.run.record import Recording
    from dem.run.resume import restart_arrays, write_restart
    from dem.run.write import CHECKPOINT_SECONDS, initial_summary

    case = load_case(args.case)
    built = build(case)
    sim = built.sim
    with tempfile.TemporaryDirectory() as tmp:
        out = Path(tmp)
        rec = Recording(case, built.scene, built.loading, sim, out)
        if rec.instruments is None:
            print(f"{args.case}: no instruments; timing the engine's snapshot alone")
        else:
            st = sim.state
            for k in range(args.samples):  # the state does not move: the sizes are what count
                rec.instruments.sample(k * case.run.instrument_interval, st.pos, st.quat, st.vel,
                                       st.omega, np.zeros(3), np.zeros(3))
        summary = initial_summary(case, built.scene, built.loading, sim)
        build_s, write_s = [], []
        for _ in range(args.repeats):
            t0 = time.perf_counter()
            arrays = restart_arrays(case, sim, rec, summary)
            t1 = time.perf_counter()
            write_restart(out, arrays)
            t2 = time.perf_counter()
            build_s.append(t1 - t0)
            write_s.append(t2 - t1)
        size = (out / "restart.npz").stat().st_size
    total = [a + b for a, b in zip(build_s, write_s)]
    med = statistics.median(total)
    print(f"case {args.case}: {built.scene.n_blocks} blocks, {sim.contacts.capacity} pair slots, "
          f"{args.samples} instrument samples")
    print(f"restart.npz {size / 1e6:.1f} MB; build {statistics.median(build_s) * 1e3:.0f} ms, "
          f"write {statistics.median(write_s) * 1e3:.0f} ms (medians of {args.repeats}); "
          f"total median {med * 1e3:.0f} ms, largest {max(total) * 1e3:.0f} ms")
    print(f"share of the run's wall time at one restart point per {CHECKPOINT_SECONDS:g} s: "
          f"{100 * med / CHECKPOINT_SECONDS:.2f} %")
    return 0


if __name__ == "__main__":
    sys.exit(main())
