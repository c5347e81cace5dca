"""Box-box contact geometry (pure ``@ti.func``): one normal per pair, several points per patch.

Why this design (see ../shared/DESIGN.md, "Contact geometry: what goes wrong with bricks"):

1. **One normal per block pair** from the separating-axis test over the 15 axes of two boxes
   (3 + 3 face normals, 9 edge-edge cross products).  The axis of least overlap is the contact
   normal.  The choice is *sticky*: the axis used at the previous step is kept unless another is
   better by ``margin`` (1e-3 of the smallest half extent of the pair), because flipping between
   nearly equal faces of flush bricks measures the gap from a slightly different plane and jumps.
   Face axes are preferred over edge axes by the same margin.

2. **Face contact: a clipped polygon, continuous in the poses.**  The incident face (the face of
   the other box most anti-parallel to the normal) is projected on the reference face plane and
   clipped (Sutherland-Hodgman, in 2-D) against the reference face rectangle and against the
   half-plane where the incident face is below the reference plane (gap d(x, y) >= 0; d is affine
   on the plane).  The polygon's vertices move continuously as the blocks move, and every vertex
   on the clip line d = 0 carries zero force, so forces never switch on or off abruptly.

3. **Points and weights: a quadrature of the pressure kn * d(x, y) over the polygon.**  Each
   polygon vertex p_k gets a tributary area w_k (median-dual: half of the two centroid-fan
   triangles next to it; sum w_k = polygon area A).  The points are pulled towards the area
   centroid c, p'_k = c + s (p_k - c), with s chosen so that sum w_k |p'_k - c|^2 equals the
   polygon's polar second moment of area J.  For rectangles and triangles (all flush brick
   joints, rocking strips) this is exact: force, centroid and second moments of the linear
   pressure are reproduced, so the joint's rotational (rocking) and torsional stiffness are
   kn * I and ks * J exactly; plain corner points would overestimate the rocking stiffness 3x.

4. **Edge-edge contact** (skewed blocks, when an edge-cross axis has the least overlap): one
   point midway between the closest points of the two edges, with weight ``edge_area``
   (``hmin * hmin``, passed by dem.engine.step.narrow_phase), depth = overlap along the axis.

5. **Imperfect faces** (docs/imperfections.md; bodies with ``faces.imperfect`` set, in the
   ``warped`` kernels only).  An arris of radius r insets the patch: the reference face
   rectangle is clipped at e - r and the incident face is the rectangle of half extents h - r,
   so a block rocks about a pivot r inside its edge.  A warped face adds the bilinear
   interpolation of its four corner offsets (m, > 0 stands out) to the gap: the penetration at
   a point of the patch is
       d(x, y) = d0 + gx x + gy y + o_R(x / e1, y / e2) + o_I(xi_I, eta_I)
   (o_R over the reference face, o_I over the incident face at the point's coordinates in that
   face).  Without twist (o_0 - o_1 - o_2 + o_3 = 0 on both faces: planar warps) d is affine,
   d = a + bx x + by y with three coefficients found once per pair (:func:`planar_gap`), and
   the patch is found as for flat faces (:func:`clip_halfplane`, :func:`patch_points`), with
   the same exact quadrature.  With twist d is not affine, and a
   quadrature of a pressure that is nonlinear and zero on part of the patch creates energy
   (measured: half of the table's work on a shaken wall), mostly because the weights of the
   points near a bearing corner grow with the depth.  So a twisted patch is sampled at the
   vertices of the two faces' overlap (the face corners for flush bricks): each bears
   kn A max(d, 0) with A its tributary area (median dual, sum = overlap area) and d the bilinear
   gap at the vertex, an open vertex bears nothing (its weight is set to zero, so no dashpot
   acts across a gap).  The vertices are material points of the faces while the bricks do not
   slide, the weights do not depend on the depth, so the forces derive from the energy
   sum kn A max(d, 0)^2 / 2: the twisted joint bears on its corners, as a rigid block does, and
   conserves energy (0.4 % of the table's work on the same wall).  The price: a twisted joint
   in full contact rocks with 3 x the elastic stiffness of a flat one (docs/engine.md:
   vertex points overestimate kn I 3 x); the joint's free play dominates its compliance anyway.
   Edge-edge contacts ignore the imperfections (skewed blocks only); an edge axis must beat the
   face axes by the two bodies' recesses (``faces.recess``) to be chosen for an imperfect pair.

Conventions: the normal ``n`` points from block A to block B; ``depth`` > 0 is penetration (m);
weights are areas (m^2).  Codes: 0-2 face k of A, 3-5 face k of B, 6-14 edge pair
(k, m) = divmod(code - 6, 3) of A's axis k and B's axis m, -1 no contact.
"""

