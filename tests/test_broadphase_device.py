"""The broad phase on the device (dem.engine.broadphase_device) against the host's
(dem.engine.broadphase.candidate_pairs, containers.pair_lists), on the device path run on the
CPU (device_arrays=True: the code a GPU runs).

The two evaluate the same formulas, so the lists must be equal, pair for pair: random poses
(tilted blocks, touching, overlapping and separated ones, a long beam that takes the host's
second tier, fixed blocks, blocks near the table), and poses exactly on the thresholds (the
inflated boxes touching, the lowest corner exactly one skin above the table: numbers exact in
binary, so that both sides decide them alike whatever their round-off).  Then a batched run
through rebuilds, the device's broad phase against the host's: the lists, the shear history
and the trajectories equal bit for bit, in fewer chunks (the reference: the CPU path by
default; the device arrays with the host's broad phase, ``device_broad_phase=False``, a kernel
variant of its own, under the ``slow`` marker).  Also under ``slow`` (their compiles): the
device kernel's hyperbolic and pair-damped variants against the CPU path, and two steps a
launch (dem.engine.step_device) against one.
"""

from __future__ import annotations

import numpy as np
import pytest

from dem.case import Material
from dem.engine.broadphase import candidate_pairs
from dem.engine.containers import pair_lists
from dem.engine.errors import CapacityError
from dem.engine.residency import DEVICE_CHUNK
from dem.engine.simulation import Engine
from dem.quaternion import matrices
from dem.run.build import joint_law
from dem.scene import Scene
from tests.test_engine_batch import JOINTS, options, shake, wall

SKIN = 2.0 ** -5  # m: a power of two, so that the threshold poses below are exact in binary


def spread(sizes, fixed=None) -> Scene:
    """Blocks of edge lengths ``sizes`` [N, 3] (m), 3 m apart in the air (no pair at the
    start); their poses are written afterwards (:func:`pose`)."""
    n = len(sizes)
    pos = np.column_stack([3.0 * np.arange(n), np.zeros(n), np.full(n, 2.0)])
    return Scene(size=np.asarray(sizes, float), position=pos,
                 quat=np.tile([1.0, 0, 0, 0], (n, 1)),
                 mass=2000.0 * np.prod(sizes, axis=1),
                 fixed=np.zeros(n, bool) if fixed is None else fixed,
                 velocity=np.zeros((n, 3)), angular_velocity=np.zeros((n, 3)),
                 group=np.zeros(n, int), course=np.zeros(n, int))


def random_scene(rng, n, beam=False):
    """n bricks of random sizes (5-25 cm) at random tilts in a 0.5 x 0.5 x 0.35 m region resting
    on the table (many touch or overlap, some lie within the skin of z = 0), two of them
    fixed; with ``beam`` the first a 1.2 m beam across the region (bounding radius > twice the
    median: the host's second tier)."""
    sizes = rng.uniform(0.05, 0.25, (n, 3))
    if beam:
        sizes[0] = (1.2, 0.08, 0.08)
    fixed = np.zeros(n, bool)
    fixed[[1, 2]] = True
    pos = np.column_stack([rng.uniform(0.0, 0.5, n), rng.uniform(0.0, 0.5, n),
                           rng.uniform(0.0, 0.35, n)])
    quat = rng.normal(size=(n, 4))
    quat /= np.linalg.norm(quat, axis=1, keepdims=True)
    return spread(sizes, fixed), pos, quat


def threshold_scene():
    """Axis-aligned unit cubes at gaps on either side of the skin, and blocks whose lowest
    face is exactly one skin above the table or just above that (every coordinate exact)."""
    sizes = np.ones((6, 3))
    x = [0.0, 1.0 + SKIN, 3.0, 4.0 + SKIN + 2.0 ** -30, 6.0, 8.0]
    z = [3.0, 3.0, 3.0, 3.0, 0.5 + SKIN, 0.5 + SKIN + 2.0 ** -30]
    return spread(sizes), np.column_stack([x, np.zeros(6), z]), np.tile([1.0, 0, 0, 0], (6, 1))


def zero_loads(t):
    """No gravity, no table motion: nothing moves in the one step taken."""
    return np.zeros((len(t), 3)), np.zeros((len(t), 3))


