"""Blind prediction of the Chapter 4 shaking-table tests with the frozen imperfection set
(issue 13, steps 3-5).

    python -m postprocess.prediction_study --frozen cases/calibration/frozen.yaml \\
        --out results/prediction                      # run (Model II y first), then report
    python -m postprocess.prediction_study --frozen cases/calibration/frozen.yaml \\
        --out results/prediction --only model-ii-y --realisations 10 --cycles 50
    python -m postprocess.prediction_study --frozen cases/calibration/frozen.yaml \\
        --out results/prediction --report             # report from the committed points.json
    python -m postprocess.prediction_study --frozen cases/calibration/frozen.yaml \\
        --out results/prediction --only model-ii-y --cycles-check 10   # 10 against 50 cycles

The protocol (issue 13: calibrate -> freeze -> predict, in this order in the git history).

* The frozen set (:func:`load_frozen`) is a YAML file under ``cases/`` with an ``imperfections:``
  mapping (the fields of docs/imperfections.md except ``seed``: ``bed_unevenness`` (m),
  ``face_shape``, ``size_scatter`` ([m, m, m]), ``arris`` (m)) and provenance fields
  (``derived_in``: where the derivation is written, e.g. results/calibration/README.md;
  ``candidate``: its name among cases/calibration/candidates.yaml; ``note``).  Nothing else:
  friction and joint stiffness are not parameters (they stay the case files' measured /
  physical values), and there is one set for every model (no per-model sections).  The study
  refuses to start (exit 2, the message names the problem) when the file is missing, is not
  such a mapping, is not tracked by git or differs from its last commit; the commit that last
  changed it (``git log -1 --format=%H -- FILE``, "the commit that froze it") goes into every
  output.
* The prediction points are shake_study's sweeps (postprocess.shake_study.SWEEPS: the case files
  of cases/shake/ and the Appendix I / Chapter 4 frequencies, imported, not copied), all but the
  amplified one (a raised excitation is context, not a prediction): Model II y first, then II x,
  II diagonal, I y, I x, III y (:data:`ORDER`).  Each case gets ``imperfections:`` = the frozen
  set and nothing else changes.  ``--cycles`` (default 50, the thesis') cycles after settling,
  N = ``--realisations`` (default 10) realisations per frequency with seeds 0 .. N-1, the same
  for every sweep and frequency.  The plan (``<out>/plan.json``: frozen set, freezing commit,
  seeds, sweeps, frequencies, cycles) is written before the first run; a later call with
  another frozen commit, parameter set, seeds or cycles refuses (exit 2) rather than mixing.
* One sweep = one ``dem sweep CASE --realisations 1 --seed S --frequencies F`` per seed S
  (dem.commands.sweep) in a child process with DEM_THREADS=1, F the frequencies of S that the
  committed ``<out>/<sweep>/points.json`` does not already hold finished for the same
  fingerprint (case, seeds, frequencies, cycles, step cap, engine results revision); its raw
  runs under ``--runs`` (default ``<out>/runs/``, git-ignored by ``results/*/runs/``).
  points.json is merged after every seed (:func:`update_points`, under a lock): a point
  finished in an earlier session counts even where its run directory is gone (a new
  checkout, another machine) and never runs again; ``dem sweep`` itself skips every point whose
  run directory holds a finished run, so an interrupted seed resumes.  A sweep whose
  points.json holds every (seed, frequency) finished is skipped without starting anything.
  ``--seeds`` / ``--frequencies`` restrict a call to a subset (the plan does not change), to
  share a sweep between processes or machines; postprocess.point_pool runs chosen points in a
  process pool without dask (a borrowed many-core machine), into the same run directories,
  from which the next call here merges them.  The child's CPU seconds (user + system of its
  process tree) add up over sessions in points.json (a point_pool machine's are not in it:
  its record says what they were).  A call works seed by seed, so with ``--workers 2`` the
  last run of a seed runs alone; two calls side by side, each ``--workers 1`` on its own
  ``--seeds``, keep both cores busy (as on 2026-11-26).
* Ending a session: ``touch <runs>/DRAIN`` (``--drain-file``) lets the runs in flight finish,
  starts no new one and writes the report (dem.batch, "Draining"); SIGTERM (or the end of a
  session) stops at once, and the runs in flight keep their last restart point (every 30 s
  after settling): the next call resumes them where their run directories are still there
  (dem.run.resume).
* points.json is the committed analysis record of a sweep: one row per (seed, frequency) with
  the numbers of the point's analysis.json (postprocess.shake via postprocess.sweep.compact):
  amplification of ds, dsr, da, a (unfiltered), a_lp (low-passed, below), a_front, a_front_lp,
  da_front (the front facade's centre accelerometer), a's amplification at each cutoff of the
  low-pass sensitivity (``a_lowpass``), the first-harmonic ratio and dominant frequency of ds,
  lags of ds and dsr (s), the excited portion, collapse_suspected, the mechanism labels.
* ``<out>/summary.json`` and ``<out>/README.md`` (:func:`report`): per sweep the predicted
  characteristic frequency (the rule of postprocess.sweep.effective_range on the median curve
  over the surviving realisations; null with the reason when the peak is at the edge of the
  sweep or not clear), the effective range, amplification of ds inside and outside (median and
  10-90 % over the realisations), lag inside, excited bricks, survival rate, CPU time; the
  criteria of issue 13 step 4 (:func:`criteria`) and the false-success checks of step 5
  (:func:`false_success_checks`), each pass / fail / pending; beside them, not criteria, the
  acceleration table, the front / back table and the cycles checks (below).

Thesis numbers: ../shared/REFERENCE.md, "Shaking-table tests (Chapter 4)" (characteristic
frequencies, effective ranges, amplifications, lags, excited portions; Appendix I groups and
peak accelerations) and issue 13's table of success criteria.  Units: Hz, s, m, m/s2; the
amplifications are dimensionless (thesis Section 4.2.5: steady-state peak-to-peak of the
response over that of the excitation of the same kind).

Shown, not scored (none is one of issue 13's criteria):

* The acceleration low-passed like an instrument's (issue 13 step 4).  The DEM's accelerometer
  is ideal (500 Hz samples of a rigid brick, every impact spike kept: an amplification of a of
  6-8 on Model II where the tests read ~2); the thesis gives no sampling rate or filter for its
  accelerometers.  ``a_lp`` is ``a`` through an ASSUMED instrument: a 4-pole Butterworth at
  20 Hz run forward and backward (postprocess.shake_signals.lowpass, LOWPASS_HZ; >= 5 harmonics
  of the highest test frequency, 3.6 Hz).  The answer depends on the cutoff (Model II y, 0.2 mm
  planar beds, 2.8 Hz, 10 cycles: raw 6.29; 50 / 20 / 10 Hz: 4.64 / 3.15 / 2.65), so the report
  gives a's amplification inside the thesis' range raw and at 10, 20 and 50 Hz
  (:func:`acceleration_inside`, from each point's ``a_lowpass_sensitivity``: no rerun).
* Front / back facades (thesis Section 4.3.4, Tables 4.9 - 4.11: front / back 0.359 Model II y,
  0.618 II x, 0.587 III y, constant over frequency).  The front facade carried only its centre
  accelerometer (A5), so the thesis' front amplification is an accelerometer quantity, a or da
  (it does not say which); here da_front / da (the headline: no impact spikes, no assumed
  cutoff) and a_front_lp / a_lp per row, then per-seed means inside the range
  (:func:`front_back_inside`) and the median ratio per frequency.  The DEM's box model is
  symmetric front to back but for the imperfections' draws and the excitation's sign.
* Fewer cycles (issue 13 step 3: "show that the cut does not change the answer").  The table's
  sine (dem.table_motion) has no ramp-in or taper, the settle phase of an imperfect scene ends
  before the clock starts and does not depend on the duration, and the run loop's steps differ
  only at the run's end: an N-cycle run is the first N cycles of a longer one.  Measured: the
  frames and instruments of Model II y (0.2 mm planar beds, seed 0, 2.8 Hz) for 2 and 4 cycles
  equal, bit for bit, the first 2 and 4 cycles of a 4- and a 10-cycle run (separate launches;
  tests/test_shake_truncation.py on a small settling wall).  So ``--cycles-check N``
  re-analyses the finished runs of a sweep over their first N cycles
  (postprocess.shake.analyze_run(cycles=N): no simulation) and compares with the full cycles
  (:func:`cycles_verdict`, rule CYCLES_RULE): characteristic frequency, ds amplification inside
  and outside, survival.  The analyses of the first N cycles for N in TRUNCATED_CYCLES are made
  as the points finish, while their raw runs exist (:func:`record_truncated`; a point_pool
  machine makes them beside its runs), and committed in ``<out>/<sweep>/truncated.json``, so
  that the check does not depend on raw runs surviving between sessions.  Both sides use the
  same runs: those with a kept analysis or a raw run (frames.npz) here; a finished point with
  neither (seed 0 of Model II y, whose runs were lost with a machine before this existed) is
  left out of both and named (``left_out_no_raw_run``), and the README gives the runs compared
  out of the sweep's finished ones.  The analysis of the first N cycles matches that of an N-cycle run to
  2e-5 in ds (the jittered samples' resampling grid spans the record), a_lp to 3e-4, da to 2-3 %
  at 2-4 cycles (the drift-free integral's fit and running mean at the record's end) and raw a
  to ~5 % (the spikes' peaks move with the grid).  ``<out>/<sweep>/cycles-check-<N>.json``
  (committed) holds the rows and the verdict.
* The cut itself (``--cut-cycles N --only SWEEPS``): the sweeps named, not yet planned and not
  Model II y, are planned at N cycles, and only once Model II y finished at the plan's cycles
  and its cycles-check-N.json, made from the finished sweep, says the answer is unchanged
  (:func:`cut_record`).  The plan records the cut per sweep with that file and its verdict; a
  planned sweep's cycles never change; the false-success check on the excitation names every
  cut and fails one without its record.  Survival is then over N cycles, which the report says.
"""

from __future__ import annotations

import argparse
import contextlib
import fcntl
import hashlib
import json
import math
import subprocess
import sys
import time
from pathlib import Path

import numpy as np
import yaml

from dem.engine import RESULTS_REVISION
from postprocess import dem_child
from postprocess.ensemble import statistics
from postprocess.shake_signals import LOWPASS_HZ, LOWPASS_ORDER, LOWPASS_SENSITIVITY_HZ
from postprocess.shake_study import CASES, SWEEPS
from postprocess.sweep import effective_range

ROOT = Path(__file__).resolve().parents[1]
DEFAULT_FROZEN = ROOT / "cases" / "calibration" / "frozen.yaml"
DEFAULT_CYCLES = 50          # thesis: 50 cycles per test (REFERENCE.md, Excitation)
DEFAULT_REALISATIONS = 10    # issue 13 step 3: at least 10 realisations per frequency
PARAM_KEYS = ("bed_unevenness", "face_shape", "size_scatter", "arris")
PROVENANCE_KEYS = ("derived_in", "candidate", "note", "frozen_on")
#: the order of the study: Model II y in full first (issue 13 step 3)
ORDER = ("model-ii-y", "model-ii-x", "model-ii-xy", "model-i-y", "model-i-x", "model-iii-y")
EXCITATION_CHECK = ("excitation as in the thesis (Appendix I peak accelerations, 50 cycles, or "
                    "fewer where shown not to change the answer)")
