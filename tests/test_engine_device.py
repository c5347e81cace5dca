"""The engine's device path (dem.engine.device), run on the CPU: Taichi's own
arrays (ti.ndarray) instead of numpy's, data moved only where the host needs it, neighbour
lists rebuilt on the device with the shear history carried there.  The kernels'
arithmetic is the same as the numpy path's, so a scene must follow the same trajectory to
round-off (tests/engine_helpers.py's bounds), lone and batched, with both kernels, through
rebuilds; a GPU runs this same code (the benchmark: benchmarks/batch_speed.py)."""

from __future__ import annotations

import numpy as np
import pytest

from dem.engine.containers import PROBES_PER_SCENE, State
from dem.engine.device import DIAGNOSTIC_COLUMNS, LOAD_COLUMNS, first_unsent_row
from dem.engine.residency import DEVICE_CHUNK, DeviceResidency
from dem.engine.simulation import Engine
from tests.engine_helpers import ROUND_OFF_POS_M, ROUND_OFF_QUAT
from tests.test_engine_batch import JOINTS, assert_same, options, shake, wall


@pytest.mark.parametrize("mode", ["serial", "parallel"])
def test_device_arrays_follow_the_numpy_path(mode):
    loads = [shake(4.0, 7.0), shake(6.0, 8.0, axis=1)]
    opts = options(mode=mode)
    host = Engine([wall() for _ in loads], JOINTS, opts)
    dev = Engine([wall() for _ in loads], JOINTS, opts, device_arrays=True)
    assert dev.on_device and not host.on_device
    steps = DEVICE_CHUNK + 17  # a chunk of DEVICE_CHUNK steps and a short one, three times
    for _ in range(3):  # the host reads the states between advances (a frame), as a run does
        host.advance(steps, loads)
        dev.advance(steps, loads)
        for a, b in zip(dev.simulations, host.simulations):
            assert np.abs(a.state.pos - b.state.pos).max() <= ROUND_OFF_POS_M
            assert np.abs(a.state.quat - b.state.quat).max() <= ROUND_OFF_QUAT
    for a, b in zip(dev.simulations, host.simulations):
        assert_same(a, b)
        assert np.array_equal(a.contacts.npts, b.contacts.npts)
        assert np.abs(a.contacts.shear - b.contacts.shear).max() <= 1e-15
    assert max(s.n_rebuilds for s in dev.simulations) > 2  # rebuilds on the device


def test_host_writes_reach_the_device():
    """A velocity set by the host (a lab start, a restart point) is what the kernels step."""
    opts = options()
    dev = Engine([wall()], JOINTS, opts, device_arrays=True)
    host = Engine([wall()], JOINTS, opts)
    for e in (dev, host):
        e.simulations[0].state.vel[:-1, 0] += 0.05
        e.advance(300, [shake(3.0, 1.0)])
    assert_same(dev.simulations[0], host.simulations[0])
    assert np.abs(dev.simulations[0].state.vel[:-1, 0]).max() > 0.01


# --- what moves between host and device (the host's copies of a batched run) ----------------
def _copies(engine) -> tuple[int, int, int, int]:
    """(pulls, bytes pulled, pushes, bytes pushed) so far (Engine.transfer_stats)."""
    s = engine.transfer_stats()
    return (s["device_to_host"]["copies"], s["device_to_host"]["bytes"],
            s["host_to_device"]["copies"], s["host_to_device"]["bytes"])


def test_read_only_accessors_copy_only_the_stale_fields_asked_for_and_nothing_back():
    """read_state / read_contacts copy the fields asked for (of every scene, once), none that
    the host holds current (the pair lists, where no list was rebuilt on the device since the
    host last had them), mark nothing to go back, and give views that cannot be written;
    sim.state still copies all and sends all back (a writer)."""
    loads = [shake(4.0, 7.0), shake(6.0, 8.0, axis=1)]
    e = Engine([wall() for _ in loads], JOINTS, options(), device_arrays=True)
    a, b = e.simulations
    e.advance(300, loads)
    n_state = len(State.field_names())
    # the control goes to the device as one copy a chunk (its steps' loads and probe slots:
    # dem.engine.device.ChunkCopies); its other fields only when the host changed them
    control_pushes = 1

    p0, pb0, q0, qb0 = _copies(e)
    st = a.read_state("pos", "vel")
    p1, pb1, q1, qb1 = _copies(e)
    assert p1 - p0 == 2 and pb1 - pb0 == e.state.pos.nbytes + e.state.vel.nbytes
    assert (q1, qb1) == (q0, qb0)
    assert not hasattr(st, "quat")  # what was not asked for is not there
    with pytest.raises(ValueError):
        st.pos[0, 0] = 1.0  # read only
    b.read_state("pos")  # the batch-mate's: copied already
    a.read_state("vel", "pos")
    assert [s.n_rebuilds for s in e.simulations] == [1, 1]  # the first lists only, the host's
    c = a.read_contacts("pairs", "wrench")  # so only wrench is copied
    p2, pb2, _, _ = _copies(e)
    assert p2 - p1 == 1 and pb2 - pb1 == e.contacts.wrench.nbytes
    assert c.n_pairs == a._contacts.n_pairs > 0
    a.kinetic_energy()
    a.unbalanced_force_ratio((0.0, 0.0, -9.81))
    assert _copies(e)[0] - p2 == 2  # omega, angmom (vel and wrench are current)
    assert not e.residency.dirty["state"] and not e.residency.dirty["contacts"]

    _, _, q3, qb3 = _copies(e)
    e.advance(DEVICE_CHUNK, loads)  # one chunk (a rebuild would push nothing either)
    _, _, q4, qb4 = _copies(e)
    assert q4 - q3 == control_pushes  # nothing of the state or contacts went back

    p4 = _copies(e)[0]
    a.state  # a writer: every field copied, every field back before the next launch
    assert _copies(e)[0] - p4 == n_state
    e.advance(DEVICE_CHUNK, loads)
    assert _copies(e)[2] - q4 == control_pushes + n_state
    assert e.n_chunks >= 3


