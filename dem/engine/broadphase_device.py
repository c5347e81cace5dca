"""Broad phase on the device: a scene's neighbour list rebuilt between two steps of a chunk.

On the device path (dem.engine.residency.DeviceResidency) :func:`rebuild_stage` runs after
every step of a chunk, in the same launch (dem.engine.step_device.advance_device).  For every
scene whose skin criterion fired at that step (``integrate_stage`` raised its REBUILD bit: a
body moved by more than skin/2 since the last rebuild), it rebuilds the scene's pair list on
the device, so that the chunk goes on for every scene and the host is not involved; a scene
without the bit costs nothing but the test of its bit.

The list is the one the host's broad phase makes (dem.engine.broadphase.candidate_pairs, the
same formulas in the same order):

* block pairs (i, j), i < j, neither the table, not both fixed (inverse mass 0), whose centres
  are within r_i + r_j + skin (r the bounding radius, m), and whose boxes inflated by skin/2
  on every side are not separated along any of the 15 axes of the separating-axis test (the
  6 face normals and the 9 cross products of edge directions, a cross product of norm
  <= 1e-6 left out as in :func:`dem.engine.broadphase._sat_separated`: the boxes are
  separated along L where |d . L| > r_a(L) + r_b(L), with r(L) = sum_k h_k |R e_k . L|);
* (i, table) for every movable block whose lowest corner is within the skin of z = 0
  (z_min = z - sum_k h_k |R_2k|).

The host's cKDTree only pre-selects pairs that the bounding-sphere test keeps anyway, so
testing every pair i < j of the scene (one thread each) gives the same set.  A pair so close
to a threshold that the two sides' round-off (fused multiply-adds under fast math) decide it
differently is a pair ~skin apart: no contact point before the next rebuild, so exact zeros
where it is gathered (tests/test_broadphase_device.py compares the lists).

The sorted list without a sort: each row i counts its partners j > i, an exclusive scan over
the rows (one thread per scene) gives each row's first slot, and each row writes its pairs in
order of j: the list is sorted (i, j), as candidate_pairs returns it.  The adjacency
(adj_ptr, adj) is that of dem.engine.containers.pair_lists: each body's count as either end,
a scan, and each body's entries 2 p + side by pair index (its pairs as j, by i, then its pairs
as i, by j).  The shear history is carried as Contacts.write_pairs carries it: each new pair's
old slot by binary search in the old sorted list, its code, points, locations and shear moved
there; a new pair starts with none; no kept patch survives (patch_shape[p, 0][3] = 0); the
reference poses of the skin criterion are the scene's poses.

A list longer than the scene's capacity is not written: the scene keeps its REBUILD bit, which
stops the chunk (control.steps_done[1]); the host then runs its own broad phase for that scene
(Simulation.rebuild), which raises today's CapacityError with its message.

Each scene's rebuilds of a chunk are counted in the ``rebuilds`` of
dem.engine.step_device.DeviceStepper (reset by dem.engine.device.unpack_chunk, brought back
with the diagnostics by dem.engine.device.pack_diagnostics: summary.json's
``neighbour_rebuilds``).

Memory (the scratch arrays of dem.engine.step_device.DeviceStepper): a G x R x R table of the
pair tests (R the largest scene's bodies, 4 bytes a cell: 19 MB for 100 scenes of 217 bodies)
and a copy of the history of every pair slot (the old list's, read while the new one is
written).
"""


import taichi as ti

from dem import ti_runtime
from dem.engine.containers import P_SKIN, REBUILD, STOP
from dem.engine.geometry import MAXP
from dem.engine.mathutil import ivec2, vec3

ti_runtime.quick_front_end()  # before this module's kernels are decorated

# a cross product of two edge directions shorter than this is no axis (parallel edges): the
# host's test's guard (dem.engine.broadphase._sat_separated)
CROSS_AXIS_MIN_NORM = 1e-6


@ti.func
def column(R, k: ti.template()):
    """Column k of a 3 x 3 matrix: body axis k in the table frame."""
    return vec3(R[0, k], R[1, k], R[2, k])