FULL_SWEEP = ORDER[0]        # run in full; its cycles check is what may justify a cut elsewhere
CHAPTER3_CHECK = "chapter3-check/check.json"  # under --out: postprocess.chapter3_check's record
MEASURED_FRICTION = 0.81     # small bricks, thesis Tables 3.1-3.2 (REFERENCE.md, Bricks)
SURVIVAL_MIN = 0.8           # issue 13: at least 80 % of the realisations survive
FC_TOL_HZ = 0.3              # characteristic frequency within +-0.3 Hz
AMP_FACTOR = 1.5             # amplification inside the range within x 1.5
AMP_RATIO_MIN = 3.0          # inside / outside > 3 for Model II
LAG_TOL_S = 0.05             # lag inside the range within +-0.05 s
EXCITED_REL_TOL = 0.2        # excited bricks within +-20 %
COURSES_TOL = 1              # excited courses within +-1
# rocking, not drift or a sliding ratchet (step 5; the harness' thresholds, not thesis values):
H1_SHARE_MIN = 0.5    # the first harmonic at f carries >= half of the ds peak-to-peak
DA_REL_TOL = 0.25     # da agrees with the table + ds phasor sum within 25 % (or DA_ABS_TOL)
DA_ABS_TOL = 0.1
DSR_SHARE_MIN = 0.2   # the facade centre moves relative to its corners (a rigid slide reads 0)
DOMINANT_REL_TOL = 0.05  # the dominant frequency of ds is f within 5 %
#: the amplifications a row keeps (postprocess.shake_signals: a_lp, a_front_lp the assumed
#: instrument low-pass; a_front, da_front the front facade's centre accelerometer)
ROW_QUANTITIES = ("ds", "dsr", "da", "a", "a_lp", "a_front", "a_front_lp", "da_front")
#: front / back amplification ratios: (front, back) quantities; da first (the headline: the
#: accelerometer-derived displacement, free of impact spikes and of the assumed cutoff)
FRONT_BACK = {"da": ("da_front", "da"), "a_lp": ("a_front_lp", "a_lp")}
CYCLES_REL_FLOOR = 0.1   # cycles check: medians agree within max(band width, 10 % of median)
TRUNCATED_CYCLES = (10, 20, 25, 30)   # cycles analyses kept as the points finish
LEFT_OUT = "left out"    # cycles check: a finished row whose raw run is not on this machine
NO_RAW_RUN = "no raw run on this machine: left out of both sides of the cycles check"
CYCLES_RULE = (
    "the answer at N cycles is unchanged from the full cycles when (1) the characteristic "
    "frequency is the same within one frequency step (both null, or at most one position apart "
    "in the sweep's sorted frequencies), (2) the medians of the ds amplification inside and "
    "outside the thesis' range agree within max(10-90 % band width at the full cycles, "
    f"{CYCLES_REL_FLOOR:g} x its median), and (3) the survival verdict (lowest survival rate "
    f">= {SURVIVAL_MIN:g}) is the same; the same runs, their first N cycles analysed as an "
    "N-cycle run (no new simulation)")

#: thesis numbers per sweep (../shared/REFERENCE.md, Chapter 4; issue 13 step 4).  peak_acc:
#: Appendix I constant peak accelerations (m/s2; the diagonal: 1.08 per axis); fc (Hz); range
#: [lo, hi] Hz (None: the text gives none); amp_in / amp_out: ds amplification inside / outside;
#: lag_in / lag_out (s); excited bricks and courses from the top.  Model I x: the thesis says only
#: "narrower" for its range, so "inside the thesis range" is its characteristic frequency alone;
#: the diagonal: no characteristic frequency in 1.7-3.6 Hz (the response grows up to 3.6 Hz).
THESIS = {
    "model-i-y": {"peak_acc": 1.53, "fc": 2.0, "range": [1.8, 2.5], "lag_in": 0.18,
                  "lag_out": 0.02, "courses": 8},
    "model-i-x": {"peak_acc": 1.71, "fc": 1.9, "range": None, "lag_in": 0.08, "lag_out": 0.06,
                  "courses": 6},
    "model-ii-y": {"peak_acc": 1.53, "fc": 2.8, "range": [2.4, 3.2], "amp_in": 2.0,
                   "amp_out_max": 0.5, "lag_in": 0.13, "lag_out": 0.03, "excited": 46,
                   "courses": 8, "a_in": 2.0, "front_back": 0.359},
    "model-ii-x": {"peak_acc": 1.71, "fc": 2.8, "range": [2.4, 2.8], "lag_in": 0.13,
                   "lag_out": 0.06, "excited": 50, "courses": 7, "front_back": 0.618},
    "model-ii-xy": {"peak_acc": 1.08, "fc": None, "fc_note": "> 3.6 Hz: the response grows up to "
                    "3.6 Hz, the highest frequency tested", "range": None},
    "model-iii-y": {"peak_acc": 1.23, "fc": 2.4, "range": [2.4, 2.5], "amp_in": 3.5,
                    "amp_out": 2.0, "excited": 62, "courses": 11, "front_back": 0.587},
}
#: a_in: the thesis' acceleration amplification inside the range (Model II y: "~2.0 (ds, a, vs)"),
#: context for a_lp, not a criterion.  front_back: the mean front / back amplification ratio of
#: Tables 4.9 - 4.11 (Section 4.3.4: "constant in each table", i.e. over frequency), context, not
#: a criterion; the front facade carried only an accelerometer (A5, Section 4.2.5), so these are
#: accelerometer amplifications (a or da: the thesis does not say which).


class PredictionInputError(ValueError):
    """Bad input (exit 2): the message names the file or option and the problem."""


# ---- the frozen set -----------------------------------------------------------------------------
def _git(cwd: Path, *args) -> subprocess.CompletedProcess:
    return subprocess.run(["git", "-C", str(cwd), *args], capture_output=True, text=True,
                          timeout=60)


def git_state(path: Path) -> dict:
    """Where ``path`` stands in its git repository: {repo (top level), rel (path in it), tracked,
    modified (differs from HEAD: staged or not), commit (the last commit that changed it)}.
    Raises PredictionInputError when it is not inside a git work tree."""
    path = Path(path).resolve()
    top = _git(path.parent, "rev-parse", "--show-toplevel")
    if top.returncode != 0:
        raise PredictionInputError(f"{path}: not inside a git repository (the freeze must be a "
                                   f"commit)")
    repo = Path(top.stdout.strip())
    rel = str(path.relative_to(repo))
    tracked = _git(repo, "ls-files", "--error-unmatch", "--", rel).returncode == 0
    status = _git(repo, "status", "--porcelain", "--", rel).stdout.strip()
    commit = _git(repo, "log", "-1", "--format=%H", "--", rel).stdout.strip() or None
    return {"repo": str(repo), "rel": rel, "tracked": tracked, "modified": bool(status),
            "commit": commit}


def validate_frozen_data(data, where: str = "frozen file") -> dict:
    """The ``imperfections:`` parameters of a frozen file's parsed YAML; PredictionInputError
    naming the problem otherwise (not a mapping, no imperfections, seed given, unknown key,
    missing key, a value the case schema rejects)."""
    from pydantic import ValidationError

    from dem.case.imperfections import Imperfections

    if not isinstance(data, dict):
        raise PredictionInputError(f"{where}: not a YAML mapping")
    extra = set(data) - {"imperfections", *PROVENANCE_KEYS}
    if extra:
        raise PredictionInputError(
            f"{where}: unknown top-level keys {sorted(extra)}: only imperfections: and the "
            f"provenance fields {list(PROVENANCE_KEYS)} (one set for every model; friction and "
            f"stiffness are not parameters)")
    imp = data.get("imperfections")
    if not isinstance(imp, dict):
        raise PredictionInputError(f"{where}: no 'imperfections:' mapping")
    if "seed" in imp:
        raise PredictionInputError(f"{where}: imperfections.seed given: the seeds are the "
                                   f"study's (0 .. N-1, fixed in advance), not the frozen set's")
    bad = set(imp) - set(PARAM_KEYS)
    if bad:
        raise PredictionInputError(f"{where}: unknown imperfections keys {sorted(bad)} (allowed: "
                                   f"{list(PARAM_KEYS)})")
    missing = [k for k in PARAM_KEYS if k not in imp]
    if missing:
        raise PredictionInputError(f"{where}: imperfections lacks {missing}: a frozen set states "
                                   f"every parameter")
    try:
        params = Imperfections.model_validate({**imp, "seed": 0}).model_dump()
    except ValidationError as err:
        raise PredictionInputError(f"{where}: imperfections: {err}") from None
    params.pop("seed")
    return params


def load_frozen(path) -> dict:
    """The frozen set (module docstring) with its provenance: {path, repo_path, parameters,
    provenance, sha256, commit}.  Refuses (PredictionInputError) a missing, malformed, untracked
    or modified file, and one outside ``cases/`` of its repository."""
    path = Path(path)
    if not path.is_file():
        raise PredictionInputError(f"{path}: frozen parameter file missing (the freeze, issue 13 "
                                   f"step 2, has not happened: commit it under cases/ first)")
    text = path.read_text()
    try:
        data = yaml.safe_load(text)
    except yaml.YAMLError as err:
        raise PredictionInputError(f"{path}: not valid YAML ({err})") from None
    params = validate_frozen_data(data, str(path))
    g = git_state(path)
    if not g["rel"].startswith("cases/"):
        raise PredictionInputError(f"{path}: the frozen set must live under cases/ of its "
                                   f"repository, it is {g['rel']}")
    if not g["tracked"] or g["commit"] is None:
        raise PredictionInputError(f"{path}: not committed in git: commit the freeze first")
    if g["modified"]:
        raise PredictionInputError(f"{path}: has uncommitted changes (git status): the "
                                   f"prediction uses only a committed frozen set")
    return {"path": g["rel"], "repo": g["repo"], "parameters": params,
            "provenance": {k: data[k] for k in PROVENANCE_KEYS if k in data},
            "sha256": hashlib.sha256(text.encode()).hexdigest(), "commit": g["commit"]}


# ---- the prediction points ----------------------------------------------------------------------
def sweep_names(only: str | None = None) -> list[str]:
    """The sweeps in study order; ``only``: comma-separated names (exit 2 on an unknown one)."""
    if not only:
        return list(ORDER)
    names = [s.strip() for s in only.split(",") if s.strip()]
    bad = [n for n in names if n not in ORDER]
    if bad:
        raise PredictionInputError(f"--only: unknown sweep(s) {bad}; choose from {list(ORDER)}")
    return [n for n in ORDER if n in names]


def frequencies(name: str) -> list[float]:
    """The sweep's frequencies (Hz): shake_study.SWEEPS (Appendix I / Chapter 4)."""
    return [float(f) for f in SWEEPS[name][1]]


def case_path(name: str) -> Path:
    return CASES / SWEEPS[name][0]


def sweep_case(name: str, params: dict):
    """The case of a sweep: its cases/shake file with ``imperfections:`` = the frozen set (seed 0;
    dem sweep sets each realisation's), the name pred-<sweep> and no VTK frames (output only:
    one .vtu per 0.02 s frame is ~75 MB per 50-cycle run, 30 GB for the 400 runs; frames.npz
    and instruments.npz, which the analysis reads, stay); the model, friction, stiffness and
    excitation are the case file's."""
    from dem.case import Case, load_case

    data = load_case(case_path(name)).model_dump()
    data["imperfections"] = {**params, "seed": 0}
    data["name"] = f"pred-{name}"
    data["run"]["vtk"] = False
    return Case.model_validate(data)


def fingerprint(case, freqs, seeds, cycles, max_steps) -> str:
    """What a finished sweep must match to be skipped (the engine's results revision included,
    dem.engine.RESULTS_REVISION)."""
    h = hashlib.sha256(case.model_dump_json().encode())
    h.update(json.dumps([list(freqs), list(seeds), cycles, max_steps,
                         RESULTS_REVISION]).encode())
    return h.hexdigest()[:16]


def sweep_cycles(plan: dict, name: str) -> float:
    """The cycles one sweep of the plan runs: its cut (:func:`cut_record`) or the plan's."""
    return plan["sweeps"][name].get("cycles", plan["cycles"])


def cut_record(out: Path, plan: dict | None, cycles: float) -> dict:
    """The justification of running sweeps other than FULL_SWEEP at ``cycles`` < the plan's
    (issue 13 step 3: "do Model II y in full first ... and show that the cut does not change
    the answer"): FULL_SWEEP finished at the plan's cycles, and its committed
    ``cycles-check-<N>.json``, made from the finished sweep, says the answer is unchanged
    (:func:`cycles_verdict`).  PredictionInputError naming what is missing otherwise."""
    if plan is None:
        raise PredictionInputError(f"--cut-cycles: {out}/plan.json missing: {FULL_SWEEP} runs "
                                   f"in full first")
    if not 2 <= cycles < plan["cycles"]:
        raise PredictionInputError(f"--cut-cycles {cycles:g}: must lie in [2, {plan['cycles']:g})"
                                   f" (the plan's cycles)")
    full = _read(points_path(out, FULL_SWEEP))
    if not sweep_finished(full) or full["prediction"]["cycles"] != plan["cycles"]:
        raise PredictionInputError(f"--cut-cycles: {FULL_SWEEP} has not finished at the plan's "
                                   f"{plan['cycles']:g} cycles ({points_path(out, FULL_SWEEP)}):"
                                   f" no cut before it")
    path = cycles_check_path(out, FULL_SWEEP, cycles)
    chk = _read(path)
    if not chk or not chk.get("sweep_finished"):
        raise PredictionInputError(f"--cut-cycles: {path} missing or made before {FULL_SWEEP} "
                                   f"finished: run --cycles-check {cycles:g} --only {FULL_SWEEP}")
    v = chk["verdict"]
    if v.get("unchanged") is not True:
        raise PredictionInputError(f"--cut-cycles {cycles:g}: {path} says the answer "
                                   f"{verdict_text(v)}: no cut")
    return {"cycles": cycles, "full_cycles": plan["cycles"], "justified_by": _rel(path),
            "verdict": verdict_text(v),
            "decided_utc": time.strftime("%Y-%m-%dT%H:%M:%SZ", time.gmtime())}


