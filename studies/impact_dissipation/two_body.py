"""The two-body model (dem.rocking) runs of the study: free and forced, with Housner's impact law
or a measured restitution.
"""

from __future__ import annotations

import math
import time

import numpy as np

from studies.impact_dissipation.physics import half_cycle_peaks, housner_r_block, impact_ratios


# ------------------------------------------------------------------------------------------
# two-body model
# ------------------------------------------------------------------------------------------
def two_body_params(masses="table-5.1", top_load=0.0, top_friction=0.0, top_contact="sliding"):
    from dem.rocking.params import RockingParams

    m1, m2 = (6.05, 9.41) if masses == "table-5.1" else masses
    return RockingParams(thickness=0.05, h1=0.14, m1=m1, h2=0.14, m2=m2, top_load=top_load,
                         top_friction=top_friction, top_contact=top_contact)


def two_body_free(P, initial, restitution="housner", duration: float = 1.5,
                  measure: str = "whole") -> dict:
    """Free motion of the two-body model from ``initial`` = (theta1, theta2, omega1, omega2)
    (absolute; rad, rad/s), no table motion, its own impact map.  ``measure = "whole"``: the
    half cycles of theta_eq = d / (H1 + H2), d = H1 sin theta1 + H2 sin theta2, energies with the
    locked pair's (c, z) = (T/2, z_G); ``"upper"``: those of theta2 with Part 2's (T/2, H2/2)."""
    from dem.rocking.analysis import centre_of_mass_height, housner_restitution
    from dem.rocking.integrate import Settings, integrate_rocking
    from dem.table_motion import TableMotion

    res = integrate_rocking(P, TableMotion(), Settings(duration=duration, output_interval=2e-4,
                                                       restitution=restitution), tuple(initial))
    if measure == "upper":
        th = np.asarray(res.theta2)
        cz = (P.thickness / 2, P.h2 / 2)
    else:
        th = (P.h1 * np.sin(res.theta1) + P.h2 * np.sin(res.theta2)) / P.height
        cz = (P.thickness / 2, centre_of_mass_height(P))
    tp, pk = half_cycle_peaks(res.t, th)
    out = impact_ratios(pk, cz)
    out.update({"restitution": restitution, "housner_restitution_locked": housner_restitution(P),
                "housner_r_part2": housner_r_block(P.thickness, P.h2),
                "m1_kg": P.m1, "m2_kg": P.m2, "initial": list(initial), "measure": measure,
                "status": res.status, "impacts_base": res.stats["impacts_base"],
                "impacts_interface": res.stats["impacts_interface"],
                "_t": np.asarray(res.t), "_theta": th})
    return out


def two_body_forced(P, f: float, peak_acc: float, restitution="housner", cycles: float = 20,
                    margin: float = 1.0) -> dict:
    """Model II y in the two-body model under a sine of peak acceleration ``peak_acc`` (m/s2) at
    f (Hz) for ``cycles`` cycles + ``margin`` s: status, uplift, steady amplitude of the top
    displacement d (mean of the per-cycle max / min over the last half of the cycles, m) and its
    amplification (P - N) / (2 A), A the table's displacement amplitude."""
    from dem.rocking.analysis import cycle_amplitudes
    from dem.rocking.integrate import Settings, RockingError, integrate_rocking
    from dem.table_motion import SineMotion

    w = 2 * math.pi * f
    A = peak_acc / (w * w)
    exc = SineMotion(A, f, cycles)
    dur = cycles / f + margin
    t0 = time.process_time()
    try:
        res = integrate_rocking(P, exc, Settings(duration=dur, output_interval=1e-3,
                                                 restitution=restitution), (0, 0, 0, 0))
    except RockingError as err:
        res = err.partial
    cpu = time.process_time() - t0
    d = P.h1 * np.sin(res.theta1) + P.h2 * np.sin(res.theta2)
    moved = bool(np.any(np.abs(d) > 1e-9))
    uplift = next((e["t"] for e in res.events if e["kind"].startswith("leave")), None)
    out = {"f_hz": f, "peak_acc_m_s2": peak_acc, "amplitude_m": A, "restitution": restitution,
           "status": res.status, "t_end_s": float(res.t[-1]) if len(res.t) else 0.0,
           "uplift_s": uplift, "max_abs_d_m": float(np.abs(d).max()) if len(d) else 0.0,
           "impacts": int(res.stats["impacts_base"] + res.stats["impacts_interface"]),
           "cpu_s": cpu, "steady_P_m": None, "steady_N_m": None, "amplification": None}
    if res.status == "ok":
        period = 1.0 / f
        idx, mx, mn = cycle_amplitudes(res.t, d, period, cycles / f)
        half = idx >= cycles // 2
        if half.any():
            Pm, Nm = float(mx[half].mean()), float(mn[half].mean())
            out.update({"steady_P_m": Pm, "steady_N_m": Nm,
                        "amplification": (Pm - Nm) / (2 * A) if moved else 0.0})
    return out


