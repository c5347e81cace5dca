"""Size scatter of builder bricks (dem.builders.scatter): the bricks are laid again on
their actual sizes without overlaps or floating blocks, with the drawn statistics."""

from __future__ import annotations

import numpy as np
import pytest

from dem.builders import Wing, build_box_model, build_facade, build_wall, check_scene
from dem.builders.scatter import scatter_sizes
from dem.imperfections import streams

SIGMA = [5e-4, 5e-4, 3e-4]  # m: L, W, H


def _scenes():
    return {"wall": build_wall("small", 9, 15),
            "facade": build_facade("small", 5, 9, left=Wing(3, "poor"), right=Wing(3, "strong")),
            "box II": build_box_model("II")}


@pytest.mark.parametrize("name", ["wall", "facade", "box II"])
@pytest.mark.parametrize("seed", [1, 3])
def test_scattered_layouts_pass_the_scene_checks(name, seed):
    """No overlap at all (tolerance 1 nm, not the default 0.1 mm: seed 3 overlapped 0.023 mm at
    a corner of Model II before the corner push) and nothing floating."""
    nominal = _scenes()[name]
    scene = scatter_sizes(nominal, SIGMA, streams(seed)[0])
    report = check_scene(scene, overlap_tolerance=1e-9)
    assert report.ok, report.format()
    dev = scene.size - nominal.size
    assert np.abs(dev).max() <= 3 * max(SIGMA) + 1e-15
    assert np.allclose(scene.mass / nominal.mass, np.prod(scene.size / nominal.size, axis=1))


def test_the_draws_have_the_asked_deviations():
    """Sample standard deviation of n deviations of a normal truncated at 3 sigma: its own sigma
    is 0.9866 sigma, and the standard error of a std estimate is about sigma / sqrt(2 n): four
    standard errors around it (n = 142 blocks of the 9 x 15 wall per edge)."""
    nominal = build_wall("small", 9, 15)
    scene = scatter_sizes(nominal, SIGMA, streams(2)[0])
    dev = scene.size - nominal.size  # the wall runs along x: L on x, W on y, H on z
    n = nominal.n_blocks
    for axis, sigma in enumerate(SIGMA):
        expected = 0.9866 * sigma
        assert dev[:, axis].std() == pytest.approx(expected, abs=4 * expected / np.sqrt(2 * n))


def test_courses_sit_on_the_actual_tops_and_head_joints_close():
    nominal = build_wall("small", 5, 6)
    scene = scatter_sizes(nominal, SIGMA, streams(3)[0])
    lo = scene.position - 0.5 * scene.size
    hi = scene.position + 0.5 * scene.size
    lo0 = nominal.position - 0.5 * nominal.size
    hi0 = nominal.position + 0.5 * nominal.size
    for b in range(scene.n_blocks):
        if scene.course[b] == 0:
            assert lo[b, 2] == 0.0
            continue
        below = (np.abs(hi0[:, 2] - lo0[b, 2]) < 1e-9) & (
            np.minimum(hi[:, 0], hi[b, 0]) - np.maximum(lo[:, 0], lo[b, 0]) > 1e-9)
        assert lo[b, 2] == pytest.approx(hi[below, 2].max(), abs=1e-12)
        left = (np.abs(hi0[:, 0] - lo0[b, 0]) < 1e-9) & (scene.course == scene.course[b])
        if left.any():
            assert lo[b, 0] == pytest.approx(hi[left, 0].max(), abs=1e-12)


def test_seed_and_zero_sigma():
    nominal = build_box_model("II")
    a = scatter_sizes(nominal, SIGMA, streams(5)[0])
    b = scatter_sizes(nominal, SIGMA, streams(5)[0])
    c = scatter_sizes(nominal, SIGMA, streams(6)[0])
    assert np.array_equal(a.size, b.size) and np.array_equal(a.position, b.position)
    assert not np.array_equal(a.size, c.size)
    zero = scatter_sizes(nominal, [0.0, 0.0, 0.0], streams(5)[0])
    for name in ("size", "position", "mass"):
        assert np.array_equal(getattr(zero, name), getattr(nominal, name))


def test_bridging_bricks_are_counted_in_one_line_and_a_real_overhang_is_still_named():
    """A scattered wall: the bricks resting on the higher of the two bricks they bridge (centre
    of mass outside that one support) rock onto the lower one while settling; with the landing
    within 6 sigma counted they are one line, not one warning each.  A top brick of a perfect
    wall pushed three quarters of its length past the wall's end has nothing to land on within
    that gap: named as before."""
    from dem.builders.checks import block_label

    scene = scatter_sizes(build_wall("small", 9, 15), SIGMA, streams(3)[0])
    plain = check_scene(scene, max_listed=1000).warnings
    assert len(plain) > 10 and all("will tip" in w for w in plain)
    grouped = check_scene(scene, max_listed=1000, settle_gap=6 * max(SIGMA)).warnings
    assert len(grouped) == 1 and grouped[0].startswith(f"{len(plain)} blocks bridge")
    nominal = build_wall("small", 9, 15)  # the overhang on flat beds: it stays supported
    course = np.flatnonzero(nominal.course == nominal.course.max())
    top = int(course[np.argmax(nominal.position[course, 0])])  # the top course's end brick (+x)
    nominal.position[top, 0] += 0.75 * nominal.size[top, 0]  # centre a quarter length past the end
    named = check_scene(nominal, max_listed=1000, settle_gap=6 * max(SIGMA)).warnings
    assert f"{block_label(nominal, top)}: centre of mass outside its support, it will tip" in named
