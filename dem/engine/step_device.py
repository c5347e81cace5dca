"""The stepping kernel of an engine on a device: several steps a launch, each followed by its
broad phase.

Why: on a GPU the kernels of a step of 64 Model II scenes take ~0.135 ms (an H100,
results/batched-engine/README.md), while the host's Python of one launch costs 70-120 us on the
test machine (dem.engine.launch: Taichi 1.7.4 needs a fresh launch context a launch on a
device, with every ndarray argument set again), and the device's broad phase was a second
launch a step.  :func:`advance_device` runs ``steps`` steps in one launch: each step is
:func:`dem.engine.step.parallel_step` and then :func:`dem.engine.broadphase_device.rebuild_stage`,
inlined one after the other at the kernel's top level (``ti.static(range(steps))`` unrolls
them: every loop stays a top-level parallel loop, and Taichi runs the top-level loops one after
the other, as the separate launches ran them).  A step s >= the chunk's length (or < 0), or
after a step that raised a stop bit, does nothing (parallel_step's test), so the host launches
s0 = 0, steps, 2 steps, ... up to the chunk's length without reading anything back, and the
trajectories are those of one step a launch, bit for bit (tests/test_engine_device.py,
tests/test_broadphase_device.py; two steps a launch under the ``slow`` marker).

One argpack, :data:`DeviceStepArgs`: every field of the four containers (their names do not
collide) and the broad phase's scratch, because Taichi 1.7.4 takes at most 64 argument elements
a kernel on x64 (the four containers' 56 fields, their 4 argpacks and 3 scalars were 63): one
argpack instead of four, the chunk's length instead of the pair slots (on a device every slot:
``pairs.shape[0]``), and the broad phase's integer scratch in one array read through views
(:class:`Packed`: the largest scene's bodies R and each table's offset in its header).

Compile time grows faster than ``steps`` (each step's code is its own, and Taichi's
control-flow-graph pass runs over the whole kernel): :data:`DEVICE_STEPS_PER_LAUNCH`.
"""

import numpy as np
import taichi as ti
from taichi.lang import impl

from dem import ti_runtime
from dem.engine.broadphase_device import rebuild_stage
from dem.engine.containers import ContactArgs, ControlArgs, ModelArgs, StateArgs
from dem.engine.geometry import MAXP
from dem.engine.step import parallel_step
from dem.environment import MAX_STEPS_PER_LAUNCH, int_variable

ti_runtime.quick_front_end()  # before this module's kernels are decorated

# steps a launch where neither the engine nor DEM_STEPS_PER_LAUNCH says: on a GPU two (the host's
# Python of a launch halved; more is not worth its compile: the engine's warm-up took 32 / 101 /
# 579 CPU-s at 1 / 2 / 4 steps on the test VM, Taichi's whole-kernel control-flow-graph pass
# growing faster than the kernel), elsewhere one (the CPU proxy of a device runs the tests: the
# cheapest compile)
DEVICE_STEPS_PER_LAUNCH = {"cuda": 2}


def steps_per_launch(requested: int | None = None) -> int:
    """Steps a launch of :func:`advance_device`: ``requested`` (the Engine's
    ``steps_per_launch``), else the environment's DEM_STEPS_PER_LAUNCH (dem.environment:
    a bad value raises its one-line error), else by arch (:data:`DEVICE_STEPS_PER_LAUNCH`, 1
    elsewhere)."""
    if requested is None:
        requested = int_variable("DEM_STEPS_PER_LAUNCH", 1, MAX_STEPS_PER_LAUNCH)
    if requested is None:
        requested = DEVICE_STEPS_PER_LAUNCH.get(ti_runtime.settings()["arch"], 1)
    if not 1 <= int(requested) <= MAX_STEPS_PER_LAUNCH:
        raise ValueError(f"steps_per_launch must be 1 - {MAX_STEPS_PER_LAUNCH}, got {requested}")
    return int(requested)


