"""E4: is the thesis' input just short of the DEM's rocking branch?

Hypothesis: at the thesis' 1.53 m/s2 the DEM's Model II y sits on its quasi-static branch
(results/prediction: ds amplification 0.1-0.2, phase 7-13 deg at 2.4-3.2 Hz) only because the
input is a little too weak; slightly stronger shaking would put it on the rocking branch
(ds 3.3-3.5, phase 127-147 deg) that the thesis' lags point to.

Experiment: Model II y (cases/shake/model-ii/group-3-y-1.53.yaml) with the frozen joints of the
first prediction (studies/calibration/frozen.yaml: planar beds, 0.1 mm unevenness), at
FREQUENCIES x ACCELERATIONS (constant peak table acceleration, m/s2) x SEEDS, CYCLES cycles each
(+ dem sweep's 1 s margin); every run judged by postprocess.verdicts.response_branch.  The onset
acceleration at a frequency is the lowest level at which at least ONSET_SEEDS of the seeds are
on the rocking branch, bracketed by the level below it.  The first prediction's 1.53 m/s2 runs of
the same seeds (50 cycles) are drawn beside them for context, not counted in the onset.

Ruled in if the onset lies within ~1.5 x the thesis' 1.53 m/s2 at the thesis' characteristic
frequency 2.8 Hz (the thesis' own table accelerations scatter by about that much between groups);
ruled out if it lies far above.

Records (committed, resumable): results/diagnosis/e4/points.json (one row per run, merged after
each ``dem sweep``; a finished row of the same fingerprint is never run again), cpu.json,
summary.json, threshold.png.  Raw runs in runs/diagnosis/e4/ (git-ignored).
"""

from __future__ import annotations

from pathlib import Path

import numpy as np

from dem.output.plotting import agg_pyplot
from postprocess.verdicts import BRANCH_AMPLIFICATION, BRANCH_PHASE_DEG, response_branch
from studies.kit import study as kit
from studies.kit.records import read_json
from studies.prediction.plan import load_frozen, sweep_case
from studies.prediction.points import collect_rows
from studies.prediction.protocol import DEFAULT_FROZEN

SWEEP = "model-ii-y"
FREQUENCIES = (2.4, 2.8, 3.2)          # Hz: the thesis' effective range of Model II y
ACCELERATIONS = (1.9, 2.3, 3.0)        # m/s2, peak: ~1.25, 1.5, 2 x the thesis' 1.53
SEEDS = (0, 1, 2)
CYCLES = 10
ONSET_SEEDS = 2                         # of 3: a majority on the rocking branch
THESIS_ACCELERATION = 1.53              # m/s2, group 3 (the first prediction's level)
OUT = kit.results_dir("diagnosis", "e4")
RUNS = kit.runs_dir("diagnosis", "e4")
PREDICTION_POINTS = kit.records_path(kit.results_dir("prediction", SWEEP))


def level_name(accel: float) -> str:
    return f"a{accel:.2f}"


def level_case(params: dict, accel: float):
    """The case of one acceleration level: the prediction's Model II y case (frozen joints, no
    VTK) at peak table acceleration ``accel`` (m/s2)."""
    from dem.case import Case

    data = sweep_case(SWEEP, params).model_dump()
    data["name"] = f"diag-e4-{level_name(accel)}"
    data["loading"]["peak_acceleration"] = float(accel)
    data["loading"]["amplitude"] = None
    return Case.model_validate(data)


def fingerprint(case) -> str:
    """What a finished row must match to count: the case, the plan and the engine's revision."""
    return kit.fingerprint(case, *PLAN)


#: what besides a level's case its fingerprint covers
PLAN = (list(FREQUENCIES), list(SEEDS), CYCLES)


def point(accel: float, frozen: dict, seed: int | None = None) -> kit.Point:
    """The kit's point of one acceleration level (m/s2), and seed, with the frozen joints."""
    return kit.Point(name=level_name(accel), case=level_case(frozen["parameters"], accel),
                     plan=PLAN, out=OUT, runs=RUNS, ledger="e4", seed=seed, owner=accel)


def finished(points: dict | None, level: str, fp: str) -> dict:
    """{(seed, f): row} of the finished rows of ``level`` recorded for fingerprint ``fp``."""
    return kit.finished_rows(points, "levels", level, fp)


