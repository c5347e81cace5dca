"""A diagnosis experiment as a grid: case variants x frequencies x seeds of one first-prediction
sweep, each run judged by the library's branch and survival verdicts (E1, E3, E5, E6, the survival
points).

An experiment (:class:`Grid`) names the first prediction's sweep whose case it starts from
(``studies.prediction.plan.sweep_case``: the cases/shake file with the frozen imperfect joints of
studies/calibration/frozen.yaml, no VTK), the variants (each a patch of that case's data, merged
key by key: the physical change the hypothesis names, nothing else), the frequencies, the seeds
and the cycles.  Every (variant, seed) runs as one ``dem sweep`` over its unfinished frequencies;
the sweeps go seed by seed across every variant of every grid run together (:func:`run`), so a
session cut short leaves whole seeds.

Each run is judged by ``postprocess.verdicts.response_branch`` (rocking: ds amplification >= 1
and phase of ds behind the table >= 90 deg) and by ``postprocess.survival`` (standing, local
collapse or collapse, from every brick of its frames).  The baseline beside each variant is
the first prediction's committed rows of the same sweep, seeds and frequencies
(results/prediction/<sweep>/points.json: 50 cycles or its cut, the case without the variant's
patch).

Records per grid (committed, resumable): results/diagnosis/<key>/points.json (one row per run,
merged after each sweep; a finished row of the same fingerprint never runs again), cpu.json,
summary.json and branches.png.  Raw runs in runs/diagnosis/<key>/<variant>/ (git-ignored).
"""

from __future__ import annotations

import copy
import hashlib
import json
import time
from dataclasses import dataclass
from pathlib import Path

import numpy as np
import yaml

from dem.case.identity import identity_json
from dem.engine import RESULTS_REVISION
from dem.output.plotting import agg_pyplot
from postprocess.verdicts import BRANCH_AMPLIFICATION, BRANCH_PHASE_DEG, response_branch
from studies.kit import child, session
from studies.kit.provenance import rel, source_state
from studies.kit.records import merge_json, read_json
from studies.prediction.plan import load_frozen, sweep_case
from studies.prediction.points import collect_rows
from studies.prediction.protocol import DEFAULT_FROZEN, ROOT

RESULTS = ROOT / "results" / "diagnosis"
RUNS = ROOT / "runs" / "diagnosis"


@dataclass(frozen=True)
class Variant:
    """One physical change: ``patch`` is merged into the sweep case's data (a dict merges key by
    key, anything else replaces); ``label`` says it in words for the tables."""
    name: str
    label: str
    patch: dict


@dataclass(frozen=True)
class Grid:
    key: str                       # e3, e5 ...: the folder under results/diagnosis and runs/
    title: str
    hypothesis: str
    sweep: str                     # the first prediction's sweep the case comes from
    variants: tuple
    frequencies: tuple             # Hz
    seeds: tuple
    cycles: float

    @property
    def out(self) -> Path:
        return RESULTS / self.key

    @property
    def runs(self) -> Path:
        return RUNS / self.key


def merge_patch(data: dict, patch: dict) -> dict:
    """``data`` with ``patch`` merged in: nested dicts key by key, any other value replaces
    (None included: ``{"loading": {"peak_acceleration": None}}`` clears a field)."""
    out = copy.deepcopy(data)
    for k, v in patch.items():
        if isinstance(v, dict) and isinstance(out.get(k), dict):
            out[k] = merge_patch(out[k], v)
        else:
            out[k] = copy.deepcopy(v)
    return out


def variant_case(grid: Grid, variant: Variant, params: dict):
    """The case of one variant: the sweep's case (frozen joints ``params``, no VTK) patched."""
    from dem.case import Case

    data = merge_patch(sweep_case(grid.sweep, params).model_dump(), variant.patch)
    data["name"] = f"diag-{grid.key}-{variant.name}"
    return Case.model_validate(data)


def fingerprint(grid: Grid, case) -> str:
    """What a finished row must match to count: the case, the plan and the engine's revision."""
    h = hashlib.sha256(identity_json(case).encode())
    h.update(json.dumps([list(grid.frequencies), list(grid.seeds), grid.cycles,
                         RESULTS_REVISION]).encode())
    return h.hexdigest()[:16]


def _key(row: dict) -> tuple:
    return int(row["seed"]), round(float(row["frequency_hz"]), 9)


def finished(points: dict | None, variant: str, fp: str) -> dict:
    """{(seed, f): row} of the finished rows of ``variant`` recorded for fingerprint ``fp``."""
    rec = ((points or {}).get("variants") or {}).get(variant) or {}
    if rec.get("fingerprint") != fp:
        return {}
    return {_key(r): r for r in rec.get("rows", []) if r.get("run_status") == "ok"}


