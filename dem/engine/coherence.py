"""Patch reuse: temporal coherence of the narrow phase for closed flat face contacts.

A brick joint that stays closed keeps the same contact polygon from step to step: the polygon is
the intersection of the reference face rectangle with the incident face projected on it
(dem.engine.geometry, module docstring 2-3), and it only changes when the two faces move *in
their plane* relative to each other (sliding, twisting).  The penetration over it, the affine
gap d(x, y) = d0 + gx x + gy y, changes with every nanometre of normal motion, and that is what
the joint law needs exactly.

So after a full narrow phase of a flat face-face pair whose patch is *closed* (the last clip,
d >= 0, cut nothing, and every polygon vertex bears at least ``CLOSED_RATIO`` of the deepest
vertex's depth), :func:`store_patch` keeps in Contacts:
  * the quadrature points (x, y) in the reference face's coordinates and their weights w, the
    area centroid and the shrink factor (patch_point, patch_shape[p, 0]);
  * the incident face's four corners projected on the reference face plane (patch_shape[p, 1:3]).
(Two fields, not four: Taichi 1.7.4 takes at most 64 argument elements per kernel on x64.)

At the next steps :func:`reuse_patch` recomputes only the reference frame, the incident face,
its projected corners and the affine gap from the current poses (the first, cheap lines of
geometry.face_contact), and takes the kept points if
  1. no projected corner moved more than ``tol`` (m) in the reference face plane since the patch
     was stored: the kept polygon is then within tol of the true one (Hausdorff distance; the
     polygon is the intersection of the reference rectangle with the corners' quadrilateral),
     so its area, centroid and second moments err by O(tol / brick size); and
  2. every kept vertex is still at least CLOSED_RATIO of the deepest one's depth under the
     *current* gap: the last clip would still cut nothing.
The depths and the points' positions are then those of the full narrow phase at the kept
(x, y) (geometry.patch_points: the same lines); the separating-axis test is skipped too, so the
sticky axis cannot change while a patch is reused (it changes only when another axis beats it
by 1e-3 of the smallest half extent; tol is far below that).  Otherwise the full narrow phase
runs, and stores the patch again if it is closed.

A reused patch emits the points of the last step in the same slots, so the contact stage reads
each point's shear history from its own slot (dem.engine.step.contact_stage).

``solver.patch_reuse`` is tol: 1e-7 m by default, 0 turns reuse off (a full narrow phase every
step).  Perfect faces only: the warped kernels never reuse a closed patch.  Its speed and its
error on the thesis' cases: benchmarks/speed_error.md and benchmarks/RESULTS.md ("Patch reuse").
The warped kernels have their own, off by default: the overlap reuse at the end of this module
(:func:`set_overlap_reuse`; benchmarks/RESULTS.md, "Overlap reuse for imperfect joints").
"""

import taichi as ti

from dem import ti_runtime
from dem.engine import geometry
from dem.engine.geometry import point_buffer
from dem.engine.mathutil import vec3, vec4

ti_runtime.quick_front_end()  # before this module's kernels are decorated

CLOSED_RATIO = 1e-3  # a patch is closed when its shallowest vertex is this fraction of its deepest


