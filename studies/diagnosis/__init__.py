"""The diagnosis: why the laboratory's box models rocked at 2.4-3.2 Hz and the DEM's
did not (results/prediction).  Each hypothesis gets one small decisive experiment; the table of
hypothesis, experiment, result and verdict is results/diagnosis/README.md.

Experiments built so far:

* **E4** (:mod:`studies.diagnosis.e4`): is the thesis' input just short of the DEM's rocking
  branch?  Model II y with the frozen joints at 2.4 / 2.8 / 3.2 Hz x 1.9 / 2.3 / 3.0 m/s2 x
  seeds 0-2, 10 cycles; the branch of each run (postprocess.verdicts.response_branch) and the
  onset acceleration at each frequency.

Run: ``python -m studies diagnosis e4 [--workers N] [--stop-at HH:MM] [--report]``.
"""