import taichi as ti

from dem import ti_runtime
from dem.engine.mathutil import vec3

ti_runtime.quick_front_end()  # before this module's kernels are decorated

MAXP = 9  # face polygon: 4 corners, clipped by 4 sides (<= 8) then by d >= 0 (<= 9)


@ti.func
def point_buffer():
    """A zeroed buffer of MAXP + 1 reals (one spare slot for the clipping passes).

    Made inside the kernel, so its type is the engine's real type when the kernel compiles
    (a ``ti.types.vector(..., float)`` made at import, before ``ti.init``, would be f32)."""
    return ti.Vector([0.0] * (MAXP + 1))

NO_CONTACT = -1

TWIST_FLOOR = 1e-12  # m: a face pair whose twists |o_0 - o_1 - o_2 + o_3| / 4 add up to no more
                     # than this is planar (module docstring, 5).  `face_shape: planar` removes
                     # the twist in floating point, which leaves ~1e-20 m on 71 % of the faces; a
                     # test `> 0` sent those pairs down the twisted (vertex) path.  A twist of
                     # 1e-12 m changes the gap by 1e-12 m, 1e-6 of a micrometre-deep joint.


@ti.func
def sat_overlaps(pA, RA, hA, pB, RB, hB):
    """Overlap (m) of the projections of boxes A and B on each of the 15 candidate axes.

    Returns a 15-vector; entries of degenerate edge axes (parallel edges) are +inf-like (1e30).
    Negative overlap on any axis means the boxes are separated.  Everything is expressed with
    C = RA^T RB (C[k, m] = a_k . b_m) and the centre offset in both frames (Gottschalk's OBB
    test): the edge axis L = a_k x b_m is (0, -C[2, m], C[1, m]) in A's frame for k = 0 and
    (0, C[k, 2], -C[k, 1]) in B's frame for m = 0 (cyclic for the others), so no cross product
    is formed; the projections on the unnormalised L are divided by |L| once.
    """
    ov = ti.Vector([0.0] * 15, dt=float)
    d = pB - pA
    dA = RA.transpose() @ d
    dB = RB.transpose() @ d
    C = RA.transpose() @ RB
    absC = ti.abs(C) + 1e-14
    for k in ti.static(range(3)):
        rb = hB[0] * absC[k, 0] + hB[1] * absC[k, 1] + hB[2] * absC[k, 2]
        ov[k] = hA[k] + rb - ti.abs(dA[k])
    for m in ti.static(range(3)):
        ra = hA[0] * absC[0, m] + hA[1] * absC[1, m] + hA[2] * absC[2, m]
        ov[3 + m] = ra + hB[m] - ti.abs(dB[m])
    for k in ti.static(range(3)):
        k1 = (k + 1) % 3
        k2 = (k + 2) % 3
        for m in ti.static(range(3)):
            m1 = (m + 1) % 3
            m2 = (m + 2) % 3
            l2 = C[k1, m] * C[k1, m] + C[k2, m] * C[k2, m]  # |a_k x b_m|^2
            ra = hA[k1] * ti.abs(C[k2, m]) + hA[k2] * ti.abs(C[k1, m])
            rb = hB[m1] * ti.abs(C[k, m2]) + hB[m2] * ti.abs(C[k, m1])
            dl = dA[k2] * C[k1, m] - dA[k1] * C[k2, m]
            # branch-free, so that the nine square roots and divisions vectorise
            ov_e = (ra + rb - ti.abs(dl)) / ti.sqrt(ti.max(l2, 1e-6))
            ov[6 + 3 * k + m] = ti.select(l2 < 1e-6, 1e30, ov_e)
    return ov


@ti.func
def choose_axis(ov, prev_code, margin, edge_margin):
    """Sticky least-overlap axis.  Returns (code, overlap) or (NO_CONTACT, min overlap).

    An edge axis wins over the best face axis only if its overlap is smaller by edge_margin
    (``margin`` for perfect boxes; more for imperfect ones, see :func:`box_contact`)."""
    best_face = 0
    ov_face = ov[0]
    for a in ti.static(range(1, 6)):
        if ov[a] < ov_face:
            best_face = a
            ov_face = ov[a]
    best_edge = 6
    ov_edge = ov[6]
    for a in ti.static(range(7, 15)):
        if ov[a] < ov_edge:
            best_edge = a
            ov_edge = ov[a]
    best = best_face
    ov_best = ov_face
    if ov_edge + edge_margin < ov_face:
        best = best_edge
        ov_best = ov_edge
    smallest = ti.min(ov_face, ov_edge)
    code = NO_CONTACT
    if smallest >= 0.0:
        code = best
        if prev_code >= 0:
            if ov[prev_code] <= ov_best + margin:
                code = prev_code
    return code, smallest


