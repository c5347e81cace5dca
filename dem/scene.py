"""Scene: the blocks of a simulation as plain numpy arrays (what builders produce).

The lowest layer above numpy: it knows nothing of case files (dem.run.build.scene_from_case
makes the scene of a case) or of the engine.

A Scene is the hand-over point between case files / builders and the engine.  All arrays have
length N (blocks, in case order: explicit blocks first, then builder blocks).

| field            | shape  | unit   | meaning                                               |
|------------------|--------|--------|-------------------------------------------------------|
| size             | [N,3]  | m      | full edge lengths along the block's own axes           |
| position         | [N,3]  | m      | centre, table frame                                   |
| quat             | [N,4]  | -      | orientation, unit quaternion (w, x, y, z), body->table |
| mass             | [N]    | kg     |                                                       |
| fixed            | [N]    | bool   | support boxes that never move                          |
| velocity         | [N,3]  | m/s    | initial                                               |
| angular_velocity | [N,3]  | rad/s  | initial, table frame                                  |
| group            | [N]    | int    | index into ``group_names``                             |
| course           | [N]    | int    | course (row) index, -1 where it does not apply         |
| face_offset      | [N,6,4]| m      | imperfect faces: offset of each face's corners along   |
|                  |        |        | its outward normal (> 0 stands out); zero: flat faces  |
| arris            | [N]    | m      | radius of the rounded edges (contact patches inset)    |
| material         | [N]    | int    | index into ``material_names`` (default 0, "brick"):    |
|                  |        |        | the joint properties per pair of materials             |
|                  |        |        | (dem.engine.pair, the case's ``material.pairs``)       |

Faces and corners (``face_offset[b, f, c]``, dem.imperfections, docs/imperfections.md): face
f = 2 k + (0 for the +e_k face, 1 for the -e_k face) of the block's own axis k; corner
c = (s1 > 0) + 2 (s2 > 0), with s1 the sign along axis (k + 1) % 3 and s2 along (k + 2) % 3.

``layout``: what a builder knows about the geometry it laid, by group name (a wall: its bond's
stagger, course height, length and height, m), so that the analysis reads it instead of
re-deriving it from the case; empty for explicit blocks.
"""

from __future__ import annotations

from dataclasses import dataclass, field

import numpy as np

from dem import quaternion

DEFAULT_MATERIAL = "brick"  # the material of a block that names none


