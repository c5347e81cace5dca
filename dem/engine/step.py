"""One time step as a short list of named stages, and the two kernels that run it.

    for each step:
        contact_stage    narrow phase + joint law for every pair of the neighbour list
                         (writes Contacts: points, forces, shear history, per-pair wrench)
        integrate_stage  loads (gravity, base acceleration) + gathered contact wrenches,
                         then symplectic Euler: v += dt F/m, L += dt T, x += dt v, and the
                         free rotation by splitting (writes State); flags a neighbour-list
                         rebuild or a bad state

The broad phase (neighbour list) runs on the host between kernel launches, when a body has moved
more than half the skin (see :mod:`dem.engine.broadphase`).

Two kernels run the same stages:
- :func:`advance_serial` runs many steps in one launch on one thread (a launch costs ~0.35 ms
  on the 2-core test machine, mostly Taichi's handling of the 35 array arguments: about three
  steps of a 150-block wall);
- :func:`advance_parallel` runs one step as two parallel loops, for large scenes.
Both sum contact forces per body in the same fixed order (CSR gather, no atomics), so they give
bit-identical trajectories.

Integrator (symplectic Euler with an exact-angular-momentum rotation splitting):
    v_{n+1} = v_n + dt F_n / m,            x_{n+1} = x_n + dt v_{n+1}
    L_{n+1} = L_n + dt T_n                 (angular momentum, table frame)
    R_{n+1} = free rotation of R_n for dt at constant L_{n+1}, split as
              X(dt/2) Y(dt/2) Z(dt) Y(dt/2) X(dt/2), each an exact rotation about one body axis
              (Dullweber, Leimkuhler & McLachlan 1997, J. Chem. Phys. 107, 5840): L is conserved
              exactly when no torque acts, the energy error stays bounded.
    omega_{n+1} = R I^-1 R^T L_{n+1}
"""

import taichi as ti

from dem.engine import geometry, laws
from dem.engine.geometry import MAXP, VP
from dem.engine.mathutil import TINY_ANGLE, quat_angle_between, quat_mul, quat_to_mat, vec3, vec4

# flags[0] bits
REBUILD = 1
NONFINITE = 2
RUNAWAY = 4
STOP = NONFINITE | RUNAWAY

# energy[] slots (J, accumulated since t = 0)
E_WORK_GRAVITY = 0
E_WORK_BASE = 1
E_DAMP_NORMAL = 2
E_DAMP_SHEAR = 3
E_FRICTION = 4
E_LOCAL_DAMPING = 5
N_ENERGY = 8

# params[] slots
P_SKIN = 0
P_MAX_SPEED = 1
P_LOCAL_DAMPING = 2
P_MATCH_TOL = 3
N_PARAMS = 8

nd = ti.types.ndarray


