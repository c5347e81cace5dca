"""Area caps of the critical-step bound (dem.engine.timestep.face_area_caps): a light block with a
large face gets the smallest cap that keeps the step stable even if it later touches with whole
faces, never below its patch at the start."""

import numpy as np

from dem.engine.timestep import omega2_bound, face_area_caps, full_face_areas

KN, KS, SAFETY = 5e9, 2e9, 0.3
BRICK = [0.105, 0.05, 0.035]
BEAM = [0.03, 0.525, 0.02]  # the box models' timber roof beam, 0.158 kg


def _scene(n_bricks=20):
    size = np.array([BRICK] * n_bricks + [BEAM])
    mass = np.array([0.336] * n_bricks + [0.158])
    inertia = mass[:, None] / 12 * np.stack([size[:, 1] ** 2 + size[:, 2] ** 2,
                                             size[:, 0] ** 2 + size[:, 2] ** 2,
                                             size[:, 0] ** 2 + size[:, 1] ** 2], axis=1)
    return size, mass, inertia, np.ones(len(size), bool)


def _ratio(size, mass, inertia, cap):
    full = full_face_areas(size)
    w_full = omega2_bound(size, mass, inertia, full, KN, KS)
    w_cap = omega2_bound(size, mass, inertia, np.minimum(full, cap), KN, KS)
    return w_full / w_cap


def test_beam_cap_is_the_smallest_that_keeps_the_stability_margin():
    """The beam's cap sits where the full-face bound is exactly 0.5 / safety^2 times the capped
    one (the margin that keeps the step stable whatever the beam touches), to the bisection's
    resolution; bricks stay uncapped."""
    size, mass, inertia, movable = _scene()
    patch = np.full(len(size), 0.0015)  # 30 x 50 mm end patches
    face, cap = face_area_caps(size, mass, inertia, movable, KN, KS, SAFETY, patch)
    assert not np.isfinite(cap[:-1]).any()
    c = cap[-1]
    assert patch[-1] < c < BRICK[0] * BRICK[1]
    limit = 0.5 / SAFETY**2
    b = slice(len(size) - 1, None)
    assert _ratio(size[b], mass[b], inertia[b], c)[0] <= limit * (1 + 1e-9)
    assert _ratio(size[b], mass[b], inertia[b], c * (1 - 1e-6))[0] > limit
    assert np.array_equal(face[-1], np.minimum(full_face_areas(size[b])[0], c))


def test_cap_never_below_the_patch_at_the_start():
    """A beam already touching over a larger patch than the smallest allowed cap keeps that
    patch as its cap (it would otherwise be raised at the first step)."""
    size, mass, inertia, movable = _scene()
    big = 0.004
    _, cap = face_area_caps(size, mass, inertia, movable, KN, KS, SAFETY,
                            np.full(len(size), big))
    assert cap[-1] == big


def test_tighter_cap_lifts_the_beam_limited_step():
    """With the old cap (the typical face) the beam set the scene's step; with the tightened one
    the step is that of the bricks' bound or of the beam at its stability margin, whichever is
    smaller, and larger than before."""
    size, mass, inertia, movable = _scene()
    old_face = np.minimum(full_face_areas(size), BRICK[0] * BRICK[1])
    w_old = omega2_bound(size, mass, inertia, old_face, KN, KS)
    face, _ = face_area_caps(size, mass, inertia, movable, KN, KS, SAFETY,
                             np.full(len(size), 0.0015))
    w_new = omega2_bound(size, mass, inertia, face, KN, KS)
    assert np.argmax(w_old) == len(size) - 1  # the beam set the step
    assert w_new.max() < w_old.max()
    np.testing.assert_array_equal(w_new[:-1], w_old[:-1])