def source_state() -> dict:
    """The code that ran: this checkout's HEAD and whether dem/, postprocess/ or cases/ differ."""
    commit = _git(ROOT, "rev-parse", "HEAD").stdout.strip() or None
    dirty = bool(_git(ROOT, "status", "--porcelain", "--", "dem", "postprocess", "cases")
                 .stdout.strip()) if commit else None
    return {"commit": commit, "dirty": dirty}


def make_plan(frozen: dict, names: list[str], realisations: int, cycles: float,
              max_steps: int | None) -> dict:
    """The pre-registration written before any run: frozen set, freezing commit, seeds (k = k),
    sweeps with their case files, frequencies and excitation, cycles, step cap."""
    if realisations < 1:
        raise PredictionInputError(f"--realisations must be >= 1, got {realisations}")
    if not cycles > 0:
        raise PredictionInputError(f"--cycles must be > 0, got {cycles}")
    sweeps = {}
    for n in names:
        case = sweep_case(n, frozen["parameters"])
        sweeps[n] = {"case_file": str(case_path(n).relative_to(ROOT)),
                     "frequencies_hz": frequencies(n),
                     "direction": list(case.loading.direction),
                     "peak_acceleration_m_s2": case.loading.peak_acceleration,
                     "friction": case.material.friction}
    return {"kind": "prediction-plan", "frozen": {k: frozen[k] for k in
                                                  ("path", "parameters", "provenance", "sha256",
                                                   "commit")},
            "seeds": list(range(realisations)), "cycles": cycles, "max_steps": max_steps,
            "order": list(names), "sweeps": sweeps,
            "created_utc": time.strftime("%Y-%m-%dT%H:%M:%SZ", time.gmtime()),
            "code": source_state()}


def write_plan(out: Path, plan: dict) -> dict:
    """Write ``<out>/plan.json`` unless one exists; an existing plan must agree on the frozen
    commit, parameters, seeds, cycles and step cap (sweeps may be added, never changed: a sweep
    already planned keeps its cycles); returns the plan in force.  PredictionInputError on a
    disagreement."""
    from dem.output.atomic import write_json

    path = Path(out) / "plan.json"
    try:
        old = json.loads(path.read_text())
    except (OSError, ValueError):
        old = None
    if old is not None:
        for key, a, b in (("frozen commit", old["frozen"]["commit"], plan["frozen"]["commit"]),
                          ("frozen parameters", old["frozen"]["parameters"],
                           plan["frozen"]["parameters"]),
                          ("seeds", old["seeds"], plan["seeds"]),
                          ("cycles", old["cycles"], plan["cycles"]),
                          ("max_steps", old["max_steps"], plan["max_steps"])):
            if a != b:
                raise PredictionInputError(
                    f"{path}: made with {key} {a!r}, this call has {b!r}: the plan is fixed "
                    f"before the runs; use another --out for another plan")
        for n in plan["order"]:
            if n in old["sweeps"] and sweep_cycles(old, n) != sweep_cycles(plan, n):
                raise PredictionInputError(
                    f"{path}: {n} is planned at {sweep_cycles(old, n):g} cycles, this call has "
                    f"{sweep_cycles(plan, n):g}: a planned sweep's cycles are fixed")
        added = [n for n in plan["order"] if n not in old["sweeps"]]
        if not added:
            return old
        old["sweeps"].update({n: plan["sweeps"][n] for n in added})
        old["order"] = [n for n in ORDER if n in old["sweeps"]]
        plan = old
    Path(out).mkdir(parents=True, exist_ok=True)
    write_json(path, plan, indent=1)
    return plan


# ---- running one sweep --------------------------------------------------------------------------
def points_path(out: Path, name: str) -> Path:
    return Path(out) / name / "points.json"


def _read(path: Path) -> dict | None:
    try:
        return json.loads(Path(path).read_text())
    except (OSError, ValueError):
        return None


def row_from_point(seed: int, p: dict) -> dict:
    """One committed row from a sweep.json point record (postprocess.sweep.point_record)."""
    amp = p.get("amplification") or {}
    lag = p.get("lag") or {}
    err = str(p.get("error") or "")
    # an analysis_status means the post hook ran, which it does only after a finished run
    # (postprocess.sweep.point_record overwrites the "analysis: " prefix of the error)
    run_ok = p.get("status") == "ok" or p.get("analysis_status") == "failed"
    row = {"seed": seed, "frequency_hz": p["frequency_hz"],
           "run_status": "ok" if run_ok else p.get("status", "pending"),
           "analysis_status": "ok" if p.get("status") == "ok" else
           ("failed" if run_ok else None),
           "amplitude_m": p.get("amplitude_m"), "steps": p.get("steps"),
           "sim_time_s": p.get("sim_time"), "wall_seconds": p.get("wall_seconds")}
    # the CPU (dem.run.resume.machine; rows before 2026-11-26 14:00 UTC have none) and those
    # a resumed run went on with: results differ in the last bits from one CPU to another
    for k in ("machine", "resumed_on"):
        if p.get(k):
            row[k] = p[k]
    if err:
        row["error"] = err[:300]
    if p.get("status") == "ok":
        exc = p.get("excited") or {}
        mech = p.get("mechanism") or {}
        row.update({
            "amplification": {q: amp.get(q) for q in ROW_QUANTITIES},
            "a_lowpass": p.get("a_lowpass"),
            "h1_ds": (p.get("h1_amplitude_ratio") or {}).get("ds"),
            "dominant_frequency_hz": p.get("dominant_frequency_hz"),
            "single_peak": p.get("single_peak"),
            "lag_s": {q: (lag.get(q) or {}).get("s") for q in ("ds", "dsr")},
            "excited": {k: exc.get(k) for k in ("n_excited", "n_upper", "n_lower",
                                                "excited_courses_from_top")},
            "collapse_suspected": p.get("collapse_suspected"),
            "mechanism": {k: mech.get(k) for k in ("response", "corners", "line")},
            "note": p.get("note")})
    return row


def collect_rows(runs_dir: Path, seeds, freqs) -> list[dict]:
    """Rows for every (seed, frequency) from ``runs_dir/seed-<k>/sweep.json``; pending where
    the sweep or the point is not there."""
    rows = []
    for s in seeds:
        data = _read(Path(runs_dir) / f"seed-{s}" / "sweep.json") or {}
        by_f = {round(p["frequency_hz"], 9): p for p in data.get("points", [])}
        for f in freqs:
            p = by_f.get(round(f, 9))
            rows.append(row_from_point(s, p) if p else
                        {"seed": s, "frequency_hz": f, "run_status": "pending",
                         "analysis_status": None})
    return rows


def _key(seed: int, f: float) -> tuple[int, float]:
    return int(seed), round(float(f), 9)


def finished_rows(data: dict | None, fp: str) -> dict:
    """{(seed, frequency): row} of the finished rows of a points.json made for fingerprint
    ``fp`` (none for another fingerprint: another case, seed list, cycles or engine)."""
    if not data or (data.get("prediction") or {}).get("fingerprint") != fp:
        return {}
    return {_key(r["seed"], r["frequency_hz"]): r for r in data.get("rows") or []
            if r.get("run_status") == "ok"}


def merge_rows(fresh: list[dict], kept: dict) -> list[dict]:
    """The rows of a sweep from this machine's run directories (``fresh``, in plan order) and
    the finished rows of the committed points.json (``kept``, :func:`finished_rows`): a finished
    fresh row wins, else a finished kept row, else the fresh one (pending or failed).  So a
    point finished in an earlier session counts even where its raw run directory is gone (a new
    checkout, another machine), and is never run again."""
    out = []
    for r in fresh:
        k = kept.get(_key(r["seed"], r["frequency_hz"]))
        out.append(r if r.get("run_status") == "ok" or k is None else k)
    return out


def sweep_finished(data: dict | None, fp: str | None = None) -> bool:
    """Every (seed, frequency) of a committed points.json has a finished run (and, if given,
    the fingerprint is ``fp``)."""
    if not data or "prediction" not in data:
        return False
    pred = data["prediction"]
    if fp is not None and pred.get("fingerprint") != fp:
        return False
    rows = data.get("rows") or []
    return len(rows) == len(pred["seeds"]) * len(pred["frequencies_hz"]) and \
        all(r.get("run_status") == "ok" for r in rows)


@contextlib.contextmanager
def _locked(path: Path):
    """An exclusive lock on ``path``.lock for a read-merge-write of points.json: two study
    processes on one sweep (e.g. different --seeds) never lose each other's rows."""
    path.parent.mkdir(parents=True, exist_ok=True)
    with open(str(path) + ".lock", "w") as fh:
        fcntl.flock(fh, fcntl.LOCK_EX)
        try:
            yield
        finally:
            fcntl.flock(fh, fcntl.LOCK_UN)


def update_points(dest: Path, name: str, plan: dict, case, case_file: Path, fp: str,
                  fresh: list[dict], cpu: float, wall: float, rc: int | None,
                  new_session: bool) -> dict:
    """Merge ``fresh`` rows into ``dest`` (points.json; :func:`merge_rows` with the finished
    rows already there) and add this call's CPU and wall seconds, under a lock; returns the
    written data."""
    from dem.output.atomic import write_json

    freqs, seeds = plan["sweeps"][name]["frequencies_hz"], plan["seeds"]
    frozen = plan["frozen"]
    with _locked(dest):
        old = _read(dest)
        prev = (old or {}).get("prediction") or {}
        same = prev.get("fingerprint") == fp
        rows = merge_rows(fresh, finished_rows(old, fp))
        data = {"kind": "prediction-sweep", "sweep": name, "rows": rows, "prediction": {
            "sweep": name, "case_file": plan["sweeps"][name]["case_file"],
            "run_case": _rel(case_file), "frozen": frozen, "seeds": seeds,
            "frequencies_hz": freqs, "cycles": sweep_cycles(plan, name),
            "max_steps": plan["max_steps"], "fingerprint": fp,
            "friction": case.material.friction,
            "peak_acceleration_m_s2": case.loading.peak_acceleration,
            "direction": list(case.loading.direction),
            "cpu_seconds": (prev.get("cpu_seconds", 0.0) if same else 0.0) + cpu,
            "wall_seconds": (prev.get("wall_seconds", 0.0) if same else 0.0) + wall,
            "sessions": (prev.get("sessions", 0) if same else 0) + (1 if new_session else 0),
            "exit_code": rc if rc is not None else prev.get("exit_code"),
            "source": source_state()}}
        data["prediction"]["finished"] = sweep_finished(data)
        write_json(dest, data, indent=1)
    return data


def write_run_case(runs: Path, name: str, case) -> Path:
    """``<runs>/<sweep>.yaml``: the sweep's case as dem sweep reads it (also point_pool's)."""
    case_file = Path(runs) / f"{name}.yaml"
    case_file.parent.mkdir(parents=True, exist_ok=True)
    case_file.write_text(yaml.safe_dump(case.model_dump(mode="json"), sort_keys=False))
    return case_file


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
    if sweep_finished(_read(dest), fp):
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
        todo = [f for f in my_freqs if _key(s, f) not in done]
        if not todo:
            continue
        args = ["sweep", str(case_file), "--out", str(sweep_dir),
                "--frequencies", ",".join(f"{f:g}" for f in todo), "--cycles", f"{cycles:g}",
                "--realisations", "1", "--seed", str(s)]
        if workers is not None:
            args += ["--workers", str(workers)]
        if plan["max_steps"] is not None:
            args += ["--max-steps", str(plan["max_steps"])]
        if drain_file is not None:
            args += ["--drain-file", str(drain_file)]
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


def _rel(path: Path) -> str:
    path = Path(path).resolve()
    return str(path.relative_to(ROOT)) if path.is_relative_to(ROOT) else str(path)


# ---- analysis of one sweep ----------------------------------------------------------------------
def _finite(x) -> bool:
    return isinstance(x, (int, float)) and not isinstance(x, bool) and math.isfinite(x)


def survived(row: dict) -> bool | None:
    """True: the run finished, was analysed and its standing check passed (postprocess.shake: the
    centre moved less than its thickness relative to the table); False: collapse suspected, the
    check missing, or the analysis failed (counted against survival: a run that cannot be
    analysed is not a standing model); None: not run / run failed (pending)."""
    if row.get("run_status") != "ok":
        return None
    if row.get("analysis_status") != "ok":
        return False
    # None: an analysis without the standing check (older sweep.json): not confirmed standing
    return row.get("collapse_suspected") is False


