"""Build phase: from a validated case to the scene, the loading and the engine.

The only place where the case schema meets the engine: ``joint_law`` and ``step_options`` copy
the ``material:`` and ``solver:`` sections into the engine's own option types
(dem.engine.options), so the engine never holds a pydantic object.  ``solver.overlap_reuse``
is applied to the built Simulation (:func:`build`, through dem.engine.coherence.set_overlap_reuse).
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from dem.builders import build_from_spec, check_scene, require_valid
from dem.builders.scatter import scatter_sizes
from dem.case import Case, Material, SolverSpec, TiltLoading
from dem.compliance import elastic_offset, rigid_stiffness
from dem.engine.options import JointLaw, PairLaw, StepOptions
from dem.imperfections import (ImperfectionParams, apply_as_built, apply_faces,
                               as_built_streams, streams)
from dem.loading import Loading, loading_from_case
from dem.scene import Scene, blocks_to_scene


def imperfection_params(case: Case) -> ImperfectionParams:
    """The case's ``imperfections:`` as plain numbers (dem.imperfections)."""
    imp = case.imperfections
    return ImperfectionParams(bed_unevenness=imp.bed_unevenness, face_shape=imp.face_shape,
                              size_scatter=tuple(imp.size_scatter), arris=imp.arris,
                              seed=imp.seed,
                              corner_gap=(imp.corner_gap.mean, imp.corner_gap.scatter),
                              head_gap=(imp.head_gap.mean, imp.head_gap.scatter),
                              plumb_sigma=tuple(imp.plumb.sigma),
                              plumb_lean=tuple(imp.plumb.lean))


def _builder_frame(spec) -> tuple[float, int, float]:
    """(course height m, yaw degrees, reach m) of a builder entry: what the as-built fields need
    (dem.imperfections.apply_as_built; the reach is the builder's min_piece)."""
    from dem.builders import brick
    from dem.builders.wall import default_min_piece

    b = brick(spec.brick)
    h = b.dims(getattr(spec, "laying", "flat"))[2]
    reach = default_min_piece(b) if spec.min_piece is None else float(spec.min_piece)
    return h, int(spec.yaw), reach


def build_parts(case: Case, imperfect: bool = True) -> tuple[Scene, list[dict]]:
    """The case's scene before the checks, and what the as-built fields drew per builder part
    (dem.imperfections.apply_as_built; empty where none is set): :func:`scene_from_case`."""
    params = imperfection_params(case) if imperfect else ImperfectionParams()
    rng_sizes, _ = streams(params.seed)
    scatter = any(s > 0 for s in params.size_scatter)
    as_built = params.as_built()
    rngs = as_built_streams(params.seed) if as_built else None
    parts, drawn = [], []
    if case.scene.blocks:
        parts.append(blocks_to_scene(case.scene.blocks))
    for spec in (case.scene.wall, case.scene.facade, case.scene.box_model):
        if spec is not None:
            built = build_from_spec(spec)
            if scatter:
                built = scatter_sizes(built, params.size_scatter, rng_sizes)
            if as_built:
                built, record = apply_as_built(built, params, rngs, *_builder_frame(spec))
                drawn.append(record)
            parts.append(built)
    scene = parts[0] if len(parts) == 1 else Scene.concatenate(parts)
    if params.any():
        apply_faces(scene, params)
    return scene, drawn


def scene_from_case(case: Case, check: bool = True, imperfect: bool = True) -> Scene:
    """Build the scene of a case: explicit blocks first, then the builder entries in the order
    wall, facade, box_model (see :mod:`dem.builders`), then the case's imperfections realised
    with its seed (dem.imperfections: the builder bricks' sizes scattered and laid again, the
    as-built gaps and courses out of plumb, face warps and arrises); ``imperfect=False`` gives
    the perfect scene of the same case.

    With ``check`` (default) the scene goes through :func:`dem.builders.check_scene`: initial
    overlaps deeper than ``solver.overlap_tolerance`` and floating blocks (unless
    ``scene.allow_floating``) raise :class:`dem.builders.SceneError` (a ValueError) naming the
    blocks.
    """
    scene, _ = build_parts(case, imperfect)
    if check:
        require_valid(
            check_scene(
                scene,
                overlap_tolerance=case.solver.overlap_tolerance,
                allow_floating=case.scene.allow_floating,
            )
        )
    return scene


