"""Overlap reuse of the warped kernels (dem.engine.coherence.set_overlap_reuse).

A warped joint keeps the faces' overlap polygon (reference rectangle clipped by the incident
face's projected corners) while those corners drift less than tol in the reference plane, and
redoes only the gap clip, the quadrature and the points from the current poses.

Tolerances.
* Full path with keeping (coherence.keep_overlap) against geometry.box_contact: the same
  operations in the same order, so the same numbers up to how the compiler fuses them
  (fast-math, FMA: machine-dependent).  A round-off difference does not stay round-off in this
  scene: 0.8 s of sticking and slipping amplify it.  Measured on a 2-core AMD EPYC VM (FMA): the
  scene turns a 1e-16 m shift of the top brick's start into 8.2e-14 m at the end (a 1e-17 m
  shift, below its coordinates' ulp, into 2.8e-17 m), and the two paths end 6.1e-13 m apart;
  on the machine this test was first written on they ended < 1e-15 m apart.  The bound is
  1e-11 m: round-off amplified by this scene (~15 x the largest difference measured), and
  still 5 000 x below what reusing polygons within tol = 1e-7 m may move it (5.2e-8 m, below).
* One pair, the incident brick moved in its plane by a fraction f of tol after the polygon was
  kept: the kept polygon is the true one shifted by at most f tol per vertex, so the patch's
  area differs by at most perimeter x f tol, its resultant sum w d (m^3) by at most
  perimeter x f tol x dmax + area x |grad d| x f tol (the points move by f tol along a gap of
  slope |grad d|), and a moved brick beyond tol is not reused.
* End to end (three bricks, planar 0.1 mm beds, settled then pushed at 0.1 g): positions with
  tol = 1e-7 m against tol = 0.  tests/test_planar_affine_gap.py measured this scene's
  sensitivity to a planar gap change: 0.26 m per m.  A polygon error of tol changes a joint's
  force and moment as a gap change of at most tol x (its slope across the joint, < 1e-2) does,
  so two joints under the top brick move it by < 2 x 0.26 x tol; the bound taken is
  0.26 x tol x 2 = 5.2e-8 m.
"""

import numpy as np
import taichi as ti

from dem import ti_runtime

ti_runtime.init()

from dem.engine import coherence, geometry  # noqa: E402
from dem.engine.containers import ContactArgs, ModelArgs, StateArgs  # noqa: E402
from dem.engine.geometry import point_buffer  # noqa: E402

L, W, H = 0.105, 0.05, 0.035


def _sim(blocks, shape="planar", seed=3):
    from dem.case import parse_case
    from dem.engine import Simulation
    from dem.run.build import case_joint_law, scene_from_case, step_options

    case = parse_case({
        "name": "overlap-reuse", "scene": {"blocks": blocks}, "material": {"friction": 0.8},
        "run": {"duration": 1.0},
        "imperfections": {"bed_unevenness": 1e-4, "seed": seed, "face_shape": shape}})
    scene = scene_from_case(case)
    return Simulation(scene, case_joint_law(case, scene), step_options(case.solver))


def _three_bricks(tol, shape="planar"):
    """tests/test_planar_affine_gap.py's scene: two bricks on the table, one across their
    joint; settled 0.4 s with local damping 0.8, then 0.4 s under a lateral 0.1 g.  Returns the
    final positions (m) and the number of pairs with a kept overlap at the end."""
    blocks = [{"size": [L, W, H], "position": [-0.5 * L, 0.0, 0.5 * H], "density": 1828.6},
              {"size": [L, W, H], "position": [0.5 * L, 0.0, 0.5 * H], "density": 1828.6},
              {"size": [L, W, H], "position": [0.2 * L, 0.0, 1.5 * H], "density": 1828.6}]
    sim = _sim(blocks, shape)
    coherence.set_overlap_reuse(sim.contacts, tol)
    sim.set_local_damping(0.8)
    steps = int(0.4 / sim.dt)

    def loads(a):
        g = np.array([a, 0.0, -9.81])
        return lambda t: (np.tile(g, (len(t), 1)), np.zeros((len(t), 3)))

    sim.advance(steps, loads(0.0))
    sim.advance(steps, loads(0.981))
    kept = int((sim.contacts.patch_shape[:sim.contacts.n_pairs, 0, 3] < 0).sum())
    return sim.state.pos[:3].copy(), kept


