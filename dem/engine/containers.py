"""The four containers of a simulation, one writer each (MuJoCo mjModel/mjData, Newton's Model /
State / Control / Contacts).

Each container is a table of named fields (``FIELDS`` below: one line per field with its element
type, shape, unit, writer and meaning; the table is the documentation, the allocation and the
kernel signature at once: adding a field is one line here).  The fields are numpy arrays: on the
CPU Taichi uses them in place (zero copy), so the host reads them without a copy, and kernels
compile once for every scene size (the offline cache keeps working).  They are passed to the
kernels as one Taichi argpack per container (``container.args``), so a kernel takes
``(model, state, contacts, control)`` and a stage reads ``state.pos[b]``.

Taichi 1.7.4 takes a local variable at kernel level (not inside a ti.func) named like an
argpack member for that kernel argument ("Kernel argument 'area' is immutable"): name kernel
locals differently from the fields below.

Taichi 1.7.4 limits a kernel's arguments ("The number of elements in kernel arguments is too
big! Do not exceed 64 on x64 backend"): the kernels take the 55 arrays below and 3 scalars
(56 before the six energy sums became one energy_sums row and the scenes added four fields);
58 arrays failed (patch reuse first wanted four Contacts fields, now two).  Pack a new field
into an existing one (a wider vec or another row) when near the limit.

Arrays are allocated once and only ever written in place (``a[...] = ...``): the argpacks and
the cached launch contexts of :mod:`dem.engine.launch` hold their addresses.

Element types: real (the engine's floating type: f64, or f32 with solver.precision = "f32"),
vec3 [..., 3], vec4 [..., 4], mat3 [..., 3, 3], i32, ivec2 [..., 2], pair [..., 7] (the pair
material record, dem.engine.pair).  Shapes: B bodies (the N
blocks of the scene in case order, then the table, index N: a large fixed box whose top face is
the plane z = 0), P pair capacity, K = MAXP points per pair, S = steps per serial launch, G the
scenes of the engine (1 for a lone simulation).

Several scenes in one engine (an ensemble's realisations side by side): the bodies of
scene g are the contiguous rows ``model.scene_bodies[g]`` = [b0, b1) (its blocks, then its table,
the last), and its pairs the slots [g P, g P + n_g) of the Contacts arrays (P the capacity of one
scene, n_g = contacts.scene_pairs[g]), which hold body indices *within the scene* (0 .. b1-b0-1)
and adjacency entries within the scene's slots, exactly as a lone simulation of that scene holds
them: the arrays of scene g are slices of the engine's (``Contacts.region``, ``State.region``),
and a kernel adds the scene's offsets (dem.engine.step.pair_bodies).  With G = 1 the offsets are 0
and the slices are the whole arrays.
"""

from __future__ import annotations

from dataclasses import dataclass, replace

import numpy as np
import taichi as ti

from dem.engine.geometry import MAXP
from dem.engine.pair import DAMPING_LAWS, LAWS, N_PAIR_FIELDS, PairMaterial
from dem.scene import Scene
from dem.ti_runtime import real_dtype

MAT_BLOCK, MAT_TABLE = 0, 1
SERIAL_CHUNK = 2000  # steps per launch of the serial kernel (S)
PROBES_PER_SCENE = 16  # bodies a scene may have probed (control.probe_body: J), on the host
PROBE_SLOTS = 16       # probed steps of one scene in one launch (control.probe_buf: Q)
PROBE_WIDTH = 13       # a probed body's row: pos (3), quat (4), vel (3), omega (3)

# status bits (control.status)
REBUILD = 1      # a body moved more than half the skin: rebuild the neighbour list
NONFINITE = 2    # a body's state became NaN or inf
RUNAWAY = 4      # a body moved faster than max_speed
STOP = NONFINITE | RUNAWAY


@dataclass(frozen=True)
class FieldDef:
    name: str
    elem: str        # real, vec3, vec4, mat3, i32, ivec2
    dims: tuple      # symbolic: "B", "P", "K", "S", "G", "Q", "J", or an int
    unit: str
    writer: str
    meaning: str


def _f(name, elem, dims, unit, writer, meaning):
    return FieldDef(name, elem, tuple(dims), unit, writer, meaning)


