"""The diagnosis's joint fits (an effect with F, G and h re-estimated, as for a model identified on
the plant): time per residual evaluation, h's design matrix built on the scored samples only
(:meth:`hwid.diagnose.rank.EffectFitter._residual`) against built on whole experiments and then
masked; and h's Legendre basis, :func:`hwid.blocks.static.legendre_vander` against numpy's
``legvander``. One core; 12 experiments of 3,000 samples, 30 % of each unscored (the lead-in).

Usage: ``.venv/bin/python benchmarks/bench_joint_fit.py [--write]``; ``--write`` also writes its output as the fragment of docs/validation/benchmarks.md
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
from hwid.blocks.static import PolynomialH, legendre_vander  # noqa: E402
from hwid.diagnose.effects import InputDeadzone, Scale, SensorLag, SensorSaturation  # noqa: E402
from hwid.diagnose.modelsim import ModelSim  # noqa: E402
from hwid.diagnose.rank import EffectFitter  # noqa: E402
from hwid.model import HWModel, InputNonlinearity  # noqa: E402

DT = 0.02
MODEL = HWModel(InputNonlinearity("backlash", 1.0, 1.0, 0.3, -0.3), LinearBlock((0.75, 0.13), (1.0, 1.7, 1.1, 0.13)),
                PolynomialH((0.0, 0.5, 0.0, -0.3, 0.0, 0.1, 0.0, -0.01)))


def fitter() -> EffectFitter:
    rng = np.random.default_rng(np.random.SeedSequence(7))
    t = np.arange(3000) * DT
    us = [1.4 * np.sin(2 * np.pi * t / p) * np.minimum(t / 10.0, 1.0) for p in np.geomspace(4.0, 60.0, 12)]
    sim = ModelSim(MODEL, DT, us)
    ys = [x + 0.01 * rng.standard_normal(x.size) for x in sim.x]
    masks = [t >= 18.0 for _ in us]
    xs = np.concatenate(sim.x)
    sc = Scale(DT, -1.4, 1.4, float(xs.min()), float(xs.max()), 1.1, 4.0, 1.0, float(t[-1]))
    return EffectFitter(sim, ys, masks, sim, ys, masks, [f"e{k}" for k in range(12)], sc, 0.01, 1.0,
                        refit_h=True, refit_g=True)


def per_call(fn, repeat: int = 5, number: int = 20) -> float:
    best = np.inf
    for _ in range(repeat):
        t0 = time.perf_counter()
        for _ in range(number):
            fn()
        best = min(best, (time.perf_counter() - t0) / number)
    return best


def main() -> None:
    print(f"machine: {platform.platform()}, {platform.machine()}, {os.cpu_count()} cores, "
          f"Python {platform.python_version()}, numpy {np.__version__}; single-threaded")
    f = fitter()
    print(f"{'effect':<18} {'scored only ms':>15} {'whole, masked ms':>17} {'ratio':>6}")
    for eff, own in ((InputDeadzone(), [0.05, 0.0]), (SensorLag(), [0.4, 0.0]), (SensorSaturation(), [-0.6, 0.7])):
        theta = np.r_[own, f.g_p]

        def whole():
            xs = f._refit_predict(eff, theta, "fit")
            return np.concatenate([((y - x)[m])[::f.stride] for y, x, m in zip(f.yf, xs, f.mf)])
        np.testing.assert_allclose(f._residual(eff, theta), whole(), rtol=0, atol=1e-10)
        a, b = per_call(lambda: f._residual(eff, theta)), per_call(whole)
        print(f"{eff.name:<18} {1e3 * a:>15.2f} {1e3 * b:>17.2f} {a / b:>6.2f}")
    x = np.random.default_rng(1).uniform(-1.0, 1.0, 3000)
    legendre_vander(x, 7)       # compiled (or loaded from numba's cache) before timing
    a = per_call(lambda: legendre_vander(x, 7), number=2000)
    b = per_call(lambda: np.polynomial.legendre.legvander(x, 7), number=2000)
    print(f"h's basis, degree 7, 3,000 samples: legendre_vander {1e6 * a:.1f} us, numpy legvander {1e6 * b:.1f} us "
          f"({b / a:.1f}x)")


if __name__ == "__main__":
    from benchpage import run
    sys.exit(run("bench_joint_fit", "benchmarks/bench_joint_fit.py", main))
