"""Run a two-body case and write its outputs: the model-level half of ``dem rocking`` (the
command itself, with its exit codes, is dem_cli.commands.rocking).

Outputs (contract of ../shared/DESIGN.md, extended):

* ``rocking.npz``: ``t`` [T] s; ``theta1``, ``theta2`` [T] rad (absolute); ``omega1``,
  ``omega2`` [T] rad/s; ``pattern`` [T] str ("1A" .. "4B", "rest"); ``top_disp`` [T] m
  (d = H1 sin theta1 + H2 sin theta2); extensions: ``top_stick`` [T] bool, ``mode`` [T, 4] int8
  (b, c, tau, sigma, see dem.rocking.patterns), ``base_disp``, ``base_acc`` [T] (m, m/s2, along the
  loading direction), ``kinetic_energy``, ``potential_energy`` [T] J, ``cycle_index``,
  ``cycle_max``, ``cycle_min`` (top displacement per excitation cycle, m), ``peak_t``,
  ``peak_disp`` (extreme of every rocking oscillation), ``event_t``, ``event_kind``,
  ``event_before``, ``event_after`` (the exact event log);
* ``summary.json`` (name, status, message, model, loading, closed-form thresholds, pattern
  statistics, amplitudes, event counts, sim_time, wall_seconds ...);
* ``events.csv``; ``rocking.png`` (time histories), ``amplitudes.png`` (per cycle).
"""

from __future__ import annotations

from pathlib import Path

import numpy as np

from dem.output import atomic
from dem.output.atomic import savefig as _atomic_savefig
from dem.output.plotting import agg_pyplot
from dem.rocking import analysis as an
from dem.rocking.energy import energy_arrays
from dem.rocking.integrate import RockingError, RockingResult, integrate_rocking
from dem.rocking.patterns import PATTERNS
from dem.rocking.schema import (
    RockingCase,
    excitation_from_case,
    initial_from_case,
    params_from_case,
    settings_from_case,
)


def run_rocking_case(case: RockingCase):
    """Simulate a validated case; returns (params, excitation, result, error or None)."""
    P = params_from_case(case)
    exc = excitation_from_case(case)
    S = settings_from_case(case)
    try:
        res = integrate_rocking(P, exc, S, initial_from_case(case))
        return P, exc, res, None
    except RockingError as err:
        return P, exc, err.partial, err


def loading_summary(case: RockingCase, exc) -> dict:
    """summary.json's ``loading``, in the DEM's layout (dem.loading.Shake.describe): the table
    moves by amplitude_m * direction * sin(2 pi f t), here with the unit direction of the case."""
    if case.loading.type == "none":
        return exc.describe()
    d = np.asarray(case.loading.direction, dtype=float)
    return {"type": "shake", "direction": (d / np.linalg.norm(d)).tolist(), **exc.describe()}


