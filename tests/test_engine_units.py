"""Unit tests of the engine's pure ``@ti.func`` pieces against closed forms.

* ``dem.engine.laws.normal_law`` and ``coulomb_shear`` (joint law at one contact point);
* ``dem.engine.geometry.polygon_quadrature`` (points and weights of a linear pressure on a
  polygon), checked against exact rational integrals of the polygon;
* ``dem.engine.geometry.box_contact`` (narrow phase of two boxes), checked against the contact
  patch of flush, tilted, cross-wise, separated and edge-to-edge bricks worked out by hand.

Four small kernels (one per function) take numpy arrays and are compiled once each; every test
feeds them a batch of cases.  Tolerances are round-off unless a docstring says otherwise.
"""

from fractions import Fraction

import numpy as np
import pytest
import taichi as ti

from dem import ti_runtime
from dem.engine import geometry, laws
from dem.engine.mathutil import mat3, vec3

nd = ti.types.ndarray
NB = geometry.MAXP + 1  # length of a point buffer

# ----------------------------------------------------------------------------------------------
# kernels (inputs and outputs are float64 numpy arrays, one row per case)


@ti.kernel
def _normal_law(inp: nd(dtype=ti.f64, ndim=2), out: nd(dtype=ti.f64, ndim=2)):
    # inp row: kn_area, depth, depth_rate, cn  ->  out row: f_el, f_visc
    for i in range(inp.shape[0]):
        f_el, f_visc = laws.normal_law(inp[i, 0], inp[i, 1], inp[i, 2], inp[i, 3])
        out[i, 0] = f_el
        out[i, 1] = f_visc


@ti.kernel
def _coulomb_shear(inp: nd(dtype=ti.f64, ndim=2), out: nd(dtype=ti.f64, ndim=2)):
    # inp row: u_old(3), n(3), v_t(3), dt, ks_area, ct, mu, fn
    # out row: ft(3), u_new(3), sliding, diss
    for i in range(inp.shape[0]):
        u_old = vec3(inp[i, 0], inp[i, 1], inp[i, 2])
        n = vec3(inp[i, 3], inp[i, 4], inp[i, 5])
        v_t = vec3(inp[i, 6], inp[i, 7], inp[i, 8])
        ft, u_new, sliding, diss = laws.coulomb_shear(u_old, n, v_t, inp[i, 9], inp[i, 10],
                                                      inp[i, 11], inp[i, 12], inp[i, 13])
        for a in ti.static(range(3)):
            out[i, a] = ft[a]
            out[i, 3 + a] = u_new[a]
        out[i, 6] = ti.cast(sliding, ti.f64)
        out[i, 7] = diss


@ti.kernel
def _polygon_quadrature(xs: nd(dtype=ti.f64, ndim=2), ys: nd(dtype=ti.f64, ndim=2),
                        nv: nd(dtype=ti.i32, ndim=1), w: nd(dtype=ti.f64, ndim=2),
                        res: nd(dtype=ti.f64, ndim=2)):
    # xs, ys: vertices in, points out; w: weights out; res row: area, s, cx, cy
    for i in range(xs.shape[0]):
        bx = geometry.point_buffer()
        by = geometry.point_buffer()
        bw = geometry.point_buffer()
        for q in ti.static(range(NB)):
            bx[q] = xs[i, q]
            by[q] = ys[i, q]
        area, s, cx, cy = geometry.polygon_quadrature(bx, by, nv[i], bw)
        for q in ti.static(range(NB)):
            xs[i, q] = bx[q]
            ys[i, q] = by[q]
            w[i, q] = bw[q]
        res[i, 0] = area
        res[i, 1] = s
        res[i, 2] = cx
        res[i, 3] = cy


# the bodies' imperfections as the narrow phase reads them (the fields of the engine's Model):
# row i of _box_contact is the pair of bodies (2 i, 2 i + 1)
FacesArgs = ti.types.argpack(face_offset=nd(dtype=ti.math.vec4, ndim=2), arris=nd(ndim=1),
                             recess=nd(ndim=1), imperfect=nd(dtype=ti.i32, ndim=1))


@ti.kernel
def _box_contact(inp: nd(dtype=ti.f64, ndim=2), res: nd(dtype=ti.f64, ndim=2),
                 pts: nd(dtype=ti.f64, ndim=3), faces: FacesArgs):
    # inp row: pA(3), RA(9, row-major), hA(3), pB(3), RB(9), hB(3), prev_code, margin, edge_area
    # res row: code, n(3), npts, shrink, centroid(3); pts[i, q]: x, y, z, depth, weight
    for i in range(inp.shape[0]):
        pA = vec3(inp[i, 0], inp[i, 1], inp[i, 2])
        hA = vec3(inp[i, 12], inp[i, 13], inp[i, 14])
        pB = vec3(inp[i, 15], inp[i, 16], inp[i, 17])
        hB = vec3(inp[i, 27], inp[i, 28], inp[i, 29])
        RA = mat3(0.0)
        RB = mat3(0.0)
        for r, c in ti.static(ti.ndrange(3, 3)):
            RA[r, c] = inp[i, 3 + 3 * r + c]
            RB[r, c] = inp[i, 18 + 3 * r + c]
        px = geometry.point_buffer()
        py = geometry.point_buffer()
        pz = geometry.point_buffer()
        dep = geometry.point_buffer()
        w = geometry.point_buffer()
        code, n, npts, shrink, centroid, _whole = geometry.box_contact(
            pA, RA, hA, pB, RB, hB, ti.cast(inp[i, 30], ti.i32), inp[i, 31], inp[i, 32],
            faces, True, 2 * i, 2 * i + 1, px, py, pz, dep, w)
        res[i, 0] = ti.cast(code, ti.f64)
        res[i, 4] = ti.cast(npts, ti.f64)
        res[i, 5] = shrink
        for a in ti.static(range(3)):
            res[i, 1 + a] = n[a]
            res[i, 6 + a] = centroid[a]
        for q in ti.static(range(NB)):
            pts[i, q, 0] = px[q]
            pts[i, q, 1] = py[q]
            pts[i, q, 2] = pz[q]
            pts[i, q, 3] = dep[q]
            pts[i, q, 4] = w[q]


# ----------------------------------------------------------------------------------------------
# Python-side drivers


def run_normal_law(rows):
    ti_runtime.init()
    inp = np.array(rows, dtype=np.float64)
    out = np.zeros((len(inp), 2))
    _normal_law(inp, out)
    return out


def run_coulomb(cases):
    """cases: dicts with u_old, n, v_t, dt, ks, ct, mu, fn.  Returns dicts ft, u, sliding, diss."""
    ti_runtime.init()
    inp = np.array([np.concatenate([c["u_old"], c["n"], c["v_t"],
                                    [c["dt"], c["ks"], c["ct"], c["mu"], c["fn"]]])
                    for c in cases], dtype=np.float64)
    out = np.zeros((len(inp), 8))
    _coulomb_shear(inp, out)
    return [dict(ft=o[0:3], u=o[3:6], sliding=int(o[6]), diss=o[7]) for o in out]


