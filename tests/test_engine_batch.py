"""Several scenes in one engine: a scene stepped among others gives the
trajectory of the same scene stepped alone.

The batched kernels differ from a lone scene's only in integer work (the scenes' body and pair
offsets, the frozen-scene tests): the floating-point operations of a scene, and their order
(each scene's energy sums on one thread, pairs then bodies, as alone), are the same.  The bound
is therefore round-off: tests/engine_helpers.py's ROUND_OFF_POS_M / ROUND_OFF_QUAT (set for two
compilations of the same arithmetic, ~5 orders below a missed or doubled load of one step).
Covered: tilts at different rates, shakes at different frequencies and amplitudes (with
neighbour-list rebuilds), imperfect faces (the warped kernel) with different realisations, scenes
of different sizes in one engine, a scene that fails while the others go on, a scene's
restart point taken in an engine of several and resumed alone, and a restart point's clock kept
as saved alone and among others (one rule for both).
"""

from __future__ import annotations

import numpy as np
import pytest

from dem.builders import build_wall
from dem.case import Material, SolverSpec
from dem.engine import InstabilityError
from dem.engine.simulation import Engine, Simulation
from dem.imperfections import ImperfectionParams, apply_faces
from dem.run.build import joint_law, step_options
from tests.engine_helpers import ROUND_OFF_POS_M, ROUND_OFF_QUAT, G, tilt_gravity


def shake(freq_hz, amp, axis=0):
    """Table acceleration amp sin(2 pi f t) along ``axis`` (m/s^2), gravity down."""
    def loads(t):
        a = np.zeros((len(t), 3))
        a[:, axis] = amp * np.sin(2 * np.pi * freq_hz * t)
        return np.tile([0.0, 0.0, -G], (len(t), 1)), a
    return loads


def wall(length=3, courses=4):
    return build_wall("small", length=length, courses=courses)


JOINTS = joint_law(Material(friction=0.6))


def options(**solver):
    return step_options(SolverSpec(**solver))


def assert_same(batched: Simulation, alone: Simulation) -> None:
    for name, bound in (("pos", ROUND_OFF_POS_M), ("vel", 1e-12), ("quat", ROUND_OFF_QUAT),
                        ("angmom", 1e-12)):
        a, b = getattr(batched.state, name), getattr(alone.state, name)
        assert a.shape == b.shape
        assert np.abs(a - b).max() <= bound, (name, np.abs(a - b).max())
    assert batched.step_count == alone.step_count and batched.t == alone.t
    assert batched.n_rebuilds == alone.n_rebuilds
    assert batched.contacts.n_pairs == alone.contacts.n_pairs
    eb, ea = batched.energy_report(), alone.energy_report()
    scale = max(abs(v) for v in ea.values())
    for k in ea:
        assert abs(eb[k] - ea[k]) <= 1e-12 * scale, (k, eb[k], ea[k])
    assert batched.deepest_penetration()[0] == pytest.approx(
        alone.deepest_penetration()[0], rel=1e-12, abs=1e-18)


def run_alone(scene, loads, steps, opts, joints=JOINTS):
    sim = Simulation(scene, joints, opts)
    sim.advance(steps, loads)
    return sim


@pytest.mark.parametrize("mode", ["serial", "parallel"])
def test_shakes_at_different_frequencies_equal_separate_runs(mode):
    """Three copies of a small wall shaken at 4, 6 and 8 Hz (7-9 m/s^2, above mu g = 5.9 m/s^2:
    the walls slide on the table, the neighbour lists are rebuilt) in one engine, against each
    alone."""
    loads = [shake(4.0, 7.0), shake(6.0, 8.0), shake(8.0, 9.0, axis=1)]
    opts = options(mode=mode)
    engine = Engine([wall() for _ in loads], JOINTS, opts)
    # the parallel kernel runs the same arithmetic ~3x slower here: half the steps (the 8 Hz
    # wall has been rebuilt 6 times by then, 18 times by 6000 steps)
    steps = 6000 if mode == "serial" else 3000
    engine.advance(steps, loads)
    for sim, ld in zip(engine.simulations, loads):
        alone = run_alone(wall(), ld, steps, opts)
        assert_same(sim, alone)
    moved = [np.abs(s.state.pos[:-1] - s.scene.position).max() for s in engine.simulations]
    assert min(moved) > 1e-5 and max(s.n_rebuilds for s in engine.simulations) > 3