MODEL_FIELDS = (
    _f("half", "vec3", "B", "m", "Model.from_scene", "half extents along the body axes"),
    _f("mass", "real", "B", "kg", "Model.from_scene", "mass (table: a nominal 1e6)"),
    _f("inv_mass", "real", "B", "1/kg", "Model.from_scene", "0 for fixed bodies"),
    _f("inertia", "vec3", "B", "kg m^2", "Model.from_scene", "principal moments (body axes)"),
    _f("inv_inertia", "vec3", "B", "1/(kg m^2)", "Model.from_scene", "0 for fixed bodies"),
    _f("radius", "real", "B", "m", "Model.from_scene", "bounding-sphere radius |half|"),
    _f("material", "i32", "B", "-", "Model.from_scene",
       "index into the material names (the scene's, then the table's; default 0 blocks, 1 table)"),
    _f("mat_pair", "pair", ("M", "M"), "-, Pa/m, Pa/m, -, -, m, m, -, s", "Model.from_scene",
       "the pair material record per pair of materials (dem.engine.pair.PAIR_FIELDS: mu, kn, ks, "
       "zeta, law, d_max, d_lim, damping, beta), read by name through pair.pair_material"),
    _f("face_offset", "vec4", ("B", 6), "m", "Model.from_scene",
       "imperfect faces: corner offsets along the outward normal (dem.scene, face_contact)"),
    _f("arris", "real", "B", "m", "Model.from_scene", "rounded-edge radius: patches inset by it"),
    _f("recess", "real", "B", "m", "Model.from_scene",
       "deepest corner recess of the faces plus the arris: how far a neighbour may sink into "
       "the nominal box (the edge-axis margin of box_contact)"),
    _f("imperfect", "i32", "B", "-", "Model.from_scene",
       "1 if the body has a face offset or an arris (the narrow phase's imperfect path)"),
    _f("scene", "i32", "B", "-", "Model.concat", "the scene of the body (0 for a lone scene)"),
    _f("scene_bodies", "ivec2", "G", "-", "Model.concat",
       "first body and one past the last body of scene g (its table is the last)"),
)

STATE_FIELDS = (
    _f("pos", "vec3", "B", "m", "integrate_stage", "centre, table frame"),
    _f("quat", "vec4", "B", "-", "integrate_stage", "orientation (w, x, y, z), body -> table"),
    _f("vel", "vec3", "B", "m/s", "integrate_stage", "velocity relative to the table"),
    _f("angmom", "vec3", "B", "kg m^2/s", "integrate_stage",
       "angular momentum about the centre, table frame"),
    _f("omega", "vec3", "B", "rad/s", "integrate_stage",
       "angular velocity, table frame (derived from quat, angmom)"),
    _f("rot", "mat3", "B", "-", "integrate_stage", "rotation matrix of quat (derived)"),
    _f("force", "vec3", "B", "N", "integrate_stage", "total force of the last step (diagnostic)"),
    _f("torque", "vec3", "B", "N m", "integrate_stage",
       "total torque about the centre of the last step (diagnostic)"),
    _f("work", "vec3", "B", "J", "integrate_stage",
       "last step's work of gravity, work of the base, local-damping dissipation"),
)

CONTACT_FIELDS = (
    _f("pairs", "ivec2", "P", "-", "broad phase",
       "body indices (i, j), i < j, within the pair's scene (b - scene_bodies[g][0])"),
    _f("adj_ptr", "i32", ("B+G",), "-", "broad phase",
       "CSR per scene, from row b0 + g: pairs of the scene's body k are adj[adj_ptr[b0+g+k] : "
       "adj_ptr[b0+g+k+1]] of its region"),
    _f("adj", "i32", ("2P",), "-", "broad phase",
       "2 * pair + side (side 0: b is i, 1: b is j), pair counted within the scene's slots"),
    _f("scene_pairs", "i32", "G", "-", "broad phase",
       "pairs of scene g (slots g P ... g P + n; Contacts.n_pairs of its region)"),
    _f("ref_pos", "vec3", "B", "m", "broad phase", "poses at the last rebuild (skin criterion)"),
    _f("ref_quat", "vec4", "B", "-", "broad phase", "orientations at the last rebuild"),
    _f("code", "i32", "P", "-", "narrow phase", "sticky contact axis (geometry.py), -1 none"),
    _f("npts", "i32", "P", "-", "narrow phase", "contact points of the pair this step"),
    _f("normal", "vec3", "P", "-", "narrow phase", "unit normal from i to j"),
    _f("loc", "vec3", ("P", "K"), "m", "contact law", "point in body i's frame (history key)"),
    _f("shear", "vec3", ("P", "K"), "m", "contact law", "elastic shear displacement (history)"),
    _f("point", "vec3", ("P", "K"), "m", "contact law", "point position, table frame"),
    _f("depth", "real", ("P", "K"), "m", "contact law", "penetration"),
    _f("area", "real", ("P", "K"), "m^2", "contact law", "tributary area (weight)"),
    _f("fn", "real", ("P", "K"), "N", "contact law", "normal force on j"),
    _f("ft", "vec3", ("P", "K"), "N", "contact law", "shear force on j"),
    _f("wrench", "vec3", ("P", 3), "N, N m", "contact law",
       "force on i, torque on i, torque on j (force on j = -force on i)"),
    _f("patch_point", "vec3", ("P", "K"), "m, m, m^2", "narrow phase (coherence.store_patch)",
       "kept patch: quadrature point (x, y) in the reference face's coordinates, weight"),
    _f("patch_shape", "vec4", ("P", 3), "m, m, -, -; m", "narrow phase (coherence.store_patch)",
       "kept patch: [0] area centroid (x, y), shrink factor, number of points (0: nothing kept, "
       "the pair's patch is not reusable); [1], [2] the x's and y's of the incident face's "
       "corners projected on the reference face; warped kernels (coherence.keep_overlap): [0][0] "
       "the overlap reuse tolerance (m, 0 off), [0][3] minus the number of vertices of the kept "
       "overlap polygon (patch_point's x, y), [1], [2] the incident corners"),
    _f("dissipation", "vec3", "P", "J", "contact law",
       "last step's normal-damping, shear-damping and friction dissipation of the pair"),
)

