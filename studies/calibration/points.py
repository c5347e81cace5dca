"""One (candidate, specimen) point: a ``dem ensemble`` child run, its committed record
``<out>/<candidate>/<specimen>/ensemble.json`` and whether it is finished.
"""

from __future__ import annotations

import json
import time
from pathlib import Path

import yaml

from studies.calibration.select import is_perfect
from studies.calibration.specimens import fingerprint, realisations_for, specimen_case
from studies.kit import child as dem_child
from studies.kit.provenance import rel, source_state
from studies.kit.records import read_json


# ---- running one point --------------------------------------------------------------------------
def _realisation_extras(run_dir: Path) -> dict:
    """Per-realisation numbers the ensemble's scalars leave out, from its summary.json."""
    try:
        s = json.loads((run_dir / "summary.json").read_text())
    except (OSError, ValueError):
        return {}
    m = s.get("mechanism") if isinstance(s.get("mechanism"), dict) else {}
    col = s.get("collapse") or {}
    out = {"engine_seconds": s.get("wall_seconds"), "compile_seconds": s.get("compile_seconds"),
           "steps": s.get("steps"), "sim_time_s": s.get("sim_time"), "n_blocks": s.get("n_blocks"),
           "relaxations": col.get("relaxations"), "n_moved": col.get("n_moved"),
           "overturning_mass_fraction": m.get("overturning_mass_fraction"),
           "crack_angle_deg": m.get("crack_angle_deg"),
           "collapsed_blocks": (m.get("collapsed") or {}).get("n_blocks"),
           "n_moving": m.get("n_moving")}
    return {k: v for k, v in out.items() if v is not None}


def point_path(out: Path, candidate: str, specimen: str) -> Path:
    return Path(out) / candidate / specimen / "ensemble.json"


def point_finished(data: dict | None, fp: str | None = None) -> bool:
    """A committed point is finished when every one of its N realisations finished ok (and, if
    given, its fingerprint is ``fp``)."""
    if not data or "calibration" not in data:
        return False
    cal = data["calibration"]
    if fp is not None and cal.get("fingerprint") != fp:
        return False
    agg = data.get("aggregate") or {}
    return bool(cal.get("finished")) and agg.get("n_ok") == cal.get("n_realisations")


def run_point(out: Path, runs: Path, candidate: str, params: dict, specimen: str,
              spec: dict, realisations: int, max_steps: int | None = None,
              log=print, record: dict | None = None, rate: float | None = None) -> str:
    """Run (or skip) one point; returns "skipped" (already finished), "finished", "pending"
    (interrupted or a realisation failed) or "failed" (dem ensemble refused the case).
    ``record``: more fields for the point's ``calibration`` block (the held-out points: the
    frozen set's file and commit).  ``rate``: a constant-rate tilt (:func:`specimen_case`)."""
    name = f"cal-{candidate}-{specimen}" + ("" if rate is None else f"-rate-{rate:g}")
    case = specimen_case(spec["path"], params, name, rate)
    n = realisations_for(params, realisations)
    fp = fingerprint(case, n, max_steps)
    dest = point_path(out, candidate, specimen)
    old = read_json(dest)
    if point_finished(old, fp):
        return "skipped"
    ens_dir = Path(runs) / candidate / specimen
    case_file = Path(runs) / candidate / f"{specimen}.yaml"
    case_file.parent.mkdir(parents=True, exist_ok=True)
    case_file.write_text(yaml.safe_dump(case.model_dump(mode="json"), sort_keys=False))
    cmd = ["ensemble", str(case_file), "--out", str(ens_dir), "--realisations", str(n),
           "--seed", "0", "--workers", "1"]
    if max_steps is not None:
        cmd += ["--max-steps", str(max_steps)]
    log(f"[{time.strftime('%H:%M:%S', time.gmtime())} UTC] {candidate} / {specimen}: {n} realisation(s) ...")
    rc, cpu, wall = dem_child.run_dem(cmd, log)
    data = read_json(ens_dir / "ensemble.json")
    if data is None:
        log(f"    dem ensemble exit {rc}: no ensemble.json")
        return "failed"
    prev = (old or {}).get("calibration") or {}
    same = prev.get("fingerprint") == fp
    rows = data.get("realisations") or []
    extras = {r["name"]: _realisation_extras(ens_dir / r["name"]) for r in rows
              if r.get("status") == "ok"}
    finished = (data.get("aggregate") or {}).get("n_ok") == n
    data["source"] = rel(case_file)
    data["calibration"] = {
        "candidate": candidate, "specimen": specimen, "specimen_case": rel(spec["path"]),
        "kind": spec["kind"], "l_over_h": spec["l_over_h"],
        "parameters": params, "friction": case.material.friction,
        "normal_stiffness_pa_per_m": case.material.normal_stiffness,
        "n_realisations": n, "seeds": list(range(n)), "max_steps": max_steps,
        "deterministic": is_perfect(params), "fingerprint": fp, "finished": finished,
        "cpu_seconds": (prev.get("cpu_seconds", 0.0) if same else 0.0) + cpu,
        "wall_seconds": (prev.get("wall_seconds", 0.0) if same else 0.0) + wall,
        "sessions": (prev.get("sessions", 0) if same else 0) + 1,
        "exit_code": rc, "source": source_state(checkout=True), "extras": extras, **(record or {})}
    from dem.output.atomic import write_json

    dest.parent.mkdir(parents=True, exist_ok=True)
    write_json(dest, data, indent=1)
    state = "finished" if finished else "pending"
    log(f"    -> {state}: {cpu:.0f} CPU-s, {wall:.0f} s this call")
    return state


