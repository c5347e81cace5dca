"""The engine's kernel plumbing: the cached launch gives what Taichi's own call gives,
bit for bit; every real number compiles in the engine's precision (no narrowing on a cold
compile); the containers' field tables are the kernels' arguments."""


import numpy as np
import pytest

from dem.builders import build_wall
from dem.case import Material, SolverSpec
from dem.engine import Simulation
from dem.engine.containers import (CONTACT_FIELDS, CONTROL_FIELDS, MODEL_FIELDS, STATE_FIELDS,
                                   ContactArgs, ControlArgs, ModelArgs, StateArgs)
from dem.run.build import joint_law, step_options
from engine_helpers import ROUND_OFF_POS_M, ROUND_OFF_QUAT, assert_cold_compile_is_f64

G = np.array([0.0, 0.0, -9.81])



def _wall_sim(scene, mode, **kw) -> Simulation:
    """An engine on a brick scene, mu 0.6, the default solver options but ``mode``."""
    return Simulation(scene, joint_law(Material(friction=0.6)),
                      step_options(SolverSpec(mode=mode)), **kw)

def _tilted(t):
    """Gravity of a table tilted by 35 deg about x (past the friction angle of mu = 0.6), plus a base acceleration pulse: every load
    path of the integrate stage is exercised, and the bricks slide and rock."""
    a = np.radians(35.0)
    g = 9.81 * np.array([0.0, np.sin(a), -np.cos(a)])
    base = np.outer(np.where(t < 0.01, 3.0, 0.0), [1.0, 0.0, 0.0])
    return np.tile(g, (len(t), 1)), base


def _run(mode, fast, steps=2500):   # 2500: 5 rebuilds, 2.4 mm moved (serial)
    sim = _wall_sim(build_wall("small", length=3, courses=4), mode, fast_launch=fast)
    sim.advance(steps, _tilted)
    return sim


def test_cached_launch_equals_taichi_call_bit_for_bit():
    """Both kernels, through the cached launch context and through Taichi's normal call, on a
    small wall sliding and rocking on a tilted, shaken table (neighbour-list rebuilds
    included): identical states, contacts and energy sums."""
    for mode in ("serial", "parallel"):
        fast, slow = _run(mode, True), _run(mode, False)
        assert fast.engine.launcher.kernel.cached, "the launch context was not recorded"
        assert fast.n_rebuilds > 1  # the scene moved enough to rebuild the neighbour list
        for name in ("pos", "quat", "vel", "angmom"):
            assert np.array_equal(getattr(fast.state, name), getattr(slow.state, name)), name
        for name in ("fn", "shear", "npts"):
            assert np.array_equal(getattr(fast.contacts, name), getattr(slow.contacts, name))
        # energy_stage sums the per-pair and per-body terms on one thread in a fixed order
        assert fast.control.energy() == slow.control.energy()
        moved = np.abs(fast.state.pos[:-1] - fast.scene.position).max()
        assert moved > 1e-3, f"{mode}: the scene barely moved ({moved:.2e} m)"


def test_parallel_kernel_is_deterministic_and_agrees_with_serial_to_round_off():
    """The parallel kernel, run twice, gives the same trajectory and energy sums bit for bit
    (CSR gather in a fixed order, no atomics on forces: a race would differ run to run); the
    serial kernel agrees with it to round-off (ROUND_OFF_*), and the energy sums up to the
    reassociation fast-math may compile differently into the two kernels (measured ~1e-17
    relative)."""
    ser, par, par2 = _run("serial", True, 600), _run("parallel", True, 600), \
        _run("parallel", True, 600)
    for name in ("pos", "quat", "vel", "angmom"):
        assert np.array_equal(getattr(par.state, name), getattr(par2.state, name)), name
    assert par.control.energy() == par2.control.energy()
    assert np.abs(ser.state.pos - par.state.pos).max() <= ROUND_OFF_POS_M
    assert np.abs(ser.state.quat - par.state.quat).max() <= ROUND_OFF_QUAT
    assert np.abs(ser.state.pos[:-1] - ser.scene.position).max() > 1e-4   # the bricks moved
    e_ser, e_par = ser.control.energy(), par.control.energy()
    scale = max(abs(v) for v in e_ser.values())
    assert scale > 0.0
    for name in e_ser:
        assert abs(e_ser[name] - e_par[name]) <= 1e-12 * scale, name


def test_argpacks_follow_the_field_tables():
    """One table per container is the allocation and the kernel signature: every field is a
    member of the container's argpack and an array of the container, in the same order."""
    sim = _wall_sim(build_wall("small", length=2, courses=2), "serial")
    for fields, pack, obj in ((MODEL_FIELDS, ModelArgs, sim.model),
                              (STATE_FIELDS, StateArgs, sim.state),
                              (CONTACT_FIELDS, ContactArgs, sim.contacts),
                              (CONTROL_FIELDS, ControlArgs, sim.control)):
        assert list(pack.members) == [f.name for f in fields]
        for f in fields:
            arr = getattr(obj, f.name)
            assert arr.flags.c_contiguous
            expect = np.int32 if f.elem in ("i32", "ivec2") else np.float64
            assert arr.dtype == expect, (f.name, arr.dtype)


@pytest.mark.slow
def test_cold_compile_has_no_narrowing_and_no_f32():
    """Compile every engine kernel with an empty offline cache in a fresh process: Taichi must
    not warn about a lossy assignment (an f32 value inside the f64 engine, as the point buffers
    were when their type was made before ti.init), and the compiled code must hold no f32."""
    assert_cold_compile_is_f64("friction=0.6")


def test_trajectory_does_not_depend_on_how_the_steps_are_launched():
    """Step k of a run sees the loads at t = k dt however the steps are grouped into launches
    (output frames, checkpoints and the parallel kernel cut the run into different launches):
    the same trajectory, bit for bit, from launches of 1, 7 and 2000 steps on a shaken table.
    (The box models amplify a last-bit difference of the loads to ~0.05 % of their response.)"""
    def shake(t):
        g = np.tile([0.0, 0.0, -9.81], (len(t), 1))
        a = np.zeros((len(t), 3))
        a[:, 1] = 3.0 * np.sin(2 * np.pi * 7.3 * t + 0.3)
        return g, a

    runs = []
    for chunk in (1, 7, 2000):
        sim = _wall_sim(build_wall("small", length=3, courses=4), "serial")
        while sim.step_count < 2100:
            sim.advance(min(chunk, 2100 - sim.step_count), shake)
        runs.append(sim)
    for sim in runs[1:]:
        assert sim.t == runs[0].t
        assert np.array_equal(sim.state.pos, runs[0].state.pos)
        assert np.array_equal(sim.state.quat, runs[0].state.quat)
    assert np.abs(runs[0].state.vel).max() > 1e-4  # the wall was shaken, not at rest