@ti.func
def face_pair(code, i, j, model: ti.template(), state: ti.template()):
    """For a face code (0-5, geometry.box_contact), the two faces from the current poses, as
    box_contact finds them: returns (rb, ib, k, sg, n, u1, u2, c, m, sm, nI, b1, b2), with rb, ib
    the reference and incident bodies (rb = j for code >= 3: the caller flips n to point from i
    to j), k, sg the reference face's axis and side, (n from R to I, u1, u2, c) its frame and
    centre (geometry.face_frame), m, sm the incident face's axis and side, nI its normal and
    b1, b2 its half-edge vectors (geometry.incident_face).  The incident face's centre,
    ci = pos[ib] + nI half[ib][m], is left to the callers, each computing it where its uses are
    (under Taichi's fast math the place of that multiply-add decides its rounding)."""
    rb = i
    ib = j
    if code >= 3:
        rb = j
        ib = i
    pR = state.pos[rb]
    RR = state.rot[rb]
    hR = model.half[rb]
    pI = state.pos[ib]
    RI = state.rot[ib]
    hI = model.half[ib]
    k = code % 3
    sg = 1.0
    if (pI - pR).dot(vec3(RR[0, k], RR[1, k], RR[2, k])) < 0.0:
        sg = -1.0
    n, u1, u2, c = geometry.face_frame(pR, RR, hR, k, sg)
    m, sm, nI, b1, b2 = geometry.incident_face(n, RI, hI)
    return rb, ib, k, sg, n, u1, u2, c, m, sm, nI, b1, b2


@ti.func
def reference_and_incident(code, i, j, model: ti.template(), state: ti.template()):
    """face_pair's reference face frame (n, u1, u2, c) and incident face (nI, b1, b2, ci), the
    part the patch reuse needs."""
    _rb, ib, _k, _sg, n, u1, u2, c, m, _sm, nI, b1, b2 = face_pair(code, i, j, model, state)
    ci = state.pos[ib] + nI * model.half[ib][m]
    return n, u1, u2, c, nI, b1, b2, ci


@ti.func
def closed(d0, gx, gy, gcx, gcy, inv_shrink, npts, xs: ti.template(), ys: ti.template()):
    """Whether every polygon vertex behind the quadrature points (xs, ys) (vertex =
    centroid + (point - centroid) / shrink) has a depth d0 + gx x + gy y of at least
    CLOSED_RATIO of the deepest vertex's, the deepest being > 0."""
    dmin = 1e300
    dmax = -1e300
    for q in range(npts):
        x = gcx + (xs[q] - gcx) * inv_shrink
        y = gcy + (ys[q] - gcy) * inv_shrink
        d = d0 + gx * x + gy * y
        dmin = ti.min(dmin, d)
        dmax = ti.max(dmax, d)
    ok = 0
    if dmax > 0.0 and dmin >= CLOSED_RATIO * dmax:
        ok = 1
    return ok


@ti.func
def store_patch(p, i, j, code, whole, npts, shrink, centroid, model: ti.template(),
                state: ti.template(), contacts: ti.template(), px: ti.template(),
                py: ti.template(), pz: ti.template(), w: ti.template()):
    """After a full narrow phase of pair p: keep its patch for reuse if it is a closed flat
    face patch (``whole`` from geometry.box_contact: the gap clip cut nothing, and the
    shallowest vertex bears CLOSED_RATIO of the deepest), else mark it not reusable.  The
    points' coordinates in the reference face are recovered from their table-frame positions
    (exact up to round-off)."""
    contacts.patch_shape[p, 0][3] = 0.0
    if whole != 0 and code >= 0 and code < 6 and npts >= 3:
        n, u1, u2, c, nI, b1, b2, ci = reference_and_incident(code, i, j, model, state)
        xs = point_buffer()
        ys = point_buffer()
        for q in range(npts):
            r = vec3(px[q], py[q], pz[q]) - c
            xs[q] = r.dot(u1)
            ys[q] = r.dot(u2)
        gcx = (centroid - c).dot(u1)
        gcy = (centroid - c).dot(u2)
        d0, gx, gy = geometry.affine_gap(c, u1, u2, n, nI, ci)
        if closed(d0, gx, gy, gcx, gcy, 1.0 / shrink, npts, xs, ys) != 0:
            for q in range(npts):
                contacts.patch_point[p, q] = vec3(xs[q], ys[q], w[q])
            cx = point_buffer()
            cy = point_buffer()
            geometry.incident_corners(c, u1, u2, ci, b1, b2, cx, cy)
            contacts.patch_shape[p, 0] = vec4(gcx, gcy, shrink, npts)
            contacts.patch_shape[p, 1] = vec4(cx[0], cx[1], cx[2], cx[3])
            contacts.patch_shape[p, 2] = vec4(cy[0], cy[1], cy[2], cy[3])