def merge_level(p: kit.Point) -> dict:
    """Merge the rows of the level's run directories into points.json (a finished row, fresh or
    committed, wins over a pending one) under its lock."""
    return kit.merge_rows(p, "levels", collect_rows(p.run_dir, SEEDS, FREQUENCIES),
                          entry={"peak_acceleration_m_s2": p.owner},
                          top={"kind": "diagnosis-e4", "frequencies_hz": list(FREQUENCIES),
                               "seeds": list(SEEDS), "cycles": CYCLES},
                          row_fields={"peak_acceleration_m_s2": p.owner})


class E4(kit.Study):
    """Every (seed, level) one ``dem sweep`` over its unfinished frequencies, seed by seed (so
    that a cut session leaves whole seeds of the map)."""
    runs = RUNS

    def __init__(self, workers: int = 1):
        self.workers = workers

    def points(self):
        frozen = load_frozen(DEFAULT_FROZEN)
        for seed in SEEDS:
            for accel in ACCELERATIONS:
                yield point(accel, frozen, seed)

    def todo(self, p):
        done = finished(merge_level(p), p.name, p.fingerprint)
        return [f for f in FREQUENCIES if (p.seed, round(f, 9)) not in done]

    def describe(self, p, todo):
        return f"E4 seed {p.seed}, {p.owner:g} m/s2: {', '.join(f'{f:g}' for f in todo)} Hz"

    def command(self, p, todo, drain):
        return kit.sweep_args(p.case_file, p.run_dir, todo, CYCLES, p.seed, self.workers,
                              drain=drain)

    def record(self, p, result, log=print):
        merge_level(p)


def run(workers: int = 1, stop_at: str | None = None, log=print) -> None:
    """Run every unfinished (seed, level) as one ``dem sweep`` over its unfinished frequencies,
    seed by seed (so that a cut session leaves whole seeds of the map), merging points.json and
    the CPU ledger after each."""
    kit.run(E4(workers), stop_at, log)


# ---- the report ---------------------------------------------------------------------------------
def context_rows() -> list[dict]:
    """The first prediction's rows of SEEDS at FREQUENCIES and 1.53 m/s2 (50 cycles)."""
    data = read_json(PREDICTION_POINTS) or {}
    return [dict(r, peak_acceleration_m_s2=THESIS_ACCELERATION) for r in data.get("rows", [])
            if r.get("run_status") == "ok" and r["seed"] in SEEDS
            and any(abs(r["frequency_hz"] - f) < 1e-9 for f in FREQUENCIES)]


def cells(rows: list[dict]) -> list[dict]:
    """One record per (acceleration, frequency): runs, branches, median ds and phase."""
    out = {}
    for r in rows:
        if r.get("run_status") != "ok":
            continue
        k = (r["peak_acceleration_m_s2"], round(r["frequency_hz"], 9))
        out.setdefault(k, []).append(response_branch(r))
    recs = []
    for (a, f), bs in sorted(out.items()):
        ds = [b["ds"] for b in bs if b["ds"] is not None]
        ph = [b["phase_deg"] for b in bs if b["phase_deg"] is not None]
        recs.append({"peak_acceleration_m_s2": a, "frequency_hz": f, "runs": len(bs),
                     "rocking": sum(b["branch"] == "rocking" for b in bs),
                     "between": sum(b["branch"] == "between" for b in bs),
                     "median_ds": float(np.median(ds)) if ds else None,
                     "median_phase_deg": float(np.median(ph)) if ph else None})
    return recs


