"""Where the engine's arrays live, and which copy is current: the host's numpy arrays alone
(:class:`HostResidency`: the CPU, the kernels use them in place, nothing is ever copied) or
those plus a device array of every field (:class:`DeviceResidency`: a CUDA GPU, or the CPU with
``device_arrays=True`` for its tests).  The engine holds exactly one of the two
(:func:`residency`); every question "is the host's copy current?" and every copy between host
and device goes through it, so the rest of the engine has no branch on "device or not".

What moves and when (dem.engine.device has the device arrays and the kernels that run there):

* Model: copied once (static).
* Control: one copy to the device before each launch (dem.engine.device.ChunkCopies: the
  loads of the chunk's steps that the device does not hold yet, and the probe slots; the
  diagnostics are reset on the device) and one back after it (status, steps done, deepest
  penetration, energy sums, packed on the device: a few hundred bytes a scene).  Its other
  fields (step parameters, local damping, active scenes, probed bodies, restored sums) go to
  the device only when the host changed them (their bytes against what the device holds),
  the area caps likewise.
* State and Contacts: per field, copied back only when the host reads it and only where the
  kernels wrote it since (``stale``); copied to the device only after the host may have written
  it (``dirty``); a host rebuild's poses only for the rebuilding scenes' rows (``host_scenes``).
  The neighbour lists are rebuilt on the device between two steps of a chunk
  (dem.engine.broadphase_device): their index arrays (pairs, adj_ptr, adj) are stale on the
  host after a chunk that rebuilt one (``LISTS``) and copied when read, the pair counts come
  back with the diagnostics.  The host's broad phase (the first lists, a list over the
  capacity, or ``device_broad_phase=False``) writes them on both sides, the shear history
  carried on the device (:meth:`DeviceResidency.install_pairs`).

Picture (one chunk of a device engine)::

    host                                   device
    ----                                   ------
    new loads rows, probe plan   --push-->  ring of loads -> Control   (one copy; unpack_chunk)
    changed Control fields       --push-->  Control           (seldom)
    dirty State/Contacts fields  --push-->  State, Contacts
                                             advance_device: each step, then the lists
                                             of the scenes that asked, U steps a launch,
                                             k/U launches (dem.engine.step_device)
    Control (status, sums, pair  <--pull--  Control           (one copy; pack_diagnostics)
      counts, rebuilds)
    State/Contacts fields        <--pull--  only the stale ones a reader asks for
    a host rebuild's index arrays --install_pairs--> Contacts (history moved on the device)
"""

from __future__ import annotations

import time

import numpy as np
import taichi as ti

from dem import ti_runtime
from dem.engine.containers import (PROBE_SLOTS, PROBES_PER_SCENE, SERIAL_CHUNK, Contacts,
                                   State, element_type, pair_lists)

# an engine on a device: steps per chunk of launches (the loads of a chunk are copied to the
# device before it; the host reads the status back after it).  A chunk end idles a GPU for the
# host's per-chunk work (~10 ms at K = 64 on the test VM, benchmarks/host_share.py: the loads,
# the copies, the probes, the caps' check), so chunks are long: the run loop's requests
# (ten frames), the settling looks (200 steps) and the probes' slots end most of them first
DEVICE_CHUNK = 1024

# an engine on a device: probed steps of a scene per chunk (control.probe_buf's Q; the most
# a chunk's header row carries, dem.engine.device.LOAD_COLUMNS): 6 slots hold the samples of a
# chunk of 810 steps at Model II's 500 Hz instruments (a sample every ~135 steps); more
# shorten the chunk
DEVICE_PROBE_SLOTS = 6

# a patch is counted as possibly over its area cap from (1 - this) x the cap
# (DeviceResidency.patches_over_caps); the device's and the host's sums of a patch's <= 9 point
# areas differ by ~1e-15 relative, so 1e-9 never hides a patch the host would find over
CAP_CHECK_MARGIN = 1e-9


