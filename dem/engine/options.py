"""The engine's own inputs besides the scene: the joint law's parameters and the stepping options.

The engine reads only these (MuJoCo's mjOption, Newton's model/solver options): it does not know
the case schema.  ``dem.run.build`` makes them from a case (``material:`` and ``solver:``, whose
descriptions and defaults are the user-facing documentation of every field); tests and benchmarks
may make them directly.  Units: Pa/m for joint stiffness (per unit joint area), s, m, m/s.
"""

from __future__ import annotations

from dataclasses import dataclass
from typing import Literal


@dataclass(frozen=True)
class JointLaw:
    """Parameters of the contact law at every joint (input of ``dem.engine.pair``, Ip2).

    friction          mu between blocks, -
    base_friction     mu between a block and the table, -
    normal_stiffness  kn, Pa/m: a patch of area A closed by a gap d pushes back with kn A d
    shear_stiffness   ks, Pa/m
    damping           viscous contact damping, fraction of critical, -
    """

    friction: float
    base_friction: float
    normal_stiffness: float
    shear_stiffness: float
    damping: float


@dataclass(frozen=True)
class StepOptions:
    """Numerical options of the stepping (the ``solver:`` section of a case says what each does).

    dt                  time step, s, or None: safety x the critical step
    safety              automatic dt = safety x critical dt, -
    skin                neighbour-list skin, m, or None: 0.1 x the smallest half edge
    max_pairs_per_block neighbour-list capacity per block
    overlap_tolerance   largest initial overlap accepted, m
    max_speed           a block faster than this stops the run, m/s
    local_damping       Cundall local (non-viscous) damping, -
    mode                "auto" | "serial" | "parallel" kernel
    threads             CPU threads, or None: all
    precision           "f64" | "f32"
    patch_reuse         largest in-plane drift of a kept contact patch, m; 0 = off
                        (dem.engine.coherence)
    """

    dt: float | None
    safety: float
    skin: float | None
    max_pairs_per_block: int
    overlap_tolerance: float
    max_speed: float
    local_damping: float
    mode: Literal["auto", "serial", "parallel"]
    threads: int | None
    precision: Literal["f64", "f32"]
    patch_reuse: float