@ti.func
def contact_stage_pair(p, dt, model_half: ti.template(), model_inv_mass: ti.template(),
        model_material: ti.template(), model_mat_pair: ti.template(), st_pos: ti.template(),
        st_vel: ti.template(), st_omega: ti.template(), st_rot: ti.template(),
        c_pairs: ti.template(), c_code: ti.template(), c_npts: ti.template(),
        c_normal: ti.template(), c_loc: ti.template(), c_shear: ti.template(),
        c_point: ti.template(), c_depth: ti.template(), c_area: ti.template(),
        c_fn: ti.template(), c_ft: ti.template(), c_wrench: ti.template(), energy: ti.template()):
    """Narrow phase and joint law of pair p (see geometry.py and laws.py)."""
    i = c_pairs[p][0]
    j = c_pairs[p][1]
    pA = st_pos[i]
    pB = st_pos[j]
    RA = st_rot[i]
    RB = st_rot[j]
    hA = model_half[i]
    hB = model_half[j]
    hmin = ti.min(hA.min(), hB.min())
    px = VP(0.0)
    py = VP(0.0)
    pz = VP(0.0)
    dep = VP(0.0)
    w = VP(0.0)
    code, n, npts, shrink, centroid = geometry.box_contact(
        pA, RA, hA, pB, RB, hB, c_code[p], 1e-3 * hmin, hmin * hmin, px, py, pz, dep, w)
    if code >= 0:
        c_code[p] = code
    # previous points (history), read before overwriting
    n_old = c_npts[p]
    lx = VP(0.0)
    ly = VP(0.0)
    lz = VP(0.0)
    ux = VP(0.0)
    uy = VP(0.0)
    uz = VP(0.0)
    for k in range(n_old):
        l = c_loc[p, k]
        u = c_shear[p, k]
        lx[k] = l[0]
        ly[k] = l[1]
        lz[k] = l[2]
        ux[k] = u[0]
        uy[k] = u[1]
        uz[k] = u[2]
    mp = model_mat_pair[model_material[i], model_material[j]]
    mu = mp[0]
    kn = mp[1]
    ks = mp[2]
    zeta = mp[3]
    inv_m = model_inv_mass[i] + model_inv_mass[j]
    area_tot = 0.0
    for q in range(npts):
        area_tot += w[q]
    # damping coefficient of the pair (fraction zeta of critical), split by area
    cn_per_area = 0.0
    ct_per_area = 0.0
    if area_tot > 0.0 and inv_m > 0.0:
        m_eff = 1.0 / inv_m
        cn_per_area = 2.0 * zeta * ti.sqrt(kn * m_eff / area_tot)
        ct_per_area = 2.0 * zeta * ti.sqrt(ks * m_eff / area_tot)
    # velocity of B's material point at x relative to A's: v0 + dw x (x - pA); the normal
    # rate at the polygon vertex pv behind a point x is that at x plus (pv - x) . (n x dw)
    dw = st_omega[j] - st_omega[i]
    v0 = st_vel[j] - st_vel[i] + st_omega[j].cross(pA - pB)
    nxw = n.cross(dw)
    inv_shrink = 1.0 / shrink
    F_i = vec3(0.0)
    T_i = vec3(0.0)
    match_tol2 = (0.05 * hmin) ** 2
    e_damp_n = 0.0
    e_shear = 0.0
    e_fric = 0.0
    for q in range(npts):
        pw = vec3(px[q], py[q], pz[q])
        rA = pw - pA
        lq = RA.transpose() @ rA
        # shear history: the old point at the same slot if it is still there, else the nearest
        u_old = vec3(0.0)
        if n_old > 0:
            best = q
            if best >= n_old:
                best = n_old - 1
            dbest = (vec3(lx[best], ly[best], lz[best]) - lq).norm_sqr()
            if dbest > match_tol2:
                for k in range(n_old):
                    dk = (vec3(lx[k], ly[k], lz[k]) - lq).norm_sqr()
                    if dk < dbest:
                        dbest = dk
                        best = k
            u_old = vec3(ux[best], uy[best], uz[best])
        vrel = v0 + dw.cross(rA)
        vn = vrel.dot(n)
        # elastic normal force at the quadrature point, viscous (impact) force at the polygon
        # vertex pv = pw + dv behind it (see module docstring: rocking impacts)
        dv = (pw - centroid) * (inv_shrink - 1.0)
        vn_v = vn + dv.dot(nxw)
        f_el, f_visc = laws.normal_law(kn * w[q], dep[q], -vn_v, cn_per_area * w[q])
        fn = f_el + f_visc
        v_t = vrel - vn * n
        ft, u_new, sliding, diss = laws.coulomb_shear(
            u_old, n, v_t, dt, ks * w[q], ct_per_area * w[q], mu, fn)
        fv = f_visc * n  # on j, at the vertex
        f = f_el * n + ft + fv  # on j; moment about A's centre rA x f + dv x fv
        F_i -= f
        T_i -= rA.cross(f) + dv.cross(fv)
        e_damp_n += f_visc * (-vn_v) * dt
        if sliding == 1:
            e_fric += diss
        else:
            e_shear += diss
        c_point[p, q] = pw
        c_depth[p, q] = dep[q]
        c_area[p, q] = w[q]
        c_fn[p, q] = fn
        c_ft[p, q] = ft
        c_loc[p, q] = lq
        c_shear[p, q] = u_new
    # torque on j about its centre: the same forces, moved from pA to pB
    T_j = -T_i - (pA - pB).cross(F_i)
    c_npts[p] = npts
    c_normal[p] = n
    c_wrench[p, 0] = F_i
    c_wrench[p, 1] = T_i
    c_wrench[p, 2] = T_j
    energy[E_DAMP_NORMAL] += e_damp_n
    energy[E_DAMP_SHEAR] += e_shear
    energy[E_FRICTION] += e_fric