def normal_stiffness(material: Material, scene: Scene | None = None, direction=None,
                     g: float = 9.81) -> float:
    """kn in Pa/m: the case's number, or for ``rigid`` the stiffness that keeps the elastic
    offset of every block's tipping load factor at 0.5 % (dem.compliance.rigid_stiffness; the
    widths along ``direction``, the load of a tilt, when given)."""
    if material.normal_stiffness != "rigid":
        return float(material.normal_stiffness)
    if scene is None:
        raise ValueError("material.normal_stiffness: 'rigid' needs the scene to choose kn")
    return rigid_stiffness(scene, g=g, direction=direction)


def joint_law(material: Material, scene: Scene | None = None, direction=None,
              g: float = 9.81) -> JointLaw:
    """The engine's joint law from a case's ``material:`` (defaults resolved: kn for 'rigid',
    ks = 0.4 kn, base friction = friction)."""
    kn = normal_stiffness(material, scene, direction, g)
    pairs = tuple(
        PairLaw(a=p.between[0], b=p.between[1], friction=p.friction,
                normal_stiffness=p.normal_stiffness,
                # ks of a pair: its own, else the material's, else 0.4 x the pair's kn
                shear_stiffness=p.shear_stiffness if p.shear_stiffness is not None else (
                    material.ks(p.normal_stiffness) if p.normal_stiffness is not None else None),
                damping=p.damping, max_closure=p.max_closure)
        for p in material.pairs)
    extra = {}
    if material.normal_law != "linear":
        extra = dict(normal_law=material.normal_law, max_closure=material.max_closure,
                     closure_limit=material.closure_limit,
                     beyond_closure_limit=material.beyond_closure_limit)
    if material.normal_damping != "critical":
        extra.update(normal_damping=material.normal_damping,
                     damping_time=material.damping_time)
    return JointLaw(friction=material.friction, base_friction=material.mu_base,
                    normal_stiffness=kn, shear_stiffness=material.ks(kn),
                    damping=material.damping, pairs=pairs, **extra)


def case_joint_law(case: Case, scene: Scene) -> JointLaw:
    """The joint law of a case's scene (the load direction of a tilt sets the widths of
    'rigid')."""
    return joint_law(case.material, scene, load_direction(case),
                     float(np.linalg.norm(case.gravity_vector())))


def load_direction(case: Case):
    """The lateral load direction of a tilt (table frame), else None."""
    if not isinstance(case.loading, TiltLoading):
        return None
    return loading_from_case(case).load_direction


def joint_summary(case: Case, scene: Scene, joints: JointLaw) -> dict:
    """summary.json's ``joints``: the kn in use, how it was chosen, and the estimated elastic
    offset of the scene's tipping load factors at that kn (dem.compliance)."""
    out = {"normal_stiffness_Pa_m": joints.normal_stiffness,
           "shear_stiffness_Pa_m": joints.shear_stiffness,
           "chosen": "rigid (elastic offset of every block <= 0.5 %)"
           if case.material.normal_stiffness == "rigid" else (
               "case file" if "normal_stiffness" in case.material.model_fields_set
               else "default: material.normal_stiffness not given"),
           "elastic_offset": elastic_offset(scene, joints.normal_stiffness,
                                            float(np.linalg.norm(case.gravity_vector())),
                                            load_direction(case))}
    if case.material.normal_stiffness == "rigid":
        default_kn = Material.model_fields["normal_stiffness"].default
        out["time_step_cost"] = {
            "vs_kn_Pa_m": default_kn,
            "steps_factor": (joints.normal_stiffness / default_kn) ** 0.5,
            "note": "the critical step scales as kn^-1/2: this many times the steps of the "
                    "default kn for the same simulated time"}
    # only where the case uses them: the summaries of every other case stay as they were
    if joints.normal_law != "linear":
        out["normal_law"] = {
            "law": joints.normal_law, "kn0_Pa_m": joints.normal_stiffness,
            "max_closure_m": joints.max_closure, "closure_limit": joints.closure_limit,
            "beyond_closure_limit": joints.beyond_closure_limit,
            "note": "elastic_offset is computed at kn0, the softest stiffness of the law: an "
                    "upper bound"}
    if joints.pairs:
        out["pairs"] = [{k: v for k, v in vars(p).items() if v is not None}
                        for p in joints.pairs]
    reuse = overlap_reuse_summary(case, scene)
    if reuse is not None:  # only where the case sets it, like normal_law above
        out["overlap_reuse"] = reuse
    return out


