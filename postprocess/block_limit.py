"""Limit analysis of a wall of rigid, axis-aligned blocks under an in-plane lateral load (the
tilting table, thesis Chapter 3), on the exact blocks a scene holds.

Units: m, kg; forces in units of weight (kg x g), so g drops out.  The table frame: z up, the
lateral load along +x (a tilt about +y puts it there, dem.loading.Tilt.load_direction); the load
factor lambda = a/g = tan(tilt angle) (thesis Section 3.3.4).  Every block carries its weight
W = m (down, -z) and the lateral load lambda W (+x) at its centroid.

Two analyses, both in the x-z plane (the in-plane projection of the 3D blocks):

1. ``lp_limit``: the rigid-block, no-tension, Coulomb limit analysis as a linear programme
   (Livesley 1978; Gilbert and Melbourne 1994, "Rigid-block analysis of masonry structures",
   Struct. Eng. 72(21)).  Every interface between two touching blocks (or a block and the table)
   is a segment in x-z; at each of its two ends a normal force n >= 0 (no tension) and a shear
   force t with |t| <= mu n (associative Coulomb; base interfaces use the base friction).  Two
   end forces represent any compressive stress distribution along the segment.  Each movable
   block is in equilibrium (x, z and the moment about y):

       sum_contacts (n n_hat + t t_hat) + W (lambda e_x - e_z) = 0,
       sum_contacts r x (n n_hat + t t_hat) = 0      (r from the block's centroid)

   and the programme maximises lambda.  Its optimum is the largest load factor at which ANY
   statically admissible set of contact forces exists; above it no rigid-block equilibrium
   exists, whatever the flow rule (a non-associative, i.e. real, Coulomb joint can only collapse
   earlier).  The projection loses nothing that could make the 3D wall stronger in plane: every
   3D equilibrium projects onto a 2D one (|t_x| <= |t| <= mu n), so this optimum is an upper
   bound on the 3D rigid-block capacity.  The duals of the equilibrium rows are the collapse
   mechanism (block velocities u, w and spin omega, up to a factor).

2. ``rotation_factor``: the kinematic load factor of one rigid portion P turning about a pivot
   (x_p, z_p) (the toe of its lowest leeward block), the rest fixed:

       lambda_rot = sum_{i in P} W_i (x_p - x_i) / sum_{i in P} W_i (z_i - z_p)

   (virtual work: the lateral load's power lambda W_i (z_i - z_p) omega against the weights'
   W_i (x_p - x_i) omega).  For a single block of width b and height h on its toe this is b/h;
   for a stack of n such blocks b/(n h).  ``upward_closure`` gives the smallest portion that can
   turn rigidly about its toe without lifting a block that stays behind: every block resting on
   a moving block moves (a fixed block above a rotating one would have to be lifted).

The thesis' eq 3-2 (postprocess.limit_analysis) is the same virtual work on a continuum wedge
whose stepped crack runs from the leeward bottom corner at the bond angle tan(alpha_b) = s/h.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

TOUCH_TOL = 1e-4   # m: faces closer than this touch (the builders leave exact contacts)
MIN_OVERLAP = 1e-4  # m: an interface shorter than this is not one


@dataclass
class Blocks2D:
    """Axis-aligned blocks: ``lo``, ``hi`` [N,3] corners (m), ``mass`` [N] (kg), ``fixed`` [N]."""

    lo: np.ndarray
    hi: np.ndarray
    mass: np.ndarray
    fixed: np.ndarray

    @property
    def n(self) -> int:
        return len(self.mass)

    @property
    def centroid(self) -> np.ndarray:
        return 0.5 * (self.lo + self.hi)

    @classmethod
    def from_boxes(cls, boxes, mass=None, fixed=None, density=1.0) -> "Blocks2D":
        """boxes: rows (x0, x1, z0, z1) [, y0, y1]; mass defaults to density x area (x depth)."""
        b = np.atleast_2d(np.asarray(boxes, float))
        if b.shape[1] == 4:
            b = np.hstack([b, np.tile([-0.5, 0.5], (len(b), 1))])
        lo = np.stack([b[:, 0], b[:, 4], b[:, 2]], axis=1)
        hi = np.stack([b[:, 1], b[:, 5], b[:, 3]], axis=1)
        m = (density * np.prod(hi - lo, axis=1) if mass is None
             else np.asarray(mass, float).reshape(-1))
        f = np.zeros(len(b), bool) if fixed is None else np.asarray(fixed, bool)
        return cls(lo, hi, m, f)

    @classmethod
    def from_scene(cls, scene) -> "Blocks2D":
        """The blocks of a dem.scene.Scene (axis-aligned ones only)."""
        from dem.builders.checks import vertices

        v = vertices(scene)
        return cls(v.min(axis=1), v.max(axis=1), np.asarray(scene.mass, float),
                   np.asarray(scene.fixed, bool))


@dataclass
class Interface:
    """A contact segment: body ``a`` (index, or -1 for the table) below / windward of body
    ``b``; the force on b is +(n n_hat + t t_hat), on a its opposite.  ``p`` [2,2]: the two
    ends (x, z); ``normal``: unit (x, z) from a to b."""

    a: int
    b: int
    p: np.ndarray
    normal: np.ndarray
    mu: float
    kind: str  # "bed" | "head" | "base"


def interfaces(blocks: Blocks2D, mu: float, mu_base: float, head_gap: float = TOUCH_TOL,
               table: bool = True, mu_head: float | None = None) -> list[Interface]:
    """Every touching pair's interface in x-z.  Bed joints: top of a within TOUCH_TOL of the
    bottom of b, overlapping in x and y; head joints: the +x face of a within ``head_gap`` of the
    -x face of b, overlapping in z and y (a gap up to head_gap counts as closed); base: a
    block's bottom on the table (z = 0).  ``mu_head``: friction of the head joints (default
    mu; 0: frictionless, as the thesis' eq 3-2 takes the crack; a negative value leaves the head
    joints out, so blocks push on each other through their beds only)."""
    mu_head = mu if mu_head is None else mu_head
    lo, hi = blocks.lo, blocks.hi
    out: list[Interface] = []
    for i in range(blocks.n):
        if table and abs(lo[i, 2]) < TOUCH_TOL and not blocks.fixed[i]:
            out.append(Interface(-1, i, np.array([[lo[i, 0], 0.0], [hi[i, 0], 0.0]]),
                                 np.array([0.0, 1.0]), mu_base, "base"))
    for i in range(blocks.n):
        for j in range(blocks.n):
            if i == j or (blocks.fixed[i] and blocks.fixed[j]):
                continue
            oy = min(hi[i, 1], hi[j, 1]) - max(lo[i, 1], lo[j, 1])
            if oy <= MIN_OVERLAP:
                continue
            if abs(hi[i, 2] - lo[j, 2]) < TOUCH_TOL:
                x0, x1 = max(lo[i, 0], lo[j, 0]), min(hi[i, 0], hi[j, 0])
                if x1 - x0 > MIN_OVERLAP:
                    z = 0.5 * (hi[i, 2] + lo[j, 2])
                    out.append(Interface(i, j, np.array([[x0, z], [x1, z]]),
                                         np.array([0.0, 1.0]), mu, "bed"))
            gap = lo[j, 0] - hi[i, 0]
            if mu_head >= 0 and -TOUCH_TOL < gap < head_gap:
                z0, z1 = max(lo[i, 2], lo[j, 2]), min(hi[i, 2], hi[j, 2])
                if z1 - z0 > MIN_OVERLAP:
                    x = 0.5 * (hi[i, 0] + lo[j, 0])
                    out.append(Interface(i, j, np.array([[x, z0], [x, z1]]),
                                         np.array([1.0, 0.0]), mu_head, "head"))
    return out


@dataclass
class LPResult:
    load_factor: float
    status: str
    velocity: np.ndarray | None   # [N,3]: u, w (m per unit), omega (rad per unit); fixed: 0
    n_interfaces: int

    def moving(self, rel: float = 0.05) -> np.ndarray:
        """Blocks whose largest point speed exceeds ``rel`` of the fastest block's."""
        if self.velocity is None:
            return np.zeros(0, bool)
        s = np.linalg.norm(self.velocity[:, :2], axis=1) + 0.0
        return s > rel * max(s.max(), 1e-300)


