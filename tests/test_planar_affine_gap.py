"""The planar warped gap as one affine function per pair (dem.engine.geometry.planar_gap).

Tolerances.
* Gap at a point inside both faces: the affine form and the two bilinear forms are the same
  function there (no clamp acts, no twist), so they differ by round-off alone.  Every term of the
  gap is a product of at most three f64 factors summed over at most ~20 terms, each with a
  relative error of a few eps (eps = 2.2e-16); the largest terms are the plane offset
  (c - ci) . nI (|c - ci| up to ~0.1 m, so ~eps x 0.1 m), gx x, gy y (lengths up to 0.1 m) and
  the offsets times the incident face's coordinates (~1e-4 m x (|c - ci| + |x| + |y|) / h).
  The bound used is 64 eps times the sum of the absolute values of those terms (~1e-15 m), plus
  the twist left by making the warps planar in floating point (|T_R| + |T_I|, <= 1e-19 m here).
  A wrong coefficient (a sign, a swapped axis, a missing cc term) moves the gap by the offsets'
  size, ~1e-5 m, ten orders above it.
* The engine's points (box_contact on two planar-warped bricks): each point's depth is the
  affine gap there, which inside both faces is the bilinear one, to the same round-off bound.
* End to end (three bricks, planar 0.1 mm beds, settled, then under a lateral 0.1 g): the final
  positions against those of the code before planar_gap (two bilinear forms per point, commit
  2a8676f), stored in OLD_POSITIONS.  The gap differs from the old one only at overlap vertices
  beyond the incident face's edge in its coordinate (planar_gap's docstring, (2)), by
  |B_I| z |n . d1| / hI <= 2e-4 m x 3e-4 m x 4e-3 / 0.025 m ~ 1e-8 m (offset slope, depth
  below the nominal face, relative tilt of two 0.1 mm planar beds across a 50 mm brick, half
  width), and by round-off elsewhere.  This scene is not chaotic: the old code run with the top
  brick's bed tilted by +-1e-12 / 1e-9 / 4e-9 m at its ends (``bump``, a planar gap change of
  that size) moves the positions by 2.6e-13 / 2.6e-10 / 1.0e-9 m, 0.26 x the gap change.  So
  the change may move them by ~0.3 x 1e-8 m per joint, two joints under the top brick: the
  tolerance is 2e-8 m.  Measured (2026-11-24): 1.9e-10 m.  The planar beds move the top
  brick by 0.26 mm against a perfect stack (checked), 1e4 x the tolerance, so a wrong gap fails.
"""

import numpy as np
import taichi as ti

from dem import ti_runtime

ti_runtime.init()

from dem.engine import geometry  # noqa: E402

EPS = np.finfo(float).eps


def _rot(axis_angle):
    """Rotation matrix of a rotation vector (rad)."""
    th = np.linalg.norm(axis_angle)
    if th == 0.0:
        return np.eye(3)
    k = axis_angle / th
    K = np.array([[0, -k[2], k[1]], [k[2], 0, -k[0]], [-k[1], k[0], 0]])
    return np.eye(3) + np.sin(th) * K + (1 - np.cos(th)) * K @ K


def _planar_offsets(rng, sigma):
    """Corner offsets (m) of a planar warp: o_3 = o_1 + o_2 - o_0 (corner c = (s1 > 0) +
    2 (s2 > 0)), the face recessed on average as dem.imperfections does."""
    o = rng.normal(0.0, sigma, 3)
    o = np.array([o[0], o[1], o[2], o[1] + o[2] - o[0]])
    return o - o.max()  # the face stands out nowhere beyond its nominal plane


def _pair(rng, sigma=1e-4):
    """Reference box R (random orientation, its +z face up in its frame) and incident box I
    on that face, turned by up to 10 mrad, shifted sideways, sunk by up to 0.2 mm into the
    nominal box (warps recess the faces)."""
    hR = rng.uniform([0.02, 0.01, 0.01], [0.06, 0.03, 0.02])
    hI = rng.uniform([0.02, 0.01, 0.01], [0.06, 0.03, 0.02])
    RR = _rot(rng.normal(0.0, 1.0, 3))
    pR = rng.uniform(-1.0, 1.0, 3)
    RI = RR @ _rot(rng.uniform(-0.01, 0.01, 3) * [1.0, 1.0, 3.0])
    shift = rng.uniform(-0.5, 0.5, 2) * (hR[:2] + hI[:2])
    sink = rng.uniform(0.0, 2e-4)
    pI = pR + RR @ np.array([shift[0], shift[1], hR[2] + hI[2] - sink])
    return pR, RR, hR, pI, RI, hI, _planar_offsets(rng, sigma), _planar_offsets(rng, sigma)


