"""The engine's arrays on a device (many scenes on a CUDA GPU).

On the CPU the kernels use the containers' numpy arrays in place (zero copy).  On a GPU a numpy
argument is copied to the device and back at every launch, which for the arrays of a hundred
scenes (~300 MB of contacts) would cost more than the step itself.  An engine on a device
therefore keeps a device array (``ti.ndarray``) of every field beside the host's numpy array,
hands the kernels the device arrays, and moves data only where the host needs it:

* Model: copied once (static).
* Control: one copy each way a chunk (:class:`ChunkCopies`): to the device the loads of the
  chunk's steps it does not hold yet (a ring of loads kept there) and the probe slots, the
  diagnostics reset there by :func:`unpack_chunk`; back the status bits, steps done, deepest
  penetration and energy sums packed by :func:`pack_diagnostics`.  The other fields only when
  the host changed them (dem.engine.residency).
* State: per field, copied back only when the host reads it (a neighbour-list rebuild: pos,
  rot, quat of the rebuilding scenes' rows only, gathered by :func:`gather_scene_rows`; a
  recorded frame: pos, quat, vel, omega) and only where the kernels wrote it since
  (``stale``), copied to the device only after the host may have written it (``dirty``:
  ``sim.state``, the writers' access; the read-only ``sim.read_state(...)`` marks nothing).
  Engine.host keeps the two sets.
* Contacts: the same, lazily and per field.  A neighbour-list rebuild happens on the device
  between two steps of a chunk (dem.engine.broadphase_device: the index arrays pairs, adj_ptr,
  adj are then copied back only when the host reads them; the pair counts come back with the
  diagnostics, :class:`ChunkCopies`).  Where the host's broad phase runs instead (the first
  lists, a list over the capacity, ``device_broad_phase=False``) the host computes the new
  index arrays of the rebuilt scene and :func:`install_pairs` installs them on the device and
  carries the shear history there (the same arithmetic as Contacts.write_pairs: the same
  results).

Each copy is counted (``DeviceArrays.counts``, Engine.transfer_stats): benchmarks/batch_speed.py
``run`` measures a real batched run's traffic on the CPU.

The same code runs on the CPU with ``device_arrays=True`` (Taichi's ndarrays in host memory):
tests/test_engine_device.py checks it against the numpy path, with no GPU.
"""

import time

import numpy as np
import taichi as ti

from dem import ti_runtime
from dem.engine.containers import (ENERGY_TERMS, ContactArgs, ControlArgs, ModelArgs, StateArgs,
                                   element_type)
from dem.engine.geometry import MAXP
from dem.engine.mathutil import vec3
from dem.engine.step import pair_bodies, slot_live, slots_per_scene

ti_runtime.quick_front_end()  # before this module's kernels are decorated


class DeviceArrays:
    """Device copies of one container's fields (``box``: Model, State, Contacts or Control),
    with ``push`` (host -> device) and ``pull`` (device -> host, into the host arrays in
    place) by field name, and the argpack of the device arrays for the kernels.

    ``counts``: the copies made each way since construction, ``{"push" | "pull": {"copies",
    "bytes", "seconds", "fields": {name: bytes}}}`` (one copy per field moved: a Taichi
    from_numpy / to_numpy, on a GPU a kernel launch, a copy and a synchronisation each; seconds:
    the host's wall time in them), for benchmarks/batch_speed.py's ``run`` mode
    (Engine.transfer_stats)."""

    def __init__(self, box):
        self.box = box
        self.dev = {}
        for f in box.FIELDS:
            host = getattr(box, f.name)
            dtype, elem_shape = element_type(f)
            shape = host.shape[: host.ndim - len(elem_shape)]
            self.dev[f.name] = ti.ndarray(dtype=dtype, shape=shape)
        self.args = box.ARGS(**self.dev)
        self.counts = {way: {"copies": 0, "bytes": 0, "seconds": 0.0, "fields": {}}
                       for way in ("push", "pull")}

    def push(self, names=None) -> None:
        t0 = time.perf_counter()
        for name in names or self.dev:
            a = np.ascontiguousarray(getattr(self.box, name))
            self.dev[name].from_numpy(a)
            self.count("push", name, a.nbytes)
        self.counts["push"]["seconds"] += time.perf_counter() - t0

    def pull(self, names=None) -> None:
        t0 = time.perf_counter()
        for name in names or self.dev:
            a = self.dev[name].to_numpy()
            getattr(self.box, name)[...] = a
            self.count("pull", name, a.nbytes)
        self.counts["pull"]["seconds"] += time.perf_counter() - t0

    def count(self, way: str, name: str, nbytes: int) -> None:
        """One copy of ``nbytes`` bytes of ``name`` (a field, or a copy that carries several:
        ChunkCopies' "chunk_rows" and "diagnostics", the caps' "area_cap") counted ``way``."""
        c = self.counts[way]
        c["copies"] += 1
        c["bytes"] += nbytes
        c["fields"][name] = c["fields"].get(name, 0) + nbytes

    def nbytes(self) -> int:
        return self.box.nbytes()


