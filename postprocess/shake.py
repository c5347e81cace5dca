"""Analysis of one shaking-table run (thesis Chapter 4: Sections 4.2.5 and 4.3): the steps.

:func:`analyze_run` reads a run directory (``case.json``, ``instruments.npz`` or ``frames.npz``)
and writes ``analysis.json``, the PNG plots and ``excited.vtu``; :func:`analyze_signals` analyses
one measuring axis.  Units: SI (m, s, m/s, m/s2, kg, J); phases in degrees.  The pieces:

    postprocess.shake_signals      the signals (u, ds, dsr, a, da ...) from instruments.npz or
                                   frames.npz, and the quantity -> excitation kind table
    postprocess.signal_analysis    drift-free integrals, steady window, amplification, phase lag,
                                   spectrum, hysteresis loop energy, eq 4-4
    postprocess.block_kinematics   angular velocities and the blocks' true kinetic energy
    postprocess.excited            the excited portion, its parts, the mechanism labels
    postprocess.shake_plots        time_histories, spectrum, hysteresis, energy PNGs
    postprocess.excited_output     excited.png and excited.vtu

Per measuring axis, in order (one function each below):
  1. the quantities' amplification, lag and spectrum over the steady window (analyze_signals),
     the low-passed accelerations a_lp, a_front_lp among them (an assumed instrument,
     postprocess.shake_signals) and a's amplification at several cutoffs
     (a_lowpass_sensitivity); beside them the accelerations relative to the table (a_rel,
     da_rel, a_rel_lp, a_front_rel ... and the front / back ratios: ``relative_to_table``,
     docs/table_protocols.md), which the thesis' a and da almost certainly are;
  2. the standing check: a centre that moved by more than the brick's own thickness along e has
     tipped past a rigid block's overturning point (collapse, not a steady response: a warning);
  3. the excited portion (needs frames.npz) and its mass m_e (the reference block's mass without
     a portion);
  4. with a steady window: the unit drift (Section 4.2.5: amplification of dar / height of the
     facade, 1/m); the hysteresis F = m_e a (eq 4-3; a = the centre accelerometer, absolute)
     against ds and its loop energy per cycle; the kinetic energy by eq 4-4 from ds and, with
     the portion and recorded velocities, of its bricks; the mechanism labels (Section 4.3,
     observations: :func:`postprocess.excited.mechanism_labels`);
  5. the plots and excited.vtu.
The first axis is the primary one: its amplification, lag, steady state, unit drift, mechanism
and error are repeated at the top of analysis.json.  ``analyze_run(..., cycles=N)`` analyses the
first N cycles of a longer record as an N-cycle run (nothing written; the prediction study's
cycles check).
"""

from __future__ import annotations

import json
from pathlib import Path

import numpy as np

from dem.output.atomic import write_json
from postprocess.block_kinematics import kinetic_energy_blocks
from postprocess.excited import ExcitedPortion, corner_twist, excited_portion, mechanism_labels
from postprocess.excited_output import plot_elevation, write_vtu
from postprocess.shake_plots import (plot_energy, plot_hysteresis, plot_spectrum,
                                     plot_time_histories)
from postprocess.shake_signals import (KIND_OF, LOWPASS_HZ, LOWPASS_ORDER,
                                       LOWPASS_SENSITIVITY_HZ, ShakeAnalysisError, ShakeSignals,
                                       derived_quantities, load_run, lowpass, lowpass_resolved,
                                       read_signals, truncate, truncate_frames)
from postprocess.signal_analysis import (STEADY_TOL, SteadyWindow, amplification, cycle_peak_mean,
                                         drift_free_integral, kinetic_energy_eq44, loop_energy,
                                         n_complete_cycles, phase_lag, spectral_peaks, spectrum,
                                         steady_window)

__all__ = ["ShakeAnalysisError", "analyze_run", "analyze_signals", "load_run"]