# solver fields that are not StepOptions: applied to the built Simulation (:func:`build`)
_AFTER_BUILD = {"overlap_reuse"}


def step_options(solver: SolverSpec) -> StepOptions:
    """The engine's stepping options from a case's ``solver:`` (the same names; the fields
    applied after construction, ``overlap_reuse``, left out: :func:`build`)."""
    return StepOptions(**solver.model_dump(exclude=_AFTER_BUILD))


def overlap_reuse_summary(case: Case, scene: Scene) -> dict | None:
    """summary.json's ``joints.overlap_reuse`` where the case sets ``solver.overlap_reuse``
    (None where it does not): the tolerance (m) and whether it acts.  It acts on imperfect faces
    only (dem.engine.coherence.set_overlap_reuse): on a perfect scene it is a no-op, said here
    instead of refused, so that one solver section serves a case's perfect and imperfect runs."""
    tol = case.solver.overlap_reuse
    if tol <= 0.0:
        return None
    active = bool(scene.imperfect.any())
    return {"tolerance_m": tol, "active": active,
            "note": "imperfect faces keep their overlap polygon while its corners drift less than "
                    "the tolerance (benchmarks/RESULTS.md, 'Overlap reuse for imperfect joints')"
            if active else "warning: no effect, the scene has no imperfect faces (the overlap "
                           "reuse acts on the warped kernels only; perfect faces have "
                           "solver.patch_reuse)"}


@dataclass
class Built:
    """What the build phase hands to the loop."""

    scene: Scene
    loading: Loading
    sim: "object"  # dem.engine.Simulation (imported lazily: Taichi)


def build(case: Case, scene: Scene | None = None, sim=None) -> Built:
    """Scene (``scene`` if already built and checked, e.g. by dem.validate), loading, engine;
    ``solver.overlap_reuse`` (m, > 0) switched on in the engine right after it is made
    (dem.engine.coherence.set_overlap_reuse; a no-op on a scene without imperfect faces,
    :func:`overlap_reuse_summary`).  ``sim``: the engine of this case already made (one scene
    of a batch, dem.run.batched: built from this ``scene``, its joint law and step options and
    the loading's gravity), used instead of a new one."""
    scene = scene if scene is not None else scene_from_case(case)
    loading = loading_from_case(case)
    if sim is None:
        from dem.engine import Simulation  # first: it imports Taichi with signals deferred

        from dem import ti_runtime

        # the run starts Taichi with its solver's settings (the arch: DEM_ARCH, or an earlier
        # init of the process's entry point); the engine's own call then only checks them
        ti_runtime.init(threads=case.solver.threads, precision=case.solver.precision)
        sim = Simulation(scene, case_joint_law(case, scene), step_options(case.solver),
                         gravity=loading.g0)
    if case.solver.overlap_reuse > 0.0:  # 0: the engine's default, left untouched (bit for bit)
        from dem.engine import coherence

        coherence.set_overlap_reuse(sim.contacts, case.solver.overlap_reuse)
    return Built(scene, loading, sim)


def as_built_record(case: Case) -> dict | None:
    """summary.json's ``imperfections.as_built`` of a case (dem.imperfections.as_built_summary),
    None where no as-built field is set: the builders and draws run again (milliseconds to a
    second for a box model), the same seed giving the same draws."""
    from dem.imperfections import as_built_summary

    params = imperfection_params(case)
    if not params.as_built():
        return None
    _, drawn = build_parts(case)
    return as_built_summary(params, drawn)


def size_reference(case: Case) -> np.ndarray:
    """The block sizes (m) the size scatter's deviations are measured from: the perfect scene's,
    or where an as-built field is set, the scene with its gaps but no size scatter (the bricks
    the gaps shortened are not counted as scattered; the as-built draws do not depend on the
    size scatter's, dem.imperfections.as_built_streams)."""
    if not case.imperfections.as_built():
        return scene_from_case(case, check=False, imperfect=False).size
    imp = case.imperfections.model_copy(update={"size_scatter": [0.0, 0.0, 0.0],
                                                "bed_unevenness": 0.0, "arris": 0.0})
    return scene_from_case(case.model_copy(update={"imperfections": imp}), check=False).size
