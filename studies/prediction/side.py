"""What the studies that run the prediction's cases beside it share (the unevenness and
resonance studies): the check of their common options (--frozen, --seeds, --cycles), the
session loop (drain file, one ``dem sweep --realisations`` child per item, the CPU ledger
``<out>/cpu.json``) and the child run itself."""

from __future__ import annotations

import sys
import time
from pathlib import Path

from studies.kit import child as dem_child
from studies.kit import session, study as kit
from studies.kit.records import read_json
from studies.prediction.plan import frozen_or_none
from studies.prediction.run import write_run_case


def frozen_and_checked(args) -> dict | None:
    """The frozen set, or None after printing why (bad --frozen, --seeds < 1, --cycles <= 0):
    the caller exits 2."""
    frozen = frozen_or_none(args.frozen)
    if frozen is not None and (args.seeds < 1 or not args.cycles > 0):
        print("error: --seeds must be >= 1 and --cycles > 0", file=sys.stderr)
        return None
    return frozen


def run_items(out: Path, items, run_one) -> tuple[dict, list[int]]:
    """Run ``run_one(item, drain) -> (exit code, CPU s)`` for each item (a key of the CPU
    ledger) until a stop signal or the drain file ``<out>/runs/DRAIN``; the CPU seconds added to
    ``<out>/cpu.json`` under its lock after each.  Returns (the ledger, the exit codes)."""
    runs, cpu_path = Path(out) / "runs", Path(out) / "cpu.json"
    cpu, codes = read_json(cpu_path) or {}, []
    if items:
        drain = session.start(runs)
        for item in items:
            if session.should_stop(drain):
                break
            rc, c = run_one(item, drain)
            codes.append(rc)
            cpu = session.add_cpu(cpu_path, item, c)
    return cpu, codes


def sweep_realisations(runs: Path, name: str, case, freqs, cycles: float, seeds: int, log=print,
                       drain_file: Path | None = None) -> tuple[int, float]:
    """The studies that run the prediction's cases beside it (unevenness, resonance): the case
    written to ``<runs>/<name>.yaml`` (:func:`write_run_case`), then one child
    ``dem sweep ... --out <runs>/<name> --frequencies F --cycles C --realisations N --seed 0
    --workers 1`` (seeds 0 .. N-1; ``drain_file`` handed on).  Returns (exit code, CPU s of the
    child's process tree)."""
    case_file = write_run_case(runs, name, case)
    fs = ",".join(f"{f:g}" for f in freqs)
    args = kit.sweep_args(case_file, Path(runs) / name, freqs, cycles, 0, workers=1,
                          drain=drain_file, realisations=seeds)
    log(f"[{time.strftime('%H:%M:%S', time.gmtime())} UTC] {name}: {seeds} realisations at "
        f"{fs.replace(',', ', ')} Hz, {cycles:g} cycles ...")
    rc, cpu, _ = dem_child.run_dem(args, log)
    return rc, cpu
