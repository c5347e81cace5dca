"""A rich progress bar over simulated time (steps/s and ETA), or nothing.

``unit``/``label``: what the bar counts, simulated time ``t`` in s by default; a quasi-static
tilt counts its table angle in degrees (its simulated time is only the relaxations': a bar over
it would stop near 1 s of a 22.5 s total).
"""

from __future__ import annotations


class Progress:
    def __init__(self, enabled: bool, duration: float, name: str, unit: str = "s",
                 label: str = "t"):
        self.bar = None
        if not enabled:
            return
        from rich.progress import (BarColumn, Progress, TextColumn, TimeElapsedColumn,
                                   TimeRemainingColumn)
        self.bar = Progress(
            TextColumn("[bold]{task.description}"), BarColumn(),
            TextColumn(f"{label} = {{task.completed:.3f}} / {{task.total:.3f}} {unit}"),
            TextColumn("{task.fields[rate]:>10} steps/s"), TimeElapsedColumn(),
            TextColumn("ETA"), TimeRemainingColumn(), transient=False)
        self.task = self.bar.add_task(name, total=duration, rate="-")
        self.bar.start()

    def update(self, t: float, steps_per_s: float) -> None:
        if self.bar is not None:
            self.bar.update(self.task, completed=t, rate=f"{steps_per_s:,.0f}")

    def close(self) -> None:
        if self.bar is not None:
            self.bar.stop()
