"""Accuracy against the noise level: 200 runs at each sigma in {0.001, 0.003, 0.01, 0.03, 0.1} of the
paper's plant (both stages, all five frequencies). Prints bias, RMSE, 95 % interval coverage and CRLB
efficiency of every estimate; saves figures in experiments/noise_sweep/results/.

    .venv/bin/python experiments/noise_sweep/run.py [--runs 200] [--jobs 2] [--out runs/noise_sweep] [--write]

Resumable: rerunning the same command computes only the missing runs. ``--write`` replaces the
table of docs/validation/monte-carlo.md (``docs/validation/generated/noise_sweep.md``).
"""
from __future__ import annotations

import argparse
import math
import sys
from pathlib import Path

sys.path.insert(0, str(Path(__file__).resolve().parents[1]))
from sweep_common import ROOT, coverage_range, mc_error, run, save_figures, seconds_per_run, table  # noqa: E402

sys.path.insert(0, str(ROOT / "docs"))
from fragment import write  # noqa: E402

SIGMAS = [0.001, 0.003, 0.01, 0.03, 0.1]
W = [0.01, 0.02, 0.05, 0.1, 0.2]
NAMES1 = ["d_plus", "slope_down", "d_minus", "h_c1", "h_c3", "h_c5"]
NAMES2 = [f"{q}@{w:g}" for w in W for q in ("gain", "phase")]
# the page's columns: (estimate, heading)
COLUMNS = [("d_plus", "d^+"), ("slope_down", "S^d"), ("d_minus", "d^-"), ("h_c5", "c_5 (6.4)"),
           ("gain@0.01", "\\|G(j0.01)\\|"), ("phase@0.01", "φ(0.01)"), ("gain@0.2", "\\|G(j0.2)\\|"),
           ("phase@0.2", "φ(0.2)")]


def page(summary: dict, runs: int, seconds: float) -> str:
    """The page's table (RMSE of the headline estimates and the range of every 95 % interval's
    coverage at each sigma) and a line on how the errors scale with sigma."""
    pts = summary["points"]
    lines = [f"{runs} runs at each σ ({seconds:.2f} s a run, median); a coverage's Monte Carlo error "
             f"is ±{mc_error(runs):.3f} (2 sd of a binomial at 0.95). Runs refused by an estimator: "
             + ", ".join(f"{p['n_errors']} at σ = {p['overrides']['plant.noise.std']:g}" for p in pts) + ".", "",
             "| σ | " + " | ".join(f"RMSE {h}" for _, h in COLUMNS) + " | 95 % coverage, all estimates |",
             "|---" * (len(COLUMNS) + 2) + "|"]
    for p in pts:
        st = p["stats"]
        cells = [f"{st[n]['rmse']:.1e}" if n in st else "" for n, _ in COLUMNS]
        lines.append(f"| {p['overrides']['plant.noise.std']:g} | " + " | ".join(cells)
                     + f" | {coverage_range(st, NAMES1 + NAMES2)} |")
    names = [n for n in NAMES1 + NAMES2 if all(n in p["stats"] for p in pts)]
    per_sigma = {n: [p["stats"][n]["rmse"] / p["overrides"]["plant.noise.std"] for p in pts] for n in names}
    spread = max(max(v) / min(v) for v in per_sigma.values())
    # bias in standard errors of the mean: without bias each is about N(0, 1), so the largest of
    # m of them is about sqrt(2 ln m)
    z = max(abs(p["stats"][n]["bias"]) / (p["stats"][n]["std"] / math.sqrt(p["stats"][n]["n"]))
            for p in pts for n in names)
    m = len(pts) * len(names)
    lines += ["", f"Over σ = {pts[0]['overrides']['plant.noise.std']:g}–{pts[-1]['overrides']['plant.noise.std']:g}, "
                  f"RMSE / σ of every estimate stays within a factor {spread:.2f} of its smallest value "
                  f"(1 would be exact proportion). The largest \\|bias\\| of the {m} (estimate, σ) pairs is "
                  f"{z:.1f} standard errors of the mean (about {math.sqrt(2 * math.log(m)):.1f} expected by chance "
                  "without bias)."]
    return "\n".join(lines)


def main() -> int:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--runs", type=int, default=200)
    ap.add_argument("--jobs", type=int, default=2)
    ap.add_argument("--out", type=Path, default=ROOT / "runs" / "noise_sweep")
    ap.add_argument("--write", action="store_true", help="write the docs page's table (docs/validation/generated/)")
    a = ap.parse_args()
    summary, path = run([("plant.noise.std", SIGMAS)], a.runs, a.jobs, a.out)
    print(table(summary, NAMES1 + NAMES2))
    errs = {p["overrides"]["plant.noise.std"]: p["n_errors"] for p in summary["points"]}
    print(f"runs that failed (estimator refused the data) per sigma: {errs}")
    if a.write:
        md = page(summary, a.runs, seconds_per_run(path, len(summary["points"])))
        print(md)
        print(f"wrote {write('noise_sweep', md, 'experiments/noise_sweep/run.py')}")
    save_figures(summary, Path(__file__).parent / "results", {"stage1": NAMES1, "stage2": NAMES2})
    print(f"batch file: {path}; figures: experiments/noise_sweep/results/")
    return 0


if __name__ == "__main__":
    sys.exit(main())