def characteristic(freqs, curve: dict, unrun=()) -> dict:
    """Characteristic frequency and effective range of an amplification curve {f: amplification}
    by postprocess.sweep.effective_range; at an edge of the sweep the frequency is null with the
    reason "peak at the edge of the sweep: no resonance found in the range".  ``unrun``: the
    frequencies of the sweep with no finished run yet; a peak at the last finished frequency
    before them is not at the edge of the sweep, and reads "pending" instead."""
    fs = [f for f in freqs if _finite(curve.get(f))]
    er = effective_range(fs, [curve[f] for f in fs])
    if not fs:
        er["characteristic_frequency_note"] = "no surviving realisation with an analysed response"
    if er.get("characteristic_frequency_hz") is None and fs:
        k = int(np.argmax([curve[f] for f in fs]))
        beyond = [f for f in unrun if (f < fs[k] if k == 0 else f > fs[k])]
        if len(fs) >= 3 and k in (0, len(fs) - 1) and beyond:
            er["characteristic_frequency_note"] = (
                f"pending: the peak so far is at {fs[k]:g} Hz, and {len(beyond)} frequencies "
                f"beyond it have not run")
        elif len(fs) >= 3 and k in (0, len(fs) - 1):
            er["characteristic_frequency_note"] = (
                f"peak at the edge of the sweep ({fs[k]:g} Hz, the "
                f"{'lowest' if k == 0 else 'highest'} frequency): no resonance found in the range")
            er["peak_at_edge"] = True
    return er


def _per_seed_mean(rows, seeds, freqs_in, key) -> list:
    """Per seed, the mean of ``key(row)`` over its surviving rows at the frequencies freqs_in;
    None for a seed with one of those frequencies not yet finished (pending or failed run: an
    unfinished sweep's seed does not enter the statistics with a part of the range).  Rows a
    cycles check left out (LEFT_OUT: no raw run here) are skipped, on both of its sides alike."""
    out = []
    for s in seeds:
        mine = [r for r in rows if r["seed"] == s and r["frequency_hz"] in freqs_in]
        if len(mine) < len(freqs_in) or any(survived(r) is None and
                                            r.get("run_status") != LEFT_OUT for r in mine):
            out.append(None)
            continue
        v = [key(r) for r in mine if survived(r)]
        v = [x for x in v if _finite(x)]
        out.append(float(np.mean(v)) if v else None)
    return out


def _amp(q: str):
    """Row -> its amplification of quantity q (None where absent)."""
    return lambda r: (r.get("amplification") or {}).get(q)


def _ratio(front: str, back: str):
    """Row -> amplification of ``front`` over that of ``back`` (None unless both are finite and
    the back one > 0)."""
    def key(r):
        a = r.get("amplification") or {}
        f, b = a.get(front), a.get(back)
        return f / b if _finite(f) and _finite(b) and b > 0 else None
    return key


def acceleration_inside(rows, seeds, freqs_in) -> dict:
    """The centre accelerometer's amplification inside (per-seed means over the surviving rows
    at the frequencies ``freqs_in`` (Hz), then median and 10-90 % over the seeds): unfiltered
    ``a``, ``a_lp`` (the assumed instrument low-pass at LOWPASS_HZ) and ``cutoff_sensitivity``
    ("raw" and one key per LOWPASS_SENSITIVITY_HZ cutoff, Hz, from the rows' ``a_lowpass``).
    Not a criterion: the thesis gives no filter, and the answer depends on the cutoff."""
    def low(k):
        return lambda r: (r.get("a_lowpass") or {}).get(k)

    keys = ["raw"] + [f"{c:g}" for c in LOWPASS_SENSITIVITY_HZ]
    return {"a": statistics(_per_seed_mean(rows, seeds, freqs_in, _amp("a"))),
            "a_lp": statistics(_per_seed_mean(rows, seeds, freqs_in, _amp("a_lp"))),
            "cutoff_sensitivity": {k: statistics(_per_seed_mean(rows, seeds, freqs_in, low(k)))
                                   for k in keys}}


def front_back_inside(rows, seeds, freqs_in) -> dict:
    """Per ratio of FRONT_BACK ("da": da_front / da, "a_lp": a_front_lp / a_lp): the front and
    back amplifications and their ratio (per row, then per-seed means over the surviving rows
    at ``freqs_in`` (Hz), then median and 10-90 % over the seeds)."""
    return {label: {"front": statistics(_per_seed_mean(rows, seeds, freqs_in, _amp(fr))),
                    "back": statistics(_per_seed_mean(rows, seeds, freqs_in, _amp(bk))),
                    "ratio": statistics(_per_seed_mean(rows, seeds, freqs_in, _ratio(fr, bk)))}
            for label, (fr, bk) in FRONT_BACK.items()}


def da_expected(row: dict) -> float | None:
    """The amplification of the absolute top displacement da that an oscillation of ds at f
    implies: |1 + A1 exp(-i 2 pi f lag)|, A1 the first-harmonic amplitude ratio of ds (relative
    to the table) and lag its lag behind the table (s).  The absolute motion is table + ds, so
    a response lagging by ~150 deg reads da < 1 while it rocks (results/shake, 4.0 m/s2:
    2.8 Hz, A1 1.56, lag 0.146 s: 0.906 expected, 0.910 measured)."""
    h1, lag = row.get("h1_ds"), (row.get("lag_s") or {}).get("ds")
    if not (_finite(h1) and _finite(lag)):
        return None
    th = 2 * math.pi * row["frequency_hz"] * lag
    return float(abs(1 + h1 * complex(math.cos(th), -math.sin(th))))


def is_rocking(row: dict) -> dict:
    """Step 5: is the row's ds amplification rocking, not drift or a sliding ratchet?  Rocking
    when (1) ds is at the excitation frequency: its dominant frequency is f within
    DOMINANT_REL_TOL and its first harmonic carries >= H1_SHARE_MIN of the peak-to-peak
    amplification (a drift or a ratchet puts its peak-to-peak into a slow or stepwise motion);
    (2) the accelerometer agrees: da (double-integrated absolute acceleration, slow wander
    removed) is the phasor sum :func:`da_expected` within DA_REL_TOL (or DA_ABS_TOL); and
    (3) the centre moves relative to its corners: dsr >= DSR_SHARE_MIN x ds (a rigid slide of
    the whole top reads dsr ~ 0).  Thresholds are this harness' choices, not thesis values.
    Returns {rocking: bool | None, why}."""
    amp = row.get("amplification") or {}
    ds, da, dsr = amp.get("ds"), amp.get("da"), amp.get("dsr")
    if not _finite(ds) or ds <= 0:
        return {"rocking": None, "why": "no ds amplification"}
    f, fd, h1 = row["frequency_hz"], row.get("dominant_frequency_hz"), row.get("h1_ds")
    why = []
    if not (_finite(fd) and abs(fd - f) <= DOMINANT_REL_TOL * f):
        why.append(f"dominant frequency of ds {_f(fd)} Hz, not {f:g}")
    if not (_finite(h1) and h1 >= H1_SHARE_MIN * ds):
        why.append(f"first harmonic {_f(h1)} < {H1_SHARE_MIN} x ds amplification {ds:.3g}: "
                   f"drift or ratchet")
    exp = da_expected(row)
    if not (_finite(da) and exp is not None
            and abs(da - exp) <= max(DA_REL_TOL * exp, DA_ABS_TOL)):
        why.append(f"da amplification {_f(da)} against {_f(exp)} from ds at f: the "
                   f"accelerometer does not see the ds oscillation")
    if not (_finite(dsr) and dsr >= DSR_SHARE_MIN * ds):
        why.append(f"dsr amplification {_f(dsr)} < {DSR_SHARE_MIN} x ds: a rigid slide, "
                   f"not rocking")
    return {"rocking": not why, "why": "; ".join(why) or "rocking"}


def analyse_sweep(name: str, data: dict | None) -> dict:
    """The numbers of one sweep (module docstring) from its points.json; {"status": "pending"}
    without one."""
    if not data or "prediction" not in data:
        return {"status": "pending", "sweep": name}
    pred, rows = data["prediction"], data.get("rows") or []
    seeds, freqs = pred["seeds"], pred["frequencies_hz"]
    thesis = THESIS.get(name, {})
    out = {"sweep": name, "status": "finished" if sweep_finished(data) else "pending",
           "n_rows": len(rows), "n_run": sum(1 for r in rows if r.get("run_status") == "ok"),
           "n_expected": len(seeds) * len(freqs), "seeds": seeds, "frequencies_hz": freqs,
           "cycles": pred["cycles"], "max_steps": pred["max_steps"],
           "smoke": pred["max_steps"] is not None, "cpu_seconds": pred.get("cpu_seconds"),
           "code": pred.get("source"), "friction": pred.get("friction"),
           "peak_acceleration_m_s2": pred.get("peak_acceleration_m_s2"),
           "frozen_commit": (pred.get("frozen") or {}).get("commit")}
    # survival per frequency
    surv = {}
    for f in freqs:
        s = [survived(r) for r in rows if r["frequency_hz"] == f]
        known = [x for x in s if x is not None]
        surv[f"{f:g}"] = {"n": len(known), "survived": int(sum(known)),
                          "rate": (sum(known) / len(known)) if known else None}
    rates = [v["rate"] for v in surv.values() if v["rate"] is not None]
    out["survival"] = {"per_frequency": surv, "min_rate": min(rates) if rates else None,
                       "overall_rate": (sum(v["survived"] for v in surv.values())
                                        / max(1, sum(v["n"] for v in surv.values())))
                       if rates else None}
    # amplification curves: median and band over the surviving realisations
    curves = {}
    for q in ROW_QUANTITIES:
        curves[q] = {f"{f:g}": statistics((r.get("amplification") or {}).get(q) for r in rows
                                          if r["frequency_hz"] == f and survived(r))
                     for f in freqs}
    out["amplification_curves"] = curves
    # front / back ratio per frequency (the thesis: constant over frequency)
    out["front_back_curves"] = {
        label: {f"{f:g}": statistics(_ratio(fr, bk)(r) for r in rows
                                     if r["frequency_hz"] == f and survived(r)) for f in freqs}
        for label, (fr, bk) in FRONT_BACK.items()}
    med = {f: curves["ds"][f"{f:g}"]["median"] for f in freqs}
    unrun = [f for f in freqs if not any(r["frequency_hz"] == f and r.get("run_status") == "ok"
                                         for r in rows)]
    er = characteristic(freqs, med, unrun)
    out["characteristic_frequency_hz"] = er.get("characteristic_frequency_hz")
    out["characteristic_frequency_note"] = er.get("characteristic_frequency_note")
    out["peak_at_edge"] = bool(er.get("peak_at_edge"))
    out["effective_range_hz"] = er.get("effective_range_hz")
    out["effective_range_rule"] = er.get("rule")
    # per-seed characteristic frequencies (the band)
    fcs = []
    for s in seeds:
        c = {r["frequency_hz"]: (r.get("amplification") or {}).get("ds") for r in rows
             if r["seed"] == s and survived(r)}
        fcs.append(characteristic(freqs, c).get("characteristic_frequency_hz"))
    out["characteristic_frequency_per_seed_hz"] = fcs
    out["characteristic_frequency_band"] = statistics(fcs)
    out["realisations_without_characteristic_frequency"] = sum(1 for x in fcs if x is None)
    # inside / outside: the thesis' range (the same frequencies as the tests; issue 13 step 4),
    # and the DEM's own effective range where it found one
    def split(rng):
        if not rng:
            return None, None
        ins = [f for f in freqs if rng[0] - 1e-9 <= f <= rng[1] + 1e-9]
        return ins, [f for f in freqs if f not in ins]

    ranges = {"thesis_range": thesis.get("range") or ([thesis["fc"]] * 2 if thesis.get("fc")
                                                       else None),
              "dem_range": out["effective_range_hz"]}
    out["inside_outside"] = {}
    for label, rng in ranges.items():
        ins, outs = split(rng)
        if not ins:
            out["inside_outside"][label] = {"range_hz": rng, "note": "no range"}
            continue
        a_in = _per_seed_mean(rows, seeds, ins, lambda r: (r.get("amplification") or {})
                              .get("ds"))
        a_out = _per_seed_mean(rows, seeds, outs, lambda r: (r.get("amplification") or {})
                               .get("ds"))
        ratio = [i / o if _finite(i) and _finite(o) and o > 0 else None
                 for i, o in zip(a_in, a_out)]
        lag_in = _per_seed_mean(rows, seeds, ins, lambda r: (r.get("lag_s") or {}).get("ds"))
        lag_out = _per_seed_mean(rows, seeds, outs, lambda r: (r.get("lag_s") or {}).get("ds"))
        out["inside_outside"][label] = {
            "range_hz": rng, "inside_hz": ins, "outside_hz": outs,
            "amplification_ds_inside": statistics(a_in),
            "amplification_ds_outside": statistics(a_out),
            "ratio_inside_outside": statistics(ratio),
            "lag_ds_inside_s": statistics(lag_in), "lag_ds_outside_s": statistics(lag_out),
            "acceleration_inside": acceleration_inside(rows, seeds, ins),
            "front_back_inside": front_back_inside(rows, seeds, ins)}
    # excited portion at the thesis' characteristic frequency (else the DEM's)
    f_exc = thesis.get("fc") or out["characteristic_frequency_hz"]
    ex_rows = [r for r in rows if f_exc is not None and abs(r["frequency_hz"] - f_exc) < 1e-9
               and survived(r)]
    out["excited_at_hz"] = f_exc
    out["excited_bricks"] = statistics((r.get("excited") or {}).get("n_excited")
                                       for r in ex_rows)
    out["excited_courses"] = statistics((r.get("excited") or {}).get("excited_courses_from_top")
                                        for r in ex_rows)
    for part in ("upper", "lower"):
        out[f"excited_{part}"] = statistics((r.get("excited") or {}).get(f"n_{part}")
                                            for r in ex_rows)
    # rocking, not drift (step 5), at the frequencies inside the thesis' / DEM's range
    chk = [{"seed": r["seed"], "frequency_hz": r["frequency_hz"], **is_rocking(r)}
           for r in rows if survived(r)]
    out["rocking_rows"] = {"n": len([c for c in chk if c["rocking"] is not None]),
                           "rocking": sum(1 for c in chk if c["rocking"]),
                           "not_rocking": [c for c in chk if c["rocking"] is False][:20]}
    return out