class HostResidency:
    """Every array lives on the host only (the CPU path): the kernels take the containers'
    numpy arrays in place; every question of staleness answers "current" and nothing is
    copied."""

    on_device = False
    CHUNK_STEPS = SERIAL_CHUNK  # the most steps of a chunk (control.loads' rows)
    PROBE_SLOTS = PROBE_SLOTS   # probed steps of a scene in a chunk (control.probe_buf's)
    lists_on_device = False     # the neighbour lists are the host's (dem.engine.broadphase)

    @staticmethod
    def probe_bodies(largest: int) -> int:
        """Probed bodies a scene (control.probe_body's J) for scenes of at most ``largest``
        bodies: an instrument's blocks (a frame ends the chunk here: it costs nothing)."""
        return PROBES_PER_SCENE

    def __init__(self, model, state, contacts, control, device_broad_phase: bool = True):
        """``device_broad_phase``: no device here, the host's broad phase always."""
        self.model, self.state, self.contacts, self.control = model, state, contacts, control
        self._args = (model.args, state.args, contacts.args, control.args)

    def containers(self) -> tuple:
        """The argpacks of (Model, State, Contacts, Control), as the kernels take them."""
        return self._args

    def host(self, name: str, write: bool = True, fields=None) -> None:
        """The host's ``name`` is always current here (:meth:`DeviceResidency.host`)."""

    def host_scenes(self, name: str, fields, scenes) -> None:
        """The host's rows are always current here (:meth:`DeviceResidency.host_scenes`)."""

    def to_device(self, k: int) -> None:
        """Nothing to copy before a launch."""

    def from_device(self) -> None:
        """Nothing to copy after a launch."""

    def device_stepper(self):
        """No broad phase between the steps of a chunk: a rebuild ends the chunk
        (:meth:`DeviceResidency.device_stepper`)."""
        return None

    def rebuilds(self) -> None:
        """No rebuilds but the host's (:meth:`DeviceResidency.rebuilds`)."""
        return None

    def pull_probes(self, rows: list[int]) -> None:
        """The probes' buffer is the host's already."""

    def patches_over_caps(self, n_slots: int, area_cap: np.ndarray, batched: bool) -> bool:
        """Whether a patch may be over its cap: the host checks every one itself."""
        return True

    def write_pairs(self, g: int, c, pairs: np.ndarray, n_bodies: int) -> None:
        """Scene g's new neighbour list ``pairs`` into its Contacts ``c`` (its region of the
        engine's), the shear history of the pairs that stay carried over (Contacts.write_pairs)."""
        n_old = c.n_pairs
        old_pairs = c.pairs[:n_old].copy() if n_old else None
        history = c.read_history() if n_old else None
        c.write_pairs(pairs, n_bodies, history, old_pairs)

    def transfer_counts(self) -> dict:
        """No device arrays: no copies (:meth:`DeviceResidency.transfer_counts`)."""
        return {}

    def install_counts(self) -> dict:
        return {"calls": 0, "bytes": 0}


