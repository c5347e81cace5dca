"""Analysis of a stepped-frequency shake on one specimen: each step's
amplification, lag and excited portion, and the up and down passes on one plot.

A ``stepped_shake`` (dem.case.SteppedShakeLoading; the table motion
dem.table_motion.SteppedSineMotion) runs its steps one after the other without settling in
between; step k runs from t_k to t_k+1 at f_k.  Each step is analysed as a shake of its own
(postprocess.shake.analyze_signals, postprocess.shake.relative_to_table,
postprocess.excited.excited_portion): the record is cut to [t_k, t_k+1] and its clock moved to
start at t_k (the cycles, the steady window and the drift-free integrals count from the step's
start; the phase lag is fitted with a free phase, so the step's start phase pi/2 or 3 pi/2 does
not matter, nor does its displacement offset c_k: amplifications are peak-to-peak).  The
response carried over from the step before is part of that step's record, as in the
laboratory's stepped tests: that is what makes the up pass and the down pass differ
(hysteresis), which a separate run at each frequency (started from rest) does not show.

Passes: a step belongs to the up pass if its frequency is above the previous step's, to the
down pass if below, to "same" if equal (a change of level at one frequency: a kick-start, an
amplitude continuation); the first step takes the second's.  ``stepped.png``: the amplification of
ds (relative displacement), and of a_rel (the acceleration relative to the table) where there is
an accelerometer, against frequency, one line per pass.

A step whose steady window holds fewer than postprocess.shake.MIN_STEADY_CYCLES cycles gets
the short-window warning a shake gets (``warnings``); ``peak`` is the step of the largest ds
amplification (what ``dem summary`` shows).

Writes ``stepped.json`` (and ``stepped.png``) into the run directory.  Units SI, lags in s and
degrees.
"""

from __future__ import annotations

import json
from dataclasses import replace
from pathlib import Path

import numpy as np

from dem.output.atomic import savefig, write_json
from dem.output.plotting import agg_pyplot
from postprocess.shake import analyze_signals, relative_to_table, short_window_warning
from postprocess.shake_signals import (ShakeAnalysisError, ShakeSignals, load_run,
                                       read_signals)


def step_signals(sig: ShakeSignals, t0: float, t1: float, f: float) -> ShakeSignals:
    """The signals of one step: samples with t0 <= t <= t1 (s; half a sample beyond t1, so the
    step's last cycle is whole), the clock moved to start at t0, frequency f (Hz) and end
    t1 - t0."""
    half = 0.5 * float(np.median(np.diff(sig.t)))
    m = (sig.t >= t0 - 1e-9) & (sig.t <= t1 + half)
    cut = {k: (None if v is None else v[m]) for k, v in
           (("ds_centre", sig.ds_centre), ("ds_corner", sig.ds_corner),
            ("ds_corner_b", sig.ds_corner_b), ("a_centre", sig.a_centre),
            ("a_corner", sig.a_corner), ("a_front", sig.a_front))}
    return replace(sig, t=sig.t[m] - t0, f=f, t_end=t1 - t0,
                   excitation={k: v[m] for k, v in sig.excitation.items()}, **cut)


def passes(frequencies) -> list[str]:
    """"up", "down" or "same" for each step (module docstring)."""
    f = list(frequencies)
    out = ["up" if k == 0 or f[k] > f[k - 1] else "down" if f[k] < f[k - 1] else "same"
           for k in range(len(f))]
    if len(f) > 1:
        out[0] = out[1]
    return out


