"""Rigid-block DEM engine: box blocks, Coulomb joints with shear history, explicit stepping.

Modules: ``options`` (the engine's inputs: JointLaw, StepOptions), ``containers`` (Model / State /
Contacts / Control: field tables and argpacks), ``geometry`` (box-box contact patches, Ig2),
``pair`` (pair properties, Ip2), ``laws`` (joint law, Law2), ``step`` (stages and kernels),
``launch`` (cached kernel launches), ``broadphase`` (neighbour list), ``timestep`` (critical
step, Clock), and the engine by job: ``assembly`` (the containers of the scenes), ``stepsize``
(the time step), ``launcher`` (kernel variants, chunks, probes), ``residency`` (host / device
arrays), ``simulation`` (Engine, and Simulation: one scene's view); ``device`` (device arrays
and kernels), ``errors``.

``Simulation`` is imported on first use (PEP 562): it imports Taichi and defines the kernels,
which ``dem check`` and the options / errors must not pay for.
"""

from dem.engine.errors import CapacityError, InputError, InstabilityError, SimulationError
from dem.engine.options import JointLaw, StepOptions

# Bumped by every change that moves a simulation's results (a fixed contact law, a new default),
# not by refactors that keep them bit for bit.  The studies' resume fingerprints include it
# (studies.calibration, studies.prediction), so a point an older engine
# finished is run again instead of being mixed with the new engine's points.
#   1: up to 8a0d44a
#   2: planar warps take the planar path (dem.engine.geometry.TWIST_FLOOR)
#   3: quasi-static tilts relax up to 3 s (was 1 s) and keep turning until the mechanism shows;
#      mechanisms read from the last equilibrium (postprocess.tilt.reference_frame); planar
#      warped faces' gap affine, coefficients once per pair (geometry.planar_gap, 7fd286f)
RESULTS_REVISION = 3

__all__ = ["RESULTS_REVISION", "Simulation", "JointLaw", "StepOptions", "InputError",
           "SimulationError", "InstabilityError", "CapacityError"]


def __getattr__(name: str):
    if name == "Simulation":
        from dem.signals import deferred

        with deferred():  # a stop signal inside Taichi's import would be lost (dem.signals)
            from dem.engine.simulation import Simulation

        return Simulation
    raise AttributeError(f"module 'dem.engine' has no attribute {name!r}")
