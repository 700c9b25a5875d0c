"""G's pure delay in the whole fit (:mod:`hwid.identify.whole`): fitted where it can only improve
on the fit without it, and kept only where no added dynamics fits as well.

A rational G alone stands in for a transport delay with fast poles the plant does not have, and a
delay stands in for dynamics the structures tried lack; what tells them apart here is the
information criterion on the same records, with the fit without a delay as the fallback.
"""
from __future__ import annotations

from dataclasses import replace

import numpy as np
from scipy import optimize

from hwid.identify.whole import STRUCTURES, Structure, WholeModelFit, _Problem


def fit_delay_added(fitter: WholeModelFit, records, borders=None) -> WholeModelFit:
    """``fitter``'s :meth:`~WholeModelFit.fit` without a delay, then again with G's delay over the
    selected type and the structures of no higher order (a delay stands in for poles, it adds
    none); the better of the two by the information criterion is kept in ``fitter``
    (``result_``, ``problem_``, ``theta_``; the result's selection table holds both, the delayed
    rows marked ``+delay``).

    The fit without a delay is the fallback a delay can only improve on: with the delay free
    from the start, a search can stop in a worse valley than the same search without it (a
    second-order G with a resonance on top, from a lab log: 2.2x the noise against 1.1x)."""
    f = fitter
    plain = WholeModelFit(f.max_degree, f.structures, False, f.types, f.max_nfev, f.staged).fit(records,
                                                                                             borders=borders)
    order = plain.problem_.structure.order
    kind = plain.result_.type
    delayed = WholeModelFit(f.max_degree, [s for s in (f.structures or STRUCTURES) if s.order <= order],
                            True, (kind,), f.max_nfev, f.staged)
    delayed.fit(records, borders=borders if borders is not None and borders.type == kind else None)
    best = min((plain, delayed), key=lambda w: min(r["aic"] for r in w.result_.selection))
    fitter.problem_, fitter.theta_ = best.problem_, best.theta_
    fitter.result_ = replace(best.result_, selection=plain.result_.selection + delayed.result_.selection)
    return fitter


def pole_for_delay(prob: _Problem, theta, width: float, span: float, dt: float, max_nfev: int):
    """The selected fit's delay replaced by one more real pole or one more pole pair, where that
    fits the records at least as well by the information criterion: ``(problem, theta, rss)`` of
    the best fit without a delay, else None.

    A pure delay and added dynamics both add phase lag; a delay that fits no better than a pole
    or a pair in its place is dynamics the structures tried lack, not a dead time, and a diagnosis
    would then blame the missing dynamics on the time_delay effect: a third-order G with a zero,
    fitted at order 2 with a delay standing in for the third pole, was called ``sensor_lag``; a
    second-order G with a lightly damped mode on top, fitted with a well-damped pair and a delay
    of 0.43 s, left the mode unnamed. A real pole costs what the delay costs; a pair one
    parameter more, charged as the selection charges G's (``ln n``)."""
    if not prob.with_delay:
        return None
    k = 3 + prob.structure.n_params
    delay = float(abs(theta[k]))
    if delay <= 0:
        return None
    s = prob.structure
    t = np.asarray(theta, float)
    n = prob.y.size
    best = (float(np.sum(prob.residual(theta) ** 2)), 0, None)     # (rss, extra parameters, fit)
    rate = np.log(1.0 / max(delay, dt))
    # the new pair started well damped (group delay 1.4 / wn, the delay's) and lightly damped
    trials = [(Structure(s.poles + 1, s.pairs, s.zeros), 3 + s.poles, [[rate]]),
              (Structure(s.poles, s.pairs + 1, s.zeros), 3 + s.poles + 2 * s.pairs,
               [[np.log(1.4 / max(delay, dt)), np.log(0.7)], [np.log(2.0 / max(delay, dt)), np.log(0.1)]])]
    for structure, at, inserts in trials:
        alt = _Problem(prob.records, prob.type, structure, prob.degree, False)
        lo, hi = alt.bounds(width, span, dt)
        extra = structure.n_params - s.n_params - 1
        for ins in inserts:
            start = np.concatenate([t[:at], ins, t[at:k], t[k + 1:]])
            sol = optimize.least_squares(alt.residual, np.clip(start, lo + 1e-9, hi - 1e-9), bounds=(lo, hi),
                                         method="trf", x_scale=1.0, max_nfev=max_nfev)
            rss = float(sol.fun @ sol.fun)
            if n * np.log(rss) + extra * np.log(n) <= n * np.log(best[0]) + best[1] * np.log(n):
                best = (rss, extra, (alt, sol.x, rss))
    return best[2]