def _bilinear(o, xi, eta):
    x = np.clip(xi, -1.0, 1.0)
    y = np.clip(eta, -1.0, 1.0)
    return 0.25 * ((1 - x) * (1 - y) * o[0] + (1 + x) * (1 - y) * o[1]
                   + (1 - x) * (1 + y) * o[2] + (1 + x) * (1 + y) * o[3])


def _reference_gap(pR, RR, hR, pI, RI, hI, oR, oI, x, y):
    """The warped gap of R's +z face against I's -z face at reference coordinates (x, y), as
    the code before planar_gap evaluated it (two bilinear forms), written in numpy; also the
    incident coordinates and a bound of the round-off of the terms (m)."""
    n, u1, u2 = RR[:, 2], RR[:, 0], RR[:, 1]
    c = pR + n * hR[2]
    nI, d1, d2 = -RI[:, 2], RI[:, 0], RI[:, 1]
    ci = pI + nI * hI[2]
    P = c[None, :] + x[:, None] * u1 + y[:, None] * u2
    plane = (P - ci) @ nI / n.dot(nI)
    r = P - ci
    xiI, etaI = r @ d1 / hI[0], r @ d2 / hI[1]
    gap = plane + _bilinear(oR, x / hR[0], y / hR[1]) + _bilinear(oI, xiI, etaI)
    big = np.abs(oR).max() + np.abs(oI).max()
    lengths = np.linalg.norm(c - ci) + np.abs(x) + np.abs(y)
    scale = lengths + np.abs(plane) + 4 * big * (2.0 + lengths / hI[:2].min())
    return gap, xiI, etaI, scale


def _twist(o):
    return abs(0.25 * (o[0] - o[1] - o[2] + o[3]))


@ti.kernel
def _coefficients(pR: ti.types.ndarray(), RR: ti.types.ndarray(), hR: ti.types.ndarray(),
                  pI: ti.types.ndarray(), RI: ti.types.ndarray(), hI: ti.types.ndarray(),
                  oR: ti.types.ndarray(), oI: ti.types.ndarray(), out: ti.types.ndarray()):
    """(a, bx, by, m, sm) of R's +z face against box I, through the engine's own frame
    functions, as geometry.face_contact / warped_patch compute them."""
    for _ in range(1):
        pr = ti.Vector([pR[0], pR[1], pR[2]])
        pi = ti.Vector([pI[0], pI[1], pI[2]])
        hr = ti.Vector([hR[0], hR[1], hR[2]])
        hi = ti.Vector([hI[0], hI[1], hI[2]])
        Rr = ti.Matrix([[RR[a, b] for b in ti.static(range(3))] for a in ti.static(range(3))])
        Ri = ti.Matrix([[RI[a, b] for b in ti.static(range(3))] for a in ti.static(range(3))])
        o_r = ti.Vector([oR[0], oR[1], oR[2], oR[3]])
        o_i = ti.Vector([oI[0], oI[1], oI[2], oI[3]])
        n, u1, u2, c = geometry.face_frame(pr, Rr, hr, 2, 1.0)
        m, sm, nI, b1, b2 = geometry.incident_face(n, Ri, hi)
        ci = pi + nI * hi[m]
        d0, gx, gy = geometry.affine_gap(c, u1, u2, n, nI, ci)
        m1 = (m + 1) % 3
        m2 = (m + 2) % 3
        d1 = ti.Vector([Ri[0, m1], Ri[1, m1], Ri[2, m1]])
        d2 = ti.Vector([Ri[0, m2], Ri[1, m2], Ri[2, m2]])
        a, bx, by = geometry.planar_gap(c - ci, u1, u2, 1.0 / hr[0], 1.0 / hr[1], o_r, d1, d2,
                                        1.0 / hi[m1], 1.0 / hi[m2], o_i, d0, gx, gy)
        out[0] = a
        out[1] = bx
        out[2] = by
        out[3] = m
        out[4] = sm


