"""``python -m studies <study> ...``: the one entry point of the studies.

Each study is a subcommand; what follows its name goes to the study's own Typer command, run by
its module's ``main(argv)`` (studies.kit.cli: ``python -m studies prediction --help``).  A
study's module is imported only when its subcommand runs, so ``python -m studies --help`` lists
them without loading Taichi.
"""

from __future__ import annotations

import importlib

import typer

#: subcommand -> (module with main(argv), one line of help)
STUDIES = {
    "prediction": ("studies.prediction.cli",
                   "blind prediction of the Chapter 4 shaking-table tests with the frozen set"),
    "point-pool": ("studies.prediction.pool",
                   "chosen prediction points in a process pool, without dask (a borrowed machine)"),
    "calibration": ("studies.calibration.cli",
                    "calibration of the imperfections on the Chapter 3 tilts, and the freeze"),
    "chapter3-check": ("studies.chapter3.check",
                       "the frozen set's calibration tilts re-run on today's engine (step 4)"),
    "qs-validation": ("studies.qs_validation.study",
                      "quasi-static lambda against slow constant-rate tilts"),
    "tilt": ("studies.tilt.study", "the Chapter 3 tilt cases, rates and quasi-static runs"),
    "shake": ("studies.shake.study", "the Chapter 4 shake sweeps with perfect joints"),
    "unevenness": ("studies.unevenness.study",
                   "sensitivity of Model II y at 2.8 Hz to the bed unevenness"),
    "resonance": ("studies.resonance.study",
                  "the sweeps continued above the thesis' range: where is the resonance?"),
    "impact-dissipation": ("studies.impact_dissipation.cli",
                           "energy lost per impact: DEM against Housner and the two-body model"),
    "impact-loss": ("studies.impact_loss.cli",
                    "r / r_Housner against slenderness for each normal dashpot of the joint"),
    "large-brick": ("studies.large_brick.study",
                    "the large-brick in-plane walls: limit analysis and DEM diagnostics"),
    "two-body-report": ("studies.two_body.report",
                        "the two-body rocking model's tables (results/two-body/README.md)"),
    "diagnosis": ("studies.diagnosis.cli",
                  "why the laboratory's models rocked and the DEM's did not (E1-E7)"),
    "as-built": ("studies.as_built.cli",
                 "masonry as built by hand: the corner bound, loose corners, the input's bounds"),
    "two-body-vs-dem": ("studies.two_body.vs_dem_sweep",
                        "the two-body model against the DEM's Model II y rocking sweep"),
}

app = typer.Typer(add_completion=False, no_args_is_help=True,
                  help="The studies: each runs many `dem` runs and writes results/<study>/.")


def _command(name: str, module: str, text: str):
    @app.command(name, help=text, add_help_option=False,
                 context_settings={"allow_extra_args": True, "ignore_unknown_options": True})
    def run(ctx: typer.Context) -> None:
        rc = importlib.import_module(module).main(list(ctx.args))
        raise typer.Exit(rc or 0)
    return run


for _name, (_module, _text) in STUDIES.items():
    _command(_name, _module, _text)


if __name__ == "__main__":
    app(prog_name="python -m studies")
