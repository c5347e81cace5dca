"""An animation (GIF, or MP4 where ffmpeg is found) and a frame strip (PNG) of recorded block
poses, drawn off-screen with matplotlib (Agg: no display, no OpenGL needed).

Every block is a box of full edge lengths ``scene.size`` (m) at centre ``pos`` (m) and
orientation ``quat`` (w, x, y, z) (dem.output.vtk.block_corners), coloured by its displacement
|x(t) - x(t0)| (m) from the first drawn frame on one colour scale for the whole animation (so
what moves shows, and a frame strip compares panels).  The poses come in the frame the run
records them in (the table's); :func:`lab_poses` puts them where they stand in the laboratory:

* a tilt: blocks and table turned by the table angle about the tilt axis through the middle of
  the first frame's footprint at table level (dem.output.snapshot.table_to_lab);
* a shake: blocks and table moved by the table displacement ``base_disp`` (m).

``magnify`` K > 1 exaggerates the motion relative to the first frame (the table's own motion is
not magnified): x = x0 + K (x - x0), and the rotation R R0^T is scaled to the same axis with
K times its angle (a shaken wall moves by millimetres; K = 50 shows the mode).  The axes keep
one scale for all frames (equal metres along x, y and z).
"""

from __future__ import annotations

import math
import shutil
from dataclasses import dataclass
from pathlib import Path

import numpy as np

from dem.output.plotting import agg_pyplot
from dem.output.vtk import block_corners

# hexahedron faces in the VTK corner numbering of block_corners
FACES = ((0, 1, 2, 3), (4, 5, 6, 7), (0, 1, 5, 4), (1, 2, 6, 5), (2, 3, 7, 6), (3, 0, 4, 7))


# light from above and in front (table frame): each face is shaded by the cosine to it, so that
# blocks of one colour (a first frame: no displacement yet) still read as boxes, not as one
# silhouette
LIGHT = np.array([0.35, -0.55, 0.76]) / np.linalg.norm([0.35, -0.55, 0.76])


def face_shading(faces: np.ndarray) -> np.ndarray:
    """[F] how lit quadrilateral faces [F, 4, 3] are, 0 - 1 (Lambert: |n . light|, n the unit
    normal; its sign is not known from the corner order alone, hence |.|)."""
    n = np.cross(faces[:, 1] - faces[:, 0], faces[:, 3] - faces[:, 0])
    n /= np.maximum(np.linalg.norm(n, axis=1, keepdims=True), 1e-300)
    return np.abs(n @ LIGHT)


@dataclass
class Poses:
    """Poses of the N blocks at T drawn frames: pos [T,N,3] (m), quat [T,N,4] (w,x,y,z); the
    table's corners [T,4,3] (m); a label per frame (time, angle); disp [T,N] (m): each block's
    displacement relative to the table from the first frame (not magnified), its colour."""

    pos: np.ndarray
    quat: np.ndarray
    table: np.ndarray
    labels: list[str]
    disp: np.ndarray


def frame_indices(n_frames: int, n_drawn: int) -> np.ndarray:
    """At most ``n_drawn`` frame indices spread evenly over 0 .. n_frames - 1, first and last
    included."""
    if n_frames <= 0:
        return np.zeros(0, dtype=int)
    n = max(1, min(int(n_drawn), n_frames))
    return np.unique(np.round(np.linspace(0, n_frames - 1, n)).astype(int))


def magnified(pos, quat, pos0, quat0, factor: float):
    """Poses with the motion from (pos0, quat0) scaled by ``factor`` (module docstring)."""
    if factor == 1.0:
        return np.asarray(pos), np.asarray(quat)
    from dem import quaternion

    r0 = quaternion.rotation(quat0)
    rel = (quaternion.rotation(quat) * r0.inv()).as_rotvec()
    from scipy.spatial.transform import Rotation

    q = quaternion.from_rotation(Rotation.from_rotvec(factor * rel) * r0)
    return pos0 + factor * (np.asarray(pos) - pos0), q


def _table(lo, hi) -> np.ndarray:
    """Corners [4,3] of the table under blocks with bounds lo, hi (a 0.3 x span margin)."""
    span = max(hi[0] - lo[0], hi[1] - lo[1], hi[2] - lo[2], 1e-3)
    x0, x1 = lo[0] - 0.3 * span, hi[0] + 0.3 * span
    y0, y1 = lo[1] - 0.3 * span, hi[1] + 0.3 * span
    return np.array([[x0, y0, 0.0], [x1, y0, 0.0], [x1, y1, 0.0], [x0, y1, 0.0]])