def run_quadrature(polygons):
    """polygons: lists of (x, y).  Returns dicts pts [n, 2], w [n], area, s, c [2]."""
    ti_runtime.init()
    m = len(polygons)
    xs = np.zeros((m, NB))
    ys = np.zeros((m, NB))
    nv = np.array([len(p) for p in polygons], dtype=np.int32)
    for i, p in enumerate(polygons):
        for q, (x, y) in enumerate(p):
            xs[i, q] = x
            ys[i, q] = y
    w = np.zeros((m, NB))
    res = np.zeros((m, 4))
    _polygon_quadrature(xs, ys, nv, w, res)
    return [dict(pts=np.stack([xs[i, :nv[i]], ys[i, :nv[i]]], axis=1), w=w[i, :nv[i]],
                 w_all=w[i], area=res[i, 0], s=res[i, 1], c=res[i, 2:4]) for i in range(m)]


def pair_row(pA, RA, hA, pB, RB, hB, prev_code=-1):
    """One input row of _box_contact with the engine's margin and edge_area for the pair."""
    hmin = min(np.min(hA), np.min(hB))
    return np.concatenate([pA, np.ravel(RA), hA, pB, np.ravel(RB), hB,
                           [prev_code, 1e-3 * hmin, hmin * hmin]])


def run_box_contact(rows, face_offset=None, arris=None):
    """Returns dicts code, n, npts, shrink, centroid, p [npts, 3], dep [npts], w [npts],
    buf (the whole point buffers, [NB, 5]).  face_offset [2 rows, 6, 4] and arris [2 rows]
    (m, dem.scene's convention): the imperfections of the bodies A, B of each row (perfect
    boxes by default)."""
    ti_runtime.init()
    inp = np.array(rows, dtype=np.float64)
    res = np.zeros((len(inp), 9))
    pts = np.full((len(inp), NB, 5), np.nan)
    off = np.zeros((2 * len(inp), 6, 4)) if face_offset is None else \
        np.asarray(face_offset, dtype=np.float64).reshape(2 * len(inp), 6, 4)
    arr = np.zeros(2 * len(inp)) if arris is None else np.asarray(arris, dtype=np.float64)
    imp = ((off != 0).any(axis=(1, 2)) | (arr != 0)).astype(np.int32)
    recess = np.maximum(-off.min(axis=(1, 2)), 0.0) + arr
    _box_contact(inp, res, pts, FacesArgs(face_offset=off, arris=arr, recess=recess,
                                          imperfect=imp))
    out = []
    for r, p in zip(res, pts):
        k = int(r[4])
        out.append(dict(code=int(r[0]), n=r[1:4], npts=k, shrink=r[5], centroid=r[6:9],
                        p=p[:k, 0:3], dep=p[:k, 3], w=p[:k, 4], buf=p))
    return out


def rot_x(t):
    c, s = np.cos(t), np.sin(t)
    return np.array([[1.0, 0.0, 0.0], [0.0, c, -s], [0.0, s, c]])


def rot_y(t):
    c, s = np.cos(t), np.sin(t)
    return np.array([[c, 0.0, s], [0.0, 1.0, 0.0], [-s, 0.0, c]])


I3 = np.eye(3)
BRICK = np.array([0.0525, 0.025, 0.0175])  # half extents of a 0.105 x 0.05 x 0.035 brick
HX, HY, HZ = BRICK

# ----------------------------------------------------------------------------------------------
# normal law


def test_normal_law_compression_release_and_elastic_only():
    """Fn parts: f_el = kn A d, f_visc = cn ddot, both 0 when f_el + f_visc <= 0.

    rows (kn A, d, ddot, cn) -> expected (f_el, f_visc):
      compression, closing       3e7, 1e-6,  2e-4, 50  -> (30, 1e-2)
      opening, sum still > 0     3e7, 1e-6, -0.1,  50  -> (30, -5)   viscous pull kept
      viscous part would pull    3e7, 1e-6, -1.0,  50  -> (0, 0)     30 - 50 < 0: released
      sum exactly zero           4.0, 0.5,  -1.0,  2   -> (0, 0)     4*0.5 - 2 = 0 (exact)
      elastic only (cn = 0)      3e7, 2.5e-6, -3.0, 0  -> (75, 0)
      touching, closing          3e7, 0.0,   1e-3, 50  -> (0, 0.05)
      no contact at all          3e7, 0.0,   0.0,  50  -> (0, 0)
    Each part is one product, correctly rounded in both numpy and the kernel: compared to
    1 ulp-level relative tolerance; the released cases must be exactly zero.
    """
    rows = [(3e7, 1e-6, 2e-4, 50.0), (3e7, 1e-6, -0.1, 50.0), (3e7, 1e-6, -1.0, 50.0),
            (4.0, 0.5, -1.0, 2.0), (3e7, 2.5e-6, -3.0, 0.0), (3e7, 0.0, 1e-3, 50.0),
            (3e7, 0.0, 0.0, 50.0)]
    out = run_normal_law(rows)
    expect = np.array([(k * d, cn * r) if k * d + cn * r > 0.0 else (0.0, 0.0)
                       for k, d, r, cn in rows])
    np.testing.assert_allclose(expect[:, 0], [30.0, 30.0, 0.0, 0.0, 75.0, 0.0, 0.0], rtol=1e-15)
    np.testing.assert_allclose(expect[:, 1], [1e-2, -5.0, 0.0, 0.0, 0.0, 0.05, 0.0],
                               rtol=1e-15)
    np.testing.assert_allclose(out, expect, rtol=1e-15, atol=0.0)
    assert np.all(out[[2, 3, 6]] == 0.0)
    assert out[1, 1] < 0.0  # a viscous pull smaller than the elastic push is not cut


# ----------------------------------------------------------------------------------------------
# Coulomb shear

KS, CT, MU, DT = 1e7, 10.0, 0.6, 1e-5
EZ = np.array([0.0, 0.0, 1.0])