@ti.func
def corner_drift(p, c, u1, u2, ci, b1, b2, contacts: ti.template(), cx: ti.template(),
                 cy: ti.template()):
    """The incident face's corners projected on the reference face (geometry.incident_corners,
    written to cx[0:4], cy[0:4]) and the largest distance along u1 or u2 (m) that one moved
    since pair p's patch was kept (contacts.patch_shape[p, 1:3]): the test of both reuses."""
    geometry.incident_corners(c, u1, u2, ci, b1, b2, cx, cy)
    kx = contacts.patch_shape[p, 1]
    ky = contacts.patch_shape[p, 2]
    drift = 0.0
    for q in ti.static(range(4)):
        drift = ti.max(drift, ti.max(ti.abs(cx[q] - kx[q]), ti.abs(cy[q] - ky[q])))
    return drift


@ti.func
def reuse_patch(p, i, j, tol, model: ti.template(), state: ti.template(),
                contacts: ti.template(), px: ti.template(), py: ti.template(),
                pz: ti.template(), dep: ti.template(), w: ti.template()):
    """Pair p's kept patch at the current poses, if it may be reused (module docstring):
    writes the point buffers as geometry.box_contact does and returns
    (reused, n, npts, shrink, centroid); reused = 0 leaves the buffers untouched."""
    reused = 0
    n_out = vec3(0.0, 0.0, 1.0)
    npts = 0
    shrink = 1.0
    centroid = vec3(0.0)
    code = contacts.code[p]
    shape = contacts.patch_shape[p, 0]
    n_kept = ti.cast(shape[3], ti.i32)
    if n_kept > 0 and code >= 0 and code < 6:
        n, u1, u2, c, nI, b1, b2, ci = reference_and_incident(code, i, j, model, state)
        cx = point_buffer()
        cy = point_buffer()
        if corner_drift(p, c, u1, u2, ci, b1, b2, contacts, cx, cy) <= tol:
            xs = point_buffer()
            ys = point_buffer()
            for q in range(n_kept):
                k = contacts.patch_point[p, q]
                xs[q] = k[0]
                ys[q] = k[1]
            d0, gx, gy = geometry.affine_gap(c, u1, u2, n, nI, ci)
            if closed(d0, gx, gy, shape[0], shape[1], 1.0 / shape[2], n_kept, xs, ys) != 0:
                reused = 1
                npts = n_kept
                shrink = shape[2]
                geometry.patch_points(c, n, u1, u2, d0, gx, gy, npts, xs, ys, px, py, pz, dep)
                for q in range(npts):
                    w[q] = contacts.patch_point[p, q][2]
                dc = ti.max(d0 + gx * shape[0] + gy * shape[1], 0.0)
                centroid = c + shape[0] * u1 + shape[1] * u2 - 0.5 * dc * n
                n_out = n
                if code >= 3:
                    n_out = -n
    return reused, n_out, npts, shrink, centroid