def lp_limit(blocks: Blocks2D, mu: float, mu_base: float, head_gap: float = TOUCH_TOL,
             direction: float = 1.0, mu_head: float | None = None) -> LPResult:
    """The largest lambda with statically admissible contact forces (module docstring, 1);
    ``mu_head`` as in ``interfaces``."""
    from scipy.optimize import linprog
    from scipy.sparse import lil_matrix

    ifs = interfaces(blocks, mu, mu_base, head_gap, mu_head=mu_head)
    movable = np.flatnonzero(~blocks.fixed)
    row = {b: 3 * k for k, b in enumerate(movable)}
    n_if = len(ifs)
    nv = 4 * n_if + 1  # per interface: n1, n2, t1, t2; then lambda
    a_eq = lil_matrix((3 * len(movable), nv))
    b_eq = np.zeros(3 * len(movable))
    a_ub = lil_matrix((4 * n_if, nv))
    c = blocks.centroid[:, [0, 2]]
    for k, f in enumerate(ifs):
        nh, th = f.normal, np.array([-f.normal[1], f.normal[0]])
        for e in range(2):
            jn, jt = 4 * k + e, 4 * k + 2 + e
            for body, sign in ((f.b, 1.0), (f.a, -1.0)):
                if body < 0 or blocks.fixed[body]:
                    continue
                r = f.p[e] - c[body]
                rr = row[body]
                for col, vec in ((jn, nh), (jt, th)):
                    a_eq[rr, col] += sign * vec[0]
                    a_eq[rr + 1, col] += sign * vec[1]
                    a_eq[rr + 2, col] += sign * (r[0] * vec[1] - r[1] * vec[0])
            a_ub[4 * k + 2 * e, jt] = 1.0
            a_ub[4 * k + 2 * e, jn] = -f.mu
            a_ub[4 * k + 2 * e + 1, jt] = -1.0
            a_ub[4 * k + 2 * e + 1, jn] = -f.mu
    for b, rr in row.items():
        w = blocks.mass[b]
        a_eq[rr, nv - 1] = direction * w   # lateral load lambda W along direction * e_x
        b_eq[rr + 1] = w                   # contact forces carry the weight
    bounds = [(0, None), (0, None), (None, None), (None, None)] * n_if + [(None, None)]
    cost = np.zeros(nv)
    cost[-1] = -1.0
    res = linprog(cost, A_ub=a_ub.tocsr(), b_ub=np.zeros(4 * n_if), A_eq=a_eq.tocsr(),
                  b_eq=b_eq, bounds=bounds, method="highs")
    if res.status != 0:
        return LPResult(float("nan"), res.message, None, n_if)
    vel = np.zeros((blocks.n, 3))
    y = np.asarray(res.eqlin.marginals)
    for b, rr in row.items():
        vel[b] = y[rr:rr + 3]
    vel *= -direction  # sign: the mechanism moves with the load
    return LPResult(float(res.x[-1]), "optimal", vel, n_if)