@ti.func
def clip_halfplane(xs: ti.template(), ys: ti.template(), n, ax, ay, off, ox: ti.template(),
                   oy: ti.template()):
    """One Sutherland-Hodgman pass: write to (ox, oy) the part of the convex polygon (xs, ys,
    n vertices) where ax*x + ay*y <= off, and return its number of vertices.

    The buffers are passed by reference (``ti.template()``): the passes of
    :func:`face_contact` ping-pong between two pairs of buffers instead of copying them.
    """
    m = 0
    if n > 0:
        px = xs[n - 1]
        py = ys[n - 1]
        fp = ax * px + ay * py - off
        for k in range(n):
            cx = xs[k]
            cy = ys[k]
            fc = ax * cx + ay * cy - off
            if fc <= 0.0:
                if fp > 0.0 and m < MAXP + 1:
                    t = fp / (fp - fc)
                    ox[m] = px + t * (cx - px)
                    oy[m] = py + t * (cy - py)
                    m += 1
                if m < MAXP + 1:
                    ox[m] = cx
                    oy[m] = cy
                    m += 1
            elif fp <= 0.0 and m < MAXP + 1:
                t = fp / (fp - fc)
                ox[m] = px + t * (cx - px)
                oy[m] = py + t * (cy - py)
                m += 1
            px = cx
            py = cy
            fp = fc
    return m


@ti.func
def bilinear(o, xi, eta):
    """Bilinear interpolation of the corner values o (vec4, corner c = (s1 > 0) + 2 (s2 > 0)) at
    the face coordinates (xi, eta), clamped to [-1, 1]."""
    x = ti.min(ti.max(xi, -1.0), 1.0)
    y = ti.min(ti.max(eta, -1.0), 1.0)
    return 0.25 * ((1.0 - x) * (1.0 - y) * o[0] + (1.0 + x) * (1.0 - y) * o[1]
                   + (1.0 - x) * (1.0 + y) * o[2] + (1.0 + x) * (1.0 + y) * o[3])


@ti.func
def face_index(axis, sgn):
    """Face f = 2 axis + (0 for the + face, 1 for the - face) (dem.scene)."""
    return 2 * axis + ti.select(sgn < 0.0, 1, 0)


@ti.func
def polygon_quadrature(xs: ti.template(), ys: ti.template(), n, w: ti.template()):
    """Quadrature points and weights of a convex polygon (xs, ys, n vertices), see the module
    docstring.  Exact for linear pressure on rectangles and triangles.

    Moves the vertices in place to the points p'_k = c + s (p_k - c), writes the weights (m^2)
    to w and returns (area, s, cx, cy): the polygon area, the shrink factor s and the area
    centroid c.
    """
    area = 0.0
    s = 1.0
    gcx = 0.0
    gcy = 0.0
    if n >= 3:
        # relative to the first vertex o, which limits cancellation; the edges through o add
        # nothing to the sums over edges below
        ox = xs[0]
        oy = ys[0]
        a2 = 0.0  # twice the signed area
        cx = 0.0
        cy = 0.0
        j0 = 0.0  # polar second moment about o, times 12 * sign
        x0 = xs[1] - ox
        y0 = ys[1] - oy
        for k in range(2, n):
            x1 = xs[k] - ox
            y1 = ys[k] - oy
            cr = x0 * y1 - x1 * y0
            a2 += cr
            cx += (x0 + x1) * cr
            cy += (y0 + y1) * cr
            j0 += cr * (x0 * x0 + x0 * x1 + x1 * x1 + y0 * y0 + y0 * y1 + y1 * y1)
            x0 = x1
            y0 = y1
        if ti.abs(a2) > 1e-24:
            inv = 1.0 / (3.0 * a2)
            cx *= inv
            cy *= inv
            area = 0.5 * ti.abs(a2)
            J = ti.abs(j0) * (1.0 / 12.0) - area * (cx * cx + cy * cy)  # about the centroid
            gcx = ox + cx
            gcy = oy + cy
            # median-dual weights from the centroid fan
            rx0 = -cx  # vertex 0 relative to the centroid
            ry0 = -cy
            rxl = xs[n - 1] - ox - cx
            ryl = ys[n - 1] - oy - cy
            tri_prev = 0.5 * ti.abs(rxl * ry0 - rx0 * ryl)
            jp = 0.0
            for k in range(n):
                k1 = k + 1
                if k1 == n:
                    k1 = 0
                rx1 = xs[k1] - ox - cx
                ry1 = ys[k1] - oy - cy
                tri = 0.5 * ti.abs(rx0 * ry1 - rx1 * ry0)
                wk = 0.5 * (tri_prev + tri)
                w[k] = wk
                jp += wk * (rx0 * rx0 + ry0 * ry0)
                tri_prev = tri
                rx0 = rx1
                ry0 = ry1
            if jp > 0.0 and J > 0.0:
                s = ti.sqrt(J / jp)
            s = ti.min(ti.max(s, 0.3), 1.0)
            for k in range(n):
                xs[k] = gcx + s * (xs[k] - gcx)
                ys[k] = gcy + s * (ys[k] - gcy)
    return area, s, gcx, gcy