def test_coulomb_sticking():
    """Sticking (|ks A u*| < mu Fn): Ft = -ks A (u_rot + v_t dt) - ct v_t, u_new = u*, no slip.

    With u_old in the contact plane, u_rot = u_old.  The dissipation closed form:
        diss = -Ft.v dt - ks A/2 (|u + v dt|^2 - |u|^2)
             = (ks A u* + ct v).v dt - ks A (u.v dt + |v|^2 dt^2 / 2)
             = (ct dt + ks A dt^2 / 2) |v_t|^2 > 0.
    It is a small difference of two ~2e-9 J terms (~1e-12 J): round-off ~1e-3 * 1e-16 relative
    of the result, tolerance 1e-10.

    Second case: |Ft*| below the cap but |Ft* - ct v_t| above it: Ft is capped at mu Fn in the
    direction of Ft* - ct v_t, still sticking, u_new = u*.
    """
    u_old = np.array([1e-7, -2e-7, 0.0])
    v = np.array([1e-4, 5e-5, 0.0])
    fn = 100.0
    # capped viscous: Ft* = -ks u* ~ 23 N (< 30 = mu fn), and a heavy damper ct = 1e4 N s/m
    # with v_t along u*: -ct v_t = (30, 15) N adds to Ft*, |Ft* - ct v_t| ~ 56 N > 30 N
    u_old2 = np.array([-2e-6, -1e-6, 0.0])
    v2 = np.array([-3e-3, -1.5e-3, 0.0])
    fn2, ct2 = 50.0, 1e4
    r, r2 = run_coulomb([dict(u_old=u_old, n=EZ, v_t=v, dt=DT, ks=KS, ct=CT, mu=MU, fn=fn),
                         dict(u_old=u_old2, n=EZ, v_t=v2, dt=DT, ks=KS, ct=ct2, mu=MU,
                              fn=fn2)])
    u_star = u_old + v * DT
    assert r["sliding"] == 0
    np.testing.assert_allclose(r["u"], u_star, rtol=1e-15)
    np.testing.assert_allclose(r["ft"], -KS * u_star - CT * v, rtol=1e-14, atol=0.0)
    diss = (CT * DT + 0.5 * KS * DT**2) * (v @ v)
    assert diss > 0.0
    assert r["diss"] == pytest.approx(diss, rel=1e-10)

    u_star2 = u_old2 + v2 * DT
    ft_star2 = -KS * u_star2
    assert np.linalg.norm(ft_star2) < MU * fn2 < np.linalg.norm(ft_star2 - ct2 * v2)
    assert r2["sliding"] == 0
    np.testing.assert_allclose(r2["u"], u_star2, rtol=1e-15)
    f = ft_star2 - ct2 * v2
    np.testing.assert_allclose(r2["ft"], MU * fn2 * f / np.linalg.norm(f), rtol=1e-14, atol=0.0)
    assert np.linalg.norm(r2["ft"]) == pytest.approx(MU * fn2, rel=1e-15)


def test_coulomb_sliding():
    """Sliding (|ks A u*| >= mu Fn): Ft = -mu Fn u*/|u*|, u_new = -Ft / (ks A) = mu Fn/(ks A) u^.

    diss = -Ft.v dt - ks A/2 (|u_new|^2 - |u_old|^2)
         = mu Fn (u^.v) dt - ks A/2 ((mu Fn / ks A)^2 - |u_old|^2),  u^ = u*/|u*|.
    Case 1, from rest (u_old = 0): u^ = v^, diss = mu Fn |v| dt - (mu Fn)^2 / (2 ks A) > 0.
    Case 2, steady sliding (u_old = mu Fn/(ks A) v^, already on the cap, along v): u_new = u_old,
    diss = mu Fn |v| dt exactly: the whole friction work.
    Case 3, generic: u_old not along v (formula above).
    Tolerance: a few ulp on the normalisations (1e-14); diss ~1e-4 J with no cancellation.
    """
    fn = 50.0
    cap = MU * fn
    v = np.array([0.5, -0.2, 0.0])
    vhat = v / np.linalg.norm(v)
    u_steady = cap / KS * vhat
    u_gen = np.array([1e-6, 2.5e-6, 0.0])
    res = run_coulomb([dict(u_old=u, n=EZ, v_t=v, dt=DT, ks=KS, ct=CT, mu=MU, fn=fn)
                       for u in (np.zeros(3), u_steady, u_gen)])
    for r, u_old in zip(res, (np.zeros(3), u_steady, u_gen)):
        u_star = u_old + v * DT
        assert KS * np.linalg.norm(u_star) > cap  # the premise: the trial force is over the cap
        uh = u_star / np.linalg.norm(u_star)
        assert r["sliding"] == 1
        assert np.linalg.norm(r["ft"]) == pytest.approx(cap, rel=1e-14)
        np.testing.assert_allclose(r["ft"], -cap * uh, rtol=1e-14, atol=1e-14 * cap)
        np.testing.assert_allclose(r["u"], -r["ft"] / KS, rtol=1e-14, atol=0.0)
        diss = cap * (uh @ v) * DT - 0.5 * KS * ((cap / KS) ** 2 - u_old @ u_old)
        assert r["diss"] > 0.0
        assert r["diss"] == pytest.approx(diss, rel=1e-12)
    assert res[0]["diss"] == pytest.approx(cap * np.linalg.norm(v) * DT - cap**2 / (2 * KS),
                                           rel=1e-12)
    np.testing.assert_allclose(res[1]["u"], u_steady, rtol=1e-13)
    assert res[1]["diss"] == pytest.approx(cap * np.linalg.norm(v) * DT, rel=1e-10)


def test_coulomb_rotation_into_new_plane_keeps_length():
    """u_old (with a normal component) is turned into the plane normal to a tilted n:
        u_rot = (u - (u.n) n) |u| / |u - (u.n) n|.
    With v_t = 0 and a small ks (sticking): u_new = u_rot, so |u_new| = |u_old|, u_new.n = 0,
    u_new is parallel to the projection, Ft = -ks A u_rot, and diss = 0 (no motion,
    no change of stored energy; to round-off of the energy, 1e-15 relative).
    """
    u_old = np.array([3e-6, 1e-6, 2e-6])
    n = np.array([0.1, -0.2, 1.0])
    n /= np.linalg.norm(n)
    (r,) = run_coulomb([dict(u_old=u_old, n=n, v_t=np.zeros(3), dt=DT, ks=KS, ct=CT, mu=MU,
                             fn=100.0)])
    proj = u_old - (u_old @ n) * n
    u_rot = proj * np.linalg.norm(u_old) / np.linalg.norm(proj)
    assert abs(u_old @ n) > 0.3 * np.linalg.norm(u_old)  # a real rotation, not a no-op
    assert r["sliding"] == 0
    assert np.linalg.norm(r["u"]) == pytest.approx(np.linalg.norm(u_old), rel=1e-14)
    assert abs(r["u"] @ n) < 1e-14 * np.linalg.norm(u_old)
    np.testing.assert_allclose(r["u"], u_rot, rtol=1e-14, atol=1e-14 * np.linalg.norm(u_old))
    np.testing.assert_allclose(r["ft"], -KS * u_rot, rtol=1e-14, atol=1e-14 * KS * 4e-6)
    # no motion and no change of stored energy: diss = 0 up to the round-off of the two equal
    # energies E = ks A |u_rot|^2 / 2 (computed separately, possibly with different FMA contraction)
    assert abs(r["diss"]) <= 1e-15 * 0.5 * KS * (u_old @ u_old)


