"""The VTK series read back with meshio and pyvista: cells, geometry, data, times, robustness."""

from __future__ import annotations

import xml.etree.ElementTree as ET

import meshio
import numpy as np
import pytest
import pyvista as pv
from scipy.spatial.transform import Rotation

from dem.builders import build_wall
from dem.output.vtk import VtkSeries, decode_names, series_from_frames

TIMES = [0.0, 0.013, 0.05, 0.1]  # deliberately uneven: the pvd must hold the real times


def quat_wxyz(rot: Rotation) -> np.ndarray:
    return rot.as_quat(scalar_first=True)


@pytest.fixture
def motion():
    """A 3 x 3 wall (3 + 4 + 3 = 10 blocks) and four frames: everything drifts along y, block 0
    turns about z by 10 deg per frame and block 1 about x by 5 deg per frame."""
    scene = build_wall("small", 3, 3)
    n = scene.n_blocks
    frames = []
    for k, t in enumerate(TIMES):
        pos = scene.position + np.array([0.0, 0.002 * k, 0.0])
        rots = [Rotation.identity()] * n
        rots[0] = Rotation.from_euler("z", 10 * k, degrees=True)
        rots[1] = Rotation.from_euler("x", 5 * k, degrees=True)
        quat = np.array([quat_wxyz(r) for r in rots])
        vel = np.tile([0.0, 0.2, 0.0], (n, 1)) * k
        frames.append((t, pos, quat, vel, np.array([0.0, 0.003 * k, 0.0])))
    return scene, frames


def pvd_entries(path):
    root = ET.parse(path).getroot()
    return [(float(d.get("timestep")), d.get("file")) for d in root.iter("DataSet")]


def test_series_reads_back(tmp_path, motion):
    scene, frames = motion
    n = scene.n_blocks
    assert n == 10
    with VtkSeries(tmp_path, scene) as series:
        for f in frames:
            series.add_frame(*f)
    vtk = tmp_path / "vtk"
    entries = pvd_entries(vtk / "scene.pvd")
    assert [t for t, _ in entries] == TIMES  # exact: written with repr()
    assert pv.get_reader(str(vtk / "scene.pvd")).time_values == pytest.approx(TIMES)
    assert decode_names(meshio.read(vtk / entries[0][1]).field_data["group_names"]) == ["wall"]
    for (t, pos, quat, vel, base), (tp, file) in zip(frames, entries):
        m = meshio.read(vtk / file)
        assert [c.type for c in m.cells] == ["hexahedron"] and len(m.cells[0].data) == n
        corners = m.points[m.cells[0].data]  # [n, 8, 3]
        assert corners.mean(axis=1) == pytest.approx(pos, abs=1e-6)  # centres = frames' pos
        # edges 0-1, 0-3, 0-4 of a VTK hexahedron are the block's own x, y, z edges
        for a, b, axis in ((0, 1, 0), (0, 3, 1), (0, 4, 2)):
            length = np.linalg.norm(corners[:, b] - corners[:, a], axis=1)
            assert length == pytest.approx(scene.size[:, axis], abs=1e-6)
        cd = {k: v[0] for k, v in m.cell_data.items()}
        assert cd["block_id"].tolist() == list(range(n))
        assert cd["course"].tolist() == scene.course.tolist()
        assert (cd["group"] == 0).all()
        assert cd["displacement"] == pytest.approx(pos - scene.position, abs=1e-6)
        assert cd["velocity"] == pytest.approx(vel, abs=1e-6)
        k = TIMES.index(t)
        expect = np.zeros(n)
        expect[0], expect[1] = 10 * k, 5 * k
        assert cd["rotation_angle"] == pytest.approx(expect, abs=1e-3)
        assert m.field_data["TimeValue"][0] == t and m.field_data["time"][0] == t
        assert m.field_data["base_displacement"] == pytest.approx(base)
        # pyvista reads the same file
        g = pv.read(vtk / file)
        assert g.n_cells == n and g.cell_data["block_id"].tolist() == list(range(n))


def test_turned_block_corners(tmp_path, motion):
    """The corners follow the quaternion: block 0 turned 30 deg about z at frame 3."""
    scene, frames = motion
    with VtkSeries(tmp_path, scene) as series:
        for f in frames:
            series.add_frame(*f)
    m = meshio.read(tmp_path / "vtk" / "blocks_00003.vtu")
    c = m.points[m.cells[0].data[0]]
    edge = c[1] - c[0]  # the block's x edge
    assert np.degrees(np.arctan2(edge[1], edge[0])) == pytest.approx(30.0, abs=1e-4)


