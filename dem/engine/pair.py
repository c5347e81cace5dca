"""Pair properties (Yade's Ip2): the constants of the joint law for one block pair.

The pair material record.  Every body has a material (``model.material``: an index into the
scene's material names, the table last); every ordered pair of materials has one record
(``model.mat_pair[a, b]``, symmetric), whose fields are named in :data:`PAIR_FIELDS`:

    mu           Coulomb friction coefficient, -
    kn           normal joint stiffness per unit area, Pa/m (the hyperbolic law: kn0, the
                 stiffness of the open joint at zero stress)
    ks           shear joint stiffness per unit area, Pa/m
    zeta         viscous contact damping, fraction of critical, -
    law          normal law: LINEAR (0) p = kn d, or HYPERBOLIC (1) p = kn0 d / (1 - d/d_max)
                 (dem.engine.laws)
    d_max        the hyperbolic law's largest closure, m (0 for the linear law)
    d_lim        the largest closure the time step is made for, m (hyperbolic: a fraction
                 ``closure_limit`` of d_max; beyond it the law goes on with the tangent at
                 d_lim and the run stops after the launch; 0 for the linear law)
    damping      the normal dashpot: CRITICAL (0) the fraction zeta of critical below, released
                 point by point (laws.normal_law); PAIR (1) the same dashpot, its pulls held
                 to the pair's pushes (laws.normal_law_pair_damped, laws.pull_scale);
                 STIFFNESS (2) beta k per unit area with the pair's rule (zeta then damps the
                 shear only)
    beta         the STIFFNESS dashpot's damping time, s (0 otherwise)

On the host the record is :class:`PairMaterial` (``Model.pair_material(a, b)``); a kernel reads it
by name through :func:`pair_material` (``pm.mu``, ``pm.kn`` ...), never by slot number, so that
adding a field cannot shift another's meaning (the same numbers reach the same operations as a
read by position, so the results are the same bit for bit).

From the pair's record and its contact area, the viscous coefficients per unit area that give the
pair a fraction zeta of critical damping (3DEC's contact damping; Cundall & Strack 1979):

    m_eff = 1 / (1/m_i + 1/m_j)                               [kg]
    cn = 2 zeta sqrt(k m_eff / A),   ct = 2 zeta sqrt(ks m_eff / A)      [N s / m^3]

with A the total area of the pair's contact points (m^2) and k = kn for the linear law, the
tangent stiffness kn0 / (1 - d/d_max)^2 at the pair's area-weighted mean closure d for the
hyperbolic one (so that zeta stays the fraction of critical as the joint stiffens); a point of
area a then gets the dashpots cn a and ct a (N s/m).  A STIFFNESS pair gets the normal
dashpot beta k a instead (k: kn, or the hyperbolic law's tangent at the pair's mean closure,
:func:`normal_stiffness_for_damping`), in the kernels compiled with ``beta_damping``
(dem.engine.step); PAIR and STIFFNESS pairs run in the kernels compiled with
``pair_damping``.  No damping for a pair without area or between
two fixed bodies.
"""


from dataclasses import astuple, dataclass, fields

import taichi as ti

from dem import ti_runtime

ti_runtime.quick_front_end()  # before this module's kernels are decorated

LINEAR, HYPERBOLIC = 0, 1
LAWS = {"linear": LINEAR, "hyperbolic": HYPERBOLIC}
CRITICAL, PAIR, STIFFNESS = 0, 1, 2
DAMPING_LAWS = {"critical": CRITICAL, "pair": PAIR, "stiffness": STIFFNESS}


