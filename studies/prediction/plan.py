"""The frozen set (protocol step 2: a committed YAML file under studies/calibration/) and the
pre-registered plan written before the first run (``<out>/plan.json``).
"""

from __future__ import annotations

import hashlib
import json
import sys
import time
from pathlib import Path

import yaml

from studies.kit.provenance import git_state, NotInGit, source_state
from studies.kit.study import fingerprint as kit_fingerprint
from studies.prediction.protocol import (ORDER, PARAM_KEYS, PredictionInputError, PROVENANCE_KEYS,
                                         ROOT)
from studies.shake.study import CASES, SWEEPS


# ---- the frozen set -----------------------------------------------------------------------------
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
    or modified file, and one outside ``studies/`` of its repository (a study's parameter sets
    live with it: studies/calibration/frozen.yaml).  The commit is the last one that changed the
    file's content (studies.kit.provenance.content_commit: a move does not count)."""
    path = Path(path)
    if not path.is_file():
        raise PredictionInputError(f"{path}: frozen parameter file missing (the freeze, issue 13 "
                                   f"step 2, has not happened: commit it under studies/ first)")
    text = path.read_text()
    try:
        data = yaml.safe_load(text)
    except yaml.YAMLError as err:
        raise PredictionInputError(f"{path}: not valid YAML ({err})") from None
    params = validate_frozen_data(data, str(path))
    try:
        g = git_state(path)
    except NotInGit as err:
        raise PredictionInputError(str(err)) from None
    if not g["rel"].startswith("studies/"):
        raise PredictionInputError(f"{path}: the frozen set must live under studies/ of its "
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
    """The sweep's frequencies (Hz): studies.shake.study.SWEEPS (Appendix I / Chapter 4)."""
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
    return kit_fingerprint(case, list(freqs), list(seeds), cycles, max_steps)


def sweep_cycles(plan: dict, name: str) -> float:
    """The cycles one sweep of the plan runs: its cut (:func:`cut_record`) or the plan's."""
    return plan["sweeps"][name].get("cycles", plan["cycles"])


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




def frozen_or_none(path) -> dict | None:
    """:func:`load_frozen` for a study that runs the frozen set (the sensitivity and resonance
    studies): None after printing ``error: ...`` on stderr, and the caller exits 2."""
    try:
        return load_frozen(path)
    except PredictionInputError as err:
        print(f"error: {err}", file=sys.stderr)
        return None