def merge_variant(grid: Grid, variant: Variant, case_file: Path, fp: str) -> dict:
    """Merge the rows of ``variant``'s run directories into points.json (a finished row, fresh
    or committed, wins over a pending one) under its lock."""
    fresh = collect_rows(grid.runs / variant.name, grid.seeds, grid.frequencies)

    def change(data):
        kept = finished(data, variant.name, fp)
        rows = [r if r.get("run_status") == "ok" or _key(r) not in kept else kept[_key(r)]
                for r in fresh]
        data.setdefault("variants", {})[variant.name] = {
            "label": variant.label, "patch": variant.patch, "run_case": rel(case_file),
            "fingerprint": fp, "rows": rows}
        data.update({"kind": f"diagnosis-{grid.key}", "sweep": grid.sweep,
                     "frequencies_hz": list(grid.frequencies), "seeds": list(grid.seeds),
                     "cycles": grid.cycles, "source": source_state()})
    return merge_json(grid.out / "points.json", change)


def prepare(grid: Grid, variant: Variant, frozen: dict) -> tuple[Path, str]:
    """Write the variant's case file (runs/diagnosis/<key>/<variant>.yaml); (its path, the
    fingerprint its rows must carry)."""
    case = variant_case(grid, variant, frozen["parameters"])
    case_file = grid.runs / f"{variant.name}.yaml"
    case_file.parent.mkdir(parents=True, exist_ok=True)
    case_file.write_text(yaml.safe_dump(case.model_dump(mode="json"), sort_keys=False))
    return case_file, fingerprint(grid, case)


def refresh(grid: Grid) -> None:
    """Merge every variant's rows from this machine's run directories into points.json again
    (what a run does after each sweep): a field added to the rows since reaches the finished
    runs whose directories are here; rows whose directories are gone stay as committed."""
    frozen = load_frozen(DEFAULT_FROZEN)
    for variant in grid.variants:
        case_file, fp = prepare(grid, variant, frozen)
        merge_variant(grid, variant, case_file, fp)


def run(grids, workers: int = 1, stop_at: str | None = None, log=print) -> None:
    """Run every unfinished (grid, variant, seed) as one ``dem sweep`` over its unfinished
    frequencies, seed by seed, and within a seed the first variant of every grid, then the
    second ... (E1: one candidate on every model before the next), merging points.json and the
    CPU ledger after each sweep.  Ends softly on the drain file runs/diagnosis/DRAIN, a signal or
    ``stop_at`` (UTC HH:MM)."""
    frozen = load_frozen(DEFAULT_FROZEN)
    drain = session.start(RUNS, log=log)
    order = [(seed, i, grid) for seed in sorted({s for g in grids for s in g.seeds})
             for i in range(max(len(g.variants) for g in grids)) for grid in grids
             if seed in grid.seeds and i < len(grid.variants)]
    for seed, i, grid in order:
        variant = grid.variants[i]
        if session.should_stop(drain, stop_at, log):
            return
        case_file, fp = prepare(grid, variant, frozen)
        done = finished(merge_variant(grid, variant, case_file, fp), variant.name, fp)
        todo = [f for f in grid.frequencies if (seed, round(f, 9)) not in done]
        if not todo:
            continue
        log(f"[{time.strftime('%H:%M:%S', time.gmtime())} UTC] {grid.key.upper()} "
            f"{variant.name} seed {seed}: {', '.join(f'{f:g}' for f in todo)} Hz")
        args = ["sweep", str(case_file), "--out", str(grid.runs / variant.name),
                "--frequencies", ",".join(f"{f:g}" for f in todo),
                "--cycles", f"{grid.cycles:g}", "--realisations", "1",
                "--seed", str(seed), "--workers", str(workers),
                "--drain-file", str(drain)]
        rc, cpu, wall = child.run_dem(args, log)
        session.add_cpu(grid.out / "cpu.json", grid.key, cpu)
        merge_variant(grid, variant, case_file, fp)
        log(f"    exit {rc}, {cpu:.0f} CPU-s, {wall:.0f} s")


# ---- the report ---------------------------------------------------------------------------------
BASELINE = "first prediction"


def baseline_rows(grid: Grid) -> list[dict]:
    """The first prediction's finished rows of the grid's sweep, seeds and frequencies."""
    data = read_json(ROOT / "results" / "prediction" / grid.sweep / "points.json") or {}
    return [r for r in data.get("rows", []) if r.get("run_status") == "ok"
            and r["seed"] in grid.seeds
            and any(abs(r["frequency_hz"] - f) < 1e-9 for f in grid.frequencies)]


def judged(row: dict) -> dict:
    """One run's verdicts: branch, ds, phase (response_branch), lag (s), collapse flag,
    survival, and the instrumented corner bricks' mean twist about z (first harmonic, deg) and
    mean peak-to-peak ds (m) where the row has them."""
    b = response_branch(row)
    mech = row.get("mechanism") or {}
    tw, pp = mech.get("corner_twist_h1_deg"), mech.get("pp_corner_m")
    return {"seed": row["seed"], "frequency_hz": row["frequency_hz"], **b,
            "lag_s": (row.get("lag_s") or {}).get("ds"),
            "collapse_suspected": row.get("collapse_suspected"),
            "survival": (row.get("survival") or {}).get("verdict"),
            "n_fallen": (row.get("survival") or {}).get("n_fallen"),
            "first_fall_cycle": (row.get("survival") or {}).get("first_fall_cycle"),
            "corner_twist_deg": float(np.mean(tw)) if tw else None,
            "corner_pp_m": float(np.mean(list(pp.values()))) if pp else None}


