"""Shared by the sweep experiments: run a batch, print a summary table, save figures."""
from __future__ import annotations

import os
import sys
from pathlib import Path

ROOT = Path(__file__).resolve().parents[1]
sys.path.insert(0, str(ROOT))


def run(sweeps, runs: int, jobs: int, out: Path, cfg_path: Path | None = None):
    import warnings
    warnings.simplefilter("ignore")
    from hwid import config
    from hwid.batch import run_batch
    from hwid.results import read_batch_summary
    cfg = config.load(cfg_path or ROOT / "configs" / "paper.yaml")
    path = run_batch(cfg, runs, out, sweeps, jobs=jobs, progress=True)
    return read_batch_summary(path), path


def table(summary, names, stats=("rmse", "coverage", "efficiency")) -> str:
    keys = summary["sweep_keys"]
    head = "| " + " | ".join(keys) + " | estimate | truth | bias | RMSE | coverage | CRLB eff. |"
    lines = [head, "|" + "---|" * (len(keys) + 6)]
    for p in summary["points"]:
        for n in names:
            s = p["stats"].get(n)
            if s is None:
                continue
            lines.append("| " + " | ".join(str(p["overrides"][k]) for k in keys) +
                         f" | {n} | {s['truth']:.4g} | {s['bias']:+.2e} | {s['rmse']:.2e} | "
                         f"{s.get('coverage', float('nan')):.3f} | {s.get('efficiency', float('nan')):.2f} |")
    return "\n".join(lines)


def mc_error(n: int, p: float = 0.95) -> float:
    """The Monte Carlo error of a coverage over ``n`` runs: two binomial standard deviations at ``p``."""
    import math
    return 2 * math.sqrt(p * (1 - p) / n) if n else float("nan")


def coverage_range(stats: dict, names) -> str:
    """``lo–hi`` of the coverages of ``names`` in one sweep point's stats (empty when none has one)."""
    cov = [stats[n]["coverage"] for n in names if n in stats and "coverage" in stats[n]]
    return f"{min(cov):.3f}–{max(cov):.3f}" if cov else ""


def seconds_per_run(path: Path, n_points: int) -> float:
    """Median seconds of one run (in its worker) over every point of ``batch.h5``."""
    import numpy as np
    from hwid.results import read_batch_runs
    sec = np.concatenate([read_batch_runs(path, i)["seconds"] for i in range(n_points)])
    return float(np.nanmedian(sec))


def save_figures(summary, out: Path, names_groups: dict):
    os.environ.setdefault("MPLBACKEND", "Agg")
    from hwid.report.figures import plot_batch_summary
    out.mkdir(parents=True, exist_ok=True)
    for stem, names in names_groups.items():
        fig = plot_batch_summary(summary, names)
        fig.savefig(out / f"{stem}.png", dpi=110)
        fig.savefig(out / f"{stem}.svg")
