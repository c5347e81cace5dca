"""Frequency sweeps of the two-block model at a fixed peak acceleration or amplitude.

Each frequency is an independent run of ``cycles`` cycles of u(t) = A sin(2 pi f t); the result
per frequency is a small dict (status, steady amplitudes of the top displacement, pattern
statistics, impact count).  Sequential on purpose: one run takes a fraction of a second.
"""

from __future__ import annotations

import math

import numpy as np

from dem.rocking import analysis as an
from dem.rocking.integrate import RockingError, Settings, integrate_rocking
from dem.rocking.params import RockingParams
from dem.table_motion import SineMotion


def sweep(P: RockingParams, frequencies, peak_acceleration: float | None = None,
          amplitude: float | None = None, cycles: float = 50, settings: dict | None = None,
          free_time: float = 0.0) -> list[dict]:
    """Run the model at each frequency (Hz); give ``peak_acceleration`` (m/s2) or ``amplitude`` (m)."""
    if (peak_acceleration is None) == (amplitude is None):
        raise ValueError("give exactly one of peak_acceleration or amplitude")
    rows = []
    for f in frequencies:
        A = amplitude if amplitude is not None else peak_acceleration / (2 * math.pi * f) ** 2
        exc = SineMotion(A, f, cycles)
        S = Settings(duration=cycles / f + free_time, **(settings or {}))
        try:
            res = integrate_rocking(P, exc, S)
            err = ""
        except RockingError as e:
            res, err = e.partial, str(e)
        d = an.top_displacement(P, res.theta1, res.theta2)
        ci, cmax, cmin = an.cycle_amplitudes(res.t, d, exc.period, exc.t_end)
        stats, _ = an.pattern_statistics(res.episodes, float(res.t[-1]) if len(res.t) else 0.0)
        steady = ci >= (cycles / 2) if len(ci) else ci
        rows.append({
            "frequency": float(f), "amplitude": A, "peak_acceleration": exc.peak_acceleration,
            "status": res.status, "error": err,
            "t_end": float(res.t[-1]) if len(res.t) else 0.0,
            "amp_pos": float(np.mean(cmax[steady])) if res.status == "ok" and np.any(steady) else math.nan,
            "amp_neg": float(np.mean(cmin[steady])) if res.status == "ok" and np.any(steady) else math.nan,
            "max_abs_disp": float(np.abs(d).max()) if len(d) else 0.0,
            "impacts": res.stats["impacts_base"] + res.stats["impacts_interface"],
            "patterns": {k: v["time_fraction"] for k, v in stats.items()},
            "occurrences": {k: v["occurrences"] for k, v in stats.items()},
            "wall_seconds": res.wall_seconds,
        })
    return rows
