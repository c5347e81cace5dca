"""One (candidate, specimen) point: a ``dem ensemble`` child run, its committed record
``<out>/<candidate>/<specimen>/ensemble.json`` and whether it is finished.
"""

from __future__ import annotations

import json
from pathlib import Path

from studies.calibration.select import is_perfect
from studies.calibration.specimens import realisations_for, specimen_case
from studies.kit import study as kit
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


class Ensembles(kit.Study):
    """Points of the calibration's kind on the kit's loop: one ``dem ensemble`` of N
    realisations (seeds 0..N-1) per (candidate, specimen[, rate]); the record
    ``<out>/<candidate>/<specimen>/ensemble.json`` with its ``calibration`` block, CPU and wall
    seconds adding up over the sessions of one fingerprint.  No drain file: a session stops on
    signals and its stop time.  ``after(point, state)``: called once each point is done with.
    The points run in the order :meth:`add` planned them."""

    def __init__(self, realisations: int, max_steps: int | None = None, after=None):
        self.realisations, self.max_steps = realisations, max_steps
        self._planned, self._after = [], after

    def add(self, *args, **kwargs) -> None:
        """Plan one more point (the arguments of :meth:`point`; its case is built when it
        comes)."""
        self._planned.append((args, kwargs))

    def point(self, out: Path, runs: Path, candidate: str, params: dict, specimen: str,
              spec: dict, record: dict | None = None, rate: float | None = None) -> kit.Point:
        """The point of ``candidate`` (parameters ``params``) on ``specimen`` (``spec``), its
        record in ``out``, its runs in ``runs``; ``record``: more fields for its calibration
        block; ``rate``: a constant-rate tilt (:func:`specimen_case`)."""
        name = f"cal-{candidate}-{specimen}" + ("" if rate is None else f"-rate-{rate:g}")
        case = specimen_case(spec["path"], params, name, rate)
        n = realisations_for(params, self.realisations)
        return kit.Point(name=specimen, case=case, plan=(n, self.max_steps), form="bars",
                         out=Path(out), runs=Path(runs) / candidate, ledger=None,
                         owner={"candidate": candidate, "params": params, "spec": spec,
                                "n": n, "record": record or {}})

    def points(self):
        for args, kwargs in self._planned:
            yield self.point(*args, **kwargs)

    def todo(self, p):
        return not point_finished(read_json(self._dest(p)), p.fingerprint)

    @staticmethod
    def _dest(p) -> Path:
        return point_path(p.out, p.owner["candidate"], p.name)

    def describe(self, p, todo):
        return f"{p.owner['candidate']} / {p.name}: {p.owner['n']} realisation(s) ..."

    def command(self, p, todo, drain):
        cmd = ["ensemble", str(p.case_file), "--out", str(p.run_dir), "--realisations",
               str(p.owner["n"]), "--seed", "0", "--workers", "1"]
        if self.max_steps is not None:
            cmd += ["--max-steps", str(self.max_steps)]
        return cmd

    def ran(self, p, rc, cpu, wall, log=print):
        """(The CPU seconds go to the point's own record; :meth:`record` logs them.)"""

    def record(self, p, result, log=print) -> str:
        """Write the point's record from its ensemble; its state: "finished", "pending"
        (interrupted or a realisation failed) or "failed" (dem ensemble refused the case: no
        ensemble.json)."""
        rc, cpu, wall = result
        o = p.owner
        n, fp, params, spec = o["n"], p.fingerprint, o["params"], o["spec"]
        data = read_json(p.run_dir / "ensemble.json")
        if data is None:
            log(f"    dem ensemble exit {rc}: no ensemble.json")
            return "failed"
        dest = self._dest(p)
        prev = (read_json(dest) or {}).get("calibration") or {}
        same = prev.get("fingerprint") == fp
        rows = data.get("realisations") or []
        extras = {r["name"]: _realisation_extras(p.run_dir / r["name"]) for r in rows
                  if r.get("status") == "ok"}
        finished = (data.get("aggregate") or {}).get("n_ok") == n
        data["source"] = rel(p.case_file)
        data["calibration"] = {
            "candidate": o["candidate"], "specimen": p.name, "specimen_case": rel(spec["path"]),
            "kind": spec["kind"], "l_over_h": spec["l_over_h"],
            "parameters": params, "friction": p.case.material.friction,
            "normal_stiffness_pa_per_m": p.case.material.normal_stiffness,
            "n_realisations": n, "seeds": list(range(n)), "max_steps": self.max_steps,
            "deterministic": is_perfect(params), "fingerprint": fp, "finished": finished,
            "cpu_seconds": (prev.get("cpu_seconds", 0.0) if same else 0.0) + cpu,
            "wall_seconds": (prev.get("wall_seconds", 0.0) if same else 0.0) + wall,
            "sessions": (prev.get("sessions", 0) if same else 0) + 1,
            "exit_code": rc, "source": source_state(checkout=True), "extras": extras,
            **o["record"]}
        from dem.output.atomic import write_json

        dest.parent.mkdir(parents=True, exist_ok=True)
        write_json(dest, data, indent=1)
        state = "finished" if finished else "pending"
        log(f"    -> {state}: {cpu:.0f} CPU-s, {wall:.0f} s this call")
        return state

    def after(self, p, state):
        if self._after is not None:
            self._after(p, state)


def run_point(out: Path, runs: Path, candidate: str, params: dict, specimen: str,
              spec: dict, realisations: int, max_steps: int | None = None,
              log=print, record: dict | None = None, rate: float | None = None) -> str:
    """Run (or skip) one point; returns "skipped" (already finished), "finished", "pending"
    (interrupted or a realisation failed) or "failed" (dem ensemble refused the case).
    ``record``: more fields for the point's ``calibration`` block (the held-out points: the
    frozen set's file and commit).  ``rate``: a constant-rate tilt (:func:`specimen_case`)."""
    study = Ensembles(realisations, max_steps)
    return kit.run_point(study, study.point(out, runs, candidate, params, specimen, spec,
                                            record, rate), log=log)