@ti.func
def face_frame(pR, RR, hR, k, sgn):
    """The reference face k of box R with outward normal sgn * R e_k: returns (n, u1, u2, c),
    its normal, the in-plane axes R e_(k+1), R e_(k+2) and its centre (m)."""
    k1 = (k + 1) % 3
    k2 = (k + 2) % 3
    n = sgn * vec3(RR[0, k], RR[1, k], RR[2, k])
    u1 = vec3(RR[0, k1], RR[1, k1], RR[2, k1])
    u2 = vec3(RR[0, k2], RR[1, k2], RR[2, k2])
    c = pR + n * hR[k]
    return n, u1, u2, c


@ti.func
def incident_face(n, RI, hI):
    """The face of box I most anti-parallel to n: returns (m, sm, nI, b1, b2), its axis m, the
    sign sm of its outward normal nI = sm RI e_m (towards R) and its half-edge vectors
    b1 = hI[m+1] RI e_(m+1), b2 = hI[m+2] RI e_(m+2) (m)."""
    dots = RI.transpose() @ n
    m = 0
    if ti.abs(dots[1]) > ti.abs(dots[m]):
        m = 1
    if ti.abs(dots[2]) > ti.abs(dots[m]):
        m = 2
    bm = vec3(RI[0, m], RI[1, m], RI[2, m])
    sm = 1.0
    if dots[m] > 0.0:
        sm = -1.0
    nI = sm * bm
    m1 = (m + 1) % 3
    m2 = (m + 2) % 3
    b1 = vec3(RI[0, m1], RI[1, m1], RI[2, m1]) * hI[m1]
    b2 = vec3(RI[0, m2], RI[1, m2], RI[2, m2]) * hI[m2]
    return m, sm, nI, b1, b2


@ti.func
def incident_corners(c, u1, u2, ci, b1, b2, xs: ti.template(), ys: ti.template()):
    """The incident face's corners ci +- b1 +- b2 projected on the reference face plane, in its
    coordinates (m, along u1, u2 from its centre c): written to xs[0:4], ys[0:4]."""
    for q in ti.static(range(4)):
        s1 = 1.0 if q == 0 or q == 3 else -1.0
        s2 = 1.0 if q < 2 else -1.0
        v = ci + s1 * b1 + s2 * b2 - c
        xs[q] = v.dot(u1)
        ys[q] = v.dot(u2)


@ti.func
def affine_gap(c, u1, u2, n, nI, ci):
    """Penetration of the incident face plane (through ci, outward normal nI) behind the
    reference face plane (centre c, normal n) at the point c + x u1 + y u2:
    d(x, y) = d0 + gx x + gy y = ((c + x u1 + y u2) - ci) . nI / (n . nI)  (m).
    Returns (d0, gx, gy)."""
    den = n.dot(nI)
    d0 = (c - ci).dot(nI) / den
    gx = u1.dot(nI) / den
    gy = u2.dot(nI) / den
    return d0, gx, gy


