"""``dem view DIR``: a look at a run without ParaView: an animation (``animation.gif``, or
``animation.mp4`` with ``--format mp4`` where ffmpeg is found) and a frame strip (``strip.png``)
drawn off-screen from the run's frames.npz and case.json (dem.output.animation).

DIR is a run directory, or a sweep / ensemble directory, of which one run is drawn: ``--point``
names it (a sweep point's directory name such as ``f2.800Hz`` or its frequency in Hz, a
realisation's ``seed-5``; for a sweep ensemble ``seed-5/f2.800Hz``); without it the command
draws the sweep point of the largest ds amplification (sweep.json) and the realisation whose
lambda is nearest the ensemble's median (the first finished one otherwise), and says which.

The files go into the drawn run's directory (``--out`` elsewhere).  ``--frames N`` frames spread
evenly over the recording (first and last included) at ``--fps``; ``--panels`` in the strip.
A shaken run's motion relative to the table is millimetres on a metre-sized model: it is drawn
magnified (``--magnify``, default: the factor, 1, 2 or 5 times a power of ten, that makes the
largest block displacement 5 % of the model's size, at most 1000; 1 for a tilt), and the
title says so.
Exit codes: 0 written, 1 a drawing failed, 2 bad input (not a run, no frames.npz, a --point that
is not there, an unknown --format).
"""

from __future__ import annotations

import json
import math
from pathlib import Path

import numpy as np

from dem_cli.commands.exit_codes import ExitCode

FORMATS = ("gif", "mp4")


class ViewError(ValueError):
    """Bad input of ``dem view`` (exit 2)."""


def _json(path: Path) -> dict:
    try:
        data = json.loads(Path(path).read_text())
    except (OSError, ValueError):
        return {}
    return data if isinstance(data, dict) else {}


def _run_dirs(path: Path) -> list[Path]:
    return [d for d in sorted(path.iterdir()) if d.is_dir() and (d / "case.json").is_file()]


def pick_sweep_point(path: Path, point: str | None) -> tuple[Path, str]:
    """(point directory, why it was picked) of a sweep directory."""
    dirs = [d for d in _run_dirs(path) if (d / "frames.npz").is_file()]
    if not dirs:
        raise ViewError(f"{path}: a sweep whose points hold no frames.npz (only their analysis "
                        f"was kept)")
    points = {p.get("dir") or p.get("name"): p for p in _json(path / "sweep.json").get("points")
              or [] if isinstance(p, dict)}
    if point is not None:
        for d in dirs:
            if d.name == point:
                return d, f"--point {point}"
        try:
            f = float(point)
        except ValueError:
            f = None
        for d in dirs:
            fp = (points.get(d.name) or {}).get("frequency_hz")
            if f is not None and fp is not None and math.isclose(fp, f, rel_tol=1e-9, abs_tol=1e-9):
                return d, f"--point {point} (Hz)"
        raise ViewError(f"{path}: no point {point!r}; its points with frames: "
                        f"{', '.join(d.name for d in dirs)}")

    def ds(d: Path) -> float:
        v = ((points.get(d.name) or {}).get("amplification") or {}).get("ds")
        return float(v) if isinstance(v, (int, float)) and math.isfinite(v) else -math.inf

    best = max(dirs, key=ds)
    names = ", ".join(d.name for d in dirs)
    if ds(best) == -math.inf:
        return dirs[0], (f"the first of {len(dirs)} points with frames ({names}); "
                         f"--point NAME for another")
    return best, (f"the largest ds amplification ({ds(best):.3g}) of {len(dirs)} points with "
                  f"frames ({names}); --point NAME for another")


def pick_realisation(path: Path, point: str | None) -> tuple[Path, str]:
    """(realisation directory, why) of an ensemble directory."""
    rows = [r for r in _json(path / "ensemble.json").get("realisations") or []
            if isinstance(r, dict) and (path / str(r.get("name")) / "frames.npz").is_file()]
    names = [str(r["name"]) for r in rows]
    if point is not None:
        if point in names:
            return path / point, f"--point {point}"
        raise ViewError(f"{path}: no realisation {point!r} with frames; there are: "
                        f"{', '.join(names) or 'none'}")
    if not rows:
        raise ViewError(f"{path}: an ensemble with no realisation holding frames.npz")
    lams = [(r.get("lambda"), r["name"]) for r in rows if isinstance(r.get("lambda"), (int, float))]
    if lams:
        med = float(np.median([v for v, _ in lams]))
        v, name = min(lams, key=lambda x: (abs(x[0] - med), x[1]))
        return path / name, (f"lambda {v:.4f} nearest the median {med:.4f} of {len(lams)} "
                             f"realisations; --point seed-S for another")
    return path / names[0], f"the first of {len(names)} realisations; --point seed-S for another"