def test_series_stays_valid_when_the_run_dies(tmp_path, motion):
    """Without close() (a crashed or interrupted run) the pvd lists exactly the frames written,
    all readable, and no temporary files are left."""
    scene, frames = motion
    series = VtkSeries(tmp_path, scene)
    for f in frames[:3]:
        series.add_frame(*f)
    vtk = tmp_path / "vtk"
    entries = pvd_entries(vtk / "scene.pvd")
    assert [t for t, _ in entries] == TIMES[:3]
    for _, file in entries:
        assert meshio.read(vtk / file).cells[0].data.shape == (scene.n_blocks, 8)
    assert sorted(p.name for p in vtk.iterdir()) == [
        "blocks_00000.vtu", "blocks_00001.vtu", "blocks_00002.vtu", "groups.json", "scene.pvd"
    ]


def test_empty_series_is_valid(tmp_path, motion):
    scene, _ = motion
    VtkSeries(tmp_path, scene)
    assert pvd_entries(tmp_path / "vtk" / "scene.pvd") == []


def test_lab_frame_adds_the_table_displacement(tmp_path, motion):
    scene, frames = motion
    with VtkSeries(tmp_path, scene, frame="lab") as series:
        for f in frames:
            series.add_frame(*f)
    t, pos, quat, vel, base = frames[3]
    m = meshio.read(tmp_path / "vtk" / "blocks_00003.vtu")
    assert m.points[m.cells[0].data].mean(axis=1) == pytest.approx(pos + base, abs=1e-6)
    # displacement stays relative to the table
    assert m.cell_data["displacement"][0] == pytest.approx(pos - scene.position, abs=1e-6)


def test_contact_series(tmp_path, motion):
    scene, frames = motion
    rng = np.random.default_rng(1)
    contacts = {
        "point": rng.random((7, 3)), "normal": np.tile([0.0, 0.0, 1.0], (7, 1)),
        "fn": rng.random(7) * 10, "ft": rng.random((7, 3)),
    }
    with VtkSeries(tmp_path, scene, write_contacts=True) as series:
        series.add_frame(*frames[0], contacts=contacts)
        series.add_frame(*frames[1], contacts=None)  # a frame without contacts
    vtk = tmp_path / "vtk"
    assert pv.get_reader(str(vtk / "contacts.pvd")).time_values == pytest.approx(TIMES[:2])
    p = pv.read(vtk / "contacts_00000.vtp")
    assert p.n_points == 7 and p.n_cells == 7  # one vertex cell per contact point
    assert p.points == pytest.approx(contacts["point"], abs=1e-6)
    assert p.point_data["fn"] == pytest.approx(contacts["fn"], rel=1e-6)
    assert p.point_data["ft_magnitude"] == pytest.approx(np.linalg.norm(contacts["ft"], axis=1), rel=1e-6)
    assert pv.read(vtk / "contacts_00001.vtp").n_points == 0


def test_frame_size_is_reasonable(tmp_path):
    """About 100 bytes per block and frame (float32, zlib): a 217-block Model II frame < 40 kB."""
    from dem.builders import build_box_model

    scene = build_box_model("II")
    rng = np.random.default_rng(0)
    with VtkSeries(tmp_path, scene) as series:
        path = series.add_frame(1.0, scene.position + rng.normal(0, 1e-3, (217, 3)), scene.quat,
                                rng.normal(0, 0.1, (217, 3)), [0, 0.004, 0])
    assert path.stat().st_size < 40_000


def test_vtk_matches_frames_npz_of_a_run(tmp_path):
    """A short real run: the .vtu block centres equal frames.npz positions, the pvd its times."""
    from dem.case import parse_case
    from dem.run import run_case
    from dem.run import scene_from_case

    case = parse_case({
        "name": "vtk-run",
        "scene": {"blocks": [
            {"size": [0.2, 0.2, 0.1], "position": [0.0, 0.0, 0.05], "mass": 4.0},
            {"size": [0.1, 0.1, 0.4], "position": [0.5, 0.0, 0.2], "rotation": [0, 0, 20], "density": 2000},
        ]},
        "material": {"friction": 0.5},
        "loading": {"type": "shake", "direction": [1, 0, 0], "frequency": 5.0, "peak_acceleration": 6.0},
        "run": {"duration": 0.05, "output_interval": 0.002},
    })
    run_case(case, tmp_path, max_steps=400)
    data = np.load(tmp_path / "frames.npz")
    vtk = tmp_path / "vtk"
    if not (vtk / "scene.pvd").exists():  # the run loop did not write VTK itself
        series_from_frames(tmp_path, scene_from_case(case))
    entries = pvd_entries(vtk / "scene.pvd")
    assert len(entries) == len(data["t"]) >= 3
    assert [t for t, _ in entries] == pytest.approx(data["t"].tolist(), abs=1e-12)
    for k, (_, file) in enumerate(entries):
        m = meshio.read(vtk / file)
        assert m.points[m.cells[0].data].mean(axis=1) == pytest.approx(data["pos"][k], abs=1e-6)
        assert m.field_data["base_displacement"] == pytest.approx(data["base_disp"][k], abs=1e-9)
