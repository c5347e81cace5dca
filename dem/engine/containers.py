"""The three containers of a simulation, one writer each (MuJoCo mjModel/mjData, Warp Model/State).

All arrays are numpy arrays passed to the kernels as ``ti.types.ndarray`` arguments: on the CPU
Taichi uses them in place (zero copy), kernels compile once for every scene size, and the host
reads them without the ~0.3 ms copy a Taichi ndarray costs.  Element shapes: vec3 -> [..., 3],
vec4 -> [..., 4], mat3 -> [..., 3, 3]; ``dtype`` f64 unless noted.  Bodies are the N
blocks of the scene in case order, followed by the table (index N), a large fixed box whose top
face is the plane z = 0.

Model (static; written once by :meth:`Model.from_scene`)
| field        | shape        | dtype | unit    | meaning                                           |
|--------------|--------------|-------|---------|---------------------------------------------------|
| half         | [B] vec3     | f64   | m       | half extents along the body axes                  |
| mass         | [B]          | f64   | kg      | (table and fixed boxes: their nominal mass)        |
| inv_mass     | [B]          | f64   | 1/kg    | 0 for fixed bodies                                |
| inertia      | [B] vec3     | f64   | kg m^2  | principal moments (body axes)                     |
| inv_inertia  | [B] vec3     | f64   | 1/(kg m^2) | 0 for fixed bodies                             |
| radius       | [B]          | f64   | m       | bounding-sphere radius |half|                      |
| material     | [B]          | i32   | -       | 0 blocks, 1 table                                  |
| mat_pair     | [M, M] vec4  | f64   | -, Pa/m, Pa/m, - | (mu, kn, ks, damping ratio) per material pair |

State (dynamic; written by the integrate stage, and by :meth:`State.from_scene` at t = 0)
| field    | shape     | unit     | meaning                                                  |
|----------|-----------|----------|----------------------------------------------------------|
| pos      | [B] vec3  | m        | centre, table frame                                      |
| quat     | [B] vec4  | -        | orientation (w, x, y, z), body -> table                  |
| vel      | [B] vec3  | m/s      | velocity relative to the table                           |
| angmom   | [B] vec3  | kg m^2/s | angular momentum about the centre, table frame           |
| omega    | [B] vec3  | rad/s    | angular velocity, table frame (derived from quat, angmom) |
| rot      | [B] mat3  | -        | rotation matrix of quat (derived)                        |
| force    | [B] vec3  | N        | total force of the last step (diagnostic)                |
| torque   | [B] vec3  | N m      | total torque about the centre of the last step           |

Contacts (history and neighbour list)
| field    | shape          | unit | writer      | meaning                                       |
|----------|----------------|------|-------------|-----------------------------------------------|
| pairs    | [P] ivec2      | -    | broad phase | body indices (i, j), i < j                    |
| adj_ptr  | [B+1]          | -    | broad phase | CSR: pairs of body b are adj[adj_ptr[b]:adj_ptr[b+1]] |
| adj      | [2P]           | -    | broad phase | 2 * pair + side (side 0: b is i, 1: b is j)  |
| ref_pos  | [B] vec3       | m    | broad phase | poses at the last rebuild (skin criterion)    |
| ref_quat | [B] vec4       | -    | broad phase |                                               |
| code     | [P]            | -    | narrow phase| sticky contact axis (see geometry.py), -1 none |
| npts     | [P]            | -    | narrow phase| contact points of the pair this step          |
| normal   | [P] vec3       | -    | narrow phase| unit normal from i to j                       |
| loc      | [P, K] vec3    | m    | contact law | point position in body i's frame (history key)|
| shear    | [P, K] vec3    | m    | contact law | elastic shear displacement (history)          |
| point    | [P, K] vec3    | m    | contact law | point position, table frame                   |
| depth    | [P, K]         | m    | contact law | penetration                                   |
| area     | [P, K]         | m^2  | contact law | tributary area (weight)                        |
| fn       | [P, K]         | N    | contact law | normal force on j                             |
| ft       | [P, K] vec3    | N    | contact law | shear force on j                              |
| wrench   | [P, 3] vec3    | N, N m | contact law | force on i, torque on i, torque on j (force on j = -force on i) |
"""

from __future__ import annotations

import numpy as np
import taichi as ti

from dem.engine.geometry import MAXP
from dem.ti_runtime import real_dtype
from dem.scene import Scene

vec3 = ti.math.vec3
vec4 = ti.math.vec4
mat3 = ti.math.mat3
ivec2 = ti.math.ivec2

MAT_BLOCK, MAT_TABLE = 0, 1


REAL = "real"  # the engine's floating type: f64, or f32 with solver.precision = "f32"
_ELEM = {vec3: ((3,), REAL), vec4: ((4,), REAL), mat3: ((3, 3), REAL), ivec2: ((2,), np.int32),
         REAL: ((), REAL), ti.i32: ((), np.int32)}


