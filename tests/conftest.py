"""Fixtures shared by several test modules.

A fixture shared by several modules is imported here, never into each module that uses it:
pytest keeps one instance per place of definition, so a session fixture imported into N
modules is built N times (``view_runs``: ~17 s a build)."""

from tests.view_runs import view_runs  # noqa: F401 - the session fixture of tests/view_runs.py
