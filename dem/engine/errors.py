"""Errors of the engine.  ``InputError`` means bad input (CLI exit 2), ``SimulationError`` a run
that failed (CLI exit 1).  Messages name the step, the block or the field."""


class InputError(ValueError):
    """The scene or the solver settings cannot be simulated (overlap, dt too large ...)."""


class SimulationError(RuntimeError):
    """The run stopped: instability, buffer overflow ..."""


class InstabilityError(SimulationError):
    """A block's state became NaN/inf or faster than ``solver.max_speed``."""

    def __init__(self, message: str, step: int, block: int):
        super().__init__(message)
        self.step = step
        self.block = block


class CapacityError(SimulationError):
    """A fixed-capacity buffer (neighbour list) is too small; the run stops, nothing is dropped."""