@ti.func
def free_rotation(q, R, L, inv_I, dt):
    """Rotate for dt at constant angular momentum L: X(dt/2) Y(dt/2) Z(dt) Y(dt/2) X(dt/2).

    Each factor turns the body by phi = h (R^T L)_k / I_k about its axis k:
    q <- q (cos(phi/2), sin(phi/2) e_k), and the body-frame components Lb = R^T L of the fixed
    L turn the other way, Lb <- Rot_k(phi)^T Lb.  For |phi| < TINY_ANGLE the sines and cosines
    are exactly phi and 1 in double precision (the correctly rounded values, what libm
    returns), so the libm calls are skipped: a resting block turns by ~1e-10 rad per step.
    The factor stays inline: Taichi 1.7.4 miscompiles a ti.func that has a template argument
    and a runtime ``if`` when it is called twice with the same template value (X and Y here).
    """
    Lb = R.transpose() @ L
    for f in ti.static(range(5)):
        k = (0, 1, 2, 1, 0)[f]
        k1 = (k + 1) % 3
        k2 = (k + 2) % 3
        phi = (0.5, 0.5, 1.0, 0.5, 0.5)[f] * dt * Lb[k] * inv_I[k]
        c = 1.0
        s = 0.5 * phi
        cp = 1.0
        sp = phi
        if ti.abs(phi) >= TINY_ANGLE:
            c = ti.cos(0.5 * phi)
            s = ti.sin(0.5 * phi)
            cp = ti.cos(phi)
            sp = ti.sin(phi)
        dq = vec4(c, 0.0, 0.0, 0.0)
        dq[k + 1] = s
        q = quat_mul(q, dq)
        a = Lb[k1]
        b = Lb[k2]
        Lb[k1] = cp * a + sp * b
        Lb[k2] = -sp * a + cp * b
    q = q.normalized()
    return q, quat_to_mat(q)


@ti.func
def integrate_stage_body(b, dt, g, a_base, params: ti.template(), model_mass: ti.template(),
        model_inv_mass: ti.template(), model_inv_inertia: ti.template(),
        model_radius: ti.template(), st_pos: ti.template(), st_quat: ti.template(),
        st_vel: ti.template(), st_angmom: ti.template(), st_omega: ti.template(),
        st_rot: ti.template(), st_force: ti.template(), st_torque: ti.template(),
        c_wrench: ti.template(), c_adj_ptr: ti.template(), c_adj: ti.template(),
        c_ref_pos: ti.template(), c_ref_quat: ti.template(), flags: ti.template(),
        energy: ti.template()):
    """Loads + gathered contact wrenches, then one symplectic Euler step of body b."""
    inv_m = model_inv_mass[b]
    if inv_m > 0.0:
        m = model_mass[b]
        F = vec3(0.0)
        T = vec3(0.0)
        for e in range(c_adj_ptr[b], c_adj_ptr[b + 1]):
            entry = c_adj[e]
            p = entry >> 1
            if entry & 1 == 0:
                F += c_wrench[p, 0]
                T += c_wrench[p, 1]
            else:
                F -= c_wrench[p, 0]
                T += c_wrench[p, 2]
        F += m * (g - a_base)
        v0 = st_vel[b]
        w0 = st_omega[b]
        alpha = params[P_LOCAL_DAMPING]
        if alpha > 0.0:
            # Cundall's local damping: a force -alpha |F_k| sign(v_k) per component
            fd = -alpha * ti.abs(F) * ti.math.sign(v0)
            td = -alpha * ti.abs(T) * ti.math.sign(w0)
            F += fd
            T += td
            energy[E_LOCAL_DAMPING] -= (fd.dot(v0) + td.dot(w0)) * dt
        v1 = v0 + dt * inv_m * F
        vmid = 0.5 * (v0 + v1)
        energy[E_WORK_GRAVITY] += m * g.dot(vmid) * dt
        energy[E_WORK_BASE] -= m * a_base.dot(vmid) * dt
        x1 = st_pos[b] + dt * v1
        L1 = st_angmom[b] + dt * T
        inv_I = model_inv_inertia[b]
        q1, R1 = free_rotation(st_quat[b], st_rot[b], L1, inv_I, dt)
        w1 = R1 @ (inv_I * (R1.transpose() @ L1))
        st_vel[b] = v1
        st_pos[b] = x1
        st_angmom[b] = L1
        st_quat[b] = q1
        st_rot[b] = R1
        st_omega[b] = w1
        st_force[b] = F
        st_torque[b] = T
        # checks: bad state, then neighbour-list validity
        speed = v1.norm() + w1.norm() * model_radius[b]
        bad = 0
        if not (speed < 1e300) or not (x1.norm_sqr() < 1e300):  # catches NaN and inf
            bad = NONFINITE
        elif speed > params[P_MAX_SPEED]:
            bad = RUNAWAY
        if bad != 0:
            ti.atomic_or(flags[0], bad)
            ti.atomic_max(flags[1], b)
        moved = (x1 - c_ref_pos[b]).norm() + model_radius[b] * quat_angle_between(
            q1, c_ref_quat[b])
        if moved > 0.5 * params[P_SKIN]:
            ti.atomic_or(flags[0], REBUILD)


