"""The blind prediction of the Chapter 4 shaking-table tests with the frozen imperfection set
(steps 3-5 of the protocol below).

    python -m studies prediction --frozen studies/calibration/frozen.yaml \\
        --out results/prediction                      # run (Model II y first), then report
    python -m studies prediction --frozen studies/calibration/frozen.yaml \\
        --out results/prediction --only model-ii-y --realisations 10 --cycles 50
    python -m studies prediction --frozen studies/calibration/frozen.yaml \\
        --out results/prediction --report             # report from the committed points.json
    python -m studies prediction --frozen studies/calibration/frozen.yaml \\
        --out results/prediction --only model-ii-y --cycles-check 10   # 10 against 50 cycles

The protocol: calibrate -> freeze -> predict, in this order in the git history, so that no
Chapter 4 result can have chosen the parameters.  Its steps, which the modules name: (1)
calibrate the imperfections on the Chapter 3 tilts (studies.calibration); (2) freeze one set, a
committed file (studies/calibration/frozen.yaml); (3) predict Chapter 4, Model II y in full
first, at least 10 realisations per frequency; (4) judge the prediction by the success criteria
(criteria.criteria); (5) reject false successes (criteria.false_success_checks).

* The frozen set (plan.load_frozen) is a YAML file under ``cases/`` with an ``imperfections:``
  mapping (the fields of docs/imperfections.md except ``seed``: ``bed_unevenness`` (m),
  ``face_shape``, ``size_scatter`` ([m, m, m]), ``arris`` (m)) and provenance fields
  (``derived_in``: where the derivation is written, e.g. results/calibration/README.md;
  ``candidate``: its name among studies/calibration/candidates.yaml; ``note``).  Nothing else:
  friction and joint stiffness are not parameters (they stay the case files' measured /
  physical values), and there is one set for every model (no per-model sections).  The study
  refuses to start (exit 2, the message names the problem) when the file is missing, is not
  such a mapping, is not tracked by git or differs from its last commit; the commit that last
  changed it (``git log -1 --format=%H -- FILE``, "the commit that froze it") goes into every
  output.
* The prediction points are the shake study's sweeps (studies.shake.study.SWEEPS: the case files
  of cases/shake/ and the Appendix I / Chapter 4 frequencies, imported, not copied), all but the
  amplified one (a raised excitation is context, not a prediction): Model II y first, then II x,
  II diagonal, I y, I x, III y (:data:`ORDER`).  Each case gets ``imperfections:`` = the frozen
  set and nothing else changes.  ``--cycles`` (default 50, the thesis') cycles after settling,
  N = ``--realisations`` (default 10) realisations per frequency with seeds 0 .. N-1, the same
  for every sweep and frequency.  The plan (``<out>/plan.json``: frozen set, freezing commit,
  seeds, sweeps, frequencies, cycles) is written before the first run; a later call with
  another frozen commit, parameter set, seeds or cycles refuses (exit 2) rather than mixing.
* One sweep = one ``dem sweep CASE --realisations 1 --seed S --frequencies F`` per seed S
  (dem_cli.commands.sweep) in a child process with DEM_THREADS=1, F the frequencies of S that the
  committed ``<out>/<sweep>/points.json`` does not already hold finished for the same
  fingerprint (case, seeds, frequencies, cycles, step cap, engine results revision); its raw
  runs under ``--runs`` (default ``<out>/runs/``, git-ignored by ``results/*/runs/``).
  points.json is merged after every seed (points.update_points, under a lock): a point
  finished in an earlier session counts even where its run directory is gone (a new
  checkout, another machine) and never runs again; ``dem sweep`` itself skips every point whose
  run directory holds a finished run, so an interrupted seed resumes.  A sweep whose
  points.json holds every (seed, frequency) finished is skipped without starting anything.
  ``--seeds`` / ``--frequencies`` restrict a call to a subset (the plan does not change), to
  share a sweep between processes or machines; studies.prediction.pool (``python -m studies point-pool``) runs chosen points in a
  process pool without dask (a borrowed many-core machine), into the same run directories,
  from which the next call here merges them.  The child's CPU seconds (user + system of its
  process tree) add up over sessions in points.json (a point_pool machine's are not in it:
  its record says what they were).  A call works seed by seed, so with ``--workers 2`` the
  last run of a seed runs alone; two calls side by side, each ``--workers 1`` on its own
  ``--seeds``, keep both cores busy (as on 2026-11-26).
* Ending a session: ``touch <runs>/DRAIN`` (``--drain-file``) lets the runs in flight finish,
  starts no new one and writes the report (dem.batch, "Draining"); SIGTERM (or the end of a
  session) stops at once, and the runs in flight keep their last restart point (every 30 s
  after settling): the next call resumes them where their run directories are still there
  (dem.run.resume).
* points.json is the committed analysis record of a sweep: one row per (seed, frequency) with
  the numbers of the point's analysis.json (postprocess.shake via postprocess.sweep.compact):
  amplification of ds, dsr, da, a (unfiltered), a_lp (low-passed, below), a_front, a_front_lp,
  da_front (the front facade's centre accelerometer), a's amplification at each cutoff of the
  low-pass sensitivity (``a_lowpass``), the first-harmonic ratio and dominant frequency of ds,
  lags of ds and dsr (s), the excited portion, collapse_suspected, the mechanism labels.
* ``<out>/summary.json`` and ``<out>/README.md`` (report.report): per sweep the predicted
  characteristic frequency (the rule of postprocess.sweep.effective_range on the median curve
  over the surviving realisations; null with the reason when the peak is at the edge of the
  sweep or not clear), the effective range, amplification of ds inside and outside (median and
  10-90 % over the realisations), lag inside, excited bricks, survival rate, CPU time; the
  criteria of step 4 (criteria.criteria) and the false-success checks of step 5
  (criteria.false_success_checks), each pass / fail / pending; beside them, not criteria, the
  acceleration table, the front / back table and the cycles checks (below).

Thesis numbers: ../shared/REFERENCE.md, "Shaking-table tests (Chapter 4)" (characteristic
frequencies, effective ranges, amplifications, lags, excited portions; Appendix I groups and
peak accelerations) and the success criteria (criteria.py, protocol.py).  Units: Hz, s, m, m/s2; the
amplifications are dimensionless (thesis Section 4.2.5: steady-state peak-to-peak of the
response over that of the excitation of the same kind).

Shown, not scored (none is one of the success criteria):

* The acceleration low-passed like an instrument's (step 4).  The DEM's accelerometer
  is ideal (500 Hz samples of a rigid brick, every impact spike kept: an amplification of a of
  6-8 on Model II where the tests read ~2); the thesis gives no sampling rate or filter for its
  accelerometers.  ``a_lp`` is ``a`` through an ASSUMED instrument: a 4-pole Butterworth at
  20 Hz run forward and backward (postprocess.shake_signals.lowpass, LOWPASS_HZ; >= 5 harmonics
  of the highest test frequency, 3.6 Hz).  The answer depends on the cutoff (Model II y, 0.2 mm
  planar beds, 2.8 Hz, 10 cycles: raw 6.29; 50 / 20 / 10 Hz: 4.64 / 3.15 / 2.65), so the report
  gives a's amplification inside the thesis' range raw and at 10, 20 and 50 Hz
  (analysis.acceleration_inside, from each point's ``a_lowpass_sensitivity``: no rerun).
* Front / back facades (thesis Section 4.3.4, Tables 4.9 - 4.11: front / back 0.359 Model II y,
  0.618 II x, 0.587 III y, constant over frequency).  The front facade carried only its centre
  accelerometer (A5), so the thesis' front amplification is an accelerometer quantity, a or da
  (it does not say which); here da_front / da (the headline: no impact spikes, no assumed
  cutoff) and a_front_lp / a_lp per row, then per-seed means inside the range
  (analysis.front_back_inside) and the median ratio per frequency.  The DEM's box model is
  symmetric front to back but for the imperfections' draws and the excitation's sign.
* Fewer cycles (step 3: a cut must be shown not to change the answer).  The table's
  sine (dem.table_motion) has no ramp-in or taper, the settle phase of an imperfect scene ends
  before the clock starts and does not depend on the duration, and the run loop's steps differ
  only at the run's end: an N-cycle run is the first N cycles of a longer one.  Measured: the
  frames and instruments of Model II y (0.2 mm planar beds, seed 0, 2.8 Hz) for 2 and 4 cycles
  equal, bit for bit, the first 2 and 4 cycles of a 4- and a 10-cycle run (separate launches;
  tests/test_shake_truncation.py on a small settling wall).  So ``--cycles-check N``
  re-analyses the finished runs of a sweep over their first N cycles
  (postprocess.shake.analyze_run(cycles=N): no simulation) and compares with the full cycles
  (cycles.cycles_verdict, rule CYCLES_RULE): characteristic frequency, ds amplification inside
  and outside, survival.  The analyses of the first N cycles for N in TRUNCATED_CYCLES are made
  as the points finish, while their raw runs exist (cycles.record_truncated; a point_pool
  machine makes them beside its runs), and committed in ``<out>/<sweep>/truncated.json``, so
  that the check does not depend on raw runs surviving between sessions.  Both sides use the
  same runs: those with a kept analysis or a raw run (frames.npz) here; a finished point with
  neither (seed 0 of Model II y, whose runs were lost with a machine before this existed) is
  left out of both and named (``left_out_no_raw_run``), and the README gives the runs compared
  out of the sweep's finished ones.  The analysis of the first N cycles matches that of an N-cycle run to
  2e-5 in ds (the jittered samples' resampling grid spans the record), a_lp to 3e-4, da to 2-3 %
  at 2-4 cycles (the drift-free integral's fit and running mean at the record's end) and raw a
  to ~5 % (the spikes' peaks move with the grid).  ``<out>/<sweep>/cycles-check-<N>.json``
  (committed) holds the rows and the verdict.
* The cut itself (``--cut-cycles N --only SWEEPS``): the sweeps named, not yet planned and not
  Model II y, are planned at N cycles, and only once Model II y finished at the plan's cycles
  and its cycles-check-N.json, made from the finished sweep, says the answer is unchanged
  (cycles.cut_record).  The plan records the cut per sweep with that file and its verdict; a
  planned sweep's cycles never change; the false-success check on the excitation names every
  cut and fails one without its record.  Survival is then over N cycles, which the report says.

The pieces, by job: protocol.py (the fixed choices, the thesis numbers), plan.py (frozen set,
plan), points.py (points.json), run.py (one sweep's child runs), analysis.py (one sweep's
numbers), cycles.py (the cycles check and the cut), criteria.py (steps 4 and 5), report.py
(summary.json, README.md, plots), cli.py (the command line), pool.py (points without dask).
"""
