"""Nuisance starts held still across a least-squares Jacobian (:class:`HeldJacobian`).

An effect's prediction may carry a nuisance start per record -- the gear's place in the play
(:meth:`hwid.diagnose.modelsim.ModelSim.gear_start`), G's rest level (``rest_level``), a friction's
or a hysteresis's memory (``memory_start``) -- each the minimiser of a one-dimensional search that
simulates the record some thirty times. Searched again in every column of a finite-difference
Jacobian, they made a fed-back friction's joint fit with G cost 20-40 s where the same fit without
the memory took 1 s.

Held at the point the Jacobian is taken at, the columns are the partial derivatives of the
residual at fixed starts: the Jacobian of variable projection in Kaufman's form (Golub and Pereyra
2003, "Separable nonlinear least squares: the variable projection method and its applications",
sect. 3), whose gradient ``J^T r`` equals the full one at a start that minimises the cost (there
``r^T dr/ds = 0``). That holds only inside the start's range: a start found on an end of its range
(a gear pushed against a border of the play, whose ends move with F's borders and with the input an
actuator effect leaves) follows that end as the parameters move, and held there it takes that share
out of the Jacobian (a slow actuator's rate fit stopped at 0.146 units/s, 6x the floor, for the
truth's 0.133). Such a start is held on its end: each column takes the end where the column's
parameters put it. Every residual the optimiser accepts or rejects a step on is still the exact
one, its starts searched.
"""
from __future__ import annotations

import threading

import numpy as np


class _State(threading.local):
    mode: str | None = None          # None: search; "record": search and note; "replay": reuse
    seen: dict | None = None
    pos: dict | None = None


_STATE = _State()

#: a start within this share of its range from an end of it is on that end (the search's own
#: tolerance is 1e-6 of the range, :func:`hwid.diagnose.starts.search_1d`)
ON_END = 1e-4


def on_end(value: float, bounds) -> int | None:
    """Which end of the range ``bounds`` (``(lo, hi)``; None: no range) ``value`` lies on: 0 (lo),
    1 (hi), or None (inside it)."""
    if bounds is None:
        return None
    lo, hi = float(bounds[0]), float(bounds[1])
    tol = ON_END * max(hi - lo, 0.0)
    return 0 if value <= lo + tol else 1 if value >= hi - tol else None


def nuisance(search, key, bounds=None) -> float:
    """``search()`` (a nuisance start's minimiser over the range ``bounds``), noted under ``key``
    while a residual is recorded, and the noted value returned in its place while one is replayed
    (:class:`HeldJacobian`); a start found on an end of its range (:func:`on_end`), where the
    minimiser is not stationary, is replayed as that end of the range ``bounds`` the replayed
    residual passes. ``key``: what the start is of (its kind and record); several searches under
    one key in one residual are told apart by their order."""
    st = _STATE
    if st.mode == "replay":
        n = st.pos.get(key, 0)
        noted = st.seen.get(key, ())
        if n < len(noted):
            st.pos[key] = n + 1
            value, end = noted[n]
            return value if end is None or bounds is None else float(bounds[end])
        return search()
    value = search()
    if st.mode == "record":
        st.seen.setdefault(key, []).append((value, on_end(value, bounds)))
    return value


class HeldJacobian:
    """``fun`` and a forward-difference Jacobian of it for ``scipy.optimize.least_squares`` on the
    unit box, the nuisance starts (:func:`nuisance`) held at their values at the point the Jacobian
    is taken at. The steps are ``least_squares``'s own for ``diff_step=step`` (relative to ``x``,
    flipped inwards at a bound), so a residual without nuisance starts gets the same Jacobian.

    :meth:`searched` says whether the residual at a point searched any start: where it did not,
    the caller may leave the Jacobian to ``least_squares``."""

    def __init__(self, fun, step: float):
        self._fun, self.step = fun, float(step)
        self._x = None
        self._f = None
        self._seen: dict = {}

    def fun(self, x) -> np.ndarray:
        """The residual at ``x``, its starts searched and noted."""
        st = _STATE
        outer = (st.mode, st.seen, st.pos)
        st.mode, st.seen, st.pos = "record", {}, {}
        try:
            f = np.asarray(self._fun(x), float)
            seen = st.seen
        finally:
            st.mode, st.seen, st.pos = outer
        self._x, self._f, self._seen = np.array(x, float), f, seen
        return f

    def searched(self, x) -> bool:
        """Whether the residual at ``x`` searches a nuisance start."""
        if self._x is None or not np.array_equal(self._x, x):
            self.fun(x)
        return bool(self._seen)

    def jac(self, x) -> np.ndarray:
        """The Jacobian at ``x``, each column's residual with the starts found at ``x``."""
        x = np.asarray(x, float)
        if self._x is None or not np.array_equal(self._x, x):
            self.fun(x)
        f0, seen = self._f, self._seen
        h = self._steps(x)
        J = np.empty((f0.size, x.size))
        st = _STATE
        outer = (st.mode, st.seen, st.pos)
        try:
            for j in range(x.size):
                x1 = x.copy()
                x1[j] = x[j] + h[j]
                st.mode, st.seen, st.pos = "replay", seen, {}
                J[:, j] = (np.asarray(self._fun(x1), float) - f0) / ((x[j] + h[j]) - x[j])
        finally:
            st.mode, st.seen, st.pos = outer
        return J

    def _steps(self, x) -> np.ndarray:
        """``least_squares``'s forward steps for a relative ``diff_step`` on [0, 1]: ``step |x|``
        (sqrt(eps) max(1, |x|) where that rounds to nothing), reversed where it would leave the box,
        cut to the distance to the farther bound where neither direction fits."""
        sign = np.where(x >= 0, 1.0, -1.0)
        h = self.step * sign * np.abs(x)
        tiny = ((x + h) - x) == 0
        h = np.where(tiny, np.sqrt(np.finfo(float).eps) * sign * np.maximum(1.0, np.abs(x)), h)
        lower, upper = x - 0.0, 1.0 - x
        out = (x + h < 0.0) | (x + h > 1.0)
        fits = np.abs(h) <= np.maximum(lower, upper)
        h = np.where(out & fits, -h, h)
        forward, backward = (upper >= lower) & ~fits, (upper < lower) & ~fits
        h = np.where(forward, upper, h)
        return np.where(backward, -lower, h)