def engine_at(poses, device=True):
    """An engine of one scene per (scene, pos, quat) of ``poses`` on the device path (or the
    CPU path: ``device`` False), every scene set to those poses with an empty list and its
    reference poses far away, so that the first step (which moves nothing: no loads, no pairs)
    flags every scene for a rebuild."""
    e = Engine([sc for sc, _, _ in poses], JOINTS,
               options(skin=SKIN, max_pairs_per_block=2, mode="parallel"), device_arrays=device)
    for sim, (sc, pos, quat) in zip(e.simulations, poses):
        st, c = sim.state, sim.contacts
        n = sc.n_blocks
        st.pos[:n], st.quat[:n], st.rot[:n] = pos, quat, matrices(quat)
        c.n_pairs = 0
        c.ref_pos[...] = 1e3
    return e


def test_device_lists_equal_the_host_broad_phase():
    """Every scene flagged at one step: the device's pair list of each scene equals
    candidate_pairs of the same poses exactly, its adjacency that of pair_lists; a scene whose
    list exceeds the capacity is not written, and the host's broad phase then raises today's
    CapacityError for it, alone among the scenes (the same message as on the CPU path)."""
    rng = np.random.default_rng(7)
    poses = [random_scene(rng, 12), random_scene(rng, 12, beam=True), threshold_scene(),
             random_scene(rng, 12)]
    pile_sc, _, pile_q = poses[3]  # the last: a dense pile, over the capacity
    poses[3] = (pile_sc, rng.uniform(0.0, 0.08, (12, 3)) + [0, 0, 0.1], pile_q)
    e = engine_at(poses)
    before = [s.n_rebuilds for s in e.simulations]
    e.advance(1, [zero_loads] * len(poses))
    capacity = e.contacts.capacity
    listed = []
    for g, sim in enumerate(e.simulations[:3]):
        assert sim.failure is None
        st = sim.read_state("pos", "rot", "quat")
        m = sim.model
        host = candidate_pairs(st.pos, st.rot, m.half_np, m.radius_np, m.fixed_np, m.table,
                               sim.skin)
        c = sim.read_contacts("pairs", "adj_ptr", "adj", "ref_pos", "ref_quat", "code", "npts")
        assert c.n_pairs == len(host) <= capacity
        assert np.array_equal(c.pairs[:c.n_pairs], host), g
        assert not c.pairs[c.n_pairs:].any()
        lists = pair_lists(host, m.n_bodies, capacity, None)
        assert np.array_equal(c.adj_ptr, lists.adj_ptr) and np.array_equal(c.adj, lists.adj)
        assert np.array_equal(c.ref_pos, st.pos) and np.array_equal(c.ref_quat, st.quat)
        assert (c.code == -1).all() and not c.npts.any()  # new pairs: no history
        assert sim.n_rebuilds == before[g] + 1  # counted on the device
        listed.append({(int(i), int(j)) for i, j in host})
    table = e.simulations[0].model.table
    assert any(j == table for _, j in listed[0]) and any(j != table for _, j in listed[0])
    assert (1, 2) not in listed[0]  # both fixed
    assert any(i == 0 for i, _ in listed[1])  # the beam
    assert {(0, 1), (4, 6)} <= listed[2] and not {(2, 3), (5, 6)} & listed[2]  # thresholds
    # the pile: over the capacity, failed by the host's broad phase with today's message
    err = e.simulations[3].failure
    assert isinstance(err, CapacityError) and "neighbour list overflow at step 1" in str(err)
    assert not e.control.active[3] and e.control.active[:3].all()
    ref = engine_at(poses, device=False)
    ref.advance(1, [zero_loads] * len(poses))
    assert str(ref.simulations[3].failure) == str(err)


# the reference: the CPU path (its host broad phase between chunks, the kernels' variants the
# warm-up compiles), or the device arrays with the host's broad phase (device_broad_phase=False:
# the parallel kernel of one step a launch on device arrays, a variant of its own: slow)
HOST_LISTS = [pytest.param({}, id="cpu-path"),
              pytest.param({"device_arrays": True, "device_broad_phase": False},
                           id="device-arrays-host-lists", marks=pytest.mark.slow)]


