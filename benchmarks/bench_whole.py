"""The whole-model output-error fit's speed: one fit (F, a first-order G, h_bar of degree 3, the
record's initial state) on 10^5 samples of random levels joined by ramps, to convergence, on one
core; and the chain's simulation alone (no noise) per sample.

Usage: ``.venv/bin/python benchmarks/bench_whole.py [--write]``; ``--write`` also writes its output as the fragment of docs/validation/benchmarks.md
"""
from __future__ import annotations

import os
import platform
import sys
import time

os.environ.setdefault("NUMBA_NUM_THREADS", "1")
os.environ.setdefault("OMP_NUM_THREADS", "1")
os.environ.setdefault("OPENBLAS_NUM_THREADS", "1")

import numpy as np  # noqa: E402

from hwid.blocks.linear import LinearBlock  # noqa: E402
from hwid.blocks.static import PolynomialH  # noqa: E402
from hwid.identify.whole import Structure, WholeModelFit  # noqa: E402
from hwid.model import HWModel, InputNonlinearity  # noqa: E402
from hwid.plant import Record  # noqa: E402

TRUTH = HWModel(InputNonlinearity("backlash", 1.0, 1.3, 0.5, -0.5), LinearBlock((2.0,), (1.0, 2.0)),
                PolynomialH((0.0, 0.5, 0.2, -0.075)))
DT = 0.05


def levels_with_ramps(rng, n_samples: int) -> np.ndarray:
    u, current = [], 0.0
    while len(u) < n_samples:
        target = rng.uniform(-1.2, 1.2)
        u += list(np.linspace(current, target, 20)) + [target] * 120
        current = target
    return np.array(u[:n_samples])


def main():
    print(f"machine: {platform.machine()}, {os.cpu_count()} cores, Python {platform.python_version()}, "
          f"numpy {np.__version__}; one thread")
    rng = np.random.default_rng(1)
    u = levels_with_ramps(rng, 100_000)
    y = TRUTH.simulate(u, DT, gear=0.0).x + 0.01 * rng.standard_normal(u.size)
    records = [Record("levels", DT, u, y)]
    WholeModelFit(max_degree=1, structures=[Structure(1, 0)], types=("backlash",), max_nfev=2).fit(
        [Record("warm", DT, u[:500], y[:500])])                  # numba kernels compiled or loaded
    t0 = time.perf_counter()
    fit = WholeModelFit(max_degree=3, structures=[Structure(1, 0)], types=("backlash",))
    fit.problem_ = None
    from hwid.identify.whole_problem import Problem
    prob = Problem(records, "backlash", Structure(1, 0), 3, False)
    theta0 = fit.start_values(records, "backlash", Structure(1, 0), None)
    from scipy import optimize
    lo, hi = prob.bounds(float(np.ptp(u)), u.size * DT, DT)
    sol = optimize.least_squares(prob.residual, np.clip(theta0, lo + 1e-9, hi - 1e-9), bounds=(lo, hi),
                                 method="trf", x_scale=1.0, max_nfev=200)
    one = time.perf_counter() - t0
    print(f"one output-error fit on {u.size:.0e} samples (degree 3, first-order G, from the border grid): "
          f"{one:.2f} s, {sol.nfev} residual evaluations, cost {2 * sol.cost:.4g} (noise floor "
          f"{u.size * 1e-4:.4g})")
    t0 = time.perf_counter()
    res = WholeModelFit(max_degree=4, structures=[Structure(1, 0), Structure(2, 0)], types=("backlash",)).fit(records).result_
    full = time.perf_counter() - t0
    print(f"full selection (2 G structures x degrees 1-4, intervals): {full:.1f} s; chosen {res.structure}, "
          f"degree {len(res.h_coefficients) - 1}, sigma {res.sigma:.4g} (truth 0.01)")
    n = 10**7
    u_long = 1.5 * np.sin(np.arange(n) * DT * 0.02)
    best = np.inf
    for _ in range(3):
        t0 = time.perf_counter()
        TRUTH.simulate(u_long, DT)
        best = min(best, time.perf_counter() - t0)
    print(f"chain simulation without noise: {n / best:.3e} samples/s ({n:.0e} samples)")


if __name__ == "__main__":
    from benchpage import run
    sys.exit(run("bench_whole", "benchmarks/bench_whole.py", main))
