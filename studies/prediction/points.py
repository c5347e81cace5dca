"""One sweep's committed record, ``<out>/<sweep>/points.json``: one row per (seed, frequency) from
the runs' sweep.json, merged with the finished rows already committed, under a lock.
"""

from __future__ import annotations

from pathlib import Path

from studies.kit.provenance import rel, source_state
from studies.kit.records import locked, read_json
from studies.kit.study import records_path
from studies.prediction.plan import sweep_cycles
from studies.prediction.protocol import ROW_QUANTITIES


# ---- running one sweep --------------------------------------------------------------------------
def points_path(out: Path, name: str) -> Path:
    return records_path(Path(out) / name)


SURVIVAL_KEYS = ("verdict", "n_fallen", "first_fall_time_s", "first_fall_cycle", "by_wall")


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
            "mechanism": {**{k: mech.get(k) for k in ("response", "corners", "line")},
                          # the instrumented corner bricks' motion (postprocess.excited):
                          # peak-to-peak ds of each (m), first-harmonic twist about z (deg)
                          "pp_corner_m": mech.get("pp_corner_m"),
                          "corner_twist_h1_deg":
                              (mech.get("corner_twist") or {}).get("h1_amplitude_deg")},
            "note": p.get("note")})
        surv = p.get("survival")
        if surv:   # postprocess.survival's verdict (points analysed before it have none)
            row["survival"] = {k: surv.get(k) for k in SURVIVAL_KEYS}
    return row


def collect_rows(runs_dir: Path, seeds, freqs) -> list[dict]:
    """Rows for every (seed, frequency) from ``runs_dir/seed-<k>/sweep.json``; pending where
    the sweep or the point is not there."""
    rows = []
    for s in seeds:
        data = read_json(Path(runs_dir) / f"seed-{s}" / "sweep.json") or {}
        by_f = {round(p["frequency_hz"], 9): p for p in data.get("points", [])}
        for f in freqs:
            p = by_f.get(round(f, 9))
            rows.append(row_from_point(s, p) if p else
                        {"seed": s, "frequency_hz": f, "run_status": "pending",
                         "analysis_status": None})
    return rows


def point_key(seed: int, f: float) -> tuple[int, float]:
    return int(seed), round(float(f), 9)


def finished_rows(data: dict | None, fp: str) -> dict:
    """{(seed, frequency): row} of the finished rows of a points.json made for fingerprint
    ``fp`` (none for another fingerprint: another case, seed list, cycles or engine)."""
    if not data or (data.get("prediction") or {}).get("fingerprint") != fp:
        return {}
    return {point_key(r["seed"], r["frequency_hz"]): r for r in data.get("rows") or []
            if r.get("run_status") == "ok"}


def merge_rows(fresh: list[dict], kept: dict) -> list[dict]:
    """The rows of a sweep from this machine's run directories (``fresh``, in plan order) and
    the finished rows of the committed points.json (``kept``, :func:`finished_rows`): a finished
    fresh row wins, else a finished kept row, else the fresh one (pending or failed).  So a
    point finished in an earlier session counts even where its raw run directory is gone (a new
    checkout, another machine), and is never run again."""
    out = []
    for r in fresh:
        k = kept.get(point_key(r["seed"], r["frequency_hz"]))
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


def update_points(dest: Path, name: str, plan: dict, case, case_file: Path, fp: str,
                  fresh: list[dict], cpu: float, wall: float, rc: int | None,
                  new_session: bool) -> dict:
    """Merge ``fresh`` rows into ``dest`` (points.json; :func:`merge_rows` with the finished
    rows already there) and add this call's CPU and wall seconds, under a lock; returns the
    written data."""
    from dem.output.atomic import write_json

    freqs, seeds = plan["sweeps"][name]["frequencies_hz"], plan["seeds"]
    frozen = plan["frozen"]
    with locked(dest):
        old = read_json(dest)
        prev = (old or {}).get("prediction") or {}
        same = prev.get("fingerprint") == fp
        rows = merge_rows(fresh, finished_rows(old, fp))
        data = {"kind": "prediction-sweep", "sweep": name, "rows": rows, "prediction": {
            "sweep": name, "case_file": plan["sweeps"][name]["case_file"],
            "run_case": rel(case_file), "frozen": frozen, "seeds": seeds,
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