# energy terms accumulated since t = 0 (J); the names are those of summary.json's "energy"
ENERGY_TERMS = ("work_gravity", "work_base", "dissipated_normal_damping",
                "dissipated_shear_damping", "dissipated_friction", "dissipated_local_damping")

# control.step_parameters' entries (one array, not three: Taichi 1.7.4 takes at most 64
# argument elements per kernel on x64, and the kernels take every container's fields)
STEP_PARAMETERS = ("skin", "max_speed", "patch_tolerance")
P_SKIN, P_MAX_SPEED, P_PATCH_TOLERANCE = range(len(STEP_PARAMETERS))

# Control, by role (the kernels take one argpack of the four tables in this order):
# what the host writes before each launch ...
CONTROL_LOADS = (
    _f("loads", "vec3", ("S", "G", 2), "m/s^2", "Launcher.launch",
       "per step of a launch and scene: (gravity, base acceleration), table frame"),
    _f("probe_slot", "i32", ("S", "G"), "-", "Launcher.launch",
       "per step of a launch and scene: the slot of probe_buf that takes the scene's probed "
       "bodies after the step, -1: none (Simulation.set_probe)"),
)
# ... the run's step parameters, set once (local_damping also by Simulation.set_local_damping) ...
CONTROL_PARAMETERS = (
    _f("step_parameters", "real", (len(STEP_PARAMETERS),), "m, m/s, m", "Control",
       "shared by every scene, in the order of STEP_PARAMETERS: the neighbour-list skin; the "
       "speed above which a body stops the run; the patch reuse's largest in-plane drift of a "
       "kept contact patch (dem.engine.coherence; 0 = off)"),
    _f("local_damping", "real", "G", "-", "Simulation", "Cundall local damping coefficient"),
    _f("probe_body", "i32", ("G", "J"), "-", "Simulation.set_probe",
       "per scene, the bodies (engine-wide index) copied to probe_buf at a probed step; -1 none"),
)
# ... what the kernels report back about the launch (diagnostics) ...
CONTROL_DIAGNOSTICS = (
    _f("status", "i32", "G", "-", "integrate_stage",
       "per scene, bits REBUILD | NONFINITE | RUNAWAY"),
    _f("bad_body", "i32", "G", "-", "integrate_stage",
       "per scene, a body (within the scene) that raised NONFINITE/RUNAWAY"),
    _f("steps_done", "i32", (2,), "-", "advance_serial, advance_parallel, integrate_stage",
       "[0] steps done by the last launch (the serial kernel) or chunk of launches (the "
       "parallel); [1] the status bits of every scene or-ed (one test per step, not G)"),
    _f("active", "i32", "G", "-", "Engine",
       "1: scene g steps; 0: frozen (its run finished or failed; its bodies and pairs are skipped)"),
    _f("deepest", "real", "G", "m", "deepest_stage",
       "per scene, deepest penetration of any contact point at any step since t = 0"),
    _f("deepest_step", "i32", "G", "-", "deepest_stage",
       "step of the last launch (0 = its first) at which deepest grew; -1 if it did not"),
    _f("probe_buf", "real", ("Q", "G", "J", PROBE_WIDTH), "m, -, m/s, rad/s",
       "probe_stage",
       "per slot, scene and probed body: pos, quat, vel, omega after the step probe_slot names"),
)
# ... and the energy sums since t = 0, one row per scene, one column per ENERGY_TERMS
CONTROL_ENERGY = (_f("energy_sums", "real", ("G", len(ENERGY_TERMS)), "J", "energy_stage",
                     "energy terms since t = 0, columns in the order of ENERGY_TERMS"),)