# the integer scratch's tables, in their order in the flat array after the header
# [R, offset of each table]: name -> (row length: the table's second index's extent or 1)
SCRATCH_TABLES = {"flagged": 1, "info": 3, "hit": 1, "rows": 2, "old_code": 1, "old_npts": 1}
HEADER = 1 + len(SCRATCH_TABLES)


def _scratch_sizes(G: int, R: int, P: int) -> dict:
    """Each table's elements (dem.engine.broadphase_device.rebuild_stage's scratch)."""
    return {"flagged": G + 1, "info": 3 * G, "hit": G * R * R, "rows": 2 * G * R,
            "old_code": G * P, "old_npts": G * P}


def scratch_layout(G: int, R: int, P: int) -> np.ndarray:
    """The header of the integer scratch: R, then each table's first element."""
    head = [R]
    at = HEADER
    for name, n in _scratch_sizes(G, R, P).items():
        head.append(at)
        at += n
    return np.array(head + [at], dtype=np.int64)  # the last: the array's length


class Packed:
    """A table of the flat integer scratch, indexed as its own array inside a kernel:
    ``view[i]`` or ``view[i, c]`` is ``base[base[slot] + i * row + c]`` (Taichi calls
    ``__getitem__`` of a Python object at compile time: the index arithmetic is the kernel's)."""

    def __init__(self, base, slot: int, row: int):
        self.base, self.slot, self.row = base, slot, row

    def __getitem__(self, index):
        at = impl.subscript(None, self.base, self.slot)
        if isinstance(index, tuple):
            i, c = index
            at = at + i * self.row + c
        else:
            at = at + index
        return impl.subscript(None, self.base, at)


class Offset:
    """Rows [offset, offset + n) of a 2-D array as their own array: ``view[i, q]`` is
    ``base[offset + i, q]`` (the old shear history kept after the old locations)."""

    def __init__(self, base, offset):
        self.base, self.offset = base, offset

    def __getitem__(self, index):
        i, q = index
        return impl.subscript(None, self.base, self.offset + i, q)


def _scratch_views(a) -> tuple:
    """rebuild_stage's scratch arguments (flagged, info, hit, rows, old_pairs, old_code,
    old_npts, old_loc, old_shear) on ``a``'s arrays."""
    slot = {name: 1 + k for k, name in enumerate(SCRATCH_TABLES)}
    v = {name: Packed(a.scratch, slot[name], row) for name, row in SCRATCH_TABLES.items()}
    return (v["flagged"], v["info"], v["hit"], v["rows"], a.old_pairs, v["old_code"],
            v["old_npts"], Offset(a.old_history, 0),
            Offset(a.old_history, a.pairs.shape[0]))


def _device_step_args():
    """Every field of the four containers, then the broad phase's scratch and its counts."""
    members = {}
    for pack in (ModelArgs, StateArgs, ContactArgs, ControlArgs):
        clash = set(members) & set(pack.members)
        assert not clash, f"container fields named alike: {sorted(clash)}"
        members.update(pack.members)
    # an engine on a device runs in f64 only (dem.engine.containers)
    members.update(
        scratch=ti.types.ndarray(dtype=ti.i32, ndim=1),
        old_pairs=ti.types.ndarray(dtype=ti.types.vector(2, ti.i32), ndim=1),
        old_history=ti.types.ndarray(dtype=ti.types.vector(3, ti.f64), ndim=2),
        rebuilds=ti.types.ndarray(dtype=ti.i32, ndim=1))
    return ti.types.argpack(**members)


DeviceStepArgs = _device_step_args()


