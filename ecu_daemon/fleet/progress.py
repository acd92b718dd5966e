"""The fleet run's progress bar (rich, as ``monitor``): drives done, drive-hours per hour, failures."""
from __future__ import annotations

import time

from rich.console import Console
from rich.progress import BarColumn, MofNCompleteColumn, Progress, TextColumn, TimeElapsedColumn, TimeRemainingColumn


class FleetProgress:
    """``with FleetProgress(n) as p: ... p.done(record)``; silent when stderr is not a terminal."""

    def __init__(self, total: int, enabled: bool = True):
        console = Console(stderr=True)
        self.progress = Progress(TextColumn("fleet"), BarColumn(), MofNCompleteColumn(), TextColumn("drives"),
                                 TextColumn("{task.fields[rate]} drive-h/h"), TextColumn("{task.fields[failed]} failed"),
                                 TimeElapsedColumn(), TimeRemainingColumn(), console=console,
                                 disable=not (enabled and console.is_terminal))
        self.task = self.progress.add_task("fleet", total=total, rate="-", failed=0)
        self.start = time.monotonic()
        self.drive_s = 0.0  # of the drives replayed in this run (not the stored ones)
        self.failed = 0

    def __enter__(self) -> FleetProgress:
        self.progress.start()
        return self

    def __exit__(self, *exc) -> None:
        self.progress.stop()

    def done(self, rec: dict) -> None:
        if not rec.get("cached"):
            self.drive_s += rec.get("duration_s") or 0.0
        self.failed += rec.get("status") != "ok"
        self.progress.update(self.task, advance=1, rate=f"{self.rate():.0f}", failed=self.failed)

    def rate(self) -> float:
        """Drive-hours replayed per wall-clock hour so far (the stored drives excluded)."""
        wall = time.monotonic() - self.start
        return self.drive_s / wall if wall > 0 else 0.0
