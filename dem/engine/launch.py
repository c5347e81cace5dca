"""Cheap repeated launches of a Taichi kernel whose array arguments never change.

Why: calling a Taichi kernel from Python costs ~45 us plus ~20 us per numpy array argument
(Taichi 1.7.4 checks and registers every array on every call; measured on the 2-core test
machine, benchmarks/RESULTS.md), about 1 ms for the stepping kernels' 45 arrays, while the
launch itself (C++) costs ~1-2 us.  The engine's arrays are allocated once and written in place,
so the launch context that Taichi builds on the first call stays valid: :class:`CachedLaunch`
records it on that call and afterwards only resets the scalar arguments (step count, pair
count, dt) and launches.

This reaches into Taichi's launch internals (``impl.get_runtime().prog``, the launch context's
``set_arg_int`` / ``set_arg_float``); it is checked on the first use against the normal call
(:meth:`CachedLaunch.__init__` records it from a real call) and falls back to normal calls if
the internals are not there.  tests/test_engine_launch.py checks that both give bit-identical
trajectories.
"""

from __future__ import annotations

from collections import deque

from taichi.lang import impl


class _Recorder:
    """Stands in for Taichi's program object during one call and keeps its launch context."""

    def __init__(self, prog):
        self._prog = prog
        self.compiled = None
        self.ctx = None

    def __getattr__(self, name):
        return getattr(self._prog, name)

    def launch_kernel(self, compiled, ctx):
        self.compiled, self.ctx = compiled, ctx
        return self._prog.launch_kernel(compiled, ctx)


class CachedLaunch:
    """``launch = CachedLaunch(kernel, scalars, *arrays)`` calls ``kernel(*scalars, *arrays)``
    once through Taichi, then ``launch(*scalars)`` relaunches it with new scalar values.

    ``scalars`` are the leading int/float arguments (their Python types decide int or float);
    ``arrays`` the remaining arguments (argpacks or arrays), which must keep their addresses,
    and last any compile-time (``ti.template()``) arguments, fixed for this launch (Taichi
    leaves them out of the launch context, so the scalars keep their slots 0, 1, ...).
    """

    def __init__(self, kernel, scalars: tuple, *arrays):
        self.kernel = kernel
        self.arrays = arrays  # keep the argpacks alive: the context points into them
        self.kinds = tuple(isinstance(v, float) for v in scalars)
        self.ctx = self.compiled = self.prog = None
        runtime = impl.get_runtime()
        prog = runtime.prog
        rec = _Recorder(prog)
        runtime.prog = rec
        primal = getattr(kernel, "_primal", None)  # Taichi's Kernel: its C++ kernel, recorded
        spied = {}
        if primal is not None:
            launch = primal.launch_kernel

            def spy(t_kernel, *args):
                spied["t_kernel"] = t_kernel
                return launch(t_kernel, *args)
            primal.launch_kernel = spy
        try:
            kernel(*scalars, *arrays)
        finally:
            runtime.prog = prog
            if primal is not None:
                del primal.launch_kernel
        self.device_arrays = []
        if rec.ctx is not None and hasattr(rec.ctx, "set_arg_int") and \
                hasattr(rec.ctx, "set_arg_float"):
            self.ctx, self.compiled, self.prog = rec.ctx, rec.compiled, prog
            args = _launch_args(kernel, scalars, arrays)
            self.device_arrays = _device_array_slots(args)
            self.slots = [slot for slot, _ in self.device_arrays]
            self.slot_arrays = [arr for _, arr in self.device_arrays]
            if self.device_arrays:
                # device arrays: a fresh context per launch (reusing one after a CUDA launch
                # crashed Taichi 1.7.4 in set_arg_int), filled with the scalars, the argpacks
                # and their arrays as Taichi's own call does, without its Python-side checks
                self.t_kernel = spied.get("t_kernel")
                self.argpacks = [((k,), v._ArgPack__argpack) for k, v in enumerate(args)
                                 if hasattr(v, "_ArgPack__argpack")]
                if (self.t_kernel is None or self.device_arrays[0][1] is None
                        or not hasattr(rec.ctx, "set_arg_ndarray")
                        or not hasattr(rec.ctx, "set_arg_argpack")):
                    self.ctx = None

    @property
    def cached(self) -> bool:
        return self.ctx is not None

    def __call__(self, *scalars) -> None:
        if self.ctx is None:
            self.kernel(*scalars, *self.arrays)
            return
        ctx = self.ctx
        if self.device_arrays:
            ctx = self.t_kernel.make_launch_context()
            for slot, pack in self.argpacks:
                ctx.set_arg_argpack(slot, pack)
            # map, not a for loop: 60 slots a launch on a device, ~4 us of loop less
            # (benchmarks/host_share.py --launch)
            deque(map(ctx.set_arg_ndarray, self.slots, self.slot_arrays), maxlen=0)
        for k, (value, is_float) in enumerate(zip(scalars, self.kinds)):
            if is_float:
                ctx.set_arg_float((k,), float(value))
            else:
                ctx.set_arg_int((k,), int(value))
        self.prog.launch_kernel(self.compiled, ctx)


def _launch_args(kernel, scalars: tuple, arrays: tuple) -> list:
    """The arguments Taichi puts in the launch context, in order: all but the compile-time
    (``ti.template()``) ones, read from the kernel's annotations (a template may be an int: the
    steps a launch of dem.engine.step_device.advance_device); without them (not the Taichi this
    was written for), all but the bools."""
    from taichi.types.annotations import template

    values = (*scalars, *arrays)
    params = getattr(getattr(kernel, "_primal", None), "arguments", None)
    if params is None or len(params) != len(values):
        return [v for v in values if not isinstance(v, bool)]
    return [v for v, p in zip(values, params) if not isinstance(p.annotation, template)]


def _device_array_slots(positional: list) -> list:
    """The launch-context slots of the Taichi ndarrays (device arrays, dem.engine.device), the
    kernel's own array arguments and the members of its argpack arguments, with their C++
    arrays: Taichi 1.7.4 sets an array argument in the slot of its position and an argpack's
    array members as extra arguments after the kernel's own (in the order of the argpacks and
    their members), and a launch replaces each ndarray's device allocation in the context by a
    raw pointer, so the context is only valid for another launch once they are set again
    (numpy arrays keep their host pointers: nothing to redo).  Empty without ndarrays."""
    from taichi.lang._ndarray import Ndarray
    from taichi.lang.argpack import ArgPack

    slot = len(positional)
    out = []
    for k, v in enumerate(positional):
        if isinstance(v, Ndarray):  # an array argument of its own: its slot is its position
            out.append(((k,), v.arr))
        if not isinstance(v, ArgPack):
            continue
        names = getattr(v, "_ArgPack__annotations", None)  # Taichi's member order
        if names is None:
            return [((-1,), None)]  # not the Taichi this was written for: no cached launch
        for name in names:
            member = v[name]
            if isinstance(member, Ndarray):
                out.append(((slot,), member.arr))
            slot += 1
    return out
