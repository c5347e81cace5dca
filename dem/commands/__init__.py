"""The command layer: the bodies of ``dem run | check | sweep | post | rocking`` (dem.cli parses the options and calls them)."""
