"""``dem summary DIR...``: one row per run, sweep or ensemble directory, read from the files the
commands wrote (nothing is recomputed), as a table on screen or as CSV (``--csv FILE``).

What a row holds, by what the directory is (dem_cli.commands.post.directory_kind):

=================  ==========================================================================
column (unit)      where it comes from
=================  ==========================================================================
kind               run-tilt, run-shake, run-record, run-none, sweep, ensemble, sweep-ensemble,
                   rocking
name               the case's name (summary.json / sweep.json / ensemble.json ``case``)
status             a run: summary.json ``status`` ("ok", "failed", "interrupted", "running";
                   "smoke" for an ok run capped by --max-steps); a sweep or an ensemble: "ok"
                   when every point / realisation is, else "n failed", "n not run"
lambda (-)         a tilt: summary.json ``collapse.load_factor`` (tan of the collapse angle);
                   an ensemble: the median over the realisations (``lambda_q10``, ``lambda_q90``
                   the 10 % and 90 % quantiles)
angle (deg)        the table angle of that lambda (an ensemble: the median)
amplification (-)  a shake run: analysis.json ``amplification.ds`` (``dem post`` writes it);
                   a stepped shake run: the largest ds amplification of its steps
                   (stepped.json ``peak``); a sweep: the peak ds amplification of the curve
                   (sweep.json aggregate); a shaking ensemble: the median of
                   ``amplification_ds``
frequency (Hz)     a shake run: the table's frequency (summary.json loading); a stepped shake:
                   the frequency of its peak step
f_c (Hz)           a sweep: the characteristic frequency (peak of ds; empty when the curve has
                   no clear peak); a sweep ensemble: its median over the realisations
f_n (Hz), zeta (-) a sweep or noise run (loading ``sweep`` / ``noise``): the first mode's
                   frequency and damping ratio (identification.json, ``dem post`` writes it;
                   postprocess.identification)
mechanism          a tilt: summary.json ``mechanism.mechanism``; a shake run: analysis.json
                   ``mechanism.response``; an ensemble: the counts of each mechanism
wall (s)           summary.json ``wall_seconds`` (compile included); a sweep or an ensemble:
                   the sum over its runs (the CPU-seconds a study costs, not its elapsed time)
cpu (s)            summary.json ``cpu_seconds`` (process CPU time of the run, every thread:
                   runs from before it was recorded leave it empty); sums likewise
runs               the number of runs the row covers (and of those whose summary.json was read)
=================  ==========================================================================
"""

from __future__ import annotations

import csv
import io
import json
import math
from dataclasses import dataclass
from pathlib import Path

from dem_cli.commands.exit_codes import ExitCode

# (key, header, unit) of the columns, in order; the unit goes into the CSV header
COLUMNS: tuple[tuple[str, str, str], ...] = (
    ("dir", "directory", ""),
    ("kind", "kind", ""),
    ("name", "name", ""),
    ("status", "status", ""),
    ("lambda", "lambda", "-"),
    ("lambda_q10", "lambda q10", "-"),
    ("lambda_q90", "lambda q90", "-"),
    ("angle_deg", "angle", "deg"),
    ("amplification", "amplification ds", "-"),
    ("frequency_hz", "frequency", "Hz"),
    ("f_c_hz", "f_c", "Hz"),
    ("f_n_hz", "f_n", "Hz"),
    ("zeta", "zeta", "-"),
    ("mechanism", "mechanism", ""),
    ("wall_s", "wall", "s"),
    ("cpu_s", "cpu", "s"),
    ("runs", "runs", ""),
)


@dataclass
class SummaryError(ValueError):
    """A directory that holds no run, sweep nor ensemble."""

    path: Path
    why: str

    def __str__(self) -> str:
        return f"{self.path}: {self.why}"


def _json(path: Path) -> dict | None:
    try:
        data = json.loads(Path(path).read_text())
    except (OSError, ValueError):
        return None
    return data if isinstance(data, dict) else None