@ti.kernel
def advance_serial(
    n_steps: ti.i32, n_pairs: ti.i32, dt: float, loads: nd(dtype=vec3, ndim=2),
    params: nd(ndim=1), flags: nd(dtype=ti.i32, ndim=1),
    energy: nd(ndim=1),
    model_half: nd(dtype=vec3, ndim=1), model_mass: nd(ndim=1),
    model_inv_mass: nd(ndim=1), model_inv_inertia: nd(dtype=vec3, ndim=1),
    model_radius: nd(ndim=1), model_material: nd(dtype=ti.i32, ndim=1),
    model_mat_pair: nd(dtype=vec4, ndim=2),
    st_pos: nd(dtype=vec3, ndim=1), st_quat: nd(dtype=vec4, ndim=1),
    st_vel: nd(dtype=vec3, ndim=1), st_angmom: nd(dtype=vec3, ndim=1),
    st_omega: nd(dtype=vec3, ndim=1), st_rot: nd(dtype=ti.math.mat3, ndim=1),
    st_force: nd(dtype=vec3, ndim=1), st_torque: nd(dtype=vec3, ndim=1),
    c_pairs: nd(dtype=ti.math.ivec2, ndim=1), c_adj_ptr: nd(dtype=ti.i32, ndim=1),
    c_adj: nd(dtype=ti.i32, ndim=1), c_ref_pos: nd(dtype=vec3, ndim=1),
    c_ref_quat: nd(dtype=vec4, ndim=1), c_code: nd(dtype=ti.i32, ndim=1),
    c_npts: nd(dtype=ti.i32, ndim=1), c_normal: nd(dtype=vec3, ndim=1),
    c_loc: nd(dtype=vec3, ndim=2), c_shear: nd(dtype=vec3, ndim=2),
    c_point: nd(dtype=vec3, ndim=2), c_depth: nd(ndim=2),
    c_area: nd(ndim=2), c_fn: nd(ndim=2),
    c_ft: nd(dtype=vec3, ndim=2), c_wrench: nd(dtype=vec3, ndim=2),
):
    """Run up to n_steps steps on one thread; stop after a step that raised a flag.

    flags[2] returns the number of steps done.  loads[s] = (gravity, base acceleration) of step s.
    """
    n_bodies = st_pos.shape[0]
    s = 0
    while s < n_steps and flags[0] == 0:
        for p in range(n_pairs):
            contact_stage_pair(p, dt, model_half, model_inv_mass, model_material,
                               model_mat_pair, st_pos, st_vel, st_omega, st_rot, c_pairs,
                               c_code, c_npts, c_normal, c_loc, c_shear, c_point, c_depth,
                               c_area, c_fn, c_ft, c_wrench, energy)
        for b in range(n_bodies):
            integrate_stage_body(b, dt, loads[s, 0], loads[s, 1], params, model_mass,
                                 model_inv_mass, model_inv_inertia, model_radius, st_pos,
                                 st_quat, st_vel, st_angmom, st_omega, st_rot, st_force,
                                 st_torque, c_wrench, c_adj_ptr, c_adj, c_ref_pos, c_ref_quat,
                                 flags, energy)
        s += 1
    flags[2] = s


