"""What every study repeats, once: where the code and an input stand in git
(:mod:`studies.kit.provenance`), JSON records read and merged under a lock
(:mod:`studies.kit.records`), ``dem`` as a child process with its CPU seconds and a clean stop on
SIGTERM / SIGINT (:mod:`studies.kit.child`), and a session's drain file, stop time, CPU ledger
and command echo (:mod:`studies.kit.session`); and a study's shape (:mod:`studies.kit.study`):
the study declares its points, what each lacks, its command and its records, and the kit owns the
paths, the fingerprint, the records and the resumable loop."""