class HistoryScratch:
    """One scene's shear history (code, npts, loc, shear of its P slots) on the device: where
    :func:`install_pairs` keeps the old list's history while it writes the new one."""

    def __init__(self, capacity: int, real):
        self.code = ti.ndarray(ti.i32, shape=(capacity,))
        self.npts = ti.ndarray(ti.i32, shape=(capacity,))
        self.loc = ti.ndarray(ti.types.vector(3, real), shape=(capacity, MAXP))
        self.shear = ti.ndarray(ti.types.vector(3, real), shape=(capacity, MAXP))


@ti.kernel
def install_pairs(g: ti.i32, n_new: ti.i32, has_history: ti.i32,
                  new_pairs: ti.types.ndarray(ndim=2), new_ptr: ti.types.ndarray(ndim=1),
                  new_adj: ti.types.ndarray(ndim=1), src: ti.types.ndarray(ndim=1),
                  model: ModelArgs, state: StateArgs, contacts: ContactArgs,
                  s_code: ti.types.ndarray(ndim=1), s_npts: ti.types.ndarray(ndim=1),
                  s_loc: ti.types.ndarray(ndim=2), s_shear: ti.types.ndarray(ndim=2)):
    """Scene g's new neighbour list (dem.engine.containers.pair_lists: pairs [P, 2], adj_ptr,
    adj, src [P]: the old slot of each new pair, -1 for a new one) into the device's Contacts,
    as Contacts.write_pairs does on the host: the history (code, npts, loc, shear) of kept pairs
    moved to their new slots, the others' cleared (code -1, no points), no kept patch reused,
    the reference poses of the skin criterion set to the scene's poses."""
    P = slots_per_scene(contacts)
    base = g * P
    for p in range(P):
        s_code[p] = contacts.code[base + p]
        s_npts[p] = contacts.npts[base + p]
        for q in range(MAXP):
            s_loc[p, q] = contacts.loc[base + p, q]
            s_shear[p, q] = contacts.shear[base + p, q]
    for p in range(P):
        slot = base + p
        contacts.pairs[slot] = ti.math.ivec2(new_pairs[p, 0], new_pairs[p, 1])
        old = -1
        if has_history != 0 and p < n_new:
            old = src[p]
        if old >= 0:
            contacts.code[slot] = s_code[old]
            contacts.npts[slot] = s_npts[old]
            for q in range(MAXP):
                contacts.loc[slot, q] = s_loc[old, q]
                contacts.shear[slot, q] = s_shear[old, q]
        else:
            contacts.code[slot] = -1
            contacts.npts[slot] = 0
            if has_history != 0:
                for q in range(MAXP):
                    contacts.loc[slot, q] = vec3(0.0)
                    contacts.shear[slot, q] = vec3(0.0)
        shape = contacts.patch_shape[slot, 0]
        shape[3] = 0.0
        contacts.patch_shape[slot, 0] = shape
    for e in range(2 * P):
        contacts.adj[2 * base + e] = new_adj[e]
    b0 = model.scene_bodies[g][0]
    b1 = model.scene_bodies[g][1]
    for k in range(b1 - b0 + 1):
        contacts.adj_ptr[b0 + g + k] = new_ptr[k]
    for b in range(b0, b1):
        contacts.ref_pos[b] = state.pos[b]
        contacts.ref_quat[b] = state.quat[b]
    contacts.scene_pairs[g] = n_new


