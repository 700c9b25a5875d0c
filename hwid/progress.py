"""Progress on stderr, drawn by :mod:`rich.progress` (done/total, rate, time left).

Silent when stderr is not a terminal unless ``HWID_PROGRESS=1`` (CI logs and pipes stay clean).
"""
from __future__ import annotations

import os
import sys

from rich.console import Console
from rich.progress import BarColumn, MofNCompleteColumn, Progress as RichProgress, TextColumn, TimeRemainingColumn


class Progress:
    """One task's progress bar: ``with Progress(total, "simulate", "samples") as bar: bar.update(n)``."""

    def __init__(self, total: int, label: str = "", unit: str = "it", enabled: bool | None = None):
        if enabled is None:
            enabled = sys.stderr.isatty() or os.environ.get("HWID_PROGRESS") == "1"
        self.enabled = bool(enabled)
        self.total = max(int(total), 1)
        self.done = 0
        self._bar = RichProgress(TextColumn("{task.description}"), BarColumn(), MofNCompleteColumn(),
                                 TextColumn(unit), TimeRemainingColumn(),
                                 console=Console(stderr=True), disable=not self.enabled, transient=False)
        self._task = self._bar.add_task(label, total=self.total)

    def update(self, n: int = 1) -> None:
        self.done += n
        self._bar.update(self._task, advance=n)

    def close(self) -> None:
        self._bar.stop()

    def __enter__(self):
        self._bar.start()
        return self

    def __exit__(self, *exc):
        self.close()