def test_coulomb_rotation_of_a_displacement_along_the_new_normal():
    """Degenerate rotation: u_old parallel to the new normal (e.g. the pair's normal turned by
    90 deg, as when the reference face changes).  There is no in-plane direction to keep, so
    whatever rotate_into_plane returns (zero is what its code aims at: res = 0 unless the
    projection is non-zero) must at least lie in the contact plane: with v_t = 0,
    |u_new . n| <= 1e-12 |u_old| and Ft . n = 0 to the same relative accuracy."""
    n = np.array([0.1, -0.2, 1.0])
    n /= np.linalg.norm(n)
    u_old = 1e-6 * n
    (r,) = run_coulomb([dict(u_old=u_old, n=n, v_t=np.zeros(3), dt=DT, ks=KS, ct=CT, mu=MU,
                             fn=100.0)])
    assert abs(r["u"] @ n) <= 1e-12 * np.linalg.norm(u_old)
    assert abs(r["ft"] @ n) <= 1e-12 * KS * np.linalg.norm(u_old)


def test_coulomb_zero_normal_force_gives_zero_shear():
    """Fn = 0: the cap is 0, so the point slides with Ft = 0 and u_new = 0, and the released
    elastic energy ks A |u_rot|^2 / 2 is counted as dissipated (diss = ks A |u_old|^2 / 2 for an
    in-plane u_old).  Also with u_old = 0 and v_t = 0."""
    u_old = np.array([2e-6, -1e-6, 0.0])
    res = run_coulomb([dict(u_old=u_old, n=EZ, v_t=np.array([1e-3, 2e-3, 0.0]), dt=DT, ks=KS,
                            ct=CT, mu=MU, fn=0.0),
                       dict(u_old=np.zeros(3), n=EZ, v_t=np.zeros(3), dt=DT, ks=KS, ct=CT,
                            mu=MU, fn=0.0)])
    for r in res:
        assert np.all(r["ft"] == 0.0)
        assert np.all(r["u"] == 0.0)
        assert r["sliding"] == 1
    assert res[0]["diss"] == pytest.approx(0.5 * KS * (u_old @ u_old), rel=1e-14)
    assert res[1]["diss"] == 0.0


# ----------------------------------------------------------------------------------------------
# polygon quadrature


def exact_moments(poly):
    """Exact (rational) integrals over the polygon of 1, x, y, x^2, y^2, x y (Green's theorem,
    shoelace-type sums over the edges, cr = x_i y_{i+1} - x_{i+1} y_i):
        A = sum cr / 2,  Sx = sum (x_i + x_{i+1}) cr / 6,  Sxx = sum (x_i^2 + x_i x_{i+1}
        + x_{i+1}^2) cr / 12,  Sxy = sum (x_i y_{i+1} + 2 x_i y_i + 2 x_{i+1} y_{i+1}
        + x_{i+1} y_i) cr / 24,  sign flipped for clockwise polygons."""
    P = [(Fraction(x), Fraction(y)) for x, y in poly]
    A = Sx = Sy = Sxx = Syy = Sxy = Fraction(0)
    for (x0, y0), (x1, y1) in zip(P, P[1:] + P[:1]):
        cr = x0 * y1 - x1 * y0
        A += cr / 2
        Sx += (x0 + x1) * cr / 6
        Sy += (y0 + y1) * cr / 6
        Sxx += (x0 * x0 + x0 * x1 + x1 * x1) * cr / 12
        Syy += (y0 * y0 + y0 * y1 + y1 * y1) * cr / 12
        Sxy += (x0 * y1 + 2 * x0 * y0 + 2 * x1 * y1 + x1 * y0) * cr / 24
    sg = 1 if A > 0 else -1
    return {k: sg * v for k, v in dict(A=A, x=Sx, y=Sy, xx=Sxx, yy=Syy, xy=Sxy).items()}


def pressure_integrals(m, a, b, c):
    """Exact integrals of p = a + b x + c y: int p, int p x, int p y, and the centred ones
    int p (x - cx), int p (y - cy) (= b Ixx_c + c Ixy_c and b Ixy_c + c Iyy_c), the centroid
    and the polar moment J = Ixx_c + Iyy_c about it (as floats)."""
    a, b, c = Fraction(a), Fraction(b), Fraction(c)
    A = m["A"]
    cx, cy = m["x"] / A, m["y"] / A
    Ixx_c = m["xx"] - A * cx * cx
    Iyy_c = m["yy"] - A * cy * cy
    Ixy_c = m["xy"] - A * cx * cy
    out = dict(P=a * A + b * m["x"] + c * m["y"],
               Px=a * m["x"] + b * m["xx"] + c * m["xy"],
               Py=a * m["y"] + b * m["xy"] + c * m["yy"],
               Pxc=b * Ixx_c + c * Ixy_c, Pyc=b * Ixy_c + c * Iyy_c,
               A=A, cx=cx, cy=cy, J=Ixx_c + Iyy_c)
    return {k: float(v) for k, v in out.items()}


def quadrature_sums(r, a, b, c, cx, cy):
    """The same integrals by the quadrature: sums of w_k p(p'_k) (1, x', y', x'-cx, y'-cy),
    and the polar moment sum w_k |p'_k - c|^2 (c: the exact centroid)."""
    x, y = r["pts"][:, 0], r["pts"][:, 1]
    wp = r["w"] * (a + b * x + c * y)
    return dict(P=wp.sum(), Px=(wp * x).sum(), Py=(wp * y).sum(), Pxc=(wp * (x - cx)).sum(),
                Pyc=(wp * (y - cy)).sum(), J=(r["w"] * ((x - cx) ** 2 + (y - cy) ** 2)).sum())


def median_dual_weights(poly):
    """w_k = half of the two centroid-fan triangles (c, p_{k-1}, p_k) and (c, p_k, p_{k+1})."""
    P = np.array(poly, float)
    m = exact_moments(poly)
    c = np.array([float(m["x"] / m["A"]), float(m["y"] / m["A"])])
    R = P - c
    Rn = np.roll(R, -1, axis=0)
    tri = 0.5 * np.abs(R[:, 0] * Rn[:, 1] - Rn[:, 0] * R[:, 1])  # (c, p_k, p_{k+1})
    return 0.5 * (tri + np.roll(tri, 1))


RECT = [(1.305, 0.75), (1.2, 0.75), (1.2, 0.70), (1.305, 0.70)]  # 0.105 x 0.05, off the origin
_ang = np.radians(30.0)
_Rz = np.array([[np.cos(_ang), -np.sin(_ang)], [np.sin(_ang), np.cos(_ang)]])
RECT_ROT_CW = [tuple(_Rz @ np.array(p) + np.array([-0.4, 0.9]))
               for p in [(0.0, 0.0), (0.0, 0.05), (0.105, 0.05), (0.105, 0.0)]]  # clockwise
