"""The containers of an engine's scenes: Model, State, Contacts and Control of every scene side
by side (dem.engine.containers: scene g's bodies are rows model.scene_bodies[g] of every body
array, its pair slots the g-th block of the Contacts' slots).

    box = assemble(scenes, joints, gravity, options, chunk_steps, probe_slots, probe_bodies)
    box.model, box.state, box.contacts, box.control      # the engine's containers
    box.models[g]                                        # scene g's own Model
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from dem.engine.containers import Contacts, Control, Model, State
from dem.engine.errors import InputError
from dem.engine.options import StepOptions
from dem.scene import Scene


@dataclass
class Assembly:
    """What :func:`assemble` made: the engine's containers, and per scene its scene, joint law,
    gravity at rest (m/s^2, table frame) and own Model."""

    scenes: list
    joints: list
    gravity: np.ndarray   # [G, 3]
    models: list
    model: Model
    state: State
    contacts: Contacts
    control: Control
    skin: float           # the neighbour lists' skin (m)

    @property
    def n_scenes(self) -> int:
        return len(self.scenes)


def assemble(scenes: list[Scene], joints, gravity, options: StepOptions, chunk_steps: int,
             probe_slots: int, probe_bodies) -> Assembly:
    """The containers of ``scenes`` (in order) with ``joints`` (one JointLaw per scene, or one
    for all), ``gravity`` (per scene, or one 3-vector for all; None: -9.81 m/s^2 along z) and
    the StepOptions ``options``; the control holds the loads of ``chunk_steps`` steps and
    ``probe_slots`` probed steps a scene and ``probe_bodies(largest scene's bodies)`` probed
    bodies a scene (the residency's: dem.engine.residency)."""
    scenes = list(scenes)
    G = len(scenes)
    if G == 0:
        raise InputError("an engine needs at least one scene")
    joints = list(joints) if isinstance(joints, (list, tuple)) else [joints] * G
    gravity = np.broadcast_to(np.asarray((0.0, 0.0, -9.81) if gravity is None else gravity,
                                         dtype=float), (G, 3))
    models = [Model.from_scene(sc, j) for sc, j in zip(scenes, joints)]
    model = Model.concat(models)
    state = State(model.n_bodies)
    for g, (sc, m) in enumerate(zip(scenes, models)):
        b0, b1 = model.scene_bodies[g]
        for k, a in State.from_scene(sc, m).arrays().items():
            getattr(state, k)[b0:b1] = a
    # capacity of one scene: max_pairs_per_block counts each pair for both blocks, plus one
    # table pair each (the largest scene's, for every scene)
    capacity = max(int(np.ceil(0.5 * options.max_pairs_per_block * m.n_bodies))
                   + m.n_bodies + 8 for m in models)
    contacts = Contacts(model.n_bodies, capacity, G)
    hmin = min(float(m.half_np[: m.n_blocks].min()) for m in models)
    skin = float(options.skin) if options.skin is not None else 0.1 * hmin
    largest = max(m.n_bodies for m in models)
    control = Control(skin, options.max_speed, options.local_damping, options.patch_reuse, G,
                      chunk_steps, probe_slots, probe_bodies(largest))
    return Assembly(scenes, joints, gravity, models, model, state, contacts, control, skin)