def analyze_steps(sig: ShakeSignals, steps: list[dict], scene=None, frames=None) -> list[dict]:
    """Per step of one axis (steps: dem.table_motion.SteppedSineMotion.steps_run()): the
    frequency, times, pass, amplification and lag of every quantity, the steady window, the
    accelerations relative to the table and, with frames, the excited portion."""
    from postprocess.excited import excited_portion

    out = []
    t_rec = float(sig.t[-1]) if len(sig.t) else 0.0
    half = 0.5 * float(np.median(np.diff(sig.t))) if len(sig.t) > 1 else 0.0
    for st, direction in zip(steps, passes(s["frequency_hz"] for s in steps)):
        t0, t1, f = st["t_start_s"], st["t_end_s"], st["frequency_hz"]
        if t_rec - t0 < 1.0 / f:   # a stopped or killed run: not one cycle of this step
            out.append({"frequency_hz": f, "pass": direction, "t_start_s": t0, "t_end_s": t1,
                        "cycles_run": st["cycles_run"], "amplitude_m": st["amplitude_m"],
                        "peak_acceleration_m_s2": st["peak_acceleration_m_s2"],
                        "amplification": {}, "lag": {}, "not_analysed":
                        f"the record ends at t = {t_rec:.3f} s, less than a cycle into this "
                        f"step ({t0:.3f}-{t1:.3f} s)"})
            continue
        sk = step_signals(sig, t0, t1, f)
        res, arr = analyze_signals(sk)
        win = arr["window"]
        entry = {"frequency_hz": f, "pass": direction, "t_start_s": t0, "t_end_s": t1,
                 "cycles_run": st["cycles_run"], "amplitude_m": st["amplitude_m"],
                 "peak_acceleration_m_s2": st["peak_acceleration_m_s2"],
                 "steady_state": res["steady_state"], "amplification": res["amplification"],
                 "lag": res["lag"]}
        if "error" in res:
            entry["error"] = res["error"]
        if t1 > t_rec + half:   # analysed on the part the run reached
            entry["record_ends_s"] = t_rec
        short = short_window_warning(sk, win)   # as a shake's (postprocess.shake)
        if short:
            entry["warning"] = f"step {st['frequency_hz']:g} Hz at {t0:.3g} s: {short}"
        rel = relative_to_table(sk, win)
        if rel is not None:
            entry["relative_to_table"] = {"amplification": rel["amplification"],
                                          "front_back_ratio": rel["front_back_ratio"]}
        if frames is not None and scene is not None and win is not None:
            try:
                portion = excited_portion(scene, frames, f, t0 + win.t0, t0 + win.t1,
                                          sk.direction, ref_block=sk.blocks["centre"],
                                          facade=sk.facade, side_walls=sk.side_walls)
                entry["excited_portion"] = portion.summary()
            except Exception as err:  # noqa: BLE001 - the step's other results still land
                entry["excited_portion_error"] = f"{type(err).__name__}: {err}"
        out.append(entry)
    return out


def step_windows(sig: ShakeSignals, step: dict, width: int) -> list[dict]:
    """Does the branch hold through a long step?  The response of one step (``step``: an entry
    of SteppedSineMotion.steps_run()) window by window: consecutive windows of ``width`` whole
    cycles from the step's start (cycles 1 - width, width + 1 - 2 width, ...; the last window
    is the step's last ``width`` whole cycles, overlapping the one before when the count is not
    a multiple), each judged as a run of its own: the ds amplification (peak-to-peak over the
    table's, postprocess.signal_analysis.amplification, over the window's cycles), the lag of
    ds behind the table (phase_lag: fitted phase at f, s) and its branch
    (postprocess.verdicts.response_branch: rocking, quasi-static or between).  The windows are
    fixed, not the steady window a shake's analysis looks for: what is asked is how the
    response evolves, transients included.  [] when the record holds fewer than ``width``
    whole cycles of the step."""
    from postprocess.signal_analysis import (SteadyWindow, amplification, n_complete_cycles,
                                             phase_lag)
    from postprocess.verdicts import response_branch

    if width < 1:
        raise ValueError(f"width must be >= 1 cycle, got {width}")
    t0, t1, f = step["t_start_s"], step["t_end_s"], step["frequency_hz"]
    if len(sig.t) < 2 or float(sig.t[-1]) - t0 < width / f:
        return []
    sk = step_signals(sig, t0, t1, f)
    n = n_complete_cycles(sk.t, f, sk.t_end)
    starts = list(range(0, n - width + 1, width))
    if starts and starts[-1] + width < n:
        starts.append(n - width)
    exc = sk.excitation["displacement"]
    out = []
    for k0 in starts:
        win = SteadyWindow(k0, k0 + width, f, f"fixed window of {width} cycles", "ds")
        amp = amplification(sk.t, sk.ds_centre, exc, win)["amplification"]
        lag = phase_lag(sk.t, sk.ds_centre, exc, f, win)["lag_s"]
        row = {"frequency_hz": f, "amplification": {"ds": amp}, "lag_s": {"ds": lag}}
        out.append({"first_cycle": k0 + 1, "last_cycle": k0 + width,
                    "t0_s": t0 + win.t0, "t1_s": t0 + win.t1, "lag_s": lag,
                    **response_branch(row)})
    return out


