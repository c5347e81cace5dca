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
class PairLaw:
    """The joint constants of one pair of named materials that differ from the default (None:
    the default's).  a, b: material names (a block's ``material``, or "table")."""

    a: str
    b: str
    friction: float | None = None
    normal_stiffness: float | None = None
    shear_stiffness: float | None = None
    damping: float | None = None
    max_closure: float | None = None


@dataclass(frozen=True)
class JointLaw:
    """Parameters of the contact law at every joint (input of ``dem.engine.pair``, Ip2).

    friction          mu between blocks, -
    base_friction     mu between a block and the table, -
    normal_stiffness  kn, Pa/m: a patch of area A closed by a gap d pushes back with kn A d
                      (the hyperbolic law: kn0, the stiffness at zero closure)
    shear_stiffness   ks, Pa/m
    damping           viscous contact damping, fraction of critical, -
    normal_law        "linear" p = kn d, or "hyperbolic" p = kn0 d / (1 - d/d_max)
                      (dem.engine.laws)
    max_closure       d_max of the hyperbolic law, m
    closure_limit     the step is made for closures up to closure_limit x d_max, -
    beyond_closure_limit  "stop": a joint closing beyond closure_limit x d_max stops the run;
                      "tangent": the law goes on along its tangent there (a capped law)
    normal_damping    the normal dashpot: "critical", ``damping`` x the pair's critical value,
                      released point by point (dem.engine.laws.normal_law); "pair", the same
                      dashpot, its pulls held to the pair's pushes (laws.normal_law_pair_damped);
                      "stiffness", beta k per unit area with the pair's rule, beta =
                      damping_time (``damping`` then damps the shear only)
    damping_time      beta of the stiffness-proportional dashpot, s
    pairs             PairLaw per pair of named materials (later entries win); every other
                      pair takes the values above (with the table: base_friction)
    """

    friction: float
    base_friction: float
    normal_stiffness: float
    shear_stiffness: float
    damping: float
    normal_law: Literal["linear", "hyperbolic"] = "linear"
    max_closure: float | None = None
    closure_limit: float = 0.5
    beyond_closure_limit: Literal["stop", "tangent"] = "stop"
    pairs: tuple[PairLaw, ...] = ()
    normal_damping: Literal["critical", "pair", "stiffness"] = "critical"
    damping_time: float | None = None

    def step_stiffness(self) -> tuple[float, float, float]:
        """(kn, ks, zeta) bounding every pair this law can give, for a critical-step estimate
        without the scene (dem check): the largest normal stiffness a pair reaches within the
        closures the step is made for (hyperbolic: kn0 / (1 - closure_limit)^2), the largest ks
        and damping ratio.  The simulation bounds the pairs of the materials in use
        (containers.Model.stiffest): the same or smaller."""
        kns = [self.normal_stiffness] + [p.normal_stiffness for p in self.pairs
                                         if p.normal_stiffness is not None]
        kss = [self.shear_stiffness] + [p.shear_stiffness for p in self.pairs
                                        if p.shear_stiffness is not None]
        zetas = [self.damping] + [p.damping for p in self.pairs if p.damping is not None]
        factor = (1.0 / (1.0 - self.closure_limit) ** 2 if self.normal_law == "hyperbolic"
                  else 1.0)
        return max(kns) * factor, max(kss), max(zetas)

    def step_beta(self) -> float:
        """The damping time (s) of the stiffness-proportional dashpot, 0 without one (the
        critical step's beta, dem.engine.timestep.critical_time_step)."""
        return float(self.damping_time) if self.normal_damping == "stiffness" else 0.0

    def __post_init__(self) -> None:
        if self.normal_law == "hyperbolic":
            if self.max_closure is None or not self.max_closure > 0:
                raise ValueError("the hyperbolic normal law needs max_closure > 0 (m)")
            if not 0.0 < self.closure_limit < 1.0:
                raise ValueError(f"closure_limit must lie in (0, 1), got {self.closure_limit}")
        if self.normal_damping not in ("critical", "pair", "stiffness"):
            raise ValueError("normal_damping is 'critical', 'pair' or 'stiffness', got "
                             f"{self.normal_damping!r}")
        if self.normal_damping == "stiffness" and not (self.damping_time is not None
                                                       and self.damping_time > 0):
            raise ValueError("normal_damping 'stiffness' needs damping_time > 0 (s)")
        if self.beyond_closure_limit not in ("stop", "tangent"):
            raise ValueError("beyond_closure_limit is 'stop' or 'tangent', got "
                             f"{self.beyond_closure_limit!r}")


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
