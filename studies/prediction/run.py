"""Running one sweep of the plan: one ``dem sweep`` child per seed over the frequencies it has not
finished, points.json merged after each, the first-N-cycles analyses kept as points finish.
"""

from __future__ import annotations

import time
from pathlib import Path

from studies.kit import child as dem_child
from studies.kit import study as kit
from studies.kit.records import read_json
from studies.prediction.cycles import record_truncated
from studies.prediction.plan import fingerprint, sweep_case, sweep_cycles
from studies.prediction.points import (collect_rows, finished_rows, point_key, points_path,
                                       sweep_finished, update_points)


def write_run_case(runs: Path, name: str, case) -> Path:
    """``<runs>/<sweep>.yaml``: the sweep's case as dem sweep reads it (also point_pool's)."""
    return kit.write_case(case, Path(runs) / f"{name}.yaml")


def run_sweep_point(out: Path, runs: Path, name: str, plan: dict, workers: int | None = None,
                    log=print, drain_file: Path | None = None, only_seeds=None,
                    only_freqs=None) -> str:
    """Run (or skip) one sweep of the plan: "skipped" (finished before), "finished", "pending"
    (interrupted, drained or a run failed) or "failed" (dem sweep refused the case).

    One ``dem sweep --realisations 1 --seed S --frequencies F`` per seed S, F the frequencies
    of S that the committed points.json does not hold finished (:func:`finished_rows`), and
    points.json merged after each (:func:`update_points`).  ``only_seeds`` / ``only_freqs``
    restrict this call to a subset of the plan's seeds / frequencies (to share a sweep between
    processes or machines; the plan and fingerprint do not change).  ``drain_file``: handed to
    dem sweep (once it exists no new run starts, and no further seed)."""
    case = sweep_case(name, plan["frozen"]["parameters"])
    freqs, seeds = plan["sweeps"][name]["frequencies_hz"], plan["seeds"]
    cycles = sweep_cycles(plan, name)
    fp = fingerprint(case, freqs, seeds, cycles, plan["max_steps"])
    dest = points_path(out, name)
    if sweep_finished(read_json(dest), fp):
        return "skipped"
    sweep_dir = Path(runs) / name
    case_file = write_run_case(runs, name, case)
    my_seeds = [s for s in seeds if only_seeds is None or s in set(only_seeds)]
    my_freqs = [f for f in freqs if only_freqs is None or
                any(abs(f - g) < 1e-9 for g in only_freqs)]
    log(f"[{time.strftime('%H:%M:%S', time.gmtime())} UTC] {name}: {len(my_freqs)} of "
        f"{len(freqs)} frequencies x {len(my_seeds)} of {len(seeds)} realisations, "
        f"{cycles:g} cycles ...")
    # what this machine's run directories hold, merged, before anything runs
    data = update_points(dest, name, plan, case, case_file, fp,
                         collect_rows(sweep_dir, seeds, freqs), 0.0, 0.0, None, True)
    record_truncated(out, runs, name, fp, log)
    cpu_all, refused = 0.0, False
    for s in my_seeds:
        if dem_child.stopped() or (drain_file is not None and drain_file.exists()):
            break
        done = finished_rows(data, fp)
        todo = [f for f in my_freqs if point_key(s, f) not in done]
        if not todo:
            continue
        args = kit.sweep_args(case_file, sweep_dir, todo, cycles, s, workers, plan["max_steps"],
                              drain_file)
        log(f"[{time.strftime('%H:%M:%S', time.gmtime())} UTC] {name} seed {s}: "
            f"{', '.join(f'{f:g}' for f in todo)} Hz")
        rc, cpu, wall = dem_child.run_dem(args, log)
        cpu_all += cpu
        fresh = collect_rows(sweep_dir, seeds, freqs)
        if rc == 2 and not any(r["run_status"] != "pending" for r in fresh
                               if r["seed"] == s):
            log(f"    dem sweep exit {rc}: refused the case")
            refused = True
            break
        data = update_points(dest, name, plan, case, case_file, fp, fresh, cpu, wall, rc,
                             False)
        record_truncated(out, runs, name, fp, log)
        if rc != 0 and (dem_child.stopped() or
                        (drain_file is not None and drain_file.exists())):
            break
    if refused:
        return "failed"
    state = "finished" if data["prediction"]["finished"] else "pending"
    log(f"    -> {state}: {cpu_all:.0f} CPU-s this call")
    return state
