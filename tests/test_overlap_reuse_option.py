"""The case option ``solver.overlap_reuse`` (m; dem.case.settings.SolverSpec), applied by
dem.run.build.build through dem.engine.coherence.set_overlap_reuse.

Tolerance of the end-to-end comparison: benchmarks/RESULTS.md ("Overlap reuse for imperfect
joints") and tests/test_imperfect_speedup.py bound the reuse's effect on this scene (two bricks on
the table, one across their joint, planar 0.1 mm beds, seed 3) by 0.26 x tol x 2: the scene's
measured sensitivity to a planar gap change (0.26 m per m, tests/test_planar_affine_gap.py) times
the polygon error (at most tol) for the two joints under the top brick.  Here the same scene runs
a few hundred steps through the case path (build), at rest and then pushed at 0.1 g; its bricks
move far more than the bound (they seat on their uneven beds), so the bound is not met by a
scene that does nothing.
"""

from __future__ import annotations

import numpy as np
import pytest

from dem import ti_runtime

ti_runtime.init()

from dem.case import CaseError, parse_case  # noqa: E402
from dem.engine import coherence  # noqa: E402
from dem.run.build import build, case_joint_law, joint_summary  # noqa: E402

L, W, H = 0.105, 0.05, 0.035
TOL = 1e-7  # m: the tolerance benchmarks/RESULTS.md measured
THREE = [{"size": [L, W, H], "position": [-0.5 * L, 0.0, 0.5 * H], "density": 1828.6},
         {"size": [L, W, H], "position": [0.5 * L, 0.0, 0.5 * H], "density": 1828.6},
         {"size": [L, W, H], "position": [0.2 * L, 0.0, 1.5 * H], "density": 1828.6}]
IMPERFECT = {"bed_unevenness": 1e-4, "seed": 3, "face_shape": "planar"}
STEPS = 300  # per phase: at rest, then pushed


def _case(tol=None, imperfections=IMPERFECT, blocks=THREE):
    doc = {"name": "overlap-reuse-option", "scene": {"blocks": blocks},
           "material": {"friction": 0.8}, "loading": {"type": "none"}, "run": {"duration": 1.0}}
    if imperfections:
        doc["imperfections"] = imperfections
    if tol is not None:
        doc["solver"] = {"overlap_reuse": tol}
    return parse_case(doc)


def test_default_is_off_and_the_option_reaches_the_engine():
    off = build(_case())
    assert coherence.overlap_reuse_tolerance(off.sim.contacts) == 0.0
    assert "overlap_reuse" not in joint_summary(_case(), off.scene, off.sim.joints)
    case = _case(TOL)
    on = build(case)
    assert coherence.overlap_reuse_tolerance(on.sim.contacts) == TOL
    summary = joint_summary(case, on.scene, case_joint_law(case, on.scene))
    assert summary["overlap_reuse"]["tolerance_m"] == TOL and summary["overlap_reuse"]["active"]


@pytest.mark.parametrize("bad", [-1e-7, 2e-3])
def test_a_tolerance_out_of_range_is_refused_naming_the_field(bad):
    with pytest.raises(CaseError, match=r"solver\.overlap_reuse"):
        _case(bad)


def test_on_a_perfect_scene_it_is_a_no_op_that_the_summary_reports():
    case = _case(TOL, imperfections=None)
    built = build(case)  # does not fail
    summary = joint_summary(case, built.scene, built.sim.joints)["overlap_reuse"]
    assert summary["active"] is False and "no effect" in summary["note"]


def _run(tol):
    """The three bricks through the case path: STEPS steps at rest, STEPS under a lateral
    0.1 g.  Returns the positions at the start and at the end (m) and how many pairs hold a kept
    overlap polygon (coherence: patch_shape[p, 0][3] < 0)."""
    sim = build(_case(tol)).sim
    start = sim.state.pos[:3].copy()

    def loads(a):
        g = np.array([a, 0.0, -9.81])
        return lambda t: (np.tile(g, (len(t), 1)), np.zeros((len(t), 3)))

    sim.advance(STEPS, loads(0.0))
    sim.advance(STEPS, loads(0.981))
    kept = int((sim.contacts.patch_shape[:sim.contacts.n_pairs, 0, 3] < 0).sum())
    return start, sim.state.pos[:3].copy(), kept


def test_a_short_imperfect_run_stays_within_the_measured_error():
    start, off, kept_off = _run(None)
    _, on, kept_on = _run(TOL)
    assert kept_off == 0 and kept_on >= 3  # the reuse acted, on the three joints at least
    bound = 0.26 * TOL * 2
    assert np.abs(on - off).max() <= bound
    # the comparison means something: the bricks moved far more than the bound
    assert np.abs(off - start).max() > 100 * bound