@dataclass(frozen=True)
class PairMaterial:
    """The joint constants of one pair of materials (units in the module docstring)."""

    mu: float
    kn: float
    ks: float
    zeta: float
    law: int = LINEAR
    d_max: float = 0.0
    d_lim: float = 0.0
    damping: int = CRITICAL
    beta: float = 0.0

    def row(self) -> tuple[float, ...]:
        """The record as the row of ``model.mat_pair`` (order of PAIR_FIELDS)."""
        return tuple(float(v) for v in astuple(self))

    @classmethod
    def from_row(cls, row) -> "PairMaterial":
        vals = [float(v) for v in row]
        vals[PAIR_FIELDS.index("law")] = int(round(vals[PAIR_FIELDS.index("law")]))
        vals[PAIR_FIELDS.index("damping")] = int(round(vals[PAIR_FIELDS.index("damping")]))
        return cls(*vals)

    def stable_stiffness(self) -> float:
        """The largest normal stiffness per unit area the pair reaches within the closures the
        step is made for, Pa/m: kn (linear), kn0 / (1 - d_lim/d_max)^2 (hyperbolic)."""
        if self.law == HYPERBOLIC:
            return self.kn / (1.0 - self.d_lim / self.d_max) ** 2
        return self.kn


PAIR_FIELDS = tuple(f.name for f in fields(PairMaterial))
N_PAIR_FIELDS = len(PAIR_FIELDS)
# slots of the record in model.mat_pair (compile-time constants of the kernels)
_MU, _KN, _KS, _ZETA, _LAW, _DMAX, _DLIM, _DAMPING, _BETA = range(N_PAIR_FIELDS)


@ti.func
def pair_material(model: ti.template(), i, j):
    """The record of bodies i, j as a struct with the fields of PAIR_FIELDS."""
    r = model.mat_pair[model.material[i], model.material[j]]
    return ti.Struct(mu=r[_MU], kn=r[_KN], ks=r[_KS], zeta=r[_ZETA], law=r[_LAW],
                     d_max=r[_DMAX], d_lim=r[_DLIM], damping=r[_DAMPING], beta=r[_BETA])


@ti.func
def hyperbolic_tangent(kn0, d_max, d_lim, d):
    """Tangent stiffness of the hyperbolic law, Pa/m: kn0 / (1 - d/d_max)^2 at the closure d
    clipped to [0, d_lim] (beyond d_lim the law is continued with the tangent at d_lim)."""
    dd = ti.min(ti.max(d, 0.0), d_lim)
    r = 1.0 - dd / d_max
    return kn0 / (r * r)


@ti.func
def normal_stiffness_for_damping(kn, law, d_max, d_lim, depth_mean, hyperbolic: ti.template()):
    """The normal stiffness per unit area a pair's dashpots are made for, Pa/m: kn (linear),
    the hyperbolic tangent at the area-weighted mean closure depth_mean (m) in kernels compiled
    with ``hyperbolic``."""
    k = kn
    if ti.static(hyperbolic):
        if law == HYPERBOLIC:
            k = hyperbolic_tangent(kn, d_max, d_lim, depth_mean)
    return k


@ti.func
def pair_properties(model: ti.template(), i, j, area_tot, depth_mean,
                    hyperbolic: ti.template()):
    """Returns a struct (mu, kn, ks, cn_per_area, ct_per_area, law, d_max, d_lim) for bodies
    i, j whose contact points cover area_tot (m^2) at an area-weighted mean closure depth_mean
    (m; read by the hyperbolic law's damping only, in kernels compiled with ``hyperbolic``)."""
    pm = pair_material(model, i, j)
    kn_damp = pm.kn
    if ti.static(hyperbolic):
        if pm.law == HYPERBOLIC:
            kn_damp = hyperbolic_tangent(pm.kn, pm.d_max, pm.d_lim, depth_mean)
    inv_m = model.inv_mass[i] + model.inv_mass[j]
    cn_per_area = 0.0
    ct_per_area = 0.0
    if area_tot > 0.0 and inv_m > 0.0:
        m_eff = 1.0 / inv_m
        cn_per_area = 2.0 * pm.zeta * ti.sqrt(kn_damp * m_eff / area_tot)
        ct_per_area = 2.0 * pm.zeta * ti.sqrt(pm.ks * m_eff / area_tot)
    return ti.Struct(mu=pm.mu, kn=pm.kn, ks=pm.ks, cn_per_area=cn_per_area,
                     ct_per_area=ct_per_area, law=pm.law, d_max=pm.d_max, d_lim=pm.d_lim)
