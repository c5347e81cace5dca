"""The as-built study's plan (studies/as_built): its points are the cases the study says they
are, before any run (the records of those that ran are checked by test_recorded_fingerprints)."""

import pytest


@pytest.fixture(scope="module")
def frozen():
    from studies.prediction.plan import load_frozen
    from studies.prediction.protocol import DEFAULT_FROZEN

    return load_frozen(DEFAULT_FROZEN)


def test_identification_points_are_each_model_joint_and_level_once_model_ii_y_first(frozen):
    from studies.as_built import identification as ident

    pts = list(ident.points(frozen))
    assert len(pts) == len(ident.MODELS) * len(ident.JOINTS) * len(ident.LEVELS)
    assert len({p.name for p in pts}) == len(pts)
    assert len({p.fingerprint for p in pts}) == len(pts)
    assert {p.owner[0] for p in pts[:6]} == {"model-ii-y"}
    for p in pts:
        sweep, joint, rms = p.owner
        ld = p.case.loading
        assert ld.type == "noise" and ld.rms_acceleration == rms
        assert (ld.f_lo, ld.f_hi, ld.duration) == (*ident.BAND, ident.DURATION)
        assert p.case.run.duration == ident.DURATION + ident.TAIL
        # the first prediction's frozen joints under every patch
        assert p.case.imperfections.bed_unevenness == frozen["parameters"]["bed_unevenness"]
        kn = p.case.material.normal_stiffness
        assert (kn == 2e8) == (joint.name == "kn-2e8")
        corners = p.case.scene.box_model.corners
        assert (corners == "unbonded") == (joint.name == "unbonded")
        direction = [0.0, 1.0, 0.0] if sweep.endswith("-y") else [1.0, 0.0, 0.0]
        assert list(ld.direction) == direction


def test_loose_corner_sets_differ_only_by_the_corner_gaps(frozen):
    from studies.as_built.grids import GRIDS, LOOSE
    from studies.diagnosis.grid import variant_case

    grid = GRIDS["loose-corners-model-ii-y"]
    cases = [variant_case(grid, v, frozen["parameters"]) for v in LOOSE]
    means = [c.imperfections.corner_gap.mean for c in cases]
    assert means == pytest.approx([0.5e-3, 1e-3, 2e-3])
    for c in cases:
        assert c.imperfections.head_gap.mean == pytest.approx(2.5e-4)
        assert list(c.imperfections.plumb.sigma) == pytest.approx([2.5e-4, 2.5e-4])
        assert c.imperfections.bed_unevenness == frozen["parameters"]["bed_unevenness"]
        assert c.loading.peak_acceleration == 1.53
    twelve = GRIDS["loose-corners-model-i-y-12mm"]
    c = variant_case(twelve, twelve.variants[0], frozen["parameters"])
    assert c.loading.amplitude == 0.012 and c.loading.peak_acceleration is None
    assert twelve.cycles == 50.0