@ti.kernel
def _pair_patches(p: ti.i32, tol: float, keep: ti.i32, model: ModelArgs, state: StateArgs,
                  contacts: ContactArgs, out: ti.types.ndarray(ndim=2)) -> ti.i32:
    """Pair p: keep its overlap at the current poses if keep (keep_overlap); row 0 of out the
    full narrow phase (box_contact), row 1 reuse_overlap of the kept polygon; columns: npts,
    then (x, y, z, depth, w) per point.  Returns reused."""
    i = contacts.pairs[p][0]
    j = contacts.pairs[p][1]
    hA = model.half[i]
    hB = model.half[j]
    hmin = ti.min(hA.min(), hB.min())
    px = point_buffer()
    py = point_buffer()
    pz = point_buffer()
    dep = point_buffer()
    w = point_buffer()
    if keep != 0:
        coherence.keep_overlap(p, i, j, 1e-3 * hmin, hmin * hmin, model, state, contacts, px,
                               py, pz, dep, w)
    _c, _n, m_full, _s, _g, _wh = geometry.box_contact(
        state.pos[i], state.rot[i], hA, state.pos[j], state.rot[j], hB, contacts.code[p],
        1e-3 * hmin, hmin * hmin, model, True, i, j, px, py, pz, dep, w)
    out[0, 0] = m_full
    for q in range(m_full):
        out[0, 1 + 5 * q] = px[q]
        out[0, 2 + 5 * q] = py[q]
        out[0, 3 + 5 * q] = pz[q]
        out[0, 4 + 5 * q] = dep[q]
        out[0, 5 + 5 * q] = w[q]
    reused, _n2, m_kept, _s2, _g2 = coherence.reuse_overlap(p, i, j, tol, model, state, contacts,
                                                           px, py, pz, dep, w)
    out[1, 0] = m_kept
    for q in range(m_kept):
        out[1, 1 + 5 * q] = px[q]
        out[1, 2 + 5 * q] = py[q]
        out[1, 3 + 5 * q] = pz[q]
        out[1, 4 + 5 * q] = dep[q]
        out[1, 5 + 5 * q] = w[q]
    return reused


def _resultants(row):
    n = int(row[0])
    pts = row[1:1 + 5 * n].reshape(n, 5)
    return pts[:, 4].sum(), (pts[:, 3] * pts[:, 4]).sum(), pts


def test_full_path_with_keeping_is_the_full_narrow_phase():
    a, _ = _three_bricks(0.0)
    b, kept = _three_bricks(1e-300)  # keeps every overlap, reuses only bit-identical poses
    assert kept >= 3  # the two bricks on the table and the bridging brick's two beds
    assert np.abs(a - b).max() <= 1e-11  # round-off amplified by the scene (docstring)


def test_reused_overlap_is_within_the_tolerance_and_refused_beyond():
    tol = 1e-6
    blocks = [{"size": [L, W, H], "position": [0.0, 0.0, 0.5 * H], "density": 1828.6},
              {"size": [L, W, H], "position": [0.01, 0.002, 1.5 * H], "density": 1828.6}]
    sim = _sim(blocks)
    coherence.set_overlap_reuse(sim.contacts, tol)
    g = np.array([0.0, 0.0, -9.81])
    sim.set_local_damping(0.8)
    sim.advance(int(0.2 / sim.dt), lambda t: (np.tile(g, (len(t), 1)), np.zeros((len(t), 3))))
    pairs = sim.contacts.pairs[:sim.contacts.n_pairs]
    p = int(np.flatnonzero((pairs[:, 0] == 0) & (pairs[:, 1] == 1))[0])
    assert sim.contacts.patch_shape[p, 0, 3] < 0  # kept
    pos0 = sim.state.pos.copy()
    out = np.zeros((2, 1 + 5 * geometry.MAXP))
    args = (sim.model.args, sim.state.args, sim.contacts.args)
    _pair_patches(p, tol, 1, *args, out)  # kept at these poses
    for f, expect in ((0.0, 1), (0.5, 1), (-0.9, 1), (2.0, 0)):
        sim.state.pos[...] = pos0
        sim.state.pos[1, 0] += f * tol  # the upper brick moved along its length
        out[...] = 0.0
        reused = _pair_patches(p, tol, 0, *args, out)
        assert reused == expect, f
        if not reused:
            continue
        a_full, r_full, pts_full = _resultants(out[0])
        a_kept, r_kept, pts_kept = _resultants(out[1])
        assert a_full > 1e-4 and r_full > 0  # a bearing joint
        shift = abs(f) * tol
        if f == 0.0:  # same poses, same polygon: the same patch, to round-off (the tail is
            # compiled twice and may be fused differently: 64 eps of the 0.1 m lengths)
            assert np.abs(out[0] - out[1]).max() <= 64 * np.finfo(float).eps * 0.1
        perimeter = 2 * (L + W)
        dmax = pts_full[:, 3].max()
        slope = 2 * dmax / W  # the gap falls from dmax to >= 0 across the patch (< W)
        # plus round-off: 64 eps of the area, and of the depths' 0.1 m lengths times the area
        roundoff = 64 * np.finfo(float).eps
        assert abs(a_kept - a_full) <= perimeter * shift + roundoff * a_full
        assert abs(r_kept - r_full) <= (perimeter * shift * dmax + a_full * slope * shift
                                        + roundoff * 0.1 * a_full)
        if f != 0.0:  # the kept polygon did differ (the bound is not met by identity)
            assert abs(a_kept - a_full) > roundoff * a_full
    sim.state.pos[...] = pos0


def test_end_to_end_error_is_bounded_by_the_tolerance():
    tol = 1e-7
    a, _ = _three_bricks(0.0)
    b, kept = _three_bricks(tol)
    assert kept >= 3
    assert np.abs(a - b).max() <= 0.26 * tol * 2
    # the beds matter far above it: the top brick sits below where a perfect one would
    assert abs(b[2, 2] - 1.5 * H) > 1e-4
