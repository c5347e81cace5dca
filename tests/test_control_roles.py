"""Control split by role: the four role tables partition Control's fields, in
the order of the kernels' argpack, and Control.role hands out the arrays the kernels write."""

from dem import ti_runtime
from dem.engine.containers import (CONTROL_FIELDS, CONTROL_ROLES, ENERGY_TERMS, P_MAX_SPEED,
                                   P_PATCH_TOLERANCE, P_SKIN, STOP, Control)


def test_roles_partition_control_in_argpack_order():
    names = [f.name for role in CONTROL_ROLES.values() for f in role]
    assert names == [f.name for f in CONTROL_FIELDS]
    assert len(set(names)) == len(names)
    energy = CONTROL_ROLES["energy"]  # one row of ENERGY_TERMS per scene
    assert [f.name for f in energy] == ["energy_sums"]
    assert energy[0].dims == ("G", len(ENERGY_TERMS))


def test_role_returns_the_live_arrays():
    ti_runtime.init()
    ctl = Control(skin=0.01, max_speed=50.0, local_damping=0.1, patch_tolerance=1e-7)
    params = ctl.role("parameters")
    step = params["step_parameters"]
    assert (step[P_SKIN], step[P_MAX_SPEED], step[P_PATCH_TOLERANCE]) == (0.01, 50.0, 1e-7)
    assert float(params["local_damping"][0]) == 0.1
    ctl.role("diagnostics")["status"][0] = STOP
    assert int(ctl.status[0]) == STOP  # the same array, not a copy


def test_a_scene_region_is_a_view_of_its_row():
    ti_runtime.init()
    ctl = Control(skin=0.01, max_speed=50.0, local_damping=0.1, n_scenes=3)
    row = ctl.region(1)
    row.energy_sums[0, 2] = 5.0
    row.status[0] = STOP
    assert ctl.energy_sums[1, 2] == 5.0 and ctl.energy_sums[[0, 2]].sum() == 0.0
    assert list(ctl.status) == [0, STOP, 0]
    assert row.loads.shape == (ctl.loads.shape[0], 1, 2, 3)
    assert row.step_parameters is ctl.step_parameters  # shared by the scenes
    assert row.probe_slot.shape == (ctl.probe_slot.shape[0], 1)  # per step, as the loads
    assert row.probe_buf.shape == (ctl.probe_buf.shape[0], 1) + ctl.probe_buf.shape[2:]
    assert (ctl.probe_slot == -1).all() and (ctl.probe_body == -1).all()  # nothing probed
