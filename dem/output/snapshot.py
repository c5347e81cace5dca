"""PNG snapshot of a state of the scene, rendered off-screen (no display needed).

pyvista renders off-screen through EGL or OSMesa when there is no X display (checked on the
project machine: VTK 9.7 picks ``vtkEGLRenderWindow`` on Mesa llvmpipe, ~1.5 s per image
including start-up).  Where pyvista cannot render at all, a matplotlib 3-D drawing of the block
faces is written instead (slower and without lighting), and the function says so in its return
value.
"""

from __future__ import annotations

import os
from pathlib import Path

import numpy as np

from dem.output.plotting import agg_pyplot
from dem.output.vtk import block_corners, blocks_grid
from dem.scene import Scene

# hexahedron faces in the HEX_CORNERS numbering
_FACES = [(0, 1, 2, 3), (4, 5, 6, 7), (0, 1, 5, 4), (1, 2, 6, 5), (2, 3, 7, 6), (3, 0, 4, 7)]


def snapshot_png(
    path,
    scene: Scene,
    pos,
    quat,
    scalars=None,
    title: str | None = None,
    scalar_name: str = "value",
    window_size=(1200, 900),
    tilt=None,
) -> str:
    """Render the blocks at ``pos`` [N,3] (m) / ``quat`` [N,4] (w, x, y, z) into a PNG at ``path``.

    Blocks are coloured by ``scalars`` ([N], e.g. displacement magnitude in m; a colour bar
    named ``scalar_name`` is drawn) or, by default, by group (wall label).  The table is drawn
    as a grey plane at z = 0; the camera looks from the front (-y) and above.
    ``tilt``: (angle in degrees, axis [3]) of a tilting table: the poses are in the table frame,
    and the table with the blocks on it is drawn turned by the angle about the axis (through
    the middle of the blocks' footprint at table level), as it stands in the laboratory
    (table_to_lab), so that the tilt shows.
    Returns "pyvista" or "matplotlib" (the renderer that was used).
    """
    path = Path(path)
    path.parent.mkdir(parents=True, exist_ok=True)
    pos = np.asarray(pos, dtype=np.float64).reshape(scene.n_blocks, 3)
    quat = np.asarray(quat, dtype=np.float64).reshape(scene.n_blocks, 4)
    lo, hi = _footprint(scene, pos, quat)
    table = _table_corners(lo, hi)
    if tilt is not None:
        pivot = np.array([0.5 * (lo[0] + hi[0]), 0.5 * (lo[1] + hi[1]), 0.0])
        pos, quat, table = table_to_lab(pos, quat, table, tilt[0], tilt[1], pivot)
    from dem.output.atomic import atomic_path

    with atomic_path(path) as tmp:  # a failed write (disk full) leaves no half PNG
        try:
            _pyvista(tmp, scene, pos, quat, scalars, title, scalar_name, window_size, table)
            return "pyvista"
        except OSError:
            raise
        except Exception:  # noqa: BLE001 - no OpenGL: draw with matplotlib instead
            matplotlib_snapshot(tmp, scene, pos, quat, scalars, title, window_size, table)
            return "matplotlib"


def _footprint(scene, pos, quat):
    """Bounds (lo, hi) [3] of the blocks' corners."""
    c = block_corners(scene.size, pos, quat).reshape(-1, 3)
    return c.min(axis=0), c.max(axis=0)


def _table_corners(lo, hi) -> np.ndarray:
    """Corners [4,3] of the table drawn under blocks with bounds lo, hi: at z = 0, a margin of
    0.3 x the largest extent around them."""
    span = max(hi[0] - lo[0], hi[1] - lo[1], hi[2] - lo[2], 1e-3)
    x0, x1 = lo[0] - 0.3 * span, hi[0] + 0.3 * span
    y0, y1 = lo[1] - 0.3 * span, hi[1] + 0.3 * span
    return np.array([[x0, y0, 0.0], [x1, y0, 0.0], [x1, y1, 0.0], [x0, y1, 0.0]])


def table_to_lab(pos, quat, points, angle_deg: float, axis, pivot=(0.0, 0.0, 0.0)):
    """Poses (pos [N,3], quat [N,4]) and points [M,3] given in the frame of a table tilted by
    ``angle_deg`` about ``axis``, in the laboratory frame: turned by +angle about the axis
    through ``pivot`` (dem.loading.Tilt turns gravity the other way, g_table = R^T g, so about
    +y the table's +x side goes down and the load points to +x)."""
    from scipy.spatial.transform import Rotation

    from dem import quaternion

    a = np.asarray(axis, dtype=np.float64)
    rot = Rotation.from_rotvec(np.radians(angle_deg) * a / np.linalg.norm(a))
    pivot = np.asarray(pivot, dtype=np.float64)
    pos_lab = pivot + rot.apply(np.asarray(pos) - pivot)
    quat_lab = quaternion.from_rotation(rot * quaternion.rotation(quat))
    return pos_lab, quat_lab, pivot + rot.apply(np.asarray(points) - pivot)