# --- Overlap reuse: the warped kernels' cut patches -------------------------------------------
#
# An imperfect (warped) joint is almost never closed whole: two tilted flat faces bear on part of
# their overlap (2-4 % of Model II's planar joints are whole, benchmarks/RESULTS.md), so the
# closed-patch reuse above would reuse almost nothing.  What stays the same from step to step is
# the faces' *overlap polygon*: the reference face rectangle (inset by the arris) clipped by the
# incident face's quadrilateral (its corners projected on the reference plane), found after the
# separating-axis test by four Sutherland-Hodgman passes (geometry.face_contact).  The gap clip
# (d >= 0), the quadrature and the points depend on the normal motion and are redone at every
# step from the current poses.
#
# keep_overlap (in the full narrow phase of a warped kernel) keeps, for a face-face pair:
#   patch_point[p, q] = (x_q, y_q, 0), q < npoly: the overlap polygon in the reference face's
#                       coordinates (m, along u1, u2 from its centre c);
#   patch_shape[p, 1], [p, 2]: the x's and y's of the incident face's four corners (arris
#                       inset) projected on the reference plane (m);
#   patch_shape[p, 0][3] = -npoly  (negative: the closed-patch reuse above takes only > 0).
# reuse_overlap, at the next steps, recomputes the reference face frame, the incident face and
# its projected corners from the poses and, while no corner moved more than tol (m) in the
# reference plane since the polygon was kept, takes the kept polygon in place of the
# separating-axis test and the four clips.  The polygon is the intersection of a fixed rectangle
# with the corners' quadrilateral, so it is within tol of the true one (Hausdorff distance, for
# the non-degenerate overlaps of bricks); the gap is the exact affine gap of the current poses
# (geometry.planar_gap for planar warps, the bilinear gap at the vertices for twisted faces),
# and the clip d >= 0, the quadrature and the points are exactly those of the full narrow phase
# on that polygon.  The sticky axis is not re-chosen while the polygon is reused (it changes
# only when another axis beats it by 1e-3 of the smallest half extent, far above tol).
#
# The tolerance is per pair, patch_shape[p, 0][0] (m; 0: off, the default), the same for every
# pair (:func:`set_overlap_reuse`): the kernels take no more array arguments (containers.py).
# The warped kernels only; a reused overlap returns reused = 0 to the contact stage, whose
# points may differ in number and place from the last step's, so the shear history is found by
# position as after a full narrow phase.


def set_overlap_reuse(contacts, tol: float) -> None:
    """Turn the warped kernels' overlap reuse on with tolerance ``tol`` (m; 0 = off, the
    default) for every pair of ``contacts`` (a dem.engine.containers.Contacts), and forget any
    kept polygon.  Perfect scenes ignore it (their kernels have their own closed-patch reuse,
    solver.patch_reuse).  The reuse is a compile-time variant of the stepping kernels
    (``overlap`` in dem.engine.step.advance_serial): a Simulation reads the tolerance with
    :func:`overlap_reuse_tolerance` before each launch and switches to the variant when it
    turns > 0 (back when 0); with 0 the warped kernels are bit for bit those before the reuse
    existed."""
    if not tol >= 0.0:
        raise ValueError(f"overlap reuse tolerance must be >= 0 m, got {tol}")
    contacts.patch_shape[:, 0, 0] = float(tol)
    contacts.patch_shape[:, 0, 3] = 0.0


def overlap_reuse_tolerance(contacts) -> float:
    """The overlap reuse tolerance set by :func:`set_overlap_reuse` (m; 0 = off)."""
    return float(contacts.patch_shape[0, 0, 0])


@ti.func
def warped_faces(code, i, j, model: ti.template(), state: ti.template()):
    """face_pair as the warped kernels need it (geometry.face_contact): returns (rb, ib, k, sg, n,
    u1, u2, c, e1, e2, m, sm, nI, b1, b2, ci, imperfect); e1, e2 the reference rectangle's half
    extents and b1, b2 the incident face's half-edge vectors, inset by the arrises of an
    imperfect pair (geometry module docstring, 5); n points from R to I."""
    rb, ib, k, sg, n, u1, u2, c, m, sm, nI, b1, b2 = face_pair(code, i, j, model, state)
    hR = model.half[rb]
    hI = model.half[ib]
    RI = state.rot[ib]
    e1 = hR[(k + 1) % 3]
    e2 = hR[(k + 2) % 3]
    imperfect = model.imperfect[rb] + model.imperfect[ib]
    if imperfect > 0:
        m1 = (m + 1) % 3
        m2 = (m + 2) % 3
        e1 -= model.arris[rb]
        e2 -= model.arris[rb]
        b1 = vec3(RI[0, m1], RI[1, m1], RI[2, m1]) * (hI[m1] - model.arris[ib])
        b2 = vec3(RI[0, m2], RI[1, m2], RI[2, m2]) * (hI[m2] - model.arris[ib])
    ci = state.pos[ib] + nI * hI[m]
    return rb, ib, k, sg, n, u1, u2, c, e1, e2, m, sm, nI, b1, b2, ci, imperfect


