"""E2: do two branches coexist, and were the laboratory's tests on the upper one?

Hypothesis: at the thesis' level the DEM has both a quiet (quasi-static) and a rocking branch
inside 2.4-3.2 Hz; a specimen started from rest lands on the quiet one (the first prediction,
E4 below 1.9 m/s2), one already rocking stays on the rocking one.  The thesis' specimens went
through stepped frequencies on one build (thesis lines 722, 1051-1071), so they may have carried
a rocking response from one step into the next.

Experiment: one specimen per (model, seed), the first prediction's case (frozen imperfect joints
of seed k, its table level: Model II y 1.53 m/s2, Model III y 1.23 m/s2) shaken as one
``stepped_shake`` (dem.case.SteppedShakeLoading: no settling between steps, the velocity
continuous) starting where the DEM rocks from rest, 4.4 Hz (results/prediction, resonance
search: the jump lies above 3.6 Hz at 1.53 m/s2), stepped DOWN through 4.0, 3.6, 3.2, 2.8, 2.4,
2.0 Hz, then UP again through 2.4 ... 4.4 Hz, CYCLES_PER_STEP cycles a step.  Each step is
analysed as a shake of its own (postprocess.stepped) and judged by the library's branch verdict
(postprocess.verdicts.response_branch), and the specimen by the library's survival verdict
(postprocess.survival): a step by whose end a brick had fallen is the response of a ruin, and
only intact steps count.

Ruled in if a specimen rocking at 4.4 Hz keeps rocking down into 2.4-3.2 Hz where the same
specimen from rest does not (the first prediction's rows of the same seeds); ruled out if the
rocking ends above 3.2 Hz going down, as it starts going up.

Records (committed, resumable): results/diagnosis/e2/points.json (one record per specimen, each
step's frequency, pass, ds amplification, phase and branch; a finished specimen of the same
fingerprint never runs again; an unfinished run continues from its restart point, ``dem run
--resume``), cpu.json, summary.json, passes.png.  Raw runs in runs/diagnosis/e2/ (git-ignored).
"""

from __future__ import annotations

from pathlib import Path

import numpy as np

from dem.output.plotting import agg_pyplot
from postprocess.verdicts import BRANCH_AMPLIFICATION, BRANCH_PHASE_DEG, response_branch
from studies.kit import study as kit
from studies.kit.provenance import rel, source_state
from studies.kit.records import merge_json, read_json
from studies.prediction.plan import load_frozen, sweep_case
from studies.prediction.protocol import DEFAULT_FROZEN

DOWN = (4.4, 4.0, 3.6, 3.2, 2.8, 2.4, 2.0)       # Hz, then back up (UP)
UP = (2.4, 2.8, 3.2, 3.6, 4.0, 4.4)
CYCLES_PER_STEP = 15
SWEEPS = ("model-ii-y", "model-iii-y")
SEEDS = (0, 1, 2)
MARGIN_S = 1.0                                    # free motion after the last step, as dem sweep
OUT = kit.results_dir("diagnosis", "e2")
RUNS = kit.runs_dir("diagnosis", "e2")


def steps() -> list[dict]:
    return [{"frequency": f, "cycles": CYCLES_PER_STEP} for f in DOWN + UP]


def specimen_name(sweep: str, seed: int) -> str:
    return f"{sweep}-seed-{seed}"


def specimen_case(sweep: str, seed: int, params: dict):
    """The first prediction's case of ``sweep`` (frozen joints of ``seed``, its direction and
    level, no VTK) with the stepped table motion of this experiment."""
    from dem.case import Case

    data = sweep_case(sweep, params).model_dump()
    ld = data["loading"]
    data["name"] = f"diag-e2-{specimen_name(sweep, seed)}"
    data["imperfections"]["seed"] = int(seed)
    data["loading"] = {"type": "stepped_shake", "direction": ld["direction"],
                       "peak_acceleration": ld.get("peak_acceleration"),
                       "amplitude": None if ld.get("peak_acceleration") else ld.get("amplitude"),
                       "steps": steps()}
    data["run"]["duration"] = sum(s["cycles"] / s["frequency"] for s in steps()) + MARGIN_S
    return Case.model_validate(data)


def fingerprint(case) -> str:
    """What a finished specimen must match: its case (the steps in it) and the engine's
    revision."""
    return kit.fingerprint(case)


def step_rows(analysis: dict, fall_times=()) -> list[dict]:
    """One row per step of postprocess.stepped's result: frequency, pass, times, ds
    amplification, lag, the branch verdict, and ``fallen_by_end``: how many bricks had fallen
    (postprocess.survival) by the step's end, of the fall times ``fall_times`` (s).  A step
    with bricks down is the response of a ruin (the instrumented brick may be among them), not
    of the model: :func:`report` reads the branch of intact steps only."""
    falls = np.sort(np.asarray(list(fall_times), float))
    rows = []
    for st in analysis.get("steps", []):
        lag = (st.get("lag") or {}).get("ds") or {}
        row = {"frequency_hz": st["frequency_hz"], "pass": st["pass"],
               "t_start_s": st["t_start_s"], "t_end_s": st.get("t_end_s"),
               "amplification": {"ds": (st.get("amplification") or {}).get("ds")},
               "lag_s": {"ds": lag.get("s") if isinstance(lag, dict) else None},
               "fallen_by_end": int(np.searchsorted(falls, st.get("t_end_s", np.inf),
                                                    side="right"))}
        row.update({k: v for k, v in response_branch(row).items() if k != "ds"})
        rows.append(row)
    return rows


