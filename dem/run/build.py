"""Build phase: from a validated case to the scene, the loading and the engine.

The only place where the case schema meets the engine: ``joint_law`` and ``step_options`` copy
the ``material:`` and ``solver:`` sections into the engine's own option types
(dem.engine.options), so the engine never holds a pydantic object.
"""

from __future__ import annotations

from dataclasses import dataclass

from dem.builders import build_from_spec, check_scene, require_valid
from dem.case import Case, Material, SolverSpec
from dem.engine.options import JointLaw, StepOptions
from dem.loading import Loading, loading_from_case
from dem.scene import Scene, blocks_to_scene


def scene_from_case(case: Case, check: bool = True) -> Scene:
    """Build the scene of a case: explicit blocks first, then the builder entries in the order
    wall, facade, box_model (see :mod:`dem.builders`).

    With ``check`` (default) the scene goes through :func:`dem.builders.check_scene`: initial
    overlaps deeper than ``solver.overlap_tolerance`` and floating blocks (unless
    ``scene.allow_floating``) raise :class:`dem.builders.SceneError` (a ValueError) naming the
    blocks.
    """
    parts = []
    if case.scene.blocks:
        parts.append(blocks_to_scene(case.scene.blocks))
    for spec in (case.scene.wall, case.scene.facade, case.scene.box_model):
        if spec is not None:
            parts.append(build_from_spec(spec))
    scene = parts[0] if len(parts) == 1 else Scene.concatenate(parts)
    if check:
        require_valid(
            check_scene(
                scene,
                overlap_tolerance=case.solver.overlap_tolerance,
                allow_floating=case.scene.allow_floating,
            )
        )
    return scene


def joint_law(material: Material) -> JointLaw:
    """The engine's joint law from a case's ``material:`` (defaults resolved: ks = 0.4 kn,
    base friction = friction)."""
    return JointLaw(friction=material.friction, base_friction=material.mu_base,
                    normal_stiffness=material.normal_stiffness,
                    shear_stiffness=material.ks, damping=material.damping)


def step_options(solver: SolverSpec) -> StepOptions:
    """The engine's stepping options from a case's ``solver:`` (the same names)."""
    return StepOptions(**solver.model_dump())


@dataclass
class Built:
    """What the build phase hands to the loop."""

    scene: Scene
    loading: Loading
    sim: "object"  # dem.engine.Simulation (imported lazily: Taichi)


def build(case: Case, scene: Scene | None = None) -> Built:
    """Scene (``scene`` if already built and checked, e.g. by dem.validate), loading, engine."""
    from dem.engine import Simulation

    scene = scene if scene is not None else scene_from_case(case)
    loading = loading_from_case(case)
    sim = Simulation(scene, joint_law(case.material), step_options(case.solver),
                     gravity=loading.g0)
    return Built(scene, loading, sim)
