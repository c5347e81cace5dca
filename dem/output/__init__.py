"""Output writers: VTK series for ParaView (:mod:`dem.output.vtk`) and PNG snapshots
(:mod:`dem.output.snapshot`).  ``summary.json`` and ``frames.npz`` are written by
:mod:`dem.runner`."""
