"""A study's shape: what a study declares and what the kit owns.

A study declares its **points** (:class:`Point`: one named case, the plan besides the case that
its records must match, where its records and raw runs go, and for a swept point its seed), what
a point still lacks (``todo``), the ``dem`` command that does it, how the point's records are
brought up to date from its run directory (``record``) and its report.  The kit owns:

* the paths: this checkout's ``ROOT`` (:mod:`studies.kit.provenance`), ``results/<study>/``
  (:func:`results_dir`) and ``runs/<study>/`` (:func:`runs_dir`, git-ignored);
* the fingerprint (:func:`fingerprint`): what a finished point must match to be skipped, the
  case's identity (dem.case.identity), the study's plan and the engine's results revision
  (dem.engine.RESULTS_REVISION);
* the records: ``<out>/points.json`` under its lock (:mod:`studies.kit.records`), and for a
  study of ``dem sweep`` rows the finished rows kept over pending ones (:func:`finished_rows`,
  :func:`merge_rows`);
* the resumable loop (:func:`run`, one point :func:`run_point`): the drain file, the signals
  and the stop time (:mod:`studies.kit.session`), the case file written, the child run with its
  CPU seconds added to ``<out>/cpu.json``, the records brought up to date after each point; a
  finished point is never run again, so a session cut anywhere resumes where it stopped.

What is special to a study (a stepped specimen resumed from its restart point, a plan fixed
before the runs) stays in the study's hooks.
"""

from __future__ import annotations

import hashlib
import json
import time
from dataclasses import dataclass
from pathlib import Path
from typing import Any

from studies.kit import child, session
from studies.kit.provenance import ROOT, rel, source_state
from studies.kit.records import merge_json, read_json

__all__ = ["ROOT", "RECORDS", "Point", "Study", "fingerprint", "finished_rows", "merge_rows",
           "records", "records_path", "results_dir", "row_key", "run", "run_point", "runs_dir",
           "sweep_args", "write_case"]

#: the file of a study's committed records in its folder
RECORDS = "points.json"


def results_dir(*parts: str) -> Path:
    """``results/<parts>`` of this checkout: a study's committed records."""
    return ROOT.joinpath("results", *parts)


def runs_dir(*parts: str) -> Path:
    """``runs/<parts>`` of this checkout: a study's raw runs (git-ignored)."""
    return ROOT.joinpath("runs", *parts)


def records_path(out: Path) -> Path:
    """``<out>/points.json``: the records of the study (or sweep, or grid) whose folder is
    ``out``."""
    return Path(out) / RECORDS


def records(out: Path) -> dict:
    """The records ``<out>/points.json`` as read ({} when missing or unreadable)."""
    return read_json(records_path(out)) or {}


def fingerprint(case, *plan, form: str = "json") -> str:
    """What a finished point must match to count: sha256 of the case's identity
    (dem.case.identity.identity_json), then of the plan parts and the engine's results revision,
    first 16 hex digits.  ``form`` is how the plan is written into the hash, fixed per study
    (the committed records carry it): "json", ``json.dumps([*plan, RESULTS_REVISION])``; "bars",
    ``"|a|b|...|RESULTS_REVISION"``."""
    from dem.case.identity import identity_json
    from dem.engine import RESULTS_REVISION

    h = hashlib.sha256(identity_json(case).encode())
    if form == "json":
        h.update(json.dumps([*plan, RESULTS_REVISION]).encode())
    elif form == "bars":
        h.update("".join(f"|{p}" for p in (*plan, RESULTS_REVISION)).encode())
    else:
        raise ValueError(f"fingerprint form must be 'json' or 'bars', got {form!r}")
    return h.hexdigest()[:16]


def write_case(case, path: Path) -> Path:
    """Write ``case`` as YAML at ``path`` (its folder made); returns ``path``."""
    import yaml

    path = Path(path)
    path.parent.mkdir(parents=True, exist_ok=True)
    path.write_text(yaml.safe_dump(case.model_dump(mode="json"), sort_keys=False))
    return path


@dataclass(frozen=True)
class Point:
    """One point of a study: ``case`` (a dem.case.Case) named ``name`` in its records, judged
    against ``plan`` (what besides the case its fingerprint covers, :func:`fingerprint` in
    ``form``); its records in ``out`` (points.json, cpu.json under the key ``ledger``), its case
    file ``<runs>/<name>.yaml`` and its raw run ``<runs>/<name>/``.  ``seed``: the realisation a
    swept point runs (None: the study's own); ``owner``: what the study needs to run it (a grid
    and its variant, an acceleration level...)."""
    name: str
    case: Any
    plan: tuple
    out: Path
    runs: Path
    ledger: str | None          # None: the CPU seconds go to the point's own record
    seed: int | None = None
    owner: Any = None
    form: str = "json"

    @property
    def fingerprint(self) -> str:
        return fingerprint(self.case, *self.plan, form=self.form)

    @property
    def case_file(self) -> Path:
        return Path(self.runs) / f"{self.name}.yaml"

    @property
    def run_dir(self) -> Path:
        return Path(self.runs) / self.name

    @property
    def records(self) -> Path:
        return records_path(self.out)


