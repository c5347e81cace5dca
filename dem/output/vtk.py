"""Streaming VTK output for ParaView: one binary ``.vtu`` per frame plus a ``.pvd`` time series.

Layout (contract of ../shared/DESIGN.md)::

    OUT/vtk/blocks_00000.vtu ...   one hexahedron cell per block (zlib-compressed binary XML)
    OUT/vtk/scene.pvd              collection: the real simulated time of every frame
    OUT/vtk/contacts_00000.vtp ... (optional) contact points as poly-data vertices
    OUT/vtk/contacts.pvd

Frame: positions are in the table frame (metres; the base stays at z = 0 and does not move),
which is what the engine integrates and what ``frames.npz`` holds.  ``frame="lab"`` adds the table
displacement ``base_disp`` to the points (the blocks then move with the table as seen in the lab);
cell data stay relative to the table either way.

Cell data per block (cell i = block i, in the order of the scene: explicit blocks first):

    block_id        int32    index of the block
    group           int32    code of the block's group: index into ``scene.group_names``
    group=NAME      uint8    one array per group NAME (e.g. ``group=L1``): 1 for the blocks of
                             the group, 0 for the others (only while the scene has at most
                             MAX_GROUP_CELL_ARRAYS groups, to keep frames small)
    course          int32    course index (0 = bottom course, -1 where it does not apply)
    displacement    float32  [3] position minus the initial position, m (table frame)
    velocity        float32  [3] m/s (table frame)
    rotation_angle  float32  angle of the rotation from the initial orientation, degrees

and, for an imperfect scene only (dem.imperfections; a perfect scene's files are unchanged):

    size            float32  [3] edge lengths as realised, m
    face_offset     float32  [24] corner offsets of the six faces (face f, corner c at 4 f + c,
                             dem.scene's numbering), m, <= 0 (recessed from the nominal face)
    arris           float32  radius of the rounded edges, m

Field data per file: ``TimeValue`` and ``time`` (s), ``base_displacement`` [3] (m), and the
table of group names: one int32 array ``group_code:NAME`` per group holding its code (the value
of ``group`` for its blocks).  ``vtk/groups.json`` lists the same names in code order.

Group names, and why they are spelled in array names: ParaView's Threshold and colouring work on
numbers, and meshio (5.3) cannot read VTK string arrays at all (an ``<Array type="String">``
anywhere in a .vtu makes ``meshio.read`` fail), so the names are carried by the names of numeric
arrays, which both read back (the characters ``% < > & "`` and control characters of a name
appear there as ``%XX``, e.g. ``group=a%26b`` for the group ``a&b``).  In ParaView, colour or
threshold by ``group=L1`` (1 to 1) for the blocks of L1, or by ``group`` with the code that the
field array ``group_code:L1`` holds (Information panel, Data Arrays; or the spreadsheet's Field
Data).  In Python,
:func:`group_names_from_field_data` turns meshio's or pyvista's field data back into the list of
names.  Files written before this (uint8 field data ``group_names``, the UTF-8 names joined by
newlines) are read by the same function (:func:`decode_names`).

Contacts carry point data ``normal`` [3], ``fn`` (N, normal force), ``ft`` [3] (N, shear force)
and ``ft_magnitude`` (N).

The ``.pvd`` files are rewritten after every frame through a temporary file and an atomic rename,
and every ``.vtu`` is written to a temporary name first, so whatever happens to the run, the
series on disk is valid and lists exactly the frames that are complete.

Size: points and data are float32 and zlib-compressed; a 217-block box model in motion takes
about 34 kB per frame (~160 bytes per block, 2.3 kB of it the 7 groups' arrays; measured, see
README "Output"), written in ~10 ms.
"""

from __future__ import annotations

import json
import xml.etree.ElementTree as ET
from pathlib import Path
from urllib.parse import unquote

import numpy as np
import pyvista as pv
from vtkmodules.util.numpy_support import numpy_to_vtk

from dem import quaternion
from dem.output.atomic import atomic_path, write_text
from dem.scene import Scene

GROUP_CODE_PREFIX = "group_code:"  # field data: GROUP_CODE_PREFIX + name -> int32 [code]
GROUP_CELL_PREFIX = "group="  # cell data: GROUP_CELL_PREFIX + name -> uint8 [N], 1 in the group
# above this many groups only the code and the table are written: a group costs about 330 bytes
# per frame (measured: Model II's 7 groups take its 217-block frames from 31.5 to 33.8 kB, median
# of 16 frames of a 0.3 s run), and a group per block (explicit blocks may each name one) would
# double a frame
MAX_GROUP_CELL_ARRAYS = 16
# VTK writes array names into the XML unescaped: a name with < & " (or a tab / newline, which
# XML turns into spaces) would make the file unreadable, so these are written as %XX
_UNSAFE_IN_NAME = set('%<>&"') | {chr(c) for c in range(32)} | {"\x7f"}