def lab_poses(size, t, pos, quat, base_disp=None, tilt_angle=None, tilt_axis=None,
              magnify: float = 1.0) -> Poses:
    """The recorded poses (table frame) of the drawn frames, in the laboratory (module
    docstring).  ``t`` [T] s; ``pos`` [T,N,3]; ``quat`` [T,N,4]; ``base_disp`` [T,3] m;
    ``tilt_angle`` [T] deg about the unit vector ``tilt_axis`` [3]."""
    from dem.output.snapshot import table_to_lab

    pos, quat = np.asarray(pos, float), np.asarray(quat, float)
    c0 = block_corners(size, pos[0], quat[0]).reshape(-1, 3)
    lo, hi = c0.min(axis=0), c0.max(axis=0)
    table0 = _table(lo, hi)
    pivot = np.array([0.5 * (lo[0] + hi[0]), 0.5 * (lo[1] + hi[1]), 0.0])
    out_p, out_q, out_t, labels = [], [], [], []
    for k in range(len(t)):
        p, q = magnified(pos[k], quat[k], pos[0], quat[0], magnify)
        tab = table0.copy()
        label = f"t = {t[k]:.3f} s"
        if tilt_angle is not None:
            p, q, tab = table_to_lab(p, q, tab, float(tilt_angle[k]), tilt_axis, pivot)
            label += f", table at {float(tilt_angle[k]):.2f} deg"
        elif base_disp is not None:
            d = np.asarray(base_disp[k], float)
            p, tab = p + d, tab + d
            label += f", table at {1e3 * d[0]:+.1f}, {1e3 * d[1]:+.1f} mm"
        out_p.append(p)
        out_q.append(q)
        out_t.append(tab)
        labels.append(label)
    disp = np.linalg.norm(pos - pos[0][None], axis=2)
    return Poses(np.array(out_p), np.array(out_q), np.array(out_t), labels, disp)


def ffmpeg_available() -> bool:
    """Whether matplotlib can write MP4 (an ffmpeg on PATH, or the imageio-ffmpeg wheel's)."""
    import matplotlib

    exe = matplotlib.rcParams.get("animation.ffmpeg_path", "ffmpeg")
    if shutil.which(exe):
        return True
    try:
        import imageio_ffmpeg  # type: ignore

        matplotlib.rcParams["animation.ffmpeg_path"] = imageio_ffmpeg.get_ffmpeg_exe()
        return True
    except Exception:  # noqa: BLE001 - not installed
        return False


class _Drawing:
    """One matplotlib 3-D axes holding the table and the blocks, updated frame by frame."""

    def __init__(self, ax, size, poses: Poses, colours_scale: float, view):
        import matplotlib
        from mpl_toolkits.mplot3d.art3d import Poly3DCollection

        self.ax, self.size, self.poses = ax, np.asarray(size, float), poses
        self.cmap = matplotlib.colormaps["viridis"]
        self.vmax = max(colours_scale, 1e-12)
        n_frames = len(poses.labels)
        corners = block_corners(np.tile(self.size, (n_frames, 1)), poses.pos.reshape(-1, 3),
                                poses.quat.reshape(-1, 4)).reshape(n_frames, -1, 3)
        pts = np.concatenate([corners, poses.table], axis=1).reshape(-1, 3)
        lo, hi = pts.min(axis=0), pts.max(axis=0)
        mid, half = 0.5 * (lo + hi), 0.5 * (hi - lo)
        half = np.maximum(half, 0.02 * half.max() + 1e-6)
        ax.set_xlim(mid[0] - half[0], mid[0] + half[0])
        ax.set_ylim(mid[1] - half[1], mid[1] + half[1])
        ax.set_zlim(mid[2] - half[2], mid[2] + half[2])
        ax.set_box_aspect(2 * half)
        ax.view_init(elev=view[0], azim=view[1])
        ax.set_xlabel("x (m)", fontsize=7)
        ax.set_ylabel("y (m)", fontsize=7)
        ax.set_zlabel("z (m)", fontsize=7)
        ax.tick_params(labelsize=6, pad=0)
        from matplotlib.ticker import MaxNLocator

        for axis in (ax.xaxis, ax.yaxis, ax.zaxis):
            axis.set_major_locator(MaxNLocator(3))
        # the blocks stand on the table and the camera looks from above it: draw them after it
        # (matplotlib's depth sort between two collections can put the table in front)
        ax.computed_zorder = False
        self.table = Poly3DCollection([poses.table[0]], facecolors="#d9d9d9", edgecolors="none",
                                      zorder=1)
        self.blocks = Poly3DCollection([], edgecolors="#333333", linewidths=0.3, zorder=2)
        ax.add_collection3d(self.table)
        ax.add_collection3d(self.blocks)

    def draw(self, k: int, title: str | None = None) -> None:
        p, q = self.poses.pos[k], self.poses.quat[k]
        corners = block_corners(self.size, p, q)
        colours = self.cmap(np.clip(self.poses.disp[k] / self.vmax, 0.0, 1.0))
        faces = [corners[i, list(f)] for i in range(len(p)) for f in FACES]
        self.blocks.set_verts(faces)
        rgba = np.repeat(colours, len(FACES), axis=0)
        lit = face_shading(np.asarray(faces))[:, None]
        # lit faces towards white, the others darker: readable on dark colours as on light ones
        rgba[:, :3] = (rgba[:, :3] + (1.0 - rgba[:, :3]) * 0.4 * lit) * (0.7 + 0.3 * lit)
        self.blocks.set_facecolor(rgba)
        self.table.set_verts([self.poses.table[k]])
        self.ax.set_title(title if title is not None else self.poses.labels[k], fontsize=8)