class Study:
    """What a study declares for :func:`run` (override the hooks; the defaults suit none)."""

    #: the folder of the drain file that ends a session softly (``<runs>/DRAIN``); None: the
    #: session stops on signals and the stop time only
    runs: Path | None = None

    def points(self):
        """The points in the order they run."""
        raise NotImplementedError

    def todo(self, point: Point):
        """What ``point`` still lacks, from its records brought up to date (falsy: nothing, the
        point is finished and is skipped)."""
        raise NotImplementedError

    def describe(self, point: Point, todo) -> str | None:
        """The log line before ``point`` runs (None: none)."""
        return point.name

    def command(self, point: Point, todo, drain: Path | None) -> list[str] | None:
        """The ``dem`` arguments that do ``todo`` (None: nothing to run, only :meth:`record`)."""
        raise NotImplementedError

    def ran(self, point: Point, rc: int, cpu: float, wall: float, log=print) -> None:
        """After the child: its CPU seconds added to ``<point.out>/cpu.json`` under
        ``point.ledger`` (no ledger: none) and its exit logged."""
        if point.ledger is not None:
            session.add_cpu(Path(point.out) / "cpu.json", point.ledger, cpu)
        log(f"    exit {rc}, {cpu:.0f} CPU-s, {wall:.0f} s")

    def record(self, point: Point, result: tuple | None, log=print):
        """Bring ``point``'s records up to date from its run directory; ``result``: the child's
        (exit code, CPU s, wall s), None when nothing ran.  Returns the point's state (None:
        "recorded")."""
        raise NotImplementedError

    def after(self, point: Point, state: str) -> None:
        """Once ``point`` is done with (``state``: "skipped" or what :meth:`record` said)."""


def run_point(study: Study, point: Point, drain: Path | None = None, log=print) -> str:
    """One point: "skipped" when ``study.todo`` finds it finished; else its case file written,
    ``study.command`` run as a child (then ``study.ran``) and ``study.record``-ed; returns the
    state that gave."""
    todo = study.todo(point)
    if not todo:
        return "skipped"
    write_case(point.case, point.case_file)
    line = study.describe(point, todo)
    if line:
        log(f"[{time.strftime('%H:%M:%S', time.gmtime())} UTC] {line}")
    args = study.command(point, todo, drain)
    result = None
    if args is not None:
        result = child.run_dem(args, log)
        study.ran(point, *result, log=log)
    return study.record(point, result, log) or "recorded"


def run(study: Study, stop_at: str | None = None, log=print) -> list[tuple[Point, str]]:
    """The resumable loop: for each of ``study.points()``, stop softly (a signal, the drain file
    ``<study.runs>/DRAIN``, the UTC time ``stop_at``: nothing new starts) or :func:`run_point`
    it, then ``study.after``.  Returns each point met with its state."""
    if study.runs is not None:
        drain = session.start(study.runs, log=log)
    else:
        drain = None
        child.install_signal_handlers()
    states = []
    for point in study.points():
        if session.should_stop(drain, stop_at, log):
            break
        state = run_point(study, point, drain, log)
        study.after(point, state)
        states.append((point, state))
    return states


# ---- the records of a study of dem sweep rows --------------------------------------------------
def row_key(row: dict) -> tuple:
    """A row's (seed, frequency) key (the frequency rounded to 1e-9 Hz)."""
    return int(row["seed"]), round(float(row["frequency_hz"]), 9)


def finished_rows(points: dict | None, section: str, name: str, fp: str) -> dict:
    """{(seed, f): row} of the finished rows recorded under ``section``/``name`` of a
    points.json for fingerprint ``fp`` (none for another fingerprint)."""
    rec = ((points or {}).get(section) or {}).get(name) or {}
    if rec.get("fingerprint") != fp:
        return {}
    return {row_key(r): r for r in rec.get("rows", []) if r.get("run_status") == "ok"}


def merge_rows(point: Point, section: str, fresh: list[dict], entry: dict, top: dict,
               row_fields: dict | None = None) -> dict:
    """Merge the rows ``fresh`` (this machine's run directories, in plan order) of ``point``
    into its points.json under ``section``/``point.name``, under the lock: a finished row,
    fresh or committed for the same fingerprint, wins over a pending one.  The point's record
    is ``entry`` + ``run_case``, ``fingerprint`` and ``rows`` (each row updated with
    ``row_fields``); the file's top level gets ``top`` and the code's ``source``.  Returns the
    file as written."""
    fp = point.fingerprint

    def change(data):
        kept = finished_rows(data, section, point.name, fp)
        rows = [r if r.get("run_status") == "ok" or row_key(r) not in kept else kept[row_key(r)]
                for r in fresh]
        for r in rows:
            r.update(row_fields or {})
        data.setdefault(section, {})[point.name] = {
            **entry, "run_case": rel(point.case_file), "fingerprint": fp, "rows": rows}
        data.update({**top, "source": source_state()})
    return merge_json(point.records, change)


def sweep_args(case_file: Path, run_dir: Path, frequencies, cycles: float, seed: int,
               workers: int | None = None, max_steps: int | None = None,
               drain: Path | None = None, realisations: int = 1) -> list[str]:
    """``dem sweep`` of ``case_file`` at ``frequencies`` (Hz), ``cycles`` cycles,
    ``realisations`` realisations from ``seed`` on, into ``run_dir``; ``workers``,
    ``max_steps`` and the drain file when given."""
    args = ["sweep", str(case_file), "--out", str(run_dir),
            "--frequencies", ",".join(f"{f:g}" for f in frequencies),
            "--cycles", f"{cycles:g}", "--realisations", str(realisations),
            "--seed", str(seed)]
    for flag, value in (("--workers", workers), ("--max-steps", max_steps),
                        ("--drain-file", drain)):
        if value is not None:
            args += [flag, str(value)]
    return args
