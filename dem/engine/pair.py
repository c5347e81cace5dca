"""Pair properties (Yade's Ip2): the constants of the joint law for one block pair.

From the materials of the two bodies (``model.mat_pair``: friction mu, normal and shear joint
stiffness kn, ks per unit area in Pa/m, damping ratio zeta) and the pair's contact area, the
viscous coefficients per unit area that give the pair a fraction zeta of critical damping
(3DEC's contact damping; Cundall & Strack 1979):

    m_eff = 1 / (1/m_i + 1/m_j)                               [kg]
    cn = 2 zeta sqrt(kn m_eff / A),   ct = 2 zeta sqrt(ks m_eff / A)      [N s / m^3]

with A the total area of the pair's contact points (m^2); a point of area a then gets the dashpots
cn a and ct a (N s/m).  No damping for a pair without area or between two fixed bodies.
"""

import taichi as ti


@ti.func
def pair_properties(model: ti.template(), i, j, area_tot):
    """Returns a struct (mu, kn, ks, cn_per_area, ct_per_area) for bodies i, j whose contact
    points cover area_tot (m^2)."""
    mp = model.mat_pair[model.material[i], model.material[j]]
    mu = mp[0]
    kn = mp[1]
    ks = mp[2]
    zeta = mp[3]
    inv_m = model.inv_mass[i] + model.inv_mass[j]
    cn_per_area = 0.0
    ct_per_area = 0.0
    if area_tot > 0.0 and inv_m > 0.0:
        m_eff = 1.0 / inv_m
        cn_per_area = 2.0 * zeta * ti.sqrt(kn * m_eff / area_tot)
        ct_per_area = 2.0 * zeta * ti.sqrt(ks * m_eff / area_tot)
    return ti.Struct(mu=mu, kn=kn, ks=ks, cn_per_area=cn_per_area, ct_per_area=ct_per_area)