def analyze_signals(sig: ShakeSignals, m_e: float | None = None) -> tuple[dict, dict]:
    """Amplification, lag and spectrum of every quantity of one axis.

    Returns (result dict for analysis.json, arrays for plots: {"q": quantities, "window": ...}).
    """
    q = derived_quantities(sig)
    win = steady_window(sig.t, sig.ds_centre, sig.excitation["displacement"], sig.f, sig.t_end)
    res: dict = {"axis": sig.axis, "direction": sig.direction.tolist(), "source": sig.source,
                 "facade": sig.facade, "side_walls": list(sig.side_walls), "front": sig.front,
                 "instrument_blocks": sig.blocks}
    if win is None:
        n = n_complete_cycles(sig.t, sig.f, sig.t_end)
        res["steady_state"] = None
        res["error"] = (f"only {n} complete excitation cycle(s) of {1 / sig.f:.3f} s in the record "
                        f"(t <= {min(sig.t[-1], sig.t_end):.3f} s); need 2 (cycle 1 is dropped)")
        res["quantities"], res["amplification"], res["lag"] = {}, {}, {}
        return res, {"q": q, "window": None}
    res["steady_state"] = win.as_dict()
    quantities, amp, lag = {}, {}, {}
    for name, y in q.items():
        kind, frame = KIND_OF[name]
        exc = sig.excitation[kind]
        a = amplification(sig.t, y, exc, win)
        p = phase_lag(sig.t, y, exc, sig.f, win)
        s = spectral_peaks(*spectrum(sig.t, y, win))
        quantities[name] = {"kind": kind, "frame": frame, **a, **p, **s}
        amp[name] = a["amplification"]
        lag[name] = {"s": p["lag_s"], "deg": p["lag_deg"]}
    res["quantities"], res["amplification"], res["lag"] = quantities, amp, lag
    if "a" in q:
        res["a_lowpass_sensitivity"] = a_lowpass_sensitivity(sig, q["a"], win)
    return res, {"q": q, "window": win}


def a_lowpass_sensitivity(sig: ShakeSignals, a: np.ndarray, win: SteadyWindow) -> dict:
    """The amplification of the centre accelerometer a [K] (m/s2) unfiltered ("raw") and through
    the assumed instrument low-pass (postprocess.shake_signals.lowpass) at each cutoff of
    LOWPASS_SENSITIVITY_HZ (keys "10", "20", "50": Hz); None where the record's sampling does
    not resolve the cutoff.  The answer depends on the cutoff, which the thesis does not give."""
    exc = sig.excitation["acceleration"]
    out = {"raw": amplification(sig.t, a, exc, win)["amplification"]}
    for c in LOWPASS_SENSITIVITY_HZ:
        out[f"{c:g}"] = (amplification(sig.t, lowpass(a, sig.t, c), exc, win)["amplification"]
                         if lowpass_resolved(sig.t, c) else None)
    return {"cutoffs_hz": list(LOWPASS_SENSITIVITY_HZ), "order": LOWPASS_ORDER,
            "amplification": out}



#: the relative accelerations: quantity -> (kind of the table input it is
#: compared with, what it is)
RELATIVE_QUANTITIES = {
    "a_rel": ("acceleration", "a - a_table: the centre accelerometer relative to the table"),
    "da_rel": ("displacement", "a_rel integrated twice without drift (as da)"),
    "a_rel_lp": ("acceleration", "a_rel through the assumed instrument low-pass (as a_lp)"),
    "a_front_rel": ("acceleration", "a_front - a_table: the front facade's centre, relative"),
    "da_front_rel": ("displacement", "a_front_rel integrated twice without drift"),
    "a_front_rel_lp": ("acceleration", "a_front_rel through the assumed low-pass"),
}