def pick_run(path: Path, point: str | None) -> tuple[Path, str | None]:
    """The run directory to draw from DIR (a run, a sweep, an ensemble, a sweep ensemble) and
    why that one (None: DIR is a run)."""
    from dem_cli.commands.post import directory_kind

    if not path.is_dir():
        raise ViewError(f"{path}: not a directory")
    kind = directory_kind(path)
    if kind == "run":
        if point is not None:
            raise ViewError(f"{path}: a run directory: --point is for sweeps and ensembles")
        return path, None
    if kind == "sweep":
        return pick_sweep_point(path, point)
    if kind == "ensemble":
        return pick_realisation(path, point)
    if kind == "sweep-ensemble":
        seeds = [r["name"] for r in _json(path / "ensemble.json").get("realisations") or []
                 if isinstance(r, dict) and (path / str(r.get("name"))).is_dir()]
        first, _, rest = (point or "").partition("/")
        seed = first or (seeds[0] if seeds else None)
        if seed not in seeds:
            raise ViewError(f"{path}: no realisation {seed!r}; there are: {', '.join(seeds)}")
        run, why = pick_sweep_point(path / seed, rest or None)
        return run, f"realisation {seed}: {why}"
    if kind == "rocking":
        raise ViewError(f"{path}: a two-body rocking run (its plots are written by `dem rocking`)")
    raise ViewError(f"{path}: not a run (no case.json), a sweep (no sweep.json) nor an "
                    f"ensemble (no ensemble.json)")


MAX_AUTO_MAGNIFY = 1000.0  # beyond it the drawing shows the joints' elastic jitter


def auto_magnify(size, pos) -> float:
    """1, 2 or 5 x 10^k that makes the largest block displacement from the first frame 5 % of
    the model's size (its largest extent), at least 1 and at most MAX_AUTO_MAGNIFY."""
    pos = np.asarray(pos, float)
    span = float(np.ptp(pos[0], axis=0).max() + np.max(size))
    dmax = float(np.linalg.norm(pos - pos[0][None], axis=2).max())
    if dmax <= 0.0 or dmax >= 0.05 * span:
        return 1.0
    want = 0.05 * span / dmax
    k = 10.0 ** math.floor(math.log10(want))
    return min(MAX_AUTO_MAGNIFY, max(1.0, max(m * k for m in (1.0, 2.0, 5.0) if m * k <= want)))