# VTK_HEXAHEDRON vertex order: bottom face counter-clockwise, then the top face
HEX_CORNERS = np.array(
    [[-1, -1, -1], [1, -1, -1], [1, 1, -1], [-1, 1, -1], [-1, -1, 1], [1, -1, 1], [1, 1, 1], [-1, 1, 1]],
    dtype=np.float64,
)


def block_corners(size: np.ndarray, pos: np.ndarray, quat: np.ndarray) -> np.ndarray:
    """Corners [N,8,3] of boxes (full edge lengths ``size``, centres ``pos``, orientations ``quat``
    (w, x, y, z)) in VTK hexahedron order, m."""
    r = quaternion.matrices(quat)
    local = HEX_CORNERS[None, :, :] * (0.5 * np.asarray(size))[:, None, :]
    return np.asarray(pos)[:, None, :] + np.einsum("nij,nkj->nki", r, local)


def rotation_angle_deg(quat: np.ndarray, quat0: np.ndarray) -> np.ndarray:
    """Angle of the rotation taking orientation ``quat0`` to ``quat`` (both [N,4], w x y z), deg."""
    q = quat / np.linalg.norm(quat, axis=1, keepdims=True)
    q0 = quat0 / np.linalg.norm(quat0, axis=1, keepdims=True)
    c = np.clip(np.abs(np.sum(q * q0, axis=1)), 0.0, 1.0)
    return np.degrees(2.0 * np.arccos(c))


def blocks_grid(
    scene: Scene,
    pos: np.ndarray,
    quat: np.ndarray,
    vel: np.ndarray | None = None,
    t: float | None = None,
    base_disp=None,
    shift=None,
    dtype=np.float32,
) -> pv.UnstructuredGrid:
    """An UnstructuredGrid with one hexahedron per block and the cell/field data described in the
    module docstring.  ``shift`` [3] is added to the points (the lab frame)."""
    n = scene.n_blocks
    pos = np.asarray(pos, dtype=np.float64).reshape(n, 3)
    quat = np.asarray(quat, dtype=np.float64).reshape(n, 4)
    pts = block_corners(scene.size, pos, quat).reshape(-1, 3)
    if shift is not None:
        pts = pts + np.asarray(shift, dtype=np.float64).reshape(1, 3)
    cells = np.hstack([np.full((n, 1), 8), np.arange(8 * n).reshape(n, 8)]).ravel()
    grid = pv.UnstructuredGrid(cells, np.full(n, pv.CellType.HEXAHEDRON, dtype=np.uint8), pts.astype(dtype))
    grid.cell_data["block_id"] = np.arange(n, dtype=np.int32)
    names = _checked_group_names(scene)
    grid.cell_data["group"] = scene.group.astype(np.int32)
    if len(names) <= MAX_GROUP_CELL_ARRAYS:
        for code, name in enumerate(names):
            grid.cell_data[GROUP_CELL_PREFIX + _array_name(name)] = (scene.group == code).astype(np.uint8)
    grid.cell_data["course"] = scene.course.astype(np.int32)
    grid.cell_data["displacement"] = (pos - scene.position).astype(dtype)
    v = np.zeros((n, 3)) if vel is None else np.asarray(vel, dtype=np.float64).reshape(n, 3)
    grid.cell_data["velocity"] = v.astype(dtype)
    grid.cell_data["rotation_angle"] = rotation_angle_deg(quat, scene.quat).astype(dtype)
    if scene.imperfect.any():
        grid.cell_data["size"] = scene.size.astype(dtype)
        grid.cell_data["face_offset"] = scene.face_offset.reshape(n, 24).astype(dtype)
        grid.cell_data["arris"] = scene.arris.astype(dtype)
    if t is not None:
        grid.field_data["TimeValue"] = np.array([t], dtype=np.float64)
        grid.field_data["time"] = np.array([t], dtype=np.float64)
    if base_disp is not None:
        grid.field_data["base_displacement"] = np.asarray(base_disp, dtype=np.float64).reshape(3)
    for code, name in enumerate(names):
        grid.field_data[GROUP_CODE_PREFIX + _array_name(name)] = np.array([code], dtype=np.int32)
    return grid


def _array_name(name: str) -> str:
    """``name`` with the characters VTK would write unescaped into the XML as %XX (inverse:
    urllib.parse.unquote)."""
    return "".join(f"%{ord(ch):02X}" if ch in _UNSAFE_IN_NAME else ch for ch in name)