def view_angles(tilt_axis=None) -> tuple[float, float]:
    """(elevation, azimuth) in degrees of the camera: looking along a tilt axis (a little off
    it), so that the table's turn shows; from the front-left otherwise."""
    if tilt_axis is not None:
        a = np.asarray(tilt_axis, float)
        return 15.0, math.degrees(math.atan2(-a[1], -a[0])) + 15.0  # camera on the -axis side
    return 25.0, -120.0


# m: the smallest top of the colour scale: below a micrometre a displacement is the joints'
# elastic settling, and a scale of 1e-12 m would print noise as a range
MIN_COLOUR_SCALE_M = 1e-6


def _colour_scale(poses: Poses) -> float:
    return max(float(poses.disp.max()), MIN_COLOUR_SCALE_M)


def _colourbar(fig, vmax: float, magnify: float, left: float) -> None:
    """The colour scale in its own axes at ``left`` (figure fraction), right of the drawings."""
    import matplotlib
    from matplotlib.cm import ScalarMappable

    sm = ScalarMappable(norm=matplotlib.colors.Normalize(0.0, 1e3 * max(vmax, 1e-12)),
                        cmap="viridis")
    label = "displacement on the table (mm" + \
        (f"; drawn x {magnify:g})" if magnify != 1.0 else ")")
    cb = fig.colorbar(sm, cax=fig.add_axes([left, 0.15, 0.012, 0.62]))
    cb.set_label(label, fontsize=7)
    cb.ax.tick_params(labelsize=6)


def write_animation(path, size, poses: Poses, title: str, fps: float = 10.0,
                    magnify: float = 1.0, view=(25.0, -120.0), dpi: int = 80) -> str:
    """The drawn frames as an animation at ``path`` (.gif: Pillow; .mp4: ffmpeg, see
    :func:`ffmpeg_available`); returns the writer's name.  Written through a temporary file
    (dem.output.atomic): a failed write leaves no half file."""
    plt = agg_pyplot()
    from matplotlib.animation import FFMpegWriter, FuncAnimation, PillowWriter

    from dem.output.atomic import atomic_path

    path = Path(path)
    mp4 = path.suffix.lower() == ".mp4"
    if mp4 and not ffmpeg_available():
        raise ValueError("MP4 needs ffmpeg (on PATH, or `pip install imageio-ffmpeg`); "
                         "write a .gif instead")
    fig = plt.figure(figsize=(6.4, 5.2), dpi=dpi)
    ax = fig.add_axes([0.0, 0.02, 0.84, 0.88], projection="3d")
    vmax = _colour_scale(poses)
    drawing = _Drawing(ax, size, poses, vmax, view)
    _colourbar(fig, vmax, magnify, 0.86)
    fig.suptitle(title, fontsize=9)
    writer = FFMpegWriter(fps=fps) if mp4 else PillowWriter(fps=fps)
    try:
        with atomic_path(path) as tmp:  # the temporary name keeps the suffix (the format)
            # made once the file can be written: an animation never saved warns on deletion
            anim = FuncAnimation(fig, lambda k: drawing.draw(k), frames=len(poses.labels),
                                 blit=False, repeat=False)
            anim.save(str(tmp), writer=writer, dpi=dpi)
    finally:
        plt.close(fig)
    return "ffmpeg" if mp4 else "pillow"


def write_strip(path, size, poses: Poses, title: str, panels: int = 6,
                magnify: float = 1.0, view=(25.0, -120.0), dpi: int = 100) -> list[int]:
    """A row of ``panels`` drawings of frames spread evenly over the drawn ones (first and
    last included) into a PNG at ``path``, on one colour scale; returns the frame indices
    (into ``poses``) drawn."""
    plt = agg_pyplot()

    from dem.output.atomic import atomic_path

    idx = frame_indices(len(poses.labels), panels)
    width = 2.6 * len(idx) + 1.0
    fig = plt.figure(figsize=(width, 3.0), dpi=dpi)
    right = 1.0 - 1.0 / width  # the last inch holds the colour scale
    vmax = _colour_scale(poses)
    for j, k in enumerate(idx):
        ax = fig.add_axes([right * j / len(idx), 0.02, right / len(idx), 0.78],
                          projection="3d")
        _Drawing(ax, size, poses, vmax, view).draw(
            int(k), poses.labels[int(k)].replace(", ", "\n", 1))
    _colourbar(fig, vmax, magnify, right + 0.15 / width)
    fig.suptitle(title, fontsize=9, y=0.99)
    with atomic_path(Path(path)) as tmp:
        fig.savefig(tmp, format="png")
    plt.close(fig)
    return [int(k) for k in idx]