def step_and_cycle(steps: list[dict], t: float | None) -> dict | None:
    """Which step (0-based index) and which cycle of it (1 for the first) time ``t`` (s) falls
    in, for a stepped shake's ``steps`` (SteppedSineMotion.steps_run()); None for None or a
    time outside the steps."""
    if t is None:
        return None
    for k, st in enumerate(steps):
        if st["t_start_s"] <= t < st["t_end_s"] or (k == len(steps) - 1 and t == st["t_end_s"]):
            return {"step": k, "cycle": int(np.floor((t - st["t_start_s"])
                                                     * st["frequency_hz"])) + 1}
    return None


def plot_passes(path, steps: list[dict], title: str = "") -> None:
    """stepped.png: amplification of ds and a_rel (where present) against frequency, the up
    pass and the down pass as separate lines (the hysteresis of the stepped test)."""
    plt = agg_pyplot()

    names = [("ds", lambda s: s["amplification"].get("ds")),
             ("a_rel", lambda s: (s.get("relative_to_table") or {}).get("amplification",
                                                                          {}).get("a_rel"))]
    names = [(n, get) for n, get in names if any(get(s) is not None for s in steps)]
    fig, axs = plt.subplots(1, len(names), figsize=(5.5 * len(names), 4), squeeze=False)
    for ax, (name, get) in zip(axs[0], names):
        for direction, style in (("up", "o-"), ("down", "s--"), ("same", "^:")):
            pts = [(s["frequency_hz"], get(s)) for s in steps
                   if s["pass"] == direction and get(s) is not None]
            if pts:
                f, a = zip(*pts)
                ax.plot(f, a, style, label=f"{direction} pass")
        ax.set_xlabel("frequency (Hz)")
        ax.set_ylabel(f"amplification of {name} (-)")
        ax.grid(alpha=0.3)
        ax.legend(fontsize=8)
    fig.suptitle(title)
    fig.tight_layout()
    savefig(fig, path)
    plt.close(fig)


def analyze_stepped_run(run_dir, plots: bool = True, write: bool = True) -> dict:
    """Read a stepped-shake run directory (case.json, instruments.npz or frames.npz), analyse
    every step of every axis, write stepped.json and stepped.png.  ShakeAnalysisError naming
    the file when it cannot."""
    from dem.case import SteppedShakeLoading

    run_dir = Path(run_dir)
    case, scene = load_run(run_dir)
    ld = case.loading
    if not isinstance(ld, SteppedShakeLoading):
        raise ShakeAnalysisError(f"{run_dir / 'case.json'}: loading.type is '{ld.type}', not "
                                 f"'stepped_shake'")
    sigs, frames = read_signals(run_dir, case, scene)
    motion = ld.motion()
    steps = motion.steps_run()
    summary_path = run_dir / "summary.json"
    status = json.loads(summary_path.read_text()).get("status") if summary_path.is_file() \
        else None
    out = {"kind": "stepped_shake", "case": case.name, "run_status": status,
           "excitation": motion.describe(), "axes": {}, "plots": [], "warnings": []}
    for sig in sigs:
        out["axes"][sig.axis] = {"steps": analyze_steps(sig, steps, scene, frames)}
        out["warnings"] += [s["warning"] for s in out["axes"][sig.axis]["steps"]
                            if "warning" in s]
    primary = sigs[0].axis
    out["primary_axis"] = primary
    out["steps"] = out["axes"][primary]["steps"]
    out["peak"] = peak_step(out["steps"])
    if write:
        if plots:
            plot_passes(run_dir / "stepped.png", out["steps"], f"{case.name}: {primary}")
            out["plots"].append("stepped.png")
        write_json(run_dir / "stepped.json", out, indent=1, strict=True)
    return out


def peak_step(steps: list[dict]) -> dict | None:
    """The step of the largest ds amplification (its frequency, pass and amplification), the
    stepped run's headline as a sweep's peak is (``dem summary``); None when no step has one."""
    best = None
    for s in steps:
        a = s["amplification"].get("ds")
        if a is not None and np.isfinite(a) and (best is None or a > best["amplification_ds"]):
            best = {"frequency_hz": s["frequency_hz"], "pass": s["pass"],
                    "amplification_ds": float(a)}
    return best


def steps_line(res: dict) -> str:
    """One line for the command line: each step's frequency, pass and ds amplification."""
    parts = []
    for s in res["steps"]:
        a = s["amplification"].get("ds")
        parts.append(f"{s['frequency_hz']:g} Hz {s['pass']} "
                     + ("not reached" if "not_analysed" in s else
                        f"ds {a:.3g}" if a is not None and np.isfinite(a) else "no steady window"))
    return f"{len(res['steps'])} steps: " + "; ".join(parts)