def _checked_group_names(scene: Scene) -> list[str]:
    """``scene.group_names``, refused (ValueError naming the field) where they could not be told
    apart in the array names: empty or repeated names, or fewer names than the codes used."""
    names = [str(g) for g in scene.group_names]
    if any(not g for g in names):
        raise ValueError(f"scene.group_names: an empty group name in {names!r}")
    if len(set(names)) != len(names):
        raise ValueError(f"scene.group_names: repeated names in {names!r}")
    if scene.n_blocks and not 0 <= int(np.min(scene.group)) <= int(np.max(scene.group)) < len(names):
        raise ValueError(f"scene.group: codes {int(np.min(scene.group))} to {int(np.max(scene.group))} "
                         f"outside the {len(names)} group_names")
    return names


def group_names_from_field_data(field_data) -> list[str]:
    """The group names in code order (``names[code]``) from the field data of a blocks .vtu read
    back: meshio's ``mesh.field_data`` or pyvista's ``grid.field_data`` (any mapping of array name
    to array).  Reads the ``group_code:NAME`` arrays, or, in files written before them, the uint8
    ``group_names`` array.  Raises ValueError if neither is there or the codes are not 0..n-1."""
    table = {
        unquote(key[len(GROUP_CODE_PREFIX):]): int(np.asarray(field_data[key]).ravel()[0])
        for key in field_data.keys() if key.startswith(GROUP_CODE_PREFIX)
    }
    if not table:
        if "group_names" in field_data.keys():
            return decode_names(field_data["group_names"])
        raise ValueError(f"no {GROUP_CODE_PREFIX}NAME (or group_names) array in the field data")
    names = sorted(table, key=table.get)
    if [table[n] for n in names] != list(range(len(names))):
        raise ValueError(f"{GROUP_CODE_PREFIX}NAME codes are not 0..{len(names) - 1}: {table}")
    return names


def decode_names(arr) -> list[str]:
    """Group names from the uint8 field array ``group_names`` of files written before the
    ``group_code:NAME`` arrays (UTF-8, names joined by newlines)."""
    return bytes(np.asarray(arr, dtype=np.uint8)).decode("utf-8").split("\n")


def _atomic_save(mesh: pv.DataSet, path: Path) -> None:
    with atomic_path(path) as tmp:
        mesh.save(tmp, binary=True, compression="zlib")


class _Collection:
    """A ParaView ``.pvd`` collection, rewritten atomically after each added data set."""

    def __init__(self, path: Path):
        self.path = path
        self.entries: list[str] = []

    def add(self, t: float, file: str) -> None:
        el = ET.Element("DataSet", timestep=repr(float(t)), group="", part="0", file=file)
        self.entries.append("    " + ET.tostring(el, encoding="unicode"))
        self.write()

    def write(self) -> None:
        text = "\n".join(
            [
                '<?xml version="1.0"?>',
                '<VTKFile type="Collection" version="0.1" byte_order="LittleEndian">',
                "  <Collection>",
                *self.entries,
                "  </Collection>",
                "</VTKFile>",
                "",
            ]
        )
        write_text(self.path, text)