@ti.func
def face_contact(pR, RR, hR, k, sgn, pI, RI, hI, faces: ti.template(), warped: ti.template(),
                 rb, ib, px: ti.template(), py: ti.template(), pz: ti.template(),
                 dep: ti.template(), w: ti.template()):
    """Contact patch of reference face k of box R (outward normal sgn * R e_k) with box I.

    ``faces`` holds the bodies' imperfections (face_offset, arris, imperfect: dem.engine's
    Model); rb, ib are the indices of R and I in it.  Writes the points (world coordinates,
    midway through the overlap) to (px, py, pz), their depth (m) to dep and weight (m^2) to w,
    and returns (n, npts, s, centroid, whole): n points from R to I; the polygon vertex behind
    point q is centroid + (p_q - centroid) / s; whole = 1 if the patch is the whole overlap of
    two flat faces (the gap clip d >= 0 cut nothing: the faces bear everywhere), else 0.
    ``warped`` (compile time): whether the kernel handles imperfect faces at all; without it
    this is the perfect model's code alone.  With it, pairs of perfect faces still take the
    perfect code and imperfect ones :func:`warped_patch`.
    """
    k1 = (k + 1) % 3
    k2 = (k + 2) % 3
    n, u1, u2, c = face_frame(pR, RR, hR, k, sgn)
    e1 = hR[k1]
    e2 = hR[k2]
    m, sm, nI, b1, b2 = incident_face(n, RI, hI)
    imperfect = 0
    if ti.static(warped):
        imperfect = faces.imperfect[rb] + faces.imperfect[ib]
        if imperfect > 0:  # the patch inset by the arrises (module docstring, 5)
            m1 = (m + 1) % 3
            m2 = (m + 2) % 3
            e1 -= faces.arris[rb]
            e2 -= faces.arris[rb]
            b1 = vec3(RI[0, m1], RI[1, m1], RI[2, m1]) * (hI[m1] - faces.arris[ib])
            b2 = vec3(RI[0, m2], RI[1, m2], RI[2, m2]) * (hI[m2] - faces.arris[ib])
    ci = pI + nI * hI[m]
    xs = point_buffer()
    ys = point_buffer()
    xt = point_buffer()  # second pair of buffers for the clipping passes
    yt = point_buffer()
    incident_corners(c, u1, u2, ci, b1, b2, xs, ys)
    npoly = clip_halfplane(xs, ys, 4, 1.0, 0.0, e1, xt, yt)
    npoly = clip_halfplane(xt, yt, npoly, -1.0, 0.0, e1, xs, ys)
    npoly = clip_halfplane(xs, ys, npoly, 0.0, 1.0, e2, xt, yt)
    npoly = clip_halfplane(xt, yt, npoly, 0.0, -1.0, e2, xs, ys)
    d0, gx, gy = affine_gap(c, u1, u2, n, nI, ci)
    npts = 0
    shrink = 1.0
    centroid = vec3(0.0)
    whole = 0
    if ti.static(warped):
        if imperfect > 0:
            npts, shrink, centroid = warped_patch(
                c, n, u1, u2, hR[k1], hR[k2], faces.face_offset[rb, face_index(k, sgn)], ci,
                RI, hI, m, faces.face_offset[ib, face_index(m, sm)], d0, gx, gy, npoly, xs, ys,
                xt, yt, px, py, pz, dep, w)
        else:
            npts, shrink, centroid, whole = flat_patch(c, n, u1, u2, d0, gx, gy, npoly, xs, ys,
                                                       xt, yt, px, py, pz, dep, w)
    else:
        npts, shrink, centroid, whole = flat_patch(c, n, u1, u2, d0, gx, gy, npoly, xs, ys, xt,
                                                   yt, px, py, pz, dep, w)
    return n, npts, shrink, centroid, whole


@ti.func
def flat_patch(c, n, u1, u2, d0, gx, gy, npoly, xs: ti.template(), ys: ti.template(),
               xt: ti.template(), yt: ti.template(), px: ti.template(), py: ti.template(),
               pz: ti.template(), dep: ti.template(), w: ti.template()):
    """The last clip (d >= 0, d affine), quadrature and points of :func:`face_contact` for flat
    faces.  Returns (npts, shrink, centroid, whole) as face_contact."""
    whole = 1  # the last clip cuts nothing when every vertex bears (dem.engine.coherence)
    for q in range(npoly):
        if d0 + gx * xs[q] + gy * ys[q] <= 0.0:
            whole = 0
    npoly = clip_halfplane(xs, ys, npoly, -gx, -gy, d0, xt, yt)
    area, shrink, gcx, gcy = polygon_quadrature(xt, yt, npoly, w)
    dc = ti.max(d0 + gx * gcx + gy * gcy, 0.0)
    centroid = c + gcx * u1 + gcy * u2 - 0.5 * dc * n
    npts = 0
    if area > 0.0:
        npts = ti.min(npoly, MAXP)
        patch_points(c, n, u1, u2, d0, gx, gy, npts, xt, yt, px, py, pz, dep)
    return npts, shrink, centroid, whole


