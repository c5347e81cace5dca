"""The run loop: one case from its scene to its output directory, as named phases.

    build   (build.py)    case -> scene, loading, engine (JointLaw / StepOptions from the case)
    settle  (settle.py)   an imperfect scene comes to rest under gravity; the clock restarts
    load    (loop.py)     advance the engine under the loading, chunk by chunk
    record  (record.py)   frames, virtual instruments, VTK, on their time schedules
    stop    (stop.py)     end time, step limit, collapse of a tilt run
    write   (write.py)    summary.json, frames.npz, instruments.npz, vtk/, final.png, atomically

``run_case`` (loop.py) strings them together: ``run_case_steps``, a generator that yields each
advance of its scene (steps.py: ``Advance``), driven alone (``steps.drive``) or with the other
runs of a batch by one loop (batched.py: ``drive_together``).  Analyses that read the finished
run (the mechanism of a tilt) are handed in by the caller (dem_cli.commands), so the loop never
imports the analysis.
"""

from dem.run.build import scene_from_case
from dem.run.loop import RunResult, run_case
from dem.run.write import OutputError

__all__ = ["OutputError", "RunResult", "run_case", "scene_from_case"]