@ti.kernel
def advance_device(s0: ti.i32, chunk_steps: ti.i32, dt: float, a: DeviceStepArgs,
                   steps: ti.template(), warped: ti.template(), hyperbolic: ti.template(),
                   overlap: ti.template(), pair_damping: ti.template()):
    """Steps s0 ... s0 + steps - 1 of a chunk of ``chunk_steps`` (module docstring), each
    followed by the broad phase of the scenes it flagged; the batched, atomic-sum variant of
    the parallel step (an engine on a device), its other variants as in
    dem.engine.step.advance_parallel."""
    for u in ti.static(range(steps)):
        parallel_step(s0 + u, chunk_steps, a.pairs.shape[0], dt, a, a, a, a, warped, hyperbolic,
                      overlap, True, pair_damping, True)
        # (local names unlike the argpack's members: Taichi refuses a local named as one)
        v_flagged, v_info, v_hit, v_rows, v_old_pairs, v_old_code, v_old_npts, v_old_loc, \
            v_old_shear = ti.static(_scratch_views(a))
        rebuild_stage(s0 + u, a.scratch[0], a.half, a.radius, a.inv_mass, a.scene_bodies,
                      a.pos, a.quat, a.rot, a.pairs, a.adj_ptr, a.adj, a.scene_pairs,
                      a.ref_pos, a.ref_quat, a.code, a.npts, a.loc, a.shear, a.patch_shape,
                      a.status, a.steps_done, a.active, a.step_parameters, v_flagged, v_info,
                      v_hit, v_rows, v_old_pairs, v_old_code, v_old_npts, v_old_loc, v_old_shear,
                      a.rebuilds)


class DeviceStepper:
    """The scratch of the device's broad phase for an engine's containers on the device
    (``dev``: dem.engine.device.DeviceArrays by container name), the argpack of the stepping
    kernel, and its launches by variant (:meth:`launch`, cached: dem.engine.launch).
    ``rebuilds``: the device array [G] of each scene's rebuilds since the chunk began
    (dem.engine.device.ChunkCopies: reset by unpack_chunk, packed with the diagnostics)."""

    def __init__(self, model, contacts, dev, rebuilds):
        G = len(model.scene_bodies)
        P = contacts.capacity
        sb = model.scene_bodies
        self.R = int((sb[:, 1] - sb[:, 0]).max())
        layout = scratch_layout(G, self.R, P)
        n = int(layout[-1])
        if n >= 2 ** 31:
            raise ValueError(f"the device broad phase's scratch needs {n} integers, over "
                             "2^31: fewer scenes an engine")
        self.scratch = ti.ndarray(ti.i32, shape=(n,))
        self.scratch.from_numpy(np.concatenate([layout[:-1], np.zeros(n - HEADER, np.int64)])
                                .astype(np.int32))
        v3 = ti.types.vector(3, ti.f64)
        self.old_pairs = ti.ndarray(ti.types.vector(2, ti.i32), shape=(G * P,))
        self.old_history = ti.ndarray(v3, shape=(2 * G * P, MAXP))
        self.rebuilds = rebuilds
        members = {}
        for name in ("model", "state", "contacts", "control"):
            members.update(dev[name].dev)
        self.args = DeviceStepArgs(**members, scratch=self.scratch, old_pairs=self.old_pairs,
                                   old_history=self.old_history, rebuilds=rebuilds)
        self._launches = {}

    def launch(self, steps: int, warped: bool, hyperbolic: bool, overlap: bool,
               pair_damping: bool):
        """The launch ``launch(s0, chunk_steps, dt)`` of :func:`advance_device` for these
        compile-time values (compiled on the first call, by a recording launch that runs no
        step: s0 = -(steps + 1) puts every step of it, s0 ... -2, below 0, which the stages
        refuse (dem.engine.step.parallel_step); a non-negative s0 + u could meet the device's
        steps done of the last chunk when a variant is recorded mid-run)."""
        from dem.engine.launch import CachedLaunch

        key = (steps, warped, hyperbolic, overlap, pair_damping)
        if key not in self._launches:
            self._launches[key] = CachedLaunch(advance_device, (-(steps + 1), 0, 0.0),
                                               self.args, *key)
        return self._launches[key]