def test_tilts_and_scenes_of_different_sizes_equal_separate_runs():
    """A 3 x 4 wall, a 5 x 3 wall and a lone brick on tables tilting at different rates (the
    walls slide off towards the end) in one engine, against each alone with the engine's time
    step (the smallest critical step of the scenes: the lone brick's own is longer)."""
    scenes = [lambda: wall(3, 4), lambda: wall(5, 3), lambda: wall(1, 1)]
    loads = [tilt_gravity(20.0, 25.0), tilt_gravity(30.0, 20.0, axis=(0.0, 1.0, 0.0)),
             tilt_gravity(10.0, 28.0)]
    opts = options()
    engine = Engine([make() for make in scenes], JOINTS, opts)
    engine.advance(4000, loads)
    same_dt = options(dt=engine.dt)
    for sim, make, ld in zip(engine.simulations, scenes, loads):
        assert_same(sim, run_alone(make(), ld, 4000, same_dt))


def test_imperfect_realisations_equal_separate_runs():
    """Two realisations of warped faces (the warped kernel) shaken in one engine, with the time
    step given (the realisations' own critical steps differ slightly; one engine has one step)."""
    def realisation(seed):  # corner offsets of 20 um (3 sigma: within the overlap tolerance)
        return apply_faces(wall(), ImperfectionParams(bed_unevenness=2e-5, seed=seed))

    opts = options(dt=2e-5)
    loads = [shake(3.0, 2.5), shake(3.0, 2.5)]
    engine = Engine([realisation(1), realisation(2)], JOINTS, opts)
    assert engine.variants.warped and engine.variants.batched
    engine.advance(2000, loads)
    for seed, sim, ld in zip((1, 2), engine.simulations, loads):
        assert_same(sim, run_alone(realisation(seed), ld, 2000, opts))


def test_a_failed_scene_is_frozen_and_the_others_go_on():
    """The middle scene's table accelerates at a steady 30 m/s^2 (5 x mu g: the wall slides,
    faster than solver.max_speed = 0.5 m/s after ~0.02 s): it stops with its InstabilityError
    kept (alone it raises the same error at the same step); the two others finish and equal
    their lone runs."""
    opts = options(max_speed=0.5)

    def runaway(t):
        return np.tile([0.0, 0.0, -G], (len(t), 1)), np.tile([30.0, 0.0, 0.0], (len(t), 1))

    loads = [shake(3.0, 1.0), runaway, shake(4.0, 1.5)]
    engine = Engine([wall() for _ in loads], JOINTS, opts)
    engine.advance(3000, loads)
    bad = engine.simulations[1]
    assert isinstance(bad.failure, InstabilityError) and not engine.active(1)
    with pytest.raises(InstabilityError) as alone_err:
        run_alone(wall(), loads[1], 3000, opts)
    assert str(alone_err.value) == str(bad.failure)
    for g in (0, 2):
        assert engine.simulations[g].failure is None
        assert_same(engine.simulations[g], run_alone(wall(), loads[g], 3000, opts))


def test_a_restart_point_of_a_scene_in_an_engine_resumes_alone():
    """Scene 1's snapshot taken after 1500 steps in an engine of three restores into a lone
    Simulation, which then goes on as the lone run of 3000 steps."""
    opts = options()
    loads = [shake(2.0, 2.0), shake(3.0, 3.0), shake(4.0, 2.0)]
    engine = Engine([wall() for _ in loads], JOINTS, opts)
    engine.advance(1500, loads)
    snap = engine.simulations[1].snapshot()
    resumed = Simulation(wall(), JOINTS, opts)
    resumed.restore(snap)
    resumed.advance(1500, loads[1])
    assert_same(resumed, run_alone(wall(), loads[1], 3000, opts))


def test_a_scene_of_an_engine_advances_only_with_the_others():
    engine = Engine([wall(), wall()], JOINTS, options())
    with pytest.raises(RuntimeError, match="advances with the others"):
        engine.simulations[0].advance(10, shake(2.0, 1.0))