def _nd(dtype, shape) -> np.ndarray:
    """A zeroed numpy array laid out as the Taichi ndarray type ``dtype`` of ``shape``."""
    elem, npdt = _ELEM[dtype]
    if npdt == REAL:
        npdt = real_dtype()
    return np.zeros(tuple(np.atleast_1d(shape)) + elem, dtype=npdt)


class Model:
    """Static description of the bodies and their contact materials."""

    def __init__(self, half, mass, inertia, fixed, material, mat_pair, n_blocks):
        self.n_blocks = int(n_blocks)
        self.n_bodies = len(half)
        self.table = self.n_blocks
        self.half_np = np.ascontiguousarray(half, dtype=np.float64)
        self.mass_np = np.ascontiguousarray(mass, dtype=np.float64)
        self.inertia_np = np.ascontiguousarray(inertia, dtype=np.float64)
        self.fixed_np = np.asarray(fixed, dtype=bool)
        self.mat_pair_np = np.ascontiguousarray(mat_pair, dtype=np.float64)
        self.material_np = np.asarray(material, dtype=np.int32)
        self.radius_np = np.linalg.norm(self.half_np, axis=1)
        inv_mass = np.where(self.fixed_np, 0.0, 1.0 / self.mass_np)
        inv_inertia = np.where(self.fixed_np[:, None], 0.0, 1.0 / self.inertia_np)

        # kernel arrays in the engine's real type (the *_np float64 copies serve the host)
        real = real_dtype()
        as_real = lambda a: np.ascontiguousarray(a, dtype=real)  # noqa: E731
        self.half = as_real(self.half_np)
        self.mass = as_real(self.mass_np)
        self.inv_mass = as_real(inv_mass)
        self.inertia = as_real(self.inertia_np)
        self.inv_inertia = as_real(inv_inertia)
        self.radius = as_real(self.radius_np)
        self.material = self.material_np
        self.mat_pair = as_real(self.mat_pair_np)

    @classmethod
    def from_scene(cls, scene: Scene, material) -> "Model":
        """Bodies = scene blocks + the table (a fixed box whose top face is z = 0)."""
        lo, hi = scene.bounding_box()
        centre = 0.5 * (lo + hi)
        extent = float(max(hi[0] - lo[0], hi[1] - lo[1], 1.0))
        table_half = np.array([10.0 * extent, 10.0 * extent, 0.5 * extent])
        half = np.vstack([0.5 * scene.size, table_half])
        table_mass = 1.0e6
        mass = np.append(scene.mass, table_mass)
        inertia_blocks = scene.inertia()
        s2 = (2 * table_half) ** 2
        table_inertia = table_mass / 12 * np.array([s2[1] + s2[2], s2[0] + s2[2], s2[0] + s2[1]])
        inertia = np.vstack([inertia_blocks, table_inertia])
        fixed = np.append(scene.fixed, True)
        mat = np.append(np.full(scene.n_blocks, MAT_BLOCK), MAT_TABLE)
        kn, ks, zeta = material.normal_stiffness, material.ks, material.damping
        mat_pair = np.zeros((2, 2, 4))
        mat_pair[MAT_BLOCK, MAT_BLOCK] = (material.friction, kn, ks, zeta)
        mat_pair[MAT_BLOCK, MAT_TABLE] = mat_pair[MAT_TABLE, MAT_BLOCK] = (
            material.mu_base, kn, ks, zeta)
        mat_pair[MAT_TABLE, MAT_TABLE] = (0.0, kn, ks, zeta)
        model = cls(half, mass, inertia, fixed, mat, mat_pair, scene.n_blocks)
        model.table_centre = np.array([centre[0], centre[1], -table_half[2]])
        return model


class State:
    """Pose and velocity of every body."""

    def __init__(self, n_bodies: int):
        B = n_bodies
        self.pos = _nd(vec3, B)
        self.quat = _nd(vec4, B)
        self.vel = _nd(vec3, B)
        self.angmom = _nd(vec3, B)
        self.omega = _nd(vec3, B)
        self.rot = _nd(mat3, B)
        self.force = _nd(vec3, B)
        self.torque = _nd(vec3, B)

    @classmethod
    def from_scene(cls, scene: Scene, model: Model) -> "State":
        st = cls(model.n_bodies)
        pos = np.vstack([scene.position, model.table_centre])
        quat = np.vstack([scene.quat, [1.0, 0.0, 0.0, 0.0]])
        vel = np.vstack([scene.velocity, np.zeros(3)])
        omega = np.vstack([scene.angular_velocity, np.zeros(3)])
        vel[model.fixed_np] = 0.0
        omega[model.fixed_np] = 0.0
        rot = np.vstack([scene.rotation_matrices(), np.eye(3)[None]])
        # L = R I R^T omega
        inertia = model.inertia_np
        angmom = np.einsum("nij,nj->ni", rot, inertia * np.einsum("nji,nj->ni", rot, omega))
        st.pos[...] = pos
        st.quat[...] = quat
        st.vel[...] = vel
        st.angmom[...] = angmom
        st.omega[...] = omega
        st.rot[...] = rot
        return st

    def snapshot(self) -> dict[str, np.ndarray]:
        """Copies of the pose and velocity arrays (numpy)."""
        return {name: getattr(self, name).copy()
                for name in ("pos", "quat", "vel", "omega", "angmom")}


