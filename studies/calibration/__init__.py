"""Calibration of the imperfection parameters on the Chapter 3 tilting tests (step 1 of the
prediction's protocol, studies/prediction/__init__.py).

    python -m studies calibration --out results/calibration          # run, then report
    python -m studies calibration --out results/calibration --report # report only
    python -m studies calibration --out results/calibration \\
        --candidates perfect bed-0.1-planar --specimens ip-small-5x5 --realisations 20

What it runs.  The calibration specimens are the small-brick tilt specimens of cases/tilt/
(in-plane/small-*.yaml, out-of-plane/small-*.yaml; the large-brick walls are held out), each
turned into a quasi-static tilt by studies.tilt.study (``quasi_static_case`` then
``study_settings``: the converged lambda, frames every 0.02 s, no VTK), with the
``imperfections:`` section of one candidate of studies/calibration/candidates.yaml.  Friction and
joint stiffness are the case files' (measured / physical) values, never parameters.  Every
(candidate, specimen) point is one ``dem ensemble`` of N realisations, seeds 0 .. N-1 (fixed in
advance; a perfect candidate is deterministic and runs one realisation), one worker, one Taichi
thread (DEM_THREADS=1), in a child process of its own.

Where things go.  The raw runs (frames.npz, summary.json per seed) go under ``--runs`` (default
``<out>/runs/``, git-ignored by ``results/*/runs/``); the committed record of a point is
``<out>/<candidate>/<specimen>/ensemble.json``: the ensemble's own ensemble.json plus a
``calibration`` block (fingerprint of the case, seeds, per-realisation extras read from the
runs: overturning mass fraction, crack angle, engine seconds; the CPU seconds of the child
processes, accumulated over resumed sessions).  ``<out>/summary.json`` and ``<out>/README.md``
score every candidate (:func:`score_candidate`) against the targets that ../shared/REFERENCE.md
supports (listed in :data:`TARGETS`, each with its strength).

Resumable.  A point whose committed ensemble.json holds all N realisations finished, for the
same case (fingerprint) and step cap, is skipped without starting anything; an unfinished point
is handed to ``dem ensemble`` again, which keeps every realisation already finished in its run
directory.  SIGTERM / SIGINT stop the running ensemble cleanly (its finished realisations stay),
record the point as pending and write the report.  A point that is not finished shows as pending
in the report, never as a number.

Units: lambda = a/g = tan(tilt angle at collapse), dimensionless; lengths in m; times in s.

The pieces, by job: specimens.py (specimens, candidates, targets, a point's case), points.py
(one point's child run and record), scoring.py (invariants, thesis checks, score), report.py
(summary.json, README.md), select.py (the selection rule and the freeze), cli.py.
"""
