"""Likelihood-ratio (profile) intervals of stage 1's borders from a recorded history.

Why not the Gauss-Newton (delta-method) interval: F's steady recursion (eqs. 7a-b, 14a-b) is
piecewise in the borders. A level whose input sits just past a border moves the gear, one just short
of it leaves the gear where it was; the weighted chi-square of :mod:`hwid.identify.history` has a
corner there, and a least-squares optimum often sits on such a corner. Its Jacobian is then one
side's derivative, and the curvature it gives can be many times the other side's: on 100 random-order
logs of tests/test_history.py's plant (5-10 s holds) the standardised errors ``(estimate - truth) / sd``
had sd 1.12-1.28 with outliers at 5 (the truth at a chi-square rise of 0.46 where the Gauss-Newton
interval put it 5 sd away), while the levels' own standardised errors had sd 1.02.

The profile interval does not linearise: for each reported quantity ``q`` (d^+, ln S^d, ln(d^+ - d^-),
d^-), ``chi2_min(q)`` is the weighted chi-square with every other parameter (the other borders, the
gear's start inside the play, h_bar by variable projection) fitted again, and the interval is
``{q : chi2_min(q) - chi2_min <= z^2 b}`` with z the normal 0.975 quantile and ``b = max(1, chi2/dof)``
the Birge ratio that also widens the Gauss-Newton covariance (Venzon & Moolgavkar 1988; the same
construction as lmfit's ``conf_interval``). It is invariant to reparametrisation (the interval of
ln S^d gives that of S^d), follows a corner's two sides, and where the chi-square never rises by
that much inside the search range the side is reported as not bounded (None), never clipped there.
"""
from __future__ import annotations

from dataclasses import dataclass
from typing import Callable

import numpy as np
from scipy import optimize

#: doublings of the first step (the Gauss-Newton standard deviation) tried before a side is unbounded
MAX_DOUBLINGS = 14
#: relative tolerance of the crossing point, in units of the first step
XTOL = 1e-3


@dataclass(frozen=True)
class Coordinate:
    """One reported quantity as a coordinate of the parameter vector ``theta``.

    ``value(theta)`` reads it; ``build(value, free)`` gives ``theta`` with it fixed at ``value`` and
    the other parameters ``free``; ``free(theta)`` the other parameters; ``lo``/``hi`` its search range."""

    value: Callable
    build: Callable
    free: Callable
    lo: float
    hi: float


def component(i: int, lo: float, hi: float) -> Coordinate:
    """The coordinate ``theta[i]``."""
    def build(v, free):
        return np.insert(np.asarray(free, float), i, v)
    return Coordinate(lambda t: float(t[i]), build, lambda t: np.delete(np.asarray(t, float), i), lo, hi)


def lower_border(lo: float, hi: float) -> Coordinate:
    """d^- = theta[0] - exp(theta[2]) (d^+ minus the dead band): fixed, with d^+ following the band."""
    def build(v, free):
        free = np.asarray(free, float)
        return np.concatenate([[v + np.exp(free[1])], free])
    return Coordinate(lambda t: float(t[0] - np.exp(t[2])), build, lambda t: np.asarray(t[1:], float), lo, hi)


def interval(residual: Callable, theta: np.ndarray, coord: Coordinate, rise: float, step: float,
             free_lo: np.ndarray, free_hi: np.ndarray) -> tuple[float | None, float | None]:
    """The profile interval of ``coord`` around the optimum ``theta`` of ``sum(residual**2)``: the
    values at which the chi-square, the other parameters fitted again (bounded by ``free_lo``,
    ``free_hi``), has risen by ``rise``; a side on which it does not inside the coordinate's range
    is None. ``step`` (> 0) is the first trial distance (the Gauss-Newton standard deviation)."""
    chi2_min = float(np.sum(residual(theta) ** 2))
    v0, start = coord.value(theta), coord.free(theta)
    step = max(float(step), 1e-9 * max(1.0, abs(v0)))

    def excess(v, free):
        def r(p):
            return residual(coord.build(v, p))
        sol = optimize.least_squares(r, np.clip(free, free_lo, free_hi), method="trf", bounds=(free_lo, free_hi),
                                     x_scale="jac", max_nfev=200)
        return 2.0 * float(sol.cost) - chi2_min - rise, sol.x

    ends = []
    for sign in (-1.0, 1.0):
        inside, free, end = v0, start, None
        edge = coord.lo if sign < 0 else coord.hi
        d = step
        for _ in range(MAX_DOUBLINGS):
            v = v0 + sign * d
            if (v - edge) * sign >= 0:
                v = edge
            f, x = excess(v, free)
            if f > 0:
                end = optimize.brentq(lambda w: excess(w, free)[0], inside, v, xtol=XTOL * step)
                break
            if v == edge:
                break
            inside, free, d = v, x, 2.0 * d
        ends.append(end)
    return ends[0], ends[1]