def relative_accelerations(sig: ShakeSignals) -> dict[str, np.ndarray]:
    """The accelerations relative to the table, [K] m/s2 (and the doubly
    integrated m): a_rel = a - a_table with a_table the table's acceleration as the same
    instruments read it (``sig.excitation["acceleration"]``: instruments.npz's table_acc, the
    same mean over the sample interval as a; from frames, the same differences), da_rel its
    drift-free double integral (postprocess.signal_analysis.drift_free_integral, as da), and
    a_rel_lp through the same assumed instrument low-pass as a_lp (the filter is linear:
    a_rel_lp = a_lp - lowpass(a_table)); likewise for the front facade's a_front.  A body
    carried by the table reads 0; the thesis' a and da are almost certainly these (its
    "all amplifications decrease to a level below 0.5" outside the effective range, line 1017,
    is impossible for an absolute acceleration of a body the table carries, and ds = da at
    1.9 Hz, line 1059)."""
    t, a_tab = sig.t, sig.excitation["acceleration"]
    out = {}
    for name, acc in (("a", sig.a_centre), ("a_front", sig.a_front)):
        if acc is None:
            continue
        rel = acc - a_tab
        out[f"{name}_rel"] = rel
        out[f"d{name}_rel"] = drift_free_integral(rel, t, sig.f, sig.t_end, 2)
        if lowpass_resolved(t):
            out[f"{name}_rel_lp"] = lowpass(rel, t)
    return out


def relative_to_table(sig: ShakeSignals, win: SteadyWindow | None) -> dict | None:
    """analysis.json's ``relative_to_table`` of one axis: amplification (against the table's
    acceleration or displacement, the same kind) and lag of each relative quantity over the
    steady window, and the front / back ratios of the relative and of the absolute
    accelerations (thesis Tables 4.9 - 4.11 give front / back amplification ratios: 0.359 Model
    II y, 0.618 Model II x, 0.587 Model III y).  None without a steady window or an
    accelerometer."""
    if win is None or sig.a_centre is None:
        return None
    rel = relative_accelerations(sig)
    quantities, amp = {}, {}
    for name, y in rel.items():
        kind = RELATIVE_QUANTITIES[name][0]
        exc = sig.excitation[kind]
        a = amplification(sig.t, y, exc, win)
        p = phase_lag(sig.t, y, exc, sig.f, win)
        quantities[name] = {"kind": kind, "frame": "relative", **a, **p}
        amp[name] = a["amplification"]
    ratios = {}
    for front, back in (("a_front_rel", "a_rel"), ("a_front_rel_lp", "a_rel_lp"),
                        ("da_front_rel", "da_rel")):
        if front in amp and back in amp and amp[back] > 0:
            ratios[f"{front}/{back}"] = amp[front] / amp[back]
    if sig.a_front is not None:
        exc = sig.excitation["acceleration"]
        a_back = amplification(sig.t, sig.a_centre, exc, win)["amplification"]
        a_front = amplification(sig.t, sig.a_front, exc, win)["amplification"]
        ratios["a_front/a (absolute)"] = a_front / a_back if a_back > 0 else None
    return {"amplification": amp, "quantities": quantities, "front_back_ratio": ratios,
            "definitions": {k: v[1] for k, v in RELATIVE_QUANTITIES.items() if k in rel}}


def analyze_run(run_dir, plots: bool = True, write: bool = True,
                cycles: float | None = None) -> dict:
    """Analyse a shaking run directory; writes analysis.json, PNGs and excited.vtu into it.

    ``cycles``: analyse only the first ``cycles`` excitation cycles of the record, as if the run
    had shaken that many (postprocess.shake_signals.truncate; the header's excitation says so
    and keeps the recorded cycles); nothing is written then (plots and write are ignored: the
    run directory's files stay the full record's).
    Raises ShakeAnalysisError (naming the file or ``cycles``) when the directory cannot be
    analysed.
    """
    from dem.case import ShakeLoading

    run_dir = Path(run_dir)
    case, scene = load_run(run_dir)
    if not isinstance(case.loading, ShakeLoading):
        raise ShakeAnalysisError(f"{run_dir / 'case.json'}: loading.type is "
                                 f"'{case.loading.type}', not 'shake'")
    sigs, frames = read_signals(run_dir, case, scene)
    out = _run_header(run_dir, case)
    if cycles is not None:
        plots = write = False
        sigs = [truncate(s, cycles) for s in sigs]
        frames = truncate_frames(frames, sigs[0].t_end)
        out["excitation"].update({"recorded_cycles": case.loading.cycles, "cycles": cycles,
                                  "t_end_s": sigs[0].t_end,
                                  "truncated": "the first cycles of a longer record "
                                               "(postprocess.shake_signals.truncate)"})
    for sig in sigs:
        sfx = "" if len(sigs) == 1 else f"_{sig.axis}"
        out["axes"][sig.axis] = _analyze_axis(sig, case, scene, frames, out, run_dir, sfx,
                                              plots and write, write)
    _lift_primary(out, sigs[0].axis)
    if write:
        write_json(run_dir / "analysis.json", out, indent=1, strict=True)
    return out


