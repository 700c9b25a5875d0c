"""Accuracy against the number of averaged periods N (eq. 23a), for both stage-2 estimators.

The paper uses N = 50 periods (50 x 628 s at 0.01 rad/s: almost nine hours on a rig). This sweeps
N in {2, 5, 10, 20, 50} crossed with ``identification.linear.method`` in {nls, paper} and prints, for
each estimator, the smallest N whose RMSE at every frequency is below the paper's own Table 2 error.

    .venv/bin/python experiments/periods_sweep/run.py [--runs 50] [--jobs 2] [--out runs/periods_sweep]
"""
from __future__ import annotations

import argparse
import sys
from pathlib import Path

sys.path.insert(0, str(Path(__file__).resolve().parents[1]))
from sweep_common import ROOT, run, save_figures, table  # noqa: E402

PERIODS = [2, 5, 10, 20, 50]
W = [0.01, 0.02, 0.05, 0.1, 0.2]
# the paper's Table 2 errors |estimate - truth| (phase, gain) at each frequency
PAPER_ERR = {0.01: (0.005, 0.012), 0.02: (0.007, 0.02), 0.05: (0.01, 0.01), 0.1: (0.02, 0.02), 0.2: (0.03, 0.03)}


def main() -> int:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--runs", type=int, default=50)
    ap.add_argument("--jobs", type=int, default=2)
    ap.add_argument("--out", type=Path, default=ROOT / "runs" / "periods_sweep")
    a = ap.parse_args()
    summary, path = run([("protocols.sine.periods", PERIODS), ("identification.linear.method", ["nls", "paper"])],
                        a.runs, a.jobs, a.out)
    names = [f"{q}@{w:g}" for w in W for q in ("gain", "phase")]
    print(table(summary, names))
    print()
    print("| estimator | N | worst RMSE / paper error over all (omega, gain|phase) | reaches the paper's accuracy |")
    print("|---|---|---|---|")
    first = {}
    for p in summary["points"]:
        N, m = p["overrides"]["protocols.sine.periods"], p["overrides"]["identification.linear.method"]
        ratio = max(p["stats"][f"{q}@{w:g}"]["rmse"] / PAPER_ERR[w][i]
                    for w in W for i, q in enumerate(("phase", "gain")) if f"{q}@{w:g}" in p["stats"])
        print(f"| {m} | {N} | {ratio:.3f} | {ratio <= 1} |")
        if ratio <= 1 and m not in first:
            first[m] = N
    for m in ("nls", "paper"):
        print(f"{m}: the paper's Table 2 accuracy is reached from N = {first.get(m, 'none of the swept')} periods")
    save_figures(summary, Path(__file__).parent / "results", {"stage2": names})
    print(f"batch file: {path}")
    return 0


if __name__ == "__main__":
    sys.exit(main())
