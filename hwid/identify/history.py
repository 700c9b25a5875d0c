"""Stage 1 from any piecewise-constant history (recorded levels in any order, of any length).

The paper's stage 1 (Section 4) reads the settled outputs of two monotone staircases. A lab's log
holds levels in whatever order the operator chose: here each level's settled output is predicted
as ``X_k = h_bar(F_bar[u_1..u_k])`` (eqs. 4a, 4c with ``G(0) = 1``, eqs. 7a-b and 14a-b), with the
steady recursion of F run over the *recorded* sequence of levels, so which border or flat path each
level sits on follows from the data and the parameters, not from an assumed lead-in. The state at
a record's first level is unknown: for a backlash, the gear's place inside the play there is a
nuisance parameter; for a Backlash-Inverse the first level's direction is unknown and that level
is not scored.

Settled outputs: the settle time is found from the data (:func:`settle_constant`: one time
constant for every level's approach through h, five of them left out of each level); what remains of a level,
when at least 20 samples, goes to :func:`hwid.identify.steady.steady_levels` (any transient left
found from the data again, batch-means standard errors; what is left of the approach after the cut
taken out of the average, :func:`_transient_corrected`); shorter ones by extrapolating their
approach with the common time constant (:func:`_extrapolated`), or from their steady tail when it
is evident (spread within two output quanta or three noise standard deviations, the noise from the
levels' successive differences, over the last half or all after the settle cut; :func:`_short_level`);
otherwise the level is not scored,
with one line saying how many samples would be needed, but it stays in the sequence F's recursion
runs over (a level the gear passed through moves its state whether or not it settled).
Quantised outputs: a settled level read to the nearest count carries ``q / sqrt(12)`` that
averaging does not remove, so every standard error is at least that.

The input's path between held levels (a stretch too short to be a level, a sine, a ramp) enters F's
recursion through its turning points (:func:`passage`), unscored. A hold in which the output moves
beyond the noise while the input holds still (a push, a load, a slip; :mod:`hwid.identify.disturbed`)
is read up to the disturbance only, with one line naming it. A record cut out of a longer one finds
its own levels (:func:`record_levels`).

Before the fit, what the levels can determine is counted (:mod:`hwid.identify.determinable`): too
few distinct levels approached from below is a :class:`hwid.HwidError`; h_bar's degree is kept to
what the design determines; a parameter the levels cannot determine, an estimate at the edge of its
search range and a zero-width interval are reported undetermined (interval None, the reason in
``undetermined``), and so is the fit's adequacy where no degree of freedom is left to judge it.
After the fit, h_bar's other real roots are read (:mod:`hwid.identify.readings`): moving the origin
of h_bar's argument to one of them is an exactly equivalent model of every level, so the paper's
``h^-1(0) = 0`` on the levels' range picks the reading (the fit moves there, one line), or, where
several roots lie in that range, the borders, the dead band and h_bar are undetermined and the
result carries the readings.

Fit: weighted least squares on ``(X_k - h_bar(v_k)) / se_k``; h_bar's coefficients (no constant,
``h_bar(0) = 0``) solved for at every step (variable projection); type and degree chosen by the
criterion of :mod:`hwid.identify.whole` (BIC's charge on F and the nuisances, AIC's on h_bar).
Intervals: 95 %, Gauss-Newton with the standard errors as given, widened by ``sqrt(chi2 / dof)``
when that exceeds 1 (the Birge ratio); those of d+, S^d, d- and the dead band from the chi-square's
profile with the same widening (:mod:`hwid.identify.history_profile`: F's recursion has corners in
the borders, where a Gauss-Newton curvature is one side's), a side the profile does not close inside
the search range reported undetermined; when the chi-square says the
model does not reach the levels' own noise (p < 0.01) the fit is a **misfit** and the result says
so (``misfit: true``), it is not printed as
if sound.
"""
from __future__ import annotations

import json
from dataclasses import replace

import numpy as np
from scipy import optimize, special

from hwid import HwidError
from hwid.identify import determinable, disturbed, history_profile, readings
from hwid.identify.joint_fit import numeric_jacobian
from hwid.identify.result import HistoryResult, Level
from hwid.identify.steady import steady_levels
from hwid.model import InputNonlinearity

#: fewest samples ``steady_levels`` averages; shorter levels go through :func:`_short_level`
MIN_STEADY = 20
#: settle time, in the levels' common time constants, left out of every level before it is averaged
SETTLE_TAUS = 5.0


