"""Constitutive law of a dry joint at one contact point (pure ``@ti.func``, testable alone).

Joint stiffness is given per unit area, as in 3DEC: kn, ks in Pa/m (N/m^3).  A contact point
stands for a tributary area A (m^2, from :func:`dem.engine.geometry.polygon_quadrature`), so its
springs are kn*A and ks*A (N/m).

Normal (no tension, viscous term on closing rate; Cundall & Strack 1979, 3DEC manual):

    Fn = max(0, kn A d + cn ddot)                                  [N]

with d >= 0 the penetration (m) and ddot its rate (m/s, > 0 closing).

Hyperbolic normal law (``material.normal_law: hyperbolic``; the joint closure law of Bandis,
Lumsden & Barton 1983, Int. J. Rock Mech. Min. Sci. 20:249, used for rock joints in UDEC/3DEC):
a dry joint is soft at low stress and stiffens as it closes towards a largest closure d_max,

    p(d)  = kn0 d / (1 - d/d_max)                       [Pa]   pressure at closure d (m)
    kt(d) = dp/dd = kn0 / (1 - d/d_max)^2               [Pa/m] tangent stiffness
    e(d)  = int_0^d p = -kn0 d_max (d + d_max ln(1 - d/d_max))     [J/m^2] stored energy

kn0 (Pa/m) the stiffness of the unloaded joint.  Inverse: d(p) = p / (kn0 + p/d_max).  The time
step is made for closures up to d_lim < d_max (``material.closure_limit`` x d_max); beyond d_lim
the law goes on along its tangent at d_lim, p = p(d_lim) + kt(d_lim)(d - d_lim) (energy
e(d_lim) + p(d_lim)(d - d_lim) + kt(d_lim)(d - d_lim)^2 / 2: the force is still the derivative
of the energy), so the step stays stable, and the simulation stops the run after the launch
(dem.engine.simulation): the results past d_lim are not the hyperbolic law's.

Shear (Coulomb with elastic stick, shear displacement kept per point across steps):

    u*  = rot(u_old) + v_t dt                 (u_old turned into the current contact plane,
                                                keeping its length)
    Ft* = -ks A u*                            (force on the second block, N)
    if |Ft*| >= mu Fn:  Ft = mu Fn Ft*/|Ft*|,  u = -Ft / (ks A)        (sliding)
    else:               Ft = Ft* - ct v_t  (capped at mu Fn),  u = u*  (sticking)

Damping coefficients cn, ct (N s/m) are fractions of critical of the pair, split over the points
in proportion to their area (see ``dem.engine.step``).  With ``material.normal_damping: pair``
or ``stiffness`` the no-tension rule of the dashpots is the pair's, not the point's
(:func:`normal_law_pair_damped`, :func:`pull_scale`); ``stiffness`` also makes the normal
dashpot beta k A (beta in s).  The returned dissipation (J) is the work
of the contact force that is not stored elastically in this step: friction when sliding, viscous
otherwise.
"""

import taichi as ti

from dem import ti_runtime
from dem.engine.mathutil import vec3

ti_runtime.quick_front_end()  # before this module's kernels are decorated


@ti.func
def normal_law(kn_area, depth, depth_rate, cn):
    """Returns (elastic part kn A d, viscous part cn ddot) of the normal force (N), both zero
    when their sum would pull (no tension: the point is released).

    The two parts act at different points (elastic at the quadrature point, viscous at the
    polygon vertex, see dem.engine.step), so they are released together: cutting only the
    viscous part to -kn A d would leave a couple with no net force, a torque from nothing.
    """
    f_el = kn_area * depth
    f_visc = cn * depth_rate
    if f_el + f_visc <= 0.0:
        f_el = 0.0
        f_visc = 0.0
    return f_el, f_visc


@ti.func
def normal_law_pair_damped(f_el, c, depth_rate, pull_scale):
    """Normal force of a point whose dashpot follows the pair's no-tension rule: (elastic
    part, viscous part) in N.

        f_visc = c ddot          closing (ddot > 0): pushes                          [N]
        f_visc = s c ddot        opening (ddot < 0): holds back the opening           [N]

    f_el: the elastic force of the point (N: kn A d, or A p(d) for the hyperbolic law);
    c: the point's dashpot (N s/m): the fraction zeta of the pair's critical value,
    cn A = 2 zeta sqrt(k m_eff / A_pair) A (``material.normal_damping: pair``), or the
    stiffness-proportional beta k A (``stiffness``: Rayleigh's beta damping of the joint, each
    joint mode of frequency omega getting zeta = beta omega / 2; the contact damping 3DEC's
    users give rocking blocks, Vlachakis, Giouvanidis, Mehrotra & Lourenco 2021, J. Eng. Mech.
    147(11) 04021089); depth_rate: ddot (m/s, > 0 closing), read at the polygon vertex behind
    the point; s = pull_scale in [0, 1] (:func:`pull_scale`).

    :func:`normal_law` releases a point (both parts 0) as soon as its own dashpot would pull
    harder than its spring pushes.  Here the no-tension rule is the pair's: an opening
    dashpot keeps holding back while the joint as a whole still pushes, sum over the pair's
    points of (f_el + f_visc) >= 0 (a point's net force may then be negative: the part of a
    joint that unloads while the rest is compressed is held by its dashpots).  Why: with
    compressive point forces only, a slender rigid block rocking onto a new edge keeps at
    least Housner's rebound (every such force acts inside the new pivot and adds to the
    angular momentum about it; docs/engine.md section 6), whereas blocks on rigid bases
    measure less (ElGawady et al. 2011, Earthquake Eng. Struct. Dyn. 40:375); the held
    unloading of the slap's far side takes that angular momentum.

    Energy: every dashpot opposes its own normal rate, f_visc ddot >= 0 (its power is
    dissipated, never supplied, also when held: s >= 0), the elastic part is the spring's, and
    the pair never pulls its blocks together (its total normal force is >= 0)."""
    f_visc = c * depth_rate
    if f_visc < 0.0:
        f_visc *= pull_scale
    return f_el + 0.0, f_visc


