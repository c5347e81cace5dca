"""The ``dem`` command line: the application layer above the library.

Its commands compose the engine and the run loop (``dem``) with the analysis of their outputs
(``postprocess``), so they live above both, and the layers read one way (docs/architecture.md):
``dem_cli`` (dem_cli.app parses the options; dem_cli.commands holds the command bodies)
-> ``postprocess`` -> ``dem``.  Nothing in ``dem`` or ``postprocess`` imports this package.
"""