TRI = [(0.3, -0.2), (0.37, -0.2), (0.3, -0.16)]  # right triangle, legs 0.07 and 0.04
TRI_CW = TRI[::-1]
QUAD = [(0.5, 0.25), (0.59, 0.26), (0.57, 0.31), (0.51, 0.295)]
PENTA = [(2.0, 1.0), (2.1, 1.0), (2.13, 1.05), (2.06, 1.09), (1.98, 1.05)]


def pressure_for(poly):
    """A linear pressure p = a + b x + c y that is far from uniform on the polygon: 0.2 at its
    lower-left bounding-box corner, rising by 1 across its x extent and by 0.8 across its y
    extent (as floats: the references integrate exactly these a, b, c)."""
    P = np.array(poly)
    (x0, y0), (x1, y1) = P.min(0), P.max(0)
    b, c = 1.0 / (x1 - x0), 0.8 / (y1 - y0)
    return 0.2 - b * x0 - c * y0, b, c

EXACT_POLYS = {"rectangle": RECT, "rotated rectangle (cw)": RECT_ROT_CW, "right triangle": TRI,
               "right triangle (cw)": TRI_CW}
GENERAL_POLYS = {"quadrilateral": QUAD, "pentagon": PENTA}


@pytest.fixture(scope="module")
def quad_results():
    names = list(EXACT_POLYS) + list(GENERAL_POLYS)
    polys = [*EXACT_POLYS.values(), *GENERAL_POLYS.values()]
    return dict(zip(names, run_quadrature(polys))), dict(zip(names, polys))


def test_reference_integrals_match_rectangle_closed_form():
    """The test's own exact integrator on the 0.105 x 0.05 rectangle vs. the rectangle closed
    forms A = L B, c = centre, Ixx_c = A L^2/12, Iyy_c = A B^2/12, Ixy_c = 0 (both must hold, or
    the references below mean nothing)."""
    m = exact_moments(RECT)
    L, B = Fraction(1.305) - Fraction(1.2), Fraction(0.75) - Fraction(0.70)
    A = L * B
    cx, cy = (Fraction(1.305) + Fraction(1.2)) / 2, (Fraction(0.75) + Fraction(0.70)) / 2
    assert m["A"] == A
    assert m["x"] == A * cx and m["y"] == A * cy
    assert m["xx"] - A * cx * cx == A * L * L / 12
    assert m["yy"] - A * cy * cy == A * B * B / 12
    assert m["xy"] - A * cx * cy == 0


@pytest.mark.parametrize("name", list(EXACT_POLYS))
def test_polygon_quadrature_exact_for_rectangles_and_triangles(quad_results, name):
    """Rectangles and triangles: the quadrature of any linear pressure p = a + b x + c y is
    exact in force and first moments:
        sum w_k p(p'_k) = int p,   sum w_k p(p'_k) x'_k = int p x,  (and y),
    which follows from sum w_k = A, sum w_k p'_k = A c and
    sum w_k (p'_k - c)(p'_k - c)^T = second-moment tensor about c.  Median-dual weights are A/4
    (rectangle) and A/3 (triangle: the centroid splits it in three equal areas), so the shrink
    closed forms are s = 1/sqrt(3) (rectangle: corners at (L/2, B/2) vs I = A L^2/12) and
    s = 1/2 (triangle: I = A/12 sum (v - c)(v - c)^T vs A/3 sum (v - c)(v - c)^T).
    References: exact rational integrals of the polygon (exact_moments).  Tolerance 1e-12
    relative (the centred moments: 1e-11, they lose ~|x|/size ~ 30x to the subtraction x - cx).
    """
    results, polys = quad_results
    r, poly = results[name], polys[name]
    a, b, c = pressure_for(poly)
    ref = pressure_integrals(exact_moments(poly), a, b, c)
    q = quadrature_sums(r, a, b, c, ref["cx"], ref["cy"])
    n = len(poly)
    assert r["area"] == pytest.approx(ref["A"], rel=1e-12)
    assert r["w"].sum() == pytest.approx(ref["A"], rel=1e-13)
    np.testing.assert_allclose(r["w"], ref["A"] / n, rtol=1e-12)
    np.testing.assert_allclose(r["c"], [ref["cx"], ref["cy"]], rtol=1e-14, atol=1e-15)
    assert r["s"] == pytest.approx(1.0 / np.sqrt(3.0) if n == 4 else 0.5, rel=1e-12)
    np.testing.assert_allclose((r["w"][:, None] * r["pts"]).sum(0) / r["w"].sum(),
                               [ref["cx"], ref["cy"]], rtol=1e-14, atol=1e-15)
    for k in ("P", "Px", "Py"):
        assert q[k] == pytest.approx(ref[k], rel=1e-12), k
    scale = abs(ref["P"]) * np.sqrt(ref["J"] / ref["A"])  # size of a centred first moment
    for k in ("Pxc", "Pyc"):
        assert abs(q[k] - ref[k]) <= 1e-11 * scale, (k, q[k], ref[k])
    assert q["J"] == pytest.approx(ref["J"], rel=1e-12)
    # the quadrature is not trivially exact: with the unshrunk corners (s = 1) the centred
    # moments would be 3x (rectangle) or 4x (triangle) too large
    assert abs(ref["Pxc"]) > 0.1 * scale


@pytest.mark.parametrize("name", list(GENERAL_POLYS))
def test_polygon_quadrature_general_convex_polygon(quad_results, name):
    """A general convex polygon: only what the docstring promises is exact: area, centroid,
    median-dual weights (half of the two centroid-fan triangles at each vertex, sum = A) and the
    polar moment sum w_k |p'_k - c|^2 = J (s is not clamped here).
    The median-dual weights also put the weighted centroid of the points at c for any polygon:
    sum_k w_k (p_k - c) = 1/2 sum_k T_k ((p_k - c) + (p_{k+1} - c)) = 3/2 sum_k T_k (g_k - c) = 0,
    with T_k, g_k the area and centroid of the fan triangle (c, p_k, p_{k+1}); so the force
    sum w_k p(p'_k) = A p(c) = int p of a linear pressure is exact too (asserted, 1e-12).
    The first moments of the pressure (which need the full second-moment tensor, of which only
    the trace J is matched) are not promised and their errors are only printed."""
    results, polys = quad_results
    r, poly = results[name], polys[name]
    a, b, c = pressure_for(poly)
    ref = pressure_integrals(exact_moments(poly), a, b, c)
    q = quadrature_sums(r, a, b, c, ref["cx"], ref["cy"])
    assert r["area"] == pytest.approx(ref["A"], rel=1e-12)
    np.testing.assert_allclose(r["c"], [ref["cx"], ref["cy"]], rtol=1e-14, atol=1e-15)
    np.testing.assert_allclose(r["w"], median_dual_weights(poly), rtol=1e-12)
    assert r["w"].sum() == pytest.approx(ref["A"], rel=1e-13)
    assert 0.3 < r["s"] < 1.0
    assert q["J"] == pytest.approx(ref["J"], rel=1e-12)
    wc = (r["w"][:, None] * r["pts"]).sum(0) / r["w"].sum()
    np.testing.assert_allclose(wc, [ref["cx"], ref["cy"]], rtol=1e-14, atol=1e-15)
    assert q["P"] == pytest.approx(ref["P"], rel=1e-12)
    scale = abs(ref["P"]) * np.sqrt(ref["J"] / ref["A"])
    print(f"\n{name}: s = {r['s']:.6f}; weight centroid - area centroid = "
          f"{wc - [ref['cx'], ref['cy']]} m; relative errors: int p {q['P'] / ref['P'] - 1:.2e}, "
          f"int p x {q['Px'] / ref['Px'] - 1:.2e}, int p y {q['Py'] / ref['Py'] - 1:.2e}, "
          f"centred first moments (/ |P| sqrt(J/A)) {(q['Pxc'] - ref['Pxc']) / scale:.2e}, "
          f"{(q['Pyc'] - ref['Pyc']) / scale:.2e}")


