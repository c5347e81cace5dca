"""Fixtures shared by several test modules.

A fixture must be defined (or imported) here, not imported into each module that uses it:
pytest keeps one instance per place of definition, so a session fixture imported into four
modules was built four times (``view_runs``: ~17 s each)."""

from tests.view_runs import view_runs  # noqa: F401 - the session fixture of tests/view_runs.py
