"""Control split by role (issue 34 item 4): the four role tables partition Control's fields, in
the order of the kernels' argpack, and Control.role hands out the arrays the kernels write."""

from dem import ti_runtime
from dem.engine.containers import (CONTROL_FIELDS, CONTROL_ROLES, ENERGY_TERMS, STOP, Control)


def test_roles_partition_control_in_argpack_order():
    names = [f.name for role in CONTROL_ROLES.values() for f in role]
    assert names == [f.name for f in CONTROL_FIELDS]
    assert len(set(names)) == len(names)
    assert [f.name for f in CONTROL_ROLES["energy"]] == list(ENERGY_TERMS)


def test_role_returns_the_live_arrays():
    ti_runtime.init()
    ctl = Control(skin=0.01, max_speed=50.0, local_damping=0.1)
    params = ctl.role("parameters")
    assert float(params["skin"][0]) == 0.01 and float(params["local_damping"][0]) == 0.1
    ctl.role("diagnostics")["status"][0] = STOP
    assert int(ctl.status[0]) == STOP  # the same array, not a copy
