"""Recorded data at scale (issue 15's benchmarks): reading and resampling a 10^7-row, 4-column CSV
with ISO 8601 timestamps, and stage 1 from a history of 1,000 recorded levels.

Usage: ``python benchmarks/bench_recorded.py [--rows 10000000] [--levels 1000] [--write]``; ``--write`` also writes its output as the fragment of docs/validation/benchmarks.md. The CSV is
written once to a temporary folder (about 0.5 GB) and removed afterwards; the figures are printed.
"""
from __future__ import annotations

import argparse
import gc
import sys
import tempfile
import time
from pathlib import Path

import numpy as np
import pandas as pd
import yaml

sys.path.insert(0, str(Path(__file__).resolve().parents[1] / "tests"))

from hwid import config                                     # noqa: E402
from hwid.identify.history import HistoryFit, settled_levels  # noqa: E402
from hwid.model import from_config                          # noqa: E402
from hwid.plant import Record                               # noqa: E402
from hwid.recorded import load_records                      # noqa: E402


def bench_csv(rows: int, folder: Path) -> None:
    dt = 0.001
    t0 = pd.Timestamp("2026-01-01T00:00:00Z")
    rng = np.random.default_rng(0)
    u = np.repeat(rng.uniform(-1, 1, rows // 1000 + 1), 1000)[:rows]
    frame = pd.DataFrame({"timestamp": (t0 + pd.to_timedelta(np.arange(rows) * dt + rng.uniform(0, 2e-4, rows), unit="s"))
                          .strftime("%Y-%m-%dT%H:%M:%S.%fZ"),
                          "target": u, "position": u + 0.01 * rng.standard_normal(rows), "current": rng.standard_normal(rows)})
    path = folder / "big.csv"
    start = time.perf_counter()
    frame.to_csv(path, index=False, float_format="%.6g")
    written = time.perf_counter() - start
    del frame, u                # the reader is timed on its own, not beside the writer's 10^7 strings
    gc.collect()
    cfg = {"name": "big", "sampling": {"dt": dt},
           "plant": {"kind": "recorded", "experiments": [{"file": str(path), "time": {"column": "timestamp"},
                                                          "input": {"column": "target"},
                                                          "output": {"column": "position"}, "role": "other"}]}}
    (folder / "big.yaml").write_text(yaml.safe_dump(cfg))
    start = time.perf_counter()
    records = load_records(config.load(folder / "big.yaml"))
    seconds = time.perf_counter() - start
    print(f"CSV {rows:,} rows x 4 columns ({path.stat().st_size / 1e6:.0f} MB, written in {written:.0f} s): "
          f"read, checked and resampled onto the grid in {seconds:.2f} s "
          f"({sum(r.u.size for r in records):,} samples, {len(records)} record(s))")


def bench_levels(n_levels: int) -> None:
    import rigs
    cfg = config.loads(yaml.safe_dump(rigs.small(**{"plant.output_nonlinearity.polynomial": [0, 1.0, 0.8, -0.6],
                                                    "plant.input_nonlinearity.slope_down": 1.3})))
    truth = from_config(cfg.plant)
    rng = np.random.default_rng(1)
    dt = 0.05
    u = np.repeat(rng.uniform(-1.2, 1.2, n_levels), rng.integers(100, 200, n_levels))
    y = truth.simulate(u, dt, gear=0.0).x + 0.01 * rng.standard_normal(u.size)
    start = time.perf_counter()
    levels, warns = settled_levels([Record("log", dt, u, y)])
    settle = time.perf_counter() - start
    start = time.perf_counter()
    res = HistoryFit(types=("backlash", "backlash_inverse")).fit(levels, warns).result_
    fit = time.perf_counter() - start
    print(f"stage 1 from {n_levels:,} recorded levels ({u.size:,} samples): settled levels in {settle:.2f} s, "
          f"fit (both types, degrees 1-5) in {fit:.2f} s; {res.type}, dead band {res.dead_band:.4f} "
          f"[{res.ci['dead_band'][0]:.4f}, {res.ci['dead_band'][1]:.4f}] (truth 1.0)")


def main() -> None:
    ap = argparse.ArgumentParser()
    ap.add_argument("--rows", type=int, default=10_000_000)
    ap.add_argument("--levels", type=int, default=1000)
    args = ap.parse_args()
    bench_levels(args.levels)
    with tempfile.TemporaryDirectory() as tmp:
        bench_csv(args.rows, Path(tmp))


if __name__ == "__main__":
    from benchpage import run
    sys.exit(run("bench_recorded", "benchmarks/bench_recorded.py", main))