# ---- the cycles check (issue 13 step 3: fewer cycles must not change the answer) -----------------
def truncated_row(seed: int, f: float, run_dir: Path, cycles: float) -> dict:
    """The row (:func:`row_from_point`) of one finished run analysed over its first ``cycles``
    cycles only (postprocess.shake.analyze_run(cycles=...): as if it had shaken that many; the
    run's first cycles do not depend on how many follow, module docstring); an analysis that
    fails gives a failed row naming the error."""
    from postprocess.shake import analyze_run
    from postprocess.sweep import compact

    try:
        p = {"frequency_hz": f, "status": "ok", **compact(analyze_run(run_dir, cycles=cycles))}
    except Exception as err:  # noqa: BLE001 - reported in the row, like dem sweep's post hook
        p = {"frequency_hz": f, "status": "failed", "analysis_status": "failed",
             "error": f"analysis: {type(err).__name__}: {err}"}
    return row_from_point(seed, p)


def has_raw_run(run_dir: Path) -> bool:
    """Whether a finished point's raw run (its frames.npz) is on this machine: a point finished
    in an earlier checkout, or run elsewhere (postprocess.point_pool) and merged from its
    summary / case / analysis.json, has only its committed row."""
    return (Path(run_dir) / "frames.npz").is_file()


def truncated_points(data: dict, sweep_dir: Path, cycles: float,
                     stored: dict | None = None) -> tuple[dict, dict, list]:
    """Both sides of a cycles check of the sweep ``data`` (its committed points.json), on the
    finished rows whose first ``cycles`` cycles were analysed when they finished (``stored``:
    {(seed, frequency): row}, :func:`stored_truncated`) or can be now from their raw runs in
    ``sweep_dir`` (``seed-<k>/<point>/``, :func:`has_raw_run`): (full, short, left_out).  A
    finished row with neither is marked LEFT_OUT on both sides (named in ``left_out`` as
    [seed, frequency]), so that the full and the short answer come from the same runs;
    unfinished rows stay as they are."""
    from dem.run.sweep import point_name

    stored = stored or {}
    full, short, left_out = [], [], []
    for r in data.get("rows") or []:
        d = Path(sweep_dir) / f"seed-{r['seed']}" / point_name(r["frequency_hz"])
        k = _key(r["seed"], r["frequency_hz"])
        if r.get("run_status") != "ok":
            full.append(dict(r))
            short.append(dict(r))
        elif k in stored or has_raw_run(d):
            full.append(r)
            short.append(stored[k] if k in stored else
                         truncated_row(r["seed"], r["frequency_hz"], d, cycles))
        else:
            left_out.append([r["seed"], r["frequency_hz"]])
            gone = {"seed": r["seed"], "frequency_hz": r["frequency_hz"],
                    "run_status": LEFT_OUT, "analysis_status": None, "note": NO_RAW_RUN}
            full.append(gone)
            short.append(dict(gone))
    return ({"prediction": data["prediction"], "rows": full},
            {"prediction": {**data["prediction"], "cycles": cycles}, "rows": short}, left_out)


def _median_agrees(full: dict | None, short: dict | None) -> dict:
    """Medians of two statistics agree when |short - full| <= max(q90 - q10 of full,
    CYCLES_REL_FLOOR x |full median|) (the floor: a band of zero width, one realisation)."""
    if not (full and full.get("n") and short and short.get("n")):
        return {"same": None, "full": (full or {}).get("median"),
                "short": (short or {}).get("median"), "why": "no data"}
    tol = max(full["q90"] - full["q10"], CYCLES_REL_FLOOR * abs(full["median"]))
    d = short["median"] - full["median"]
    return {"same": abs(d) <= tol + 1e-12, "full": full["median"], "short": short["median"],
            "full_band": [full["q10"], full["q90"]], "short_band": [short["q10"], short["q90"]],
            "difference": d, "tolerance": tol}


def cycles_verdict(full: dict, short: dict, freqs) -> dict:
    """Does analysing fewer cycles change the answer?  ``full`` / ``short``: analyse_sweep of the
    same runs over all / the first N cycles; freqs: the sweep's frequencies (Hz).  The rule:
    CYCLES_RULE ((2): :func:`_median_agrees`).  Returns the three comparisons, ``changed`` (the
    names of those that differ) and ``unchanged`` (None when one could not be judged)."""
    fs = sorted(freqs)
    a, b = full.get("characteristic_frequency_hz"), short.get("characteristic_frequency_hz")
    if a is None or b is None:
        same_fc = a is None and b is None
    else:
        same_fc = abs(fs.index(a) - fs.index(b)) <= 1
    out = {"characteristic_frequency": {"full": a, "short": b, "same": same_fc,
                                        "full_note": full.get("characteristic_frequency_note"),
                                        "short_note": short.get("characteristic_frequency_note")}}
    io_f = (full.get("inside_outside") or {}).get("thesis_range") or {}
    io_s = (short.get("inside_outside") or {}).get("thesis_range") or {}
    for key in ("amplification_ds_inside", "amplification_ds_outside"):
        out[key] = _median_agrees(io_f.get(key), io_s.get(key))
    rf = (full.get("survival") or {}).get("min_rate")
    rs = (short.get("survival") or {}).get("min_rate")
    ok_f = None if rf is None else rf >= SURVIVAL_MIN - 1e-12
    ok_s = None if rs is None else rs >= SURVIVAL_MIN - 1e-12
    out["survival"] = {"full": rf, "short": rs, "full_pass": ok_f, "short_pass": ok_s,
                       "same": ok_f == ok_s if None not in (ok_f, ok_s) else None}
    items = {k: v["same"] for k, v in out.items()}
    changed = [k for k, v in items.items() if v is False]
    out["changed"] = changed
    out["unchanged"] = None if not changed and None in items.values() else not changed
    return out


def truncated_path(out: Path, name: str) -> Path:
    return Path(out) / name / "truncated.json"


def stored_truncated(out: Path, name: str, fp: str, cycles: float) -> dict:
    """{(seed, frequency): row} of the committed truncated.json for ``cycles`` cycles (none
    when it was made for another fingerprint)."""
    data = _read(truncated_path(out, name)) or {}
    if data.get("fingerprint") != fp:
        return {}
    return {_key(r["seed"], r["frequency_hz"]): r
            for r in (data.get("rows") or {}).get(f"{cycles:g}", [])}


POOL_TRUNCATED = "truncated-rows.json"   # a point_pool run's analyses of its first N cycles


def record_truncated(out: Path, runs: Path, name: str, fp: str, log=print) -> int:
    """Analyse every finished point of the sweep's points.json over its first N cycles, for each
    N of TRUNCATED_CYCLES below the sweep's cycles, while its raw run is here (or take the
    analyses a point_pool machine made, ``<point>/truncated-rows.json``), and merge them into the
    committed ``<out>/<sweep>/truncated.json`` (under the lock of points.json).  So the cycles
    check (:func:`cycles_check`) does not depend on raw runs surviving from session to session
    (a new checkout loses them; a pooled point never had them here).  ~0.6 s per analysis.
    Returns the number of points added."""
    from dem.output.atomic import write_json
    from dem.run.sweep import point_name

    data = _read(points_path(out, name))
    if not data or (data.get("prediction") or {}).get("fingerprint") != fp:
        return 0
    ns = [n for n in TRUNCATED_CYCLES if 2 <= n < data["prediction"]["cycles"]]
    if not ns:
        return 0
    have = stored_truncated(out, name, fp, ns[0])
    new: dict[str, list] = {f"{n:g}": [] for n in ns}
    for r in data.get("rows") or []:
        k = _key(r["seed"], r["frequency_hz"])
        if r.get("run_status") != "ok" or k in have:
            continue
        d = Path(runs) / name / f"seed-{r['seed']}" / point_name(r["frequency_hz"])
        pooled = _read(d / POOL_TRUNCATED)
        if pooled is not None and all(f"{n:g}" in pooled for n in ns):
            for n in ns:
                new[f"{n:g}"].append(pooled[f"{n:g}"])
        elif has_raw_run(d):
            for n in ns:
                new[f"{n:g}"].append(truncated_row(r["seed"], r["frequency_hz"], d, n))
    added = len(new[f"{ns[0]:g}"])
    if not added:
        return 0
    dest = truncated_path(out, name)
    with _locked(points_path(out, name)):
        old = _read(dest) or {}
        rows = (old.get("rows") or {}) if old.get("fingerprint") == fp else {}
        for n, lst in new.items():
            mine = {_key(x["seed"], x["frequency_hz"]): x for x in rows.get(n, [])}
            mine.update({_key(x["seed"], x["frequency_hz"]): x for x in lst})
            rows[n] = [mine[k] for k in sorted(mine)]
        write_json(dest, {"kind": "prediction-truncated-rows", "sweep": name,
                          "fingerprint": fp, "cycles": ns, "rows": rows,
                          "what": "each finished point's analysis over its first N cycles "
                                  "(postprocess.shake.analyze_run(cycles=N)), made while its "
                                  "raw run existed: the input of the cycles checks"},
                   indent=1)
    log(f"    {name}: first {', '.join(f'{n:g}' for n in ns)} cycles of {added} finished "
        f"point(s) analysed -> {_rel(dest)}")
    return added


def cycles_check(out: Path, runs: Path, name: str, cycles: float) -> dict:
    """Compare the finished runs of a sweep over their first ``cycles`` cycles (the kept
    analyses of truncated.json, after :func:`record_truncated` has added those of the raw runs
    here; else analysed now from a raw run; no simulation) with the full cycles
    (:func:`cycles_verdict`) and write ``<out>/<sweep>/cycles-check-<N>.json`` (committed, like
    points.json); returns it.
    PredictionInputError without the sweep's points.json or with ``cycles`` not in
    [2, the sweep's cycles)."""
    from dem.output.atomic import write_json

    data = _read(points_path(out, name))
    if not data or "prediction" not in data:
        raise PredictionInputError(f"{points_path(out, name)}: missing: run the sweep first")
    full_cycles = data["prediction"]["cycles"]
    if not 2 <= cycles < full_cycles:
        raise PredictionInputError(f"--cycles-check {cycles:g}: must lie in [2, {full_cycles:g}) "
                                   f"(the sweep ran {full_cycles:g} cycles; cycle 1 is dropped)")
    fp = data["prediction"].get("fingerprint")
    record_truncated(out, runs, name, fp, log=lambda m: print(m, file=sys.stderr))
    stored = stored_truncated(out, name, fp, cycles)
    full, short, left_out = truncated_points(data, Path(runs) / name, cycles, stored)
    full_sw, short_sw = analyse_sweep(name, full), analyse_sweep(name, short)
    res = {"kind": "prediction-cycles-check", "sweep": name, "cycles": cycles,
           "full_cycles": full_cycles, "sweep_finished": sweep_finished(data),
           "n_runs": full_sw["n_run"],
           "n_runs_sweep": sum(1 for r in data.get("rows") or [] if r.get("run_status") == "ok"),
           "left_out_no_raw_run": left_out, "rows": short["rows"],
           "verdict": cycles_verdict(full_sw, short_sw, data["prediction"]["frequencies_hz"]),
           "rule": CYCLES_RULE,
           "source": source_state()}
    write_json(cycles_check_path(out, name, cycles), res, indent=1)
    return res


def verdict_text(v: dict) -> str:
    """One line for a :func:`cycles_verdict`."""
    return {True: "unchanged", False: "CHANGED: " + ", ".join(v["changed"]),
            None: "not judged (no data)"}[v["unchanged"]]


def cycles_check_path(out: Path, name: str, cycles: float) -> Path:
    return Path(out) / name / f"cycles-check-{cycles:g}.json"