@ti.func
def separates(L, d, Ra, ha, Rb, hb):
    """1 if the axis L separates boxes a and b (centre offset d = p_b - p_a, rotations Ra, Rb,
    half extents ha, hb): |d . L| > sum_k ha_k |Ra e_k . L| + sum_k hb_k |Rb e_k . L|, for a
    valid axis (L . L > 0.5: a unit vector, not a left-out cross product)."""
    ra = ha[0] * ti.abs(column(Ra, 0).dot(L)) + ha[1] * ti.abs(column(Ra, 1).dot(L)) \
        + ha[2] * ti.abs(column(Ra, 2).dot(L))
    rb = hb[0] * ti.abs(column(Rb, 0).dot(L)) + hb[1] * ti.abs(column(Rb, 1).dot(L)) \
        + hb[2] * ti.abs(column(Rb, 2).dot(L))
    out = 0
    if L.dot(L) > 0.5 and ti.abs(d.dot(L)) > ra + rb:
        out = 1
    return out


@ti.func
def boxes_separated(pa, Ra, ha, pb, Rb, hb):
    """1 if some axis of the 15 of the separating-axis test separates the two boxes (the
    host's broadphase._sat_separated for one pair)."""
    d = pb - pa
    sep = 0
    for k in ti.static(range(3)):
        sep |= separates(column(Ra, k), d, Ra, ha, Rb, hb)
    for k in ti.static(range(3)):
        sep |= separates(column(Rb, k), d, Ra, ha, Rb, hb)
    for k in ti.static(range(3)):
        for m in ti.static(range(3)):
            L = column(Ra, k).cross(column(Rb, m))
            nrm = L.norm()
            axis = vec3(0.0)
            if nrm > CROSS_AXIS_MIN_NORM:
                axis = L / ti.max(nrm, 1e-300)
            sep |= separates(axis, d, Ra, ha, Rb, hb)
    return sep


@ti.func
def listed(b0, i, j, table, skin, half: ti.template(), radius: ti.template(),
           inv_mass: ti.template(), pos: ti.template(), rot: ti.template()):
    """1 if the host's broad phase lists the pair (i, j), i < j, of the scene whose first body
    is b0 and whose table is body ``table`` (within the scene): the module docstring."""
    a = b0 + i
    b = b0 + j
    out = 0
    if j == table:
        R = rot[a]
        h = half[a]
        zmin = pos[a][2] - (ti.abs(R[2, 0]) * h[0] + ti.abs(R[2, 1]) * h[1]
                            + ti.abs(R[2, 2]) * h[2])
        if zmin <= skin and inv_mass[a] > 0.0:
            out = 1
    elif inv_mass[a] > 0.0 or inv_mass[b] > 0.0:
        if (pos[a] - pos[b]).norm() <= radius[a] + radius[b] + skin:
            grow = vec3(0.5 * skin)
            if boxes_separated(pos[a], rot[a], half[a] + grow, pos[b], rot[b],
                               half[b] + grow) == 0:
                out = 1
    return out


@ti.func
def flagged_scene(f, flagged: ti.template(), scene_bodies: ti.template()):
    """The f-th scene flagged for a rebuild: (its index g, its first body b0, its bodies nb)."""
    g = flagged[1 + f]
    b0 = scene_bodies[g][0]
    return g, b0, scene_bodies[g][1] - b0


@ti.func
def no_kept_patch(slot, patch_shape: ti.template()):
    """No kept contact patch survives a rebuild (patch_shape[slot, 0][3] = 0)."""
    shape = patch_shape[slot, 0]
    shape[3] = 0.0
    patch_shape[slot, 0] = shape