@ti.func
def patch_points(c, n, u1, u2, d0, gx, gy, npts, xs: ti.template(), ys: ti.template(),
                 px: ti.template(), py: ti.template(), pz: ti.template(), dep: ti.template()):
    """The points of a flat patch whose quadrature points are (xs, ys) in the reference face's
    coordinates: depth d = max(d0 + gx x + gy y, 0) (m) and position c + x u1 + y u2 - d n / 2,
    midway through the overlap (table frame, m)."""
    for q in range(npts):
        dq = ti.max(d0 + gx * xs[q] + gy * ys[q], 0.0)
        p = c + xs[q] * u1 + ys[q] * u2 - 0.5 * dq * n
        px[q] = p[0]
        py[q] = p[1]
        pz[q] = p[2]
        dep[q] = dq


@ti.func
def planar_gap(cc, u1, u2, inv1, inv2, oR, d1, d2, invI1, invI2, oI, d0, gx, gy):
    """The gap of a planar warped face pair as an affine function of the reference face's
    coordinates, d(x, y) = a + bx x + by y (m; x, y in m along u1, u2 from the reference face's
    centre c).  Returns (a, bx, by), found once per pair.

    A face's bilinear offset (:func:`bilinear`, corner values o_0..o_3, m) is
        o(xi, eta) = A + B xi + C eta + T xi eta,
        A = (o_0 + o_1 + o_2 + o_3) / 4,  B = (o_1 - o_0 + o_3 - o_2) / 4,
        C = (o_2 - o_0 + o_3 - o_1) / 4,  T = (o_0 - o_1 - o_2 + o_3) / 4 (the twist).
    The reference face's coordinates are xi_R = x / hR1, eta_R = y / hR2 (inv1 = 1 / hR1,
    inv2 = 1 / hR2), the incident face's xi_I = r . d1 / hI1, eta_I = r . d2 / hI2 with
    r = cc + x u1 + y u2, cc = c - ci (its centre ci, in-plane axes d1, d2, invI1 = 1 / hI1,
    invI2 = 1 / hI2).  With T_R = T_I = 0 the gap d0 + gx x + gy y + o_R + o_I is affine:
        a  = d0 + A_R + A_I + B_I (cc . d1) / hI1 + C_I (cc . d2) / hI2
        bx = gx + B_R / hR1 + B_I (u1 . d1) / hI1 + C_I (u1 . d2) / hI2
        by = gy + C_R / hR2 + B_I (u2 . d1) / hI1 + C_I (u2 . d2) / hI2.
    Where it differs from evaluating the two bilinear forms at a point (the twisted path's
    way):
    (1) the twist: the planar path takes pairs with |T_R| + |T_I| <= TWIST_FLOOR (1e-12 m), and
        |T xi eta| <= |T| inside a face, so dropping it moves the gap by <= 1e-12 m (face_shape:
        planar leaves ~1e-20 m);
    (2) the clamp: :func:`bilinear` clamps xi, eta to [-1, 1], a constant extension of the
        offset beyond the face's edge; here the plane goes on.  Inside both faces they are the
        same up to round-off.  The clipped polygon is inside the reference face (|x| <= e1,
        up to round-off), but not always inside the incident face in xi_I: its vertices on the
        incident face's edge are that edge projected along n onto the reference plane, and
        xi_I reads r . d1, the projection along the incident face's normal, so a vertex on the
        edge xi_I = 1 at a height z off the reference plane reads xi_I = 1 - z (n . d1) / hI1:
        beyond 1 by the depth times the boxes' relative tilt over hI1 (faces tilted against
        each other and sunk into the nominal boxes), where the two forms differ by B_I times that (measured up to 4e-9 m on Model II with
        0.1 mm beds, benchmarks/RESULTS.md).  That is the size of the gap definition's own
        ambiguity there (the offset read at the foot of the normal rather than along n), and
        the affine form is the one the planar path's exact clip (linear interpolation of d
        along each edge) and quadrature assume: with the clamp d is only piecewise affine near
        an incident edge.  So no clamp here;
    (3) round-off: a, bx, by are sums of the same terms in another order, so the gap moves by a
        few ulp of its largest term (tests/test_planar_affine_gap.py)."""
    AR = 0.25 * (oR[0] + oR[1] + oR[2] + oR[3])
    BR = 0.25 * (oR[1] - oR[0] + oR[3] - oR[2])
    CR = 0.25 * (oR[2] - oR[0] + oR[3] - oR[1])
    AI = 0.25 * (oI[0] + oI[1] + oI[2] + oI[3])
    BI = 0.25 * (oI[1] - oI[0] + oI[3] - oI[2]) * invI1
    CI = 0.25 * (oI[2] - oI[0] + oI[3] - oI[1]) * invI2
    a = d0 + AR + AI + BI * cc.dot(d1) + CI * cc.dot(d2)
    bx = gx + BR * inv1 + BI * u1.dot(d1) + CI * u1.dot(d2)
    by = gy + CR * inv2 + BI * u2.dot(d1) + CI * u2.dot(d2)
    return a, bx, by