def test_polygon_quadrature_degenerate_polygons():
    """Fewer than 3 vertices, or collinear vertices (exactly zero signed area): area 0, s = 1,
    no weights written (the zeroed buffer stays zero), points untouched."""
    seg = [(0.1, 0.2), (0.3, 0.4)]
    line = [(0.0, 0.0), (0.5, 0.0), (1.0, 0.0)]
    for r, poly in zip(run_quadrature([seg, line]), [seg, line]):
        assert r["area"] == 0.0
        assert r["s"] == 1.0
        assert np.all(r["w_all"] == 0.0)
        np.testing.assert_array_equal(r["pts"], np.array(poly))


# ----------------------------------------------------------------------------------------------
# box contact

D_PRESS = 1e-6
# depths are differences of coordinates of size ~0.035-0.07 m (ulp 7e-18 to 1.4e-17 m):
ATOL_LEN = 1e-16


def flush_row(dx, dy, d=D_PRESS, upper_is_A=False, prev_code=-1, RB=I3):
    lower, upper = np.zeros(3), np.array([dx, dy, 2 * HZ - d])
    if upper_is_A:
        return pair_row(upper, RB, BRICK, lower, I3, BRICK, prev_code)
    return pair_row(lower, I3, BRICK, upper, RB, BRICK, prev_code)


def check_rect_patch(r, x_lo, x_hi, y_lo, y_hi, z_mid, d, nz):
    """Shared checks of a flush rectangular patch [x_lo, x_hi] x [y_lo, y_hi]: normal (0, 0, nz),
    4 points, sum w = area, depths d, points at z_mid (midway through the overlap), weighted
    centroid = rectangle centre = returned centroid, second moments of the weights = those of
    the rectangle (A Lx^2/12, A Ly^2/12, 0: the rocking stiffness kn I is exact)."""
    Lx, Ly = x_hi - x_lo, y_hi - y_lo
    A = Lx * Ly
    cx, cy = 0.5 * (x_lo + x_hi), 0.5 * (y_lo + y_hi)
    np.testing.assert_array_equal(r["n"], [0.0, 0.0, nz])
    assert r["npts"] == 4
    assert r["w"].sum() == pytest.approx(A, rel=1e-12)
    np.testing.assert_allclose(r["dep"], d, rtol=0.0, atol=ATOL_LEN)
    np.testing.assert_allclose(r["p"][:, 2], z_mid, rtol=0.0, atol=ATOL_LEN)
    pc = (r["w"][:, None] * r["p"]).sum(0) / r["w"].sum()
    np.testing.assert_allclose(pc, [cx, cy, z_mid], rtol=0.0, atol=ATOL_LEN)
    np.testing.assert_allclose(r["centroid"], [cx, cy, z_mid], rtol=0.0, atol=ATOL_LEN)
    rx, ry = r["p"][:, 0] - cx, r["p"][:, 1] - cy
    assert (r["w"] * rx**2).sum() == pytest.approx(A * Lx**2 / 12, rel=1e-11)
    assert (r["w"] * ry**2).sum() == pytest.approx(A * Ly**2 / 12, rel=1e-11)
    assert abs((r["w"] * rx * ry).sum()) <= 1e-11 * A * Lx * Ly
    assert r["shrink"] == pytest.approx(1.0 / np.sqrt(3.0), rel=1e-12)
    assert np.all(r["buf"][4:, 3:5] == 0.0)  # buffers zero beyond the points


@pytest.mark.parametrize("dx, dy", [(0.0, 0.0), (0.02, -0.01), (-0.0337, 0.0121)])
def test_box_contact_flush_bricks(dx, dy):
    """Brick B on brick A (0.105 x 0.05 x 0.035, both unrotated), B shifted by (dx, dy) in plan
    and pressed down by d = 1e-6 (centre at z = 0.035 - d).  The least overlap, d, is on the z
    axis, shared by A's top face (code 2) and B's bottom face (code 5): they tie, and round-off
    decides which a fresh pair takes; a previous code 2 or 5 is kept (sticky).  Whichever face
    is the reference, n = +z from A to B and the patch is the overlap rectangle
    [max(-hx, dx - hx), min(hx, dx + hx)] x (same in y), area (0.105 - |dx|)(0.05 - |dy|), depth
    d everywhere, points midway through the overlap: z = (top of A + bottom of B) / 2
    = 0.0175 - d/2, weighted centroid (dx/2, dy/2).  With A and B swapped (A on top) n = -z."""
    rows = [flush_row(dx, dy), flush_row(dx, dy, prev_code=2), flush_row(dx, dy, prev_code=5),
            flush_row(dx, dy, upper_is_A=True)]
    r, r_2, r_5, r_swap = run_box_contact(rows)
    x_lo, x_hi = max(-HX, dx - HX), min(HX, dx + HX)
    y_lo, y_hi = max(-HY, dy - HY), min(HY, dy + HY)
    assert (x_hi - x_lo) * (y_hi - y_lo) == pytest.approx((0.105 - abs(dx)) * (0.05 - abs(dy)),
                                                          rel=1e-14)
    z_mid = HZ - 0.5 * D_PRESS
    assert r["code"] in (2, 5) and r_swap["code"] in (2, 5)
    assert r_2["code"] == 2 and r_5["code"] == 5
    for res in (r, r_2, r_5):
        check_rect_patch(res, x_lo, x_hi, y_lo, y_hi, z_mid, D_PRESS, 1.0)
    check_rect_patch(r_swap, x_lo, x_hi, y_lo, y_hi, z_mid, D_PRESS, -1.0)


TILT = 2e-4  # rad, about x: the penetration changes by tan(TILT) * 0.05 = 1e-5 m across the width


