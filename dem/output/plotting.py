"""matplotlib for files, never for a screen: every plot of the package is drawn on the Agg
backend, so that it runs headless (a CI runner, a dask worker, a borrowed machine) and never
opens a window.  matplotlib is imported on the first call, not with this module."""

from __future__ import annotations


def agg_pyplot():
    """``matplotlib.pyplot`` with the Agg backend selected (no display needed)."""
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    return plt