def _run_header(run_dir: Path, case) -> dict:
    """analysis.json before the axes: the run, its excitation and the definitions used."""
    ld = case.loading
    summary_path = run_dir / "summary.json"
    status = json.loads(summary_path.read_text()).get("status") if summary_path.is_file() else None
    return {
        "kind": "shake", "case": case.name, "run_status": status,
        "excitation": {"frequency_hz": ld.frequency, "amplitude_m": ld.displacement_amplitude,
                       "peak_acceleration_m_s2": ld.displacement_amplitude
                       * (2 * np.pi * ld.frequency) ** 2,
                       "direction": list(ld.direction), "cycles": ld.cycles,
                       "t_end_s": ld.cycles / ld.frequency},
        "definitions": {
            "amplification": "(P - N) / (P_in - N_in): means of per-cycle max/min over the steady "
                             "cycles, input of the same kind (table displacement / velocity / "
                             "acceleration); ds, dsr, vs, vsr, ar, dar, var relative; a, da, va "
                             "absolute",
            "lag": "fitted phase at f (c0 + c1 t + R sin(2 pi f t + phi)) over the steady window; "
                   "lag_deg = phi_in - phi_out, lag_s = lag_deg / (360 f)",
            "a_lp": f"a (a_front_lp: a_front) through an ASSUMED instrument low-pass, not a "
                    f"thesis value (the thesis gives no sampling rate or filter): Butterworth "
                    f"order {LOWPASS_ORDER} at {LOWPASS_HZ:g} Hz run forward and backward "
                    f"(scipy.signal.sosfiltfilt; zero phase, |H|^2, -6 dB at {LOWPASS_HZ:g} Hz); "
                    f"compared with the unfiltered table acceleration; a_lowpass_sensitivity: "
                    f"a's amplification raw and at {list(LOWPASS_SENSITIVITY_HZ)} Hz",
            "da": "cumulative trapezoid twice; polynomial c0 + c1 t + c2 t^2 removed (fitted "
                  "jointly with 3 harmonics of f over the shaking); one-period running mean "
                  "removed",
            "steady_state": f"cycle 1 dropped; from the first cycle after which per-cycle "
                            f"peak-to-peak of ds stays within {STEADY_TOL:.0%} of its median, else "
                            f"the last half of the cycles",
        },
        "axes": {}, "plots": [], "warnings": [],
    }


def _analyze_axis(sig: ShakeSignals, case, scene, frames, out: dict, run_dir: Path, sfx: str,
                  plots: bool, write: bool) -> dict:
    """Steps 1 - 5 of the module docstring for one axis; the axis' entry of analysis.json.
    Warnings, plot and VTU file names are appended to ``out``."""
    res, arr = analyze_signals(sig)
    win, q = arr["window"], arr["q"]
    relative = relative_to_table(sig, win)   # the thesis' a, da: docs/table_protocols.md
    if relative is not None:
        res["relative_to_table"] = relative
    _check_standing(res, sig, scene, out["warnings"])
    short = short_window_warning(sig, win)   # a caveat, not a silent number
    if short:
        out["warnings"].append(short)
    portion = None
    if frames is not None and win is not None:
        portion = _find_portion(sig, scene, frames, win, out["warnings"])
    if portion is not None:
        res["excited_portion"] = portion.summary()
    res["m_e_kg"], res["m_e_source"] = _excited_mass(portion, scene, sig)
    energy = None
    if win is not None:
        energy = _steady_results(res, sig, q, win, scene, frames, portion)
    title = f"{case.name}: {sig.axis}, {case.loading.frequency:g} Hz"
    if plots:
        out["plots"] += _plot_axis(run_dir, sfx, title, sig, q, win, res["m_e_kg"], energy)
    if portion is not None and write:
        if plots:
            plot_elevation(run_dir / f"excited{sfx}.png", scene, portion, title)
            out["plots"].append(f"excited{sfx}.png")
        write_vtu(run_dir / f"excited{sfx}.vtu", scene, portion)
        out.setdefault("vtk", []).append(f"excited{sfx}.vtu")
    return res


