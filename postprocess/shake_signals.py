"""The signals of a shaking run (thesis Section 4.2.5): read from a run directory's
``instruments.npz`` (the virtual instruments, dem.instruments) or, without it, from the block poses
in ``frames.npz``, and turned into the thesis' quantities.  Units: SI (m, s, m/s, m/s2).

Signals, all projected on the instrument's measuring direction e (the excitation axis; for the
diagonal tests each axis is analysed on its own):

    u, u', u''  table displacement, velocity, acceleration (the input; absolute, lab frame)
    ds          transducer at the facade centre: displacement of the brick RELATIVE TO THE TABLE
                (the thesis' transducers are bolted to the table)
    dsr         ds(centre) - ds(corner): centre relative to the corner brick (corner "a", the
                brick that also carries the corner accelerometer, so dsr and dar compare)
    a, ar       accelerometer at the centre (ABSOLUTE acceleration) and a(centre) - a(corner)
    da, dar     a and ar integrated twice (ABSOLUTE displacement for da; dar is relative again)
    vs, vsr     d(ds)/dt and d(dsr)/dt (the thesis differentiates the transducer readings)
    va, var     a and ar integrated once (absolute / relative velocity)
    a_front, da_front   the front facade's centre accelerometer (L2 or T2; Tables 4.9 - 4.11)
    a_lp, a_front_lp    a and a_front through an ASSUMED instrument low-pass (:func:`lowpass`)

The instrument low-pass (``a_lp``, ``a_front_lp``) is an assumption, not a thesis value: the
thesis (Section 4.2.5) names five accelerometers read in g and gives no sampling rate, no
anti-aliasing or other filter.  The DEM's accelerometer is ideal (500 Hz samples of the rigid
brick's acceleration, every impact spike included), so its ``a`` amplification (6-8 on Model II)
is not what a real instrument would read.  :data:`LOWPASS_HZ` = 20 Hz (>= 5 harmonics of the
highest test frequency, 3.6 Hz), a Butterworth of order :data:`LOWPASS_ORDER` = 4 run forward
and backward (scipy.signal.sosfiltfilt: zero phase, gain |H|^2 = 1 / (1 + (f / f_c)^8) of the
analog prototype, -6 dB at f_c, 1 - 1e-6 at 3.6 Hz; the bilinear transform only deepens the
stopband: 8e-7 at 100 Hz for 500 Hz samples).  The excitation it is compared with stays the unfiltered table
acceleration (a sine at f, which the filter passes within that error).  How much the answer
depends on the cutoff: postprocess.shake's ``a_lowpass_sensitivity`` (the amplification of a at
:data:`LOWPASS_SENSITIVITY_HZ`).  The unfiltered ``a`` is kept as it was.

The integrals without drift: postprocess.signal_analysis.drift_free_integral.  Each quantity is
compared with the excitation OF THE SAME KIND (``KIND_OF``): table displacement for ds, dsr, da,
dar; table velocity for vs, vsr, va, var; table acceleration for a, ar.  ds, dsr, vs, vsr, ar,
dar, var are relative (to the table or to the corner); a, da, va are absolute.  A block bolted to
the table therefore has A = 1 for a, da, va and A = 0 for ds, vs (and for the relative
quantities).
"""

from __future__ import annotations

from dataclasses import dataclass, field, replace
from pathlib import Path

import numpy as np
from scipy import signal as _signal

from postprocess.block_kinematics import point_histories
from postprocess.signal_analysis import drift_free_integral

KIND_OF = {  # quantity -> (kind of the excitation it is compared with, frame)
    "ds": ("displacement", "relative"), "dsr": ("displacement", "relative"),
    "da": ("displacement", "absolute"), "dar": ("displacement", "relative"),
    "vs": ("velocity", "relative"), "vsr": ("velocity", "relative"),
    "va": ("velocity", "absolute"), "var": ("velocity", "relative"),
    "a": ("acceleration", "absolute"), "ar": ("acceleration", "relative"),
    "a_front": ("acceleration", "absolute"), "da_front": ("displacement", "absolute"),
    "a_lp": ("acceleration", "absolute"), "a_front_lp": ("acceleration", "absolute"),
}
#: the ASSUMED accelerometer low-pass (module docstring; not a thesis value): cutoff, Hz, and the
#: Butterworth order (run forward and backward, so the magnitude is squared)
LOWPASS_HZ = 20.0
LOWPASS_ORDER = 4
#: cutoffs (Hz) at which postprocess.shake reports a's amplification (the cutoff sensitivity)
LOWPASS_SENSITIVITY_HZ = (10.0, 20.0, 50.0)