@pytest.mark.parametrize("ref_kind", HOST_LISTS)
def test_a_batched_run_equals_the_host_broad_phase_bit_for_bit(ref_kind):
    """Three small walls shaken, some blocks set sliding, with a small skin (rebuilds), on the
    device path with the device's broad phase and with the host's: the same lists and shear
    history after every advance, the same trajectories bit for bit (the kernels read the same
    numbers), the same rebuild counts, and the rebuilds no longer end a chunk."""
    loads = [shake(4.0, 7.0), shake(6.0, 8.0, axis=1), shake(5.0, 9.0)]
    opts = options(skin=2e-4, mode="parallel")
    dev = Engine([wall() for _ in loads], JOINTS, opts, device_arrays=True)
    ref = Engine([wall() for _ in loads], JOINTS, opts, **ref_kind)
    for e in (dev, ref):
        for g, sim in enumerate(e.simulations):
            sim.state.vel[g:-1, g % 2] += 0.2  # sliding blocks: rebuilds every few tens of steps
    for _ in range(2):
        for e in (dev, ref):
            e.advance(300, loads)
        for a, b in zip(dev.simulations, ref.simulations):
            for name in ("pos", "quat", "vel", "angmom"):
                assert np.array_equal(getattr(a.read_state(name), name),
                                      getattr(b.read_state(name), name)), name
            fields = ("pairs", "adj_ptr", "adj", "code", "npts", "loc", "shear")
            ca, cb = a.read_contacts(*fields), b.read_contacts(*fields)
            assert ca.n_pairs == cb.n_pairs
            for name in fields:
                assert np.array_equal(getattr(ca, name), getattr(cb, name)), name
            assert a.n_rebuilds == b.n_rebuilds
    # sliding 0.2 m/s for 600 steps of 14 us (~1 mm, friction slowing it) with a skin of
    # 0.2 mm: a rebuild per 0.1 mm moved, several per scene
    assert min(s.n_rebuilds - 1 for s in dev.simulations) >= 5  # after the first lists
    assert dev.transfer_stats()["install_pairs"]["calls"] == len(loads)  # the first lists only
    assert dev.n_chunks == 2 * -(-300 // DEVICE_CHUNK) < ref.n_chunks  # no rebuild ends one


@pytest.mark.parametrize("ref_kind", HOST_LISTS)
def test_a_lone_scene_on_the_device_rebuilds_there(ref_kind):
    """One scene on the device path (the batched kernels' pair counts, read on the device):
    its rebuilds happen inside the chunks and give the host broad phase's trajectory."""
    loads = [shake(6.0, 8.0, axis=1)]
    opts = options(skin=2e-4, mode="parallel")
    dev = Engine([wall()], JOINTS, opts, device_arrays=True)
    ref = Engine([wall()], JOINTS, opts, **ref_kind)
    for e in (dev, ref):
        e.simulations[0].state.vel[:-1, 1] += 0.2
        e.advance(400, loads)
    a, b = dev.simulations[0], ref.simulations[0]
    assert a.n_rebuilds == b.n_rebuilds > 2
    assert np.array_equal(a.read_state("pos").pos, b.read_state("pos").pos)
    assert dev.n_chunks == -(-400 // DEVICE_CHUNK) < ref.n_chunks


def test_steps_a_launch_come_from_the_engine_the_environment_or_the_arch(monkeypatch):
    """The device kernel's steps a launch: the Engine's value over DEM_STEPS_PER_LAUNCH over
    the arch's default (1 on the CPU); a bad value is refused with the name of its source."""
    from dem.engine.step_device import steps_per_launch

    monkeypatch.delenv("DEM_STEPS_PER_LAUNCH", raising=False)
    assert steps_per_launch() == 1  # the tests run on the CPU
    monkeypatch.setenv("DEM_STEPS_PER_LAUNCH", "3")
    assert steps_per_launch() == 3
    assert steps_per_launch(2) == 2
    monkeypatch.setenv("DEM_STEPS_PER_LAUNCH", "two")
    with pytest.raises(ValueError, match="DEM_STEPS_PER_LAUNCH='two'"):
        steps_per_launch()
    with pytest.raises(ValueError, match="steps_per_launch must be 1 - 8, got 0"):
        steps_per_launch(0)


def test_a_launch_at_a_negative_step_runs_nothing():
    """The launch that records a stepping kernel's launch context runs at a negative step
    (dem.engine.launch); at step -1 the count of steps done, 0, also reads "step -1 ran"
    (steps_done == s + 1), which without the stages' test s >= 0 runs a step on the loads of
    row -1.  A launch of the device's kernel at s0 = -1 moves nothing and counts no step."""
    e = Engine([wall(), wall()], JOINTS, options(), device_arrays=True)
    sim = e.simulations[0]
    sim.state.vel[0, 0] = 0.5  # a step would move block 0 by dt x 0.5 m/s
    before = sim.read_state("pos").pos.copy()
    e.residency.to_device(1)  # the velocity, and the chunk's diagnostics reset (steps done 0)
    e.launcher.kernel(-1, 1, e.dt)
    e.residency.from_device()
    assert e.control.steps_done[0] == 0
    assert np.array_equal(sim.read_state("pos").pos, before)


@pytest.mark.slow  # compiles the device kernel for 2 steps a launch (~100 CPU-s on the test
# VM, 3x one step's); the default tests run it at one step a launch, the same code once a step
def test_two_steps_a_launch_give_the_run_of_one_step_a_launch():
    """The device's kernel at 2 steps a launch against one step a launch, 8 scenes: nothing
    moves at the engine's construction (its recording launch runs no step: a step -1 on the
    loads of row -1 made NaNs at some batch sizes); then chunks of 301 steps (the last launch of each runs past the chunk's end) with
    rebuilds, and a scene that fails inside a launch: the same lists, history, trajectories,
    rebuilds and chunks bit for bit, about half the launches."""
    K = 8
    loads = [shake(4.0 + g, 7.0 + g % 3, axis=g % 2) for g in range(K)]
    opts = options(skin=2e-4)
    runs = {u: Engine([wall() for _ in loads], JOINTS, opts, device_arrays=True,
                      steps_per_launch=u) for u in (1, 2)}
    one, two = runs[1], runs[2]
    assert two.launcher.variants.device_steps == 2
    for name in ("pos", "quat", "vel", "angmom"):
        for a, b in zip(two.simulations, one.simulations):
            assert np.array_equal(getattr(a.read_state(name), name),
                                  getattr(b.read_state(name), name)), name
    for e in runs.values():
        for g, sim in enumerate(e.simulations):
            sim.state.vel[g % 3:-1, g % 2] += 0.2
        e.advance(301, loads)
        e.simulations[1].state.vel[0, 2] = np.nan  # scene 1 fails at its next step
        e.advance(301, loads)
    for a, b in zip(two.simulations, one.simulations):
        for name in ("pos", "quat", "vel", "angmom"):  # the failed scene's NaNs alike
            assert np.array_equal(getattr(a.read_state(name), name),
                                  getattr(b.read_state(name), name), equal_nan=True), name
        fields = ("pairs", "adj_ptr", "adj", "code", "npts", "loc", "shear")
        ca, cb = a.read_contacts(*fields), b.read_contacts(*fields)
        for name in fields:
            assert np.array_equal(getattr(ca, name), getattr(cb, name), equal_nan=True), name
        assert (a.n_rebuilds, a.step_count, a.t) == (b.n_rebuilds, b.step_count, b.t)
    assert min(s.n_rebuilds - 1 for s in two.simulations) >= 5
    assert two.simulations[1].failure is not None
    assert type(two.simulations[1].failure) is type(one.simulations[1].failure)
    assert two.n_chunks == one.n_chunks
    assert two.launcher.n_launches < 0.6 * one.launcher.n_launches


@pytest.mark.slow  # two device kernel variants of their own (~25 CPU-s of compile each)
@pytest.mark.parametrize("material", [
    pytest.param(Material(friction=0.6, normal_law="hyperbolic", max_closure=1e-3),
                 id="hyperbolic"),
    pytest.param(Material(friction=0.6, normal_damping="pair"), id="pair-damping")])
def test_the_device_kernels_variants_follow_the_cpu_path(material):
    """The device's kernel in its hyperbolic and pair-damped variants (the default tests reach
    the linear and the warped ones) against the CPU path, through rebuilds: the same
    trajectories bit for bit and the same rebuilds."""
    law = joint_law(material)
    loads = [shake(4.0, 7.0), shake(6.0, 8.0, axis=1)]
    opts = options(skin=2e-4, mode="parallel")
    dev = Engine([wall() for _ in loads], law, opts, device_arrays=True)
    ref = Engine([wall() for _ in loads], law, opts)
    for e in (dev, ref):
        for g, sim in enumerate(e.simulations):
            sim.state.vel[g:-1, g % 2] += 0.2
        e.advance(500, loads)
    for a, b in zip(dev.simulations, ref.simulations):
        for name in ("pos", "quat", "vel", "angmom"):
            assert np.array_equal(getattr(a.read_state(name), name),
                                  getattr(b.read_state(name), name)), name
        assert a.n_rebuilds == b.n_rebuilds > 3
