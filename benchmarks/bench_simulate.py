"""Simulation throughput: backlash (eq. 1) + G (eq. 3b, exact ZOH) + h (eq. 3c) + noise, in samples/s.

Times hwid's SimulatedPlant.run (the chain and its white noise, drawn in the chain's pass from the
experiment's numpy Generator, the Record) beside the chain alone (HWModel.simulate, no noise), best
of five, checks the goal (with noise >= 5*10^7 samples/s at 10^6 and 10^7 samples), and times a
plain Python loop of the same chain with noise (run on 2*10^5 samples and reported per sample).
Single-threaded; on a shared machine pin it to one core (``taskset -c 1``) and take the best of a
few invocations.
Usage: ``.venv/bin/python benchmarks/bench_simulate.py [--write]``; ``--write`` also writes its output as the fragment of docs/validation/benchmarks.md
"""
from __future__ import annotations

import os
import platform
import sys
import time

os.environ.setdefault("NUMBA_NUM_THREADS", "1")
os.environ.setdefault("OMP_NUM_THREADS", "1")

import numba  # noqa: E402
import numpy as np  # noqa: E402
from scipy import linalg, signal  # noqa: E402

from hwid.blocks.linear import LinearBlock  # noqa: E402
from hwid.blocks.static import PolynomialH  # noqa: E402
from hwid.model import HWModel, InputNonlinearity  # noqa: E402
from hwid.plant import SimulatedPlant  # noqa: E402

MODEL = HWModel(InputNonlinearity("backlash", 1.0, 1.0, 0.5, -0.5), LinearBlock((0.2,), (1.0, 0.7, 0.1)),
                PolynomialH((0, 0.25, 0, -0.42, 0, 0.2)))
DT = 0.01
GOAL = 5e7          # samples/s with white noise, at 10^6 and at 10^7 samples


def plain_python(u):
    A, B, C, D = signal.tf2ss([0.2], [1.0, 0.7, 0.1])
    M = np.zeros((3, 3)); M[:2, :2] = A; M[:2, 2] = B[:, 0]
    E = linalg.expm(M * DT)
    Phi, Gam = E[:2, :2].tolist(), E[:2, 2].tolist()
    c = C[0].tolist()
    rng = np.random.default_rng(0)
    e = rng.standard_normal(len(u)).tolist()
    v = 0.0
    x = [0.0, 0.0]
    y = []
    for k, uk in enumerate(u):
        v = min(max(v, uk - 0.5), uk + 0.5)
        w = c[0] * x[0] + c[1] * x[1]
        y.append(0.25 * w - 0.42 * w ** 3 + 0.2 * w ** 5 + 0.01 * e[k])
        x = [Phi[0][0] * x[0] + Phi[0][1] * x[1] + Gam[0] * v, Phi[1][0] * x[0] + Phi[1][1] * x[1] + Gam[1] * v]
    return y


def best_of(f, repeats: int = 5) -> float:
    """The shortest of ``repeats`` wall times of ``f()``, in seconds."""
    best = np.inf
    for _ in range(repeats):
        t0 = time.perf_counter()
        f()
        best = min(best, time.perf_counter() - t0)
    return best


def main():
    print(f"machine: {platform.platform()}, {platform.machine()}, {os.cpu_count()} cores, Python "
          f"{platform.python_version()}, numpy {np.__version__}, numba {numba.__version__}; single-threaded")
    plant = SimulatedPlant(MODEL, DT, noise_std=0.01, seed=0)
    plant.run("warmup", np.sin(np.arange(1000) * 0.01))           # numba compile / cache load
    MODEL.simulate(np.sin(np.arange(1000) * 0.01), DT)
    print(f"{'samples':>10} {'run s':>8} {'with noise /s':>14} {'chain s':>8} {'chain alone /s':>15}")
    rates = []
    for n in (10**6, 10**7):
        u = 1.5 * np.sin(np.arange(n) * DT * 0.2)
        t_run = best_of(lambda: plant.run("bench", u))
        t_chain = best_of(lambda: MODEL.simulate(u, DT))
        rates.append(n / t_run)
        print(f"{n:>10.0e} {t_run:8.3f} {n / t_run:14.3e} {t_chain:8.3f} {n / t_chain:15.3e}")
    verdict = "met" if min(rates) >= GOAL else "NOT met"
    print(f"goal with noise >= {GOAL:.0e} samples/s at 1e6 and 1e7: {verdict} (lowest {min(rates):.3e})")
    n = 200_000
    u = 1.5 * np.sin(np.arange(n) * DT * 0.2)
    t0 = time.perf_counter()
    plain_python(u)
    tp = time.perf_counter() - t0
    print(f"plain Python loop: {n / tp:.3e} samples/s (on {n} samples)")


if __name__ == "__main__":
    from benchpage import run
    sys.exit(run("bench_simulate", "benchmarks/bench_simulate.py", main))
