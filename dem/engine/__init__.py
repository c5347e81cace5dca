"""Rigid-block DEM engine: box blocks, Coulomb joints with shear history, explicit stepping.

Modules: ``containers`` (Model / State / Contacts), ``geometry`` (box-box contact patches),
``laws`` (joint law), ``step`` (stages and kernels), ``broadphase`` (neighbour list),
``timestep`` (critical step), ``simulation`` (driver), ``errors``.
"""

from dem.engine.errors import CapacityError, InputError, InstabilityError, SimulationError
from dem.engine.simulation import Simulation

__all__ = ["Simulation", "InputError", "SimulationError", "InstabilityError", "CapacityError"]