@ti.kernel
def advance_parallel(
    n_pairs: ti.i32, n_bodies: ti.i32, dt: float, loads: nd(dtype=vec3, ndim=2),
    params: nd(ndim=1), flags: nd(dtype=ti.i32, ndim=1),
    energy: nd(ndim=1),
    model_half: nd(dtype=vec3, ndim=1), model_mass: nd(ndim=1),
    model_inv_mass: nd(ndim=1), model_inv_inertia: nd(dtype=vec3, ndim=1),
    model_radius: nd(ndim=1), model_material: nd(dtype=ti.i32, ndim=1),
    model_mat_pair: nd(dtype=vec4, ndim=2),
    st_pos: nd(dtype=vec3, ndim=1), st_quat: nd(dtype=vec4, ndim=1),
    st_vel: nd(dtype=vec3, ndim=1), st_angmom: nd(dtype=vec3, ndim=1),
    st_omega: nd(dtype=vec3, ndim=1), st_rot: nd(dtype=ti.math.mat3, ndim=1),
    st_force: nd(dtype=vec3, ndim=1), st_torque: nd(dtype=vec3, ndim=1),
    c_pairs: nd(dtype=ti.math.ivec2, ndim=1), c_adj_ptr: nd(dtype=ti.i32, ndim=1),
    c_adj: nd(dtype=ti.i32, ndim=1), c_ref_pos: nd(dtype=vec3, ndim=1),
    c_ref_quat: nd(dtype=vec4, ndim=1), c_code: nd(dtype=ti.i32, ndim=1),
    c_npts: nd(dtype=ti.i32, ndim=1), c_normal: nd(dtype=vec3, ndim=1),
    c_loc: nd(dtype=vec3, ndim=2), c_shear: nd(dtype=vec3, ndim=2),
    c_point: nd(dtype=vec3, ndim=2), c_depth: nd(ndim=2),
    c_area: nd(ndim=2), c_fn: nd(ndim=2),
    c_ft: nd(dtype=vec3, ndim=2), c_wrench: nd(dtype=vec3, ndim=2),
):
    """One step (loads[0]) as two parallel loops, over pairs then over bodies.

    The array arguments are those of :func:`advance_serial`: one launch per step, whose cost
    is mostly Taichi's handling of the 35 array arguments (~15 us each on the test machine).
    """
    for p in range(n_pairs):
        contact_stage_pair(p, dt, model_half, model_inv_mass, model_material, model_mat_pair,
                           st_pos, st_vel, st_omega, st_rot, c_pairs, c_code, c_npts, c_normal,
                           c_loc, c_shear, c_point, c_depth, c_area, c_fn, c_ft, c_wrench,
                           energy)
    for b in range(n_bodies):
        integrate_stage_body(b, dt, loads[0, 0], loads[0, 1], params, model_mass,
                             model_inv_mass, model_inv_inertia, model_radius, st_pos, st_quat,
                             st_vel, st_angmom, st_omega, st_rot, st_force, st_torque, c_wrench,
                             c_adj_ptr, c_adj, c_ref_pos, c_ref_quat, flags, energy)


@ti.kernel
def probe_contacts(
    n_pairs: ti.i32, out_depth: nd(ndim=1),
    model_half: nd(dtype=vec3, ndim=1), st_pos: nd(dtype=vec3, ndim=1),
    st_rot: nd(dtype=ti.math.mat3, ndim=1), c_pairs: nd(dtype=ti.math.ivec2, ndim=1),
):
    """Largest penetration (m) of every pair, without touching the history (overlap checks)."""
    for p in range(n_pairs):
        i = c_pairs[p][0]
        j = c_pairs[p][1]
        hA = model_half[i]
        hB = model_half[j]
        hmin = ti.min(hA.min(), hB.min())
        px = VP(0.0)
        py = VP(0.0)
        pz = VP(0.0)
        dep = VP(0.0)
        w = VP(0.0)
        code, n, npts, shrink, centroid = geometry.box_contact(
            st_pos[i], st_rot[i], hA, st_pos[j], st_rot[j], hB, -1, 1e-3 * hmin, hmin * hmin,
            px, py, pz, dep, w)
        dmax = 0.0
        for q in range(npts):
            dmax = ti.max(dmax, dep[q])
        out_depth[p] = dmax


@ti.kernel
def elastic_energy(n_pairs: ti.i32, model_material: nd(dtype=ti.i32, ndim=1),
                   model_mat_pair: nd(dtype=vec4, ndim=2),
                   c_pairs: nd(dtype=ti.math.ivec2, ndim=1), c_npts: nd(dtype=ti.i32, ndim=1),
                   c_depth: nd(ndim=2), c_area: nd(ndim=2),
                   c_shear: nd(dtype=vec3, ndim=2)) -> float:
    """Energy stored in the joint springs (J): sum of kn A d^2 / 2 + ks A |u|^2 / 2."""
    e = 0.0
    for p in range(n_pairs):
        mp = model_mat_pair[model_material[c_pairs[p][0]], model_material[c_pairs[p][1]]]
        for q in range(c_npts[p]):
            a = c_area[p, q]
            e += 0.5 * a * (mp[1] * c_depth[p, q] ** 2 + mp[2] * c_shear[p, q].norm_sqr())
    return e