CONTROL_ROLES = {"loads": CONTROL_LOADS, "parameters": CONTROL_PARAMETERS,
                 "diagnostics": CONTROL_DIAGNOSTICS, "energy": CONTROL_ENERGY}
CONTROL_FIELDS = CONTROL_LOADS + CONTROL_PARAMETERS + CONTROL_DIAGNOSTICS + CONTROL_ENERGY

# the argpacks' element types, made at import (before ti.init) from explicit scalar types: a
# numpy argument brings its own scalar type (f64, or f32 with solver.precision f32), a device
# array (dem.engine.device) must match these: f64 (an engine on a device runs in f64 only)
_ELEM = {"real": (None, ()), "vec3": (ti.types.vector(3, ti.f64), (3,)),
         "vec4": (ti.types.vector(4, ti.f64), (4,)),
         "mat3": (ti.types.matrix(3, 3, ti.f64), (3, 3)), "i32": (ti.i32, ()),
         "ivec2": (ti.types.vector(2, ti.i32), (2,)),
         "pair": (ti.types.vector(N_PAIR_FIELDS, ti.f64), (N_PAIR_FIELDS,))}


def _argpack_type(fields):
    """The Taichi argpack of a field table: one ndarray member per field.  The element types
    only give the element shape here; the scalar type is the numpy array's (f64 or f32)."""
    members = {}
    for f in fields:
        dtype, _ = _ELEM[f.elem]
        ndim = len(f.dims)
        members[f.name] = (ti.types.ndarray(ndim=ndim) if dtype is None
                           else ti.types.ndarray(dtype=dtype, ndim=ndim))
    return ti.types.argpack(**members)


ModelArgs = _argpack_type(MODEL_FIELDS)
StateArgs = _argpack_type(STATE_FIELDS)
ContactArgs = _argpack_type(CONTACT_FIELDS)
ControlArgs = _argpack_type(CONTROL_FIELDS)


def _allocate(obj, fields, sizes: dict) -> None:
    for f in fields:
        shape = tuple(sizes[d] if isinstance(d, str) else d for d in f.dims)
        _, elem_shape = _ELEM[f.elem]
        npdt = real_dtype() if f.elem in ("real", "vec3", "vec4", "mat3", "pair") else np.int32
        setattr(obj, f.name, np.zeros(shape + elem_shape, dtype=npdt))


class _Container:
    FIELDS: tuple = ()
    ARGS = None

    @property
    def args(self):
        """The argpack handed to the kernels (built once: the arrays never move)."""
        if getattr(self, "_args", None) is None:
            self._args = self.ARGS(**{f.name: getattr(self, f.name) for f in self.FIELDS})
        return self._args

    def __getstate__(self):
        """Copies (copy.deepcopy, pickle) get their own argpack, built on first use."""
        state = dict(self.__dict__)
        state["_args"] = None
        return state

    def arrays(self) -> dict[str, np.ndarray]:
        return {f.name: getattr(self, f.name) for f in self.FIELDS}

    @classmethod
    def field_names(cls) -> tuple[str, ...]:
        """The names of the container's fields, in FIELDS order."""
        return tuple(f.name for f in cls.FIELDS)

    def nbytes(self) -> int:
        return sum(a.nbytes for a in self.arrays().values())


