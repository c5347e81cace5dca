"""Output writers: atomic file writes (JSON, NPZ, text, figures: :mod:`dem.output.atomic`), VTK
series for ParaView (:mod:`dem.output.vtk`) and PNG snapshots (:mod:`dem.output.snapshot`).
What a run directory holds and who writes it: :mod:`dem.run.write`."""