def test_the_affine_gap_is_the_bilinear_gap_inside_both_faces():
    """200 random planar-warped pairs, 200 random points inside both faces each."""
    rng = np.random.default_rng(20261124)
    worst = 0.0
    for _ in range(200):
        pR, RR, hR, pI, RI, hI, oR, oI = _pair(rng)
        out = np.zeros(5)
        _coefficients(pR, RR, hR, pI, RI, hI, oR, oI, out)
        a, bx, by, m, sm = out
        assert (m, sm) == (2, -1)  # I's -z face is the incident one
        x = rng.uniform(-hR[0], hR[0], 2000)
        y = rng.uniform(-hR[1], hR[1], 2000)
        gap, xiI, etaI, scale = _reference_gap(pR, RR, hR, pI, RI, hI, oR, oI, x, y)
        inside = (np.abs(xiI) <= 1.0) & (np.abs(etaI) <= 1.0)
        assert inside.sum() >= 50
        affine = a + bx * x + by * y
        err = np.abs(affine - gap)[inside]
        tol = 64 * EPS * scale[inside] + _twist(oR) + _twist(oI)
        assert np.all(err <= tol), (err.max(), tol.min())
        worst = max(worst, (err / tol).max())
    # the bound is not vacuous: the largest error is at least a sizeable part of it
    assert worst > 1e-3


# ------------------------------------------------------------------------------------------
# the engine's points: box_contact on two planar-warped bricks


@ti.data_oriented
class _Faces:
    """The fields of dem.engine's Model that box_contact reads for imperfect faces."""

    def __init__(self):
        self.face_offset = ti.Vector.field(4, float, shape=(2, 6))
        self.arris = ti.field(float, shape=2)
        self.recess = ti.field(float, shape=2)
        self.imperfect = ti.field(ti.i32, shape=2)


_FACES = None


def _faces():
    global _FACES
    if _FACES is None:
        _FACES = _Faces()
    return _FACES


@ti.kernel
def _contact(faces: ti.template(), pos: ti.types.ndarray(), rot: ti.types.ndarray(),
             half: ti.types.ndarray(), out: ti.types.ndarray()) -> ti.i32:
    """box_contact of body 0 (A) against body 1 (B): its points (x, y, z, depth, weight) in
    out[0:npts], returns code * 100 + npts."""
    res = 0
    for _ in range(1):
        pA = ti.Vector([pos[0, 0], pos[0, 1], pos[0, 2]])
        pB = ti.Vector([pos[1, 0], pos[1, 1], pos[1, 2]])
        hA = ti.Vector([half[0, 0], half[0, 1], half[0, 2]])
        hB = ti.Vector([half[1, 0], half[1, 1], half[1, 2]])
        RA = ti.Matrix([[rot[0, a, b] for b in ti.static(range(3))] for a in ti.static(range(3))])
        RB = ti.Matrix([[rot[1, a, b] for b in ti.static(range(3))] for a in ti.static(range(3))])
        px = geometry.point_buffer()
        py = geometry.point_buffer()
        pz = geometry.point_buffer()
        dep = geometry.point_buffer()
        w = geometry.point_buffer()
        code, n, npts, shrink, centroid, whole = geometry.box_contact(
            pA, RA, hA, pB, RB, hB, -1, 1e-5, 1e-6, faces, True, 0, 1, px, py, pz, dep, w)
        for q in range(npts):
            out[q, 0] = px[q]
            out[q, 1] = py[q]
            out[q, 2] = pz[q]
            out[q, 3] = dep[q]
            out[q, 4] = w[q]
        res = code * 100 + npts
    return res


