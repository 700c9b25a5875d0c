"""G's excess phase in the whole fit (:mod:`hwid.identify.whole`): a pure delay fitted where it can
only improve on the fit without it, and a delay or a right-half-plane zero kept only where no
added dynamics fits as well.

A rational G alone stands in for a transport delay with fast poles the plant does not have, and a
delay or a zero in the right half plane stands in for dynamics the structures tried lack; what
tells them apart here is the information criterion on the same records, with the fit without a
delay as the fallback.
"""
from __future__ import annotations

from dataclasses import replace
import numpy as np
from scipy import optimize

from hwid.identify.g_structure import STRUCTURES, Structure, g_from_params, g_params_from
from hwid.identify.whole_problem import Problem, descend, extent, table_row

#: the :class:`hwid.identify.whole.WholeModelFit` whose step this is (it calls this module, so the
#: type is named here, not imported)
Estimator = object


def fit_delay_added(fitter: Estimator, records, borders=None) -> Estimator:
    """``fitter``'s :meth:`~WholeModelFit.fit` without a delay, then with G's delay over the
    selected type and degree and the structures of no higher order (a delay stands in for poles,
    it adds none), each started from the fit without it (:func:`_delayed_start`); the better of
    the two by the information criterion is kept in ``fitter`` (``result_``, ``problem_``,
    ``theta_``; the result's selection table holds both, the delayed rows marked ``+delay``).

    The fit without a delay is the fallback a delay can only improve on: with the delay free
    from the start, a search can stop in a worse valley than the same search without it (a
    second-order G with a resonance on top, from a lab log: 2.2x the noise against 1.1x). Its
    type, degree, borders, h_bar and initial states are the delayed fits' starts; only G and the
    delay are new, so no staged selection is run again."""
    f = fitter
    plain = f.variant(delay=False).fit(records, borders=borders)
    base, theta = plain.problem_, np.asarray(plain.theta_, float)
    records = base.records
    span, dt, width = extent(records)
    delayed = f.variant(delay=True, types=(base.type,))
    probs = [Problem(records, base.type, s, base.degree, True)
             for s in (f.structures or STRUCTURES) if s.order <= base.structure.order]
    fits = descend(probs, [_delayed_start(base, theta, p.structure, span, dt) for p in probs], f.max_nfev)
    rows = [table_row(p, rss) for p, (_, rss) in zip(probs, fits)]
    i = int(np.argmin([r["aic"] for r in rows]))
    prob, x = probs[i], fits[i][0]
    table = list(plain.result_.selection) + rows
    if rows[i]["aic"] >= min(r["aic"] for r in plain.result_.selection):
        fitter.problem_, fitter.theta_ = plain.problem_, plain.theta_
        fitter.result_ = replace(plain.result_, selection=tuple(table))
        return fitter
    pole = pole_for_delay(prob, x, width, span, dt, f.max_nfev)
    if pole is not None:
        prob, x, rss = pole
        table.append(table_row(prob, rss))
    delayed.hold(prob, x, table)
    fitter.problem_, fitter.theta_, fitter.result_ = delayed.problem_, delayed.theta_, delayed.result_
    return fitter


def _delayed_start(base: Problem, theta, structure: Structure, span: float, dt: float) -> np.ndarray:
    """Start of a fit with G's delay from the fit ``theta`` of ``base`` (no delay): its borders and
    initial states; G of ``structure`` from its slowest real poles and pairs and its zeros (a
    structure's default where it lacks them), and the delay the group delay at ``w = 0`` of the
    poles and pairs left out (the lag a delay in their place must give)."""
    G = g_from_params(base.structure, theta[3:3 + base.structure.n_params])
    poles = np.roots(G.den)
    real = sorted(float(-q.real) for q in poles if abs(q.imag) < 1e-9)
    pairs = sorted((abs(q), -q.real / abs(q)) for q in poles if q.imag > 1e-9)
    zeros = [float(-1.0 / z.real) for z in np.roots(np.trim_zeros(np.asarray(G.num, float), "f"))
             if abs(z.imag) < 1e-9 and abs(z.real) > 1e-12]
    p = g_params_from(structure, None, span, dt)
    if len(real) >= structure.poles and len(pairs) >= structure.pairs and len(zeros) >= structure.zeros:
        p = np.array([np.log(r) for r in real[:structure.poles]]
                     + [v for wn, z in pairs[:structure.pairs] for v in (np.log(wn), np.log(max(z, 1e-3)))]
                     + zeros[:structure.zeros], float)
        lag = sum(1.0 / r for r in real[structure.poles:]) + sum(2 * z / wn for wn, z in pairs[structure.pairs:])
    else:
        lag = 0.0
    k = 3 + base.structure.n_params
    return np.concatenate([theta[:3], p, [lag], theta[k:]])