class Model(_Container):
    """Static description of the bodies and their contact materials."""

    FIELDS, ARGS = MODEL_FIELDS, ModelArgs

    def __init__(self, half, mass, inertia, fixed, material, mat_pair, n_blocks):
        self.n_blocks = int(n_blocks)
        self.n_bodies = len(half)
        self.table = self.n_blocks
        # float64 copies for the host (broad phase, time step, energy)
        self.half_np = np.ascontiguousarray(half, dtype=np.float64)
        self.mass_np = np.ascontiguousarray(mass, dtype=np.float64)
        self.inertia_np = np.ascontiguousarray(inertia, dtype=np.float64)
        self.fixed_np = np.asarray(fixed, dtype=bool)
        self.mat_pair_np = np.ascontiguousarray(mat_pair, dtype=np.float64)
        self.material_np = np.asarray(material, dtype=np.int32)
        self.radius_np = np.linalg.norm(self.half_np, axis=1)
        _allocate(self, MODEL_FIELDS, {"B": self.n_bodies, "M": len(self.mat_pair_np), "G": 1})
        self.scene_bodies[0] = (0, self.n_bodies)
        self.half[...] = self.half_np
        self.mass[...] = self.mass_np
        self.inv_mass[...] = np.where(self.fixed_np, 0.0, 1.0 / self.mass_np)
        self.inertia[...] = self.inertia_np
        self.inv_inertia[...] = np.where(self.fixed_np[:, None], 0.0, 1.0 / self.inertia_np)
        self.radius[...] = self.radius_np
        self.material[...] = self.material_np
        self.mat_pair[...] = self.mat_pair_np

    @classmethod
    def from_scene(cls, scene: Scene, joints) -> "Model":
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
        names = list(scene.material_names)
        if "table" not in names:
            names.append("table")
        table_mat = names.index("table")
        mat = np.append(scene.material, table_mat)
        mat_pair = pair_table(names, joints)
        model = cls(half, mass, inertia, fixed, mat, mat_pair, scene.n_blocks)
        model.face_offset[: scene.n_blocks] = scene.face_offset
        model.arris[: scene.n_blocks] = scene.arris
        model.imperfect[: scene.n_blocks] = scene.imperfect
        model.recess[: scene.n_blocks] = np.maximum(
            -scene.face_offset.min(axis=(1, 2), initial=0.0), 0.0) + scene.arris
        model.table_centre = np.array([centre[0], centre[1], -table_half[2]])
        model.material_names = names
        return model

    def pair_material(self, a: str | int, b: str | int) -> PairMaterial:
        """The record of materials a, b (names, or indices into ``material_names``)."""
        ia = self.material_names.index(a) if isinstance(a, str) else int(a)
        ib = self.material_names.index(b) if isinstance(b, str) else int(b)
        return PairMaterial.from_row(self.mat_pair_np[ia, ib])

    def stiffest(self) -> tuple[float, float, float]:
        """(kn, ks, zeta) bounding every pair of the materials in use, for the critical step:
        the largest normal stiffness a pair reaches within the closures the step is made for
        (PairMaterial.stable_stiffness), the largest ks and the largest damping ratio (the
        critical step shrinks as sqrt(1 + zeta^2) - zeta)."""
        recs = [self.pair_material(a, b) for a in range(len(self.material_names))
                for b in range(len(self.material_names))]
        return (max(r.stable_stiffness() for r in recs), max(r.ks for r in recs),
                max(r.zeta for r in recs))

    def largest_beta(self) -> float:
        """The largest damping time (s) of a pair's stiffness-proportional normal dashpot
        (PairMaterial.beta), 0 if no pair has one."""
        return max(self.pair_material(a, b).beta for a in range(len(self.material_names))
                   for b in range(len(self.material_names)))

    def pair_damping(self) -> bool:
        """Whether a pair's normal dashpots follow the pair's no-tension rule (PAIR or
        STIFFNESS: the kernels compiled with ``pair_damping``)."""
        return any(self.pair_material(a, b).damping != DAMPING_LAWS["critical"]
                   for a in range(len(self.material_names))
                   for b in range(len(self.material_names)))

    def closure_limit(self) -> float | None:
        """The smallest d_lim (m) of the hyperbolic pairs, None if every pair is linear."""
        lims = [r.d_lim for a in range(len(self.material_names))
                for b in range(len(self.material_names))
                if (r := self.pair_material(a, b)).law == LAWS["hyperbolic"]]
        return min(lims) if lims else None


    @classmethod
    def concat(cls, models: list["Model"]) -> "Model":
        """The model of an engine of several scenes: the bodies of ``models`` one scene after
        the other (each its blocks then its table), their material tables side by side (scene
        g's materials renumbered after those of the scenes before it: no pair between scenes),
        ``scene`` and ``scene_bodies`` set.  One model is returned as it is."""
        if len(models) == 1:
            return models[0]
        cat = lambda name: np.concatenate([getattr(m, name) for m in models])  # noqa: E731
        n_mat = [len(m.mat_pair_np) for m in models]
        mat_pair = np.zeros((sum(n_mat), sum(n_mat), N_PAIR_FIELDS))
        material = []
        off = 0
        for m, k in zip(models, n_mat):
            mat_pair[off:off + k, off:off + k] = m.mat_pair_np
            material.append(m.material_np + off)
            off += k
        out = cls.__new__(cls)
        out.n_blocks = sum(m.n_blocks for m in models)
        out.n_bodies = sum(m.n_bodies for m in models)
        out.table = None  # one table per scene: the last body of each scene_bodies range
        out.half_np, out.mass_np, out.inertia_np = cat("half_np"), cat("mass_np"), \
            cat("inertia_np")
        out.fixed_np, out.radius_np = cat("fixed_np"), cat("radius_np")
        out.mat_pair_np = mat_pair
        out.material_np = np.concatenate(material).astype(np.int32)
        _allocate(out, MODEL_FIELDS, {"B": out.n_bodies, "M": len(mat_pair), "G": len(models)})
        for f in MODEL_FIELDS:
            if f.name in ("material", "mat_pair", "scene", "scene_bodies"):
                continue
            getattr(out, f.name)[...] = cat(f.name)
        out.material[...] = out.material_np
        out.mat_pair[...] = mat_pair
        starts = np.cumsum([0] + [m.n_bodies for m in models])
        for g in range(len(models)):
            out.scene[starts[g]:starts[g + 1]] = g
            out.scene_bodies[g] = (starts[g], starts[g + 1])
        out.material_names = None  # per scene: the scenes' own models
        return out