def rotation_factor(blocks: Blocks2D, portion, pivot) -> float:
    """lambda_rot of ``portion`` (bool [N] or indices) turning about ``pivot`` (x_p, z_p)."""
    idx = np.flatnonzero(np.asarray(portion)) if np.asarray(portion).dtype == bool \
        else np.asarray(portion, int)
    m = blocks.mass[idx]
    c = blocks.centroid[idx]
    return float(m @ (pivot[0] - c[:, 0]) / (m @ (c[:, 2] - pivot[1])))


def upward_closure(blocks: Blocks2D, seed) -> np.ndarray:
    """bool [N]: ``seed`` and every block resting (directly or through others) on it."""
    moving = np.zeros(blocks.n, bool)
    moving[np.asarray(seed, int)] = True
    lo, hi = blocks.lo, blocks.hi
    changed = True
    while changed:
        changed = False
        for j in np.flatnonzero(~moving & ~blocks.fixed):
            below = moving & (np.abs(hi[:, 2] - lo[j, 2]) < TOUCH_TOL) \
                & (np.minimum(hi[:, 0], hi[j, 0]) - np.maximum(lo[:, 0], lo[j, 0]) > MIN_OVERLAP) \
                & (np.minimum(hi[:, 1], hi[j, 1]) - np.maximum(lo[:, 1], lo[j, 1]) > MIN_OVERLAP)
            if below.any():
                moving[j] = True
                changed = True
    return moving


def leeward_wedges(blocks: Blocks2D) -> list[dict]:
    """The rotation mechanisms 'leeward portion cut off by a stepped crack through the head
    joints, turning about its leeward toe': for every course k and every head joint x_j of that
    course, the seed = the blocks of course k from x_j to the leeward (+x) end, its upward
    closure the portion, its pivot (x_max, bottom of course k).  Blocks below course k do not
    move (the portion rests on them)."""
    lo, hi = blocks.lo, blocks.hi
    x_end = hi[:, 0].max()
    bottoms = np.unique(np.round(lo[:, 2], 6))
    out = []
    for k, zb in enumerate(bottoms):
        course = np.flatnonzero((np.abs(lo[:, 2] - zb) < TOUCH_TOL) & ~blocks.fixed)
        starts = np.unique(np.round(lo[course, 0], 6))
        for x0 in starts:
            seed = course[lo[course, 0] >= x0 - TOUCH_TOL]
            portion = upward_closure(blocks, seed)
            pivot = np.array([x_end, zb])
            out.append({"course": k, "crack_x0": float(x0), "pivot": pivot.tolist(),
                        "n_blocks": int(portion.sum()),
                        "mass_share": float(blocks.mass[portion].sum()
                                            / blocks.mass[~blocks.fixed].sum()),
                        "load_factor": rotation_factor(blocks, portion, pivot),
                        "blocks": np.flatnonzero(portion).tolist()})
    return sorted(out, key=lambda d: d["load_factor"])


def crack_profile(blocks: Blocks2D, portion) -> list[float]:
    """Per course (bottom up), the windward-most x of the portion's blocks (nan if none)."""
    portion = np.asarray(portion, bool)
    bottoms = np.unique(np.round(blocks.lo[:, 2], 6))
    out = []
    for zb in bottoms:
        sel = portion & (np.abs(blocks.lo[:, 2] - zb) < TOUCH_TOL)
        out.append(float(blocks.lo[sel, 0].min()) if sel.any() else float("nan"))
    return out
