"""``python -m dem_cli ARGS`` is ``dem ARGS`` (the console script), with the same name in its
usage lines."""

from dem_cli.app import app

app(prog_name="dem")
