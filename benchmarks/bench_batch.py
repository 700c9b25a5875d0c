"""Monte Carlo batch throughput: the paper config, both stages, all five frequencies (issue 5).

Two measurements with :func:`hwid.batch.run_batch` (a local process pool, one writer):

1. the batch itself: ``--runs`` runs (default 1,000) with ``--jobs`` workers (default 2): wall time,
   runs per second, and the split of the per-run time between simulation and estimation (from the
   ``seconds_simulate`` / ``seconds_estimate`` that ``batch.h5`` stores per run);
2. scaling: ``--scaling-runs`` runs (default 100) with 1 worker, then with 2 workers; the factor is
   the ratio of the wall times.

CPU time (the workers' and the parent's) and the load average are printed as well: on a machine
shared with other work the wall times include their load, the CPU times do not. The workers run
one BLAS thread each (:func:`hwid.threads.limit_blas_threads`, as ``hwid batch`` does).

Usage::

    .venv/bin/python benchmarks/bench_batch.py                      # 1,000 runs + 100-run scaling
    .venv/bin/python benchmarks/bench_batch.py --runs 100 --scaling-runs 20
    .venv/bin/python benchmarks/bench_batch.py --runs 0             # scaling only

``--write`` also writes the output as its fragment of docs/validation/benchmarks.md.
"""
from __future__ import annotations

import argparse
import os
import platform
import shutil
import sys
import tempfile
import time
import warnings
from pathlib import Path

import numpy as np

from hwid import config
from hwid.batch import limit_blas_threads, run_batch, run_once
from hwid.results import read_batch_runs, read_batch_summary

ROOT = Path(__file__).resolve().parents[1]


def _cpu() -> float:
    """CPU seconds of this process and of its finished children (the pool's workers)."""
    t = os.times()
    return t.user + t.system + t.children_user + t.children_system


def measure(cfg, runs: int, jobs: int, out: Path) -> dict:
    """One batch of ``runs`` runs with ``jobs`` workers in a fresh directory."""
    if out.exists():
        shutil.rmtree(out)
    load0 = os.getloadavg()[0]
    c0, t0 = _cpu(), time.perf_counter()
    h5 = run_batch(cfg, runs, out, jobs=jobs, progress=False)
    wall = time.perf_counter() - t0
    cpu = _cpu() - c0
    r = read_batch_runs(h5)
    sim, est, per = r["seconds_simulate"], r["seconds_estimate"], r["seconds"]
    n_err = int(read_batch_summary(h5)["points"][0]["n_errors"])
    return {"runs": runs, "jobs": jobs, "wall": wall, "cpu": cpu, "sim": float(np.sum(sim)),
            "est": float(np.sum(est)), "per_run": float(np.mean(per)), "load": (load0, os.getloadavg()[0]),
            "errors": n_err}


def report(m: dict, title: str) -> None:
    busy = m["sim"] + m["est"]
    print(f"{title}: {m['runs']} runs, {m['jobs']} worker(s)")
    print(f"  wall time            {m['wall']:8.1f} s   ({m['runs'] / m['wall']:.2f} runs/s)")
    print(f"  CPU time             {m['cpu']:8.1f} s   ({m['cpu'] / m['runs']:.3f} s per run, workers + parent)")
    print(f"  per run (in worker)  {m['per_run']:8.3f} s   simulation {m['sim'] / m['runs']:.3f} s "
          f"({100 * m['sim'] / busy:.0f} %), estimation {m['est'] / m['runs']:.3f} s ({100 * m['est'] / busy:.0f} %)")
    print(f"  load average         {m['load'][0]:.2f} at start, {m['load'][1]:.2f} at end"
          + (f"; {m['errors']} run(s) stopped with an error" if m["errors"] else ""))


def main(argv=None) -> int:
    ap = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    ap.add_argument("--config", default=str(ROOT / "configs" / "paper.yaml"))
    ap.add_argument("--runs", type=int, default=1000, help="runs of the main batch (0: skip it)")
    ap.add_argument("--jobs", type=int, default=2, help="workers of the main batch")
    ap.add_argument("--scaling-runs", type=int, default=100, help="runs of each scaling batch (0: skip)")
    ap.add_argument("--out", default=None, help="directory for the batches (default: a temporary one)")
    args = ap.parse_args(argv)

    warnings.simplefilter("ignore")
    cfg = config.load(args.config)
    tmp = Path(args.out) if args.out else Path(tempfile.mkdtemp(prefix="hwid-bench-"))
    tmp.mkdir(parents=True, exist_ok=True)
    print(f"hwid batch benchmark: {cfg.name} ({Path(args.config).name}), both stages, "
          f"{len(cfg.protocols.sine.frequencies)} frequencies")
    print(f"machine: {platform.machine()}, {os.cpu_count()} cores, Python {platform.python_version()}, "
          f"numpy {np.__version__}; load average {os.getloadavg()[0]:.2f} before the warm-up")
    limit_blas_threads()                                     # as in the pool's workers
    t0 = time.process_time()
    run_once(cfg.source_text, np.random.SeedSequence(0))     # numba kernels: compile once, cached on disk
    print(f"warm-up run (numba cache): {time.process_time() - t0:.2f} s CPU")
    t0 = time.process_time()
    r = run_once(cfg.source_text, np.random.SeedSequence(1))
    print(f"one run in this process: {time.process_time() - t0:.3f} s CPU (simulation "
          f"{r['seconds_simulate']:.3f} s, estimation {r['seconds_estimate']:.3f} s wall)")
    print()
    try:
        if args.runs > 0:
            m = measure(cfg, args.runs, args.jobs, tmp / "main")
            report(m, "batch")
            per_core = m["cpu"] / m["runs"] / max(1, min(args.jobs, os.cpu_count() or 1))
            print(f"  -> 1,000 runs: {1000 * m['wall'] / m['runs'] / 60:.1f} min at this wall-clock rate, "
                  f"{1000 * per_core / 60:.1f} min from the CPU time on {args.jobs} free cores (goal: under 10 min)")
            print()
        if args.scaling_runs > 0:
            m1 = measure(cfg, args.scaling_runs, 1, tmp / "j1")
            report(m1, "scaling, J = 1")
            m2 = measure(cfg, args.scaling_runs, 2, tmp / "j2")
            report(m2, "scaling, J = 2")
            print(f"scaling 1 -> 2 workers: {m1['wall'] / m2['wall']:.2f}x wall time "
                  f"(goal >= 1.8x); CPU per run {m1['cpu'] / m1['runs']:.3f} s (J = 1), "
                  f"{m2['cpu'] / m2['runs']:.3f} s (J = 2)")
    finally:
        if not args.out:
            shutil.rmtree(tmp, ignore_errors=True)
    return 0


if __name__ == "__main__":
    from benchpage import run
    sys.exit(run("bench_batch", "benchmarks/bench_batch.py", main))