def view_command(path, out=None, point: str | None = None, frames: int = 40, fps: float = 10.0,
                 panels: int = 6, fmt: str = "gif", magnify: float | None = None,
                 echo=print, err=print) -> int:
    """Body of ``dem view``; returns the exit code."""
    from dem.output import animation

    if fmt not in FORMATS:
        err(f"error: --format: '{fmt}' is not one of {', '.join(FORMATS)}")
        return ExitCode.BAD_INPUT
    for name, v, lo in (("--frames", frames, 1), ("--panels", panels, 1), ("--fps", fps, 1e-9)):
        if not v >= lo:
            err(f"error: {name} must be >= {lo:g} (got {v})")
            return ExitCode.BAD_INPUT
    if magnify is not None and not magnify > 0:
        err(f"error: --magnify must be > 0 (got {magnify})")
        return ExitCode.BAD_INPUT
    if fmt == "mp4" and not animation.ffmpeg_available():
        err("error: --format mp4 needs ffmpeg (on PATH, or `pip install imageio-ffmpeg`); "
            "the default gif needs nothing more")
        return ExitCode.BAD_INPUT
    try:
        run_dir, why = pick_run(Path(path), point)
        data = load_view(run_dir)
    except ViewError as e:
        err(f"error: {e}")
        return ExitCode.BAD_INPUT
    if why is not None:
        echo(f"{path}: drawing {run_dir.name}: {why}")
    out = Path(out) if out is not None else run_dir
    from dem_cli.commands.exit_codes import os_error_code, os_error_text, writable_directory

    why_not = writable_directory(out, "--out" if out != run_dir else "the run directory")
    if why_not is not None:  # before anything is drawn: one line, nothing half-written
        err(f"error: {why_not}" + ("; give --out DIR" if out == run_dir else ""))
        return ExitCode.BAD_INPUT
    t_all = data["t"]
    idx = animation.frame_indices(len(t_all), frames)
    shaken = data["tilt_angle"] is None and data["base_disp"] is not None
    if magnify is None:
        magnify = auto_magnify(data["size"], data["pos"][idx]) if shaken else 1.0
    poses = animation.lab_poses(
        data["size"], t_all[idx], data["pos"][idx], data["quat"][idx],
        base_disp=data["base_disp"][idx] if shaken else None,
        tilt_angle=data["tilt_angle"][idx] if data["tilt_angle"] is not None else None,
        tilt_axis=data["tilt_axis"], magnify=magnify)
    title = data["name"] + (f" (motion relative to the table drawn x {magnify:g})"
                            if magnify != 1.0 else "")
    if magnify != 1.0:
        echo(f"the motion relative to the table drawn x {magnify:g} (--magnify)")
    view = animation.view_angles(data["tilt_axis"] if data["tilt_angle"] is not None else None)
    movie = out / f"animation.{fmt}"
    strip = out / "strip.png"
    from dem.signals import signal_name, stop_on_signals

    try:
        # a stop signal ends the drawing like Ctrl-C: the atomic writer removes its temporary
        # file, and the files already there stay as they were
        with stop_on_signals():
            animation.write_animation(movie, data["size"], poses, title, fps=fps,
                                      magnify=magnify, view=view)
            drawn = animation.write_strip(strip, data["size"], poses, title, panels=panels,
                                          magnify=magnify, view=view)
    except OSError as e:
        err(f"error: cannot write in {out}: {os_error_text(e)}")
        return os_error_code(e)
    except KeyboardInterrupt as e:
        err(f"interrupted by {signal_name(e)}: nothing new written in {out} (the files there "
            f"are as they were)")
        return ExitCode.RUN_FAILED
    echo(f"wrote {movie} ({len(idx)} of {len(t_all)} frames, t = {t_all[idx[0]]:.3f} - "
         f"{t_all[idx[-1]]:.3f} s, {fps:g} fps) and {strip} ({len(drawn)} "
         f"panel{'s' if len(drawn) != 1 else ''} at t = "
         + ", ".join(f"{t_all[idx[k]]:.3f}" for k in drawn) + " s)")
    return ExitCode.OK


def load_view(run_dir: Path) -> dict:
    """What a drawing needs from a run directory: the case's name, the blocks' sizes [N,3] (m,
    the scene rebuilt from case.json, imperfections included), and frames.npz's t [T] (s),
    pos [T,N,3] (m), quat [T,N,4], base_disp [T,3] (m), tilt_angle [T] (deg) with the tilt
    axis (unit vector) of a tilt run."""
    from dem.case import Case
    from dem.loading import AXES
    from dem.run.build import scene_from_case

    path = run_dir / "frames.npz"
    if not path.is_file():
        raise ViewError(f"{run_dir}: no frames.npz (the run wrote none yet, or it was not kept)")
    try:
        case = Case.model_validate_json((run_dir / "case.json").read_text())
    except Exception as e:  # noqa: BLE001 - name the file
        raise ViewError(f"{run_dir / 'case.json'}: not a valid case: {e}") from None
    scene = scene_from_case(case, check=False)
    try:
        with np.load(path, allow_pickle=False) as z:
            fr = {k: z[k] for k in ("t", "pos", "quat", "base_disp", "tilt_angle") if k in z.files}
    except (OSError, ValueError, EOFError) as e:
        raise ViewError(f"{path}: unreadable ({e})") from None
    if len(fr.get("t", ())) == 0:
        raise ViewError(f"{path}: no frames recorded")
    if fr["pos"].shape[1] != scene.n_blocks:
        raise ViewError(f"{path}: {fr['pos'].shape[1]} blocks, the case's scene has "
                        f"{scene.n_blocks}")
    axis = None
    if case.loading.type == "tilt":
        ax = case.loading.axis
        axis = np.asarray(AXES[ax] if isinstance(ax, str) else ax, float)
        axis = axis / np.linalg.norm(axis)
    return {"name": case.name, "size": scene.size, "t": fr["t"], "pos": fr["pos"],
            "quat": fr["quat"], "base_disp": fr.get("base_disp"),
            "tilt_angle": fr.get("tilt_angle") if axis is not None else None, "tilt_axis": axis}
