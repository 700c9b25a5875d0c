"""A small progress bar on stderr: done/total, rate and time left. Silent when stderr is not a TTY
unless ``HWID_PROGRESS=1``."""
from __future__ import annotations

import os
import sys
import time


class Progress:
    def __init__(self, total: int, label: str = "", unit: str = "it", enabled: bool | None = None):
        self.total = max(int(total), 1)
        self.label = label
        self.unit = unit
        self.done = 0
        self.t0 = time.monotonic()
        self._last = 0.0
        if enabled is None:
            enabled = sys.stderr.isatty() or os.environ.get("HWID_PROGRESS") == "1"
        self.enabled = enabled

    def update(self, n: int = 1) -> None:
        self.done += n
        now = time.monotonic()
        if self.enabled and (now - self._last > 0.2 or self.done >= self.total):
            self._last = now
            el = now - self.t0
            rate = self.done / el if el > 0 else 0.0
            left = (self.total - self.done) / rate if rate > 0 else float("nan")
            frac = self.done / self.total
            bar = "#" * int(30 * frac) + "-" * (30 - int(30 * frac))
            sys.stderr.write(f"\r{self.label} [{bar}] {self.done}/{self.total} {self.unit} "
                             f"{rate:.3g} {self.unit}/s, {left:.0f} s left   ")
            sys.stderr.flush()

    def close(self) -> None:
        if self.enabled:
            sys.stderr.write("\n")
            sys.stderr.flush()

    def __enter__(self):
        return self

    def __exit__(self, *exc):
        self.close()
