"""Wall-clock of the two-body rocking model (dem.rocking): medians of several runs.

    python benchmarks/rocking_speed.py [--repeat 5] [--convergence]

* a 50-cycle run that rocks all the way (Model II parts, no top load, 2.8 Hz at 1.84 m/s2 =
  1.16 x the uplift threshold: ~105 impacts) - integration alone and through the full
  ``dem rocking`` runner (validation, outputs, no plots);
* a thesis case (Model II, Table 5.2, 2.8 Hz): it stays at rest, so it costs almost nothing;
* a 20-frequency sweep (1.5 - 6 Hz, 50 cycles each, same model at 1.84 m/s2);
* ``--convergence``: event times against a reference run (rtol 1e-12, max step T/200), for the
  choice of the default max step and tolerance.
"""

from __future__ import annotations

import argparse
import math
import statistics
import tempfile
import time
from pathlib import Path

import numpy as np

from dem_cli.commands.rocking import run_rocking_case_file
from dem.rocking.integrate import Settings, integrate_rocking
from dem.rocking.params import RockingParams
from dem.rocking.sweep import sweep
from dem.table_motion import SineMotion

ROOT = Path(__file__).resolve().parents[1]
P_N0 = RockingParams(thickness=0.05, h1=0.14, m1=6.05, h2=0.14, m2=9.41)
PEAK, F = 1.84, 2.8


def timed(fn, repeat):
    out = []
    for _ in range(repeat):
        t0 = time.perf_counter()
        fn()
        out.append(time.perf_counter() - t0)
    return statistics.median(out), min(out), max(out)


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    ap.add_argument("--repeat", type=int, default=5)
    ap.add_argument("--convergence", action="store_true")
    args = ap.parse_args()
    exc = SineMotion(PEAK / (2 * math.pi * F) ** 2, F, 50)
    S = Settings(duration=50 / F)
    res = integrate_rocking(P_N0, exc, S)
    print(f"50-cycle rocking run: {len(res.events)} events, "
          f"{res.stats['impacts_base'] + res.stats['impacts_interface']} impacts, status {res.status}")
    med, lo, hi = timed(lambda: integrate_rocking(P_N0, exc, S), args.repeat)
    print(f"  integration only          median {med:.3f} s  (min {lo:.3f}, max {hi:.3f}, n={args.repeat})")
    case = ROOT / "cases" / "rocking" / "extra-model-ii-n0-2.8hz-1.84.yaml"
    with tempfile.TemporaryDirectory() as tmp:
        med, lo, hi = timed(lambda: run_rocking_case_file(case, tmp, plots=False, echo=lambda *_: None),
                            args.repeat)
    print(f"  dem rocking runner        median {med:.3f} s  (min {lo:.3f}, max {hi:.3f}; validation, "
          "rocking.npz, summary.json, no plots)")
    thesis = ROOT / "cases" / "rocking" / "model-ii-2.8hz.yaml"
    with tempfile.TemporaryDirectory() as tmp:
        med, lo, hi = timed(lambda: run_rocking_case_file(thesis, tmp, plots=False, echo=lambda *_: None),
                            args.repeat)
    print(f"thesis case model-ii-2.8hz (stays at rest): runner median {med:.3f} s")
    freqs = np.linspace(1.5, 6.0, 20)
    rep = max(1, args.repeat // 2)
    med, lo, hi = timed(lambda: sweep(P_N0, freqs, peak_acceleration=PEAK), rep)
    rows = sweep(P_N0, freqs, peak_acceleration=PEAK)
    n_col = sum(r["status"] == "collapsed" for r in rows)
    print(f"20-frequency sweep (1.5-6 Hz, 50 cycles, {PEAK} m/s2): median {med:.2f} s "
          f"(min {lo:.2f}, max {hi:.2f}, n={rep}); {n_col} of 20 runs collapse")
    if args.convergence:
        ref = integrate_rocking(P_N0, exc, Settings(duration=50 / F, rtol=1e-12, atol=1e-14,
                                           max_step_fraction=1 / 200))
        tr = np.array([e["t"] for e in ref.events])
        print("convergence (same 50-cycle run): max |event time - reference| over all events")
        print("  method  rtol    max_step  events  max dt (s)   wall (s)")
        for method in ("DOP853", "RK45"):
            for rtol in (1e-8, 1e-10):
                for frac in (1 / 8, 1 / 16, 1 / 32):
                    St = Settings(duration=50 / F, method=method, rtol=rtol, atol=rtol * 1e-2,
                                  max_step_fraction=frac)
                    r = integrate_rocking(P_N0, exc, St)
                    te = np.array([e["t"] for e in r.events])
                    n = min(len(te), len(tr))
                    err = np.max(np.abs(te[:n] - tr[:n])) if len(te) == len(tr) else math.inf
                    print(f"  {method:6s}  {rtol:.0e}  T/{round(1 / frac):<3d}     {len(te):4d}    "
                          f"{err:.2e}     {r.wall_seconds:.3f}")


if __name__ == "__main__":
    main()
