"""Small output directories of every kind, made once per test session for tests/test_view.py,
tests/test_summary.py and tests/test_units.py: a tilt run, a shake run (analysed by ``dem post``),
a sweep of two frequencies and an ensemble of two realisations, through the commands
themselves (the batches run in this process: :func:`in_process_batch`).

* tilt: a squat block (0.2 x 0.2 x 0.1 m, b/h = 2) with mu = 0.5 on a quasi-static tilt: it
  slides at lambda = tan(angle) = mu = 0.5 (26.57 deg), long before it could tip;
* shake: the squat block under 1.5 m/s2 at 2 Hz, 2 cycles (it moves with the table);
* sweep: the same at 2 and 3 Hz;
* ensemble: the tilt's block with a warped bed (0.1 mm, planar faces), seeds 5 and 6 (the
  default joint stiffness: a sliding block needs no 'rigid', and the fixture stays cheap).
"""

from __future__ import annotations

import pytest
import yaml
from typer.testing import CliRunner

from dem_cli.app import app

TILT = {
    "name": "block-sliding",
    "scene": {"blocks": [{"size": [0.2, 0.2, 0.1], "position": [0, 0, 0.05], "mass": 4.0}]},
    "material": {"friction": 0.5},
    "loading": {"type": "tilt", "axis": "y", "max_angle": 40.0, "start_angle": 24.0,
                "quasi_static": {"resolution": 0.02}},
    "run": {"duration": 20.0, "output_interval": 0.01, "vtk": False, "snapshot": False},
}

SHAKE = {
    "name": "block-on-shaking-table",
    "scene": {"blocks": [{"size": [0.2, 0.2, 0.1], "position": [0, 0, 0.05], "mass": 4.0}]},
    "material": {"friction": 0.8},
    "loading": {"type": "shake", "direction": [0, 1, 0], "frequency": 2.0,
                "peak_acceleration": 1.5, "cycles": 2},
    "run": {"duration": 1.0, "output_interval": 0.005, "vtk": False, "snapshot": False},
}


ENSEMBLE = {**TILT, "name": "block-sliding-warped",
            "imperfections": {"bed_unevenness": 1e-4, "face_shape": "planar", "seed": 0}}


def _write(path, data):
    path.write_text(yaml.safe_dump(data))
    return path


def _ok(res):
    assert res.exit_code == 0, res.output
    return res


def in_process_batch(cases, out_root, scheduler=None, n_workers=None, max_steps=None,
                     post=None, on_done=None, analyses=(), drain=None):
    """dem.batch.run_batch in this process, one case after the other (what one worker does),
    to keep the fixture to seconds; the dask path has its own tests (test_ensemble_dask.py)."""
    from dem.run import run_case

    recs = []
    for name, case in cases:
        d = str(out_root / name)
        res = run_case(case, d, max_steps=max_steps, analyses=analyses)
        rec = {"name": name, "status": "ok", "out_dir": d, "summary": res.summary}
        if post is not None:
            rec["post"] = post(case, res, d)
        if on_done is not None:
            on_done(rec)
        recs.append(rec)
    return recs


@pytest.fixture(scope="session")
def view_runs(tmp_path_factory):
    """{"tilt": DIR, "shake": DIR, "sweep": DIR, "ensemble": DIR} (see the module docstring)."""
    import dem.batch

    root = tmp_path_factory.mktemp("view_runs")
    runner = CliRunner()
    dirs = {k: root / k for k in ("tilt", "shake", "sweep", "ensemble")}
    _ok(runner.invoke(app, ["run", str(_write(root / "tilt.yaml", TILT)), "--out",
                            str(dirs["tilt"]), "--no-progress"]))
    shake = _write(root / "shake.yaml", SHAKE)
    _ok(runner.invoke(app, ["run", str(shake), "--out", str(dirs["shake"]), "--no-progress"]))
    _ok(runner.invoke(app, ["post", str(dirs["shake"])]))
    with pytest.MonkeyPatch.context() as mp:
        mp.setattr(dem.batch, "run_batch", in_process_batch)
        _ok(runner.invoke(app, ["sweep", str(shake), "--out", str(dirs["sweep"]),
                                "--frequencies", "2,3", "--cycles", "2", "--margin", "0.1"]))
        ens = _write(root / "ensemble.yaml", ENSEMBLE)
        _ok(runner.invoke(app, ["ensemble", str(ens), "--out", str(dirs["ensemble"]),
                                "--realisations", "2", "--seed", "5"]))
    return dirs
