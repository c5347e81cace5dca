"""What every study repeats, once: where the code and an input stand in git
(:mod:`studies.kit.provenance`), JSON records read and merged under a lock
(:mod:`studies.kit.records`), ``dem`` as a child process with its CPU seconds and a clean stop on
SIGTERM / SIGINT (:mod:`studies.kit.child`), and a session's drain file, stop time, CPU ledger
and command echo (:mod:`studies.kit.session`)."""