def settled_levels(records, resolution: float | None = None) -> tuple[list[Level], list[str]]:
    """The settled levels of every record (attribute ``segments`` from :mod:`hwid.recorded`, or the
    piecewise-constant stretches of ``u``), with their standard errors; and the warnings."""
    warns: list[str] = []
    per_record = []
    for r in records:
        segs = record_levels(r)
        q = resolution if resolution is not None else (float(r.attrs.get("output_resolution", 0.0)) or None)
        per_record.append((r, segs, q))
    segments = [np.asarray(r.y[s["start"]:s["stop"]], float) for r, segs, _ in per_record for s in segs]
    sigma = _robust_sigma(segments)
    tau = settle_constant(segments)
    cut = int(np.ceil(SETTLE_TAUS * tau))
    per_record, cut_short = _undisturbed(per_record, cut, warns)
    if cut_short:       # pushes inside the holds bend every level's fitted approach: fitted again without them
        segments = [np.asarray(r.y[s["start"]:s["stop"]], float) for r, segs, _ in per_record for s in segs]
        tau = settle_constant(segments)
        cut = int(np.ceil(SETTLE_TAUS * tau))
    long = [(r, s) for r, segs, _ in per_record for s in segs if s["stop"] - s["start"] - cut >= MIN_STEADY]
    steady = {}
    if long:
        st = steady_levels([np.asarray(r.y[s["start"] + cut:s["stop"]], float) for r, s in long])
        for (r, s), mean, se, n, first, ok in zip(long, st.mean, st.se, st.n, st.first, st.settled):
            if ok:      # what is left of the approach after the cut, taken out of the average
                mean, se = _transient_corrected(np.asarray(r.y[s["start"]:s["stop"]], float), tau,
                                                cut + int(first), float(mean), float(se))
            steady[r.name, s["start"]] = (float(mean), float(se), int(n))
        warns += list(st.warnings)
    levels: list[Level] = []
    for r, segs, q in per_record:
        k, done = 0, 0
        for s in segs:
            # the input's path since the last level: its turning points move F's state too
            for i in passage(np.asarray(r.u, float), done, s["start"]):
                if k and levels[-1].u == r.u[i]:
                    continue        # the rest of a hold cut short (a disturbance): no new input
                levels.append(Level(r.name, k, float(r.u[i]), float(r.y[i]), float(max(sigma, 1e-300)), 0, False))
                k += 1
            done = s["stop"]
            y = np.asarray(r.y[s["start"]:s["stop"]], float)
            if y.size == 0:     # a level cut to nothing (a fit block that ends where it starts)
                continue
            got = (steady.get((r.name, s["start"])) or _extrapolated(y, tau, max(sigma, (q or 0.0) / np.sqrt(12.0)))
                   or _short_level(y, q, sigma, cut))
            if got is None:
                # not scored, but kept in the sequence: the gear still passed through it
                warns.append(f"{r.name}: the level at u = {s['value']:.6g} (t = {s['start'] * r.dt:.6g}-"
                             f"{s['stop'] * r.dt:.6g} s, samples {s['start']}-{s['stop']}) is still moving at its "
                             f"end; holds of at least {MIN_STEADY} samples after the settle time of {cut} samples "
                             "are needed to find its steady state: not scored (the input's passage through it is kept)")
                levels.append(Level(r.name, k, float(s["value"]), float(y[-1]), float(max(sigma, 1e-300)), 0, False))
                k += 1
                continue
            mean, se, n = got
            if q:
                se = float(np.hypot(se, q / np.sqrt(12.0)))
            levels.append(Level(r.name, k, float(s["value"]), mean, se, n))
            k += 1
    return levels, warns