def survival_record(run_dir: Path) -> tuple[dict, list[float]]:
    """postprocess.survival's verdict of a finished specimen (compact) and every fall time."""
    from postprocess.survival import compact, survival_of_run

    full = survival_of_run(run_dir)
    rec = compact(full)
    return {k: rec[k] for k in ("verdict", "n_fallen", "first_fall_time_s", "by_wall")}, \
        [f["time_s"] for f in full["fallen"]]


def record(name: str, sweep: str, seed: int, case_file: Path, fp: str, status: str,
           analysis: dict | None, survival: dict | None = None, fall_times=()) -> dict:
    def change(data):
        data.setdefault("specimens", {})[name] = {
            "sweep": sweep, "seed": seed, "run_case": rel(case_file), "fingerprint": fp,
            "run_status": status, "survival": survival,
            "steps": step_rows(analysis, fall_times) if analysis else []}
        data.update({"kind": "diagnosis-e2", "down_hz": list(DOWN), "up_hz": list(UP),
                     "cycles_per_step": CYCLES_PER_STEP, "source": source_state()})
    return merge_json(kit.records_path(OUT), change)


class E2(kit.Study):
    """Every unfinished specimen, seed by seed across the sweeps: ``dem run --resume`` (a killed
    run continues from its restart point), then the stepped analysis, recorded after each."""

    def __init__(self, sweeps=SWEEPS, seeds=SEEDS):
        self.sweeps, self.seeds, self.runs = sweeps, seeds, RUNS

    def points(self):
        frozen = load_frozen(DEFAULT_FROZEN)
        for seed in self.seeds:
            for sweep in self.sweeps:
                yield kit.Point(name=specimen_name(sweep, seed),
                                case=specimen_case(sweep, seed, frozen["parameters"]), plan=(),
                                out=OUT, runs=RUNS, ledger="e2", seed=seed, owner=sweep)

    def todo(self, p):
        """What is left: "run", "analyse" (a finished run recorded before its survival was) or
        nothing."""
        rec = (kit.records(OUT).get("specimens") or {}).get(p.name)
        done = rec and rec.get("fingerprint") == p.fingerprint and rec.get("run_status") == "ok"
        if done and rec.get("survival"):
            return None
        return "analyse" if done else "run"

    def describe(self, p, todo):
        return (f"E2 {p.name}: {len(steps())} steps, {p.case.run.duration:.1f} s"
                if todo == "run" else None)

    def command(self, p, todo, drain):
        return (["run", str(p.case_file), "--out", str(p.run_dir), "--resume", "--no-progress"]
                if todo == "run" else None)

    def record(self, p, result, log=print):
        from postprocess.stepped import analyze_stepped_run

        summary = read_json(p.run_dir / "summary.json") or {}
        status = summary.get("status", "unknown")
        analysis, surv, falls = None, None, []
        if status == "ok":
            analysis = analyze_stepped_run(p.run_dir)
            surv, falls = survival_record(p.run_dir)
        record(p.name, p.owner, p.seed, p.case_file, p.fingerprint, status, analysis, surv,
               falls)
        log(f"    {p.name}: {status}" + (f", {surv['verdict']} ({surv['n_fallen']} bricks "
                                        f"down)" if surv else ""))


def run(sweeps=SWEEPS, seeds=SEEDS, stop_at: str | None = None, log=print) -> None:
    """Run every unfinished specimen, seed by seed across ``sweeps``: ``dem run --resume`` (a
    killed run continues), then the stepped analysis, recorded after each."""
    kit.run(E2(sweeps, seeds), stop_at, log)


# ---- the report ---------------------------------------------------------------------------------
def from_rest(sweep: str, seeds) -> dict:
    """{f: [branch verdicts]} of the first prediction's rows of ``sweep`` and ``seeds`` (each
    run started from rest at its own frequency)."""
    data = kit.records(kit.results_dir("prediction", sweep))
    out = {}
    for r in data.get("rows", []):
        if r.get("run_status") == "ok" and r["seed"] in seeds:
            out.setdefault(round(r["frequency_hz"], 9), []).append(response_branch(r))
    return out


SEED_STYLES = ("-", "-.", ":")  # the line of seed 0, 1, 2 (then again)