@ti.kernel
def patches_over_caps(n_slots: ti.i32, cap: ti.types.ndarray(ndim=1), margin: float,
                      model: ModelArgs, contacts: ContactArgs, control: ControlArgs,
                      batched: ti.template()) -> ti.i32:
    """The number of live pair slots whose contact patch (the sum of its points' areas, m^2)
    exceeds ``margin`` x the smaller area cap of its two bodies (``cap``: per body, m^2, inf
    where uncapped).  StepSize.check_caps (dem.engine.stepsize) asks it before copying every
    patch area to the host: with ``margin`` just below 1 (residency.CAP_CHECK_MARGIN) a count
    of 0 means the host's own check, whose sums differ from these by round-off only, would find
    no patch over its cap."""
    over = 0
    for p in range(n_slots):
        if slot_live(p, contacts, control, batched) == 1:
            i, j = pair_bodies(p, model, contacts, batched)
            patch = 0.0
            for q in range(contacts.npts[p]):
                patch += contacts.area[p, q]
            if patch > margin * ti.min(cap[i], cap[j]):
                over += 1
    return over


# the loads kept on the device (ChunkCopies): per row and scene gravity (3 reals, m/s^2) and
# base acceleration (3, m/s^2), control.loads' two vectors
LOAD_COLUMNS = 6
# the diagnostics and sums brought back in one copy (ChunkCopies.pull_diagnostics), per scene:
# status, bad_body, deepest (m), deepest_step, then the energy sums (J) in ENERGY_TERMS' order,
# then the pair count (contacts.scene_pairs: the device's broad phase may have changed it) and
# the neighbour-list rebuilds of the chunk on the device (dem.engine.broadphase_device);
# a last row: steps_done[0], steps_done[1] (the integers held exactly by reals)
N_ENERGY = len(ENERGY_TERMS)
DIAGNOSTIC_COLUMNS = 4 + N_ENERGY + 2


def first_unsent_row(ring: np.ndarray, held: np.ndarray, loads: np.ndarray,
                     ring_rows: np.ndarray, active: np.ndarray) -> int:
    """The first of a chunk's rows of ``loads`` ([k, G, LOAD_COLUMNS]; row i read from the
    ring's row ``ring_rows[i]``) that the host's copy of the ring (``ring``, ``held``: the rows
    it holds) does not hold, or holds with other bytes for an active scene (``active``: [G]
    bools); k if none (ChunkCopies.push_chunk sends the rows from it on).  Compared in blocks
    of growing length from the first row (1, 8, 64, ... rows): a chunk whose first row is new
    (every chunk of a load phase in time: its steps' times are new) costs one row's
    comparison, not the chunk's (4.4 ms at 750 steps x 64 scenes on the test VM); the row found
    is the one a comparison of every row finds."""
    k = len(loads)
    a, size = 0, 1
    while a < k:
        b = min(k, a + size)
        rows = ring_rows[a:b]
        same = held[rows] & np.all(
            (ring[rows][:, active].view(np.uint8)
             == np.ascontiguousarray(loads[a:b, active]).view(np.uint8)).reshape(b - a, -1),
            axis=1)
        if not same.all():
            return a + int(np.argmin(same))
        a, size = b, size * 8
    return k


