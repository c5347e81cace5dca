"""One time step as a short list of named stages, and the kernels that run it.

    for each step:
        contact_stage    for every pair of the neighbour list:
                           narrow_phase      geometry: contact points, depths, areas, normal
                                             (dem.engine.geometry, Yade's Ig2); a closed
                                             joint's patch is reused while its faces do not
                                             drift (dem.engine.coherence, solver.patch_reuse)
                           pair_properties   mu, kn, ks, damping coefficients (dem.engine.pair, Ip2)
                           previous_points   shear history of the pair (Contacts)
                           joint law         normal_law + coulomb_shear per point
                                             (dem.engine.laws, Law2)
                         writes Contacts: points, forces, shear history, per-pair wrench
        integrate_stage  loads (gravity, base acceleration) + gathered contact wrenches,
                         then symplectic Euler: v += dt F/m, L += dt T, x += dt v, and the
                         free rotation by splitting (writes State); flags a neighbour-list
                         rebuild or a bad state (Control.status)
        energy_stage     adds the step's work and dissipation of every pair and body to the
                         energy sums (Control), on one thread in a fixed order
        deepest_stage    keeps the deepest penetration of any contact point and the step it
                         happened (Control), read by Simulation.deepest_penetration
        probe_stage      at the steps the host asked for, copies the probed bodies' state
                         to Control.probe_buf (Simulation.set_probe: instrument samples)

The broad phase (neighbour list) runs when a body has moved more than half the skin: on the host
between kernel launches (:mod:`dem.engine.broadphase`), or on a device between two steps of a
chunk (:mod:`dem.engine.broadphase_device`).

Every stage is a function of the containers (Model, State, Contacts, Control: see
:mod:`dem.engine.containers`), which the kernels take as one argpack each.  One kernel per job,
each with the model's variants as compile-time arguments (``ti.template()``: ``warped`` for
imperfect faces, ``hyperbolic`` for the hyperbolic joint law; Taichi compiles each combination
the first time it is called, and ``ti.static`` branches leave the code of the others out, so the
perfect, linear combination is the code that ran before the variants existed, bit for bit):
:func:`advance_serial`, :func:`advance_parallel`, :func:`probe_contacts` (depths and patch
areas without touching the history) and :func:`elastic_energy`.  Two kernels run the same
stages:
- :func:`advance_serial` runs many steps in one launch on one thread;
- :func:`advance_parallel` runs one step as two parallel loops (pairs, then bodies), for scenes
  large enough to pay for the thread pool's dispatch (~30-60 us per parallel loop on the 2-core
  test machine, benchmarks/RESULTS.md); :mod:`dem.engine.launch` makes its launch cheap.
Both sum contact forces per body in the same fixed order (CSR gather, no atomics), so they give
the same trajectories: bit for bit where the compiler emits the same instructions for both
kernels, to the last bit where fast-math selects them differently (AVX-512 CPUs; docs/engine.md).

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

from dem import ti_runtime
from dem.engine import coherence, geometry, laws
from dem.engine.containers import (ENERGY_TERMS, NONFINITE, P_MAX_SPEED, P_PATCH_TOLERANCE,
                                   P_SKIN, REBUILD, RUNAWAY, ContactArgs, ControlArgs,
                                   ModelArgs, StateArgs)
from dem.engine.geometry import point_buffer
from dem.engine.mathutil import TINY_ANGLE, quat_angle_between, quat_mul, quat_to_mat, vec3, vec4
from dem.engine.pair import (CRITICAL, HYPERBOLIC, STIFFNESS, normal_stiffness_for_damping,
                             pair_material, pair_properties)

ti_runtime.quick_front_end()  # before this module's kernels are decorated

# Tolerances of the stages, in units of the smaller half extent hmin of the pair's blocks (m),
# so that they scale with the masonry unit:
AXIS_MARGIN = 1e-3     # a contact axis other than the pair's sticky one (contacts.code) must
#                        overlap less by more than this x hmin to take over (geometry.choose_axis):
#                        without it round-off flips a flush joint between two nearly equal axes
MATCH_RADIUS = 0.05    # a new contact point takes the shear history of the old point at its
#                        slot if that lies within MATCH_RADIUS x hmin (in body i's frame), else
#                        the nearest old point's (matched_point): far above a step's motion
#                        (~1e-6 hmin), far below the spacing of a patch's points (~0.5 hmin)
FINITE_LIMIT = 1e300   # |x|^2 and speeds at or above this (or NaN) flag NONFINITE: the largest
#                        f64 is ~1.8e308, so any real state is far below, any overflow above
REBUILD_FRACTION = 0.5  # rebuild the neighbour list once a body moved this fraction of the
#                         skin (two bodies moving towards each other close the whole skin)

# the columns of control.energy (containers.ENERGY_TERMS)
E_GRAVITY, E_BASE, E_NORMAL, E_SHEAR, E_FRICTION, E_LOCAL = (ENERGY_TERMS.index(name) for name in (
    "work_gravity", "work_base", "dissipated_normal_damping", "dissipated_shear_damping",
    "dissipated_friction", "dissipated_local_damping"))


@ti.func
def narrow_phase(p, i, j, model: ti.template(), state: ti.template(), contacts: ti.template(),
                 control: ti.template(), warped: ti.template(), px: ti.template(),
                 py: ti.template(), pz: ti.template(), dep: ti.template(), w: ti.template(),
                 overlap: ti.template()):
    """Contact patch of pair p = (i, j) into the point buffers (see geometry.box_contact);
    keeps the sticky axis in contacts.code.  Returns (reused, n, npts, shrink, centroid).  With a
    patch tolerance > 0 (control.step_parameters) a closed flat patch of the last steps is
    reused (reused = 1) while the poses allow it (dem.engine.coherence), and a full narrow phase
    keeps its patch for that.  In the warped kernels (imperfect faces) that reuse is off.

    ``overlap`` (compile time, only with ``warped``): the overlap reuse of
    coherence.set_overlap_reuse (tolerance tol_o = contacts.patch_shape[p, 0][0] > 0 m): the
    faces' overlap polygon is kept and only the gap clip, quadrature and points are redone while
    the faces do not drift (coherence.reuse_overlap); reused stays 0 then (the points are new:
    history by position).  Without it the code below is exactly that of the narrow phase before
    the overlap reuse existed (commit aec8507), with no runtime test of tol_o: a runtime branch,
    even never taken, changed how LLVM fuses the arithmetic and moved the default imperfect
    path by round-off (1.4e-15 m after 3000 steps); as a separate compiled variant it stays
    bit for bit."""
    reused = 0
    n = vec3(0.0, 0.0, 1.0)
    npts = 0
    shrink = 1.0
    centroid = vec3(0.0)
    if ti.static(warped and overlap):
        tol_o = contacts.patch_shape[p, 0][0]  # overlap reuse (coherence.set_overlap_reuse)
        kept = 0
        if tol_o > 0.0:
            kept, n, npts, shrink, centroid = coherence.reuse_overlap(
                p, i, j, tol_o, model, state, contacts, px, py, pz, dep, w)
        hA = model.half[i]
        hB = model.half[j]
        hmin = ti.min(hA.min(), hB.min())
        code = 0
        if tol_o > 0.0:
            if kept == 0:
                code, n, npts, shrink, centroid = coherence.keep_overlap(
                    p, i, j, 1e-3 * hmin, hmin * hmin, model, state, contacts, px, py, pz,
                    dep, w)
                if code >= 0:
                    contacts.code[p] = code
        else:
            whole = 0
            code, n, npts, shrink, centroid, whole = geometry.box_contact(
                state.pos[i], state.rot[i], hA, state.pos[j], state.rot[j], hB,
                contacts.code[p], 1e-3 * hmin, hmin * hmin, model, warped, i, j, px, py, pz,
                dep, w)
            if code >= 0:
                contacts.code[p] = code
    else:  # the narrow phase of aec8507, unchanged
        tol = control.step_parameters[P_PATCH_TOLERANCE]
        if ti.static(not warped):  # patch reuse: perfect faces only (dem.engine.coherence)
            if tol > 0.0:
                reused, n, npts, shrink, centroid = coherence.reuse_patch(
                    p, i, j, tol, model, state, contacts, px, py, pz, dep, w)
        if reused == 0:
            hA = model.half[i]
            hB = model.half[j]
            hmin = ti.min(hA.min(), hB.min())
            code = 0
            whole = 0
            code, n, npts, shrink, centroid, whole = geometry.box_contact(
                state.pos[i], state.rot[i], hA, state.pos[j], state.rot[j], hB,
                contacts.code[p], 1e-3 * hmin, hmin * hmin, model, warped, i, j, px, py, pz,
                dep, w)
            if code >= 0:
                contacts.code[p] = code
            if ti.static(not warped):
                if tol > 0.0:
                    coherence.store_patch(p, i, j, code, whole, npts, shrink, centroid, model,
                                          state, contacts, px, py, pz, w)
    return reused, n, npts, shrink, centroid


@ti.func
def previous_points(p, contacts: ti.template(), lx: ti.template(), ly: ti.template(),
                    lz: ti.template(), ux: ti.template(), uy: ti.template(), uz: ti.template(),
                    wo: ti.template()):
    """Copies the pair's points of the last step (in body i's frame), their shear
    displacements and weights into the buffers, before the law overwrites them.  Returns their
    number."""
    n_old = contacts.npts[p]
    for k in range(n_old):
        l = contacts.loc[p, k]
        u = contacts.shear[p, k]
        lx[k] = l[0]
        ly[k] = l[1]
        lz[k] = l[2]
        ux[k] = u[0]
        uy[k] = u[1]
        uz[k] = u[2]
        wo[k] = contacts.area[p, k]
    return n_old


@ti.func
def matched_point(q, lq, n_old, match_tol2, lx: ti.template(), ly: ti.template(),
                  lz: ti.template()):
    """The old point whose shear history new point q at lq (body i's frame) takes: the old
    point at the same slot if it is within sqrt(match_tol2), else the nearest old point; -1
    for a new pair."""
    best = -1
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
    return best


@ti.func
def point_elastic(props, area, depth, hyperbolic: ti.template()):
    """The elastic normal force of a contact point (N): kn A d, or A p(d) for a hyperbolic
    pair (laws.hyperbolic_pressure) in kernels compiled with ``hyperbolic``."""
    f = props.kn * area * depth
    if ti.static(hyperbolic):
        if props.law == HYPERBOLIC:
            f = area * laws.hyperbolic_pressure(props.kn, props.d_max, props.d_lim, depth)
    return f


@ti.func
def slots_per_scene(contacts: ti.template()):
    """P, the pair slots of one scene (dem.engine.containers: scene g owns g P ... g P + P)."""
    return contacts.pairs.shape[0] // contacts.scene_pairs.shape[0]


@ti.func
def pair_bodies(p, model: ti.template(), contacts: ti.template(), batched: ti.template()):
    """The engine's body indices (i, j) of pair slot p: the pair's indices within its scene plus
    the scene's first body (``batched``, compile time; a lone scene's are the indices)."""
    i = contacts.pairs[p][0]
    j = contacts.pairs[p][1]
    if ti.static(batched):
        b0 = model.scene_bodies[p // slots_per_scene(contacts)][0]
        i += b0
        j += b0
    return i, j


@ti.func
def slot_live(p, contacts: ti.template(), control: ti.template(), batched: ti.template()):
    """1 if slot p holds a pair of an active scene (``batched``; a lone scene's slots below
    n_pairs are the loop's range)."""
    live = 1
    if ti.static(batched):
        P = slots_per_scene(contacts)
        g = p // P
        live = 0
        if p - g * P < contacts.scene_pairs[g] and control.active[g] != 0:
            live = 1
    return live


@ti.func
def contact_stage(p, dt, model: ti.template(), state: ti.template(), contacts: ti.template(),
                  control: ti.template(), warped: ti.template(), hyperbolic: ti.template(),
                  overlap: ti.template() = False, batched: ti.template() = False,
                  pair_damping: ti.template() = False):
    """Narrow phase, pair properties, history and joint law of pair p.  ``warped``
    (compile time): the kernel handles imperfect faces (docs/imperfections.md);
    ``hyperbolic`` (compile time): the kernel reads each pair's normal law (linear or
    hyperbolic, dem.engine.laws); without it every pair is linear, the code that ran before
    the hyperbolic law existed (the same results bit for bit); ``overlap`` (compile time, False
    by default): the warped kernels' overlap reuse (:func:`narrow_phase`); ``batched`` (compile
    time): an engine of several scenes (:func:`pair_bodies`); ``pair_damping`` (compile time,
    False by default): the kernel reads each pair's normal dashpot (PairMaterial.damping) and
    holds the pulls of the opening dashpots of a PAIR or STIFFNESS pair to the pair's pushes
    (laws.normal_law_pair_damped, laws.pull_scale); without it every pair's dashpots are
    released point by point (laws.normal_law), the code of before (bit for bit)."""
    i, j = pair_bodies(p, model, contacts, batched)
    pA = state.pos[i]
    pB = state.pos[j]
    RA = state.rot[i]
    px = point_buffer()
    py = point_buffer()
    pz = point_buffer()
    dep = point_buffer()
    w = point_buffer()
    reused, n, npts, shrink, centroid = narrow_phase(p, i, j, model, state, contacts, control,
                                                     warped, px, py, pz, dep, w, overlap)
    lx = point_buffer()
    ly = point_buffer()
    lz = point_buffer()
    ux = point_buffer()
    uy = point_buffer()
    uz = point_buffer()
    wo = point_buffer()
    claimed = point_buffer()
    # a reused patch has the points of the last step in the same slots (coherence.reuse_patch),
    # which matched_point would pick (they moved by far less than its tolerance): the history
    # is read from the slot itself, without the copies and the search
    n_old = 0
    if reused == 0:
        n_old = previous_points(p, contacts, lx, ly, lz, ux, uy, uz, wo)
    imperfect_pair = 0
    if ti.static(warped):
        imperfect_pair = model.imperfect[i] + model.imperfect[j]
    area_tot = 0.0
    for q in range(npts):
        area_tot += w[q]
    depth_mean = 0.0  # the area-weighted mean closure (m): the hyperbolic law's damping
    if ti.static(hyperbolic):
        closure_area = 0.0
        for q in range(npts):
            closure_area += w[q] * dep[q]
        if area_tot > 0.0:
            depth_mean = closure_area / area_tot
    props = pair_properties(model, i, j, area_tot, depth_mean, hyperbolic)
    # velocity of B's material point at x relative to A's: v0 + dw x (x - pA); the normal
    # rate at the polygon vertex pv behind a point x is that at x plus (pv - x) . (n x dw)
    dw = state.omega[j] - state.omega[i]
    v0 = state.vel[j] - state.vel[i] + state.omega[j].cross(pA - pB)
    nxw = n.cross(dw)
    inv_shrink = 1.0 / shrink
    damping = CRITICAL  # the pair's normal dashpot (PairMaterial.damping)
    cn_pair = 0.0  # its coefficient per unit area (N s/m^3)
    s_pull = 1.0  # the pair's factor on its opening dashpots (laws.pull_scale)
    if ti.static(pair_damping):
        pm = pair_material(model, i, j)
        damping = ti.cast(pm.damping, ti.i32)
        cn_pair = props.cn_per_area
        if damping == STIFFNESS:
            cn_pair = pm.beta * normal_stiffness_for_damping(pm.kn, pm.law, pm.d_max, pm.d_lim,
                                                             depth_mean, hyperbolic)
        if damping != CRITICAL:
            push = 0.0
            pull = 0.0
            for q in range(npts):
                pw = vec3(px[q], py[q], pz[q])
                vn_v = (v0 + dw.cross(pw - pA)).dot(n) + (
                    (pw - centroid) * (inv_shrink - 1.0)).dot(nxw)
                fe = point_elastic(props, w[q], dep[q], hyperbolic)
                fv = cn_pair * w[q] * (-vn_v)
                push += fe + ti.max(fv, 0.0)
                pull += ti.min(fv, 0.0)
            s_pull = laws.pull_scale(push, pull)
    F_i = vec3(0.0)
    T_i = vec3(0.0)
    hmin = ti.min(model.half[i].min(), model.half[j].min())
    match_tol2 = (MATCH_RADIUS * hmin) ** 2
    e_damp_n = 0.0
    e_shear = 0.0
    e_fric = 0.0
    for q in range(npts):
        pw = vec3(px[q], py[q], pz[q])
        rA = pw - pA
        lq = RA.transpose() @ rA
        u_old = vec3(0.0)
        best = -1
        if reused != 0:
            u_old = contacts.shear[p, q]
        else:
            best = matched_point(q, lq, n_old, match_tol2, lx, ly, lz)
        if best >= 0:
            u_old = vec3(ux[best], uy[best], uz[best])
            if imperfect_pair > 0:
                # warped patches gain and lose vertices often: an old point's history goes to
                # one new point only, its spring energy ks w |u|^2 / 2 never grows in the
                # transfer (docs/imperfections.md)
                if claimed[best] > 0.0:
                    u_old = vec3(0.0)
                else:
                    claimed[best] = 1.0
                    if w[q] > wo[best]:
                        u_old *= ti.sqrt(wo[best] / w[q])
        vrel = v0 + dw.cross(rA)
        vn = vrel.dot(n)
        # elastic normal force at the quadrature point, viscous (impact) force at the polygon
        # vertex pv = pw + dv behind it (docs/engine.md: rocking impacts)
        dv = (pw - centroid) * (inv_shrink - 1.0)
        vn_v = vn + dv.dot(nxw)
        f_el = 0.0
        f_visc = 0.0
        if ti.static(pair_damping):
            if damping != CRITICAL:
                f_el, f_visc = laws.normal_law_pair_damped(
                    point_elastic(props, w[q], dep[q], hyperbolic), cn_pair * w[q], -vn_v,
                    s_pull)
            elif ti.static(hyperbolic):
                if props.law == HYPERBOLIC:
                    f_el, f_visc = laws.normal_law_hyperbolic(
                        w[q], props.kn, props.d_max, props.d_lim, dep[q], -vn_v,
                        props.cn_per_area * w[q])
                else:
                    f_el, f_visc = laws.normal_law(props.kn * w[q], dep[q], -vn_v,
                                                   props.cn_per_area * w[q])
            else:
                f_el, f_visc = laws.normal_law(props.kn * w[q], dep[q], -vn_v,
                                               props.cn_per_area * w[q])
        elif ti.static(hyperbolic):
            if props.law == HYPERBOLIC:
                f_el, f_visc = laws.normal_law_hyperbolic(
                    w[q], props.kn, props.d_max, props.d_lim, dep[q], -vn_v,
                    props.cn_per_area * w[q])
            else:
                f_el, f_visc = laws.normal_law(props.kn * w[q], dep[q], -vn_v,
                                               props.cn_per_area * w[q])
        else:
            f_el, f_visc = laws.normal_law(props.kn * w[q], dep[q], -vn_v,
                                           props.cn_per_area * w[q])
        fn = f_el + f_visc
        fn_cap = fn  # the normal force that caps friction
        if ti.static(pair_damping):
            fn_cap = ti.max(fn, 0.0)  # a point's dashpot may pull (the pair's sum does not)
        v_t = vrel - vn * n
        ft, u_new, sliding, diss = laws.coulomb_shear(
            u_old, n, v_t, dt, props.ks * w[q], props.ct_per_area * w[q], props.mu, fn_cap)
        fv = f_visc * n  # on j, at the vertex
        f = f_el * n + ft + fv  # on j; moment about A's centre rA x f + dv x fv
        F_i -= f
        T_i -= rA.cross(f) + dv.cross(fv)
        e_damp_n += f_visc * (-vn_v) * dt
        if sliding == 1:
            e_fric += diss
        else:
            e_shear += diss
        contacts.point[p, q] = pw
        contacts.depth[p, q] = dep[q]
        contacts.area[p, q] = w[q]
        contacts.fn[p, q] = fn
        contacts.ft[p, q] = ft
        contacts.loc[p, q] = lq
        contacts.shear[p, q] = u_new
    # torque on j about its centre: the same forces, moved from pA to pB
    T_j = -T_i - (pA - pB).cross(F_i)
    contacts.npts[p] = npts
    contacts.normal[p] = n
    contacts.wrench[p, 0] = F_i
    contacts.wrench[p, 1] = T_i
    contacts.wrench[p, 2] = T_j
    contacts.dissipation[p] = vec3(e_damp_n, e_shear, e_fric)


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
def gather_wrench(b, g, model: ti.template(), contacts: ti.template(), batched: ti.template()):
    """Sum of the contact forces and torques on body b (of scene g), in the fixed CSR order of
    its scene's region (dem.engine.containers)."""
    F = vec3(0.0)
    T = vec3(0.0)
    slot0 = 0
    row = b
    if ti.static(batched):
        slot0 = g * slots_per_scene(contacts)
        row = b + g
    for e in range(contacts.adj_ptr[row], contacts.adj_ptr[row + 1]):
        entry = contacts.adj[2 * slot0 + e]
        p = slot0 + (entry >> 1)
        if entry & 1 == 0:
            F += contacts.wrench[p, 0]
            T += contacts.wrench[p, 1]
        else:
            F -= contacts.wrench[p, 0]
            T += contacts.wrench[p, 2]
    return F, T


@ti.func
def integrate_stage(b, s, dt, model: ti.template(), state: ti.template(),
                    contacts: ti.template(), control: ti.template(), batched: ti.template()):
    """Loads of step s of the launch + gathered contact wrenches, then one symplectic Euler
    step of body b; raises the status bits (of its scene) of a bad state or a stale neighbour
    list.  ``batched``: the body's scene's loads and flags, nothing for a frozen scene."""
    inv_m = model.inv_mass[b]
    k = 0  # the body's scene
    if ti.static(batched):
        k = model.scene[b]
        if control.active[k] == 0:
            inv_m = 0.0
    if inv_m > 0.0:
        m = model.mass[b]
        g = control.loads[s, k, 0]
        a_base = control.loads[s, k, 1]
        F, T = gather_wrench(b, k, model, contacts, batched)
        F += m * (g - a_base)
        v0 = state.vel[b]
        w0 = state.omega[b]
        alpha = control.local_damping[k]
        e_local = 0.0
        if alpha > 0.0:
            # Cundall's local damping: a force -alpha |F_k| sign(v_k) per component
            fd = -alpha * ti.abs(F) * ti.math.sign(v0)
            td = -alpha * ti.abs(T) * ti.math.sign(w0)
            F += fd
            T += td
            e_local = -(fd.dot(v0) + td.dot(w0)) * dt
        v1 = v0 + dt * inv_m * F
        vmid = 0.5 * (v0 + v1)
        state.work[b] = vec3(m * g.dot(vmid) * dt, -(m * a_base.dot(vmid) * dt), e_local)
        x1 = state.pos[b] + dt * v1
        L1 = state.angmom[b] + dt * T
        inv_I = model.inv_inertia[b]
        q1, R1 = free_rotation(state.quat[b], state.rot[b], L1, inv_I, dt)
        w1 = R1 @ (inv_I * (R1.transpose() @ L1))
        state.vel[b] = v1
        state.pos[b] = x1
        state.angmom[b] = L1
        state.quat[b] = q1
        state.rot[b] = R1
        state.omega[b] = w1
        state.force[b] = F
        state.torque[b] = T
        # checks: bad state, then neighbour-list validity
        speed = v1.norm() + w1.norm() * model.radius[b]
        bad = 0
        if not (speed < FINITE_LIMIT) or not (x1.norm_sqr() < FINITE_LIMIT):  # NaN, inf
            bad = NONFINITE
        elif speed > control.step_parameters[P_MAX_SPEED]:
            bad = RUNAWAY
        if bad != 0:
            ti.atomic_or(control.status[k], bad)
            ti.atomic_or(control.steps_done[1], bad)
            ti.atomic_max(control.bad_body[k], b - model.scene_bodies[k][0])
        moved = (x1 - contacts.ref_pos[b]).norm() + model.radius[b] * quat_angle_between(
            q1, contacts.ref_quat[b])
        if moved > REBUILD_FRACTION * control.step_parameters[P_SKIN]:
            ti.atomic_or(control.status[k], REBUILD)
            ti.atomic_or(control.steps_done[1], REBUILD)


@ti.func
def scene_ranges(k, n_pairs, model: ti.template(), state: ti.template(),
                 contacts: ti.template(), batched: ti.template()):
    """(first slot, end slot, first body, end body) of scene k; a lone scene: all of them."""
    p0, p1, b0, b1 = 0, n_pairs, 0, state.pos.shape[0]
    if ti.static(batched):
        P = slots_per_scene(contacts)
        p0 = k * P
        p1 = p0 + contacts.scene_pairs[k]
        b0 = model.scene_bodies[k][0]
        b1 = model.scene_bodies[k][1]
    return p0, p1, b0, b1


@ti.func
def energy_stage(k, n_pairs, model: ti.template(), state: ti.template(),
                 contacts: ti.template(), control: ti.template(), batched: ti.template()):
    """Adds the step's energy terms of scene k's pairs (contacts.dissipation) and bodies
    (state.work) to its sums in Control (row k, columns ENERGY_TERMS), in a fixed order (pairs,
    then bodies) on one thread per scene: the same sums, bit for bit, from both kernels and from
    a scene alone or among others, and no atomic adds in the parallel loops."""
    p0, p1, b0, b1 = scene_ranges(k, n_pairs, model, state, contacts, batched)
    for p in range(p0, p1):
        d = contacts.dissipation[p]
        control.energy_sums[k, E_NORMAL] += d[0]
        control.energy_sums[k, E_SHEAR] += d[1]
        control.energy_sums[k, E_FRICTION] += d[2]
    for b in range(b0, b1):
        w = state.work[b]
        control.energy_sums[k, E_GRAVITY] += w[0]
        control.energy_sums[k, E_BASE] += w[1]
        control.energy_sums[k, E_LOCAL] += w[2]


@ti.func
def deepest_stage(k, s, n_pairs, model: ti.template(), state: ti.template(),
                  contacts: ti.template(), control: ti.template(), batched: ti.template()):
    """Keeps the deepest penetration (m) of any contact point of scene k at this step (the
    depths of the poses at the start of step s, as the contact stage found them) in
    control.deepest[k], and s in control.deepest_step[k] when it grew.  A resting scene's depth
    is ~weight / (kn area); an impact shows its peak here even when it falls between two output
    frames."""
    p0, p1, _b0, _b1 = scene_ranges(k, n_pairs, model, state, contacts, batched)
    for p in range(p0, p1):
        for q in range(contacts.npts[p]):
            d = contacts.depth[p, q]
            if d > control.deepest[k]:
                control.deepest[k] = d
                control.deepest_step[k] = s


@ti.func
def probe_stage(k, j, s, state: ti.template(), control: ti.template()):
    """After step s: scene k's probed body j (control.probe_body[k, j], -1: none) copied to
    slot control.probe_slot[s, k] of control.probe_buf (pos, quat, vel, omega), if the host
    asked for that step (Simulation.set_probe: an instrument sampled without ending the
    launch)."""
    slot = control.probe_slot[s, k]
    b = control.probe_body[k, j]
    if slot >= 0 and b >= 0:
        x = state.pos[b]
        q = state.quat[b]
        v = state.vel[b]
        w = state.omega[b]
        for c in ti.static(range(3)):
            control.probe_buf[slot, k, j, c] = x[c]
            control.probe_buf[slot, k, j, 7 + c] = v[c]
            control.probe_buf[slot, k, j, 10 + c] = w[c]
        for c in ti.static(range(4)):
            control.probe_buf[slot, k, j, 3 + c] = q[c]


@ti.func
def no_stop(control: ti.template()):
    """1 while no scene raised a status bit (control.steps_done[1]: all scenes' bits or-ed)."""
    ok = 1
    if control.steps_done[1] != 0:
        ok = 0
    return ok


@ti.func
def scene_sums_atomic(p, k, s, contacts: ti.template(), control: ti.template()):
    """Pair p's part of its scene's energy sums and deepest penetration at step s, added with
    atomics (the device kernel: no loop of one thread per scene; the sums' order, so their
    last bits, then vary from run to run, the trajectories do not: they never read them)."""
    d = contacts.dissipation[p]
    ti.atomic_add(control.energy_sums[k, E_NORMAL], d[0])
    ti.atomic_add(control.energy_sums[k, E_SHEAR], d[1])
    ti.atomic_add(control.energy_sums[k, E_FRICTION], d[2])
    deepest = 0.0
    for q in range(contacts.npts[p]):
        deepest = ti.max(deepest, contacts.depth[p, q])
    if deepest > control.deepest[k]:
        old = ti.atomic_max(control.deepest[k], deepest)
        if deepest > old:
            control.deepest_step[k] = s  # every writer of a step writes the same s


@ti.func
def body_sums_atomic(b, k, state: ti.template(), control: ti.template()):
    """Body b's work of step s added to its scene's sums with atomics (as scene_sums_atomic)."""
    w = state.work[b]
    ti.atomic_add(control.energy_sums[k, E_GRAVITY], w[0])
    ti.atomic_add(control.energy_sums[k, E_BASE], w[1])
    ti.atomic_add(control.energy_sums[k, E_LOCAL], w[2])


@ti.kernel
def advance_serial(n_steps: ti.i32, n_slots: ti.i32, dt: float, model: ModelArgs,
                   state: StateArgs, contacts: ContactArgs, control: ControlArgs,
                   warped: ti.template(), hyperbolic: ti.template(), overlap: ti.template(),
                   batched: ti.template(), pair_damping: ti.template()):
    """Run up to n_steps steps on one thread; stop after a step that raised a status bit (of
    any scene).  control.steps_done returns the number of steps done; control.loads[s, k] holds
    step s's loads of scene k.  n_slots: the pairs of a lone scene, else the pair slots up to
    the last one in use.

    Compile-time variants (``ti.template()``: each combination is its own compiled kernel,
    built on first use): ``warped`` for scenes with imperfect faces (warps, arrises),
    ``hyperbolic`` for scenes with a hyperbolic joint (dem.engine.laws), ``overlap`` for warped
    scenes with the overlap reuse on (coherence.set_overlap_reuse; :func:`narrow_phase`),
    ``batched`` for an engine of several scenes (dem.engine.containers: the scene offsets, the
    frozen scenes), ``pair_damping`` for scenes whose normal dashpots follow the pair's
    no-tension rule (laws.normal_law_pair_damped); (False, False, False, False, False) is the perfect,
    linear model's code of a lone scene, without a branch of the others (see
    :func:`contact_stage`).
    """
    n_bodies = state.pos.shape[0]
    n_scenes = control.status.shape[0]
    s = 0
    while s < n_steps and no_stop(control) == 1:
        for p in range(n_slots):
            if slot_live(p, contacts, control, batched) == 1:
                contact_stage(p, dt, model, state, contacts, control, warped, hyperbolic,
                              overlap, batched, pair_damping)
        for b in range(n_bodies):
            integrate_stage(b, s, dt, model, state, contacts, control, batched)
        for k in range(n_scenes):
            if control.active[k] != 0:
                energy_stage(k, n_slots, model, state, contacts, control, batched)
                deepest_stage(k, s, n_slots, model, state, contacts, control, batched)
                if control.probe_slot[s, k] >= 0:
                    for j in range(control.probe_body.shape[1]):
                        probe_stage(k, j, s, state, control)
        s += 1
    control.steps_done[0] = s


@ti.kernel
def advance_parallel(s: ti.i32, n_slots: ti.i32, dt: float, model: ModelArgs,
                     state: StateArgs, contacts: ContactArgs, control: ControlArgs,
                     warped: ti.template(), hyperbolic: ti.template(), overlap: ti.template(),
                     batched: ti.template(), pair_damping: ti.template(),
                     atomic_sums: ti.template()):
    """Step s of a chunk of launches (control.loads[s]) as parallel loops: over pair slots,
    over bodies, then over scenes (each scene's energy and deepest stages on one thread, in
    the serial kernel's order); a probed body is copied in the body loop (:func:`probe_stage`).
    The host launches s = 0, 1, ... without reading anything back (no round trip per step, the
    GPU's way): a launch whose chunk already stopped (an earlier
    step raised a status bit) does nothing, so the chunk stops where the serial kernel would,
    and control.steps_done counts the steps done (the host zeroes it before s = 0).
    ``warped``, ``hyperbolic``, ``overlap``, ``batched``, ``pair_damping`` as in
    :func:`advance_serial`;
    ``atomic_sums`` (an engine on a device): the energy sums and the deepest penetration added
    by each pair and body with atomics (scene_sums_atomic) instead of one thread per scene
    summing its pairs in order, which on a GPU costs more than the step (latency-bound loops
    of ~1000 loads): the trajectories are the same, the sums' last bits vary."""
    parallel_step(s, s + 1, n_slots, dt, model, state, contacts, control, warped, hyperbolic,
                  overlap, batched, pair_damping, atomic_sums)


@ti.func
def parallel_step(s, chunk_steps, n_slots, dt, model: ti.template(), state: ti.template(),
                  contacts: ti.template(), control: ti.template(), warped: ti.template(),
                  hyperbolic: ti.template(), overlap: ti.template(), batched: ti.template(),
                  pair_damping: ti.template(), atomic_sums: ti.template()):
    """Step s of a chunk of ``chunk_steps`` steps as top-level parallel loops (inlined at a
    kernel's top level: :func:`advance_parallel`, one step a launch, and
    dem.engine.step_device.advance_device, several); the step runs where 0 <= s < chunk_steps,
    the steps before it ran (control.steps_done[0] == s) and no scene raised a status bit.  Its
    loops test "step s ran" as control.steps_done[0] == s + 1 and s >= 0: at s = -1 that count
    is also "no step yet" (a launch at a negative s runs nothing: the recording launches)."""
    if s < chunk_steps and control.steps_done[0] == s and no_stop(control) == 1:
        control.steps_done[0] = s + 1  # this step runs
    for p in range(n_slots):
        if s >= 0 and control.steps_done[0] == s + 1 and \
                slot_live(p, contacts, control, batched) == 1:
            contact_stage(p, dt, model, state, contacts, control, warped, hyperbolic, overlap,
                          batched, pair_damping)
            if ti.static(atomic_sums):
                k = 0
                if ti.static(batched):
                    k = p // slots_per_scene(contacts)
                scene_sums_atomic(p, k, s, contacts, control)
    for b in range(state.pos.shape[0]):
        if s >= 0 and control.steps_done[0] == s + 1:
            integrate_stage(b, s, dt, model, state, contacts, control, batched)
            k = 0
            if ti.static(batched):
                k = model.scene[b]
            if ti.static(atomic_sums):
                if model.inv_mass[b] > 0.0 and control.active[k] != 0:
                    body_sums_atomic(b, k, state, control)
            if control.probe_slot[s, k] >= 0:  # body b's own state is final: copy it if probed
                for j in range(control.probe_body.shape[1]):
                    if control.probe_body[k, j] == b:
                        probe_stage(k, j, s, state, control)
    if ti.static(not atomic_sums):
        for k in range(control.status.shape[0]):
            if s >= 0 and control.steps_done[0] == s + 1 and control.active[k] != 0:
                energy_stage(k, n_slots, model, state, contacts, control, batched)
                deepest_stage(k, s, n_slots, model, state, contacts, control, batched)


@ti.func
def probe_pair(p, out_depth: ti.template(), out_area: ti.template(), p0, model: ti.template(),
               state: ti.template(), contacts: ti.template(), warped: ti.template(),
               batched: ti.template()):
    """Largest penetration (m) and patch area (m^2) of pair slot p into out_depth[p - p0],
    out_area[p - p0] (p0: the first slot of the probed scene)."""
    i, j = pair_bodies(p, model, contacts, batched)
    hA = model.half[i]
    hB = model.half[j]
    hmin = ti.min(hA.min(), hB.min())
    px = point_buffer()
    py = point_buffer()
    pz = point_buffer()
    dep = point_buffer()
    w = point_buffer()
    _axis, _normal, n_points, _shrink, _centroid, _whole = geometry.box_contact(
        state.pos[i], state.rot[i], hA, state.pos[j], state.rot[j], hB, -1,
        AXIS_MARGIN * hmin, hmin * hmin, model, warped, i, j, px, py, pz, dep, w)
    dmax = 0.0
    patch_area = 0.0
    for q in range(n_points):
        dmax = ti.max(dmax, dep[q])
        patch_area += w[q]
    out_depth[p - p0] = dmax
    out_area[p - p0] = patch_area


@ti.kernel
def probe_contacts(p0: ti.i32, p1: ti.i32, out_depth: ti.types.ndarray(ndim=1),
                   out_area: ti.types.ndarray(ndim=1), model: ModelArgs, state: StateArgs,
                   contacts: ContactArgs, warped: ti.template(), batched: ti.template()):
    """Largest penetration (m) and patch area (m^2) of the pairs of slots [p0, p1) (one
    scene's), into out_depth, out_area [p - p0], without touching the history (overlap checks,
    area caps of the critical step).  ``warped`` (compile time): the narrow phase of imperfect
    faces, as in :func:`advance_serial`."""
    for p in range(p0, p1):
        probe_pair(p, out_depth, out_area, p0, model, state, contacts, warped, batched)


@ti.kernel
def elastic_energy(p0: ti.i32, p1: ti.i32, model: ModelArgs, contacts: ContactArgs,
                   hyperbolic: ti.template(), batched: ti.template()) -> float:
    """Energy stored in the joint springs of the pairs of slots [p0, p1) (one scene's, J).
    Linear normal law (``hyperbolic`` False, compile time): sum of kn A d^2 / 2 + ks A |u|^2 / 2.
    With ``hyperbolic`` each pair's law: A e(d) + ks A |u|^2 / 2 for a hyperbolic pair, e the
    integral of the pressure (laws.hyperbolic_energy), linear pairs as above."""
    e = 0.0
    for p in range(p0, p1):
        i, j = pair_bodies(p, model, contacts, batched)
        pm = pair_material(model, i, j)
        for q in range(contacts.npts[p]):
            a = contacts.area[p, q]
            if ti.static(hyperbolic):
                d = contacts.depth[p, q]
                e_n = 0.5 * pm.kn * d * d
                if pm.law == HYPERBOLIC:
                    e_n = laws.hyperbolic_energy(pm.kn, pm.d_max, pm.d_lim, d)
                e += a * (e_n + 0.5 * pm.ks * contacts.shear[p, q].norm_sqr())
            else:
                e += 0.5 * a * (pm.kn * contacts.depth[p, q] ** 2
                                + pm.ks * contacts.shear[p, q].norm_sqr())
    return e