# ---- criteria (issue 13 step 4) and false-success checks (step 5) --------------------------------
def band_verdict(stats: dict | None, thesis: float | None, tol_abs: float | None = None,
                 factor: float | None = None) -> dict:
    """pass / fail / pending of a numeric criterion judged two ways: the median within the
    tolerance of the thesis value (``tol_abs``: |median - thesis| <= tol_abs; ``factor``:
    thesis / factor <= median <= thesis x factor) AND the thesis value inside the 10-90 % band
    [q10, q90] of the realisations.  pending without data."""
    if thesis is None:
        return {"status": "n/a", "why": "no thesis value"}
    if not stats or not stats.get("n"):
        return {"status": "pending", "why": "no realisation finished"}
    med, q10, q90 = stats["median"], stats["q10"], stats["q90"]
    if tol_abs is not None:
        by_median = abs(med - thesis) <= tol_abs + 1e-12
        tol = f"+-{tol_abs:g}"
    else:
        by_median = thesis / factor - 1e-12 <= med <= thesis * factor + 1e-12
        tol = f"x/{factor:g}"
    in_band = q10 - 1e-12 <= thesis <= q90 + 1e-12
    ok = by_median and in_band
    return {"status": "pass" if ok else "fail", "by_median": by_median, "in_band": in_band,
            "thesis_value": thesis, "median": med, "band": [q10, q90], "tolerance": tol,
            "why": f"median {med:.3g}, 10-90 % [{q10:.3g}, {q90:.3g}]: " + (
                "both agree with the thesis" if ok else "; ".join(
                w for w, bad in ((f"median {med:.3g} outside thesis {thesis:g} {tol}",
                                  not by_median),
                                 (f"thesis {thesis:g} outside the 10-90 % band "
                                  f"[{q10:.3g}, {q90:.3g}]", not in_band)) if bad))}


def fc_verdict(sw: dict, thesis_fc: float | None) -> dict:
    """Characteristic frequency: the median curve's peak within FC_TOL_HZ of the thesis and the
    thesis value inside the band of the per-seed characteristic frequencies; a null prediction
    (peak at the edge, no clear peak) fails with its reason; fewer than half the seeds with a
    characteristic frequency fails."""
    if sw.get("status") == "pending" and not sw.get("n_run"):
        return {"status": "pending", "why": "not run"}
    if thesis_fc is None:
        return {"status": "n/a", "why": "the thesis gives no characteristic frequency"}
    fc = sw.get("characteristic_frequency_hz")
    if fc is None:
        return {"status": "fail",
                "why": f"no characteristic frequency: {sw.get('characteristic_frequency_note')}"}
    n_null = sw.get("realisations_without_characteristic_frequency", 0)
    if n_null * 2 > len(sw.get("seeds") or []):
        return {"status": "fail", "why": f"{n_null} of {len(sw['seeds'])} realisations have no "
                                         f"characteristic frequency", "median_curve_fc": fc}
    band = dict(sw.get("characteristic_frequency_band") or {})
    band["median"] = fc  # judged on the peak of the median curve
    return band_verdict(band, thesis_fc, tol_abs=FC_TOL_HZ)


def survival_verdict(sw: dict, min_rate: float = SURVIVAL_MIN) -> dict:
    """At least ``min_rate`` of the realisations survive at every frequency."""
    r = (sw.get("survival") or {}).get("min_rate")
    if r is None:
        return {"status": "pending", "why": "no realisation finished"}
    ok = r >= min_rate - 1e-12
    return {"status": "pass" if ok else "fail", "min_rate": r, "threshold": min_rate,
            "why": f"lowest survival over the frequencies {r:.0%} "
                   f"({'>=' if ok else '<'} {min_rate:.0%}) in {_f(sw.get('cycles'), 'g')} cycles"}


def criteria(summary: dict, chapter3: dict | None = None) -> list[dict]:
    """The rows of issue 13 step 4 for every sweep in ``summary`` (sweep -> analyse_sweep);
    ``chapter3``: the record of postprocess.chapter3_check (its check.json) for the last row,
    pending without one."""
    rows = []

    def add(sweep, quantity, thesis_text, v):
        sw = summary.get(sweep) or {}
        if sw.get("status") == "pending" and sw.get("n_run") and v["status"] in ("pass", "fail"):
            # no verdict before a sweep's last run: the partial one is shown as "so far"
            v = {**v, "status": "pending", "so_far": v["status"],
                 "why": f"unfinished ({sw['n_run']} of {sw.get('n_expected')} runs), so far "
                        f"{v['status']}: {v['why']}"}
        rows.append({"sweep": sweep, "quantity": quantity, **v, "thesis": thesis_text})

    for name in ORDER:
        sw, th = summary.get(name) or {"status": "pending"}, THESIS.get(name, {})
        pend = {"status": "pending", "why": "not run"} if sw.get("status") == "pending" and \
            not sw.get("n_run") else None
        if th.get("fc") is not None:
            add(name, "characteristic frequency (Hz)", f"{th['fc']:g} +-{FC_TOL_HZ:g}",
                pend or fc_verdict(sw, th["fc"]))
        elif name == "model-ii-xy":
            fc, edge = sw.get("characteristic_frequency_hz"), sw.get("peak_at_edge")
            v = pend or ({"status": "pass" if edge and sw.get("frequencies_hz") and
                          (sw.get("characteristic_frequency_note") or "").find("highest") >= 0
                          else "fail", "why": f"DEM: {fc if fc is not None else 'none'} "
                          f"({sw.get('characteristic_frequency_note') or ''})"})
            add(name, "response grows up to 3.6 Hz", th.get("fc_note", ""), v)
        io = (sw.get("inside_outside") or {}).get("thesis_range") or {}
        if th.get("amp_in") is not None:
            add(name, "ds amplification inside the thesis range", f"~{th['amp_in']:g} (x/1.5)",
                pend or band_verdict(io.get("amplification_ds_inside"), th["amp_in"],
                                     factor=AMP_FACTOR))
        if name == "model-ii-y":
            st = io.get("ratio_inside_outside")
            if pend or not st or not st.get("n"):
                v = pend or {"status": "pending", "why": "no realisation finished"}
            else:
                ok = st["median"] > AMP_RATIO_MIN and st["q10"] > AMP_RATIO_MIN
                v = {"status": "pass" if ok else "fail", "median": st["median"],
                     "band": [st["q10"], st["q90"]],
                     "why": f"median {st['median']:.3g}, 10 % quantile {st['q10']:.3g} "
                            f"(need > {AMP_RATIO_MIN:g})"}
            add(name, "ds amplification inside / outside", f"~2 / < 0.5: > {AMP_RATIO_MIN:g}", v)
        if th.get("lag_in") is not None:
            add(name, "lag inside the thesis range (s)", f"{th['lag_in']:g} +-{LAG_TOL_S:g}",
                pend or band_verdict(io.get("lag_ds_inside_s"), th["lag_in"], tol_abs=LAG_TOL_S))
        if th.get("excited") is not None:
            add(name, f"excited bricks at {th['fc']:g} Hz", f"{th['excited']} +-20 %",
                pend or band_verdict(sw.get("excited_bricks"), th["excited"],
                                     tol_abs=EXCITED_REL_TOL * th["excited"]))
        if th.get("excited") is not None:
            up, lo = sw.get("excited_upper") or {}, sw.get("excited_lower") or {}
            if pend or not up.get("n"):
                v = pend or {"status": "pending", "why": "no realisation finished"}
            else:
                ok = up["median"] > 0 and lo["median"] > 0
                v = {"status": "pass" if ok else "fail",
                     "why": f"median upper {up['median']:g} + lower {lo['median']:g} bricks"}
            add(name, f"excited portion in two parts at {th['fc']:g} Hz",
                "upper part + stepped lower part", v)
        if th.get("courses") is not None:
            add(name, f"excited courses from the top at {th['fc']:g} Hz", f"{th['courses']} +-1",
                pend or band_verdict(sw.get("excited_courses"), th["courses"],
                                     tol_abs=COURSES_TOL))
        add(name, "survival (no overturning in the cycles)", ">= 80 % at every frequency",
            pend or survival_verdict(sw))
    ii, iii = summary.get("model-ii-y") or {}, summary.get("model-iii-y") or {}
    f2, f3 = ii.get("characteristic_frequency_hz"), iii.get("characteristic_frequency_hz")
    if ii.get("status") == "finished" and iii.get("status") == "finished":
        def fc(x):
            return f"{x:g} Hz" if x is not None else "none (no characteristic frequency)"
        v = {"status": "pass" if (f2 is not None and f3 is not None and f3 < f2) else "fail",
             "why": f"III {fc(f3)}, II {fc(f2)}"}
    else:
        v = {"status": "pending", "why": "needs both sweeps finished"}
    add("model-iii-y vs model-ii-y", "III below II (y)", "2.4 < 2.8", v)
    if chapter3 and chapter3.get("verdict"):
        src = chapter3.get("source") or {}
        v = {**chapter3["verdict"], "why": chapter3["verdict"]["why"] + (
            f"; seeds {chapter3.get('seeds')} re-run at commit {str(src.get('commit'))[:7]}"
            f"{' (dirty tree)' if src.get('dirty') else ''}, engine results revision "
            f"{chapter3.get('engine_results_revision')} (postprocess.chapter3_check)")}
    else:
        v = {"status": "pending", "why": "not checked yet: python -m postprocess.chapter3_check "
                                         "re-runs the frozen set's tilts on this engine"}
    add("chapter 3", "calibrated tilt results unchanged within 5 %", "results/calibration", v)
    return rows


def false_success_checks(plan: dict | None, summary: dict) -> list[dict]:
    """Issue 13 step 5 as explicit rows, each pass / fail / pending with what was checked."""
    rows = []
    sweeps = (plan or {}).get("sweeps") or {}
    frozen = (plan or {}).get("frozen") or {}
    # 1. one parameter set and one seed list for everything
    per = [(n, (summary.get(n) or {}).get("frozen_commit")) for n in sweeps]
    commits = {c for _, c in per if c}
    seeds = {tuple((summary.get(n) or {}).get("seeds") or ()) for n in sweeps
             if (summary.get(n) or {}).get("seeds")}
    ok = len(commits) <= 1 and commits <= {frozen.get("commit")} and len(seeds) <= 1 and \
        (not seeds or seeds == {tuple(plan["seeds"])})
    rows.append({"check": "no per-model or per-frequency parameters or seeds",
                 "status": ("pass" if ok else "fail") if plan else "pending",
                 "why": f"every sweep ran the frozen set of commit {frozen.get('commit')} "
                        f"({frozen.get('path')}) with seeds {plan['seeds'] if plan else '-'}"
                 if ok else f"sweeps disagree: commits {sorted(commits)}, seeds {sorted(seeds)}"})
    # 2. friction unchanged
    fr = {n: s.get("friction") for n, s in sweeps.items()}
    bad = {n: f for n, f in fr.items() if f != MEASURED_FRICTION}
    rows.append({"check": "friction unchanged (measured 0.81)",
                 "status": ("fail" if bad else "pass") if sweeps else "pending",
                 "why": f"not {MEASURED_FRICTION}: {bad}" if bad else
                 f"every case: friction {MEASURED_FRICTION} (case files, not parameters)"})
    # 3. excitation as in the thesis
    bad = {n: s.get("peak_acceleration_m_s2") for n, s in sweeps.items()
           if n in THESIS and s.get("peak_acceleration_m_s2") != THESIS[n]["peak_acc"]}
    cyc = (plan or {}).get("cycles")
    cuts = {n: s["cut"] for n, s in sweeps.items() if s.get("cut")}
    unjustified = {n: s["cycles"] for n, s in sweeps.items()
                   if "cycles" in s and s["cycles"] != cyc and not s.get("cut")}
    rows.append({"check": EXCITATION_CHECK,
                 "status": ("fail" if bad or cyc != DEFAULT_CYCLES or plan.get("max_steps")
                            or unjustified else "pass") if plan else "pending",
                 "why": "; ".join(filter(None, [
                     f"peak accelerations differ: {bad}" if bad else
                     "peak accelerations 1.53 (y) / 1.71 (x) / 1.08 (diagonal) / 1.23 (III) m/s2",
                     f"{cyc:g} cycles, not {DEFAULT_CYCLES}" if plan and cyc != DEFAULT_CYCLES
                     else None,
                     f"cycles cut without a cycles check: {unjustified}" if unjustified else None,
                     "cut: " + ", ".join(f"{n} {c['cycles']:g} cycles ({c['justified_by']}: "
                                         f"{c['verdict']})" for n, c in cuts.items())
                     if cuts else None,
                     f"runs capped at {plan['max_steps']} steps (smoke)" if plan and
                     plan.get("max_steps") else None]))})
    # 4. an edge peak is not a characteristic frequency
    edge = [n for n in sweeps if (summary.get(n) or {}).get("peak_at_edge")]
    leak = [n for n in edge if (summary.get(n) or {}).get("characteristic_frequency_hz")
            is not None]
    ran = [n for n in sweeps if (summary.get(n) or {}).get("n_run")]
    rows.append({"check": "a peak at the edge of a sweep is not a characteristic frequency",
                 "status": "fail" if leak else ("pass" if ran else "pending"),
                 "why": (f"edge peaks reported as null: {edge}" if edge else
                         "no sweep peaked at an edge") if not leak else f"numbers at {leak}"})
    # 5. rocking, not drift or a sliding ratchet (da, dsr), where an amplification is compared:
    # the DEM's effective range where it found one, else the thesis' (its characteristic
    # frequency alone where the thesis gives no range), else the whole sweep
    bad, scopes, pend = [], [], False
    for n in sweeps:
        sw = summary.get(n) or {}
        if sw.get("status") != "finished":
            pend = True
        rr = sw.get("rocking_rows") or {}
        if not rr.get("n"):
            continue
        rng, where = sw.get("effective_range_hz"), "DEM range"
        if not rng:   # analyse_sweep's thesis range (its fc alone where it gives no range)
            rng = ((sw.get("inside_outside") or {}).get("thesis_range") or {}).get("range_hz")
            where = "thesis range"
        if not rng:
            rng, where = [-math.inf, math.inf], "whole sweep"
        for r in rr.get("not_rocking", []):
            if rng[0] - 1e-9 <= r["frequency_hz"] <= rng[1] + 1e-9:
                bad.append(f"{n} {r['frequency_hz']:g} Hz seed {r['seed']}: {r['why']}")
        scopes.append(f"{n} ({where}; {rr['rocking']} of {rr['n']} runs rock over the sweep)")
    rows.append({"check": "amplification is rocking, not drift or a sliding ratchet (da, dsr)",
                 "status": "fail" if bad else ("pending" if pend or not scopes else "pass"),
                 "why": "; ".join(bad[:5]) if bad else
                 f"every surviving run where the amplification is compared rocks: ds at f (first "
                 f"harmonic >= {H1_SHARE_MIN} of the peak-to-peak), da = table + ds phasor within "
                 f"{DA_REL_TOL:.0%}, dsr >= {DSR_SHARE_MIN} ds; " + ", ".join(scopes)})
    # 6. collapses are not a match
    bad = []
    for n in sweeps:
        sw = summary.get(n) or {}
        rng = sw.get("effective_range_hz")
        for f, v in ((sw.get("survival") or {}).get("per_frequency") or {}).items():
            if rng and rng[0] - 1e-9 <= float(f) <= rng[1] + 1e-9 and v["rate"] is not None \
                    and v["rate"] < SURVIVAL_MIN:
                bad.append(f"{n} {f} Hz: {v['survived']}/{v['n']} survive")
    rows.append({"check": "a match by collapsing facades is not a match",
                 "status": "fail" if bad else ("pending" if pend or not sweeps else "pass"),
                 "why": "; ".join(bad) if bad else
                 "amplifications use surviving realisations only; no frequency of a DEM "
                 f"effective range has survival below {SURVIVAL_MIN:.0%}"})
    return rows