def _num(v) -> float | None:
    return float(v) if isinstance(v, (int, float)) and not isinstance(v, bool) \
        and math.isfinite(v) else None


def _sum(values) -> float | None:
    """Sum of the finite values; None when there is none."""
    vals = [v for v in (_num(x) for x in values) if v is not None]
    return float(sum(vals)) if vals else None


def run_row(path: Path) -> dict:
    """The row of one run directory (summary.json, and analysis.json of a shake run)."""
    s = _json(path / "summary.json")
    from dem_cli.commands.post import run_state

    state = run_state(path)
    if s is None:
        raise SummaryError(path, f"no readable summary.json: {state}")
    loading = s.get("loading") or {}
    kind = loading.get("type") or "none"
    status = s.get("status")
    if status == "ok" and s.get("step_limit") is not None:
        status = "smoke"  # capped by --max-steps: not a finished run
    elif state is not None and state.startswith(("running", "killed")):
        status = state.split(":")[0]  # "running, pid N, t = x s ...", "killed (SIGKILL ...)"
    row = {"kind": f"run-{kind}", "name": s.get("name"), "status": status,
           "wall_s": _num(s.get("wall_seconds")), "cpu_s": _num(s.get("cpu_seconds")),
           "runs": "1"}
    col = s.get("collapse") or {}
    if col.get("detected"):
        row["lambda"] = _num(col.get("load_factor"))
        row["angle_deg"] = _num(col.get("angle_deg"))
    elif col:
        row["mechanism"] = f"none up to {col.get('last_angle_deg', 0.0):.2f} deg"
    mech = s.get("mechanism")
    if isinstance(mech, dict) and (mech.get("mechanism") or mech.get("kind")):
        row["mechanism"] = str(mech.get("mechanism") or mech.get("kind"))
    if col.get("detected") and row.get("lambda") is None:
        # a collapse whose onset the detector could not place (dem.collapse): say so, an empty
        # lambda cell alone reads as "no result"
        row["mechanism"] = f"{row.get('mechanism') or 'collapse'} (onset not resolved: no lambda)"
    if kind == "stepped_shake":
        ana = _json(path / "stepped.json")
        if ana is None:
            row["mechanism"] = "(no stepped.json: dem post)"
        else:
            peak = ana.get("peak") or {}
            row["amplification"] = _num(peak.get("amplification_ds"))
            row["frequency_hz"] = _num(peak.get("frequency_hz"))
    if kind in ("sweep", "noise"):
        ana = _json(path / "identification.json")
        if ana is None:
            row["mechanism"] = "(no identification.json: dem post)"
        else:
            row["f_n_hz"], row["zeta"] = _num(ana.get("f_n_hz")), _num(ana.get("zeta"))
    if kind in ("shake", "record"):
        row["frequency_hz"] = _num(loading.get("frequency_hz"))
        ana = _json(path / "analysis.json")
        if ana is None:
            row["mechanism"] = "(no analysis.json: dem post)"
        else:
            row["amplification"] = _num((ana.get("amplification") or {}).get("ds"))
            resp = (ana.get("mechanism") or {}).get("response")
            if resp:
                row["mechanism"] = str(resp)
    return row


def sweep_row(path: Path) -> dict:
    """The row of a sweep directory (sweep.json; the points' summary.json for the times)."""
    data = _json(path / "sweep.json")
    if data is None:
        raise SummaryError(path, "a sweep without a readable sweep.json (rebuild it with "
                                 "`dem post`)")
    points = data.get("points") or []
    agg = data.get("aggregate") or {}
    n_bad = sum(1 for p in points if p.get("status") != "ok")
    summaries = [_json(path / str(p.get("dir") or p.get("name")) / "summary.json")
                 for p in points]
    read = [x for x in summaries if x is not None]
    wall = _sum(x.get("wall_seconds") for x in read)
    if wall is None:
        wall = _sum(p.get("wall_seconds") for p in points)
    return {"kind": "sweep", "name": data.get("case"),
            "status": "ok" if n_bad == 0 and points else f"{n_bad} of {len(points)} failed",
            "amplification": _num(agg.get("peak_amplification")),
            "f_c_hz": _num(agg.get("characteristic_frequency_hz")),
            "wall_s": wall, "cpu_s": _sum(x.get("cpu_seconds") for x in read),
            "runs": f"{len(points)} ({len(read)} read)"}