class DeviceResidency:
    """A device array beside every host array (dem.engine.device.DeviceArrays) and, per field
    of State and Contacts, which copy is current: the module docstring."""

    on_device = True
    CHUNK_STEPS = DEVICE_CHUNK
    PROBE_SLOTS = DEVICE_PROBE_SLOTS

    @staticmethod
    def probe_bodies(largest: int) -> int:
        """Every body of the largest scene (or an instrument's blocks, if more): a frame is
        probed inside the launches (dem.run.record), as a chunk end costs a synchronisation
        and the host's per-chunk work; control.probe_buf is Q x G x J x 13 reals (6 x 64 x
        218 x 13: 8.7 MB for 64 Model II scenes), of which a chunk brings back the slots and
        rows it filled (:meth:`pull_probes`)."""
        return max(PROBES_PER_SCENE, int(largest))

    # Contacts fields current on the host after any launch, never copied back by Engine.host:
    # the broad phase's index arrays, which the stepping kernels only read (the host's broad
    # phase writes them on both sides: install_pairs), and the pair counts, brought back with
    # the diagnostics (ChunkCopies) where the device's broad phase may change them
    HOST_KEPT = {"state": frozenset(),
                 "contacts": frozenset({"pairs", "adj_ptr", "adj", "scene_pairs"})}
    # the index arrays the device's broad phase rewrites (dem.engine.broadphase_device): stale
    # on the host after a chunk in which a scene's list was rebuilt on the device, until read
    LISTS = ("pairs", "adj_ptr", "adj")
    # Contacts fields that install_pairs writes on the device from the device's history (a
    # rebuild): stale on the host after it
    INSTALLED = ("code", "npts", "loc", "shear", "patch_shape")
    # Control fields only the kernels write and the host reads on demand (the probes' samples)
    CONTROL_KERNEL_ONLY = ("probe_buf",)
    # Control fields only the host writes (before a launch): never copied back
    CONTROL_HOST_WRITTEN = ("loads", "probe_slot", "probe_body")
    # Control fields whose rows of a chunk go to the device in one copy (ChunkCopies)
    CONTROL_CHUNK_ROWS = ("loads", "probe_slot")

    def __init__(self, model, state, contacts, control, device_broad_phase: bool = True):
        """``device_broad_phase``: a scene's neighbour list is rebuilt on the device between
        two steps of a chunk (dem.engine.broadphase_device; the lists are then kernel-written:
        :attr:`LISTS`); False: by the host between chunks, a rebuild ending the chunk (the
        broad phase of the CPU path, dem.engine.broadphase, installed by :meth:`write_pairs`)."""
        from dem.engine.device import ChunkCopies, DeviceArrays, HistoryScratch

        self.model, self.state, self.contacts, self.control = model, state, contacts, control
        self.lists_on_device = bool(device_broad_phase)
        self._stepper = None  # dem.engine.step_device.DeviceStepper, when asked
        self.dev = {name: DeviceArrays(box) for name, box in (
            ("model", model), ("state", state), ("contacts", contacts), ("control", control))}
        for d in self.dev.values():
            d.push()
        real = ti.f32 if ti_runtime.real_dtype() == np.float32 else ti.f64
        self._scratch = HistoryScratch(contacts.capacity, real)
        self._cap_dev = None  # the area caps, for patches_over_caps
        self._cap_sent = None  # the caps the device holds
        self._chunk = ChunkCopies(control, self.dev["control"], contacts, self.dev["contacts"],
                                  real)
        # the Control fields copied per field only when changed (to_device): what the device
        # holds, as the host last sent or received it
        self._sent = {}
        self._remember([f for f in self.dev["control"].dev
                        if f not in self.CONTROL_KERNEL_ONLY + self.CONTROL_CHUNK_ROWS])
        # what unpack_chunk leaves in the diagnostics it resets
        self._reset = {"status": np.zeros_like(control.status),
                       "bad_body": np.zeros_like(control.bad_body),
                       "deepest_step": np.full_like(control.deepest_step, -1),
                       "steps_done": np.zeros_like(control.steps_done)}
        self.fields = {"state": State.field_names(), "contacts": Contacts.field_names()}
        self.stale = {"state": set(), "contacts": set()}   # fields whose device copy is newer
        self.dirty = {"state": set(), "contacts": set()}   # fields the host may have written
        self._installs = {"calls": 0, "bytes": 0}  # install_pairs' host arrays
        self._current = {}  # (container, stale field) -> scenes whose rows the host holds
        self._scene_lists = {}  # host_scenes' device arrays: scene lists, gathered rows
        self._gathered = {}
        self._probe_rows = {}  # pull_probes' device arrays by (slots, rows)

    def containers(self) -> tuple:
        """The argpacks of the device's (Model, State, Contacts, Control) arrays."""
        d = self.dev
        return (d["model"].args, d["state"].args, d["contacts"].args, d["control"].args)

    def host(self, name: str, write: bool = True, fields=None) -> None:
        """Make the host's ``name`` ("state" or "contacts") current before the host reads it,
        and, with ``write``, copy it to the device before the next launch (the host may write
        it).  ``fields``: only these fields of it (names of the container's FIELDS; None: all).

        Per field: a field is *stale* where the kernels wrote it since the host last copied it
        (every field but :attr:`HOST_KEPT` after a launch, :attr:`LISTS` too after a launch in
        which the device's broad phase rebuilt a list; :attr:`INSTALLED` after a host rebuild's
        install): only the stale fields asked for are copied back (one copy per field, of every
        scene of the engine), once.  ``write`` marks the fields asked for *dirty* (whether the
        host then writes them or not, and whether they were stale or not: a field the host
        writes whole without reading it still goes to the device); the dirty fields are copied
        to the device before the next launch (or install) and are never stale meanwhile, so a
        copy back never overwrites what the host wrote.  ``sim.state`` / ``sim.contacts`` ask for
        every field with ``write`` (a writer gets what it always got); the read-only accessors
        (Simulation.read_state / read_contacts) ask for their fields without it."""
        names = self.fields[name] if fields is None else tuple(fields)
        unknown = set(names) - set(self.fields[name])
        if unknown:
            raise KeyError(f"{name} has no field(s) {sorted(unknown)}")
        stale = self.stale[name]
        pull = [f for f in names if f in stale]
        if pull:
            self.dev[name].pull(pull)
            stale.difference_update(pull)
        if write:
            self.dirty[name].update(names)

    def host_scenes(self, name: str, fields, scenes) -> None:
        """Make the host's rows of the scenes ``scenes`` of ``fields`` (per-body fields of
        ``name``) current, to read them (a neighbour-list rebuild reads the poses of its scene
        only): a stale field's rows of those scenes are gathered on the device
        (dem.engine.device.gather_scene_rows) and copied back, one copy a field for all of them
        (and, for more than FEW_SCENES scenes, one of their list to the device), not the field
        of every scene.  The
        field stays stale for the other scenes (``_current``: the scenes whose rows of a stale
        field the host holds); nothing is marked to go back."""
        from dem.engine.device import FEW_SCENES, gather_scene_rows

        sb = self.model.scene_bodies
        need = {f: [g for g in scenes if g not in self._current.setdefault((name, f), set())]
                for f in fields if f in self.stale[name]}
        want = sorted({g for gs in need.values() for g in gs})
        if not want:
            return
        G = len(sb)
        n_cap = min(G, 1 << (len(want) - 1).bit_length())
        rows = int((sb[:, 1] - sb[:, 0]).max())
        d = self.dev[name]
        few = (want + [0] * FEW_SCENES)[:FEW_SCENES]  # the kernel's scalars name up to 4
        list_cap = n_cap if len(want) > FEW_SCENES else 1
        scenes_dev = self._scene_lists.get(list_cap)
        if scenes_dev is None:
            scenes_dev = self._scene_lists[list_cap] = ti.ndarray(ti.i32, shape=(list_cap,))
        if len(want) > FEW_SCENES:
            listed = np.zeros(n_cap, dtype=np.int32)
            listed[:len(want)] = want
            scenes_dev.from_numpy(listed)
            d.count("push", "scene_list", listed.nbytes)
        for f in need:
            dtype, elem = element_type(next(x for x in d.box.FIELDS if x.name == f))
            key = (name, f, n_cap * rows)
            out = self._gathered.get(key)
            if out is None:
                out = self._gathered[key] = ti.ndarray(dtype, shape=(n_cap * rows,))
            gather_scene_rows(len(want), rows, *few, scenes_dev,
                              self.dev["model"].dev["scene_bodies"], d.dev[f], out)
            got = out.to_numpy()
            d.count("pull", f, got.nbytes)
            host = getattr(d.box, f)
            for r, g in enumerate(want):
                b0, b1 = int(sb[g, 0]), int(sb[g, 1])
                host[b0:b1] = got[r * rows:r * rows + b1 - b0]
            self._current[(name, f)].update(want)

    def push_dirty(self, name: str) -> None:
        dirty = self.dirty[name]
        if dirty:
            self.dev[name].push([f for f in self.fields[name] if f in dirty])
            dirty.clear()

    def to_device(self, k: int) -> None:
        """Before a launch of k steps: the loads and probe slots of its k steps in one copy,
        with the diagnostics reset on the device (dem.engine.device.ChunkCopies); each other
        Control field only where the host changed it since the device last had it (its bytes
        against :attr:`_sent`'s: the host's writes of the step parameters, local damping,
        active scenes, probed bodies, restored sums, which change seldom); every dirty
        State / Contacts field."""
        self._chunk.push_chunk(k)
        self._sent.update(self._reset)
        changed = [f for f, sent in self._sent.items()
                   if not _same_bytes(getattr(self.control, f), sent)]
        if changed:
            self.dev["control"].push(changed)
            self._remember(changed)
        for name in ("state", "contacts"):
            self.push_dirty(name)

    def from_device(self) -> None:
        """After a launch: the control's kernel-written fields back in one copy
        (dem.engine.device.ChunkCopies, with the pair counts); every State / Contacts field the
        kernels write marked stale (nothing is dirty: to_device pushed it), the index arrays
        (:attr:`LISTS`) where the device's broad phase rebuilt a list in the launch or in an
        earlier one whose lists the host has not read yet."""
        self._remember(self._chunk.pull_diagnostics())
        lists = self.stale["contacts"] & set(self.LISTS)
        for name in ("state", "contacts"):
            self.stale[name] = set(self.fields[name]) - self.HOST_KEPT[name]
        self.stale["contacts"] |= lists
        if self._chunk.rebuilds_host.any():
            self.stale["contacts"].update(self.LISTS)
        self._current.clear()

    def device_stepper(self):
        """The device's stepping kernel with its broad phase (dem.engine.step_device: its
        scratch made on the first call), or None where the host's broad phase is used
        (``device_broad_phase`` False: one step a launch of dem.engine.step.advance_parallel)."""
        if not self.lists_on_device:
            return None
        if self._stepper is None:
            from dem.engine.step_device import DeviceStepper

            self._stepper = DeviceStepper(self.model, self.contacts, self.dev,
                                          self._chunk.rebuilds)
        return self._stepper

    def rebuilds(self) -> np.ndarray:
        """Each scene's neighbour-list rebuilds on the device in the last launch (brought back
        with the diagnostics)."""
        return self._chunk.rebuilds_host

    def _remember(self, names) -> None:
        """The host's ``names`` of the Control are what the device holds now."""
        for f in names:
            self._sent[f] = getattr(self.control, f).copy()

    def pull_probes(self, rows: list[int]) -> None:
        """The probes' samples of the last launch to the host: of control.probe_buf's first
        ``len(rows)`` slots, slot s's first ``rows[s]`` rows of each scene (the whole buffer is
        Q x G x J x 13 reals, J every body of the largest scene: a chunk's samples need a few
        of its slots and the instruments' few rows, a frame its slot's every row).  One gather
        on the device of every slot's fewest rows (dem.engine.device.gather_probe_rows, into an
        array of that shape: one a shape, kept), then one of each slot that needs more (a
        frame's): a chunk with a frame among six samples brings back one slot of every body,
        not six (8.7 MB for 64 Model II scenes)."""
        dev = self.dev["control"]
        buf = self.control.probe_buf
        if not rows:
            return
        if len(rows) == buf.shape[0] and min(rows) == buf.shape[2]:
            dev.pull(["probe_buf"])
            return
        fewest = min(rows)
        self._gather_probes(0, len(rows), fewest)
        for s, n in enumerate(rows):
            if n > fewest:
                self._gather_probes(s, 1, n)

    def _gather_probes(self, first: int, slots: int, rows: int) -> None:
        """control.probe_buf's slots first ... first + slots - 1, their first ``rows`` rows of
        each scene, from the device."""
        from dem.engine.device import gather_probe_rows

        t0 = time.perf_counter()
        dev = self.dev["control"]
        buf = self.control.probe_buf
        key = (slots, rows)
        if key not in self._probe_rows:
            self._probe_rows[key] = ti.ndarray(dev.dev["probe_buf"].dtype,
                                               shape=(slots, buf.shape[1], rows, buf.shape[3]))
        out = self._probe_rows[key]
        gather_probe_rows(dev.dev["probe_buf"], out, first)
        a = out.to_numpy()
        buf[first:first + slots, :, :rows] = a
        dev.count("pull", "probe_buf", a.nbytes)
        dev.counts["pull"]["seconds"] += time.perf_counter() - t0

    def patches_over_caps(self, n_slots: int, area_cap: np.ndarray, batched: bool) -> bool:
        """Whether any live pair's patch may exceed its bodies' area cap, counted on the device
        (dem.engine.device.patches_over_caps) so that the patches' areas of every scene (most
        of the bytes a chunk end brings back) are copied only when one may.  The margin
        (CAP_CHECK_MARGIN) is far above the round-off between the device's sum of a patch's
        point areas and the host's: where it says no, the host's check would find none."""
        from dem.engine.device import patches_over_caps

        if self._cap_dev is None:
            real = ti.f32 if ti_runtime.real_dtype() == np.float32 else ti.f64
            self._cap_dev = ti.ndarray(real, shape=(self.model.n_bodies,))
        if self._cap_sent is None or not _same_bytes(area_cap, self._cap_sent):
            cap = np.ascontiguousarray(area_cap, dtype=ti_runtime.real_dtype())
            self._cap_dev.from_numpy(cap)
            self._cap_sent = cap.copy()
            self.dev["control"].count("push", "area_cap", cap.nbytes)
        m, _, c, ctl = self.containers()
        return patches_over_caps(n_slots, self._cap_dev, 1.0 - CAP_CHECK_MARGIN, m, c, ctl,
                                 batched) > 0

    def write_pairs(self, g: int, c, pairs: np.ndarray, n_bodies: int) -> None:
        """Scene g's new neighbour list ``pairs`` into its Contacts ``c``: the host writes the
        index arrays on its copy (made current first where the device's broad phase rewrote
        them) and the device's (:meth:`install_pairs`); the history stays on the device."""
        self.host("contacts", write=False, fields=self.LISTS)
        n_old = c.n_pairs
        old_pairs = c.pairs[:n_old].copy() if n_old else None
        lists = pair_lists(pairs, n_bodies, c.capacity, old_pairs)
        c.pairs[...] = lists.pairs
        c.adj_ptr[...] = lists.adj_ptr
        c.adj[...] = lists.adj
        c.n_pairs = lists.n
        self.install_pairs(g, lists, n_old > 0)

    def install_pairs(self, g: int, lists, has_history: bool) -> None:
        """Scene g's new pair lists (containers.pair_lists) into the device's contacts
        (dem.engine.device.install_pairs: the history carried on the device)."""
        from dem.engine.device import install_pairs

        # what the host wrote since goes to the device first
        self.push_dirty("contacts")
        self.push_dirty("state")
        src = lists.src if lists.src is not None else np.zeros(0, dtype=np.int32)
        src_full = np.full(self.contacts.capacity, -1, dtype=np.int32)
        src_full[: len(src)] = src
        sc = self._scratch
        _, st, c, _ = self.containers()
        self._installs["calls"] += 1
        self._installs["bytes"] += (lists.pairs.nbytes + lists.adj_ptr.nbytes + lists.adj.nbytes
                                    + src_full.nbytes)
        install_pairs(g, lists.n, int(has_history), lists.pairs, lists.adj_ptr, lists.adj,
                      src_full, self.dev["model"].args, st, c, sc.code, sc.npts, sc.loc,
                      sc.shear)
        self.stale["contacts"].update(self.INSTALLED)  # the history, moved on the device
        for f in self.INSTALLED:  # stale for every scene again
            self._current.pop(("contacts", f), None)
        self.stale["contacts"].difference_update(self.LISTS)  # the host's are the device's

    def transfer_counts(self) -> dict:
        """Per container, the copies each way since construction (DeviceArrays.counts)."""
        return {name: d.counts for name, d in self.dev.items()}

    def install_counts(self) -> dict:
        return dict(self._installs)


def _same_bytes(a: np.ndarray, b: np.ndarray) -> bool:
    """Whether two arrays hold the same bytes (not ==: -0.0 and 0.0 differ, a NaN is itself)."""
    a, b = np.ascontiguousarray(a), np.ascontiguousarray(b)
    return a.shape == b.shape and a.dtype == b.dtype and np.array_equal(a.view(np.uint8),
                                                                         b.view(np.uint8))


def residency_kind(on_device: bool) -> type:
    """The residency of an engine's containers: on a device, or on the host only (its
    CHUNK_STEPS, PROBE_SLOTS and probe_bodies shape the Control; an instance holds the
    containers)."""
    return DeviceResidency if on_device else HostResidency
