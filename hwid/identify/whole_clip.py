"""An actuator that stops short of the commanded range, in the whole fit from logs
(:mod:`hwid.identify.whole`): the input's limits fitted as two more outer parameters, kept only
where the information criterion prefers them.

An input clip is not in the paper's structure, and a fit without it mimics the clip with F, G and
h bent out of shape: a development log of the paper's plant whose actuator stopped at 0.76 (its
staircase went to 1.2) was fitted with ``G = (21 s + 1)/(140 s^2 + 24 s + 1)`` for the plant's
``1/(10 s^2 + 7 s + 1)`` and a slew rate of 0.27 units/s, too far for the diagnosis's refit (which
moves G's coefficients by a bounded factor) to reach once ``input_saturation`` is added: the clip
explained 0.29 of the gap. Fitted here, the limits are taken out of the model again and handed to
the diagnosis as the effect's start (:class:`hwid.diagnose.rank.EffectFitter`, ``hints``), which
must earn them back on the validation part like any other effect.
"""
from __future__ import annotations

from dataclasses import replace
import numpy as np

from hwid.identify.defaults import CLIP_POINTS
from hwid.identify.g_structure import STRUCTURES
from hwid.identify.whole_problem import Problem, best_states, border_grid, descend, extent, table_row

#: the :class:`hwid.identify.whole.WholeModelFit` whose step this is (it calls this module, so the
#: type is named here, not imported)
Estimator = object


def fit_clip_added(fitter: Estimator) -> tuple[float, float] | None:
    """After ``fitter``'s fit: its degree and delay again with the input's limits fitted too, for
    each input type tried and the structures of no higher order than the selected (without the
    slew rate: where the selected fit has one, it may be what stood in for the clip). The fit
    without the limits has bent F, G and h to mimic them, so each type and structure starts from
    the border grid and G's default (:func:`_grid_start`); the selected type and structure also
    from the selected fit, limits added. Every start is descended. The limits are kept where the
    criterion prefers the fit with them over every fit so far and over the same fit descended
    again without them, and neither sits at the input's centre (:func:`_pressed_inward`):
    ``fitter`` then holds that fit
    (``problem_``, ``theta_``, ``result_``, whose table gains the rows marked ``+clip``) and
    ``(u_lo, u_hi)`` is returned; else None and ``fitter`` keeps the best fit without limits (its
    table gains the rows)."""
    base, theta = fitter.problem_, np.asarray(fitter.theta_, float)
    records = base.records
    probs, starts = [], []
    for kind in fitter.types:
        for s in (fitter.structures or STRUCTURES):
            if s.order > base.structure.order:
                continue
            prob = Problem(records, kind, s, base.degree, base.with_delay, with_clip=True)
            probs.append(prob)
            starts.append(_grid_start(fitter, prob))
            if (kind, s) == (base.type, base.structure):
                # the selected fit's F, G and states (its slew rate left out), at its best limits
                own = np.concatenate([theta[:base.rate_at], [0.0, 0.0], theta[base.states_at:]])
                probs.append(prob)
                starts.append(best_states(prob, _best_limits(prob, own)))
    fits = descend(probs, starts, fitter.max_nfev)
    best: dict = {}
    for prob, (x, rss) in zip(probs, fits):       # one row per type and structure: its better start
        key = (prob.type, str(prob.structure))
        if key not in best or rss < best[key][2]:
            best[key] = (prob, x, rss)
    rows = [table_row(p, rss) for p, _, rss in best.values()]
    i = int(np.argmin([r["aic"] for r in rows]))
    table = list(fitter.result_.selection) + rows
    if rows[i]["aic"] >= min(r["aic"] for r in fitter.result_.selection):
        fitter.result_ = replace(fitter.result_, selection=tuple(table))
        return None
    prob, x, _ = list(best.values())[i]
    if _pressed_inward(prob, *prob.clip(x)):
        fitter.result_ = replace(fitter.result_, selection=tuple(table))
        return None
    # the limits must earn their parameters against their own fit without them: from another
    # start the search may only have found a better valley (limits beyond the input's reach, or
    # pressed into its last levels), which is the model's, not the actuator's
    free = Problem(records, prob.type, prob.structure, prob.degree, prob.with_delay)
    k = prob.clip_at
    (x0, rss0), = descend([free], [np.concatenate([x[:k], x[k + 2:]])], fitter.max_nfev)
    row0 = table_row(free, rss0)
    table.append(row0)
    if row0["aic"] <= rows[i]["aic"]:
        if row0["aic"] < min(r["aic"] for r in fitter.result_.selection):
            fitter.hold(free, x0, table)
        else:
            fitter.result_ = replace(fitter.result_, selection=tuple(table))
        return None
    lo, hi = prob.clip(x)
    fitter.hold(prob, x, table, f"the input is clipped to [{lo:.4g}, {hi:.4g}] in this fit; F, G and h are "
                                "fitted with it, and the model keeps it")
    return lo, hi


def _pressed_inward(prob: Problem, lo: float, hi: float) -> bool:
    """Whether a limit sits at the input's centre, the inner end of its range (within 2 % of the
    range): the fit then wants the input stopped short of half its travel, which is the clip
    standing in for something else (a 4 s sensor lag on the paper's plant was fitted with an
    actuator that never passed -0.1 of a range -1.4 to 1.2), not an actuator that stops short."""
    (_, lo_in), (hi_in, _) = prob.clip_bounds()
    tol = 0.02 * extent(prob.records)[2]
    return bool(lo >= lo_in - tol or hi <= hi_in + tol)


def _grid_start(fitter: Estimator, prob: Problem) -> np.ndarray:
    """A start for ``prob`` from the border grid and G's default: the grid's best borders without
    limits, the best limits for them, the grid's best borders again with those limits, and the
    best limits for these (a clip moves where the borders fit best, and the borders where the
    limits do)."""
    k = prob.clip_at
    start = fitter.variant([prob.structure], prob.with_delay, (prob.type,)).start_values(
        prob.records, prob.type, prob.structure, None)
    theta = _best_limits(prob, np.concatenate([start[:k], [0.0, 0.0], start[k:]]))
    trials = []
    for d_plus, log_gap in border_grid(prob.records):
        t = theta.copy()
        t[0], t[2] = d_plus, log_gap
        trials.append(t)
    theta = min(trials + [theta], key=lambda t: float(np.sum(prob.residual(t) ** 2)))
    return best_states(prob, _best_limits(prob, theta))


def _best_limits(prob: Problem, theta) -> np.ndarray:
    """``theta`` with the limits at the best of :func:`_limit_pairs`."""
    k = prob.clip_at
    trials = []
    for pair in _limit_pairs(prob):
        t = np.array(theta, float)
        t[k:k + 2] = pair
        trials.append(t)
    return min(trials, key=lambda t: float(np.sum(prob.residual(t) ** 2)))


def _limit_pairs(prob: Problem) -> list[np.ndarray]:
    """Starting limits: ``CLIP_POINTS`` places of each from the input's centre outwards, the last
    at its bound (beyond the input's range)."""
    (lo_a, lo_b), (hi_a, hi_b) = prob.clip_bounds()
    q = np.linspace(0.4, 1.0, CLIP_POINTS)
    los = lo_b + q * (lo_a - lo_b)
    his = hi_a + q * (hi_b - hi_a)
    return [np.array([a, b]) for a in los for b in his]
