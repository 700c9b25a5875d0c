"""Accuracy against the noise level: 200 runs at each sigma in {0.001, 0.003, 0.01, 0.03, 0.1} of the
paper's plant (both stages, all five frequencies). Prints bias, RMSE, 95 % interval coverage and CRLB
efficiency of every estimate; saves figures in experiments/noise_sweep/results/.

    .venv/bin/python experiments/noise_sweep/run.py [--runs 200] [--jobs 2] [--out runs/noise_sweep]

Resumable: rerunning the same command computes only the missing runs.
"""
from __future__ import annotations

import argparse
import sys
from pathlib import Path

sys.path.insert(0, str(Path(__file__).resolve().parents[1]))
from sweep_common import ROOT, run, save_figures, table  # noqa: E402

SIGMAS = [0.001, 0.003, 0.01, 0.03, 0.1]
W = [0.01, 0.02, 0.05, 0.1, 0.2]


def main() -> int:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--runs", type=int, default=200)
    ap.add_argument("--jobs", type=int, default=2)
    ap.add_argument("--out", type=Path, default=ROOT / "runs" / "noise_sweep")
    a = ap.parse_args()
    summary, path = run([("plant.noise.std", SIGMAS)], a.runs, a.jobs, a.out)
    names1 = ["d_plus", "slope_down", "d_minus", "h_c1", "h_c3", "h_c5"]
    names2 = [f"{q}@{w:g}" for w in W for q in ("gain", "phase")]
    print(table(summary, names1 + names2))
    errs = {p["overrides"]["plant.noise.std"]: p["n_errors"] for p in summary["points"]}
    print(f"runs that failed (estimator refused the data) per sigma: {errs}")
    save_figures(summary, Path(__file__).parent / "results", {"stage1": names1, "stage2": names2})
    print(f"batch file: {path}; figures: experiments/noise_sweep/results/")
    return 0


if __name__ == "__main__":
    sys.exit(main())