@ti.func
def warped_patch(c, n, u1, u2, hR1, hR2, oR, ci, RI, hI, m, oI, d0, gx, gy, npoly,
                 xs: ti.template(), ys: ti.template(), xt: ti.template(), yt: ti.template(),
                 px: ti.template(), py: ti.template(), pz: ti.template(), dep: ti.template(),
                 w: ti.template()):
    """The last clip, quadrature and points of :func:`face_contact` for warped faces (module
    docstring, 5): the gap adds the bilinear corner offsets oR of the reference face (half
    extents hR1, hR2 along u1, u2, centre c) and oI of the incident face (box I's face m,
    centre ci).  The polygon clipped to both faces is (xs, ys, npoly) in the reference face's
    coordinates.  Twisted faces: vertex points; planar warps: the exact clip and quadrature.
    Returns (npts, shrink, centroid) as face_contact."""
    m1 = (m + 1) % 3
    m2 = (m + 2) % 3
    d1 = vec3(RI[0, m1], RI[1, m1], RI[2, m1])
    d2 = vec3(RI[0, m2], RI[1, m2], RI[2, m2])
    inv1 = 1.0 / hR1
    inv2 = 1.0 / hR2
    invI1 = 1.0 / hI[m1]
    invI2 = 1.0 / hI[m2]
    cc = c - ci
    tw = ti.abs(0.25 * (oR[0] - oR[1] - oR[2] + oR[3])) + ti.abs(
        0.25 * (oI[0] - oI[1] - oI[2] + oI[3]))
    npts = 0
    shrink = 1.0
    centroid = c
    if tw > TWIST_FLOOR:
        # twisted faces: the points are the vertices of the two faces' overlap, with their
        # tributary areas; each bears kn A max(d, 0) with d the bilinear gap there (module
        # docstring, 5)
        for q in range(npoly):
            xt[q] = xs[q]
            yt[q] = ys[q]
        area, s_unused, gcx, gcy = polygon_quadrature(xt, yt, npoly, w)
        centroid = c + gcx * u1 + gcy * u2
        if area > 0.0:
            npts = ti.min(npoly, MAXP)
            for q in range(npts):
                r = cc + xs[q] * u1 + ys[q] * u2
                d = d0 + gx * xs[q] + gy * ys[q] + bilinear(oR, xs[q] * inv1, ys[q] * inv2) \
                    + bilinear(oI, r.dot(d1) * invI1, r.dot(d2) * invI2)
                dq = ti.max(d, 0.0)
                if d <= 0.0:
                    w[q] = 0.0  # open: no spring, no dashpot across the gap
                p = c + xs[q] * u1 + ys[q] * u2 - 0.5 * dq * n
                px[q] = p[0]
                py[q] = p[1]
                pz[q] = p[2]
                dep[q] = dq
    else:
        # planar warps: the gap is affine, a + bx x + by y (planar_gap, once per pair); the
        # clip exact, the quadrature and the points those of flat faces
        a, bx, by = planar_gap(cc, u1, u2, inv1, inv2, oR, d1, d2, invI1, invI2, oI, d0, gx, gy)
        npoly = clip_halfplane(xs, ys, npoly, -bx, -by, a, xt, yt)
        area, shrink_, gcx, gcy = polygon_quadrature(xt, yt, npoly, w)
        shrink = shrink_
        dc = ti.max(a + bx * gcx + by * gcy, 0.0)
        centroid = c + gcx * u1 + gcy * u2 - 0.5 * dc * n
        if area > 0.0:
            npts = ti.min(npoly, MAXP)
            patch_points(c, n, u1, u2, a, bx, by, npts, xt, yt, px, py, pz, dep)
    return npts, shrink, centroid