def plot(specimens: dict, path: Path) -> None:
    """ds amplification against frequency, the down (red) and the up (blue) pass of each
    specimen as lines, one line style per seed (filled markers: rocking branch), the first
    prediction's from-rest medians dashed black."""
    plt = agg_pyplot()

    sweeps = sorted({s["sweep"] for s in specimens.values()})
    fig, axes = plt.subplots(1, len(sweeps), figsize=(4.6 * len(sweeps), 3.8), squeeze=False)
    for ax, sweep in zip(axes[0], sweeps):
        for name, s in sorted(specimens.items()):
            if s["sweep"] != sweep:
                continue
            for pas, color in (("down", "C3"), ("up", "C0")):
                pts = [r for r in s["steps"] if r["pass"] == pas and r["amplification"]["ds"]]
                if not pts:
                    continue
                f = [r["frequency_hz"] for r in pts]
                a = [r["amplification"]["ds"] for r in pts]
                ax.plot(f, a, SEED_STYLES[s["seed"] % len(SEED_STYLES)], color=color, lw=1,
                        alpha=0.7, label=f"seed {s['seed']} {pas}")
                for r in pts:
                    rock = r.get("branch") == "rocking"
                    if r.get("fallen_by_end", 0) > 0:     # a ruin's response: a cross
                        ax.scatter(r["frequency_hz"], r["amplification"]["ds"], s=30,
                                   marker="x", color=color)
                        continue
                    ax.scatter(r["frequency_hz"], r["amplification"]["ds"], s=24,
                               facecolors=color if rock else "none", edgecolors=color)
        rest = from_rest(sweep, SEEDS)
        fr = sorted(rest)
        med = [np.median([b["ds"] for b in rest[f] if b["ds"] is not None]) for f in fr]
        ax.plot(fr, med, "k--", lw=0.8, label="from rest (first prediction)")
        ax.axhline(BRANCH_AMPLIFICATION, color="0.5", ls=":", lw=0.8)
        ax.set_yscale("log")
        ax.set_xlabel("frequency, Hz")
        ax.set_ylabel("ds amplification (filled: rocking; x: bricks down)")
        ax.set_title(sweep, fontsize=8)
        ax.legend(fontsize=6)
    fig.suptitle(f"E2: stepped down from 4.4 Hz and up again, {CYCLES_PER_STEP} cycles a step",
                 fontsize=8)
    fig.tight_layout()
    fig.savefig(path, dpi=120)
    plt.close(fig)


def report(log=print) -> dict:
    from dem.output.atomic import write_json

    data = kit.records(OUT)
    specimens = {n: s for n, s in (data.get("specimens") or {}).items()
                 if s.get("run_status") == "ok"}
    verdicts = {}
    for name, s in sorted(specimens.items()):
        rest = from_rest(s["sweep"], [s["seed"]])
        intact = [r for r in s["steps"] if r.get("fallen_by_end", 0) == 0]
        rocking_down = [r["frequency_hz"] for r in intact if r["pass"] == "down"
                        and r.get("branch") == "rocking"]
        rocking_up = [r["frequency_hz"] for r in intact if r["pass"] == "up"
                      and r.get("branch") == "rocking"]
        rest_rocking = sorted(f for f, bs in rest.items()
                              if any(b["branch"] == "rocking" for b in bs))
        ruined = [(r["frequency_hz"], r["pass"]) for r in s["steps"]
                  if r.get("fallen_by_end", 0) > 0]
        surv = s.get("survival") or {}
        verdicts[name] = {
            "rocking_going_down_hz": rocking_down, "rocking_going_up_hz": rocking_up,
            "lowest_rocking_down_hz": min(rocking_down) if rocking_down else None,
            "lowest_rocking_up_hz": min(rocking_up) if rocking_up else None,
            "from_rest_rocking_hz": rest_rocking,
            "steps_with_bricks_down": ruined, "survival": surv.get("verdict"),
            "first_fall_time_s": surv.get("first_fall_time_s")}
        log(f"E2 {name}: intact steps rocking going down at {rocking_down or 'none'} Hz, going "
            f"up at {rocking_up or 'none'} Hz; from rest (first prediction) at "
            f"{rest_rocking or 'none of its frequencies'}; {surv.get('verdict')}, first brick "
            f"down at t = {surv.get('first_fall_time_s')} s, {len(ruined)} steps with bricks "
            f"down")
    summary = {"experiment": "E2", "hypothesis": "two branches coexist; the tests were on the "
               "upper one", "down_hz": list(DOWN), "up_hz": list(UP),
               "cycles_per_step": CYCLES_PER_STEP,
               "specimens_finished": len(specimens),
               "specimens_planned": len(SWEEPS) * len(SEEDS),
               "branch_rule": {"amplification_min": BRANCH_AMPLIFICATION,
                               "phase_min_deg": BRANCH_PHASE_DEG},
               "specimens": specimens, "verdicts": verdicts,
               "cpu_seconds": (read_json(OUT / "cpu.json") or {}).get("e2"),
               "command": "python -m studies diagnosis e2"}
    OUT.mkdir(parents=True, exist_ok=True)
    write_json(OUT / "summary.json", summary, indent=1)
    if specimens:
        plot(specimens, OUT / "passes.png")
    log(f"E2: {len(specimens)} of {summary['specimens_planned']} specimens finished")
    return summary