def pair_table(names: list[str], joints) -> np.ndarray:
    """[M, M, N_PAIR_FIELDS] records for the materials ``names`` (the table among them) from a
    JointLaw: every pair gets the default (friction, kn, ks, damping, normal law), pairs with
    the table the base friction (table with table: mu = 0), then ``joints.pairs`` override
    field by field, in their order, for the pairs whose two materials are both in ``names``."""
    kn, ks, zeta = joints.normal_stiffness, joints.shear_stiffness, joints.damping
    law = LAWS[getattr(joints, "normal_law", "linear")]
    d_max = d_lim = 0.0
    if law == LAWS["hyperbolic"]:
        d_max = float(joints.max_closure)
        d_lim = float(joints.closure_limit) * d_max
    damping = DAMPING_LAWS[getattr(joints, "normal_damping", "critical")]
    beta = float(joints.damping_time) if damping == DAMPING_LAWS["stiffness"] else 0.0
    default = PairMaterial(joints.friction, kn, ks, zeta, law, d_max, d_lim, damping, beta)
    table = names.index("table")
    m = len(names)
    out = np.zeros((m, m, N_PAIR_FIELDS))
    for a in range(m):
        for b in range(m):
            mu = joints.friction
            if a == table and b == table:
                mu = 0.0
            elif a == table or b == table:
                mu = joints.base_friction
            out[a, b] = replace(default, mu=mu).row()
    for ov in getattr(joints, "pairs", ()):
        if ov.a not in names or ov.b not in names:
            continue
        a, b = names.index(ov.a), names.index(ov.b)
        rec = PairMaterial.from_row(out[a, b])
        changes = {"mu": ov.friction, "kn": ov.normal_stiffness, "ks": ov.shear_stiffness,
                   "zeta": ov.damping}
        rec = replace(rec, **{k: float(v) for k, v in changes.items() if v is not None})
        if ov.max_closure is not None and rec.law == LAWS["hyperbolic"]:
            rec = replace(rec, d_max=float(ov.max_closure),
                          d_lim=float(joints.closure_limit) * float(ov.max_closure))
        out[a, b] = out[b, a] = rec.row()
    return out


class State(_Container):
    """Pose and velocity of every body."""

    FIELDS, ARGS = STATE_FIELDS, StateArgs

    def __init__(self, n_bodies: int):
        _allocate(self, STATE_FIELDS, {"B": n_bodies})

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

    def region(self, b0: int, b1: int) -> "State":
        """The state of bodies [b0, b1) (one scene of an engine): views, written in place."""
        out = State.__new__(State)
        for f in STATE_FIELDS:
            setattr(out, f.name, getattr(self, f.name)[b0:b1])
        return out

    def snapshot(self) -> dict[str, np.ndarray]:
        """Copies of the pose and velocity arrays (numpy)."""
        return {name: getattr(self, name).copy()
                for name in ("pos", "quat", "vel", "omega", "angmom")}


