"""Levenberg-Marquardt with an analytic Jacobian, with little overhead per iteration.

Stage 1 solves hundreds of small problems per run (eqs. 11-14 for every candidate degree, type and
horizontal path) and stage 2 a few hundred two-parameter fits (eq. 20 for every stage-1
perturbation), so the Python overhead of :func:`scipy.optimize.least_squares` (about 80 us per
iteration) dominates their cost. :func:`lm` calls the same MINPACK ``lmder`` routine that
``least_squares(method="lm", x_scale="jac")`` calls, with the same arguments (``factor = 100``,
``diag = None``: scaling by the Jacobian's column norms), through :func:`scipy.optimize.leastsq`;
given the same residual and Jacobian functions the iterates are the same.
"""
from __future__ import annotations

from typing import Callable

import numpy as np
from scipy import optimize


def lm(fun: Callable, jac: Callable, x0, ftol: float = 1e-8, xtol: float = 1e-8, gtol: float = 1e-8,
       max_nfev: int | None = None) -> tuple[np.ndarray, float, int]:
    """Minimise ``||fun(x)||^2`` from ``x0``; return ``(x, cost, status)``.

    ``cost = ||fun(x)||^2 / 2`` as in ``least_squares``; ``status`` is MINPACK's ``info`` (1-4:
    converged, 5: ``max_nfev`` reached). ``jac(x)`` returns the ``(m, n)`` Jacobian. Raises
    ``ValueError`` where ``least_squares`` would: a non-finite start or non-finite residuals there.
    """
    x0 = np.array(x0, dtype=float).ravel()
    if not np.all(np.isfinite(x0)):
        raise ValueError("x0 must be finite")
    if not np.all(np.isfinite(fun(x0))):
        raise ValueError("Residuals are not finite in the initial point.")
    x, _, info, _, status = optimize.leastsq(fun, x0, Dfun=jac, full_output=True, ftol=ftol, xtol=xtol,
                                             gtol=gtol, maxfev=max_nfev or 100 * x0.size, factor=100,
                                             diag=None)
    f = info["fvec"]
    return np.asarray(x, float), 0.5 * float(np.dot(f, f)), int(status)