def onsets(recs: list[dict]) -> dict:
    """Per frequency: the lowest E4 level with >= ONSET_SEEDS rocking runs and the level below
    it, or the reason there is none (not reached, or levels still unrun)."""
    out = {}
    for f in FREQUENCIES:
        by_a = {r["peak_acceleration_m_s2"]: r for r in recs
                if abs(r["frequency_hz"] - f) < 1e-9 and r["peak_acceleration_m_s2"] in
                ACCELERATIONS}
        below, found, unknown = None, None, []
        for a in ACCELERATIONS:
            r = by_a.get(a)
            if r is None or (r["runs"] < ONSET_SEEDS and r["rocking"] < ONSET_SEEDS):
                unknown.append(a)
                continue
            if r["rocking"] >= ONSET_SEEDS:
                found = a
                break
            below = a
        if found is not None and not unknown:
            out[f"{f:g}"] = {"onset_m_s2": found, "above_m_s2": below,
                             "text": f"between {below:g} and {found:g} m/s2" if below else
                             f"at or below {found:g} m/s2 (the lowest level)"}
        elif found is not None:
            out[f"{f:g}"] = {"onset_m_s2": found, "above_m_s2": None,
                             "text": f"at or below {found:g} m/s2 (levels {unknown} not run)"}
        elif unknown:
            out[f"{f:g}"] = {"onset_m_s2": None, "above_m_s2": below,
                             "text": f"pending (levels {unknown} not run)" +
                             (f"; above {below:g} m/s2" if below else "")}
        else:
            out[f"{f:g}"] = {"onset_m_s2": None, "above_m_s2": below,
                             "text": f"not reached: above {below:g} m/s2"}
    return out


def plot(recs: list[dict], path: Path) -> None:
    """The threshold map: each (frequency, acceleration) cell coloured by its share of seeds on
    the rocking branch, labelled with the median ds amplification and phase."""
    plt = agg_pyplot()

    fig, ax = plt.subplots(figsize=(6.4, 4.6))
    for r in recs:
        share = r["rocking"] / r["runs"]
        ctx = r["peak_acceleration_m_s2"] == THESIS_ACCELERATION
        ax.scatter(r["frequency_hz"], r["peak_acceleration_m_s2"], s=900, marker="s",
                   c=[[share, 0.2, 1 - share]], alpha=0.5 if ctx else 0.9, edgecolors="k")
        ax.annotate(f"{r['rocking']}/{r['runs']}\nds {r['median_ds']:.2g}\n"
                    f"{r['median_phase_deg']:.0f} deg",
                    (r["frequency_hz"], r["peak_acceleration_m_s2"]), ha="center", va="center",
                    fontsize=7)
    ax.axhline(THESIS_ACCELERATION, color="0.5", ls="--", lw=0.8)
    ax.text(FREQUENCIES[0] - 0.25, THESIS_ACCELERATION + 0.05, "thesis 1.53 m/s2 (first "
            "prediction, 50 cycles)", fontsize=7, color="0.3")
    ax.set_xlim(FREQUENCIES[0] - 0.3, FREQUENCIES[-1] + 0.3)
    ax.set_ylim(THESIS_ACCELERATION - 0.35, ACCELERATIONS[-1] + 0.35)
    ax.set_xlabel("frequency, Hz")
    ax.set_ylabel("peak table acceleration, m/s$^2$")
    ax.set_title(f"E4, Model II y: seeds on the rocking branch (ds >= {BRANCH_AMPLIFICATION:g}, "
                 f"phase >= {BRANCH_PHASE_DEG:g} deg)", fontsize=8)
    fig.tight_layout()
    fig.savefig(path, dpi=120)
    plt.close(fig)


def report(log=print) -> dict:
    """summary.json and threshold.png from points.json (and the first prediction's context)."""
    from dem.output.atomic import write_json

    data = kit.records(OUT)
    rows = [r for lv in (data.get("levels") or {}).values() for r in lv.get("rows", [])]
    recs = cells(rows + context_rows())
    done = sum(r.get("run_status") == "ok" for r in rows)
    summary = {"experiment": "E4", "hypothesis": "the input is just short of the rocking branch",
               "runs_finished": done,
               "runs_planned": len(FREQUENCIES) * len(ACCELERATIONS) * len(SEEDS),
               "branch_rule": {"amplification_min": BRANCH_AMPLIFICATION,
                               "phase_min_deg": BRANCH_PHASE_DEG},
               "cells": recs, "onset": onsets(recs),
               "cpu_seconds": (read_json(OUT / "cpu.json") or {}).get("e4"),
               "command": "python -m studies diagnosis e4"}
    OUT.mkdir(parents=True, exist_ok=True)
    write_json(OUT / "summary.json", summary, indent=1)
    if recs:
        plot(recs, OUT / "threshold.png")
    for f, o in summary["onset"].items():
        log(f"E4 {f} Hz: onset {o['text']}")
    log(f"E4: {done} of {summary['runs_planned']} runs finished")
    return summary