class ShakeAnalysisError(ValueError):
    """The run directory cannot be analysed; the message names the file or field."""


@dataclass
class ShakeSignals:
    """Histories of one measuring axis, on a uniform time grid ``t`` [K] (s).

    excitation: {"displacement": u [K] m, "velocity": u' [K] m/s, "acceleration": u'' [K] m/s2}
    ds_centre, ds_corner, ds_corner_b: transducer displacements relative to the table [K], m
    a_centre, a_corner, a_front: absolute accelerations [K], m/s2 (None where absent)
    """

    t: np.ndarray
    f: float
    t_end: float
    direction: np.ndarray
    axis: str
    excitation: dict
    ds_centre: np.ndarray
    ds_corner: np.ndarray | None = None
    ds_corner_b: np.ndarray | None = None
    a_centre: np.ndarray | None = None
    a_corner: np.ndarray | None = None
    a_front: np.ndarray | None = None
    source: str = ""
    blocks: dict = field(default_factory=dict)   # role -> block index
    facade: str | None = None                    # facade group name (box models)
    side_walls: tuple = ()
    front: str | None = None


def lowpass(y: np.ndarray, t: np.ndarray, cutoff_hz: float = LOWPASS_HZ,
            order: int = LOWPASS_ORDER) -> np.ndarray:
    """y [K] (any unit, kept) on the uniform grid t [K] (s) through a zero-phase Butterworth
    low-pass of ``order`` at ``cutoff_hz`` (Hz), run forward and backward (sosfiltfilt, odd
    padding at the ends): |H(f)|^2 = 1 / (1 + (f / cutoff)^(2 order)).  ValueError naming the
    cutoff when it is not below the record's Nyquist frequency (1 / (2 dt)), or naming the
    record when it is too short for the filter's padding."""
    t = np.asarray(t, float)
    fs = 1.0 / float(np.median(np.diff(t)))
    if not 0.0 < cutoff_hz < 0.5 * fs:
        raise ValueError(f"lowpass cutoff_hz = {cutoff_hz:g} Hz: must lie in (0, {0.5 * fs:g}) "
                         f"Hz, the Nyquist frequency of samples {1e3 / fs:.3g} ms apart")
    sos = _signal.butter(order, cutoff_hz, fs=fs, output="sos")
    pad = 3 * (2 * len(sos) + 1)
    if len(y) <= pad:
        raise ValueError(f"lowpass: a record of {len(y)} samples is too short (> {pad} needed)")
    return _signal.sosfiltfilt(sos, np.asarray(y, float))