def _counts(d: dict | None) -> str | None:
    if not d:
        return None
    return ", ".join(f"{k} {v}" for k, v in sorted(d.items(), key=lambda kv: (-kv[1], kv[0])))


def ensemble_row(path: Path) -> dict:
    """The row of a ``dem ensemble`` directory (ensemble.json; the realisations' summary.json
    for the times)."""
    data = _json(path / "ensemble.json") or {}
    rows = data.get("realisations") or []
    agg = data.get("aggregate") or {}
    stats = agg.get("statistics") or {}
    n_failed, n_pending = agg.get("n_failed", 0), agg.get("n_pending", 0)
    status = "ok" if not n_failed and not n_pending and rows else \
        "; ".join(x for x in (f"{n_failed} failed" if n_failed else "",
                              f"{n_pending} not run" if n_pending else "") if x) or "empty"
    read = [x for x in (_json(path / str(r.get("name")) / "summary.json") for r in rows)
            if x is not None]
    lam, ang, amp = (stats.get(k) or {} for k in ("lambda", "angle_deg", "amplification_ds"))
    return {"kind": "ensemble", "name": data.get("case"), "status": status,
            "lambda": _num(lam.get("median")), "lambda_q10": _num(lam.get("q10")),
            "lambda_q90": _num(lam.get("q90")), "angle_deg": _num(ang.get("median")),
            "amplification": _num(amp.get("median")),
            "mechanism": _counts(agg.get("mechanisms")),
            "wall_s": _sum(x.get("wall_seconds") for x in read),
            "cpu_s": _sum(x.get("cpu_seconds") for x in read),
            "runs": f"{len(rows)} ({len(read)} read)"}


def sweep_ensemble_row(path: Path) -> dict:
    """The row of a ``dem sweep --realisations`` directory (ensemble.json, each realisation's
    sweep.json and their points' summary.json)."""
    data = _json(path / "ensemble.json") or {}
    per = data.get("realisations") or []
    subs = [sweep_row(path / r["name"]) for r in per
            if isinstance(r, dict) and (path / str(r.get("name")) / "sweep.json").is_file()]
    n_bad = len(per) - sum(1 for s in subs if s["status"] == "ok")
    fc = data.get("characteristic_frequency_hz") or {}
    peaks = [s["amplification"] for s in subs if s.get("amplification") is not None]
    import numpy as np

    return {"kind": "sweep-ensemble", "name": data.get("case"),
            "status": "ok" if n_bad == 0 and per else f"{n_bad} of {len(per)} not ok",
            "amplification": float(np.median(peaks)) if peaks else None,
            "f_c_hz": _num(fc.get("median")),
            "wall_s": _sum(s["wall_s"] for s in subs), "cpu_s": _sum(s["cpu_s"] for s in subs),
            "runs": f"{len(per)} sweeps"}


def rocking_row(path: Path) -> dict:
    s = _json(path / "summary.json") or {}
    return {"kind": "rocking", "name": s.get("name"), "status": s.get("status", "ok"),
            "wall_s": _num(s.get("wall_seconds")), "cpu_s": _num(s.get("cpu_seconds")),
            "runs": "1"}


