"""Steppable runs: a run's phases as a generator that asks for its engine's steps.

A run (dem.run.loop.run_case_steps) and its phases that advance the engine (dem.run.settle,
dem.run.quasi_static) do not call ``sim.advance`` themselves: they ``yield Advance(sim, n,
loads)`` ("advance my scene by n steps under these loads") and go on when the request is done.
Whoever drives the generator decides how:

* a run alone: :func:`drive` does each request at once (``sim.advance``), so the run is the
  blocking call it always was (``run_case``);
* K runs whose scenes share one engine: dem.run.batched drives the K generators from one loop,
  advancing the engine by the smallest request of those waiting (every scene with its own
  loads), then resuming each run whose request is done, in index order: no threads.

A scene that fails (its ``sim.failure``) gets its failure raised at its ``yield`` (the
generator's ``throw``), where the run loop's ``except`` writes the failed run as always; so does
a stop (dem.signals.Interrupted).
"""

from __future__ import annotations

from dataclasses import dataclass
from typing import Any, Callable, Generator

import numpy as np

# loads(t [K]) -> (gravity [K,3], base acceleration [K,3]), both in the table frame, m/s^2
LoadFn = Callable[[np.ndarray], tuple[np.ndarray, np.ndarray]]


@dataclass
class Advance:
    """A run's request: advance ``sim`` (one scene: dem.engine.Simulation) by ``n_steps``
    steps under ``loads`` (a LoadFn of this scene)."""

    sim: Any
    n_steps: int
    loads: LoadFn


Steps = Generator[Advance, None, Any]


def drive(steps: Steps):
    """Run a steppable run alone: each request done at once by ``sim.advance``; returns the
    generator's value.  An exception of the advance (a failure, a stop) is raised into the
    generator at its request, and out of here where the generator does not handle it."""
    try:
        request = next(steps)
        while True:
            try:
                request.sim.advance(request.n_steps, request.loads)
            except BaseException as err:  # noqa: BLE001 - raised where the run asked
                request = steps.throw(err)
            else:
                request = next(steps)
    except StopIteration as done:
        return done.value