def test_a_field_read_then_written_whole_goes_to_the_device():
    """A velocity read read-only (not marked), then written through sim.state, reaches the
    kernels; so does one written without a read (Engine.host with write and fields)."""
    opts = options()
    dev = Engine([wall()], JOINTS, opts, device_arrays=True)
    host = Engine([wall()], JOINTS, opts)
    for e in (dev, host):
        e.advance(300, [shake(3.0, 1.0)])
        sim = e.simulations[0]
        sim.read_state("vel")
        sim.state.vel[:-1, 0] += 0.05
        e.advance(300, [shake(3.0, 1.0)])
        e.host("state", write=True, fields=("angmom",))  # a no-op on the numpy path
        sim._state.angmom[:-1, 2] += 1e-4
        e.advance(300, [shake(3.0, 1.0)])
    assert_same(dev.simulations[0], host.simulations[0])


def test_the_device_counts_the_patches_over_their_caps_as_the_host_would():
    """StepSize.check_caps copies every patch area to the host only where the device counts a
    patch over (or within CAP_CHECK_MARGIN of) its bodies' smaller area cap
    (dem.engine.device.patches_over_caps): the count must be the host's own count from the
    copied areas, for caps that no patch reaches and for caps that some exceed."""
    from dem.engine.device import patches_over_caps

    loads = [shake(4.0, 7.0), shake(6.0, 8.0, axis=1)]
    dev = Engine([wall() for _ in loads], JOINTS, options(mode="parallel"), device_arrays=True)
    dev.advance(300, loads)
    c = dev.contacts
    dev.host("contacts", write=False, fields=("area", "npts"))  # what the host check reads
    P = c.capacity
    slots, areas = [], []
    for g, sim in enumerate(dev.simulations):
        b0 = int(dev.model.scene_bodies[g][0])
        for p in range(sim.contacts.n_pairs):
            slot = g * P + p
            slots.append(c.pairs[slot] + b0)
            areas.append(c.area[slot, : c.npts[slot]].sum())
    slots, areas = np.array(slots), np.array(areas)
    assert (areas > 0).sum() > 10  # closed joints to count
    m, _, cd, ctl = dev.containers()
    import taichi as ti

    for cap_value in (np.inf, 10 * areas.max(), np.median(areas[areas > 0]), 0.0):
        cap = np.full(dev.model.n_bodies, cap_value)
        cap_dev = ti.ndarray(ti.f64, shape=(dev.model.n_bodies,))
        cap_dev.from_numpy(cap)
        on_device = patches_over_caps(dev.n_pair_slots(), cap_dev, 1.0, m, cd, ctl,
                                      dev.variants.batched)
        on_host = int((areas > np.minimum(cap[slots[:, 0]], cap[slots[:, 1]])).sum())
        assert on_device == on_host, (cap_value, on_device, on_host)
    assert on_host > 0  # the last caps are exceeded