#: fewest steady cycles an amplification is taken from without a caveat
MIN_STEADY_CYCLES = 3


def short_window_warning(sig: ShakeSignals, win: SteadyWindow | None) -> str | None:
    """A warning when the steady window holds fewer than MIN_STEADY_CYCLES cycles.

    The window is "steady" when every per-cycle peak-to-peak of ds stays within STEADY_TOL of
    their median (postprocess.signal_analysis.steady_window): with one cycle that test compares
    the cycle with itself and with two with their mean, so nothing says the response is
    steady; three cycles are the fewest where the median is a cycle of its own and one odd
    cycle shows.  The amplification is then the peaks of n cycles, not a mean over a steady
    state, and the spectrum over the window T = n / f has bins df = 1 / T = f / n Hz apart
    (f / 1 at one cycle: the excitation's bin and its neighbours, no peak can be told apart).
    The thesis' runs had 50 cycles."""
    if win is None or win.n_cycles >= MIN_STEADY_CYCLES:
        return None
    T = win.n_cycles / sig.f
    return (f"{sig.axis}: the steady window holds only {win.n_cycles} cycle(s) "
            f"({win.t0:.3g} - {win.t1:.3g} s) of the {sig.t_end * sig.f:.3g} shaken: the "
            f"amplification and lag come from {win.n_cycles} cycle(s) with no check that the "
            f"response is steady (fewer than {MIN_STEADY_CYCLES}), and the spectrum's "
            f"resolution is 1 / {T:.3g} s = {1 / T:.3g} Hz; shake longer (the thesis: 50 cycles) "
            f"for a result that means something")


def _check_standing(res: dict, sig: ShakeSignals, scene, warnings: list) -> None:
    """Step 2: a steady response needs the facade standing: a centre that moved by more than the
    brick's own thickness along e has tipped past a rigid block's overturning point."""
    ref = sig.blocks["centre"]
    thick = float(np.abs(scene.rotation_matrices()[ref].T @ sig.direction) @ scene.size[ref])
    shaking = sig.t <= sig.t_end + 1e-9
    moved = float(np.abs(sig.ds_centre[shaking]).max())
    res["max_abs_ds_m"], res["collapse_suspected"] = moved, bool(moved > thick)
    if moved > thick:
        warnings.append(
            f"{sig.axis}: the centre moved {moved * 1e3:.1f} mm relative to the table, more "
            f"than its thickness {thick * 1e3:.0f} mm: collapse, not a steady response")


def _find_portion(sig: ShakeSignals, scene, frames, win: SteadyWindow, warnings: list
                  ) -> ExcitedPortion | None:
    """Step 3: the excited portion over the steady window, or None (with a warning) if it fails."""
    try:
        return excited_portion(scene, frames, sig.f, win.t0, win.t1, sig.direction,
                               ref_block=sig.blocks["centre"], facade=sig.facade,
                               side_walls=sig.side_walls)
    except Exception as err:  # noqa: BLE001 - the rest of the analysis still lands
        warnings.append(f"{sig.axis}: excited portion failed: {err}")
        return None


def _excited_mass(portion: ExcitedPortion | None, scene, sig: ShakeSignals) -> tuple[float, str]:
    """Step 3: m_e (kg) and where it comes from."""
    if portion is None:
        return float(scene.mass[sig.blocks["centre"]]), "reference block (no frames)"
    if not portion.excited.any():
        return float(scene.mass[sig.blocks["centre"]]), \
            "reference block (no excited portion found)"
    return portion.mass, "bricks of the excited portion"


def _facade_height(scene, sig: ShakeSignals) -> float:
    if sig.facade is not None and sig.facade in scene.group_names:
        m = scene.group == scene.group_names.index(sig.facade)
    else:
        m = np.zeros(scene.n_blocks, bool)
        m[sig.blocks["centre"]] = True
    return float((scene.position[m, 2] + 0.5 * scene.size[m, 2]).max())


