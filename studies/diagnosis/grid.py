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
summary.json and branches.png.  Raw runs in runs/diagnosis/<key>/<variant>/ (git-ignored).  A
grid of another study names its own folders (``Grid.results_dir``, ``Grid.runs_dir``).  The
paths, fingerprint, records and resumable loop are the study kit's (studies.kit.study).
"""

from __future__ import annotations

import copy
from dataclasses import dataclass
from pathlib import Path

import numpy as np

from dem.output.plotting import agg_pyplot
from postprocess.verdicts import BRANCH_AMPLIFICATION, BRANCH_PHASE_DEG, response_branch
from studies.kit import study as kit
from studies.kit.records import read_json
from studies.prediction.plan import load_frozen, sweep_case
from studies.prediction.points import collect_rows
from studies.prediction.protocol import DEFAULT_FROZEN

RESULTS = kit.results_dir("diagnosis")
RUNS = kit.runs_dir("diagnosis")


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
    #: where the records (``<results_dir>/<key>/``) and the raw runs (``<runs_dir>/<key>/``)
    #: go: another study's folders for a grid of its own (None: results/diagnosis, runs/diagnosis)
    results_dir: Path | None = None
    runs_dir: Path | None = None
    #: the study command whose ``grid`` subcommand runs it (the report's regenerating command)
    study: str = "diagnosis"

    @property
    def out(self) -> Path:
        return Path(self.results_dir if self.results_dir is not None else RESULTS) / self.key

    @property
    def runs(self) -> Path:
        return Path(self.runs_dir if self.runs_dir is not None else RUNS) / self.key


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
    return kit.fingerprint(case, list(grid.frequencies), list(grid.seeds), grid.cycles)


def point(grid: Grid, variant: Variant, frozen: dict, seed: int | None = None) -> kit.Point:
    """The kit's point of one variant (and seed) of ``grid`` with the frozen joints
    ``frozen``."""
    return kit.Point(name=variant.name, case=variant_case(grid, variant, frozen["parameters"]),
                     plan=(list(grid.frequencies), list(grid.seeds), grid.cycles),
                     out=grid.out, runs=grid.runs, ledger=grid.key, seed=seed,
                     owner=(grid, variant))


def finished(points: dict | None, variant: str, fp: str) -> dict:
    """{(seed, f): row} of the finished rows of ``variant`` recorded for fingerprint ``fp``."""
    return kit.finished_rows(points, "variants", variant, fp)


def merge_variant(p: kit.Point) -> dict:
    """Merge the rows of the variant's run directories into points.json (a finished row, fresh
    or committed, wins over a pending one) under its lock."""
    grid, variant = p.owner
    return kit.merge_rows(
        p, "variants", collect_rows(p.run_dir, grid.seeds, grid.frequencies),
        entry={"label": variant.label, "patch": variant.patch},
        top={"kind": f"diagnosis-{grid.key}", "sweep": grid.sweep,
             "frequencies_hz": list(grid.frequencies), "seeds": list(grid.seeds),
             "cycles": grid.cycles})


def refresh(grid: Grid) -> None:
    """Merge every variant's rows from this machine's run directories into points.json again
    (what a run does after each sweep): a field added to the rows since reaches the finished
    runs whose directories are here; rows whose directories are gone stay as committed."""
    frozen = load_frozen(DEFAULT_FROZEN)
    for variant in grid.variants:
        p = point(grid, variant, frozen)
        kit.write_case(p.case, p.case_file)
        merge_variant(p)


class GridStudy(kit.Study):
    """Grids run together on the kit's loop: every (grid, variant, seed) one ``dem sweep`` over
    its unfinished frequencies."""

    def __init__(self, grids, workers: int = 1):
        self.grids, self.workers = list(grids), workers
        first = self.grids[0].runs_dir
        self.runs = Path(first) if first is not None else RUNS   # where the drain file is

    def points(self):
        """Seed by seed, and within a seed the first variant of every grid, then the second."""
        frozen = load_frozen(DEFAULT_FROZEN)
        grids = self.grids
        for seed in sorted({s for g in grids for s in g.seeds}):
            for i in range(max(len(g.variants) for g in grids)):
                for grid in grids:
                    if seed in grid.seeds and i < len(grid.variants):
                        yield point(grid, grid.variants[i], frozen, seed)

    def todo(self, p):
        done = finished(merge_variant(p), p.name, p.fingerprint)
        return [f for f in p.owner[0].frequencies if (p.seed, round(f, 9)) not in done]

    def describe(self, p, todo):
        return (f"{p.owner[0].key.upper()} {p.name} seed {p.seed}: "
                f"{', '.join(f'{f:g}' for f in todo)} Hz")

    def command(self, p, todo, drain):
        return kit.sweep_args(p.case_file, p.run_dir, todo, p.owner[0].cycles, p.seed,
                              self.workers, drain=drain)

    def record(self, p, result, log=print):
        merge_variant(p)


def run(grids, workers: int = 1, stop_at: str | None = None, log=print) -> None:
    """Run every unfinished (grid, variant, seed) as one ``dem sweep`` over its unfinished
    frequencies, seed by seed, and within a seed the first variant of every grid, then the
    second ... (E1: one candidate on every model before the next), merging points.json and the
    CPU ledger after each sweep.  Ends softly on the drain file DRAIN in the first grid's
    ``runs_dir`` (default runs/diagnosis/DRAIN), a signal or ``stop_at`` (UTC HH:MM)."""
    kit.run(GridStudy(grids, workers), stop_at, log)


# ---- the report ---------------------------------------------------------------------------------
BASELINE = "first prediction"


def baseline_rows(grid: Grid) -> list[dict]:
    """The first prediction's finished rows of the grid's sweep, seeds and frequencies."""
    data = kit.records(kit.results_dir("prediction", grid.sweep))
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

    data = kit.records(grid.out)
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
               "command": f"python -m studies {grid.study} grid {grid.key}"}
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