def _pyvista(path, scene, pos, quat, scalars, title, scalar_name, window_size, table_pts) -> None:
    if not os.environ.get("DISPLAY"):
        # without X, go straight to EGL (VTK would first try X and print a warning)
        os.environ.setdefault("VTK_DEFAULT_OPENGL_WINDOW", "vtkEGLRenderWindow")
    import pyvista as pv

    grid = blocks_grid(scene, pos, quat)
    lo, hi = grid.bounds[0::2], grid.bounds[1::2]
    span = max(hi[0] - lo[0], hi[1] - lo[1], hi[2] - lo[2], 1e-3)
    plotter = pv.Plotter(off_screen=True, window_size=list(window_size))
    plotter.set_background("white")
    table = pv.PolyData(np.asarray(table_pts, dtype=np.float64), faces=[4, 0, 1, 2, 3])
    plotter.add_mesh(table, color="#d9d9d9")
    if scalars is not None:
        grid.cell_data[scalar_name] = np.asarray(scalars, dtype=np.float64).reshape(scene.n_blocks)
        plotter.add_mesh(grid, scalars=scalar_name, cmap="viridis", show_edges=True, edge_color="#333333",
                         scalar_bar_args={"title": scalar_name, "color": "black"})
    else:
        n_groups = max(len(scene.group_names), 1)
        grid.cell_data["group_id"] = scene.group.astype(np.int32)
        plotter.add_mesh(
            grid, scalars="group_id", cmap="tab10", clim=[-0.5, max(n_groups, 10) - 0.5],
            show_edges=True, edge_color="#333333", show_scalar_bar=False,
        )
        plotter.add_legend(
            [[name, _tab10(i)] for i, name in enumerate(scene.group_names)],
            bcolor="white", face="rectangle", size=(0.18, 0.04 * n_groups + 0.02), loc="lower left",
        )
    if title:
        plotter.add_title(title, font_size=12, color="black")
    centre = np.array([(lo[i] + hi[i]) / 2 for i in range(3)])
    plotter.camera_position = [
        tuple(centre + np.array([-0.9, -1.6, 1.0]) * 1.3 * span),
        tuple(centre),
        (0, 0, 1),
    ]
    plotter.screenshot(str(path))
    plotter.close()


def _tab10(i: int) -> str:
    import matplotlib

    return matplotlib.colors.to_hex(matplotlib.colormaps["tab10"](i % 10))


def matplotlib_snapshot(path, scene, pos, quat, scalars, title, window_size,
                        table_pts=None) -> None:
    plt = agg_pyplot()
    import matplotlib
    from mpl_toolkits.mplot3d.art3d import Poly3DCollection

    corners = block_corners(scene.size, pos, quat)
    if scalars is not None:
        v = np.asarray(scalars, dtype=np.float64)
        rng = np.ptp(v) or 1.0
        colours = matplotlib.colormaps["viridis"]((v - v.min()) / rng)
    else:
        colours = [_tab10(g) for g in scene.group]
    polys, fc = [], []
    for i in range(scene.n_blocks):
        for f in _FACES:
            polys.append(corners[i, list(f)])
            fc.append(colours[i])
    fig = plt.figure(figsize=(window_size[0] / 100, window_size[1] / 100), dpi=100)
    ax = fig.add_subplot(projection="3d")
    if table_pts is None:
        table_pts = _table_corners(*_footprint(scene, pos, quat))
    table_pts = np.asarray(table_pts, dtype=np.float64)
    ax.add_collection3d(Poly3DCollection([table_pts], facecolors="#d9d9d9", edgecolors="none"))
    ax.add_collection3d(Poly3DCollection(polys, facecolors=fc, edgecolors="#333333", linewidths=0.2))
    pts = np.concatenate([corners.reshape(-1, 3), table_pts])
    lo, hi = pts.min(axis=0), pts.max(axis=0)
    ax.set_xlim(lo[0], hi[0])
    ax.set_ylim(lo[1], hi[1])
    ax.set_zlim(lo[2], hi[2])
    ax.set_box_aspect(np.maximum(hi - lo, 1e-3))
    ax.view_init(elev=25, azim=-120)
    ax.set_xlabel("x (m)")
    ax.set_ylabel("y (m)")
    ax.set_zlabel("z (m)")
    if title:
        ax.set_title(title)
    fig.savefig(path)
    plt.close(fig)