def tilted_case(d0, dx=0.013):
    """B = A rotated by TILT about x, shifted by dx in plan, and lowered so that the penetration
    below the reference plane z = hz (top of A) at plan point (x, y) is
        d(y) = d0 - y tan(TILT).
    Derivation: B's bottom face has outward normal nI = (0, s, -c) and passes through
    pB + hz nI; its height over (x, y) is zB - hz / c + y tan(TILT).  With
    zB = hz + hz / c - d0 the gap measured along n = +z is d(y) = hz - height = d0 - y t.
    Its plan projection is x in dx +- hx, y in hz s +- hy c; clipped by A's top face
    (|x| <= hx, |y| <= hy) and by d >= 0 (y <= d0 / t) the region is the rectangle
    [x_lo, x_hi] x [y_lo, y_hi] returned here."""
    s, c = np.sin(TILT), np.cos(TILT)
    t = s / c
    zB = HZ + HZ / c - d0
    row = pair_row(np.zeros(3), I3, BRICK, np.array([dx, 0.0, zB]), rot_x(TILT), BRICK)
    d0_eff = HZ + HZ / c - zB  # the d0 that the rounded zB represents
    x_lo, x_hi = max(-HX, dx - HX), min(HX, dx + HX)
    y_lo = max(-HY, HZ * s - HY * c)
    y_hi = min(HY, HZ * s + HY * c, d0_eff / t)
    return row, d0_eff, t, (x_lo, x_hi, y_lo, y_hi)


@pytest.mark.parametrize("d0, cut", [(1e-5, False), (2e-6, True)])
def test_box_contact_tilted_bed_linear_pressure(d0, cut):
    """Tilted bed (upper brick turned by 2e-4 rad about x): the pressure kn d(y) is linear across
    the width.  Closed forms over the rectangle [x_lo, x_hi] x [y_lo, y_hi] (see tilted_case):
        F  = kn int d dA     = kn Lx [d0 (y_hi - y_lo) - t (y_hi^2 - y_lo^2) / 2]
        Mx = kn int d y dA   = kn Lx [d0 (y_hi^2 - y_lo^2) / 2 - t (y_hi^3 - y_lo^3) / 3]
        My = kn int d x dA   = F (x_lo + x_hi) / 2
    and the quadrature gives F = kn sum w_k dep_k, Mx = kn sum w_k dep_k y_k,
    My = kn sum w_k dep_k x_k: exact, as the region is a rectangle and d is affine.
    d0 = 1e-5: d > 0 over the whole overlap (5e-6 .. 1.5e-5); d0 = 2e-6: the gap line d = 0
    (y = d0 / t = 0.01) cuts the overlap, a rectangle again.
    Tolerance: depths carry ~1e-17 m round-off (coordinates ~0.035 m) against depths of ~1e-6
    and more: 1e-9 relative on F and M, and the points' z = hz - dep/2 to 1e-16 m.
    """
    kn = 1e10
    row, d0e, t, (x_lo, x_hi, y_lo, y_hi) = tilted_case(d0)
    (r,) = run_box_contact([row])
    Lx = x_hi - x_lo
    assert (y_hi < HY - 1e-3) == cut  # the premise: the gap line is inside the overlap or not
    F = kn * Lx * (d0e * (y_hi - y_lo) - t * (y_hi**2 - y_lo**2) / 2)
    Mx = kn * Lx * (d0e * (y_hi**2 - y_lo**2) / 2 - t * (y_hi**3 - y_lo**3) / 3)
    My = F * (x_lo + x_hi) / 2
    assert r["code"] == 2
    np.testing.assert_allclose(r["n"], [0.0, 0.0, 1.0], rtol=0.0, atol=1e-15)
    assert r["npts"] == 4
    assert r["w"].sum() == pytest.approx(Lx * (y_hi - y_lo), rel=1e-11)
    assert np.all(r["dep"] >= 0.0)
    np.testing.assert_allclose(r["dep"], d0e - t * r["p"][:, 1], rtol=0.0, atol=ATOL_LEN)
    np.testing.assert_allclose(r["p"][:, 2], HZ - 0.5 * r["dep"], rtol=0.0, atol=ATOL_LEN)
    f = kn * r["w"] * r["dep"]
    assert f.sum() == pytest.approx(F, rel=1e-9)
    assert (f * r["p"][:, 1]).sum() == pytest.approx(Mx, rel=1e-9)
    assert (f * r["p"][:, 0]).sum() == pytest.approx(My, rel=1e-9)
    # the load is far from uniform, so these moments test more than the area and centroid
    assert abs(Mx) > 0.05 * F * (y_hi - y_lo)


def test_box_contact_crosswise_brick():
    """B turned 90 deg about z (exact matrix) on A, shifted (0.01, 0.005), pressed by d = 1e-6:
    B's footprint is x in 0.01 +- 0.025, y in 0.005 +- 0.0525, so the overlap is the square
    [-0.015, 0.035] x [-0.025, 0.025] (0.05 x 0.05, centre (0.01, 0)).  Whichever z face is the
    reference (A's or B's: they tie), n = +z and the patch is that square."""
    Rz90 = np.array([[0.0, -1.0, 0.0], [1.0, 0.0, 0.0], [0.0, 0.0, 1.0]])
    row = pair_row(np.zeros(3), I3, BRICK, np.array([0.01, 0.005, 2 * HZ - D_PRESS]), Rz90,
                   BRICK)
    (r,) = run_box_contact([row])
    assert r["code"] in (2, 5)
    assert r["w"].sum() == pytest.approx(0.05 * 0.05, rel=1e-12)
    check_rect_patch(r, -0.015, 0.035, -0.025, 0.025, HZ - 0.5 * D_PRESS, D_PRESS, 1.0)


def rot_z(t):
    c, s = np.cos(t), np.sin(t)
    return np.array([[c, -s, 0.0], [s, c, 0.0], [0.0, 0.0, 1.0]])


def edge_edge_row(delta, phi=0.0):
    """A turned 45 deg about x; B turned 45 deg about y, then by phi about z.  B's lowest edge
    (along Rz(phi) e_y, horizontal) crosses A's highest edge (along x) at plan point (0, yA),
    overlapping by delta along z.
      A's top edge: local (x, hy, hz) -> (x, c hy - s hz, s hy + c hz), so yA = c hy - s hz and
      its height is zA = s hy + c hz.
      B's bottom edge: local (hx, y, -hz) -> pB + Rz(phi) (c hx - s hz, y, -(s hx + c hz)).
    Its midpoint is put at (0, yA, zA - delta):
      pB = (0, yA, zA + s hx + c hz - delta) - Rz(phi) (c hx - s hz, 0, 0).
    Both edges are horizontal, so the axis a_x cross b_y is +z (length cos phi before
    normalisation), the overlap along it is zA + (s hx + c hz) - pB_z = delta, and the
    midpoint of the closest points of the edges is (0, yA, zA - delta / 2)."""
    q = np.pi / 4
    s, c = np.sin(q), np.cos(q)
    yA = c * HY - s * HZ
    zA = s * HY + c * HZ
    Rz = rot_z(phi)
    pB = np.array([0.0, yA, zA + (s * HX + c * HZ) - delta]) - Rz @ [c * HX - s * HZ, 0.0, 0.0]
    ov = zA + (s * HX + c * HZ) - pB[2]
    row = pair_row(np.zeros(3), rot_x(q), BRICK, pB, Rz @ rot_y(q), BRICK)
    return row, np.array([0.0, yA, zA]), ov