def directory_row(path) -> dict:
    """The row of one directory (a run, a sweep, an ensemble, a sweep ensemble, a two-body
    run); raises SummaryError for anything else."""
    from dem_cli.commands.post import directory_kind

    path = Path(path)
    if not path.is_dir():
        raise SummaryError(path, "not a directory")
    kind = directory_kind(path)
    maker = {"run": run_row, "sweep": sweep_row, "ensemble": ensemble_row,
             "sweep-ensemble": sweep_ensemble_row, "rocking": rocking_row}.get(kind)
    if maker is None:
        raise SummaryError(path, "not a run (no case.json), a sweep (no sweep.json) nor an "
                                 "ensemble (no ensemble.json)")
    row = {key: None for key, _, _ in COLUMNS}
    row.update(maker(path))
    row["dir"] = str(path)
    return row


def _text(key: str, v) -> str:
    if v is None:
        return ""
    if isinstance(v, float):
        if key.startswith("lambda"):
            return f"{v:.4f}"
        if key in ("wall_s", "cpu_s"):
            return f"{v:.1f}"
        if key == "angle_deg":
            return f"{v:.2f}"
        if key == "zeta":
            return f"{v:.3f}"
        return f"{v:.4g}"
    return str(v)


def header(key: str, title: str, unit: str) -> str:
    """A column's header with its unit: ``lambda (-)``, ``wall (s)``."""
    return f"{title} ({unit})" if unit else title


def to_csv(rows: list[dict]) -> str:
    """The rows as CSV: a header with units, full-precision numbers, empty for none."""
    buf = io.StringIO()
    w = csv.writer(buf, lineterminator="\n")
    w.writerow([header(*c) for c in COLUMNS])
    for r in rows:
        w.writerow(["" if r.get(k) is None else (repr(r[k]) if isinstance(r[k], float)
                                                 else r[k]) for k, _, _ in COLUMNS])
    return buf.getvalue()


def print_table(rows: list[dict]) -> None:
    """The rows as a rich table on stdout: an ensemble's lambda with its 10-90 % range in one
    cell; the columns no row fills are left out."""
    from rich.console import Console
    from rich.table import Table

    shown = [c for c in COLUMNS if c[0] not in ("lambda_q10", "lambda_q90")
             and any(r.get(c[0]) is not None for r in rows)]
    summed = any(not str(r.get("kind", "")).startswith(("run", "rocking")) for r in rows)
    table = Table(title="dem summary", show_lines=False,
                  caption="wall and cpu of a sweep or an ensemble: the sum over its runs (what "
                          "the study cost, not its elapsed time)" if summed else None)
    for key, title, unit in shown:
        table.add_column(header(key, title, unit) if key != "lambda" else "lambda (-)",
                         overflow="fold", no_wrap=bool(unit), justify="right" if unit else "left")
    for r in rows:
        cells = []
        for k, _, _ in shown:
            text = _text(k, r.get(k))
            if k == "lambda" and r.get("lambda_q10") is not None:
                text += f" ({_text(k, r['lambda_q10'])}-{_text(k, r['lambda_q90'])})"
            cells.append(text)
        table.add_row(*cells)
    console = Console()
    if not console.is_terminal:
        console = Console(width=200)  # a pipe or a file: no terminal width to fit
    console.print(table)


def summary_command(paths: list[Path], csv_path: Path | None = None,
                    fmt: str = "table", echo=print, err=print) -> int:
    """Body of ``dem summary``: a row per directory; exit 0, or 2 when a directory is not a
    run, a sweep nor an ensemble (the others are still shown) or the format is unknown."""
    if fmt not in ("table", "csv"):
        err(f"error: --format: '{fmt}' is not one of table, csv")
        return ExitCode.BAD_INPUT
    rows, bad = [], 0
    for p in paths:
        try:
            rows.append(directory_row(p))
        except SummaryError as e:
            err(f"error: {e}")
            bad += 1
    if rows:
        if fmt == "csv":
            echo(to_csv(rows).rstrip("\n"))
        else:
            print_table(rows)
        if csv_path is not None:
            from dem_cli.commands.exit_codes import write_output_file

            code = write_output_file(Path(csv_path), to_csv(rows), err, err, option="--csv")
            if code != ExitCode.OK:
                return code
    return ExitCode.BAD_INPUT if bad else ExitCode.OK
