"""Reproduce the paper's Section 6 in one command: Table 1 (stage 1) then Table 2 (stage 2).

    .venv/bin/python experiments/paper/run.py [--write]   # or: make paper

``--write`` passes on to both scripts: each replaces its fragment of docs/validation/paper.md.

Exit code 0 when every expectation of the issues holds (borders within the paper's bounds and their
intervals; every level within its simultaneous interval; every nls estimate of G within its
interval, with errors below the paper's at 0.2 rad/s).
"""
from __future__ import annotations

import subprocess
import sys
from pathlib import Path

HERE = Path(__file__).resolve().parent


def main() -> int:
    rc = 0
    for script in ("table1.py", "table2.py"):
        print(f"==== {script}", flush=True)
        rc |= subprocess.call([sys.executable, str(HERE / script), *(["--write"] if "--write" in sys.argv[1:] else [])])
        print(flush=True)
    return rc


if __name__ == "__main__":
    sys.exit(main())