class ChunkCopies:
    """The per-chunk copies of the Control between host and device, one each way.

    Before a launch of k steps (:meth:`push_chunk`): the loads of a step are a function of its
    time only, and a chunk cut short (a rebuild, a failure, a probe) is followed by one whose
    first steps are the ones the device was sent already.  So the device keeps a *ring* of
    W = 2 S rows of loads (S: control.loads' rows), step n of the engine's chunks in row
    n mod W, and the host a copy of what it holds (``_ring``, with ``_held``: rows it holds).
    The host compares the loads of the chunk's k steps, byte for byte, with its copy of the
    rows they will be read from, and sends only the rows from the first that differs (or was
    never sent) on, in one array with a header row (each scene's probed steps, slot by slot:
    control.probe_slot in Q numbers a scene instead of S); :func:`unpack_chunk` writes them
    into the ring, the ring's k rows into control.loads, the probe slots into
    control.probe_slot, and resets the diagnostics as Launcher.launch resets the host's.
    A row is compared for the scenes that step only (a frozen scene's loads are not read).
    The kernels read exactly the loads the host computed: a row not sent holds the same bytes.

    After it (:meth:`pull_diagnostics`): the diagnostics and energy sums, each scene's pair
    count (contacts.scene_pairs) and its rebuilds on the device in the chunk (``rebuilds``,
    dem.engine.broadphase_device), packed on the device by :func:`pack_diagnostics` into one
    array of G + 1 rows, unpacked into the host's fields.

    Both copies are counted with the Control's (DeviceArrays.count, as the fields
    "chunk_rows" and "diagnostics").  The reals are copied as they are and the integers are
    exactly representable as reals: the same values as a copy per field."""

    def __init__(self, control, control_dev: "DeviceArrays", contacts,
                 contacts_dev: "DeviceArrays", real):
        self.control, self.dev = control, control_dev
        self.contacts, self.contacts_dev = contacts, contacts_dev
        self.real = real
        self.np_real = np.float64 if real == ti.f64 else np.float32
        self.G = control.status.shape[0]
        self.S = control.loads.shape[0]
        self.Q = control.probe_buf.shape[0]
        if self.Q > LOAD_COLUMNS:
            raise ValueError(f"probe slots {self.Q} do not fit a header row of "
                             f"{LOAD_COLUMNS} columns")
        self.W = 2 * self.S
        self._ring = np.zeros((self.W, self.G, LOAD_COLUMNS), dtype=self.np_real)
        self._held = np.zeros(self.W, dtype=bool)
        self._ring_dev = ti.ndarray(real, shape=self._ring.shape)
        self.first = 0  # the ring row of the next chunk's first step
        self._rows = {}  # R -> (host array [1 + R, G, LOAD_COLUMNS], device array)
        self._diag_host = np.zeros((self.G + 1, DIAGNOSTIC_COLUMNS), dtype=self.np_real)
        self._diag_dev = ti.ndarray(real, shape=self._diag_host.shape)
        # each scene's neighbour-list rebuilds on the device since the chunk began (written by
        # dem.engine.broadphase_device.rebuild_stage), and the host's copy of the last chunk's
        self.rebuilds = ti.ndarray(ti.i32, shape=(self.G,))
        self.rebuilds.from_numpy(np.zeros(self.G, dtype=np.int32))
        self.rebuilds_host = np.zeros(self.G, dtype=np.int64)

    def rows(self, n: int) -> int:
        """R: the rows of the array that carries n rows of loads (a power of two, at most
        2 S: a handful of device arrays serve every n; 0 for none)."""
        return 0 if n <= 0 else min(self.W, 1 << (int(n) - 1).bit_length())

    def push_chunk(self, k: int) -> None:
        """The loads and probe slots of the chunk's first k steps to the device (the rows the
        ring does not hold yet), and the diagnostics reset there (:func:`unpack_chunk`)."""
        t0 = time.perf_counter()
        ctl = self.control
        loads = ctl.loads[:k].reshape(k, self.G, LOAD_COLUMNS)
        ring_rows = (self.first + np.arange(k)) % self.W
        j = first_unsent_row(self._ring, self._held, loads, ring_rows, ctl.active != 0)
        n = k - j
        R = self.rows(n)
        if R not in self._rows:
            host = np.zeros((1 + R, self.G, LOAD_COLUMNS), dtype=self.np_real)
            self._rows[R] = (host, ti.ndarray(self.real, shape=host.shape))
        host, dev = self._rows[R]
        host[0] = -1.0  # the header: each scene's probed step of each slot, -1 none
        steps, scenes = np.nonzero(ctl.probe_slot[:k] >= 0)
        host[0, scenes, ctl.probe_slot[steps, scenes]] = steps
        host[1:1 + n] = loads[j:]
        self._ring[ring_rows[j:]] = loads[j:]
        self._held[ring_rows[j:]] = True
        dev.from_numpy(host)
        self.dev.count("push", "chunk_rows", host.nbytes)
        d = self.dev.dev
        unpack_chunk(k, self.first, j, n, dev, self._ring_dev, d["loads"], d["probe_slot"],
                     d["status"], d["bad_body"], d["deepest_step"], d["steps_done"],
                     self.rebuilds)
        self.dev.counts["push"]["seconds"] += time.perf_counter() - t0

    def advance(self, done: int) -> None:
        """The chunk did ``done`` steps: the next one starts ``done`` rows on."""
        self.first = (self.first + int(done)) % self.W

    def pull_diagnostics(self) -> tuple:
        """The diagnostics and energy sums of the last chunk to the host's fields (one copy),
        with each scene's pair count (into contacts.scene_pairs) and rebuilds on the device
        (into :attr:`rebuilds_host`); returns the names of the Control fields written."""
        t0 = time.perf_counter()
        d = self.dev.dev
        pack_diagnostics(self._diag_dev, d["status"], d["bad_body"], d["deepest"],
                         d["deepest_step"], d["steps_done"], d["energy_sums"],
                         self.contacts_dev.dev["scene_pairs"], self.rebuilds)
        out = self._diag_dev.to_numpy()
        self.dev.count("pull", "diagnostics", out.nbytes)
        ctl, G = self.control, self.G
        ctl.status[...] = out[:G, 0]
        ctl.bad_body[...] = out[:G, 1]
        ctl.deepest[...] = out[:G, 2]
        ctl.deepest_step[...] = out[:G, 3]
        E = 4 + len(ENERGY_TERMS)
        ctl.energy_sums[...] = out[:G, 4:E]
        self.contacts.scene_pairs[...] = out[:G, E]
        self.rebuilds_host[...] = out[:G, E + 1]
        ctl.steps_done[...] = out[G, :2]
        self.dev.counts["pull"]["seconds"] += time.perf_counter() - t0
        self.advance(int(ctl.steps_done[0]))
        return ("status", "bad_body", "deepest", "deepest_step", "energy_sums", "steps_done")