@ti.func
def no_history(slot, n_old, code: ti.template(), npts: ti.template(), loc: ti.template(),
               shear: ti.template(), patch_shape: ti.template()):
    """Pair slot ``slot`` without history: no contact code, no points, no kept patch; its
    locations and shear zeroed where the old list had any pair (n_old > 0) to leave them."""
    code[slot] = -1
    npts[slot] = 0
    if n_old > 0:
        for q in range(MAXP):
            loc[slot, q] = vec3(0.0)
            shear[slot, q] = vec3(0.0)
    no_kept_patch(slot, patch_shape)


@ti.func
def rebuild_stage(s, R, half: ti.template(), radius: ti.template(),
                  inv_mass: ti.template(), scene_bodies: ti.template(), pos: ti.template(),
                  quat: ti.template(), rot: ti.template(), pairs: ti.template(),
                  adj_ptr: ti.template(), adj: ti.template(), scene_pairs: ti.template(),
                  ref_pos: ti.template(), ref_quat: ti.template(), code: ti.template(),
                  npts: ti.template(), loc: ti.template(), shear: ti.template(),
                  patch_shape: ti.template(), status: ti.template(), steps_done: ti.template(),
                  active: ti.template(), step_parameters: ti.template(), flagged: ti.template(),
                  info: ti.template(), hit: ti.template(), rows: ti.template(),
                  old_pairs: ti.template(), old_code: ti.template(), old_npts: ti.template(),
                  old_loc: ti.template(), old_shear: ti.template(), rebuilds: ti.template()):
    """After step s of a chunk (inlined after each step of dem.engine.step_device.advance_device):
    the neighbour list of every scene whose REBUILD bit is set, rebuilt on the device (module
    docstring).  Nothing happens where step s did not run (the chunk stopped earlier or ended:
    control.steps_done[0] != s + 1).

    R: the bodies of the largest scene (the rows of ``hit`` and ``rows``).  Scratch:
    ``flagged`` [G + 1] (the count of scenes to rebuild, then their indices), ``info`` [G, 3]
    (per such scene: old pair count, new pair count, 1 if it fits), ``hit`` [G R R] (pair
    (i, j)'s test, then its index in the new list + 1), ``rows`` [G R, 2] (row i's count of
    partners j > i, then its first pair; body i's adjacency count), the old list and history
    of every slot (``old_*``); ``rebuilds`` [G] each scene's rebuilds since the chunk began.
    Top-level loops run one after the other; the loops over a count read from ``flagged``
    are empty where no scene rebuilds."""
    G = status.shape[0]
    P = pairs.shape[0] // G
    skin = step_parameters[P_SKIN]
    # 1. the scenes to rebuild; the stop bits of the chunk without their REBUILD (given back
    #    below to a scene whose list does not fit)
    ti.loop_config(serialize=True)
    for _ in range(1):
        n = 0
        if s >= 0 and steps_done[0] == s + 1:
            bits = 0
            for g in range(G):
                st = status[g]
                if active[g] != 0 and st & REBUILD != 0 and st & STOP == 0:
                    flagged[1 + n] = g
                    n += 1
                    st = st & ~REBUILD
                bits |= st
            if n > 0:
                steps_done[1] = bits
        flagged[0] = n
    # 2. every pair i < j of each such scene, one thread a pair
    for t in range(flagged[0] * R * R):
        f = t // (R * R)
        i = (t // R) % R
        j = t % R
        g, b0, nb = flagged_scene(f, flagged, scene_bodies)
        if i < j < nb:
            hit[t] = listed(b0, i, j, nb - 1, skin, half, radius, inv_mass, pos, rot)
    # 3. per body: its partners j > i (its row), and its pairs as either end
    for t in range(flagged[0] * R):
        f = t // R
        i = t % R
        _g, _b0, nb = flagged_scene(f, flagged, scene_bodies)
        if i < nb:
            row = 0
            for j in range(i + 1, nb):
                row += hit[(f * R + i) * R + j]
            col = 0
            for k in range(i):
                col += hit[(f * R + k) * R + i]
            rows[t, 0] = row
            rows[t, 1] = row + col
    # 4. per scene (one thread each): the rows' first pairs and the adjacency pointers by
    #    exclusive scans; a list over the capacity is not written and keeps its REBUILD bit
    for f in range(flagged[0]):
        g, b0, nb = flagged_scene(f, flagged, scene_bodies)
        total = 0
        for i in range(nb):
            c = rows[f * R + i, 0]
            rows[f * R + i, 0] = total
            total += c
        info[f, 0] = scene_pairs[g]
        info[f, 1] = total
        info[f, 2] = 0
        if total > P:
            ti.atomic_or(steps_done[1], REBUILD)
        else:
            info[f, 2] = 1
            status[g] = status[g] & ~REBUILD
            rebuilds[g] += 1
            e = 0
            for k in range(nb):
                adj_ptr[b0 + g + k] = e
                e += rows[f * R + k, 1]
            adj_ptr[b0 + g + nb] = e
            scene_pairs[g] = total
    # 5. per slot of each scene that rebuilds: the old list and history kept aside; a slot
    #    past the new list emptied (the padding of pair_lists, the history cleared)
    for t in range(flagged[0] * P):
        f = t // P
        p = t % P
        if info[f, 2] == 1:
            g = flagged[1 + f]
            slot = g * P + p
            n_old = info[f, 0]
            if p < n_old:
                old_pairs[slot] = pairs[slot]
                old_code[slot] = code[slot]
                old_npts[slot] = npts[slot]
                for q in range(MAXP):
                    old_loc[slot, q] = loc[slot, q]
                    old_shear[slot, q] = shear[slot, q]
            if p >= info[f, 1]:
                pairs[slot] = ivec2(0, 0)
                no_history(slot, n_old, code, npts, loc, shear, patch_shape)
                adj[2 * g * P + 2 * p] = 0
                adj[2 * g * P + 2 * p + 1] = 0
    # 6. per row: its pairs in order of j, each with the history of its old slot (binary
    #    search in the old sorted list) or none; the body's reference pose
    for t in range(flagged[0] * R):
        f = t // R
        i = t % R
        g, b0, nb = flagged_scene(f, flagged, scene_bodies)
        if info[f, 2] == 1 and i < nb:
            n_old = info[f, 0]
            k = rows[t, 0]
            for j in range(i + 1, nb):
                cell = (f * R + i) * R + j
                if hit[cell] != 0:
                    slot = g * P + k
                    hit[cell] = k + 1
                    pairs[slot] = ivec2(i, j)
                    lo = 0
                    hi = n_old
                    while lo < hi:
                        mid = (lo + hi) // 2
                        o = old_pairs[g * P + mid]
                        if o[0] < i or (o[0] == i and o[1] < j):
                            lo = mid + 1
                        else:
                            hi = mid
                    old = -1
                    if lo < n_old:
                        o = old_pairs[g * P + lo]
                        if o[0] == i and o[1] == j:
                            old = lo
                    if old >= 0:
                        src = g * P + old
                        code[slot] = old_code[src]
                        npts[slot] = old_npts[src]
                        for q in range(MAXP):
                            loc[slot, q] = old_loc[src, q]
                            shear[slot, q] = old_shear[src, q]
                        no_kept_patch(slot, patch_shape)
                    else:
                        no_history(slot, n_old, code, npts, loc, shear, patch_shape)
                    k += 1
            ref_pos[b0 + i] = pos[b0 + i]
            ref_quat[b0 + i] = quat[b0 + i]
    # 7. per body: its adjacency entries 2 p + side by pair index (pair_lists' order)
    for t in range(flagged[0] * R):
        f = t // R
        k = t % R
        g, b0, nb = flagged_scene(f, flagged, scene_bodies)
        if info[f, 2] == 1 and k < nb:
            e = 2 * g * P + adj_ptr[b0 + g + k]
            for i in range(k):
                p = hit[(f * R + i) * R + k]
                if p != 0:
                    adj[e] = 2 * (p - 1) + 1
                    e += 1
            for j in range(k + 1, nb):
                p = hit[(f * R + k) * R + j]
                if p != 0:
                    adj[e] = 2 * (p - 1)
                    e += 1
