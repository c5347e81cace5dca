"""Impacts of the two-block model: velocity jumps when a joint closes (or the beam changes corner).

Moreau's plastic impact, which is Housner's for one block: the post-impact velocities minimise the
kinetic energy of the velocity jump, in the metric of the mass matrix M (maximal coordinates),
over the velocities allowed by the post-impact contacts G:

    M (v+ - v-) = G^T Lambda,   G v+ = 0.

The post-impact contact modes are enumerated (the velocity-level LCP); the one whose normal
impulses are compressive and whose released corners separate is taken.  A joint that closes with
a rate below ``zeno_velocity`` is locked (the end of an accumulation of impacts).  With a
restitution number e the plastic velocity direction is kept with e^2 of the kinetic energy.
"""

from __future__ import annotations

import math

import numpy as np

from dem.rocking.maximal import contact_rows, mass6, maximal_velocity, mode_row_keys
from dem.rocking.modes import TOL_REL
from dem.rocking.params import RockingParams
from dem.rocking.patterns import geometry


def bb_default(b, bs):
    return b if b in bs else bs[0]


def cc_default(c, cs):
    return c if c in cs else cs[0]


class ImpactResolver:
    """Plastic impacts and joint locks.  ``S``: the run's Settings (restitution, zeno_velocity);
    ``stats``: the run's counters (impact outcomes are counted here)."""

    def __init__(self, P: RockingParams, S, stats: dict):
        self.P, self.S, self.stats = P, S, stats

    def resolve(self, mode, y, closing):
        """Plastic (Moreau / Housner) impact, then the restitution rule; returns (mode, y, info).

        The post-impact velocities minimise the kinetic energy of the velocity jump, in the
        metric of the mass matrix, over the velocities allowed by the post-impact contact modes:
        M (v+ - v-) = G^T Lambda, G v+ = 0.  Candidate post modes are enumerated; the one whose
        normal impulses are compressive and whose released corners separate is taken.
        """
        P, S = self.P, self.S
        b, c, tau, sig = mode
        th1, phi, w1, wphi = y
        th2, w2 = th1 + phi, w1 + wphi
        s1, s2 = geometry(P, b, c)
        v_minus = maximal_velocity(P, s1, s2, th1, th2, w1, w2, sig)
        M = mass6(P)
        ke_minus = 0.5 * v_minus @ M @ v_minus
        p_scale = max(np.linalg.norm(M @ v_minus), 1e-300)
        tol_p = TOL_REL * p_scale
        tol_v = TOL_REL * max(np.max(np.abs(v_minus)), 1e-300)
        base_zero = th1 == 0.0
        if_zero = phi == 0.0
        # co-moving top load: at theta2 = 0 the beam may pass to the other top corner (the rising
        # corner strikes it); the post-impact corner is chosen with the other contacts
        beam_zero = P.comoving and P.load_point == "corner" and th2 == 0.0
        bs = [1, -1, 0] if base_zero else [b]
        cs = ([0] if P.locked else [1, -1, 0]) if if_zero else [c]
        ss = [-sig, sig] if beam_zero else [sig]
        n1 = np.array([math.sin(th1), math.cos(th1)])
        best = None
        order = [(bb, cc, sg) for bb in bs for cc in cs for sg in ss]
        # the usual outcome first: the closing joint swaps corners, the others keep their mode
        natural = (-b if base_zero and b != 0 else bb_default(b, bs),
                   -c if if_zero and c != 0 else cc_default(c, cs), ss[0])
        if natural in order:
            order.remove(natural)
            order.insert(0, natural)
        for bb, cc, sg in order:
            vplus, lam, rows = self.plastic(bb, cc, th1, th2, v_minus, M, sg)
            conds = []
            if beam_zero:
                # the beam's new corner pushes it up; the corner it leaves separates from it
                k, o = ("+", "-") if sg > 0 else ("-", "+")
                conds += [lam["beam_z" + k] / tol_p, rows["beam_z" + o] @ vplus / tol_v]
            if base_zero:
                if bb != 0:
                    k, o = ("+", "-") if bb > 0 else ("-", "+")
                    conds += [lam["base_z" + k] / tol_p, rows["base_z" + o] @ vplus / tol_v]
                else:
                    conds += [lam["base_z+"] / tol_p, lam["base_z-"] / tol_p]
            if if_zero and not P.locked:
                if cc != 0:
                    k, o = ("+", "-") if cc > 0 else ("-", "+")
                    ln = n1 @ np.array([lam["if_x" + k], lam["if_z" + k]])
                    conds += [ln / tol_p, rows["if_n" + o] @ vplus / tol_v]
                else:
                    ln = n1 @ np.array([lam["if_x+"], lam["if_z+"]])
                    conds += [ln / tol_p, lam["if_n-"] / tol_p]
            margin = min(conds) if conds else math.inf
            n_flat = int(bb == 0) + int(cc == 0)
            # consistent first, strictly consistent next; among marginal ones (zero post-impact
            # rate) prefer locking, the acceleration-level choice then decides about lift-off
            key = (margin >= -1.0, margin > 1.0, n_flat, margin)
            if best is None or key > best[0]:
                best = (key, bb, cc, sg, vplus, lam)
            if margin > 1.0:   # strictly consistent: the unique solution of the LCP
                break
        (consistent, _, _, margin), bb, cc, sg, vplus, lam = best
        if not consistent:
            self.stats["inconsistent_impacts"] += 1
        # persistent pivots pulled apart (flight would be needed; the model keeps contact)
        if not base_zero and lam.get("base_z" + ("+" if bb > 0 else "-"), 0.0) < -tol_p:
            self.stats["tension_impulses"] += 1
        if not if_zero and cc != 0:
            k = "+" if cc > 0 else "-"
            if n1 @ np.array([lam["if_x" + k], lam["if_z" + k]]) < -tol_p:
                self.stats["tension_impulses"] += 1
        # Zeno: a contact that closes with a negligible rate is locked
        w1p, w2p = vplus[2], vplus[5]
        relock = False
        if base_zero and bb != 0 and abs(w1p) < S.zeno_velocity:
            bb, relock = 0, True
        if if_zero and cc != 0 and abs(w2p - w1p) < S.zeno_velocity:
            cc, relock = 0, True
        if relock:
            self.stats["zeno_locks"] += 1
            vplus, lam, _ = self.plastic(bb, cc, th1, th2, v_minus, M, sg)
        if P.comoving:
            # friction the beam would need to follow the top through the impact: |H| / V of the
            # impulse it receives at its corner (a stick-slip condition would be <= mu)
            k = "+" if sg > 0 else "-"
            jx, jz = lam["beam_x" + k], lam["beam_z" + k]
            if jz > tol_p:
                self.stats["top_impulse_ratio_max"] = max(
                    self.stats.get("top_impulse_ratio_max", 0.0), float(abs(jx) / jz))
            if beam_zero and sg != sig:
                self.stats["impacts_top"] = self.stats.get("impacts_top", 0) + 1
        # restitution: a number e keeps the plastic velocity direction and e^2 of the energy
        if S.restitution != "housner":
            ke_plus = 0.5 * vplus @ M @ vplus
            if ke_plus > 1e-300:
                vplus = vplus * (float(S.restitution) * math.sqrt(ke_minus / ke_plus))
        ke_after = 0.5 * vplus @ M @ vplus
        w1p, w2p = float(vplus[2]), float(vplus[5])
        if bb == 0:
            w1p = 0.0
        if cc == 0:
            w2p = w1p
        y_new = (th1, phi, w1p, w2p - w1p)
        info = {"ke_before": float(ke_minus), "ke_after": float(ke_after), "margin": float(margin)}
        return (bb, cc, sg), y_new, info

    def lock(self, mode, y, lock_b, lock_c):
        """Plastic lock of the joint(s) that reclose at once (base if ``lock_b``, interface if
        ``lock_c``); returns (b, c, y) after the lock.  With a restitution number the lock keeps
        the kinetic energy (e was applied at the impact that started this flight)."""
        P = self.P
        b, c, tau, sig = mode
        th1, phi, w1, wphi = y
        s1, s2 = geometry(P, b, c)
        v = maximal_velocity(P, s1, s2, th1, th1 + phi, w1, w1 + wphi, sig)
        bb, cc = (0 if lock_b else b), (0 if lock_c else c)
        M = mass6(P)
        vp, _, _ = self.plastic(bb, cc, th1, th1 + phi, v, M, sig)
        if self.S.restitution != "housner":
            ke0, ke1 = 0.5 * v @ M @ v, 0.5 * vp @ M @ vp
            if ke1 > 1e-300:
                vp = vp * math.sqrt(ke0 / ke1)
        w1p, w2p = (0.0 if bb == 0 else float(vp[2])), float(vp[5])
        if cc == 0:
            w2p = w1p
        return bb, cc, (th1, phi, w1p, w2p - w1p)

    def plastic(self, bb, cc, th1, th2, v_minus, M, sig=1):
        """Plastic impact onto the modes (bb, cc) (beam on the corner sigma = sig if co-moving):
        M (v+ - v-) = G^T Lambda, G v+ = 0; returns v+, the impulses Lambda by row, the rows."""
        P = self.P
        s1, s2 = geometry(P, bb, cc)
        rows, _ = contact_rows(P, s1, s2, th1, th2)
        keys = mode_row_keys(bb, cc, sig, P.comoving)
        G = np.array([rows[k] for k in keys])
        n = len(keys)
        nd = len(v_minus)
        K = np.zeros((nd + n, nd + n))
        K[:nd, :nd] = M
        K[:nd, nd:] = -G.T
        K[nd:, :nd] = G
        sol = np.linalg.solve(K, np.concatenate([M @ v_minus, np.zeros(n)]))
        return sol[:nd], dict(zip(keys, sol[nd:])), rows
