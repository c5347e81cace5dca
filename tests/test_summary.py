"""``dem summary DIR...`` (a table across runs) on a tilt, a shake, a sweep and an
ensemble directory (tests/view_runs.py): every number of a row is read back from the files the
commands wrote (computed here independently of dem_cli/commands/summary.py), the tilt's lambda is
the sliding closed form, and the CSV carries units in its header."""

from __future__ import annotations

import csv
import io
import json

import numpy as np
import pytest
from typer.testing import CliRunner

from dem_cli.app import app


def _json(path):
    return json.loads(path.read_text())


def _csv_rows(text):
    return {r["kind"]: r for r in csv.DictReader(io.StringIO(text))}


def test_summary_has_one_row_per_directory_with_units_and_the_files_numbers(view_runs, tmp_path):
    dirs = view_runs
    out = tmp_path / "all.csv"
    res = CliRunner().invoke(app, ["summary", *(str(dirs[k]) for k in
                                                ("tilt", "shake", "sweep", "ensemble")),
                                   "--csv", str(out)])
    assert res.exit_code == 0, res.output
    for k in ("tilt", "shake", "sweep", "ensemble"):
        assert dirs[k].name in res.output                # the rich table names every directory
    text = out.read_text()
    header = text.splitlines()[0]
    for col in ("lambda (-)", "angle (deg)", "amplification ds (-)", "f_c (Hz)", "wall (s)",
                "cpu (s)"):
        assert col in header
    rows = _csv_rows(text)
    assert set(rows) == {"run-tilt", "run-shake", "sweep", "ensemble"}

    # tilt: lambda and the times are summary.json's; a lone squat block (b/h = 2) with
    # mu = 0.5 slides at lambda = mu (the quasi-static search reads it within its tolerance,
    # 1e-3 in unbalanced-force ratio: 0.2 %, benchmarks/quasi_static_tilt.py)
    s = _json(dirs["tilt"] / "summary.json")
    tilt = rows["run-tilt"]
    assert tilt["status"] == "ok" and tilt["name"] == "block-sliding"
    assert float(tilt["lambda (-)"]) == s["collapse"]["load_factor"]
    assert float(tilt["lambda (-)"]) == pytest.approx(0.5, rel=2e-3)
    assert tilt["mechanism"] == "sliding"
    assert float(tilt["wall (s)"]) == s["wall_seconds"]
    assert float(tilt["cpu (s)"]) == s["cpu_seconds"] > 0.0

    # shake: the ds amplification of analysis.json (dem post) and the table's frequency
    ana = _json(dirs["shake"] / "analysis.json")
    shake = rows["run-shake"]
    assert float(shake["amplification ds (-)"]) == ana["amplification"]["ds"]
    assert float(shake["frequency (Hz)"]) == 2.0

    # sweep: the peak of the ds curve over its points, f_c empty or the frequency of that peak;
    # wall and CPU: the sums over the points' summary.json
    sw = _json(dirs["sweep"] / "sweep.json")
    amps = [p["amplification"]["ds"] for p in sw["points"]]
    sweep = rows["sweep"]
    assert sweep["status"] == "ok"
    assert float(sweep["amplification ds (-)"]) == pytest.approx(max(amps), rel=1e-12)
    fc = sw["aggregate"]["characteristic_frequency_hz"]
    assert sweep["f_c (Hz)"] == ("" if fc is None else repr(float(fc)))
    summ = [_json(dirs["sweep"] / p["dir"] / "summary.json") for p in sw["points"]]
    assert float(sweep["wall (s)"]) == pytest.approx(sum(x["wall_seconds"] for x in summ),
                                                     rel=1e-12)
    assert float(sweep["cpu (s)"]) == pytest.approx(sum(x["cpu_seconds"] for x in summ),
                                                    rel=1e-12)

    # ensemble: the median and 10-90 % quantiles of the realisations' lambda
    ens = _json(dirs["ensemble"] / "ensemble.json")
    lam = [r["lambda"] for r in ens["realisations"]]
    row = rows["ensemble"]
    assert row["status"] == "ok" and row["runs"].startswith("2")
    assert float(row["lambda (-)"]) == pytest.approx(float(np.median(lam)), rel=1e-12)
    assert float(row["lambda q10 (-)"]) == pytest.approx(float(np.quantile(lam, 0.1)), rel=1e-12)
    assert float(row["lambda q90 (-)"]) == pytest.approx(float(np.quantile(lam, 0.9)), rel=1e-12)
    wall = sum(_json(dirs["ensemble"] / r["name"] / "summary.json")["wall_seconds"]
               for r in ens["realisations"])
    assert float(row["wall (s)"]) == pytest.approx(wall, rel=1e-12)


def test_summary_csv_on_stdout_and_a_bad_directory_exits_2_keeping_the_others(view_runs,
                                                                              tmp_path):
    empty = tmp_path / "empty"
    empty.mkdir()
    res = CliRunner().invoke(app, ["summary", str(view_runs["tilt"]), str(empty),
                                   "--format", "csv"])
    assert res.exit_code == 2
    assert f"{empty}: not a run" in res.output
    rows = list(csv.DictReader(io.StringIO(res.stdout)))
    assert [r["kind"] for r in rows] == ["run-tilt"]
    res = CliRunner().invoke(app, ["summary", str(view_runs["tilt"]), "--format", "xml"])
    assert res.exit_code == 2 and "--format" in res.output


def test_a_run_writes_its_cpu_time(view_runs):
    """summary.json ``cpu_seconds``: the process's CPU time after the build,
    positive, and with one Taichi thread per core at most the wall time of the run after its
    compile times the cores."""
    import os

    s = _json(view_runs["tilt"] / "summary.json")
    assert 0.0 < s["cpu_seconds"] <= (s["wall_seconds"] - s["compile_seconds"]) * \
        (os.cpu_count() or 1) + 1.0
    assert s["units"]["cpu_seconds"] == "s"