def pole_for_delay(prob: Problem, theta, width: float, span: float, dt: float, max_nfev: int):
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
    t = np.asarray(theta, float)
    return _added_dynamics(prob, theta, [np.concatenate([t[:k], t[k + 1:]])], delay, 1, width, span, dt, max_nfev)


def pole_for_rhp_zero(prob: Problem, theta, width: float, span: float, dt: float, max_nfev: int):
    """A fit without a delay whose G has zeros in the right half plane, tried again with one more
    real pole or one more pole pair (the zeros started where they are and mirrored into the left
    half plane): ``(problem, theta, rss)`` of the best that fits the records at least as well by
    the information criterion, else None.

    A right-half-plane zero ``z`` adds the excess phase of a delay of ``2 / z``
    (:func:`hwid.diagnose.baseline.mirror_rhp_zeros`), and a diagnosis reads it as one; where the
    records are better fitted by a pole the structure lacked, that is the plant's own dynamics (a
    third-order G with a zero at -6, fitted at order two with a zero at +11, was called
    ``sensor_lag``). A real pole and a pair are charged as the selection charges G's parameters."""
    if prob.with_delay or prob.structure.zeros == 0:
        return None
    s = prob.structure
    t = np.asarray(theta, float)
    zk = 3 + s.poles + 2 * s.pairs
    zeros = t[zk:zk + s.zeros]
    if not np.any(zeros < 0):
        return None
    mirrored = t.copy()
    mirrored[zk:zk + s.zeros] = np.abs(zeros)
    lag = float(np.sum(-2.0 * zeros[zeros < 0]))
    return _added_dynamics(prob, theta, [t, mirrored], lag, 0, width, span, dt, max_nfev)


def _added_dynamics(prob: Problem, theta, starts, lag: float, freed: int, width: float, span: float,
                    dt: float, max_nfev: int):
    """Fits without a delay of ``prob``'s structure with one more real pole and with one more pole
    pair, each from every one of ``starts`` (``prob``'s parameters without a delay), the new pole
    started at the phase lag ``lag`` it stands in for and the pair well and lightly damped; the
    best by the information criterion, where it is at least as good as ``prob``'s own fit
    (``theta``), as ``(problem, theta, rss)``, else None. ``freed``: parameters the new
    structures no longer need (1 for a delay)."""
    s = prob.structure
    n = prob.y.size
    best = (float(np.sum(prob.residual(theta) ** 2)), 0, None)     # (rss, extra parameters, fit)
    rate = np.log(1.0 / max(lag, dt))
    trials = [(Structure(s.poles + 1, s.pairs, s.zeros), 3 + s.poles, [[rate]]),
              (Structure(s.poles, s.pairs + 1, s.zeros), 3 + s.poles + 2 * s.pairs,
               [[np.log(1.4 / max(lag, dt)), np.log(0.7)], [np.log(2.0 / max(lag, dt)), np.log(0.1)]])]
    for structure, at, inserts in trials:
        alt = replace(prob, structure=structure, with_delay=False)    # its slew rate and clip kept
        lo, hi = alt.bounds(width, span, dt)
        extra = structure.n_params - s.n_params - freed
        for t in starts:
            for ins in inserts:
                start = np.concatenate([t[:at], ins, t[at:]])
                sol = optimize.least_squares(alt.residual, np.clip(start, lo + 1e-9, hi - 1e-9), bounds=(lo, hi),
                                             method="trf", x_scale=1.0, max_nfev=max_nfev)
                rss = float(sol.fun @ sol.fun)
                if n * np.log(rss) + extra * np.log(n) <= n * np.log(best[0]) + best[1] * np.log(n):
                    best = (rss, extra, (alt, sol.x, rss))
    return best[2]
