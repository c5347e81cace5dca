"""The VTK series read back with meshio and pyvista: cells, geometry, data, times, robustness."""

from __future__ import annotations

import json
import xml.etree.ElementTree as ET

import meshio
import numpy as np
import pytest
import pyvista as pv
from scipy.spatial.transform import Rotation

from dem.builders import build_wall
from dem.output.vtk import (
    GROUP_CELL_PREFIX, GROUP_CODE_PREFIX, MAX_GROUP_CELL_ARRAYS, VtkSeries, blocks_grid,
    group_names_from_field_data, series_from_frames,
)
from dem.scene import Scene

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
    assert group_names_from_field_data(meshio.read(vtk / entries[0][1]).field_data) == ["wall"]
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


def grouped_scene(names) -> Scene:
    """One 2-brick, 1-course wall per name, side by side along x (group k = the k-th wall)."""
    return Scene.concatenate(
        [build_wall("small", 2, 1, origin=(0.6 * k, 0.0, 0.0), group=g) for k, g in enumerate(names)]
    )


def test_group_names_read_back_as_names(tmp_path):
    """The group names come back as names, not uint8 codes, from both readers, and
    select their blocks by name.  pyvista reads with VTK's own vtkXMLUnstructuredGridReader and
    thresholds with vtkThreshold, what ParaView's reader and Threshold filter use; meshio cannot
    read VTK string arrays, so the names are in the arrays' names.  Names with the characters
    VTK writes unescaped into the XML (& < > " tab) must not spoil the file."""
    names = ["wall_x", "corner", 'pier <&> "ä"\t2']
    scene = grouped_scene(names)
    assert scene.group_names == names and sorted(set(scene.group.tolist())) == [0, 1, 2]
    with VtkSeries(tmp_path, scene) as series:
        path = series.add_frame(0.0, scene.position, scene.quat, None, None)
    m = meshio.read(path)
    g = pv.read(path)
    for field, cells in ((m.field_data, {k: v[0] for k, v in m.cell_data.items()}),
                         (g.field_data, g.cell_data)):
        # the names are spelled in the file: one field array per group, holding its code
        table = {k[len(GROUP_CODE_PREFIX):]: int(np.asarray(v).ravel()[0])
                 for k, v in field.items() if k.startswith(GROUP_CODE_PREFIX)}
        assert sorted(table.values()) == [0, 1, 2]
        assert GROUP_CODE_PREFIX + "wall_x" in field and GROUP_CODE_PREFIX + "corner" in field
        assert group_names_from_field_data(field) == names
        assert np.asarray(cells["group"]).tolist() == scene.group.tolist()  # the code stays
        # one 0/1 cell array per group, named as its table entry (plain names as they are)
        assert sorted(k for k in cells if k.startswith(GROUP_CELL_PREFIX)) == \
            sorted(GROUP_CELL_PREFIX + k for k in table)
        for spelled, code in table.items():
            assert np.asarray(cells[GROUP_CELL_PREFIX + spelled]).tolist() == \
                (scene.group == code).astype(int).tolist()
            if code == 2:  # the name with & < > " tab
                assert spelled != names[2] and set('&<>"\t').isdisjoint(spelled)
            else:
                assert spelled == names[code]
    for spelled, code in table.items():  # ParaView's "Threshold group=NAME between 1 and 1"
        picked = g.threshold(value=(1, 1), scalars=GROUP_CELL_PREFIX + spelled)
        assert sorted(picked.cell_data["block_id"].tolist()) == \
            np.flatnonzero(scene.group == code).tolist()
    assert json.loads((tmp_path / "vtk" / "groups.json").read_text())["group_names"] == names


def test_many_groups_keep_the_table_but_not_one_array_each():
    """Above MAX_GROUP_CELL_ARRAYS groups no per-group cell arrays (a frame would double), but
    the code and the name table are still written."""
    names = [f"g{k}" for k in range(MAX_GROUP_CELL_ARRAYS + 1)]
    scene = grouped_scene(names)
    grid = blocks_grid(scene, scene.position, scene.quat)
    assert not [k for k in grid.cell_data if k.startswith(GROUP_CELL_PREFIX)]
    assert group_names_from_field_data(grid.field_data) == names
    assert grid.cell_data["group"].tolist() == scene.group.tolist()
    fewer = grouped_scene(names[:-1])
    grid = blocks_grid(fewer, fewer.position, fewer.quat)
    assert len([k for k in grid.cell_data if k.startswith(GROUP_CELL_PREFIX)]) == len(names) - 1


def test_files_written_before_the_name_table_still_read():
    """The uint8 ``group_names`` field array of older runs (UTF-8 names joined by newlines)."""
    names = ["L1", "roof-beam", "ä"]
    old = {"group_names": np.frombuffer("\n".join(names).encode("utf-8"), dtype=np.uint8)}
    assert group_names_from_field_data(old) == names
    with pytest.raises(ValueError, match="group_code"):
        group_names_from_field_data({"time": np.zeros(1)})


@pytest.mark.parametrize("names, field", [(["a", "a"], "group_names"), (["a", ""], "group_names")])
def test_group_names_that_cannot_be_told_apart_are_refused(names, field):
    scene = build_wall("small", 2, 1)
    scene.group_names = names
    scene.group[:] = 0
    with pytest.raises(ValueError, match=f"scene.{field}"):
        blocks_grid(scene, scene.position, scene.quat)