@ti.kernel
def unpack_chunk(k: ti.i32, first: ti.i32, j: ti.i32, n: ti.i32,
                 rows: ti.types.ndarray(ndim=3), ring: ti.types.ndarray(ndim=3),
                 loads: ti.types.ndarray(ndim=3), probe_slot: ti.types.ndarray(ndim=2),
                 status: ti.types.ndarray(ndim=1), bad_body: ti.types.ndarray(ndim=1),
                 deepest_step: ti.types.ndarray(ndim=1), steps_done: ti.types.ndarray(ndim=1),
                 rebuilds: ti.types.ndarray(ndim=1)):
    """A chunk of k steps from ChunkCopies.push_chunk's array ``rows`` ([1 + R, G,
    LOAD_COLUMNS]: a header row, each scene's probed step of each probe slot, -1 none; then
    the loads of the chunk's steps j .. j + n - 1): those loads into the ring (step s of the
    chunk in row (first + s) mod W), the ring's rows of steps 0 .. k - 1 into control.loads, the
    probe slots into control.probe_slot, and the diagnostics reset as Launcher.launch resets
    the host's: status 0, bad_body 0, deepest_step -1, steps_done 0, and each scene's count of
    rebuilds on the device 0.  (Top-level loops run one after the other.)"""
    W = ring.shape[0]
    G = status.shape[0]
    for i, g in ti.ndrange(n, G):
        for c in ti.static(range(LOAD_COLUMNS)):
            ring[(first + j + i) % W, g, c] = rows[1 + i, g, c]
    for s, g in ti.ndrange(k, G):
        r = (first + s) % W
        loads[s, g, 0] = vec3(ring[r, g, 0], ring[r, g, 1], ring[r, g, 2])
        loads[s, g, 1] = vec3(ring[r, g, 3], ring[r, g, 4], ring[r, g, 5])
        probe_slot[s, g] = -1
    for g in range(G):
        for q in range(rows.shape[2]):
            s = ti.cast(rows[0, g, q], ti.i32)
            if 0 <= s < k:
                probe_slot[s, g] = q
        status[g] = 0
        bad_body[g] = 0
        deepest_step[g] = -1
        rebuilds[g] = 0
    for i in range(2):
        steps_done[i] = 0


