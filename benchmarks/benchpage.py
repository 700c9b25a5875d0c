"""A benchmark's printed output as its fragment of docs/validation/benchmarks.md.

Every ``bench_*.py`` timing script ends in :func:`run`: called with ``--write`` it prints as usual
and then writes what it printed, with the load average at its start and end (a timing under load
is slower than the machine can do), as ``docs/validation/generated/<name>.md``.
"""
from __future__ import annotations

import contextlib
import io
import os
import sys
from collections.abc import Callable
from pathlib import Path

sys.path.insert(0, str(Path(__file__).resolve().parents[1] / "docs"))
from fragment import write  # noqa: E402


class _Tee(io.TextIOBase):
    """Writes to every stream given."""

    def __init__(self, *streams):
        self.streams = streams

    def write(self, text: str) -> int:
        for s in self.streams:
            s.write(text)
        return len(text)

    def flush(self) -> None:
        for s in self.streams:
            s.flush()


def run(name: str, script: str, main: Callable[[], int | None]) -> int:
    """Run ``main`` (which reads ``sys.argv`` without ``--write``); with ``--write`` write its output
    as the fragment ``name``. Returns ``main``'s exit code."""
    write_it = "--write" in sys.argv[1:]
    if write_it:
        sys.argv.remove("--write")
    load0 = os.getloadavg()[0]
    buf = io.StringIO()
    with contextlib.redirect_stdout(_Tee(sys.stdout, buf)):
        rc = main()
    if write_it:
        load1 = os.getloadavg()[0]
        md = (f"```\n{buf.getvalue().rstrip()}\n```\n\nLoad average (1 min) {load0:.2f} at the start, {load1:.2f} at "
              f"the end, on {os.cpu_count()} cores (above about 1.5 the timings are slower than the machine can do).")
        print(f"wrote {write(name, md, script)}")
    return rc or 0
