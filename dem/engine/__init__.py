"""Rigid-block DEM engine: box blocks, Coulomb joints with shear history, explicit stepping.

Modules: ``options`` (the engine's inputs: JointLaw, StepOptions), ``containers`` (Model / State /
Contacts / Control: field tables and argpacks), ``geometry`` (box-box contact patches, Ig2),
``pair`` (pair properties, Ip2), ``laws`` (joint law, Law2), ``step`` (stages and kernels),
``launch`` (cached kernel launches), ``broadphase`` (neighbour list), ``timestep`` (critical
step), ``simulation`` (driver), ``errors``.

``Simulation`` is imported on first use (PEP 562): it imports Taichi and defines the kernels,
which ``dem check`` and the options / errors must not pay for.
"""

from dem.engine.errors import CapacityError, InputError, InstabilityError, SimulationError
from dem.engine.options import JointLaw, StepOptions

__all__ = ["Simulation", "JointLaw", "StepOptions", "InputError", "SimulationError",
           "InstabilityError", "CapacityError"]


def __getattr__(name: str):
    if name == "Simulation":
        from dem.signals import deferred

        with deferred():  # a stop signal inside Taichi's import would be lost (dem.signals)
            from dem.engine.simulation import Simulation

        return Simulation
    raise AttributeError(f"module 'dem.engine' has no attribute {name!r}")
