"""Monte Carlo coverage of stage 1 and of the whole fit: the figures the coverage tests assert on,
measured and printed (the tests stay tests; this script gives the docs their numbers).

- ``stage1``: tests/test_stage1_coverage.py's setup (the paper's h and backlash behind G = 5/(s+5),
  5 s holds, AR(1) noise with pole 0.5, degree and type fixed), the same seeds;
- ``history``: stage 1 from recorded levels in random order (tests/test_history.py's plant: backlash
  ±0.5 with S^d 1.3, G = 2/(s+2), cubic h, σ = 0.01, 30 levels), holds of 5–10 s and of 2–6 s; the
  coverage over the runs where an estimate is determined, with the count of undetermined ones;
- ``whole``: tests/test_whole_coverage.py's setup (24 random levels joined by ramps, the same
  seeds), and the same with 12 levels.

    python experiments/interval_coverage/run.py [--stage1 250] [--history 100] [--whole 200] [--write]

Each count is the number of noise realisations (0 skips that part). ``--write`` replaces the
fragments of docs/validation/monte-carlo.md (``docs/validation/generated/coverage_*.md``).
"""
from __future__ import annotations

import argparse
import sys
import time
import warnings
from pathlib import Path

import numpy as np
import yaml

ROOT = Path(__file__).resolve().parents[2]
sys.path[:0] = [str(ROOT), str(ROOT / "tests"), str(ROOT / "docs")]
import plants  # noqa: E402  (tests/plants.py: the tests' plant definitions)
import rigs  # noqa: E402  (tests/rigs.py)
from fragment import write  # noqa: E402
from hwid import config  # noqa: E402
from hwid.identify.history import identify_history  # noqa: E402
from hwid.identify.nonlinear import identify_nonlinear  # noqa: E402
from hwid.identify.whole import Structure, WholeModelFit  # noqa: E402
from hwid.model import from_config  # noqa: E402
from hwid.plant import Record, make_plant  # noqa: E402

DT = 0.05
SYMBOL = {"d_plus": "d^+", "slope_down": "S^d", "d_minus": "d^-", "dead_band": "dead band"}


def mc_error(n: int, p: float = 0.95) -> float:
    """Two binomial standard deviations of a coverage over ``n`` runs at ``p``."""
    return 2 * float(np.sqrt(p * (1 - p) / n))


def small_plant():
    """The plant of tests/test_history.py and tests/test_whole_coverage.py."""
    cfg = config.loads(yaml.safe_dump(rigs.small(**{"plant.output_nonlinearity.polynomial": [0, 1.0, 0.8, -0.6],
                                                    "plant.input_nonlinearity.slope_down": 1.3})))
    return from_config(cfg.plant)


def levels_with_ramps(rng, n_levels: int, hold: float, ramp: float, lo=-1.2, hi=1.2) -> np.ndarray:
    """Random levels joined by linear ramps (as tests/test_whole.py draws them)."""
    u, current = [], 0.0
    for _ in range(n_levels):
        target = rng.uniform(lo, hi)
        u += list(np.linspace(current, target, int(ramp / DT)))
        u += [target] * int(hold / DT)
        current = target
    return np.array(u)


def stage1(runs: int) -> dict:
    """Coverage of d^+, S^d, d^- over ``runs`` realisations (tests/test_stage1_coverage.py)."""
    cfg = config.loads(plants.config_text(plants.PAPER_FAST_G, name="coverage", seed=0,
                                          **{"plant.noise.ar": 0.5, "identification": {
                                              "nonlinear": {"degree": 5, "input_type": "backlash"}}}))
    truth = from_config(cfg.plant).normalised().input
    hits = dict.fromkeys(("d_plus", "slope_down", "d_minus"), 0)
    for ss in np.random.SeedSequence(20240905).spawn(runs):
        res, _ = identify_nonlinear(cfg, plant=make_plant(cfg, seed=ss))
        for k in hits:
            hits[k] += res.ci[k][0] <= getattr(truth, k) <= res.ci[k][1]
    return {"runs": runs, "coverage": {k: v / runs for k, v in hits.items()}}


def history(runs: int, shortest: int, longest: int) -> dict:
    """Coverage of the borders, the slope and the dead band from 30 levels in random order with
    holds of ``shortest``–``longest`` samples, and the share of runs called misfits."""
    truth = small_plant()
    norm = truth.normalised().input
    want = {"d_plus": norm.d_plus, "slope_down": norm.slope_down, "d_minus": norm.d_minus,
            "dead_band": norm.d_plus - norm.d_minus}
    hits, counted, misfits, shifted = dict.fromkeys(want, 0), dict.fromkeys(want, 0), 0, 0
    for seed in range(runs):
        rng = np.random.default_rng(seed)
        u = np.repeat(rng.uniform(-1.2, 1.2, 30), rng.integers(shortest, longest, 30))
        y = truth.simulate(u, DT, gear=0.0).x + 0.01 * rng.standard_normal(u.size)
        res = identify_history([Record("log", DT, u, y)], types=("backlash",))
        misfits += bool(res.misfit)
        shifted += any("reading is shifted" in w for w in res.warnings)
        for k, v in want.items():      # an undetermined estimate (interval None) is counted apart
            if res.ci[k] is not None:
                counted[k] += 1
                hits[k] += res.ci[k][0] <= v <= res.ci[k][1]
    return {"runs": runs, "coverage": {k: hits[k] / max(counted[k], 1) for k in want},
            "undetermined": {k: runs - counted[k] for k in want}, "shifted": shifted, "misfits": misfits / runs}


