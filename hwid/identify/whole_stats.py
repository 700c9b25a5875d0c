"""Numerical helpers of the whole-model fit's intervals (:mod:`hwid.identify.whole`): the residual's
correlation time and central differences."""
from __future__ import annotations

import numpy as np


def correlation_time(residual, lengths, max_lag: int = 100) -> float:
    """The residual's integrated autocorrelation time ``1 + 2 sum_k rho_k`` (samples), summed over
    lags until the autocorrelation first turns negative, pooled over the records (``lengths``):
    the factor by which correlated residuals carry less information than white ones."""
    pieces = np.split(np.asarray(residual, float), np.cumsum(lengths)[:-1])
    sums, counts = np.zeros(max_lag + 1), np.zeros(max_lag + 1)
    for e in pieces:
        e = e - e.mean()
        for lag in range(min(max_lag + 1, e.size)):
            sums[lag] += float(e[lag:] @ e[:e.size - lag])
            counts[lag] += e.size - lag
    if sums[0] <= 0:
        return 1.0
    rho = (sums / np.maximum(counts, 1)) / (sums[0] / counts[0])
    tau = 1.0
    for lag in range(1, max_lag + 1):
        if counts[lag] == 0 or rho[lag] <= 0:
            break
        tau += 2 * rho[lag]
    return float(tau)


def central_jacobian(fun, x, rel: float = 1e-6) -> np.ndarray:
    """Central-difference Jacobian of ``fun`` at ``x``."""
    f0 = fun(x)
    jac = np.empty((f0.size, x.size))
    for i in range(x.size):
        h = rel * max(abs(x[i]), 1e-3)
        e = np.zeros_like(x)
        e[i] = h
        jac[:, i] = (fun(x + e) - fun(x - e)) / (2 * h)
    return jac


def central_grad(g, x, rel: float = 1e-7) -> np.ndarray:
    """Gradient of the scalar ``g`` at ``x`` (central differences); returns ``(g(x), grad)``."""
    out = np.zeros_like(x)
    for i in range(x.size):
        h = rel * max(abs(x[i]), 1e-3)
        e = np.zeros_like(x)
        e[i] = h
        out[i] = (g(x + e) - g(x - e)) / (2 * h)
    return float(g(x)), out