# ---- report -------------------------------------------------------------------------------------
def _f(x, spec=".3g"):
    return format(x, spec) if _finite(x) else "-"


def _band(st: dict | None, spec=".3g") -> str:
    if not st or not st.get("n"):
        return "-"
    return f"{_f(st['median'], spec)} ({_f(st['q10'], spec)} - {_f(st['q90'], spec)})"


def read_cycles_checks(out: Path) -> dict:
    """sweep -> [{cycles, full_cycles, verdict}] from the committed cycles-check-<N>.json files."""
    res = {}
    for n in ORDER:
        for path in sorted((Path(out) / n).glob("cycles-check-*.json")):
            d = _read(path)
            if d and d.get("kind") == "prediction-cycles-check":
                res.setdefault(n, []).append({k: d.get(k) for k in (
                    "cycles", "full_cycles", "n_runs", "n_runs_sweep", "verdict")})
    return res


def _io(sw: dict) -> dict:
    return (sw.get("inside_outside") or {}).get("thesis_range") or {}


def acceleration_table(summary: dict) -> list[str]:
    """README lines: a's amplification inside the thesis' range, raw and low-passed (the
    assumed instrument and the cutoff sensitivity), against the thesis' ~2 (Model II y)."""
    cut = [f"{c:g}" for c in sorted(LOWPASS_SENSITIVITY_HZ, reverse=True)]
    L = ["## Acceleration amplification (not a criterion: the instrument filter is assumed)", "",
         f"The DEM's accelerometer is ideal (500 Hz samples of the rigid brick, every impact "
         f"spike kept); the thesis names no sampling rate or filter for its accelerometers "
         f"(Section 4.2.5).  `a_lp` is `a` through an ASSUMED instrument: a Butterworth of "
         f"order {LOWPASS_ORDER} at {LOWPASS_HZ:g} Hz run forward and backward (zero phase; >= "
         f"5 harmonics of the highest test frequency 3.6 Hz).  Because the answer depends on "
         f"the cutoff, the median inside the thesis' range is also given at other cutoffs.", "",
         "| sweep | thesis a inside | a raw | a_lp (" + f"{LOWPASS_HZ:g}" + " Hz) | "
         + " | ".join(f"median at {c} Hz" for c in cut) + " | median raw |",
         "|---|---|---|---|" + "---|" * (len(cut) + 1)]
    for n in ORDER:
        sw = summary.get(n) or {}
        acc = _io(sw).get("acceleration_inside")
        if not sw.get("n_run") or not acc:
            continue
        sens = acc.get("cutoff_sensitivity") or {}
        th = THESIS.get(n, {}).get("a_in")
        L.append(f"| {n} | {f'~{th:g}' if th else '-'} | {_band(acc.get('a'))} | "
                 f"{_band(acc.get('a_lp'))} | "
                 + " | ".join(_f((sens.get(c) or {}).get("median")) for c in cut + ["raw"])
                 + " |")
    return L + [""]


def front_back_table(summary: dict) -> list[str]:
    """README lines: front and back facade amplification inside the thesis' range and their
    ratio, against the thesis' Tables 4.9 - 4.11 (context, not a criterion)."""
    L = ["## Front / back facade (context, not a criterion)", "",
         "The thesis (Section 4.3.4, Tables 4.9 - 4.11) found the back facade (L1 / T1, near the "
         "actuators, carrying the instruments) rocking more than the front one (L2 / T2), with a "
         "front / back ratio constant over frequency: 0.359 (Model II y), 0.618 (II x), 0.587 "
         "(III y).  The front facade carried one accelerometer only (A5, on its centre brick), "
         "so these are accelerometer amplifications; the thesis does not say whether of a or of "
         "its double integral da.  Shown here: da (the headline: free of impact spikes and of "
         "the assumed filter) and a_lp, the front facade's centre accelerometer against the "
         "back one's.  The DEM's box model is symmetric front to back up to the imperfections' "
         "random draws, and its table is rigid and moves the whole base at once: the only "
         "asymmetry it has is the excitation's sign (the sine starts towards one side), which "
         "averages out over the cycles.  It has no reason to reproduce the thesis' ratio, "
         "which the thesis itself puts down to the discrete models and to the side walls "
         "damping the input on its way to the front.", "",
         "| sweep | thesis ratio | front da | back da | ratio da (front / back) | "
         "ratio a_lp | median ratio da per frequency |", "|---|---|---|---|---|---|---|"]
    for n in ORDER:
        sw = summary.get(n) or {}
        fb = _io(sw).get("front_back_inside")
        if not sw.get("n_run") or not fb:
            continue
        per_f = (sw.get("front_back_curves") or {}).get("da") or {}
        th = THESIS.get(n, {}).get("front_back")
        L.append(f"| {n} | {_f(th)} | {_band(fb['da']['front'])} | {_band(fb['da']['back'])} | "
                 f"{_band(fb['da']['ratio'])} | {_band(fb['a_lp']['ratio'])} | "
                 + ", ".join(f"{f}: {_f(st.get('median'))}" for f, st in per_f.items()
                             if st.get("n")) + " |")
    return L + [""]


def cycles_table(checks: dict) -> list[str]:
    """README lines: the cycles check of each sweep that has one (:func:`cycles_check`)."""
    L = ["## Fewer cycles: does the cut change the answer? (issue 13 step 3)", "",
         "The finished runs re-analysed over their first N cycles (no new simulation: a run's "
         "first cycles do not depend on how many follow; module docstring).  Rule: "
         + CYCLES_RULE + ".", ""]
    if not checks:
        return L + ["No cycles check yet (`--cycles-check N`).", ""]

    def med(v):
        return f"{_f(v.get('short'))} / {_f(v.get('full'))}"
    L += ["| sweep | N / full cycles | runs compared | f_c (Hz) | ds inside | ds outside | "
          "lowest survival | answer |", "|---|---|---|---|---|---|---|---|"]
    for n, lst in checks.items():
        for c in lst:
            v = c["verdict"]
            fc, sv = v["characteristic_frequency"], v["survival"]
            ans = verdict_text(v)
            n_all = c.get("n_runs_sweep", c.get("n_runs"))
            L.append(f"| {n} | {c['cycles']:g} / {c['full_cycles']:g} | "
                     f"{c.get('n_runs')} of {n_all} | "
                     f"{fc['short'] if fc['short'] is not None else 'none'} / "
                     f"{fc['full'] if fc['full'] is not None else 'none'} | "
                     f"{med(v['amplification_ds_inside'])} | "
                     f"{med(v['amplification_ds_outside'])} | "
                     f"{_f(sv['short'], '.0%')} / {_f(sv['full'], '.0%')} | {ans} |")
    return L + [""]


def report(out: Path, frozen: dict, command: str, runs: Path | None = None) -> dict:
    """summary.json and README.md of ``out`` from plan.json and the sweeps' points.json."""
    from dem.output.atomic import write_json

    out = Path(out)
    out.mkdir(parents=True, exist_ok=True)
    plan = _read(out / "plan.json")
    summary = {n: analyse_sweep(n, _read(points_path(out, n))) for n in ORDER}
    crit = criteria(summary, _read(out / CHAPTER3_CHECK))
    checks = false_success_checks(plan, summary)
    cycles = read_cycles_checks(out)
    cpu = sum((s.get("cpu_seconds") or 0.0) for s in summary.values())
    data = {"kind": "prediction-summary", "command": command,
            "frozen": {k: frozen[k] for k in ("path", "parameters", "provenance", "sha256",
                                              "commit")},
            "freezing_commit": frozen["commit"], "plan": plan, "cpu_seconds": cpu,
            "low_pass": {"quantities": ["a_lp", "a_front_lp"], "cutoff_hz": LOWPASS_HZ,
                         "order": LOWPASS_ORDER, "zero_phase": True,
                         "sensitivity_cutoffs_hz": list(LOWPASS_SENSITIVITY_HZ),
                         "note": "an ASSUMED instrument (the thesis gives no sampling rate or "
                                 "filter); not a criterion; the unfiltered 'a' is kept"},
            "sweeps": summary, "criteria": crit, "false_success_checks": checks,
            "cycles_checks": cycles}
    write_json(out / "summary.json", data, indent=1)
    L = ["# Blind prediction of Chapter 4 (issue 13, steps 3-5)", "",
         f"Generated by `{command}`; `--report` rebuilds this page and summary.json from "
         "plan.json and the committed `<sweep>/points.json` files.", "",
         f"Frozen set: `{frozen['path']}`, frozen in commit `{frozen['commit']}` "
         f"(the last commit that changed it): `{json.dumps(frozen['parameters'])}`"
         + (f"; provenance {json.dumps(frozen['provenance'])}" if frozen["provenance"] else ""),
         "",
         f"Plan (written before the first run): seeds {plan['seeds'] if plan else '-'}, "
         f"{plan['cycles'] if plan else '-'} cycles after settling"
         + "".join(f"; {n} CUT to {c['cycles']:g} cycles ({c['justified_by']}: {c['verdict']})"
                   for n, c in ((n, s.get("cut")) for n, s in
                                ((plan or {}).get("sweeps") or {}).items()) if c)
         + (f", runs capped at {plan['max_steps']} steps (SMOKE, not a prediction)"
            if plan and plan.get("max_steps") else "") + f".  CPU time so far: {cpu:.0f} s.", "",
         "Amplification of ds (thesis Section 4.2.5), median (10 % - 90 %) over the realisations "
         "that survived; inside / outside: the per-realisation means over the sweep frequencies "
         "inside / outside the thesis' effective range.  The characteristic frequency is the peak "
         "of the median curve by postprocess.sweep.effective_range, null when the peak is at an "
         "edge of the sweep or not clear.  The acceleration and the front / back facades: "
         "their own tables below (not criteria).", "",
         "## Per sweep", "",
         "| sweep | done | thesis f_c (Hz) | DEM f_c (Hz) | per-seed f_c | DEM range (Hz) | "
         "ds inside (thesis range) | ds outside | lag inside (s) | excited bricks | courses | "
         "survival (lowest f) | CPU s |", "|---|---|---|---|---|---|---|---|---|---|---|---|---|"]
    for n in ORDER:
        s, th = summary[n], THESIS.get(n, {})
        if s.get("status") == "pending" and not s.get("n_run"):
            L.append(f"| {n} | 0 | {th.get('fc') or th.get('fc_note', '-')} | not run | | | | | "
                     f"| | | | |")
            continue
        io = (s.get("inside_outside") or {}).get("thesis_range") or {}
        fc = s.get("characteristic_frequency_hz")
        fc_txt = _f(fc, "g") if fc is not None else \
            f"none: {s.get('characteristic_frequency_note')}"
        sv = (s.get("survival") or {}).get("min_rate")
        L.append(f"| {n} | {s['n_run']}/{s['n_expected']} | "
                 f"{th.get('fc') if th.get('fc') is not None else th.get('fc_note', '-')} | "
                 f"{fc_txt} | {_band(s.get('characteristic_frequency_band'), 'g')} | "
                 f"{s.get('effective_range_hz') or '-'} | "
                 f"{_band(io.get('amplification_ds_inside'))} | "
                 f"{_band(io.get('amplification_ds_outside'))} | "
                 f"{_band(io.get('lag_ds_inside_s'))} | {_band(s.get('excited_bricks'), 'g')} | "
                 f"{_band(s.get('excited_courses'), 'g')} | "
                 f"{f'{sv:.0%}' if sv is not None else '-'} | {_f(s.get('cpu_seconds'), '.0f')} |")
    L += [""] + acceleration_table(summary) + front_back_table(summary) + cycles_table(cycles)
    L += ["## Success criteria (issue 13 step 4)", "",
          "Each criterion passes only when the median agrees within the tolerance AND the thesis "
          "value lies inside the 10-90 % band of the realisations.", "",
          "| sweep | quantity | thesis | status | detail |", "|---|---|---|---|---|"]
    for r in crit:
        L.append(f"| {r['sweep']} | {r['quantity']} | {r['thesis']} | **{r['status']}** | "
                 f"{r.get('why', '')} |")
    L += ["", "## False successes rejected (issue 13 step 5)", "",
          "| check | status | detail |", "|---|---|---|"]
    for r in checks:
        L.append(f"| {r['check']} | **{r['status']}** | {r['why']} |")
    L += ["", "## Figures", ""]
    for n in ORDER:
        s = summary[n]
        if not s.get("n_run"):
            continue
        if plot_sweep(out / n / "amplification.png", n, s):
            L.append(f"![{n}]({n}/amplification.png)")
        exc = copy_excited(out, n, s, runs)
        if exc:
            L.append(f"![{n} excited portion]({exc})")
        L.append("")
    (out / "README.md").write_text("\n".join(L) + "\n")
    return data


