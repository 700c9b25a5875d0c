"""Accuracy against the number of averaged periods N (eq. 23a), for both stage-2 estimators.

The paper uses N = 50 periods (50 x 628 s at 0.01 rad/s: almost nine hours on a rig). This sweeps
N in {2, 5, 10, 20, 50} crossed with ``identification.linear.method`` in {nls, paper} and prints, for
each estimator, the smallest N whose RMSE at every frequency is below the paper's own Table 2 error.

    .venv/bin/python experiments/periods_sweep/run.py [--runs 50] [--jobs 2] [--out runs/periods_sweep] [--write]

Resumable like every batch. ``--write`` replaces the table of docs/validation/monte-carlo.md
(``docs/validation/generated/periods_sweep.md``).
"""
from __future__ import annotations

import argparse
import sys
from pathlib import Path

sys.path.insert(0, str(Path(__file__).resolve().parents[1]))
from sweep_common import ROOT, coverage_range, mc_error, run, save_figures, seconds_per_run, table  # noqa: E402

sys.path.insert(0, str(ROOT / "docs"))
from fragment import write  # noqa: E402

PERIODS = [2, 5, 10, 20, 50]
W = [0.01, 0.02, 0.05, 0.1, 0.2]
# the paper's Table 2 errors |estimate - truth| (phase, gain) at each frequency
PAPER_ERR = {0.01: (0.005, 0.012), 0.02: (0.007, 0.02), 0.05: (0.01, 0.01), 0.1: (0.02, 0.02), 0.2: (0.03, 0.03)}


def worst_ratio(stats: dict) -> float:
    """The largest RMSE / the paper's Table 2 error over every (omega, gain|phase)."""
    return max(stats[f"{q}@{w:g}"]["rmse"] / PAPER_ERR[w][i]
               for w in W for i, q in enumerate(("phase", "gain")) if f"{q}@{w:g}" in stats)


def page(summary: dict, runs: int, seconds: float) -> str:
    """The page's table: per N, the RMSE of the headline estimates and the range of the 95 %
    coverages over every frequency for each estimator; then the smallest N reaching the paper's
    Table 2 accuracy."""
    by = {(p["overrides"]["protocols.sine.periods"], p["overrides"]["identification.linear.method"]): p
          for p in summary["points"]}
    names = [f"{q}@{w:g}" for w in W for q in ("gain", "phase")]
    err = lambda p, n: f"{p['stats'][n]['rmse']:.1e}" if n in p["stats"] else ""  # noqa: E731
    lines = [f"{runs} runs at each (N, estimator) ({seconds:.2f} s a run, median); a coverage's Monte Carlo "
             f"error is ±{mc_error(runs):.3f} (2 sd of a binomial at 0.95). Runs refused by an estimator: "
             f"{sum(p['n_errors'] for p in summary['points'])} of {runs * len(summary['points'])}.", "",
             "| N | nls RMSE \\|G(j0.2)\\| | nls RMSE φ(0.2) | nls RMSE \\|G(j0.01)\\| | paper-eq.(37) RMSE \\|G(j0.2)\\| "
             "| nls coverage | paper-eq.(37) coverage | worst RMSE / paper's error, nls / eq. (37) |",
             "|---|---|---|---|---|---|---|---|"]
    for N in PERIODS:
        n, q = by[(N, "nls")], by[(N, "paper")]
        lines.append(f"| {N} | {err(n, 'gain@0.2')} | {err(n, 'phase@0.2')} | {err(n, 'gain@0.01')} | "
                     f"{err(q, 'gain@0.2')} | {coverage_range(n['stats'], names)} | "
                     f"{coverage_range(q['stats'], names)} | {worst_ratio(n['stats']):.2f} / {worst_ratio(q['stats']):.2f} |")
    first = {m: next((N for N in PERIODS if worst_ratio(by[(N, m)]["stats"]) <= 1), None) for m in ("nls", "paper")}
    lines += ["", "The paper's Table 2 accuracy (every RMSE at most the paper's own error) is reached from "
              + "; ".join(f"{label}: {'N = ' + str(first[m]) if first[m] else 'none of the swept N'}"
                          for m, label in (("nls", "nls"), ("paper", "eq. (37)"))) + "."]
    return "\n".join(lines)


def main() -> int:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--runs", type=int, default=50)
    ap.add_argument("--jobs", type=int, default=2)
    ap.add_argument("--out", type=Path, default=ROOT / "runs" / "periods_sweep")
    ap.add_argument("--write", action="store_true", help="write the docs page's table (docs/validation/generated/)")
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
        ratio = worst_ratio(p["stats"])
        print(f"| {m} | {N} | {ratio:.3f} | {ratio <= 1} |")
        if ratio <= 1 and m not in first:
            first[m] = N
    for m in ("nls", "paper"):
        print(f"{m}: the paper's Table 2 accuracy is reached from N = {first.get(m, 'none of the swept')} periods")
    if a.write:
        md = page(summary, a.runs, seconds_per_run(path, len(summary["points"])))
        print(md)
        print(f"wrote {write('periods_sweep', md, 'experiments/periods_sweep/run.py')}")
    save_figures(summary, Path(__file__).parent / "results", {"stage2": names})
    print(f"batch file: {path}")
    return 0


if __name__ == "__main__":
    sys.exit(main())