class Control(_Container):
    """Step control, four roles (CONTROL_ROLES): the loads of the steps of a launch, the run's
    step parameters, the diagnostics the kernels report (status bits, steps done, deepest
    penetration) and the energy sums (J since t = 0).  Named fields, no slot numbers."""

    FIELDS, ARGS = CONTROL_FIELDS, ControlArgs

    # the fields every scene shares (the others have one row per scene)
    SHARED = ("step_parameters", "steps_done")

    def __init__(self, skin: float, max_speed: float, local_damping: float,
                 patch_tolerance: float = 0.0, n_scenes: int = 1, steps: int = SERIAL_CHUNK,
                 probe_slots: int = PROBE_SLOTS, probe_bodies: int = PROBES_PER_SCENE):
        """``steps``: S, the most steps of one launch (or chunk of launches); ``probe_slots``:
        Q, the most probed steps of a scene in one (Launcher.plan_probes); ``probe_bodies``: J,
        the most probed bodies of a scene (Simulation.set_probe)."""
        _allocate(self, CONTROL_FIELDS, {"S": int(steps), "G": int(n_scenes),
                                         "Q": int(probe_slots), "J": int(probe_bodies)})
        self.probe_slot[...] = -1
        self.probe_body[...] = -1
        self.step_parameters[[P_SKIN, P_MAX_SPEED, P_PATCH_TOLERANCE]] = \
            (skin, max_speed, patch_tolerance)
        self.local_damping[...] = local_damping
        self.active[...] = 1

    def region(self, g: int) -> "Control":
        """Scene g's rows (views, shaped as a lone simulation's: one scene), the shared fields
        as they are."""
        out = Control.__new__(Control)
        for f in CONTROL_FIELDS:
            a = getattr(self, f.name)
            if f.name in self.SHARED:
                setattr(out, f.name, a)
            elif f.name in ("loads", "probe_slot", "probe_buf"):  # per step or slot, then scene
                setattr(out, f.name, a[:, g:g + 1])
            else:
                setattr(out, f.name, a[g:g + 1])
        return out

    def energy(self) -> dict[str, float]:
        """The energy sums of scene 0 (a lone simulation's, or a region's), J since t = 0."""
        return {name: float(self.energy_sums[0, k]) for k, name in enumerate(ENERGY_TERMS)}

    def role(self, name: str) -> dict[str, np.ndarray]:
        """The arrays of one role of CONTROL_ROLES ("loads", "parameters", "diagnostics",
        "energy"), by field name (the arrays themselves, not copies)."""
        return {f.name: getattr(self, f.name) for f in CONTROL_ROLES[name]}


class Contacts(_Container):
    """Neighbour list, contact points and their shear history."""

    FIELDS, ARGS = CONTACT_FIELDS, ContactArgs

    def __init__(self, n_bodies: int, capacity: int, n_scenes: int = 1):
        """``capacity`` pairs for each of ``n_scenes`` scenes (their slots side by side)."""
        self.capacity = int(capacity)
        G = int(n_scenes)
        _allocate(self, CONTACT_FIELDS, {"P": G * self.capacity, "B": int(n_bodies), "K": MAXP,
                                         "B+G": int(n_bodies) + G, "2P": 2 * G * self.capacity,
                                         "G": G})
        self.code[...] = -1

    @property
    def n_pairs(self) -> int:
        """Pairs in the list (of this scene: a lone simulation's, or a region's)."""
        if len(self.scene_pairs) != 1:
            raise AttributeError("the contacts of several scenes: read scene_pairs[g], or the "
                                 "scene's region")
        return int(self.scene_pairs[0])

    @n_pairs.setter
    def n_pairs(self, n: int) -> None:
        if len(self.scene_pairs) != 1:
            raise AttributeError("the contacts of several scenes: set the scene's region")
        self.scene_pairs[0] = n

    def region(self, g: int, b0: int, b1: int) -> "Contacts":
        """Scene g's contacts (its slots, its bodies [b0, b1)): views, written in place, shaped
        and indexed as a lone simulation of that scene holds them."""
        out = Contacts.__new__(Contacts)
        out.capacity = self.capacity
        P = self.capacity
        for f in CONTACT_FIELDS:
            a = getattr(self, f.name)
            if f.dims[0] == "P":
                a = a[g * P:(g + 1) * P]
            elif f.name == "adj":
                a = a[2 * g * P:2 * (g + 1) * P]
            elif f.name == "adj_ptr":
                a = a[b0 + g:b1 + g + 1]
            elif f.dims[0] == "B":
                a = a[b0:b1]
            elif f.name == "scene_pairs":
                a = a[g:g + 1]
            setattr(out, f.name, a)
        return out

    # -- history transfer across neighbour-list rebuilds ------------------------------------
    HISTORY = ("code", "npts", "loc", "shear")

    def read_history(self) -> dict[str, np.ndarray]:
        return {name: getattr(self, name).copy() for name in self.HISTORY}

    def write_pairs(self, pairs: np.ndarray, n_bodies: int, history_from: dict | None,
                    old_pairs: np.ndarray | None) -> None:
        """Install a new pair list (sorted (i, j), i < j) and carry the history of kept pairs
        (the host's arrays; an engine on a device: dem.engine.device.install_pairs)."""
        lists = pair_lists(pairs, n_bodies, self.capacity,
                           old_pairs if history_from is not None else None)
        self.pairs[...] = lists.pairs
        self.adj_ptr[...] = lists.adj_ptr
        self.adj[...] = lists.adj
        if lists.src is not None:
            found = lists.src >= 0
            src, dst = lists.src[found], np.flatnonzero(found)
            new = {name: np.zeros_like(arr) for name, arr in history_from.items()}
            new["code"][:] = -1
            for name in self.HISTORY:
                new[name][dst] = history_from[name][src]
            for name in self.HISTORY:
                getattr(self, name)[...] = new[name]
        else:
            self.code[...] = -1
            self.npts[...] = 0
        # a kept patch belongs to a pair index of the old list: none is reused across a rebuild
        self.patch_shape[:, 0, 3] = 0.0
        self.n_pairs = lists.n

    def max_depth(self) -> float:
        """Deepest penetration among the current contact points (m)."""
        n = self.n_pairs
        if n == 0:
            return 0.0
        mask = np.arange(MAXP)[None, :] < self.npts[:n, None]
        return float(self.depth[:n][mask].max(initial=0.0))

    # the fields active_points reads (besides n_pairs)
    POINT_FIELDS = ("npts", "normal", "pairs", "point", "fn", "ft", "area", "depth")

    def active_points(self) -> dict[str, np.ndarray]:
        """All current contact points (table frame): point, normal, fn, ft, area, depth, pair.
        (Also called on a Simulation.read_contacts view of POINT_FIELDS.)"""
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