def face_axis_overlaps(row):
    """Overlaps of the two boxes on their six face axes (numpy: rA(L) + rB(L) - |(pB - pA).L|)."""
    pA, RA, hA = row[0:3], row[3:12].reshape(3, 3), row[12:15]
    pB, RB, hB = row[15:18], row[18:27].reshape(3, 3), row[27:30]
    axes = np.concatenate([RA.T, RB.T])
    return np.array([np.abs(RA.T @ L) @ hA + np.abs(RB.T @ L) @ hB - abs((pB - pA) @ L)
                     for L in axes])


def test_box_contact_separated_boxes():
    """No contact: (i) B resting 1e-6 above A; (ii) B beside A, 1e-3 apart in x (overlapping in
    z); (iii) the edge-edge pairs below (phi = 0 and 30 deg) with a gap of 1e-6 along z, where
    all six face axes still overlap (checked here in numpy) and only the edge axis a_x cross b_y
    separates.
    Expected: code -1 and no points."""
    rows = [flush_row(0.0, 0.0, d=-1e-6), flush_row(2 * HX + 1e-3, 0.0)]
    rows_e = []
    for phi in (0.0, np.radians(30.0)):
        row_e, _, ov = edge_edge_row(-1e-6, phi)
        assert ov < 0 and np.all(face_axis_overlaps(row_e) > 1e-3)
        rows_e.append(row_e)
    for r in run_box_contact(rows + rows_e):
        assert r["code"] == -1
        assert r["npts"] == 0
        assert np.all(r["buf"][:, 3:5] == 0.0)


@pytest.mark.parametrize("phi_deg", [0.0, 30.0])
def test_box_contact_edge_edge(phi_deg):
    """Edge-to-edge contact (see edge_edge_row, overlap 1e-6; phi = 0: perpendicular edges,
    phi = 30 deg: edges at 60 deg, |a_x cross b_y| = cos phi): the edge axis of A's x and B's y
    has the least overlap, code = 6 + 3 * 0 + 1 = 7; n = normalised a_x cross b_y = +z (from A
    to B); one point at the crossing, midway through the overlap, (0, yA, zA - delta/2), depth =
    the overlap along the axis, weight edge_area = (smallest half extent)^2 = 0.0175^2.
    Tolerances: coordinates ~0.07 m (ulp 1.4e-17): 1e-16 m on the point and the depth."""
    delta = 1e-6
    row, top, ov = edge_edge_row(delta, np.radians(phi_deg))
    (r,) = run_box_contact([row])
    assert ov == pytest.approx(delta, rel=1e-10)
    assert r["code"] == 7
    b_y = row[18:27].reshape(3, 3)[:, 1]
    axis = np.cross([1.0, 0.0, 0.0], b_y)
    np.testing.assert_allclose(r["n"], axis / np.linalg.norm(axis), rtol=0.0, atol=1e-15)
    np.testing.assert_allclose(r["n"], [0.0, 0.0, 1.0], rtol=0.0, atol=1e-15)
    assert r["npts"] == 1
    assert r["w"][0] == HZ * HZ
    assert r["dep"][0] == pytest.approx(ov, abs=ATOL_LEN)
    np.testing.assert_allclose(r["p"][0], top - [0.0, 0.0, 0.5 * delta], rtol=0.0, atol=ATOL_LEN)
    np.testing.assert_allclose(r["centroid"], r["p"][0], rtol=0.0, atol=0.0)
    assert np.all(r["buf"][1:, 3:5] == 0.0)


# ----------------------------------------------------------------------------------------------
# imperfect faces (docs/imperfections.md): arris inset and warped faces


def test_box_contact_arris_insets_the_patch():
    """B on A flush, both with arris r = 2 mm: the patch is the rectangle inset by r on every
    side, (0.105 - 2 r) x (0.05 - 2 r), depth d everywhere, with the exact second moments."""
    r = 0.002
    (res,) = run_box_contact([flush_row(0.0, 0.0)], arris=[r, r])
    check_rect_patch(res, -HX + r, HX - r, -HY + r, HY - r, HZ - 0.5 * D_PRESS, D_PRESS, 1.0)


def test_box_contact_uniform_recess_is_a_shift():
    """All four corners of A's top face recessed by delta: the gap is that of two flat faces
    delta apart, so pressed by d > delta the patch is the full rectangle at depth d - delta;
    pressed by less than delta there is no force (every point at depth 0 or no point)."""
    delta = 4e-7
    off = np.zeros((2, 6, 4))
    off[0, 4] = -delta  # body A (row 0: bodies 0 and 1), face 4 = +z
    (res,) = run_box_contact([flush_row(0.0, 0.0)], face_offset=off)
    np.testing.assert_array_equal(res["n"], [0.0, 0.0, 1.0])
    assert res["w"].sum() == pytest.approx(4 * HX * HY, rel=1e-12)
    np.testing.assert_allclose(res["dep"], D_PRESS - delta, rtol=0.0, atol=1e-15)
    (shallow,) = run_box_contact([flush_row(0.0, 0.0, d=0.5 * delta)], face_offset=off)
    assert np.all(shallow["dep"] == 0.0)


def test_box_contact_twisted_face_bears_on_its_high_diagonal():
    """B's bottom face twisted: corners 0 (-x, -y) and 3 (+x, +y) on the nominal face, 1 and 2
    recessed by 2 t = 20 um, B pressed by d = 1 um.  A twisted patch is sampled at the corners
    of the overlap (docs/imperfections.md): the two high corners bear the depth d, the two low
    ones are open (depth 0, weight 0), the weights of the bearing corners are their tributary
    areas, a quarter of the face each."""
    t = 1e-5
    off = np.zeros((2, 6, 4))
    off[1, 5] = [0.0, -2 * t, -2 * t, 0.0]  # body B, face 5 = -z; corners c = (x>0) + 2 (y>0)
    (res,) = run_box_contact([flush_row(0.0, 0.0)], face_offset=off)
    assert res["npts"] == 4
    x, y = res["p"][:, 0] / HX, res["p"][:, 1] / HY
    np.testing.assert_allclose(np.abs(x), 1.0, atol=1e-12)  # the corners
    np.testing.assert_allclose(np.abs(y), 1.0, atol=1e-12)
    high = x * y > 0
    np.testing.assert_allclose(res["dep"][high], D_PRESS, rtol=0.0, atol=1e-15)
    assert np.all(res["dep"][~high] == 0.0) and np.all(res["w"][~high] == 0.0)
    np.testing.assert_allclose(res["w"][high], HX * HY, rtol=1e-12)