@dataclass
class Scene:
    size: np.ndarray
    position: np.ndarray
    quat: np.ndarray
    mass: np.ndarray
    fixed: np.ndarray
    velocity: np.ndarray
    angular_velocity: np.ndarray
    group: np.ndarray
    course: np.ndarray
    group_names: list[str] = field(default_factory=lambda: ["blocks"])
    layout: dict[str, dict] = field(default_factory=dict)
    face_offset: np.ndarray | None = None
    arris: np.ndarray | None = None
    material: np.ndarray | None = None
    material_names: list[str] = field(default_factory=lambda: [DEFAULT_MATERIAL])

    def __post_init__(self) -> None:
        n = len(self.size)
        self.material = np.zeros(n, dtype=np.int32) if self.material is None else \
            np.asarray(self.material, dtype=np.int32).reshape(n)
        self.face_offset = np.zeros((n, 6, 4)) if self.face_offset is None else \
            np.asarray(self.face_offset, dtype=np.float64).reshape(n, 6, 4)
        self.arris = np.zeros(n) if self.arris is None else \
            np.asarray(self.arris, dtype=np.float64).reshape(n)
        for name in ("position", "velocity", "angular_velocity"):
            arr = np.asarray(getattr(self, name), dtype=np.float64).reshape(n, 3)
            setattr(self, name, arr)
        self.size = np.asarray(self.size, dtype=np.float64).reshape(n, 3)
        self.quat = np.asarray(self.quat, dtype=np.float64).reshape(n, 4)
        self.quat /= np.linalg.norm(self.quat, axis=1, keepdims=True)
        self.mass = np.asarray(self.mass, dtype=np.float64).reshape(n)
        self.fixed = np.asarray(self.fixed, dtype=bool).reshape(n)
        self.group = np.asarray(self.group, dtype=np.int32).reshape(n)
        self.course = np.asarray(self.course, dtype=np.int32).reshape(n)
        bad = np.flatnonzero(~(self.size > 0).all(axis=1))
        if bad.size:
            raise ValueError(f"block {bad[0]}: every edge length must be > 0, got {self.size[bad[0]]}")
        bad = np.flatnonzero(~(self.mass > 0) & ~self.fixed)
        if bad.size:
            raise ValueError(f"block {bad[0]}: mass must be > 0, got {self.mass[bad[0]]}")

    def copy(self) -> "Scene":
        """A deep copy: every array and list copied, nothing shared with this scene."""
        return Scene(size=self.size.copy(), position=self.position.copy(), quat=self.quat.copy(),
                     mass=self.mass.copy(), fixed=self.fixed.copy(),
                     velocity=self.velocity.copy(), angular_velocity=self.angular_velocity.copy(),
                     group=self.group.copy(), course=self.course.copy(),
                     group_names=list(self.group_names), layout=dict(self.layout),
                     face_offset=self.face_offset.copy(), arris=self.arris.copy(),
                     material=self.material.copy(), material_names=list(self.material_names))

    @property
    def n_blocks(self) -> int:
        return len(self.size)

    def inertia(self) -> np.ndarray:
        """Principal moments of inertia of solid boxes [N,3], kg m^2: m (b^2 + c^2) / 12."""
        s2 = self.size**2
        return self.mass[:, None] / 12.0 * np.stack(
            [s2[:, 1] + s2[:, 2], s2[:, 0] + s2[:, 2], s2[:, 0] + s2[:, 1]], axis=1
        )

    def rotation_matrices(self) -> np.ndarray:
        """Body-to-table rotation matrices [N,3,3]."""
        return quaternion.matrices(self.quat)

    def bounding_box(self) -> tuple[np.ndarray, np.ndarray]:
        """Axis-aligned bounds (lo, hi) of all blocks, m."""
        corners = np.array([[sx, sy, sz] for sx in (-1, 1) for sy in (-1, 1) for sz in (-1, 1)])
        r = self.rotation_matrices()
        pts = self.position[:, None, :] + np.einsum(
            "nij,nkj->nki", r, corners[None, :, :] * 0.5 * self.size[:, None, :]
        )
        return pts.reshape(-1, 3).min(axis=0), pts.reshape(-1, 3).max(axis=0)

    @staticmethod
    def concatenate(scenes: list["Scene"]) -> "Scene":
        names: list[str] = []
        groups = []
        mat_names: list[str] = []
        mats = []
        for s in scenes:
            remap = []
            for g in s.group_names:
                if g not in names:
                    names.append(g)
                remap.append(names.index(g))
            groups.append(np.asarray(remap, dtype=np.int32)[s.group])
            remap = []
            for g in s.material_names:
                if g not in mat_names:
                    mat_names.append(g)
                remap.append(mat_names.index(g))
            mats.append(np.asarray(remap, dtype=np.int32)[s.material])
        cat = lambda attr: np.concatenate([getattr(s, attr) for s in scenes])  # noqa: E731
        return Scene(
            size=cat("size"), position=cat("position"), quat=cat("quat"), mass=cat("mass"),
            fixed=cat("fixed"), velocity=cat("velocity"), angular_velocity=cat("angular_velocity"),
            group=np.concatenate(groups), course=cat("course"), group_names=names,
            layout={k: v for s in scenes for k, v in s.layout.items()},
            face_offset=cat("face_offset"), arris=cat("arris"),
            material=np.concatenate(mats), material_names=mat_names,
        )

    def set_materials(self, by_group: dict[str, str]) -> None:
        """Give the blocks of the named groups the named materials (``{group: material}``; the
        other blocks keep theirs).  Raises ValueError for a group the scene does not have."""
        for group, mat in by_group.items():
            if group not in self.group_names:
                raise ValueError(f"no group {group!r} in the scene (groups: "
                                 f"{', '.join(self.group_names)})")
            if mat not in self.material_names:
                self.material_names.append(mat)
            self.material[self.group == self.group_names.index(group)] = \
                self.material_names.index(mat)

    @property
    def imperfect(self) -> np.ndarray:
        """[N] bool: blocks with a face offset or an arris."""
        return (self.face_offset != 0).any(axis=(1, 2)) | (self.arris != 0)


def scene_to_blocks(scene: Scene, groups: bool = True) -> list[dict]:
    """The blocks of a scene as a case's explicit blocks (``scene: blocks:`` entries, m, kg,
    intrinsic XYZ Euler angles in degrees), in scene order: the inverse of
    :func:`blocks_to_scene` (``groups``: keep each block's group; ``fixed`` where it is)."""
    eul = quaternion.rotation(scene.quat).as_euler("XYZ", degrees=True)
    out = []
    for i in range(scene.n_blocks):
        b = {"size": scene.size[i].tolist(), "position": scene.position[i].tolist(),
             "rotation": eul[i].tolist(), "mass": float(scene.mass[i])}
        if groups:
            b["group"] = scene.group_names[scene.group[i]]
        if scene.fixed[i]:
            b["fixed"] = True
        if scene.material_names[scene.material[i]] != DEFAULT_MATERIAL:
            b["material"] = scene.material_names[scene.material[i]]
        out.append(b)
    return out


def blocks_to_scene(blocks) -> Scene:
    """Scene from a list of :class:`dem.case.BlockSpec`."""
    names: list[str] = []
    for b in blocks:
        if b.group not in names:
            names.append(b.group)
    materials: list[str] = []
    for b in blocks:
        if getattr(b, "material", DEFAULT_MATERIAL) not in materials:
            materials.append(getattr(b, "material", DEFAULT_MATERIAL))
    return Scene(
        size=np.array([b.size for b in blocks], dtype=np.float64),
        position=np.array([b.position for b in blocks], dtype=np.float64),
        quat=quaternion.from_euler_xyz([b.rotation for b in blocks]),
        mass=np.array([b.block_mass() for b in blocks]),
        fixed=np.array([b.fixed for b in blocks]),
        velocity=np.array([b.velocity for b in blocks], dtype=np.float64),
        angular_velocity=np.array([b.angular_velocity for b in blocks], dtype=np.float64),
        group=np.array([names.index(b.group) for b in blocks]),
        course=np.full(len(blocks), -1),
        group_names=names,
        material=np.array([materials.index(getattr(b, "material", DEFAULT_MATERIAL))
                           for b in blocks]),
        material_names=materials,
    )