def whole(runs: int, n_levels: int) -> dict:
    """Coverage of the whole fit's borders (tests/test_whole_coverage.py with ``n_levels`` levels)."""
    norm = small_plant().normalised().input
    u = levels_with_ramps(np.random.default_rng(0), n_levels, 2.0, 0.5)
    x = small_plant().simulate(u, DT, gear=0.0).x
    hits = {"d_plus": 0, "d_minus": 0, "slope_down": 0}
    for seed in np.random.SeedSequence(2024).spawn(runs):
        y = x + 0.01 * np.random.default_rng(seed).standard_normal(u.size)
        res = WholeModelFit(max_degree=3, structures=[Structure(1, 0)], types=("backlash",)).fit(
            [Record("levels", DT, u, y)]).result_
        for k in hits:
            hits[k] += res.ci[k][0] <= getattr(norm, k) <= res.ci[k][1]
    return {"runs": runs, "coverage": {k: v / runs for k, v in hits.items()}}


def _cells(cov: dict, keys) -> str:
    return " | ".join(f"{100 * cov[k]:.1f} %" for k in keys)


def page_stage1(r: dict, seconds: float) -> str:
    keys = ("d_plus", "slope_down", "d_minus")
    return "\n".join([
        f"{r['runs']} noise realisations ({seconds / r['runs']:.2f} s each); a coverage's Monte Carlo error "
        f"is ±{100 * mc_error(r['runs']):.1f} % (2 sd of a binomial at 0.95).", "",
        "| " + " | ".join(f"coverage {SYMBOL[k]}" for k in keys) + " |", "|---|---|---|",
        "| " + _cells(r["coverage"], keys) + " |"])


def page_history(results: dict, seconds: float) -> str:
    keys = ("d_plus", "d_minus", "slope_down", "dead_band")
    runs = next(iter(results.values()))["runs"]
    lines = [f"{runs} runs at each hold length ({seconds / (2 * runs):.2f} s each); a coverage's Monte Carlo "
             f"error is ±{100 * mc_error(runs):.1f} %.", "",
             "| holds | " + " | ".join(f"coverage {SYMBOL[k]}" for k in keys) + " | called misfit |",
             "|---" * (len(keys) + 2) + "|"]
    for label, r in results.items():
        lines.append(f"| {label} | {_cells(r['coverage'], keys)} | {100 * r['misfits']:.1f} % |")
    lines.append("")
    lines.append("Coverage counts the runs where the estimate is determined; undetermined (h_bar's root-shifted "
                 "readings left open, hwid/identify/readings.py) and fits moved to the one reading by h^-1(0) = 0: "
                 + "; ".join(f"{label}: undetermined " + ", ".join(f"{SYMBOL[k]} {r['undetermined'][k]}" for k in keys)
                             + f", moved {r['shifted']}" for label, r in results.items()) + ".")
    return "\n".join(lines)


def page_whole(results: dict, seconds: float) -> str:
    keys = ("d_plus", "d_minus", "slope_down")
    runs = next(iter(results.values()))["runs"]
    lines = [f"{runs} noise realisations at each number of levels ({seconds / (2 * runs):.2f} s each); a "
             f"coverage's Monte Carlo error is ±{100 * mc_error(runs):.1f} %.", "",
             "| levels | " + " | ".join(f"coverage {SYMBOL[k]}" for k in keys) + " |", "|---" * (len(keys) + 1) + "|"]
    for n, r in results.items():
        lines.append(f"| {n} | {_cells(r['coverage'], keys)} |")
    return "\n".join(lines)


def main(argv=None) -> int:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--stage1", type=int, default=250, help="realisations for stage 1 (0: skip)")
    ap.add_argument("--history", type=int, default=100, help="realisations per hold length (0: skip)")
    ap.add_argument("--whole", type=int, default=200, help="realisations per number of levels (0: skip)")
    ap.add_argument("--write", action="store_true", help="write the docs page's fragments (docs/validation/generated/)")
    a = ap.parse_args(argv)
    warnings.simplefilter("ignore")
    script = "experiments/interval_coverage/run.py"
    parts = []
    if a.stage1:
        parts.append(("coverage_stage1", page_stage1, lambda: stage1(a.stage1)))
    if a.history:
        parts.append(("coverage_history", page_history,
                      lambda: {"5–10 s": history(a.history, 100, 200), "2–6 s": history(a.history, 40, 120)}))
    if a.whole:
        parts.append(("coverage_whole", page_whole, lambda: {24: whole(a.whole, 24), 12: whole(a.whole, 12)}))
    for name, page, compute in parts:
        t0 = time.perf_counter()
        md = page(compute(), time.perf_counter() - t0)
        print(f"== {name} ({time.perf_counter() - t0:.0f} s)\n{md}\n", flush=True)
        if a.write:
            print(f"wrote {write(name, md, script)}", flush=True)
    return 0


if __name__ == "__main__":
    sys.exit(main())