def summarize(case: RockingCase, P, exc, res: RockingResult, wall: float) -> tuple[dict, dict]:
    """summary.json content and the derived arrays for rocking.npz."""
    d = an.top_displacement(P, res.theta1, res.theta2)
    t_end = float(res.t[-1]) if len(res.t) else 0.0
    arrays = {}
    if exc.period:
        ci, cmax, cmin = an.cycle_amplitudes(res.t, d, exc.period, min(exc.t_end, t_end + 1e-12))
    else:
        ci, cmax, cmin = np.zeros(0, int), np.zeros(0), np.zeros(0)
    tp, dp = an.oscillation_peaks(res.t, d)
    arrays.update(cycle_index=ci, cycle_max=cmax, cycle_min=cmin, peak_t=tp, peak_disp=dp)
    stats, merged = an.pattern_statistics(res.episodes, t_end)
    moving = {k: v for k, v in stats.items() if k != "rest"}
    kinds = {}
    for e in res.events:
        kinds[e["kind"]] = kinds.get(e["kind"], 0) + 1
    uplift = next((e["t"] for e in res.events if e["before"] == "rest"), None)
    # steady state: the second half of the shaking cycles
    amp = {}
    half = ci >= (ci.max() + 1) / 2 if len(ci) else np.zeros(0, bool)
    if half.any() and res.status == "ok":  # none: the run ended before the second half
        amp = {
            "positive_mean_m": float(np.mean(cmax[half])),
            "negative_mean_m": float(np.mean(cmin[half])),
            "positive_max_m": float(cmax.max()),
            "negative_min_m": float(cmin.min()),
            "peak_to_peak_mean_m": float(np.mean(cmax[half] - cmin[half])),
        }
    summary = {
        "name": case.name,
        "description": case.description,
        "status": res.status,
        "message": res.message,
        "model": {
            "thickness": P.thickness, "h1": P.h1, "m1": P.m1, "h2": P.h2, "m2": P.m2,
            "top_load": P.top_load, "top_friction": P.top_friction, "gravity": P.gravity,
            "restitution": case.rocking.restitution, "top_load_point": P.load_point,
            "locked": P.locked, "top_contact": P.top_contact,
            "top_mass_kg": P.mN,
        },
        "loading": loading_summary(case, exc),
        "closed_form": {
            # thresholds of the chosen top contact (docs/rocking_model.md, section 4)
            "top_contact": P.top_contact,
            "uplift_threshold_whole_m_s2": an.uplift_threshold(P, "whole"),
            "uplift_threshold_upper_m_s2": an.uplift_threshold(P, "upper"),
            "uplift_threshold_m_s2": an.uplift_thresholds(P)["governing"],
            "first_pattern": an.uplift_thresholds(P)["first_pattern"],
            "thesis_eq_5_4_threshold_m_s2": an.thesis_uplift_threshold(P),
            "housner_restitution_locked": an.housner_restitution(P),
            "peak_over_threshold": (exc.peak_acceleration / an.uplift_thresholds(P)["governing"])
            if getattr(exc, "peak_acceleration", None) else None,
        },
        "sim_time": t_end,
        "wall_seconds": wall,
        "integration_seconds": res.wall_seconds,
        "n_samples": int(len(res.t)),
        "output_interval": case.run.output_interval,
        "first_uplift_time": uplift,
        "events": kinds,
        "patterns": stats,
        "most_frequent_pattern_by_occurrences": max(moving, key=lambda k: moving[k]["occurrences"])
        if moving else "rest",
        "most_frequent_pattern_by_time": max(moving, key=lambda k: moving[k]["time_fraction"])
        if moving else "rest",
        "pattern_sequence": [p for _, _, p in merged][:200],
        "response": {
            "max_abs_theta1_rad": float(np.abs(res.theta1).max()) if len(res.t) else 0.0,
            "max_abs_theta2_rad": float(np.abs(res.theta2).max()) if len(res.t) else 0.0,
            "top_disp_max_m": float(d.max()) if len(d) else 0.0,
            "top_disp_min_m": float(d.min()) if len(d) else 0.0,
            "amplitude_steady": amp,
            "oscillations": int(len(tp)),
        },
        "diagnostics": res.stats,
    }
    if P.comoving:
        summary["top_friction_demand"] = an.top_friction_demand(P, res, exc)
    return summary, arrays


def nonfinite_fields(data, prefix: str = "") -> list[str]:
    """The paths of the NaN / inf numbers in a (nested) summary dict."""
    bad = []
    if isinstance(data, dict):
        for k, v in data.items():
            bad += nonfinite_fields(v, f"{prefix}.{k}" if prefix else str(k))
    elif isinstance(data, (list, tuple)):
        for i, v in enumerate(data):
            bad += nonfinite_fields(v, f"{prefix}[{i}]")
    elif isinstance(data, (float, np.floating)) and not np.isfinite(data):
        bad.append(prefix)
    return bad


def _fail_nonfinite(summary: dict, res: RockingResult) -> None:
    """A NaN or inf anywhere in the state or the summary is a failed run, never ``ok`` (a
    two-body case at 2.8e5 Hz would otherwise print 'nan mm' and exit 0)."""
    bad = [k for k in ("theta1", "theta2", "omega1", "omega2")
           if len(getattr(res, k)) and not np.all(np.isfinite(getattr(res, k)))]
    bad += nonfinite_fields({k: summary.get(k) for k in ("response", "closed_form",
                                                         "sim_time")})
    if bad:
        summary["status"] = "failed"
        summary["message"] = (f"non-finite result (NaN or inf) in {', '.join(bad[:5])}"
                              + (f" and {len(bad) - 5} more" if len(bad) > 5 else "")
                              + (f"; before: {res.status}: {res.message}" if res.message
                                 else ""))


