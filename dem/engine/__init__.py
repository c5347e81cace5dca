"""Rigid-block DEM engine: box blocks, Coulomb joints with shear history, explicit stepping.

Modules: ``containers`` (Model / State / Contacts / Control: field tables and argpacks),
``geometry`` (box-box contact patches, Ig2), ``pair`` (pair properties, Ip2), ``laws`` (joint
law, Law2), ``step`` (stages and kernels), ``launch`` (cached kernel launches), ``broadphase``
(neighbour list), ``timestep`` (critical step), ``simulation`` (driver), ``errors``.
"""

from dem.engine.errors import CapacityError, InputError, InstabilityError, SimulationError
from dem.engine.simulation import Simulation

__all__ = ["Simulation", "InputError", "SimulationError", "InstabilityError", "CapacityError"]