def test_a_restart_point_with_another_time_step_keeps_its_clock():
    """A scene restored from a restart point taken with a smaller time step (a lone run whose
    area caps shortened it) goes on from the snapshot's time, and the engine takes the smaller
    step for every scene, each clock re-anchored where it stands."""
    opts = options()
    loads = [shake(2.0, 2.0), shake(3.0, 3.0)]
    lone = Simulation(wall(), JOINTS, options(dt=0.5 * Engine([wall()], JOINTS, opts).dt))
    lone.advance(400, loads[1])
    snap = lone.snapshot()
    engine = Engine([wall(), wall()], JOINTS, opts)
    engine.advance(100, loads)
    t_other = engine.simulations[0].t
    engine.simulations[1].restore(snap)
    assert engine.dt == lone.dt
    assert engine.simulations[1].t == pytest.approx(lone.t, rel=1e-12)
    assert engine.simulations[0].t == pytest.approx(t_other, rel=1e-12)
    engine.advance(10, loads)
    assert engine.simulations[1].t == pytest.approx(lone.t + 10 * lone.dt, rel=1e-12)
    assert engine.simulations[0].t == pytest.approx(t_other + 10 * lone.dt, rel=1e-12)


def test_a_restored_scene_keeps_its_saved_clock_alone_or_among_others():
    """Restart points alike: a scene restored from a restart point taken with a smaller step
    keeps the snapshot's anchors and step, in an engine of two as in a lone Simulation, so its
    times are the lone run's bit for bit (t = t_anchor + (step - step_anchor) dt, the same
    operands), and the engine's other scene is re-anchored where it stood."""
    opts = options()
    loads = [shake(2.0, 2.0), shake(3.0, 3.0)]
    lone = Simulation(wall(), JOINTS, options(dt=0.5 * Engine([wall()], JOINTS, opts).dt))
    lone.advance(401, loads[1])
    snap = lone.snapshot()
    alone = Simulation(wall(), JOINTS, opts)
    alone.restore(snap)
    engine = Engine([wall(), wall()], JOINTS, opts)
    engine.advance(100, loads)
    t_other = engine.simulations[0].t
    among = engine.simulations[1]
    among.restore(snap)
    for sim in (alone, among):
        assert (sim._t_anchor, sim._step_anchor, sim.dt) == \
            (float(snap["sim._t_anchor"]), int(snap["sim._step_anchor"]), float(snap["sim.dt"]))
        assert sim.dt_changes == lone.dt_changes and sim.dt_crit == lone.dt_crit
        assert [sim.clock.time(lone.step_count + k) for k in (0, 7, 1000)] == \
            [lone.clock.time(lone.step_count + k) for k in (0, 7, 1000)]
    assert engine.simulations[0].t == t_other  # re-anchored at its own t: the same value


def test_loads_written_ahead_serve_the_next_chunk_only_where_they_are_still_its_loads():
    """Where an advance goes on past a chunk, the launcher writes the next chunk's loads while
    the chunk's launches run (Launcher.write_loads, ``ahead``); the next chunk takes a scene's
    rows as written only where its step count, clock and load function are the ones they were
    written for and they cover its steps, and computes them otherwise: the rows are always the
    scene's loads at its steps' times, bit for bit."""
    e = Engine([wall(), wall(), wall()], JOINTS, options())
    calls = []

    def counted(fn, g):
        def loads(t):
            calls.append(g)
            return fn(t)
        return loads

    fns = [shake(4.0, 7.0), shake(6.0, 8.0, axis=1), shake(5.0, 2.0)]
    loads = [counted(f, g) for g, f in enumerate(fns)]
    ctl, L = e.control, e.launcher
    k, ahead = 40, 25
    L.write_loads(k, loads, ahead=ahead)  # the next chunk's, written while this one runs
    assert calls == [0, 1, 2]
    for sim in e.simulations:  # the chunk did its steps
        sim.count_steps(ahead, -1, sim.dt)
    clock = e.simulations[1].clock  # scene 1's dt changes at the chunk's end
    clock.anchor(clock.time(e.simulations[1].step_count), e.simulations[1].step_count)
    clock.dt *= 0.5
    mine = counted(fns[2], 2)  # scene 2 gets another load function object
    calls.clear()
    L.write_loads(k, [loads[0], loads[1], mine])
    assert calls == [1, 2]  # scene 0's rows as written ahead; 1 and 2 computed again
    for g, sim in enumerate(e.simulations):
        grav, acc = fns[g](sim.clock.times(sim.step_count, k))
        assert np.array_equal(ctl.loads[:k, g, 0], grav)
        assert np.array_equal(ctl.loads[:k, g, 1], acc)
    calls.clear()
    L.write_loads(k, loads)  # what was written ahead served once
    assert calls == [0, 1, 2]
    L.write_loads(k, loads, ahead=ahead)
    for sim in e.simulations:
        sim.count_steps(ahead, -1, sim.dt)
    calls.clear()
    L.write_loads(k + 1, loads)  # a longer chunk than was written ahead
    assert calls == [0, 1, 2]