def _undisturbed(per_record, cut: int, warns: list[str]) -> tuple[list, bool]:
    """Each record's levels with every disturbed hold (:mod:`hwid.identify.disturbed`: the output
    moved beyond the noise while the input held) cut at the disturbance's onset, one line each; and
    whether any was. A hold is searched from its settle cut or its first quarter, whichever is
    earlier: a push inside a hold lengthens the common settle time fitted to all of them."""
    quanta = [q for _, _, q in per_record if q]
    q = max(quanta) if quanta else None

    def first(s):
        return s["start"] + min(cut, (s["stop"] - s["start"]) // 4)

    held = [np.asarray(r.y[first(s):s["stop"]], float) for r, segs, _ in per_record for s in segs]
    sigma = disturbed.noise_scale(held, q)
    thr = disturbed.threshold(sigma, q)
    out, any_cut = [], False
    for r, segs, rq in per_record:
        kept = []
        for s in segs:
            a = first(s)
            y = np.asarray(r.y[a:s["stop"]], float)
            k = disturbed.onset(y, thr)
            if k is not None:
                moved = float(np.max(np.abs(y[k:] - np.median(y[:max(k, 1)]))))
                warns.append(f"{r.name}: the output moved by {moved:.4g} (more than {thr:.4g}: {disturbed.K:g} times "
                             f"the noise's {sigma:.3g} from the quieter holds, or {disturbed.Q_FLOOR:g} quanta) while "
                             f"the input held u = {s['value']:.6g}, from t = {(a + k) * r.dt:.6g} s to the hold's end "
                             f"at {s['stop'] * r.dt:.6g} s (a push, a load or a slip): that part is left out of "
                             "stage 1, the hold's settled output read before it")
                s, any_cut = {**s, "stop": a + k}, True
            kept.append(s)
        out.append((r, kept, rq))
    return out, any_cut


def passage(u: np.ndarray, start: int, stop: int, most: int = 64) -> list[int]:
    """The samples of ``u[start:stop]`` (the input between two held levels: a stretch too short to
    be a level, a sine, a ramp) at which it turns, and its last one: F's steady recursion over them
    ends in the state the whole path leaves (between turning points the path is monotone, and a
    monotone path leaves a Backlash or a Backlash-Inverse where a step to its end would). Beyond
    ``most`` turning points only those outside the range of all later ones are kept (the play's
    wiping-out property: a later wider excursion erases an earlier narrower one)."""
    x = np.asarray(u[start:stop], float)
    if x.size == 0:
        return []
    keep = np.flatnonzero(np.r_[np.diff(x) != 0, True])       # the last sample of each constant run
    v = x[keep]
    d = np.sign(np.diff(v))
    turn = np.r_[np.flatnonzero(d[1:] != d[:-1]) + 1, v.size - 1] if v.size > 1 else np.array([0])
    idx = keep[turn]
    if idx.size > most:
        lo, hi, out = np.inf, -np.inf, []
        for i in idx[::-1]:
            if x[i] < lo or x[i] > hi:
                out.append(i)
                lo, hi = min(lo, x[i]), max(hi, x[i])
        idx = np.array(out[::-1])
    return [int(start + i) for i in idx]


def record_levels(record) -> list[dict]:
    """The held levels of ``record``: its ``segments`` attribute (:mod:`hwid.recorded`) where that
    describes this record's own input -- every level inside it and the input constant at the level's
    value there -- else the piecewise-constant stretches of its ``u`` found again. A record cut out of
    a longer one (a fit block, an excluded window) keeps its parent's attributes; their sample
    numbers then point past its end or at other samples."""
    from hwid.recorded import level_segments
    u = np.asarray(record.u, float)
    if "segments" in record.attrs:
        segs = [s for s in json.loads(record.attrs["segments"]) if s["kind"] == "level"]
        if all(0 <= s["start"] < s["stop"] <= u.size and np.all(u[s["start"]:s["stop"]] == s["value"])
               for s in segs):
            return segs
    return level_segments(u)


def settle_constant(segments, skip: int = 1) -> float:
    """The time constant (samples) of the levels' approach to their steady states, common to all:
    ``y = X_k + A_k exp(-t / tau) + B_k exp(-2 t / tau)`` (:func:`_approach`) fitted to every level
    of at least 8 samples (X_k, A_k, B_k solved for; ``tau`` on a log grid from 0.3 samples to half
    the longest level, then refined; the first ``skip`` samples, where G's faster modes and the
    hold's own delay act, left out)."""
    segs = [y[skip:] for y in segments if y.size >= 8 + skip]
    if not segs:
        return 0.0
    def cost(log_tau: float) -> float:
        total = 0.0
        for y in segs:
            a = _approach(y.size, np.exp(log_tau))
            e = y - a @ np.linalg.lstsq(a, y, rcond=None)[0]
            total += float(e @ e)
        return total

    grid = np.log(np.geomspace(0.3, max(segs, key=len).size / 2, 40))
    k = int(np.argmin([cost(g) for g in grid]))
    lo, hi = grid[max(k - 1, 0)], grid[min(k + 1, grid.size - 1)]
    return float(np.exp(optimize.minimize_scalar(cost, bounds=(lo, hi), method="bounded",
                                                 options={"xatol": 1e-4}).x))


def _approach(n: int, tau: float) -> np.ndarray:
    """Columns ``1, exp(-t / tau), exp(-2 t / tau)``: G's slowest mode seen through h (a
    polynomial of an exponential approach holds its powers; the square is the largest that lasts)."""
    e = np.exp(-np.arange(n) / tau)
    return np.column_stack([np.ones(n), e, e * e])


def _transient_corrected(y: np.ndarray, tau: float, first: int, mean: float, se: float,
                         skip: int = 1) -> tuple[float, float]:
    """``(X, se)`` of a settled level whose samples from ``first`` on were averaged to ``mean`` (with
    standard error ``se``), less what remains of its approach there: :func:`_approach` with the
    levels' common ``tau`` fitted to the whole level from its second sample, and its transient
    columns' average over the averaged samples taken off.

    A cut of :data:`SETTLE_TAUS` time constants leaves ``exp(-5)`` of a step in the first averaged
    sample: of a 2-unit step behind noise of 0.01 it biases a 100-sample average by about one of its
    standard errors, towards where the level came from (levels approached from below low, from above
    high), which moves the borders and not the chi-square. ``X = w^T y`` is linear in the samples, so
    its standard error is ``sqrt(lrv w^T w)`` with ``lrv = n se^2`` the long-run noise variance the
    average's standard error was built on."""
    x = y[skip:]
    start = first - skip
    if tau <= 0 or x.size < 8 or not 0 <= start < x.size:
        return mean, se
    a = _approach(x.size, tau)
    pinv = np.linalg.pinv(a)                         # (3, N): the approach's coefficients per sample
    m = a[start:, 1:].mean(axis=0)                   # the transient columns' average over the kept samples
    w = -(m @ pinv[1:])
    w[start:] += 1.0 / (x.size - start)
    lrv = se * se * (x.size - start)
    return float(w @ x), float(np.sqrt(lrv * float(w @ w)))


def _robust_sigma(segments) -> float:
    """The output noise's standard deviation from successive differences inside the levels (median
    absolute difference: steps, transients and pushes inside a level do not inflate it)."""
    d = np.concatenate([np.diff(y) for y in segments if y.size > 1] or [np.zeros(1)])
    return float(1.4826 * np.median(np.abs(d)) / np.sqrt(2.0))


def _extrapolated(y: np.ndarray, tau: float, sigma: float, skip: int = 1):
    """``(X, se, n)`` of a level too short to settle: :func:`_approach` with the levels' common
    ``tau``, fitted from its second sample on. None -- the level is not extrapolated -- when it
    holds fewer than 6 samples or fewer than 3 time constants (the steady state would be a guess),
    when it settled long ago (:func:`_short_level` takes it), or when the approach does not follow
    the exponential to within 1.5 noise standard deviations ``sigma`` (a controller's ramp, a push)."""
    y = y[skip:]
    if y.size < 6 or tau <= 0 or not 3 * tau <= y.size <= 30 * tau:
        return None
    a = _approach(y.size, tau)
    coef = np.linalg.lstsq(a, y, rcond=None)[0]
    e = y - a @ coef
    if float(np.sqrt(np.mean(e * e))) > 1.5 * sigma:
        return None
    cov = np.linalg.pinv(a.T @ a)
    return float(coef[0]), float(max(sigma, 1e-300) * np.sqrt(cov[0, 0])), int(y.size)


def _short_level(y: np.ndarray, q: float | None, sigma: float, cut: int | None = None):
    """``(mean, se, n)`` of a short level's steady tail when it has one: the longest run of its last
    samples whose spread stays within two output quanta or three noise standard deviations, when
    that run holds at least 3 samples and covers the level's last half or all of it after the
    settle cut ``cut`` (:data:`SETTLE_TAUS` of the levels' common time constant) when the level
    outlasts that cut; else None. (A level shorter than the cut, with only its last few samples
    within the tolerance, is still on its approach: on holds of 2-6 time constants such tails were
    read 16-24 standard errors short of the settled output.)"""
    tol = max(2.0 * (q or 0.0), 3.0 * sigma)
    if tol == 0.0 or y.size < 3:
        return None
    lo, hi = np.minimum.accumulate(y[::-1]), np.maximum.accumulate(y[::-1])
    n = int(np.argmax(np.r_[hi - lo > tol, True]))        # samples from the end within tol
    # a level no longer than the settle cut has no part after it: its last half must be flat
    need = y.size - y.size // 2 if cut is None or cut >= y.size else min(y.size - y.size // 2, y.size - cut)
    if n < max(3, need):
        return None
    tail = y[y.size - n:]
    return float(tail.mean()), float(sigma / np.sqrt(tail.size)), int(tail.size)


class HistoryFit:
    """Stage 1 on recorded levels (module docstring).

    Parameters
    ----------
    max_degree : int
        Highest degree of h_bar tried.
    types : sequence of str
        Input nonlinearity types tried.
    """

    def __init__(self, max_degree: int = 5, types=("backlash", "backlash_inverse")):
        self.max_degree = max_degree
        self.types = tuple(types)

    def fit(self, levels: list[Level], warnings=()) -> "HistoryFit":
        """Fit on ``levels`` in recorded order; those with ``scored`` false (not settled) are not
        scored but the input's passage through them still moves F's state."""
        n_settled = sum(lv.scored for lv in levels)
        if n_settled < 4:
            raise HwidError(f"stage 1 from a recorded history needs at least 4 settled levels; found {n_settled} "
                            "(for records without held levels, `hwid run` fits the whole model)")
        names = list(dict.fromkeys(lv.record for lv in levels))
        u = np.array([lv.u for lv in levels if lv.scored])
        width = float(np.ptp(u)) or 1.0
        des = determinable.design(levels)
        if len(des.up) < 2:     # too few levels on the descending branch leave S^d and d- undetermined
            raise HwidError(determinable.refusal(des, "stage 1 from a recorded history",
                                                 " (or let `hwid run` fit the whole model)"))
        table, best = [], None
        for kind in self.types:
            for degree in range(1, min(self.max_degree, des.max_degree()) + 1):
                prob = _Problem(levels, names, kind, degree)
                if prob.n <= prob.n_outer + degree:
                    break
                sol = None
                for theta0 in prob.starts(width):
                    trial = optimize.least_squares(prob.residual, theta0, method="trf", max_nfev=400,
                                                   bounds=prob.bounds(width))
                    if sol is None or trial.cost < sol.cost:
                        sol = trial
                chi2 = float(sol.fun @ sol.fun)
                crit = chi2 + np.log(prob.n) * prob.n_outer + 2 * degree
                table.append({"type": kind, "degree": degree, "chi2": chi2, "criterion": float(crit)})
                if best is None or crit < best[0]:
                    best = (crit, prob, sol.x)
        if best is None:
            raise HwidError(f"stage 1 from a recorded history: {len(levels)} settled levels cannot determine "
                            "F and h (more levels, at more inputs, are needed)")
        _, prob, theta = best
        theta, verdict, note = _anchored(prob, theta, width)
        self.problem_, self.theta_, self.design_, self.verdict_ = prob, theta, des, verdict
        res = self._result(prob, theta, tuple(table), list(warnings) + ([note] if note else []))
        res, unbounded = _profiled(res, prob, theta, width)
        self.result_ = _honest(res, des, prob, theta, len(self.types) > 1, verdict, unbounded)
        return self

    @staticmethod
    def _result(prob: "_Problem", theta, table, warns) -> HistoryResult:
        c = prob.h(theta)
        full = np.concatenate([theta, c])
        r = prob.full_residual(full)
        chi2 = float(r @ r)
        dof = max(prob.n - full.size, 1)
        p = float(special.chdtrc(dof, chi2))
        misfit = p < 0.01
        jac = numeric_jacobian(prob.full_residual, full)
        norms = np.sqrt(np.sum(jac * jac, axis=0))
        norms[norms == 0] = 1.0
        cov = np.linalg.pinv((jac / norms).T @ (jac / norms)) / np.outer(norms, norms)
        # the levels' standard errors come from a few dozen samples each: where the chi-square
        # says they were optimistic, the intervals follow it (Birge ratio), never the other way
        cov = cov * max(1.0, chi2 / dof)
        if misfit:
            warns.append(f"misfit: chi2 = {chi2:.4g} on {dof} dof (p = {p:.2g}); the model does not reach the "
                         f"levels' own noise, intervals widened by sqrt(chi2/dof) = {np.sqrt(chi2 / dof):.3g}")
        z = special.ndtri(0.975)
        e_sd, e_gap = np.exp(theta[1]), np.exp(theta[2])
        # the reported quantities and their gradients in (d_plus, ln S^d, ln(d_plus - d_minus))
        quantities = {"d_plus": (theta[0], [1, 0, 0]), "slope_down": (e_sd, [0, e_sd, 0]),
                      "d_minus": (theta[0] - e_gap, [1, 0, -e_gap]), "dead_band": (e_gap, [0, 0, e_gap])}
        ci = {}
        for name, (value, g) in quantities.items():
            grad = np.zeros(full.size)
            grad[:3] = g
            sd = float(np.sqrt(max(grad @ cov @ grad, 0.0)))
            ci[name] = (float(value - z * sd), float(value + z * sd))
        sd_c = np.sqrt(np.clip(np.diag(cov)[prob.n_outer:], 0, None))
        ci["h_coefficients"] = [None] + [(float(a - z * s), float(a + z * s)) for a, s in zip(c, sd_c)]
        levels = tuple(Level(lv.record, lv.index, lv.u, lv.x, lv.se, lv.n, bool(s))
                       for lv, s in zip(prob.levels, prob.scored))
        # (c1..cp, d_plus, slope_down, d_minus) from (d_plus, ln S^d, ln(d_plus - d_minus), states, c)
        T = np.zeros((c.size + 3, full.size))
        T[np.arange(c.size), prob.n_outer + np.arange(c.size)] = 1.0
        T[c.size, 0] = 1.0
        T[c.size + 1, 1] = e_sd
        T[c.size + 2, 0], T[c.size + 2, 2] = 1.0, -e_gap
        cov_out = T @ cov @ T.T
        names = tuple(f"c{i + 1}" for i in range(c.size)) + ("d_plus", "slope_down", "d_minus")
        return HistoryResult(prob.type, float(e_sd), float(theta[0]), float(theta[0] - e_gap),
                             tuple([0.0] + [float(a) for a in c]), ci, chi2, int(dof), p, bool(misfit), levels,
                             table, tuple(warns), tuple(tuple(float(x) for x in row) for row in cov_out), names)


def _anchored(prob: "_Problem", theta, width: float):
    """``(theta, verdict, note)``: the fit moved to the reading the paper's assumption ``h^-1(0) = 0``
    picks among h_bar's root-shifted readings (:func:`hwid.identify.readings.assess`, the working
    range the hull of the fitted ``v`` of the scored levels; a move is exact: the gear's place in
    the play is a share of the band between the borders, which move together), and the warning
    line of a move (None without one)."""
    v = prob.v(theta)
    coef = np.concatenate([[0.0], prob.h(theta)])
    lo, hi = prob.bounds(width)
    sd, dp = float(np.exp(theta[1])), float(theta[0])

    def admissible(r):
        return (lo[0] <= r.d_plus <= hi[0] and r.dead_band > 0
                and lo[2] <= np.log(r.dead_band) <= hi[2])

    verdict = readings.assess(prob.type, sd, dp, dp - float(np.exp(theta[2])), coef,
                              (float(v.min()), float(v.max())), admissible)
    if not verdict.shifted:
        return theta, verdict, None
    moved = np.array(theta, float)
    moved[0], moved[2] = verdict.chosen.d_plus, np.log(verdict.chosen.dead_band)
    return moved, verdict, verdict.note(dp)


def _profiled(res: HistoryResult, prob: "_Problem", theta, width: float) -> tuple[HistoryResult, dict]:
    """``res`` with the 95 % intervals of d^+, S^d, d^- and the dead band from the chi-square's profile
    (:mod:`hwid.identify.history_profile`: F's recursion has corners in the borders, where the
    Gauss-Newton interval takes one side's curvature), the rise ``z^2`` times the Birge ratio the
    covariance is widened by; and, per quantity whose profile does not rise that far inside its
    search range on a side, the reason it is not bounded."""
    lo, hi = prob.bounds(width)
    z = special.ndtri(0.975)
    rise = z * z * max(1.0, res.chi2 / max(res.dof, 1))
    band = res.d_plus - res.d_minus
    coords = {      # quantity: (coordinate, free parameters' indices, Gauss-Newton sd there, back-transform)
        "d_plus": (history_profile.component(0, lo[0], hi[0]), 0, 1.0, float),
        "slope_down": (history_profile.component(1, lo[1], hi[1]), 1, 1.0 / res.slope_down, np.exp),
        "dead_band": (history_profile.component(2, lo[2], hi[2]), 2, 1.0 / band, np.exp),
        "d_minus": (history_profile.lower_border(lo[0] - np.exp(hi[2]), hi[0] - np.exp(lo[2])), 0, 1.0, float)}
    ci, unbounded = dict(res.ci), {}
    for name, (coord, fixed, scale, back) in coords.items():
        a, b = ci[name]
        step = scale * (b - a) / (2 * z)
        if not np.isfinite(step) or step <= 0:
            continue        # a zero-width or broken interval: determinable.interval_flaw reports it
        lo_p, hi_p = history_profile.interval(prob.residual, np.asarray(theta, float), coord, rise, step,
                                              np.delete(lo, fixed), np.delete(hi, fixed))
        if lo_p is None or hi_p is None:
            unbounded[name] = ("the levels do not bound it: the chi-square rises by less than "
                               f"{rise:.3g} up to the {'lower' if lo_p is None else 'upper'} edge of its search range")
            continue
        ci[name] = (float(back(lo_p)), float(back(hi_p)))
    return replace(res, ci=ci), unbounded


def _honest(res: HistoryResult, des, prob: "_Problem", theta, types_tried: bool,
            verdict: "readings.Verdict | None" = None, unbounded: dict | None = None) -> HistoryResult:
    """``res`` with every parameter the levels cannot determine (:mod:`hwid.identify.determinable`;
    the borders and h_bar also where h_bar's root-shifted readings leave them open,
    :mod:`hwid.identify.readings`), every interval of zero width or not finite
    (:func:`~hwid.identify.determinable.interval_flaw`) and every estimate at the edge of its search
    range reported as undetermined: interval None and the reason, one warning line each."""
    why = des.undetermined(prob.degree)
    for name, reason in (unbounded or {}).items():
        why.setdefault(name, reason)
    if verdict is not None and not verdict.determined:
        params = [*res.h_coefficients[1:], res.d_plus, res.slope_down, res.d_minus]
        res = replace(res, readings=tuple(verdict.to_dicts(prob.type, params, np.asarray(res.cov, float))))
        for name, reason in verdict.undetermined(res.ci["dead_band"]).items():
            why.setdefault(name, reason)
    lo, hi = prob.bounds(float(np.ptp([lv.u for lv in prob.levels if lv.scored])) or 1.0)
    edge = {"d_plus": 0, "slope_down": 1, "dead_band": 2}
    for name, i in edge.items():
        if name not in why and not lo[i] + 1e-6 * (hi[i] - lo[i]) < theta[i] < hi[i] - 1e-6 * (hi[i] - lo[i]):
            why[name] = (f"the estimate sits at the edge of its search range [{lo[i]:.4g}, {hi[i]:.4g}] (of "
                         f"{'ln ' if i else ''}{name}): these levels do not bound it")
    if "dead_band" in why and "d_minus" not in why:
        why["d_minus"] = why["dead_band"]
    for name in ("d_plus", "d_minus", "dead_band", "slope_down"):
        flaw = determinable.interval_flaw(getattr(res, name), res.ci[name])
        if name not in why and flaw:
            why[name] = flaw
    if "h_coefficients" not in why:
        for i, (c, interval) in enumerate(zip(res.h_coefficients, res.ci["h_coefficients"])):
            flaw = determinable.interval_flaw(c, interval) if i else None
            if flaw:
                why[f"c{i}"] = flaw
    if "adequacy" in why and types_tried:
        why["type"] = "with no degrees of freedom left, either type of F reproduces the levels"
    if not why:
        return res
    ci = dict(res.ci)
    for name in ("d_plus", "d_minus", "dead_band", "slope_down"):
        if name in why:
            ci[name] = None
    ci["h_coefficients"] = [None if "h_coefficients" in why or f"c{i}" in why else v
                            for i, v in enumerate(res.ci["h_coefficients"])]
    warns = list(res.warnings) + determinable.warning_lines(why)
    return replace(res, ci=ci, warnings=tuple(warns), undetermined=dict(why))


class _Problem:
    """The levels and the fixed choices of one fit (type, degree)."""

    def __init__(self, levels, names, kind: str, degree: int = 1):
        self.levels, self.names, self.type, self.degree = levels, names, kind, degree
        self.by_record = [[i for i, lv in enumerate(levels) if lv.record == name] for name in names]
        self.u = np.array([lv.u for lv in levels])
        self.scored = np.array([lv.scored for lv in levels], bool)
        if kind != "backlash":
            for idx in self.by_record:
                self.scored[idx[0]] = False
        self.x = np.array([lv.x for lv in levels])[self.scored]
        self.se = np.array([lv.se for lv in levels])[self.scored]

    @property
    def n(self) -> int:
        return int(self.scored.sum())

    @property
    def n_outer(self) -> int:
        return 3 + (len(self.names) if self.type == "backlash" else 0)

    def starts(self, width: float, keep: int = 6) -> list[np.ndarray]:
        """The ``keep`` best of a grid over the borders' place, the play's width and S^d. With a
        non-invertible h_bar the cost has a valley per way of folding the levels onto h_bar, so the
        grid spans the play up to 60 % of the input range and the borders' centre over +-30 %."""
        out = []
        for a in np.linspace(-0.3, 0.3, 7):
            for b in (0.02, 0.06, 0.15, 0.3, 0.45, 0.6):
                for ln_sd in (-0.4, 0.0, 0.4):
                    for frac in ((-6.0, 0.0, 6.0) if self.type == "backlash" else (0.0,)):
                        # a*width is the play's centre: d_plus sits half the play above it
                        out.append(np.array([(a + 0.5 * b) * width, ln_sd, np.log(b * width)]
                                            + [frac] * (self.n_outer - 3)))
        costs = [float(np.sum(self.residual(t) ** 2)) for t in out]
        order = np.argsort(costs)
        return [out[i] for i in order[:keep]]

    def bounds(self, width: float):
        lo = [-2.0 * width, np.log(0.05), np.log(1e-6 * width)] + [-30.0] * (self.n_outer - 3)
        hi = [2.0 * width, np.log(20.0), np.log(2.0 * width)] + [30.0] * (self.n_outer - 3)
        return np.array(lo), np.array(hi)

    def v(self, theta) -> np.ndarray:
        """``F_bar`` run over each record's levels (eqs. 7a-b, 14a-b, :meth:`InputNonlinearity.steady`),
        from the record's first level: for a backlash, the gear at the place inside the play that
        ``theta`` gives; for a Backlash-Inverse, that level is not scored."""
        dp, sd, dm = theta[0], np.exp(theta[1]), theta[0] - np.exp(theta[2])
        f = InputNonlinearity(self.type, 1.0, sd, dp, dm)
        v = np.empty(len(self.levels))
        for j, idx in enumerate(self.by_record):
            u = self.u[idx]
            state = 0.0
            if self.type == "backlash":
                lo, hi = f.ascending(u[0]), f.descending(u[0])
                state = lo + 0.5 * (1 + np.tanh(0.5 * theta[3 + j])) * (hi - lo)
            v[idx] = f.steady(u, state)
        return v[self.scored]

    def design(self, v) -> np.ndarray:
        return np.vander(v, self.degree + 1, increasing=True)[:, 1:] / self.se[:, None]

    def h(self, theta) -> np.ndarray:
        """h_bar's coefficients ``c_1..c_p`` for the outer parameters ``theta`` (weighted least squares)."""
        return np.linalg.lstsq(self.design(self.v(theta)), self.x / self.se, rcond=None)[0]

    def residual(self, theta) -> np.ndarray:
        """The weighted residuals with h_bar solved for (variable projection)."""
        return self.full_residual(np.concatenate([theta, self.h(theta)]))

    def full_residual(self, full) -> np.ndarray:
        theta, c = full[:self.n_outer], full[self.n_outer:]
        return self.x / self.se - self.design(self.v(theta)) @ c


def identify_history(records, resolution: float | None = None, max_degree: int = 5,
                     types=("backlash", "backlash_inverse")) -> HistoryResult:
    """Settle every level of ``records`` and fit stage 1 on them (the module docstring)."""
    levels, warns = settled_levels(records, resolution)
    return HistoryFit(max_degree, types).fit(levels, warns).result_


def identify_recorded(cfg, records) -> HistoryResult:
    """Stage 1 of a recorded plant's ``records`` with the config's settings (``plant.output_resolution``,
    ``identification.nonlinear.max_degree`` and ``input_type``)."""
    nl = cfg.identification.nonlinear
    types = ("backlash", "backlash_inverse") if nl.input_type == "auto" else (nl.input_type,)
    return identify_history(records, cfg.plant.output_resolution, nl.max_degree, types)