def cells(rows: list[dict]) -> list[dict]:
    """One record per frequency of finished rows: runs, rocking count, median ds and phase, and
    every run's verdicts."""
    by_f = {}
    for r in rows:
        if r.get("run_status") == "ok":
            by_f.setdefault(round(r["frequency_hz"], 9), []).append(judged(r))
    out = []
    for f, js in sorted(by_f.items()):
        ds = [j["ds"] for j in js if j["ds"] is not None]
        ph = [j["phase_deg"] for j in js if j["phase_deg"] is not None]
        out.append({"frequency_hz": f, "runs": len(js),
                    "rocking": sum(j["branch"] == "rocking" for j in js),
                    "collapse_suspected": sum(bool(j["collapse_suspected"]) for j in js),
                    "survival": {v: sum(j["survival"] == v for j in js) for v in
                                 sorted({j["survival"] for j in js if j["survival"]})},
                    "median_ds": float(np.median(ds)) if ds else None,
                    "median_phase_deg": float(np.median(ph)) if ph else None,
                    "seeds": sorted(js, key=lambda j: j["seed"])})
    return out


def plot(grid: Grid, table: dict, path: Path) -> None:
    """ds amplification of every run against frequency, one panel per variant (and the
    baseline): filled markers on the rocking branch, open ones off it; the branch threshold
    dashed."""
    plt = agg_pyplot()

    names = list(table)
    fig, axes = plt.subplots(1, len(names), figsize=(3.2 * len(names), 3.4), sharey=True,
                             squeeze=False)
    for ax, name in zip(axes[0], names):
        for c in table[name]["cells"]:
            for j in c["seeds"]:
                if j["ds"] is None:
                    continue
                rock = j["branch"] == "rocking"
                ax.scatter(c["frequency_hz"] + 0.03 * (j["seed"] - 1), j["ds"], s=28,
                           marker="o", facecolors="C3" if rock else "none",
                           edgecolors="C3" if rock else "C0")
        ax.axhline(BRANCH_AMPLIFICATION, color="0.5", ls="--", lw=0.8)
        ax.set_yscale("log")
        ax.set_xlabel("frequency, Hz")
        ax.set_title(table[name]["label"], fontsize=7, wrap=True)
    axes[0][0].set_ylabel("ds amplification (filled: rocking branch)")
    fig.suptitle(f"{grid.key.upper()}: {grid.title}", fontsize=8)
    fig.tight_layout()
    fig.savefig(path, dpi=120)
    plt.close(fig)


def report(grid: Grid, log=print) -> dict:
    """summary.json and branches.png of ``grid`` from its points.json and the baseline."""
    from dem.output.atomic import write_json

    data = read_json(grid.out / "points.json") or {}
    recs = (data.get("variants") or {})
    table = {BASELINE: {"label": f"{BASELINE} ({grid.sweep}, no change)",
                        "cells": cells(baseline_rows(grid))}}
    done = 0
    for v in grid.variants:
        rows = (recs.get(v.name) or {}).get("rows", [])
        done += sum(r.get("run_status") == "ok" for r in rows)
        table[v.name] = {"label": v.label, "patch": v.patch, "cells": cells(rows)}
    summary = {"experiment": grid.key.upper(), "title": grid.title,
               "hypothesis": grid.hypothesis, "sweep": grid.sweep,
               "frequencies_hz": list(grid.frequencies), "seeds": list(grid.seeds),
               "cycles": grid.cycles, "runs_finished": done,
               "runs_planned": len(grid.variants) * len(grid.frequencies) * len(grid.seeds),
               "branch_rule": {"amplification_min": BRANCH_AMPLIFICATION,
                               "phase_min_deg": BRANCH_PHASE_DEG},
               "variants": table,
               "cpu_seconds": (read_json(grid.out / "cpu.json") or {}).get(grid.key),
               "command": f"python -m studies diagnosis grid {grid.key}"}
    grid.out.mkdir(parents=True, exist_ok=True)
    write_json(grid.out / "summary.json", summary, indent=1)
    if any(t["cells"] for t in table.values()):
        plot(grid, table, grid.out / "branches.png")
    for name, t in table.items():
        line = "; ".join(f"{c['frequency_hz']:g} Hz {c['rocking']}/{c['runs']} rocking, "
                         f"ds {c['median_ds']:.2g}" + (f", {c['survival']}" if c["survival"]
                                                       else "")
                         for c in t["cells"] if c["median_ds"])
        log(f"{grid.key.upper()} {name}: {line or 'no finished run'}")
    log(f"{grid.key.upper()}: {done} of {summary['runs_planned']} runs finished")
    return summary
