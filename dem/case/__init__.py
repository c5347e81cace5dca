"""Case files: the validated description of one simulation.

Units: SI everywhere (m, kg, s, N, Pa), except angles, which are in degrees (as in
``../shared/DESIGN.md``).  The base is the table plane z = 0 with z up; positions are in the
table's frame.  Unknown keys are rejected everywhere.

The minimal schema of DESIGN.md is accepted exactly as written there::

    name: block-on-tilt
    scene:
      blocks:
        - {size: [0.2, 0.2, 0.1], position: [0.0, 0.0, 0.05], mass: 4.0}
    material: {friction: 0.5}
    loading: {type: tilt, axis: x, rate: 2.0, max_angle: 40.0}
    run: {duration: 25.0, output_interval: 0.01}

Loading functions (gravity and base acceleration versus time) live in :mod:`dem.loading`.

The schema lives in one module per section: ``scene`` (blocks, builder entries), ``material``,
``loadings`` (tilt, shake, stepped shake, sweep, noise, record, none), ``settings`` (run, solver) and ``document`` (the whole
``Case``, loading a file with errors that name the field); this package exports them all.
"""

from dem.case.document import (Case, CaseError, case_json_schema, format_validation_error,
                               load_case, parse_case)
from dem.case.imperfections import Imperfections
from dem.case.loadings import (CollapseSpec, Distortion, FrequencyStep, Loading, NoiseLoading,
                               NoLoading, QuasiStaticSpec, RecordLoading, ReversalSpike,
                               ShakeLoading, SteppedShakeLoading,
                               SweepLoading, TiltLoading, check_record_time, read_record_csv)
from dem.case.material import MAX_FRICTION, Material
from dem.case.scene import BlockSpec, SceneSpec
from dem.case.settings import RunSpec, SolverSpec

__all__ = ["BlockSpec", "Case", "CaseError", "CollapseSpec", "Distortion", "Imperfections", "Loading", "MAX_FRICTION",
           "Material", "NoiseLoading", "NoLoading", "QuasiStaticSpec", "RecordLoading", "ReversalSpike", "RunSpec", "SceneSpec",
           "ShakeLoading", "SolverSpec", "SteppedShakeLoading", "SweepLoading", "TiltLoading", "FrequencyStep", "case_json_schema", "check_record_time",
           "format_validation_error", "load_case", "parse_case", "read_record_csv"]