class Contacts:
    """Neighbour list, contact points and their shear history."""

    def __init__(self, n_bodies: int, capacity: int):
        P, B, K = int(capacity), int(n_bodies), MAXP
        self.capacity = P
        self.n_pairs = 0
        self.pairs = _nd(ivec2, P)
        self.adj_ptr = _nd(ti.i32, B + 1)
        self.adj = _nd(ti.i32, 2 * P)
        self.ref_pos = _nd(vec3, B)
        self.ref_quat = _nd(vec4, B)
        self.code = _nd(ti.i32, P)
        self.npts = _nd(ti.i32, P)
        self.normal = _nd(vec3, P)
        self.loc = _nd(vec3, (P, K))
        self.shear = _nd(vec3, (P, K))
        self.point = _nd(vec3, (P, K))
        self.depth = _nd(REAL, (P, K))
        self.area = _nd(REAL, (P, K))
        self.fn = _nd(REAL, (P, K))
        self.ft = _nd(vec3, (P, K))
        self.wrench = _nd(vec3, (P, 3))
        self.code[...] = np.full(P, -1, dtype=np.int32)

    # -- history transfer across neighbour-list rebuilds ------------------------------------
    HISTORY = ("code", "npts", "loc", "shear")

    def read_history(self) -> dict[str, np.ndarray]:
        return {name: getattr(self, name).copy() for name in self.HISTORY}

    def write_pairs(self, pairs: np.ndarray, n_bodies: int, history_from: dict | None,
                    old_pairs: np.ndarray | None) -> None:
        """Install a new pair list (sorted (i, j), i < j) and carry the history of kept pairs."""
        P = self.capacity
        n = len(pairs)
        pad = np.zeros((P, 2), dtype=np.int32)
        pad[:n] = pairs
        self.pairs[...] = pad
        # CSR adjacency, deterministic order (pair index ascending)
        ends = np.concatenate([pairs[:, 0], pairs[:, 1]])
        entry = np.concatenate([2 * np.arange(n), 2 * np.arange(n) + 1]).astype(np.int32)
        order = np.lexsort((entry, ends))
        counts = np.bincount(ends, minlength=n_bodies)
        ptr = np.zeros(n_bodies + 1, dtype=np.int32)
        ptr[1:] = np.cumsum(counts)
        adj = np.zeros(2 * P, dtype=np.int32)
        adj[: 2 * n] = entry[order]
        self.adj_ptr[...] = ptr
        self.adj[...] = adj
        # history: index of each new pair in the old list, or -1
        new = {name: np.zeros_like(arr) for name, arr in (history_from or {}).items()}
        if history_from is not None and old_pairs is not None and len(old_pairs):
            key_old = old_pairs[:, 0].astype(np.int64) * n_bodies + old_pairs[:, 1]
            key_new = pairs[:, 0].astype(np.int64) * n_bodies + pairs[:, 1]
            srt = np.argsort(key_old)
            pos = np.searchsorted(key_old[srt], key_new)
            pos = np.minimum(pos, len(key_old) - 1)
            found = key_old[srt][pos] == key_new
            src = srt[pos[found]]
            dst = np.flatnonzero(found)
            new["code"][:] = -1
            for name in self.HISTORY:
                new[name][dst] = history_from[name][src]
            for name in self.HISTORY:
                getattr(self, name)[...] = new[name]
        else:
            self.code[...] = np.full(P, -1, dtype=np.int32)
            self.npts[...] = np.zeros(P, dtype=np.int32)
        self.n_pairs = n

    def max_depth(self) -> float:
        """Deepest penetration among the current contact points (m)."""
        n = self.n_pairs
        if n == 0:
            return 0.0
        mask = np.arange(MAXP)[None, :] < self.npts[:n, None]
        return float(self.depth[:n][mask].max(initial=0.0))

    def active_points(self) -> dict[str, np.ndarray]:
        """All current contact points (table frame): point, normal, fn, ft, area, depth, pair."""
        n = self.n_pairs
        npts = self.npts[:n]
        mask = np.arange(MAXP)[None, :] < npts[:, None]
        normal = np.repeat(self.normal[:n, None, :], MAXP, axis=1)
        pairs = np.repeat(self.pairs[:n, None, :], MAXP, axis=1)
        return {
            "point": self.point[:n][mask],
            "normal": normal[mask],
            "fn": self.fn[:n][mask],
            "ft": self.ft[:n][mask],
            "area": self.area[:n][mask],
            "depth": self.depth[:n][mask],
            "pair": pairs[mask],
        }