@ti.func
def rectangle_clips(e1, e2, npoly, xs: ti.template(), ys: ti.template(), xt: ti.template(),
                    yt: ti.template()):
    """The four clips of geometry.face_contact: the polygon (xs, ys) clipped to |x| <= e1,
    |y| <= e2, result back in (xs, ys); returns its number of vertices."""
    npoly = geometry.clip_halfplane(xs, ys, npoly, 1.0, 0.0, e1, xt, yt)
    npoly = geometry.clip_halfplane(xt, yt, npoly, -1.0, 0.0, e1, xs, ys)
    npoly = geometry.clip_halfplane(xs, ys, npoly, 0.0, 1.0, e2, xt, yt)
    npoly = geometry.clip_halfplane(xt, yt, npoly, 0.0, -1.0, e2, xs, ys)
    return npoly


@ti.func
def overlap_patch(code, rb, ib, k, sg, n, u1, u2, c, m, sm, nI, ci, imperfect, npoly,
                  model: ti.template(), state: ti.template(), xs: ti.template(),
                  ys: ti.template(), xt: ti.template(), yt: ti.template(), px: ti.template(),
                  py: ti.template(), pz: ti.template(), dep: ti.template(), w: ti.template()):
    """The tail of geometry.face_contact on the overlap polygon (xs, ys, npoly): the gap, its
    clip, the quadrature and the points (geometry.warped_patch for an imperfect pair,
    geometry.flat_patch otherwise).  Returns (n, npts, shrink, centroid) with n from body i to
    body j, as box_contact."""
    hR = model.half[rb]
    hI = model.half[ib]
    RI = state.rot[ib]
    k1 = (k + 1) % 3
    k2 = (k + 2) % 3
    d0, gx, gy = geometry.affine_gap(c, u1, u2, n, nI, ci)
    npts = 0
    shrink = 1.0
    centroid = vec3(0.0)
    if imperfect > 0:
        npts, shrink, centroid = geometry.warped_patch(
            c, n, u1, u2, hR[k1], hR[k2], model.face_offset[rb, geometry.face_index(k, sg)], ci,
            RI, hI, m, model.face_offset[ib, geometry.face_index(m, sm)], d0, gx, gy, npoly, xs,
            ys, xt, yt, px, py, pz, dep, w)
    else:
        whole = 0
        npts, shrink, centroid, whole = geometry.flat_patch(c, n, u1, u2, d0, gx, gy, npoly, xs,
                                                            ys, xt, yt, px, py, pz, dep, w)
    n_out = n
    if code >= 3:
        n_out = -n
    return n_out, npts, shrink, centroid