@ti.func
def edge_contact(pA, RA, hA, pB, RB, hB, k, m, overlap, edge_area, px: ti.template(),
                 py: ti.template(), pz: ti.template(), dep: ti.template(), w: ti.template()):
    """Edge k of A against edge m of B: one point (slot 0 of the buffers), normal from A to B.

    Returns (n, npts, s, centroid) as :func:`face_contact`."""
    ak = vec3(RA[0, k], RA[1, k], RA[2, k])
    bm = vec3(RB[0, m], RB[1, m], RB[2, m])
    n = ak.cross(bm).normalized()
    if (pB - pA).dot(n) < 0.0:
        n = -n
    # support edge of A in direction +n, of B in direction -n
    ca = pA
    cb = pB
    for q in ti.static(range(3)):
        aq = vec3(RA[0, q], RA[1, q], RA[2, q])
        bq = vec3(RB[0, q], RB[1, q], RB[2, q])
        if q != k:
            sa = 1.0 if aq.dot(n) > 0.0 else -1.0
            ca += sa * hA[q] * aq
        if q != m:
            sb = 1.0 if bq.dot(n) < 0.0 else -1.0
            cb += sb * hB[q] * bq
    # closest points of the two segments ca + s ak (|s| <= hA[k]), cb + t bm (|t| <= hB[m])
    r = ca - cb
    b = ak.dot(bm)
    dd = ak.dot(r)
    e = bm.dot(r)
    den = 1.0 - b * b
    s = 0.0
    if den > 1e-12:
        s = (b * e - dd) / den
    s = ti.min(ti.max(s, -hA[k]), hA[k])
    t = ti.min(ti.max(b * s + e, -hB[m]), hB[m])
    s = ti.min(ti.max(b * t - dd, -hA[k]), hA[k])
    p = 0.5 * ((ca + s * ak) + (cb + t * bm))
    px[0] = p[0]
    py[0] = p[1]
    pz[0] = p[2]
    dep[0] = overlap
    w[0] = edge_area
    return n, 1, 1.0, p


@ti.func
def box_contact(pA, RA, hA, pB, RB, hB, prev_code, margin, edge_area, faces: ti.template(),
                warped: ti.template(), i, j, px: ti.template(), py: ti.template(),
                pz: ti.template(), dep: ti.template(), w: ti.template()):
    """Full narrow phase for one pair: A is body i, B body j of ``faces`` (their imperfections,
    read only if ``warped``, a compile-time flag: see :func:`face_contact`).

    Writes the points, depths and weights to the buffers (px, py, pz, dep, w: point buffers, zero beyond
    the points) and returns (code, n, npts, shrink, centroid, whole); n points from A to B
    whatever the reference face; see :func:`face_contact` for shrink, centroid and whole (0 for
    edge contacts and warped faces).
    """
    ov = sat_overlaps(pA, RA, hA, pB, RB, hB)
    # the overlaps are those of the nominal boxes: a block resting on recessed (warped) faces
    # or rounded edges sinks into its neighbour's nominal box by up to their recess, and an
    # edge axis could then look better than the face axis of a flush bed joint and take the
    # nominal overlap as its depth (a 0.5 mm edge contact that throws the block off).  The
    # face axis keeps the contact unless an edge axis is better by more than the recesses.
    code = NO_CONTACT
    smallest = 0.0
    if ti.static(warped):
        edge_margin = margin
        if faces.imperfect[i] + faces.imperfect[j] > 0:
            edge_margin = margin + faces.recess[i] + faces.recess[j]
        code, smallest = choose_axis(ov, prev_code, margin, edge_margin)
    else:
        code, smallest = choose_axis(ov, prev_code, margin, margin)
    n = vec3(0.0, 0.0, 1.0)
    npts = 0
    shrink = 1.0
    centroid = vec3(0.0)
    whole = 0
    if code >= 0 and code < 6:
        # reference box R (owner of the face), incident box I
        pR = pA
        RR = RA
        hR = hA
        pI = pB
        RI = RB
        hI = hB
        rb = i
        ib = j
        if code >= 3:
            rb = j
            ib = i
            pR = pB
            RR = RB
            hR = hB
            pI = pA
            RI = RA
            hI = hA
        k = code % 3
        sg = 1.0
        if (pI - pR).dot(vec3(RR[0, k], RR[1, k], RR[2, k])) < 0.0:
            sg = -1.0
        n, npts, shrink, centroid, whole = face_contact(pR, RR, hR, k, sg, pI, RI, hI, faces,
                                                        warped, rb, ib, px, py, pz, dep, w)
        if code >= 3:
            n = -n
    elif code >= 6:
        n, npts, shrink, centroid = edge_contact(
            pA, RA, hA, pB, RB, hB, (code - 6) // 3, (code - 6) % 3, ov[code], edge_area, px,
            py, pz, dep, w)
    return code, n, npts, shrink, centroid, whole