def plot_sweep(path: Path, name: str, sw: dict) -> bool:
    """Amplification of ds, da and dsr against frequency: median with the 10-90 % band over the
    surviving realisations; the thesis' characteristic frequency, effective range and
    amplifications (REFERENCE.md, Chapter 4) drawn over them."""
    curves = sw.get("amplification_curves") or {}
    ds = curves.get("ds") or {}
    fs = sorted(float(f) for f, st in ds.items() if st.get("n"))
    if not fs:
        return False
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    from dem.output.atomic import savefig

    th = THESIS.get(name, {})
    fig, ax = plt.subplots(figsize=(7, 4))
    for q, c in (("ds", "C0"), ("da", "C1"), ("dsr", "C2")):
        st = [(curves.get(q) or {}).get(f"{f:g}") or {} for f in fs]
        ok = [i for i, x in enumerate(st) if x.get("n")]
        if not ok:
            continue
        f_ok = [fs[i] for i in ok]
        ax.fill_between(f_ok, [st[i]["q10"] for i in ok], [st[i]["q90"] for i in ok], color=c,
                        alpha=0.2)
        ax.plot(f_ok, [st[i]["median"] for i in ok], "o-", color=c,
                label=f"{q}: median, 10-90 % band")
    if th.get("range"):
        ax.axvspan(th["range"][0], th["range"][1], color="0.5", alpha=0.15,
                   label="thesis effective range")
    if th.get("fc"):
        ax.axvline(th["fc"], color="k", ls="--", lw=1, label=f"thesis f_c {th['fc']:g} Hz")
    if th.get("amp_in") is not None and th.get("range"):
        ax.plot(th["range"], [th["amp_in"]] * 2, "k-", lw=3, label="thesis ds inside")
    if sw.get("characteristic_frequency_hz") is not None:
        ax.axvline(sw["characteristic_frequency_hz"], color="C3", lw=1,
                   label=f"DEM f_c {sw['characteristic_frequency_hz']:g} Hz")
    ax.set_xlabel("frequency (Hz)")
    ax.set_ylabel("amplification")
    ax.set_title(f"{name}: {len(sw.get('seeds') or [])} realisations"
                 + (" (SMOKE: capped steps)" if sw.get("smoke") else ""))
    ax.legend(fontsize=7)
    fig.tight_layout()
    savefig(fig, path, dpi=100)
    plt.close(fig)
    return True


def copy_excited(out: Path, name: str, sw: dict, runs: Path | None = None) -> str | None:
    """Copy the excited-portion drawing (postprocess.excited_output, excited.png) of the
    realisation whose excited-brick count is nearest the median, at the frequency of
    ``excited_at_hz``, from the raw runs to ``<out>/<sweep>/``; its path relative to out.  The
    drawings of other realisations copied there before (the median moved) are removed."""
    import shutil

    f, med = sw.get("excited_at_hz"), (sw.get("excited_bricks") or {}).get("median")
    data = _read(points_path(out, name)) or {}
    rows = [r for r in data.get("rows") or [] if f is not None
            and abs(r["frequency_hz"] - f) < 1e-9 and survived(r)
            and _finite((r.get("excited") or {}).get("n_excited"))]
    if not rows or med is None:
        return None
    r = min(rows, key=lambda r: (abs(r["excited"]["n_excited"] - med), r["seed"]))
    from dem.run.sweep import point_name

    src = (runs or Path(out) / "runs") / name / f"seed-{r['seed']}" / point_name(f) / "excited.png"
    if not src.is_file():
        return None
    dst = Path(out) / name / f"excited-{f:g}Hz-seed{r['seed']}.png"
    shutil.copyfile(src, dst)
    for old in dst.parent.glob("excited-*Hz-seed*.png"):
        if old != dst:
            old.unlink()
    return str(dst.relative_to(out))


def _command(args) -> str:
    cmd = ["python -m postprocess.prediction_study", "--frozen", _rel(Path(args.frozen)),
           "--out", _rel(Path(args.out))]
    if args.realisations != DEFAULT_REALISATIONS:
        cmd += ["--realisations", str(args.realisations)]
    if args.cycles != DEFAULT_CYCLES:
        cmd += ["--cycles", f"{args.cycles:g}"]
    if args.max_steps is not None:
        cmd += ["--max-steps", str(args.max_steps)]
    if args.cycles_check is not None:
        cmd += ["--cycles-check", f"{args.cycles_check:g}"]
    return " ".join(cmd)


def _subset(text: str | None, kind, flag: str) -> list | None:
    """A comma-separated --seeds / --frequencies value as a list (None: all of the plan's)."""
    if text is None:
        return None
    try:
        vals = [kind(x) for x in text.split(",") if x.strip()]
    except ValueError:
        raise PredictionInputError(f"{flag}: expected comma-separated numbers, got {text!r}")
    if not vals:
        raise PredictionInputError(f"{flag}: empty")
    return vals


def main(argv=None) -> int:
    ap = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawTextHelpFormatter)
    ap.add_argument("--frozen", type=Path, default=DEFAULT_FROZEN)
    ap.add_argument("--out", type=Path, default=ROOT / "results" / "prediction")
    ap.add_argument("--runs", type=Path, default=None, help="raw runs (default <out>/runs, "
                                                            "git-ignored)")
    ap.add_argument("--only", default=None, help=f"comma-separated sweeps of {list(ORDER)}")
    ap.add_argument("--realisations", type=int, default=DEFAULT_REALISATIONS)
    ap.add_argument("--cycles", type=float, default=DEFAULT_CYCLES)
    ap.add_argument("--workers", type=int, default=None)
    ap.add_argument("--max-steps", type=int, default=None, help="cap every run (smoke tests)")
    ap.add_argument("--report", action="store_true", help="only rebuild the report")
    ap.add_argument("--cycles-check", type=float, default=None, metavar="N",
                    help="no runs: re-analyse the finished runs of the sweeps (--only) over "
                         "their first N cycles, compare with the full cycles, then report")
    ap.add_argument("--cut-cycles", type=float, default=None, metavar="N",
                    help=f"run the sweeps of --only (not {FULL_SWEEP}, not yet planned) at N "
                         f"cycles; only once {FULL_SWEEP} finished in full and its "
                         f"cycles-check-N.json says the answer is unchanged")
    ap.add_argument("--seeds", default=None, metavar="S,S,...",
                    help="run only these of the plan's seeds (share a sweep between processes "
                         "or machines; the plan does not change)")
    ap.add_argument("--frequencies", default=None, metavar="F,F,...",
                    help="run only these of each sweep's frequencies (Hz; as --seeds)")
    ap.add_argument("--drain-file", type=Path, default=None,
                    help="once this file exists no new run starts, the runs in flight finish, "
                         "then the report is written (default <runs>/DRAIN); SIGTERM instead "
                         "stops at once: the runs in flight resume from their last restart "
                         "point on the next call")
    args = ap.parse_args(argv)
    try:
        only_seeds = _subset(args.seeds, int, "--seeds")
        only_freqs = _subset(args.frequencies, float, "--frequencies")
        frozen = load_frozen(args.frozen)
        names = sweep_names(args.only)
        if not args.report and args.cycles_check is None:
            new = make_plan(frozen, names, args.realisations, args.cycles, args.max_steps)
            if args.cut_cycles is not None:
                if FULL_SWEEP in names:
                    raise PredictionInputError(f"--cut-cycles: {FULL_SWEEP} runs in full (issue "
                                               f"13 step 3); leave it out of --only")
                cut = cut_record(args.out, _read(Path(args.out) / "plan.json"), args.cut_cycles)
                for n in names:
                    new["sweeps"][n].update(cycles=args.cut_cycles, cut=cut)
            plan = write_plan(args.out, new)
        else:
            plan = _read(Path(args.out) / "plan.json")
            if plan is not None and plan["frozen"]["commit"] != frozen["commit"]:
                raise PredictionInputError(
                    f"{args.out}/plan.json: made with frozen commit {plan['frozen']['commit']}, "
                    f"{args.frozen} is now at {frozen['commit']}")
        if plan is not None and only_seeds is not None and \
                not set(only_seeds) <= set(plan["seeds"]):
            raise PredictionInputError(f"--seeds {args.seeds}: not among the plan's seeds "
                                       f"{plan['seeds']}")
        if plan is not None and only_freqs is not None:
            known = [f for n in names for f in plan["sweeps"].get(n, {}).get("frequencies_hz", [])]
            bad = [f for f in only_freqs if not any(abs(f - g) < 1e-9 for g in known)]
            if bad:
                raise PredictionInputError(f"--frequencies: {bad} Hz not in the plan of "
                                           f"{', '.join(names)}")
        if args.cycles_check is not None:
            runs = args.runs or Path(args.out) / "runs"
            have = [n for n in names if points_path(args.out, n).is_file()]
            if not have:
                raise PredictionInputError(
                    f"--cycles-check: no {points_path(args.out, names[0]).name} of "
                    f"{', '.join(names)} under {args.out}: nothing to check")
            for n in have:
                v = cycles_check(args.out, runs, n, args.cycles_check)["verdict"]
                print(f"{n}: {args.cycles_check:g} cycles: {verdict_text(v)}", file=sys.stderr)
    except PredictionInputError as err:
        print(f"error: {err}", file=sys.stderr)
        return 2
    states = []
    if not args.report and args.cycles_check is None:
        from dem.batch import DRAIN_FILE, clear_drain_file

        runs = args.runs or Path(args.out) / "runs"
        drain = args.drain_file or runs / DRAIN_FILE
        clear_drain_file(drain, lambda m: print(m, file=sys.stderr))
        dem_child.install_signal_handlers()
        for n in names:
            if dem_child.stopped() or drain.exists():
                break
            states.append(run_sweep_point(args.out, runs, n, plan, args.workers,
                                          drain_file=drain, only_seeds=only_seeds,
                                          only_freqs=only_freqs))
    report(args.out, frozen, _command(args), args.runs)
    print(f"{args.out}/summary.json, {args.out}/README.md", file=sys.stderr)
    return 0 if all(s in ("skipped", "finished") for s in states) else 1


if __name__ == "__main__":
    sys.exit(main())