class VtkSeries:
    """Streaming writer of the ``vtk/`` directory, called by the run loop once per output frame.

    ``VtkSeries(out_dir, scene, write_contacts=False)``, then ``add_frame(t, pos, quat, vel,
    base_disp, contacts=None)`` per frame and ``close()`` at the end (also a context manager).

    t          simulated time, s
    pos        [N,3] block centres, m, table frame
    quat       [N,4] orientations (w, x, y, z), body -> table
    vel        [N,3] velocities, m/s, table frame
    base_disp  [3] table displacement, m
    contacts   {"point": [M,3] m, "normal": [M,3], "fn": [M] N, "ft": [M,3] N} or None
    frame      "table" (default: points in the table frame) or "lab" (points + base_disp)
    """

    def __init__(self, out_dir: Path, scene: Scene, write_contacts: bool = False, frame: str = "table"):
        if frame not in ("table", "lab"):
            raise ValueError(f"frame must be 'table' or 'lab', got {frame!r}")
        self.dir = Path(out_dir) / "vtk"
        self.dir.mkdir(parents=True, exist_ok=True)
        for stale in [*self.dir.glob("blocks_*.vtu"), *self.dir.glob("contacts_*.vtp")]:
            stale.unlink()  # from an earlier run into the same directory
        self.scene = scene
        self.write_contacts = write_contacts
        self.frame = frame
        self.n_frames = 0
        self.bytes_written = 0
        self.closed = False
        self._blocks = _Collection(self.dir / "scene.pvd")
        self._contacts = _Collection(self.dir / "contacts.pvd") if write_contacts else None
        self._blocks.write()  # an empty but valid series from the start
        write_text(self.dir / "groups.json",
                   json.dumps({"group_names": list(scene.group_names)}, indent=1) + "\n")
        if self._contacts is not None:
            self._contacts.write()

    def add_frame(self, t: float, pos, quat, vel, base_disp, contacts: dict | None = None) -> Path:
        """Write one frame; returns the path of its ``.vtu``."""
        if self.closed:
            raise RuntimeError("VtkSeries is closed")
        k = self.n_frames
        base = np.zeros(3) if base_disp is None else np.asarray(base_disp, dtype=np.float64).reshape(3)
        grid = blocks_grid(
            self.scene, pos, quat, vel, t=float(t), base_disp=base,
            shift=base if self.frame == "lab" else None,
        )
        name = f"blocks_{k:05d}.vtu"
        _atomic_save(grid, self.dir / name)
        self.bytes_written += (self.dir / name).stat().st_size
        if self._contacts is not None:
            cname = f"contacts_{k:05d}.vtp"
            _atomic_save(self._contact_polydata(float(t), base, contacts), self.dir / cname)
            self.bytes_written += (self.dir / cname).stat().st_size
            self._contacts.add(t, cname)
        self._blocks.add(t, name)
        self.n_frames += 1
        return self.dir / name

    def _contact_polydata(self, t: float, base: np.ndarray, contacts: dict | None) -> pv.PolyData:
        if contacts is None or len(np.asarray(contacts.get("point", []))) == 0:
            pts = np.zeros((0, 3))
            normal, fn, ft = np.zeros((0, 3)), np.zeros(0), np.zeros((0, 3))
        else:
            pts = np.asarray(contacts["point"], dtype=np.float64).reshape(-1, 3)
            m = len(pts)
            normal = np.asarray(contacts["normal"], dtype=np.float64).reshape(m, 3)
            fn = np.asarray(contacts["fn"], dtype=np.float64).reshape(m)
            ft = np.asarray(contacts["ft"], dtype=np.float64).reshape(m, 3)
        if self.frame == "lab":
            pts = pts + base
        poly = pv.PolyData(pts.astype(np.float32))
        if len(pts):
            poly.verts = np.hstack([np.ones((len(pts), 1), dtype=np.int64), np.arange(len(pts))[:, None]]).ravel()
        arrays = {
            "normal": normal,
            "fn": fn,
            "ft": ft,
            "ft_magnitude": np.linalg.norm(ft, axis=1),
        }
        for key, arr in arrays.items():
            # through VTK directly: pyvista refuses empty arrays, and a frame may have no contact
            vtk_arr = numpy_to_vtk(np.ascontiguousarray(arr, dtype=np.float32), deep=True)
            vtk_arr.SetName(key)
            if arr.ndim == 2:
                vtk_arr.SetNumberOfComponents(3)
            poly.GetPointData().AddArray(vtk_arr)
        poly.field_data["TimeValue"] = np.array([t])
        poly.field_data["time"] = np.array([t])
        poly.field_data["base_displacement"] = base
        return poly

    def close(self) -> None:
        """Finish the series (the .pvd files are already complete after every frame)."""
        if not self.closed:
            self._blocks.write()
            if self._contacts is not None:
                self._contacts.write()
            self.closed = True

    def __enter__(self) -> "VtkSeries":
        return self

    def __exit__(self, *exc) -> None:
        self.close()


def series_from_frames(
    out_dir, scene: Scene, frames_path=None, frame: str = "table", every: int = 1
) -> int:
    """Write ``out_dir/vtk/`` from a ``frames.npz`` (arrays t, pos, quat, base_disp and, if
    present, vel) of the same scene: for runs recorded without VTK, or to rebuild it.  ``every``
    keeps every k-th frame (and the last).  Returns the number of frames written."""
    out_dir = Path(out_dir)
    data = np.load(frames_path or out_dir / "frames.npz")
    t, pos, quat, base = data["t"], data["pos"], data["quat"], data["base_disp"]
    vel = data["vel"] if "vel" in data.files else np.zeros_like(pos)
    keep = list(range(0, len(t), max(1, int(every))))
    if keep and keep[-1] != len(t) - 1:
        keep.append(len(t) - 1)
    with VtkSeries(out_dir, scene, frame=frame) as series:
        for k in keep:
            series.add_frame(float(t[k]), pos[k], quat[k], vel[k], base[k])
    return len(keep)