@ti.func
def pull_scale(push, pull):
    """The factor s in [0, 1] on the opening dashpots of a pair (N): push >= 0 the sum of its
    points' elastic forces and closing dashpots, pull <= 0 the sum of its opening dashpots;
    s = 1 unless the pulls would exceed the pushes, then s = push / (-pull), so that the pair's
    normal force push + s pull >= 0 (:func:`normal_law_pair_damped`)."""
    s = 1.0
    if push + pull < 0.0:
        s = push / (-pull)
    return s


@ti.func
def hyperbolic_pressure(kn0, d_max, d_lim, d):
    """Pressure of the hyperbolic law at closure d (Pa), continued along the tangent beyond
    d_lim (module docstring); 0 for d <= 0."""
    dd = ti.min(ti.max(d, 0.0), d_lim)
    r = 1.0 - dd / d_max
    p = kn0 * dd / r
    if d > d_lim:
        p += kn0 / (r * r) * (d - d_lim)
    return p


@ti.func
def hyperbolic_energy(kn0, d_max, d_lim, d):
    """Energy per unit joint area stored at closure d (J/m^2): the integral of
    :func:`hyperbolic_pressure` from 0 to d.  e = kn0 d_max^2 (-x - ln(1 - x)), x = d/d_max;
    below x = 0.05 by its series x^2/2 + x^3/3 + ... + x^14/14 (the difference of logarithms
    would lose ~x^-1 of the digits; the series' first dropped term is below 1e-15 of the sum)."""
    dd = ti.min(ti.max(d, 0.0), d_lim)
    x = dd / d_max
    f = 0.0
    if x < 0.05:
        xk = x
        for k in ti.static(range(2, 15)):
            xk *= x
            f += xk / k
    else:
        f = -x - ti.log(1.0 - x)
    e = kn0 * d_max * d_max * f
    if d > d_lim:
        r = 1.0 - x
        s = d - d_lim
        e += kn0 * dd / r * s + 0.5 * kn0 / (r * r) * s * s
    return e


@ti.func
def normal_law_hyperbolic(area, kn0, d_max, d_lim, depth, depth_rate, cn):
    """:func:`normal_law` for the hyperbolic law: (elastic part A p(d), viscous part cn ddot)
    (N), both zero when their sum would pull."""
    f_el = area * hyperbolic_pressure(kn0, d_max, d_lim, depth)
    f_visc = cn * depth_rate
    if f_el + f_visc <= 0.0:
        f_el = 0.0
        f_visc = 0.0
    return f_el, f_visc


@ti.func
def rotate_into_plane(u, n):
    """Turn a stored shear displacement into the plane normal to n, keeping its length.

    A displacement (nearly) along n has no in-plane direction to keep: its projection is then
    round-off, which must not be blown up to the full length (it would point along n), so the
    history is dropped (zero) when the projection is below 1e-12 of the length."""
    mag = u.norm()
    ut = u - u.dot(n) * n
    mt = ut.norm()
    res = vec3(0.0)
    if mt > 1e-12 * mag:
        res = ut * (mag / mt)
    return res


@ti.func
def coulomb_shear(u_old, n, v_t, dt, ks_area, ct, mu, fn):
    """Returns (Ft on the second block (N), new shear displacement (m), sliding flag, dissipation J).

    v_t: tangential velocity of the second block relative to the first at the point (m/s).
    """
    u_rot = rotate_into_plane(u_old, n)
    u_trial = u_rot + v_t * dt
    ft_el = -ks_area * u_trial
    cap = mu * fn
    cap2 = cap * cap  # the tests compare squares (cap >= 0): no square root while sticking
    mag2 = ft_el.norm_sqr()
    ft = vec3(0.0)
    u_new = u_trial
    sliding = 0
    if mag2 >= cap2:
        sliding = 1
        scale = 0.0  # Ft = scale Ft*, u = -Ft / (ks A) = scale u*
        if mag2 > 0.0:
            scale = cap / ti.sqrt(mag2)
        ft = ft_el * scale
        u_new = u_trial * scale
    else:
        ft = ft_el - ct * v_t
        fm2 = ft.norm_sqr()
        if fm2 > cap2:
            ft = ft * (cap / ti.sqrt(fm2))
    # work not stored elastically: -(Ft . v_t) dt - (E_new - E_old), E = ks A |u|^2 / 2
    diss = -ft.dot(v_t) * dt - 0.5 * ks_area * (u_new.norm_sqr() - u_rot.norm_sqr())
    return ft, u_new, sliding, diss
