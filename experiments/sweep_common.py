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


def save_figures(summary, out: Path, names_groups: dict):
    os.environ.setdefault("MPLBACKEND", "Agg")
    from hwid.report.figures import plot_batch_summary
    out.mkdir(parents=True, exist_ok=True)
    for stem, names in names_groups.items():
        fig = plot_batch_summary(summary, names)
        fig.savefig(out / f"{stem}.png", dpi=110)
        fig.savefig(out / f"{stem}.svg")