def _steady_results(res: dict, sig: ShakeSignals, q: dict, win: SteadyWindow, scene, frames,
                    portion: ExcitedPortion | None) -> dict:
    """Step 4: unit drift, hysteresis, kinetic energies and mechanism labels into ``res``;
    returns the energy histories for the plot."""
    m_e = res["m_e_kg"]
    A = res["amplification"]
    H = _facade_height(scene, sig)
    res["facade_height_m"] = H
    res["unit_drift_per_m"] = A["dar"] / H if "dar" in A else None
    if "a" in q:
        E = loop_energy(sig.t, m_e * q["a"], q["ds"], sig.f, win)
        res["hysteresis"] = {"m_e_kg": m_e, "loop_energy_J_mean": float(np.mean(E)),
                             "loop_energy_J_per_cycle": E.tolist()}
    res["kinetic_energy"], energy = _kinetic_energy(sig, q, win, scene, frames, portion, m_e)
    if portion is not None:
        twist = None
        if frames is not None and "corner_a" in sig.blocks:
            twist = corner_twist(frames, scene, [sig.blocks["corner_a"],
                                                 sig.blocks.get("corner_b")],
                                 sig.f, win.t0, win.t1)
        res["mechanism"] = mechanism_labels(res["quantities"], q, sig, win, portion, twist)
    return energy


def _kinetic_energy(sig: ShakeSignals, q: dict, win: SteadyWindow, scene, frames,
                    portion: ExcitedPortion | None, m_e: float) -> tuple[dict, dict]:
    """Step 4: peak kinetic energies by eq 4-4 and, with an excited portion and recorded
    velocities, of its bricks; (the analysis.json entry, the histories for the plot)."""
    e44 = kinetic_energy_eq44(q["ds"], sig.f, m_e)
    ke = {"eq_4_4_peak_J": cycle_peak_mean(sig.t, e44, sig.f, win),
          "definition": "means over the steady cycles of the per-cycle maximum"}
    e_bl = t_bl = None
    if portion is not None and portion.excited.any() and "vel" in frames:
        t_bl = np.asarray(frames["t"], float)
        e_bl = kinetic_energy_blocks(t_bl, frames["vel"], frames["quat"], scene,
                                     np.flatnonzero(portion.excited))
        ke["blocks_peak_J"] = cycle_peak_mean(t_bl, e_bl, sig.f, win)
        ke["ratio_eq44_over_blocks"] = (ke["eq_4_4_peak_J"] / ke["blocks_peak_J"]
                                        if ke["blocks_peak_J"] > 0 else None)
    return ke, {"eq44": e44, "t_blocks": t_bl, "blocks": e_bl}


def _plot_axis(run_dir: Path, sfx: str, title: str, sig: ShakeSignals, q: dict,
               win: SteadyWindow | None, m_e: float, energy: dict | None) -> list[str]:
    """Step 5: the PNGs of one axis (only the time histories without a steady window)."""
    plot_time_histories(run_dir / f"time_histories{sfx}.png", sig, q, win, title)
    if win is None:
        return [f"time_histories{sfx}.png"]
    plot_spectrum(run_dir / f"spectrum{sfx}.png", sig, q, win, title)
    names = [f"time_histories{sfx}.png", f"spectrum{sfx}.png"]
    if "a" in q:
        plot_hysteresis(run_dir / f"hysteresis{sfx}.png", sig.t, q["ds"], m_e * q["a"], win,
                        f"{title}, m_e = {m_e:.2f} kg")
        names.append(f"hysteresis{sfx}.png")
    plot_energy(run_dir / f"energy{sfx}.png", sig.t, energy["eq44"], energy["t_blocks"],
                energy["blocks"], win, title)
    names.append(f"energy{sfx}.png")
    return names


def _lift_primary(out: dict, axis: str) -> None:
    """The primary (first) axis' headline results, repeated at the top of analysis.json."""
    primary = out["axes"][axis]
    out["primary_axis"] = axis
    for key in ("amplification", "lag", "steady_state", "unit_drift_per_m", "mechanism", "error"):
        if key in primary:
            out[key] = primary[key]