@ti.func
def keep_overlap(p, i, j, margin, edge_area, model: ti.template(), state: ti.template(),
                 contacts: ti.template(), px: ti.template(), py: ti.template(),
                 pz: ti.template(), dep: ti.template(), w: ti.template()):
    """Full narrow phase of pair p in a warped kernel (the arithmetic of geometry.box_contact
    with warped = True, step for step) that also keeps the face pair's overlap polygon and the
    incident corners for :func:`reuse_overlap` (else marks nothing kept).  Returns (code, n,
    npts, shrink, centroid) as box_contact (without whole)."""
    pA = state.pos[i]
    RA = state.rot[i]
    hA = model.half[i]
    pB = state.pos[j]
    RB = state.rot[j]
    hB = model.half[j]
    ov = geometry.sat_overlaps(pA, RA, hA, pB, RB, hB)
    edge_margin = margin
    if model.imperfect[i] + model.imperfect[j] > 0:
        edge_margin = margin + model.recess[i] + model.recess[j]
    code, smallest = geometry.choose_axis(ov, contacts.code[p], margin, edge_margin)
    n = vec3(0.0, 0.0, 1.0)
    npts = 0
    shrink = 1.0
    centroid = vec3(0.0)
    shape0 = contacts.patch_shape[p, 0]
    contacts.patch_shape[p, 0] = vec4(shape0[0], shape0[1], shape0[2], 0.0)
    if code >= 0 and code < 6:
        rb, ib, k, sg, nR, u1, u2, c, e1, e2, m, sm, nI, b1, b2, ci, imperfect = warped_faces(
            code, i, j, model, state)
        xs = point_buffer()
        ys = point_buffer()
        xt = point_buffer()
        yt = point_buffer()
        geometry.incident_corners(c, u1, u2, ci, b1, b2, xs, ys)
        contacts.patch_shape[p, 1] = vec4(xs[0], xs[1], xs[2], xs[3])
        contacts.patch_shape[p, 2] = vec4(ys[0], ys[1], ys[2], ys[3])
        npoly = rectangle_clips(e1, e2, 4, xs, ys, xt, yt)
        if npoly >= 3:
            for q in range(npoly):
                contacts.patch_point[p, q] = vec3(xs[q], ys[q], 0.0)
            contacts.patch_shape[p, 0] = vec4(shape0[0], shape0[1], shape0[2], -npoly)
        n, npts, shrink, centroid = overlap_patch(code, rb, ib, k, sg, nR, u1, u2, c, m, sm, nI,
                                                  ci, imperfect, npoly, model, state, xs, ys,
                                                  xt, yt, px, py, pz, dep, w)
    elif code >= 6:
        n, npts, shrink, centroid = geometry.edge_contact(
            pA, RA, hA, pB, RB, hB, (code - 6) // 3, (code - 6) % 3, ov[code], edge_area, px,
            py, pz, dep, w)
    return code, n, npts, shrink, centroid


@ti.func
def reuse_overlap(p, i, j, tol, model: ti.template(), state: ti.template(),
                  contacts: ti.template(), px: ti.template(), py: ti.template(),
                  pz: ti.template(), dep: ti.template(), w: ti.template()):
    """Pair p's kept overlap polygon at the current poses, if no incident corner drifted more
    than tol (m) since it was kept: writes the point buffers as geometry.box_contact does and
    returns (reused, n, npts, shrink, centroid); reused = 0 leaves the buffers untouched."""
    reused = 0
    n_out = vec3(0.0, 0.0, 1.0)
    npts = 0
    shrink = 1.0
    centroid = vec3(0.0)
    code = contacts.code[p]
    npoly = -ti.cast(contacts.patch_shape[p, 0][3], ti.i32)
    if npoly >= 3 and code >= 0 and code < 6:
        rb, ib, k, sg, n, u1, u2, c, e1, e2, m, sm, nI, b1, b2, ci, imperfect = warped_faces(
            code, i, j, model, state)
        xs = point_buffer()
        ys = point_buffer()
        if corner_drift(p, c, u1, u2, ci, b1, b2, contacts, xs, ys) <= tol:
            xt = point_buffer()
            yt = point_buffer()
            for q in range(npoly):
                kq = contacts.patch_point[p, q]
                xs[q] = kq[0]
                ys[q] = kq[1]
            reused = 1
            n_out, npts, shrink, centroid = overlap_patch(code, rb, ib, k, sg, n, u1, u2, c, m,
                                                          sm, nI, ci, imperfect, npoly, model,
                                                          state, xs, ys, xt, yt, px, py, pz,
                                                          dep, w)
    return reused, n_out, npts, shrink, centroid
