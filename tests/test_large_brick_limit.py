"""The rigid-block limit analysis of postprocess.block_limit against closed forms (it
explains the thesis' L/H = 2.5 large-brick walls).

Closed forms (load factor lambda = a/g, load along +x, blocks rigid, Coulomb joints):
* one block b x h on a rough base turns about its leeward toe at lambda = b/h (its weight's
  lever b/2 against the load's h/2); on a base of friction mu < b/h it slides at lambda = mu;
* a stack of n such blocks turns as one at b/(n h) (the centroid at n h / 2);
* a top block on a joint of friction mu slides off at lambda = mu whatever lies below it;
* mass drops out (every load is proportional to it).
The tolerances are those of the LP solver (1e-7 relative), not fitted.
"""

from __future__ import annotations

import numpy as np
import pytest

from postprocess.block_limit import (Blocks2D, interfaces, leeward_wedges, lp_limit,
                                     rotation_factor, upward_closure)

TOL = 1e-7  # HiGHS' feasibility tolerance is 1e-7; the closed forms are exact


@pytest.mark.parametrize("b,h", [(0.2, 1.0), (0.1, 0.05), (0.075, 0.05)])
def test_single_block_tips_at_b_over_h(b, h):
    bl = Blocks2D.from_boxes([[0.0, b, 0.0, h]])
    assert rotation_factor(bl, [0], (b, 0.0)) == pytest.approx(b / h, rel=1e-12)
    assert lp_limit(bl, mu=0.5, mu_base=10.0).load_factor == pytest.approx(b / h, rel=TOL)


def test_single_block_slides_at_the_base_friction():
    bl = Blocks2D.from_boxes([[0.0, 0.2, 0.0, 0.1]])  # b/h = 2 > mu_base
    assert lp_limit(bl, mu=0.3, mu_base=0.7).load_factor == pytest.approx(0.7, rel=TOL)


@pytest.mark.parametrize("n", [2, 3, 6])
def test_stack_of_n_blocks_tips_at_b_over_nh(n):
    b, h = 0.15, 0.05
    bl = Blocks2D.from_boxes([[0.0, b, k * h, (k + 1) * h] for k in range(n)])
    assert rotation_factor(bl, np.arange(n), (b, 0.0)) == pytest.approx(b / (n * h), rel=1e-12)
    assert lp_limit(bl, mu=10.0, mu_base=10.0).load_factor == pytest.approx(b / (n * h),
                                                                            rel=TOL)


def test_stack_slides_at_the_joint_friction_when_lower():
    b, h, n, mu = 0.15, 0.05, 3, 0.4  # b/(n h) = 1 > mu
    bl = Blocks2D.from_boxes([[0.0, b, k * h, (k + 1) * h] for k in range(n)])
    assert lp_limit(bl, mu=mu, mu_base=10.0).load_factor == pytest.approx(mu, rel=TOL)


def test_mass_and_direction_drop_out():
    boxes = [[0.0, 0.2, 0.0, 0.1], [0.1, 0.3, 0.1, 0.2], [0.2, 0.4, 0.0, 0.1]]
    a = lp_limit(Blocks2D.from_boxes(boxes, density=1.0), 0.6, 1.5).load_factor
    b = lp_limit(Blocks2D.from_boxes(boxes, density=1830.0), 0.6, 1.5).load_factor
    assert b == pytest.approx(a, rel=TOL)
    mirrored = [[-x1, -x0, z0, z1] for x0, x1, z0, z1 in boxes]
    c = lp_limit(Blocks2D.from_boxes(mirrored), 0.6, 1.5, direction=-1.0).load_factor
    assert c == pytest.approx(a, rel=TOL)


def test_fixed_support_and_interfaces():
    # a block on a fixed block: the bed between them is a joint (mu), not the base
    bl = Blocks2D.from_boxes([[0.0, 0.2, 0.0, 0.1], [0.0, 0.2, 0.1, 0.2]], fixed=[True, False])
    kinds = sorted(f.kind for f in interfaces(bl, 0.5, 1.5))
    assert kinds == ["bed"]
    assert lp_limit(bl, 0.5, 1.5).load_factor == pytest.approx(0.5, rel=TOL)
    assert lp_limit(bl, 5.0, 5.0).load_factor == pytest.approx(2.0, rel=TOL)  # b/h = 0.2/0.1


def test_upward_closure_and_the_half_bond_wedge():
    # two courses of a half bond: what rests on the leeward bottom block moves with it
    boxes = [[0, 2, 0, 1], [2, 4, 0, 1], [0, 1, 1, 2], [1, 3, 1, 2], [3, 4, 1, 2]]
    bl = Blocks2D.from_boxes(boxes)
    assert np.flatnonzero(upward_closure(bl, [1])).tolist() == [1, 3, 4]
    # the wedge of the top course's leeward half block alone: b/h = 1 about (4, 1)
    w = {(d["course"], d["crack_x0"]): d for d in leeward_wedges(bl)}
    assert w[(1, 3.0)]["load_factor"] == pytest.approx(1.0, rel=1e-12)
    # blocks 1, 3, 4 about (4, 0): weights 2, 2, 1 at levers 1, 2, 0.5 and heights 0.5, 1.5, 1.5
    assert w[(0, 2.0)]["load_factor"] == pytest.approx((2 + 4 + 0.5) / (1 + 3 + 1.5), rel=1e-12)