@ti.kernel
def pack_diagnostics(out: ti.types.ndarray(ndim=2), status: ti.types.ndarray(ndim=1),
                     bad_body: ti.types.ndarray(ndim=1), deepest: ti.types.ndarray(ndim=1),
                     deepest_step: ti.types.ndarray(ndim=1), steps_done: ti.types.ndarray(ndim=1),
                     energy_sums: ti.types.ndarray(ndim=2), scene_pairs: ti.types.ndarray(ndim=1),
                     rebuilds: ti.types.ndarray(ndim=1)):
    """The diagnostics and energy sums, the pair counts and the rebuilds into one array
    (ChunkCopies.pull_diagnostics: its columns, DIAGNOSTIC_COLUMNS)."""
    G = status.shape[0]
    for g in range(G):
        out[g, 0] = ti.cast(status[g], ti.f64)
        out[g, 1] = ti.cast(bad_body[g], ti.f64)
        out[g, 2] = deepest[g]
        out[g, 3] = ti.cast(deepest_step[g], ti.f64)
        for e in ti.static(range(len(ENERGY_TERMS))):
            out[g, 4 + e] = energy_sums[g, e]
        out[g, 4 + N_ENERGY] = ti.cast(scene_pairs[g], ti.f64)
        out[g, 5 + N_ENERGY] = ti.cast(rebuilds[g], ti.f64)
    for i in range(2):
        out[G, i] = ti.cast(steps_done[i], ti.f64)


# scenes that DeviceResidency.host_scenes names by the gathering kernel's scalar arguments (the
# usual case: one or a few scenes rebuild at a chunk end); more go to the device as a list
FEW_SCENES = 4


@ti.kernel
def gather_scene_rows(n: ti.i32, rows: ti.i32, g0: ti.i32, g1: ti.i32, g2: ti.i32, g3: ti.i32,
                      scenes: ti.types.ndarray(ndim=1), scene_bodies: ti.types.ndarray(ndim=1),
                      src: ti.types.ndarray(ndim=1), out: ti.types.ndarray(ndim=1)):
    """The bodies' rows of ``src`` (a per-body field) of n scenes into ``out``, the r-th
    scene's bodies from row r x ``rows`` on (``rows``: at least the largest scene's bodies):
    DeviceResidency.host_scenes copies only these back.  The scenes: g0 .. g3 for n <=
    FEW_SCENES, else ``scenes[:n]`` (a list on the device)."""
    for r, i in ti.ndrange(n, rows):
        g = g0
        if n > FEW_SCENES:
            g = scenes[r]
        elif r == 1:
            g = g1
        elif r == 2:
            g = g2
        elif r == 3:
            g = g3
        b0 = scene_bodies[g][0]
        if b0 + i < scene_bodies[g][1]:
            out[r * rows + i] = src[b0 + i]


@ti.kernel
def gather_probe_rows(src: ti.types.ndarray(ndim=4), out: ti.types.ndarray(ndim=4),
                      first: ti.i32):
    """Slots first ... first + q - 1 of control.probe_buf [Q, G, J, 13] (``src``), their
    first j rows, into ``out`` [q, G, j, 13]: DeviceResidency.pull_probes copies back only the
    slots a chunk filled and the rows its steps need (an instrument's few blocks; a frame's
    every block)."""
    for q, g, j, c in ti.ndrange(out.shape[0], out.shape[1], out.shape[2], out.shape[3]):
        out[q, g, j, c] = src[first + q, g, j, c]
