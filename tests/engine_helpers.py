"""Shared helpers of the engine tests: scenes from explicit blocks and a stepping loop."""

from __future__ import annotations

import numpy as np
from scipy.spatial.transform import Rotation

from dem.builders import build_wall
from dem.case import parse_case
from dem.engine import Simulation
from dem.run.build import joint_law, step_options
from dem.scene import blocks_to_scene

G = 9.81


def make_sim(blocks, friction=0.5, solver=None, gravity=(0.0, 0.0, -G), **material):
    """A Simulation of explicit blocks (dicts in the case format) on the table."""
    case = parse_case({
        "name": "test",
        "scene": {"blocks": blocks},
        "material": {"friction": friction, **material},
        "run": {"duration": 1.0},
        "solver": solver or {},
    })
    return Simulation(blocks_to_scene(case.scene.blocks), joint_law(case.material),
                      step_options(case.solver),
                      gravity=gravity)


def constant_loads(g=(0.0, 0.0, -G), a=(0.0, 0.0, 0.0)):
    g = np.asarray(g, float)
    a = np.asarray(a, float)
    return lambda t: (np.tile(g, (len(t), 1)), np.tile(a, (len(t), 1)))


def tilt_gravity(rate_deg, start_deg, axis=(1.0, 0.0, 0.0)):
    """Gravity in the frame of a table turning about `axis` (see dem.loading.Tilt)."""
    axis = np.asarray(axis, float)

    def loads(t):
        theta = np.radians(start_deg + rate_deg * t)
        g = Rotation.from_rotvec(-theta[:, None] * axis[None, :]).apply([0.0, 0.0, -G])
        return g, np.zeros((len(t), 3))

    return loads


def record(sim, loads, duration, every):
    """Step for `duration` s, sampling every `every` s: t [T], pos [T,N,3], quat [T,N,4],
    omega [T,N,3]."""
    n_every = max(1, int(round(every / sim.dt)))
    n = sim.n_blocks
    ts, ps, qs, ws = [sim.t], [sim.state.pos[:n].copy()], [sim.state.quat[:n].copy()], \
        [sim.state.omega[:n].copy()]
    while sim.t < duration - 0.5 * sim.dt:
        sim.advance(n_every, loads)
        ts.append(sim.t)
        ps.append(sim.state.pos[:n].copy())
        qs.append(sim.state.quat[:n].copy())
        ws.append(sim.state.omega[:n].copy())
    return np.array(ts), np.array(ps), np.array(qs), np.array(ws)


def rotation_angle(quat, quat0):
    """Angle (rad) between orientations, arrays [..., 4] (w, x, y, z)."""
    c = np.abs(np.sum(quat * quat0, axis=-1))
    return 2.0 * np.arccos(np.clip(c, 0.0, 1.0))


def stretcher_wall(n_bricks=9, n_courses=15):
    """The builder's small-brick stretcher-bond wall (dem.builders.build_wall: half bricks at the
    ends of every other course, 9 x 15 = 142 blocks, counts tested in test_builders.py) as
    explicit block dicts, shifted so that the wall starts at x = 0."""
    wall = build_wall("small", length=n_bricks, courses=n_courses)
    assert np.allclose(wall.quat, [1.0, 0.0, 0.0, 0.0])  # laid flat, axis-aligned
    pos = wall.position - [(wall.position[:, 0] - 0.5 * wall.size[:, 0]).min(), 0.0, 0.0]
    return [{"size": sz.tolist(), "position": p.tolist(), "mass": float(m)}
            for sz, p, m in zip(wall.size, pos, wall.mass)]


# Serial against parallel kernel: the same arithmetic, compiled into two kernels.  Where the
# compiler emits the same instructions for both (the AMD EPYC test VMs) the
# trajectories are bit-identical; on an AVX-512 CPU (an Intel Xeon VM) fast-math's
# instruction selection differs at the last bit between them: measured 2.7e-20 m in position and
# 1.1e-19 in the quaternions after 600 steps of the wall of tests/test_engine_launch.py, 5.4e-20 m
# and 3.5e-18 after 2500 steps of the drop in tests/test_engine_stability.py.  The bounds sit
# ~4-5 orders above that and ~5 orders below a logic difference (one step's load missed or
# applied twice moves a block by g dt^2 ~ 1e-9 m).
ROUND_OFF_POS_M = 1e-15
ROUND_OFF_QUAT = 1e-13


def assert_cold_compile_is_f64(material_code: str, modes=("serial", "parallel")) -> None:
    """Compile the engine's kernels for a 2 x 2 small-brick wall of ``Material(material_code)``
    (Python source of the keyword arguments) in ``modes``, with an empty offline cache, in a
    fresh process: Taichi must not warn about a lossy assignment (an f32 value inside the f64
    engine, as the point buffers were when their type was made before ti.init), and the
    compiled code must hold no f32."""
    import os
    import subprocess
    import sys
    import tempfile
    import textwrap

    code = textwrap.dedent(f"""
        import numpy as np
        from dem.builders import build_wall
        from dem.case import Material, SolverSpec
        from dem.engine import Simulation
        from dem.run.build import joint_law, step_options
        for mode in {tuple(modes)!r}:
            sim = Simulation(build_wall("small", length=2, courses=2),
                             joint_law(Material({material_code})),
                             step_options(SolverSpec(mode=mode)))
            g = np.array([0.0, 0.0, -9.81])
            sim.advance(3, lambda t: (np.tile(g, (len(t), 1)), np.zeros((len(t), 3))))
            sim.mechanical_energy()
        print("COMPILED")
    """)
    with tempfile.TemporaryDirectory() as cache:
        env = dict(os.environ, TI_OFFLINE_CACHE_FILE_PATH=cache, TI_LOG_LEVEL="warn")
        out = subprocess.run([sys.executable, "-c", code], env=env, capture_output=True,
                             text=True, timeout=900)
        assert os.listdir(cache), "the offline cache was not written: not a cold compile"
    text = out.stdout + out.stderr
    assert out.returncode == 0 and "COMPILED" in out.stdout, text[-3000:]
    assert "lose precision" not in text, text[-3000:]
    assert "f32" not in text, text[-3000:]