def test_the_control_goes_as_the_rows_of_a_chunk_and_what_the_host_changed():
    """A chunk sends the loads of its steps that the device does not hold yet and its probe
    slots in one copy (dem.engine.device.ChunkCopies) and brings the diagnostics and sums (and
    the pair counts and rebuilds of the device's broad phase) back in one; a Control field the host writes between chunks (a scene's local damping, the energy
    sums of a restored point) reaches the kernels, copied once, not every chunk."""
    loads = [shake(4.0, 7.0), shake(6.0, 8.0, axis=1)]
    opts = options()
    dev = Engine([wall() for _ in loads], JOINTS, opts, device_arrays=True)
    host = Engine([wall() for _ in loads], JOINTS, opts)

    def fields(way):
        return dict(dev.transfer_stats()[way]["by_container"]["control"]["fields"])

    for e in (dev, host):
        e.advance(300, loads)
    n0, push0, pull0 = dev.n_chunks, fields("host_to_device"), fields("device_to_host")
    saved = [e.simulations[0].save_point() for e in (dev, host)]
    for e in (dev, host):
        e.simulations[1].set_local_damping(0.3)
        e.advance(200, loads)
    for e, point in zip((dev, host), saved):
        e.simulations[0].restore_point(point)  # its energy sums back to the saved ones
        e.advance(200, loads)
    n1, push1, pull1 = dev.n_chunks, fields("host_to_device"), fields("device_to_host")
    chunks = n1 - n0
    assert chunks >= 2
    # a header row a chunk, and each step's loads about once: R < 2 n for n rows sent, and the
    # rows sent are the 400 steps' and at most one chunk's of DEVICE_CHUNK beyond the last
    G, row = len(loads), 6 * dev.control.loads.itemsize
    sent = push1["chunk_rows"] - push0["chunk_rows"]
    assert chunks * G * row + 400 * G * row <= sent \
        <= chunks * G * row + 2 * (400 + DEVICE_CHUNK) * G * row
    assert push1.get("local_damping", 0) - push0.get("local_damping", 0) \
        == dev.control.local_damping.nbytes  # once, not once a chunk
    assert push1.get("energy_sums", 0) - push0.get("energy_sums", 0) \
        == dev.control.energy_sums.nbytes
    for name in ("loads", "probe_slot", "status", "steps_done", "active", "step_parameters"):
        assert push1.get(name, 0) == push0.get(name, 0), name
    back = pull1["diagnostics"] - pull0["diagnostics"]
    assert back == chunks * (G + 1) * DIAGNOSTIC_COLUMNS * dev.control.energy_sums.itemsize
    for name in set(pull1) - {"diagnostics"}:  # no Control field back one by one
        assert pull1[name] == pull0.get(name, 0), name
    for a, b in zip(dev.simulations, host.simulations):
        assert_same(a, b)
    # the damping reached the kernels of scene 1 only
    assert dev.simulations[1].energy_report()["dissipated_local_damping"] > 0.0
    assert dev.simulations[0].energy_report()["dissipated_local_damping"] == 0.0


def test_a_rebuild_reads_the_poses_of_its_own_scenes_only():
    """Engine.host_scenes (a rebuild's read of pos, rot, quat): the rows of the scenes asked
    for, gathered on the device, one copy a field; the rows equal those of the whole field's
    copy; asked again, nothing is copied; after the next chunk they are stale again."""
    loads = [shake(4.0, 7.0), shake(6.0, 8.0, axis=1), shake(5.0, 6.0)]
    e = Engine([wall() for _ in loads], JOINTS, options(), device_arrays=True)
    e.advance(300, loads)

    def pulled():
        return dict(e.transfer_stats()["device_to_host"]["by_container"]["state"]["fields"])

    sb = e.model.scene_bodies
    rows = int((sb[:, 1] - sb[:, 0]).max())
    b0, b1 = (int(x) for x in sb[1])
    before = pulled()
    e.host_scenes("state", ("pos", "quat"), [1])
    after = pulled()
    assert after["pos"] - before.get("pos", 0) == rows * e.state.pos[0].nbytes  # one scene of 3
    assert after["quat"] - before.get("quat", 0) == rows * e.state.quat[0].nbytes
    got = e.state.pos[b0:b1].copy(), e.state.quat[b0:b1].copy()
    e.host_scenes("state", ("pos", "quat"), [1])
    assert pulled() == after  # current: nothing copied again
    whole = e.simulations[1].read_state("pos", "quat")  # the whole fields, copied
    assert np.array_equal(whole.pos, got[0]) and np.array_equal(whole.quat, got[1])
    e.advance(10, loads)
    now = pulled()
    e.host_scenes("state", ("pos",), [0, 2])  # stale again: scenes 0 and 2, one copy
    assert pulled()["pos"] - now["pos"] == 2 * rows * e.state.pos[0].nbytes


