"""The command layer: the bodies of the ``dem`` commands (dem_cli.app parses the options and calls
them); the one place that joins the engine and the run loop (dem) with the analysis
(postprocess)."""