def test_the_engines_planar_points_bear_the_bilinear_gap():
    """Each point of a planar-warped patch has depth max(gap, 0) with gap the two bilinear
    forms' value at the point (inside both faces: the quadrature points are pulled in towards
    the centroid), and the patch bears: its points carry weight and depth."""
    rng = np.random.default_rng(7)
    faces = _faces()
    checked = 0
    for _ in range(60):
        pR, RR, hR, pI, RI, hI, oR, oI = _pair(rng)
        fo = np.zeros((2, 6, 4))
        fo[0, 4] = oR  # A's +z face
        fo[1, 5] = oI  # B's -z face
        faces.face_offset.from_numpy(fo)
        faces.arris.from_numpy(np.zeros(2))
        faces.recess.from_numpy(np.full(2, 4e-4))
        faces.imperfect.from_numpy(np.ones(2, np.int32))
        out = np.zeros((geometry.MAXP + 1, 5))
        res = _contact(faces, np.array([pR, pI]), np.array([RR, RI]), np.array([hR, hI]), out)
        code, npts = divmod(res, 100)
        if code != 2 or npts == 0:  # A's z face the reference one: the case written out above
            continue
        n = RR[:, 2]
        c = pR + n * hR[2]
        P = out[:npts, :3]
        x = (P - c) @ RR[:, 0]
        y = (P - c) @ RR[:, 1]
        gap, xiI, etaI, scale = _reference_gap(pR, RR, hR, pI, RI, hI, oR, oI, x, y)
        assert np.all(np.abs(xiI) <= 1.0) and np.all(np.abs(etaI) <= 1.0)
        tol = 64 * EPS * scale + _twist(oR) + _twist(oI)
        assert np.all(np.abs(out[:npts, 3] - np.maximum(gap, 0.0)) <= tol)
        assert np.all(out[:npts, 4] > 0.0) and np.all(out[:npts, 3] >= 0.0)
        checked += 1
    assert checked >= 20


# ------------------------------------------------------------------------------------------
# end to end: three bricks with planar beds, against the code before planar_gap


# final positions (m) of _three_bricks() run by the code before planar_gap (commit 2a8676f,
# two bilinear forms per point), printed by ``python tests/test_planar_affine_gap.py`` there
OLD_POSITIONS = [[-0.05250529556770336, 1.1953544606121536e-05, 0.017442859773075536],
                 [0.05251113353215399, 4.562396142056043e-05, 0.01736113642591088],
                 [0.021008378950878318, -8.085786889103513e-06, 0.052235187499205755]]


def _three_bricks(bump=0.0):
    """Two small bricks side by side on the table and one across their joint, planar 0.1 mm
    beds (seed 3), local damping 0.8: settled 0.4 s, then 0.4 s under a lateral 0.1 g.
    ``bump`` (m) tilts the top brick's bed by +-bump at its short ends (a planar change, to
    measure how far a gap change of that size moves the result).  Returns the final positions
    (m, 3 x 3)."""
    from dem.case import parse_case
    from dem.engine import Simulation
    from dem.run.build import case_joint_law, scene_from_case, step_options

    L, W, H = 0.105, 0.05, 0.035
    blocks = [{"size": [L, W, H], "position": [-0.5 * L, 0.0, 0.5 * H], "density": 1828.6},
              {"size": [L, W, H], "position": [0.5 * L, 0.0, 0.5 * H], "density": 1828.6},
              {"size": [L, W, H], "position": [0.2 * L, 0.0, 1.5 * H], "density": 1828.6}]
    case = parse_case({
        "name": "three-bricks", "scene": {"blocks": blocks}, "material": {"friction": 0.8},
        "run": {"duration": 1.0},
        "imperfections": {"bed_unevenness": 1e-4, "seed": 3, "face_shape": "planar"}})
    scene = scene_from_case(case)
    scene.face_offset[2, 5] += bump * np.array([-1.0, 1.0, -1.0, 1.0])
    sim = Simulation(scene, case_joint_law(case, scene), step_options(case.solver))
    sim.set_local_damping(0.8)
    steps = int(0.4 / sim.dt)

    def loads(a):
        g = np.array([a, 0.0, -9.81])
        return lambda t: (np.tile(g, (len(t), 1)), np.zeros((len(t), 3)))

    sim.advance(steps, loads(0.0))
    sim.advance(steps, loads(0.981))
    return sim.state.pos[:3].copy()


def test_three_bricks_end_where_the_bilinear_code_left_them():
    pos = _three_bricks()
    assert np.abs(pos - np.array(OLD_POSITIONS)).max() <= 2e-8
    # the planar beds matter far above the tolerance: the top brick sits 0.26 mm below where a
    # perfect one would (1.5 H over the table)
    assert abs(pos[2, 2] - 1.5 * 0.035) > 1e-4


if __name__ == "__main__":  # prints the positions to store in OLD_POSITIONS, and the spread
    import sys

    base = _three_bricks()
    print(repr(base.tolist()))
    for bump in map(float, sys.argv[1:]):
        print(bump, np.abs(_three_bricks(bump) - base).max())