@dataclass(frozen=True)
class PairLists:
    """A scene's new neighbour list as its Contacts hold it: ``pairs`` [P, 2] (padded with
    zeros), ``adj_ptr`` [n_bodies + 1] and ``adj`` [2P] (CSR, deterministic order: pair index
    ascending), ``n`` pairs, and ``src`` [n]: each new pair's index in the old list, -1 for a
    new pair (None where there was no old list)."""

    pairs: np.ndarray
    adj_ptr: np.ndarray
    adj: np.ndarray
    n: int
    src: np.ndarray | None


def pair_lists(pairs: np.ndarray, n_bodies: int, capacity: int,
               old_pairs: np.ndarray | None) -> PairLists:
    """The index arrays of a new pair list (sorted (i, j), i < j) and where each pair's history
    comes from in ``old_pairs`` (pure: Contacts.write_pairs applies them to the host's arrays,
    dem.engine.device.install_pairs to a device's)."""
    P = int(capacity)
    n = len(pairs)
    pad = np.zeros((P, 2), dtype=np.int32)
    pad[:n] = pairs
    ends = np.concatenate([pairs[:, 0], pairs[:, 1]])
    entry = np.concatenate([2 * np.arange(n), 2 * np.arange(n) + 1]).astype(np.int32)
    order = np.lexsort((entry, ends))
    counts = np.bincount(ends, minlength=n_bodies)
    ptr = np.zeros(n_bodies + 1, dtype=np.int32)
    ptr[1:] = np.cumsum(counts)
    adj = np.zeros(2 * P, dtype=np.int32)
    adj[: 2 * n] = entry[order]
    src = None
    if old_pairs is not None and len(old_pairs):
        key_old = old_pairs[:, 0].astype(np.int64) * n_bodies + old_pairs[:, 1]
        key_new = pairs[:, 0].astype(np.int64) * n_bodies + pairs[:, 1]
        srt = np.argsort(key_old)
        pos = np.searchsorted(key_old[srt], key_new)
        pos = np.minimum(pos, len(key_old) - 1)
        found = key_old[srt][pos] == key_new
        src = np.where(found, srt[pos], -1).astype(np.int32)
    return PairLists(pad, ptr, adj, n, src)


def element_type(field: FieldDef):
    """(Taichi element type, element shape) of a field: the type of a device array (ti.ndarray)
    of it, in the engine's precision (call after dem.ti_runtime.init)."""
    real = ti.f32 if real_dtype() == np.float32 else ti.f64
    kinds = {"real": (real, ()), "vec3": (ti.types.vector(3, real), (3,)),
             "vec4": (ti.types.vector(4, real), (4,)),
             "mat3": (ti.types.matrix(3, 3, real), (3, 3)), "i32": (ti.i32, ()),
             "ivec2": (ti.types.vector(2, ti.i32), (2,)),
             "pair": (ti.types.vector(N_PAIR_FIELDS, real), (N_PAIR_FIELDS,))}
    return kinds[field.elem]
