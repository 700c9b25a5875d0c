"""Each record's unknown start, estimated and written as a short virtual pre-input.

A log begins wherever the rig happened to be: the gear anywhere in its play, G anywhere (parked,
homed, left mid-move). Burning in the samples until the model has forgotten its start (the input
spanning the play, then G settling) costs a slow plant every sample of a short record. Instead
each record's start is two nuisance parameters, as in the whole-model fit (:mod:`hwid.identify.whole`)
and ``hwid compare``: the level ``L`` at which G rests and the gear's position ``g0`` inside the
play at ``u[0]``. They are fitted to the record's output through the model, then written as
:data:`PRE` input samples put before the record:

* sample 0 puts F's output at ``L`` from F's default start (on the ascending border for ``L >= 0``,
  the descending one otherwise), so G, which every simulator starts at rest at its first input,
  rests at ``L``;
* sample 1 pushes the gear to ``g0`` (along the border it has to move along).

The record then starts with the gear at ``g0`` and G at rest at ``L`` (it has seen one sample of
``g0``, which is part of the parameterisation, not an approximation: the fit runs through the same
pre-input). Every simulation in the diagnosis -- the baseline, each effect, each refit of h or G --
runs from a record's input, so all of them start from the estimated state without knowing about
it; the pre-input is never scored. A Backlash-Inverse has no play to sit in: its nuisance is ``L``
and the direction of its last move before ``u[0]`` (which branch it starts on).
"""
from __future__ import annotations

import numpy as np
from scipy.optimize import minimize_scalar

from hwid.model import HWModel, InputNonlinearity

#: samples of the virtual pre-input put before each record
PRE = 2


def search_1d(cost, lo: float, hi: float, points: int = 9) -> float:
    """The minimiser of ``cost`` over [lo, hi]: a grid of ``points``, then Brent's bounded search
    across the best point's neighbours (to 1e-6 of the range)."""
    if not hi > lo:
        return float(lo)
    grid = np.linspace(lo, hi, points)
    costs = [cost(g) for g in grid]
    k = int(np.argmin(costs))
    a, b = grid[max(k - 1, 0)], grid[min(k + 1, grid.size - 1)]
    sol = minimize_scalar(cost, bounds=(a, b), method="bounded", options={"xatol": 1e-6 * (hi - lo)})
    return float(sol.x) if sol.fun <= costs[k] else float(grid[k])


def pre_input(F: InputNonlinearity, level: float, gear: float, u0: float, width: float) -> np.ndarray:
    """The :data:`PRE` input samples that leave G at rest at ``level`` and the gear at ``gear`` (a
    Backlash) or on the branch of the last move's direction ``sign(gear)`` (a Backlash-Inverse)
    when ``u0`` is applied; ``width``: the input's range (sets the Backlash-Inverse's last move)."""
    su, sd, dp, dm = float(F.slope_up), float(F.slope_down), float(F.d_plus), float(F.d_minus)
    if F.type == "backlash":
        p0 = level / su + dp if level >= 0 else level / sd + dm
        p1 = gear / su + dp if gear >= level else gear / sd + dm
        return np.array([p0, p1])
    # a Backlash-Inverse starts at the midpoint of its branches: 0.5 (z/su + dp + z/sd + dm) = level
    p0 = (2.0 * level - dp - dm) / (1.0 / su + 1.0 / sd)
    return np.array([p0, u0 - np.sign(gear) * 1e-6 * max(width, 1e-9)])


def estimate(model: HWModel, u, y, dt: float, stop: int | None = None) -> dict:
    """The start ``{"level", "gear", "pre", "rms_before", "rms_after"}`` of one record that fits its
    first ``stop`` samples best through ``model`` (all of them by default). ``rms_before``: the fit
    from the default start (every simulator's); ``rms_after``: from the estimated one.

    G's response is affine in ``L`` for a given gear start (``w = w_g + L d``, ``d`` its response
    to a unit rest level that leaves after one sample), so the search is Brent's over the gear with
    an inner search over ``L`` that only evaluates h."""
    F, G, h = model.input, model.linear, model.output
    u = np.asarray(u, float)
    y = np.asarray(y, float)
    stop = u.size if stop is None else int(min(max(stop, 1), u.size))
    u, y = u[:stop], y[:stop]
    width = float(np.ptp(u)) if u.size else 0.0
    v_def = F.apply(u)
    lo_v, hi_v = float(v_def.min()), float(v_def.max())
    if F.type == "backlash":
        a, b = F.start_band(u)            # the gear's place in the play at u[0]
        lo_v, hi_v = min(lo_v, a), max(hi_v, b)
    # the rig may have been left beyond anything this record drives it to (the previous one went
    # further): G's rest level is looked for over the record's own range widened by it each way
    span = hi_v - lo_v
    lo_v, hi_v = lo_v - span, hi_v + span
    d = G.simulate(np.r_[1.0, np.zeros(PRE - 1 + stop)], dt)[PRE:]

    def inner(gear):
        """(best level, its cost) for a gear start."""
        pre = pre_input(F, 0.0, gear, float(u[0]), width)
        # the chain from rest at 0 with the pre-input's first sample at 0: the level comes in by d
        v = F.apply(np.r_[pre, u])
        v[0] = 0.0
        w0 = G.simulate(v, dt, 0.0)[PRE:]

        def cost(level):
            r = y - h(w0 + level * d)
            return float(r @ r)

        level = search_1d(cost, lo_v, hi_v, 25)
        return level, cost(level)

    if F.type == "backlash":
        gear = search_1d(lambda g: inner(g)[1], a, b) if b > a else a
        level = inner(gear)[0]
    else:
        (l_up, c_up), (l_dn, c_dn) = inner(1.0), inner(-1.0)
        gear, level = (1.0, l_up) if c_up <= c_dn else (-1.0, l_dn)
    pre = pre_input(F, level, gear, float(u[0]), width)
    x = model.output(G.simulate(F.apply(np.r_[pre, u]), dt))[PRE:]
    x_def = model.output(G.simulate(v_def, dt))
    rms = lambda r: float(np.sqrt(np.mean(r * r)))
    return {"level": float(level), "gear": float(gear), "pre": pre,
            "rms_before": rms(y - x_def), "rms_after": rms(y - x)}
