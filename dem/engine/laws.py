"""Constitutive law of a dry joint at one contact point (pure ``@ti.func``, testable alone).

Joint stiffness is given per unit area, as in 3DEC: kn, ks in Pa/m (N/m^3).  A contact point
stands for a tributary area A (m^2, from :func:`dem.engine.geometry.polygon_quadrature`), so its
springs are kn*A and ks*A (N/m).

Normal (no tension, viscous term on closing rate; Cundall & Strack 1979, 3DEC manual):

    Fn = max(0, kn A d + cn ddot)                                  [N]

with d >= 0 the penetration (m) and ddot its rate (m/s, > 0 closing).

Shear (Coulomb with elastic stick, shear displacement kept per point across steps):

    u*  = rot(u_old) + v_t dt                 (u_old turned into the current contact plane,
                                                keeping its length)
    Ft* = -ks A u*                            (force on the second block, N)
    if |Ft*| >= mu Fn:  Ft = mu Fn Ft*/|Ft*|,  u = -Ft / (ks A)        (sliding)
    else:               Ft = Ft* - ct v_t  (capped at mu Fn),  u = u*  (sticking)

Damping coefficients cn, ct (N s/m) are fractions of critical of the pair, split over the points
in proportion to their area (see ``dem.engine.step``).  The returned dissipation (J) is the work
of the contact force that is not stored elastically in this step: friction when sliding, viscous
otherwise.
"""

import taichi as ti

from dem.engine.mathutil import vec3


@ti.func
def normal_law(kn_area, depth, depth_rate, cn):
    """Returns (elastic part kn A d, viscous part) of Fn = max(0, kn A d + cn ddot) (N).

    The viscous part is cut so that the sum never pulls (no tension).
    """
    f_el = kn_area * depth
    f_visc = ti.max(cn * depth_rate, -f_el)
    return f_el, f_visc


@ti.func
def rotate_into_plane(u, n):
    """Turn a stored shear displacement into the plane normal to n, keeping its length."""
    mag = u.norm()
    ut = u - u.dot(n) * n
    mt = ut.norm()
    res = vec3(0.0)
    if mt > 1e-300:
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
    mag = ft_el.norm()
    ft = vec3(0.0)
    u_new = u_trial
    sliding = 0
    if mag >= cap:
        sliding = 1
        if mag > 0.0:
            ft = ft_el * (cap / mag)
        u_new = vec3(0.0)
        if ks_area > 0.0:
            u_new = -ft / ks_area
    else:
        ft = ft_el - ct * v_t
        fm = ft.norm()
        if fm > cap:
            ft = ft * (cap / fm)
    # work not stored elastically: -(Ft . v_t) dt - (E_new - E_old), E = ks A |u|^2 / 2
    diss = -ft.dot(v_t) * dt - 0.5 * ks_area * (u_new.norm_sqr() - u_rot.norm_sqr())
    return ft, u_new, sliding, diss
