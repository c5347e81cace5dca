"""Reduced two-body rocking model of a facade (thesis Chapter 5), a fast companion to the DEM.

Two stacked rigid blocks rock on a rigid base, with a top load N and a friction mu N from the roof
beams, under a horizontal base acceleration.  Modules:

* :mod:`dem.rocking.params`     RockingParams (dimensions, masses, top load); the conventions
* :mod:`dem.rocking.patterns`   contact modes: pattern labels, equation sets, pivot geometry
* :mod:`dem.rocking.equations`  equations of motion (Lagrangian, all patterns), top-load force
* :mod:`dem.rocking.energy`     kinetic and potential energy
* :mod:`dem.rocking.maximal`    the parts as free planar bodies: contact rows, Newton-Euler check
* :mod:`dem.rocking.integrate`  event-driven integration (solve_ivp + events): ``integrate_rocking``
* :mod:`dem.rocking.modes`      contact modes by complementarity, exits from stationary modes
* :mod:`dem.rocking.impacts`    plastic (Moreau / Housner) impacts, joint locks, restitution
* :mod:`dem.rocking.events`     event functions and what happens at an event
* :mod:`dem.rocking.recording`  output samples, event log, episodes; RockingResult, RockingError
* :mod:`dem.table_motion`      the table motion (shared with the DEM: dem.loading.Shake)
* :mod:`dem.rocking.analysis`   closed forms (Housner limits, thresholds), amplitudes, statistics
* :mod:`dem.rocking.schema`     the case format; :mod:`dem.rocking.runner` run a case, write its
  outputs (the ``dem rocking`` command: dem_cli.commands.rocking)

Derivation and choices: docs/rocking_model.md; results against the thesis: results/two-body/README.md.
"""

from dem.rocking.integrate import RockingError, RockingResult, Settings, integrate_rocking
from dem.rocking.params import RockingParams
from dem.rocking.patterns import pattern_name

__all__ = ["RockingParams", "pattern_name", "RockingError", "RockingResult", "Settings",
           "integrate_rocking"]
