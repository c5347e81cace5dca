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

    from studies.as_built.grids import LOOSE

    pts = list(ident.points(frozen))
    assert len(pts) == len(ident.MODELS) * len(ident.JOINTS) * len(ident.LEVELS) + len(LOOSE)
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
        gap = p.case.imperfections.corner_gap
        assert (gap is not None and gap.mean > 0) == joint.name.startswith("loose-")
    # the loose sets (criterion (iii)) come last, on Model II y at the target's level
    tail = pts[-len(LOOSE):]
    assert [p.owner[1].name for p in tail] == [v.name for v in LOOSE]
    assert {(p.owner[0], p.owner[2]) for p in tail} == {(ident.SETS_MODEL, ident.SETS_LEVEL)}
    assert all(p.case.imperfections.head_gap.mean == pytest.approx(2.5e-4) for p in tail)


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


def test_kick_start_points_ask_the_kick_then_the_test_level_on_each_seed(frozen, tmp_path):
    """The kick-start's cases, read back from the case files the study writes: Model II y's
    frozen case, 2 cycles at 2.3 m/s2 then 50 at 1.53 m/s2 at 2.8 Hz, seeds 0-2, run on 1 s
    after the steps."""
    from dem.case import load_case
    from dem.table_motion import SteppedSineMotion
    from studies.as_built import kick_start as ks
    from studies.kit.study import write_case
    from studies.prediction.plan import sweep_case

    pts = list(ks.points(frozen, runs=tmp_path))
    assert [p.seed for p in pts] == [0, 1, 2]
    assert len({p.fingerprint for p in pts}) == 3
    base = sweep_case("model-ii-y", frozen["parameters"])
    for p in pts:
        case = load_case(write_case(p.case, p.case_file))
        ld = case.loading
        assert ld.type == "stepped_shake" and list(ld.direction) == [0.0, 1.0, 0.0]
        assert [(s.frequency, s.cycles, s.peak_acceleration) for s in ld.steps] == [
            (2.8, 2.0, 2.3), (2.8, 50.0, None)]
        assert ld.peak_acceleration == 1.53 and ld.start == "table-frame"
        motion = ld.motion()
        assert isinstance(motion, SteppedSineMotion)
        assert [s["peak_acceleration_m_s2"] for s in motion.steps_run()] == pytest.approx(
            [2.3, 1.53])
        assert motion.steps_run()[1]["cycles_run"] == pytest.approx(50.0)
        assert case.run.duration == pytest.approx(motion.t_end + 1.0)
        assert case.imperfections.seed == p.seed
        # everything else is the first prediction's frozen Model II y case
        assert case.imperfections.bed_unevenness == frozen["parameters"]["bed_unevenness"]
        assert case.material == base.material and case.scene == base.scene
        assert not case.run.vtk
    # the study's own points are these
    assert [p.fingerprint for p in ks.KickStart(frozen).points()] == \
        [p.fingerprint for p in pts]


def test_waveform_grid_patches_only_the_distortion_of_model_ii_y(frozen, tmp_path):
    """The waveform grid's cases, read back from the written case files: h3-20, spike, h3-10 in
    that order, each the frozen Model II y shake at 1.53 m/s2 with its distortion, 2.0 / 2.8 /
    3.6 Hz, 10 cycles, seeds 0-2."""
    from dem.case import load_case
    from studies.as_built.grids import GRIDS
    from studies.diagnosis.grid import variant_case
    from studies.kit.study import write_case
    from studies.prediction.plan import sweep_case

    grid = GRIDS["waveform-model-ii-y"]
    assert [v.name for v in grid.variants] == ["h3-20", "spike", "h3-10"]
    assert grid.frequencies == (2.0, 2.8, 3.6) and grid.seeds == (0, 1, 2)
    assert grid.cycles == 10.0
    base = sweep_case("model-ii-y", frozen["parameters"]).model_dump()
    want = {"h3-20": (0.20, None), "spike": (0.0, (0.5, 0.010)), "h3-10": (0.10, None)}
    for v in grid.variants:
        case = load_case(write_case(variant_case(grid, v, frozen["parameters"]),
                                    tmp_path / f"{v.name}.yaml"))
        d = case.loading.distortion
        spike = d.reversal_spike
        assert (d.third_harmonic, spike and (spike.peak, spike.duration)) == want[v.name]
        assert case.loading.peak_acceleration == 1.53 and case.loading.type == "shake"
        data = case.model_dump()
        data["loading"].pop("distortion")
        assert {k: data[k] for k in ("scene", "material", "imperfections", "loading")} == \
            {k: base[k] for k in ("scene", "material", "imperfections", "loading")}
        # the spike fits every frequency of the grid (half a period at 3.6 Hz: 0.139 s)
        for f in grid.frequencies:
            case.loading.model_validate({**case.loading.model_dump(), "frequency": f})


def test_the_kick_start_verdicts():
    from studies.as_built.kick_start import judge, verdict

    rock, quiet = {"branch": "rocking"}, {"branch": "quasi-static"}
    assert judge([rock] * 5, "roof only") == {"started": True, "holds": True,
                                               "rocking_at_end": True}
    assert judge([rock] * 5, "bricks fallen")["holds"] is False
    assert judge([rock, rock, quiet, rock, rock], "standing") == {
        "started": True, "holds": False, "rocking_at_end": True}
    assert judge([quiet] + [rock] * 4, "standing")["started"] is False
    assert judge([rock, {"branch": None}], "standing")["holds"] is None
    assert judge([], "standing")["holds"] is None
    # any of 3 seeds / majority (2 of 3), pending while the seeds left could still decide
    assert verdict([True]) == {"seeds_run": 1, "yes": 1, "any": True, "majority": None}
    assert verdict([False, False]) == {"seeds_run": 2, "yes": 0, "any": False,
                                       "majority": False}
    assert verdict([True, False, True])["majority"] is True
    assert verdict([True, False, False]) == {"seeds_run": 3, "yes": 1, "any": True,
                                             "majority": False}
    assert verdict([]) == {"seeds_run": 0, "yes": 0, "any": None, "majority": None}