def lowpass_resolved(t: np.ndarray, cutoff_hz: float = LOWPASS_HZ) -> bool:
    """Whether the record t (s) resolves the cutoff (Hz) and is long enough for the filter's
    padding.  Resolved: below 0.9 x the Nyquist frequency 1 / (2 dt): a cutoff at the Nyquist
    frequency filters nothing, and the resampling of jittered frames (:func:`uniform_frames`) moves
    it by a fraction of a percent, so frames 10 ms apart never count as resolving 50 Hz."""
    return len(t) > 3 * (2 * ((LOWPASS_ORDER + 1) // 2) + 1) and \
        cutoff_hz < 0.9 * 0.5 / float(np.median(np.diff(t)))


def derived_quantities(sig: ShakeSignals) -> dict:
    """The thesis' quantities (module docstring) as arrays [K]; absent instruments are skipped."""
    t = sig.t

    def dint(acc, n):
        return drift_free_integral(acc, t, sig.f, sig.t_end, n)
    q: dict[str, np.ndarray] = {"ds": sig.ds_centre, "vs": np.gradient(sig.ds_centre, t)}
    if sig.ds_corner is not None:
        q["dsr"] = sig.ds_centre - sig.ds_corner
        q["vsr"] = np.gradient(q["dsr"], t)
    if sig.a_centre is not None:
        q["a"] = sig.a_centre
        q["va"] = dint(sig.a_centre, 1)
        q["da"] = dint(sig.a_centre, 2)
        if sig.a_corner is not None:
            q["ar"] = sig.a_centre - sig.a_corner
            q["var"] = dint(q["ar"], 1)
            q["dar"] = dint(q["ar"], 2)
    if sig.a_front is not None:
        q["a_front"] = sig.a_front
        q["da_front"] = dint(sig.a_front, 2)
    if lowpass_resolved(t):   # the assumed instrument (module docstring); frames at 50 Hz are not
        for name in ("a", "a_front"):
            if name in q:
                q[f"{name}_lp"] = lowpass(q[name], t)
    return q


def truncate(sig: ShakeSignals, cycles: float) -> ShakeSignals:
    """The signals of the first ``cycles`` excitation cycles: the samples up to t_end = cycles / f
    (s; and half a sample beyond, so the last cycle is complete) and t_end set there, as if the
    run had shaken ``cycles`` cycles.  The run's first cycles do not depend on how many follow
    (dem.table_motion: a ramp start lies within its first ramp_cycles; the settle phase ends
    before the clock starts).
    ShakeAnalysisError naming ``cycles`` when it is not in (0, the recorded cycles]."""
    recorded = sig.t_end * sig.f
    if not 0.0 < cycles <= recorded + 1e-9:
        raise ShakeAnalysisError(f"cycles = {cycles:g}: must lie in (0, {recorded:g}], the "
                                 f"cycles the run shook")
    t_end = cycles / sig.f
    m = sig.t <= t_end + 0.5 * float(np.median(np.diff(sig.t)))
    cut = {k: (None if v is None else v[m]) for k, v in
           (("ds_centre", sig.ds_centre), ("ds_corner", sig.ds_corner),
            ("ds_corner_b", sig.ds_corner_b), ("a_centre", sig.a_centre),
            ("a_corner", sig.a_corner), ("a_front", sig.a_front))}
    return replace(sig, t=sig.t[m], t_end=t_end,
                   excitation={k: v[m] for k, v in sig.excitation.items()}, **cut)


def truncate_frames(frames: dict | None, t_end: float) -> dict | None:
    """frames.npz arrays (time first, as many rows as ``t``) up to t_end (s) and the first frame
    past it (frames are taken at the first step past each output time)."""
    if frames is None:
        return None
    t = np.asarray(frames["t"], float)
    n = min(len(t), int(np.searchsorted(t, t_end, side="right")) + 1)
    return {k: (v[:n] if np.ndim(v) and len(v) == len(t) else v) for k, v in frames.items()}


# ---------------------------------------------------------------------------------------------
# reading a run directory
# ---------------------------------------------------------------------------------------------
def load_run(run_dir: Path):
    """(case, scene) of a run directory from its case.json."""
    from dem.case import Case
    from dem.run.build import scene_from_case

    path = Path(run_dir) / "case.json"
    if not path.is_file():
        raise ShakeAnalysisError(f"{path}: missing (the run directory must hold case.json)")
    try:
        case = Case.model_validate_json(path.read_text())
    except Exception as err:  # noqa: BLE001 - report which file
        raise ShakeAnalysisError(f"{path}: not a valid case: {err}") from None
    return case, scene_from_case(case, check=False)


def uniform_frames(t, arrays):
    """Resample arrays (first axis = time) linearly onto a uniform grid if t is not uniform
    (frames are taken at the first step past each output time: jitter of one time step).
    A record of fewer than two samples (a run stopped in its settle phase) has no time grid:
    ShakeAnalysisError."""
    if len(t) < 2:
        raise ShakeAnalysisError(f"{len(t)} sample(s) recorded: nothing to analyse (a run stopped "
                                 "before its loading started?)")
    dt = np.diff(t)
    if len(dt) and np.allclose(dt, np.median(dt), rtol=1e-3, atol=0):
        return t, arrays
    n = int(round((t[-1] - t[0]) / float(np.median(dt)))) + 1
    tu = np.linspace(t[0], t[-1], n)  # keeps both ends of the record
    out = []
    for a in arrays:
        if a is None:
            out.append(None)
            continue
        flat = a.reshape(len(t), -1)
        res = np.column_stack([np.interp(tu, t, flat[:, j]) for j in range(flat.shape[1])])
        out.append(res.reshape((len(tu),) + a.shape[1:]))
    return tu, out


def _axes_of(direction) -> list[str]:
    d = np.abs(np.asarray(direction, float))
    if d[0] > 1e-9 and d[1] > 1e-9:
        return ["y", "x"]
    return ["x"] if d[0] > d[1] else ["y"]


def _side_walls(facade: str) -> tuple:
    return ("T1", "T2") if facade in ("L1", "L2") else ("L1", "L2")


def excitation_timing(ld) -> dict:
    """{"f": Hz, "t_end": s} of a shake loading: its frequency and the end of its cycles; for a
    stepped shake the first step's frequency and the end of the last step (the
    per-step analysis, postprocess.stepped, cuts the record into steps with their own); for a
    sweep or a noise the band's lowest frequency and the motion's end."""
    from dem.case import NoiseLoading, SteppedShakeLoading, SweepLoading

    if isinstance(ld, SteppedShakeLoading):
        return {"f": ld.steps[0].frequency, "t_end": ld.motion().t_end}
    if isinstance(ld, SweepLoading):   # the lowest frequency (postprocess.identification)
        return {"f": ld.f0, "t_end": ld.sweep_duration}
    if isinstance(ld, NoiseLoading):
        return {"f": ld.f_lo, "t_end": ld.duration}
    return {"f": ld.frequency, "t_end": ld.cycles / ld.frequency}


def signals_from_instruments(npz, case) -> list[ShakeSignals]:
    """Signals per axis from ``instruments.npz`` (layout in :mod:`dem.instruments`)."""
    ld = case.loading
    t = np.asarray(npz["t"], float)
    names = [str(n) for n in npz["names"]]
    groups = [str(g) for g in npz["group"]]
    out = []
    for axis in _axes_of(ld.direction):
        prefix = f"{axis}-" if any(n.startswith(f"{axis}-") for n in names) else ""

        def idx(nm):
            full = prefix + nm
            return names.index(full) if full in names else None

        i_c = idx("ds-centre")
        if i_c is None:
            raise ShakeAnalysisError(f"instruments.npz: no '{prefix}ds-centre' among {names}")
        e = np.asarray(npz["direction"][i_c], float)
        proj = lambda arr, i: None if i is None else np.asarray(arr)[:, i, :] @ e  # noqa: E731
        tu, (disp, acc, tdisp, tacc) = uniform_frames(
            t, [np.asarray(npz[k]) for k in ("disp", "acc", "table_disp", "table_acc")])
        u = tdisp @ e
        exc = {"displacement": u, "velocity": np.gradient(u, tu), "acceleration": tacc @ e}
        i_ca, i_cb = idx("ds-corner-a"), idx("ds-corner-b")
        i_a, i_ac, i_af = idx("a-centre"), idx("a-corner"), idx("a-front-centre")
        blocks = {r: int(npz["block"][i]) for r, i in (("centre", i_c), ("corner_a", i_ca),
                                                        ("corner_b", i_cb), ("front", i_af))
                  if i is not None}
        facade = groups[i_c]
        out.append(ShakeSignals(
            t=tu, **excitation_timing(ld), direction=e, axis=axis,
            excitation=exc, ds_centre=proj(disp, i_c), ds_corner=proj(disp, i_ca),
            ds_corner_b=proj(disp, i_cb), a_centre=proj(acc, i_a), a_corner=proj(acc, i_ac),
            a_front=proj(acc, i_af), source="instruments.npz", blocks=blocks, facade=facade,
            side_walls=_side_walls(facade),
            front=groups[i_af] if i_af is not None else None))
    return out


def signals_from_frames(frames, case, scene) -> list[ShakeSignals]:
    """Signals per axis from ``frames.npz`` when a run has no instruments.npz.

    Box models: the Fig 4.4 instruments (dem.instruments.thesis_instruments) read from the block
    poses.  Other scenes: the centre of the top block (highest top face; nearest the plan centre
    on ties); no corner, so no relative quantities.  Accelerations: the point's relative velocity
    np.gradient(x_rel) plus the exact table velocity, differentiated again with np.gradient; the
    excitation's acceleration is differentiated from the table velocity on the same samples, so a
    block moving with the table reads exactly the table.
    """
    from dem.instruments import thesis_instruments
    from dem.loading import loading_from_case

    loading = loading_from_case(case)
    t0 = np.asarray(frames["t"], float)
    t, (pos, quat) = uniform_frames(t0, [np.asarray(frames["pos"]), np.asarray(frames["quat"])])
    quat = quat / np.linalg.norm(quat, axis=-1, keepdims=True)
    table_disp = loading.base_disp(t)
    table_vel = loading.base_vel(t)
    ld = case.loading
    boxy = {"L1", "L2", "T1", "T2"} <= set(scene.group_names)
    out = []
    for axis in _axes_of(ld.direction):
        if boxy:
            inst = {i.name: i for i in thesis_instruments(scene, axis)}
            e = inst["ds-centre"].direction
            roles = {"centre": inst["ds-centre"], "corner_a": inst["ds-corner-a"],
                     "corner_b": inst["ds-corner-b"], "front": inst["a-front-centre"]}
            blocks = {r: i.block for r, i in roles.items()}
            pts = np.array([roles[r].point for r in roles])
            facade = scene.group_names[scene.group[blocks["centre"]]]
            front = scene.group_names[scene.group[blocks["front"]]]
        else:
            d = np.asarray(ld.direction, float)
            e = np.eye(3)[{"x": 0, "y": 1}[axis]] if len(_axes_of(d)) > 1 else d / np.linalg.norm(d)
            free = np.flatnonzero(~scene.fixed)
            top = scene.position[free, 2] + 0.5 * scene.size[free, 2]
            cand = free[top >= top.max() - 1e-6]
            c = cand[np.argmin(np.linalg.norm(scene.position[cand, :2], axis=1))]
            blocks, pts, facade, front = {"centre": int(c)}, np.zeros((1, 3)), None, None
        x = point_histories(pos, quat, list(blocks.values()), pts)
        rel = (x - x[:1]) @ e                       # [T, n] relative to the table
        u = table_disp @ e
        uv = table_vel @ e
        v_abs = np.gradient(rel, t, axis=0) + uv[:, None]
        a_abs = np.gradient(v_abs, t, axis=0)
        exc = {"displacement": u, "velocity": np.gradient(u, t),
               "acceleration": np.gradient(uv, t)}
        col = {r: k for k, r in enumerate(blocks)}
        get = lambda arr, r: arr[:, col[r]] if r in col else None  # noqa: E731
        out.append(ShakeSignals(
            t=t, **excitation_timing(ld), direction=np.asarray(e, float),
            axis=axis, excitation=exc, ds_centre=get(rel, "centre"),
            ds_corner=get(rel, "corner_a"), ds_corner_b=get(rel, "corner_b"),
            a_centre=get(a_abs, "centre"), a_corner=get(a_abs, "corner_a"),
            a_front=get(a_abs, "front"), source="frames.npz", blocks=blocks, facade=facade,
            side_walls=_side_walls(facade) if facade else (), front=front))
    return out


def read_signals(run_dir: Path, case, scene) -> tuple[list[ShakeSignals], dict | None]:
    """Signals per axis of a run directory (from instruments.npz, else from frames.npz) and its
    frames (None without frames.npz); raises ShakeAnalysisError naming what is missing."""
    run_dir = Path(run_dir)
    frames = None
    if (run_dir / "frames.npz").is_file():
        frames = dict(np.load(run_dir / "frames.npz"))
    if (run_dir / "instruments.npz").is_file():
        sigs = signals_from_instruments(np.load(run_dir / "instruments.npz"), case)
    elif frames is not None:
        sigs = signals_from_frames(frames, case, scene)
    else:
        raise ShakeAnalysisError(f"{run_dir}: neither instruments.npz nor frames.npz")
    if len(sigs[0].t) < 4:
        raise ShakeAnalysisError(f"{run_dir}: only {len(sigs[0].t)} samples recorded")
    return sigs, frames
