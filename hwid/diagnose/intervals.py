"""Intervals of a fitted effect's own parameters (:func:`param_intervals`): the Gauss-Newton
covariance of the fit's residual at its optimum, with the model's re-estimated parameters (F's, G's)
fitted jointly and so marginalised, the residual's variance and its correlation time taken from the
residual itself.

For the fit's residual ``r(x)`` on the unit box ``x`` (log scale where a parameter spans decades,
:func:`hwid.diagnose.search.to_unit`), ``cov(x) = s^2 kappa_r (J^T J)^-1`` with ``J`` the central
finite-difference Jacobian (one-sided at a bound), ``s^2 = r^T r / (n - p)`` and ``kappa_r`` the
residual's integrated autocorrelation time in its own samples (a misfit leaves a residual far more
correlated than the noise, and its samples are not independent). The 95 % interval is
``x +- 1.96 sd`` mapped back to the parameter's units (asymmetric on a log scale), cut at the bounds.
A parameter whose interval would span more than half its range, or whose Jacobian column is null,
is undetermined by the fit experiments: its interval is null, with the reason.
"""
from __future__ import annotations

import numpy as np

from hwid.diagnose import search
from hwid.diagnose.gap import correlation_time

Z95 = 1.96
#: a parameter whose 95 % interval spans more than this share of its unit range is undetermined
UNDETERMINED_SPAN = 0.5


def param_intervals(residual, theta, lo, hi, logs, names, kappa_min: float = 1.0, step: float = 1e-3) -> dict:
    """``{name: [low, high] or None}`` for the first ``len(names)`` parameters of ``theta``, and
    ``{name: reason}`` under ``"undetermined"`` for each null one.

    Parameters
    ----------
    residual : callable
        ``residual(theta) -> r`` on the fit experiments (every parameter, the effect's first).
    theta, lo, hi : arrays
        The fit and its bounds.
    logs : tuple of bool
        Which parameters are fitted on a log scale.
    names : sequence of str
        The effect's own parameters.
    kappa_min : float
        The noise's correlation time in the residual's samples (the least ``kappa_r`` taken).
    step : float
        Finite-difference step on the unit box.
    """
    theta = np.asarray(theta, float)
    lo, hi = np.asarray(lo, float), np.asarray(hi, float)
    x0 = search.to_unit(theta, lo, hi, logs)
    r0 = np.asarray(residual(theta), float)
    p = theta.size
    J = np.zeros((r0.size, p))
    for j in range(p):
        if hi[j] <= lo[j]:
            continue
        a, b = max(x0[j] - step, 0.0), min(x0[j] + step, 1.0)
        xa, xb = x0.copy(), x0.copy()
        xa[j], xb[j] = a, b
        ra = r0 if a == x0[j] else residual(search.from_unit(xa, lo, hi, logs))
        rb = r0 if b == x0[j] else residual(search.from_unit(xb, lo, hi, logs))
        J[:, j] = (np.asarray(rb) - np.asarray(ra)) / max(b - a, 1e-15)
    n = r0.size
    s2 = float(r0 @ r0) / max(n - p, 1)
    kappa = max(float(correlation_time(r0)), float(kappa_min), 1.0)
    cov = np.full((p, p), np.inf)
    free = np.flatnonzero(np.any(J != 0.0, axis=0))
    if free.size:
        # by the singular values: a direction the residual does not see (a singular value below
        # 1e-8 of the largest) leaves every parameter it involves undetermined, not exact
        _, sv, Vt = np.linalg.svd(J[:, free], full_matrices=False)
        seen = sv > 1e-8 * sv[0] if sv.size and sv[0] > 0 else np.zeros(sv.size, bool)
        blind = np.any(np.abs(Vt[~seen]) > 1e-6, axis=0) if (~seen).any() else np.zeros(free.size, bool)
        V = Vt[seen].T / sv[seen]
        var = np.sum(V * V, axis=1) * s2 * kappa
        cov[free, free] = np.where(blind, np.inf, var)
    out, why = {}, {}
    for j, name in enumerate(names):
        sd = float(np.sqrt(cov[j, j])) if np.isfinite(cov[j, j]) and cov[j, j] >= 0 else np.inf
        if not np.isfinite(sd) or 2 * Z95 * sd > UNDETERMINED_SPAN:
            out[name] = None
            why[name] = ("the fit experiments do not move the residual with it" if not np.isfinite(sd) else
                         f"its 95 % interval spans {min(2 * Z95 * sd, 99.0):.2g} of its range: the fit experiments "
                         "do not determine it")
            continue
        ends = []
        for xj in (max(x0[j] - Z95 * sd, 0.0), min(x0[j] + Z95 * sd, 1.0)):
            x = x0.copy()
            x[j] = xj
            ends.append(float(search.from_unit(x, lo, hi, logs)[j]))
        out[name] = [min(ends), max(ends)]
    if why:
        out["undetermined"] = why
    return out


def forms_alike(best, fits, criterion, same_fit: float):
    """``best`` (a :class:`hwid.diagnose.verdict.Candidate`, one of an effect's forms ``fits``) with
    each form parameter (:meth:`Effect.form_params`: friction's ``fed_back``, the hysteresis's
    ``after_h``) in which another form that fits the fit experiments alike (its ``criterion`` within
    ``same_fit`` of ``best``'s) differs marked undetermined in its intervals: the experiments cannot
    tell where the effect acts, and the next experiment should."""
    mine = best.fitted.form_params()
    for other in fits:
        if other is best or criterion(other) - criterion(best) >= same_fit:
            continue
        theirs = other.fitted.form_params()
        for key in (k for k in mine if k in theirs and theirs[k] != mine[k]):
            best.intervals = dict(best.intervals or {})
            best.intervals[key] = None
            best.intervals.setdefault("undetermined", {})[key] = (
                f"the fit experiments fit {key} = {mine[key]:g} and {key} = {theirs[key]:g} alike (criteria "
                f"within {same_fit:g}); {mine[key]:g} is the lower")
    return best