def write_outputs(out: Path, case: RockingCase, P, exc, res: RockingResult, wall: float,
                  plots: bool = True) -> dict:
    """Every output file (module docstring), each through dem.output.atomic.  A write that
    fails (a full disk) does not stop the others; summary.json then says ``failed`` with
    ``write_errors`` (a minimal one if the full one cannot be written) and
    dem.output.atomic.OutputError is raised (exit 1), as for a DEM run (dem.run.write)."""
    out.mkdir(parents=True, exist_ok=True)
    summary, arrays = summarize(case, P, exc, res, wall)
    _fail_nonfinite(summary, res)
    errors: dict[str, str] = {}

    def guarded(name, fn, *args) -> None:
        try:
            fn(*args)
        except OSError as err:
            errors[name] = f"{err.strerror or err}" + (f" (errno {err.errno})" if err.errno
                                                       else "")

    d = an.top_displacement(P, res.theta1, res.theta2)
    ke, v = energy_arrays(P, res.theta1, res.theta2, res.omega1, res.omega2,
                          res.mode[:, 0], res.mode[:, 1], res.mode[:, 3]) if len(res.t) else \
        (np.zeros(0), np.zeros(0))
    ev = res.events
    guarded("rocking.npz", atomic.save_npz, out / "rocking.npz", dict(
        t=res.t, theta1=res.theta1, theta2=res.theta2, omega1=res.omega1, omega2=res.omega2,
        pattern=res.pattern.astype("<U4"), top_disp=d, top_stick=res.top_stick, mode=res.mode,
        base_disp=exc.displacement(res.t), base_acc=exc.acceleration(res.t),
        kinetic_energy=ke, potential_energy=v,
        event_t=np.array([e["t"] for e in ev], dtype=float),
        event_kind=np.array([e["kind"] for e in ev], dtype="<U20"),
        event_before=np.array([e["before"] for e in ev], dtype="<U4"),
        event_after=np.array([e["after"] for e in ev], dtype="<U4"),
        **arrays,
    ))
    guarded("events.csv", atomic.write_text, out / "events.csv",
            "t_s,kind,before,after\n" + "".join(
                f"{e['t']:.12g},{e['kind']},{e['before']},{e['after']}\n" for e in ev))
    if plots and len(res.t) and not errors:
        try:
            plot_results(out, case, P, exc, res, d, arrays)
        except OSError as err:
            errors["plots"] = f"{err.strerror or err}"
        except Exception as err:  # a plot must never lose the run's data
            summary["plot_error"] = f"{type(err).__name__}: {err}"
    if errors:
        summary["status"] = "failed"
        summary["write_errors"] = dict(errors)
    try:
        atomic.write_json(out / "summary.json", summary)
    except OSError as err:
        errors["summary.json"] = f"{err.strerror or err}"
        small = {k: summary.get(k) for k in ("name", "status", "message", "sim_time")}
        small["write_errors"] = dict(errors)
        try:
            atomic.write_json(out / "summary.json", small)
        except OSError:
            pass
    if errors:
        first = next(iter(errors))
        raise atomic.OutputError(
            None, f"cannot write the output in {out}: {first}: {errors[first]}"
            + ("; summary.json says failed" if (out / "summary.json").is_file()
               else "; no summary.json could be written"))
    return summary


def plot_results(out: Path, case, P, exc, res, d, arrays) -> None:
    plt = agg_pyplot()

    t = res.t
    fig, ax = plt.subplots(4, 1, figsize=(11, 10), sharex=True)
    ax[0].plot(t, res.theta1, lw=0.8, label=r"$\theta_1$ (Part 1)")
    ax[0].plot(t, res.theta2, lw=0.8, label=r"$\theta_2$ (Part 2)")
    ax[0].set_ylabel("angle (rad)")
    ax[0].legend(loc="upper right")
    ax[1].plot(t, 1e3 * d, lw=0.8, label="top displacement d")
    ax[1].plot(t, 1e3 * exc.displacement(t), lw=0.6, color="0.6", label="table displacement")
    ax[1].set_ylabel("mm")
    ax[1].legend(loc="upper right")
    ax[2].plot(t, exc.acceleration(t), lw=0.6, color="0.4")
    thr = an.uplift_threshold(P)
    for s in (1, -1):
        ax[2].axhline(s * thr, color="r", lw=0.6, ls="--")
    ax[2].set_ylabel("table acc. (m/s2)")
    ax[2].set_title("dashed: uplift threshold (closed form)", fontsize=8)
    levels = {p: i for i, p in enumerate(PATTERNS)}
    ax[3].step(t, [levels[p] for p in res.pattern], where="post", lw=0.8)
    ax[3].set_yticks(range(len(PATTERNS)), PATTERNS)
    ax[3].set_ylabel("pattern")
    ax[3].set_xlabel("t (s)")
    fig.suptitle(f"{case.name}: {res.status}", fontsize=10)
    fig.tight_layout()
    _atomic_savefig(fig, out / "rocking.png", dpi=110)
    plt.close(fig)

    fig, ax = plt.subplots(1, 1, figsize=(9, 4))
    if len(arrays["cycle_index"]):
        ax.plot(arrays["cycle_index"] + 1, 1e3 * arrays["cycle_max"], "o-", ms=3, label="max per cycle")
        ax.plot(arrays["cycle_index"] + 1, 1e3 * arrays["cycle_min"], "s-", ms=3, label="min per cycle")
        ax.set_xlabel("excitation cycle")
    else:
        ax.plot(arrays["peak_t"], 1e3 * arrays["peak_disp"], "o", ms=3, label="oscillation peaks")
        ax.set_xlabel("t (s)")
    ax.set_ylabel("top displacement (mm)")
    ax.legend()
    ax.set_title(case.name, fontsize=10)
    fig.tight_layout()
    _atomic_savefig(fig, out / "amplitudes.png", dpi=110)
    plt.close(fig)