def test_host_scenes_names_many_scenes_by_a_list_on_the_device():
    """More scenes than the gathering kernel's scalars name (device.FEW_SCENES): their list
    goes to the device (one copy) and each scene's rows are its own."""
    from dem.engine.device import FEW_SCENES

    G = FEW_SCENES + 2
    loads = [shake(3.0 + g, 5.0 + g, axis=g % 2) for g in range(G)]
    e = Engine([wall() for _ in loads], JOINTS, options(), device_arrays=True)
    e.advance(40, loads)
    pushed = e.transfer_stats()["host_to_device"]["by_container"]["state"]["copies"]
    asked = list(range(1, G))  # FEW_SCENES + 1 scenes
    e.host_scenes("state", ("pos",), asked)
    assert e.transfer_stats()["host_to_device"]["by_container"]["state"]["copies"] == pushed + 1
    got = e.state.pos.copy()
    whole = e.simulations[0].read_state("pos")  # the whole field now (every scene)
    sb = e.model.scene_bodies
    for g in asked:
        b0, b1 = (int(x) for x in sb[g])
        assert np.array_equal(got[b0:b1], e.state.pos[b0:b1])
    assert whole.pos.shape[0] == int(sb[0, 1] - sb[0, 0])


def test_the_probes_pull_brings_back_only_the_slots_and_rows_asked_for():
    """The probe buffer holds every body of the largest scene on a device (a frame is probed
    there, dem.run.record.LaunchProbe), so a chunk's pull copies back only its first slots,
    each with the rows asked for (DeviceResidency.pull_probes: a frame's slot every row, a
    sample's few): exactly those, and no byte more."""
    e = Engine([wall(), wall()], JOINTS, options(), device_arrays=True)
    sim = e.simulations[0]
    ctl = e.control
    Q, G, J, W = ctl.probe_buf.shape
    largest = int(np.diff(e.model.scene_bodies, axis=1).max())
    assert J == sim.probe_capacity == max(PROBES_PER_SCENE, largest)
    assert sim.frames_in_launches
    values = np.arange(ctl.probe_buf.size, dtype=float).reshape(ctl.probe_buf.shape)
    ctl.probe_buf[...] = values
    e.residency.dev["control"].push(["probe_buf"])
    ctl.probe_buf[...] = 0.0
    before = _copies(e)
    e.residency.pull_probes([3, 3])
    after = _copies(e)
    assert np.array_equal(ctl.probe_buf[:2, :, :3], values[:2, :, :3])
    assert not ctl.probe_buf[2:].any() and not ctl.probe_buf[:, :, 3:].any()
    assert (after[0] - before[0], after[1] - before[1]) == (1, 2 * G * 3 * W * 8)
    # a frame in slot 1 between two samples: every slot's 2 rows, then slot 1's every row
    ctl.probe_buf[...] = 0.0
    e.residency.pull_probes([2, J, 2])
    again = _copies(e)
    want = np.zeros_like(values)
    want[:3, :, :2] = values[:3, :, :2]
    want[1] = values[1]
    assert np.array_equal(ctl.probe_buf, want)
    assert (again[0] - after[0], again[1] - after[1]) == (2, (3 * 2 + J) * G * W * 8)
    e.residency.pull_probes([J] * Q)  # the whole buffer: one copy of the field
    assert np.array_equal(ctl.probe_buf, values)


def _first_unsent_every_row(ring, held, loads, ring_rows, active) -> int:
    """The definition first_unsent_row implements, row by row."""
    for i, r in enumerate(ring_rows):
        if not held[r] or ring[r][active].tobytes() != loads[i][active].tobytes():
            return i
    return len(loads)


def test_the_first_unsent_row_is_the_one_a_comparison_of_every_row_finds():
    """ChunkCopies.push_chunk sends a chunk's loads from the first row the ring does not hold
    (or holds with other bytes, for a scene that steps); first_unsent_row compares in growing
    blocks and must find that row wherever it is: in the first row, inside or at the edges of
    a block (1, 9, 73, ...), in no row, by a row not held, by a sign of zero, by a frozen
    scene's loads only (not a difference)."""
    rng = np.random.default_rng(7)
    W, G, k = 512, 5, 200
    cases = 0
    for where in [0, 1, 2, 8, 9, 10, 72, 73, 74, 150, k - 1, None]:
        for how in ("value", "not held", "negative zero", "frozen scene"):
            ring = rng.normal(size=(W, G, LOAD_COLUMNS))
            ring[:, :, 0] = 0.0
            held = np.ones(W, dtype=bool)
            first = int(rng.integers(W))
            ring_rows = (first + np.arange(k)) % W  # wraps around the ring's end
            loads = ring[ring_rows].copy()
            active = np.ones(G, dtype=bool)
            active[3] = False
            if where is not None:
                if how == "value":
                    loads[where, 1, 2] += 1e-12
                elif how == "not held":
                    held[ring_rows[where]] = False
                elif how == "negative zero":
                    loads[where, 4, 0] = -0.0
                else:  # only the frozen scene's loads differ: not a row to send
                    loads[where, 3, 1] += 1.0
            want = _first_unsent_every_row(ring, held, loads, ring_rows, active)
            expected = k if where is None or how == "frozen scene" else where
            assert want == expected  # the reference reads the cases as meant
            assert first_unsent_row(ring, held, loads, ring_rows, active) == want
            cases += 1
    assert cases == 48
