"""The whole model by output error on any input (``identification.whole``).

Fits the normalised model of eqs. (4a-c) in one go: F (type; ``slope_up = 1``, ``slope_down``,
``d_plus``, ``d_minus``), a rational G(s) with ``G(0) = 1`` (structure selected) and h_bar (degree
selected, ``h_bar(0) = 0``), by least squares on the free-run (simulation) error of every
experiment, whatever its input: staircases, sines, random levels joined by ramps, a lab's log.
Each experiment's initial state is a nuisance parameter: the gear's place inside the play at its
first sample and the level at which G is at rest (as in :mod:`hwid.compare`).

h_bar enters linearly, so it is solved for at every step (variable projection, Golub and Pereyra):
the nonlinear search runs over F, G and the initial states only. G is a product of unit-gain
factors, stable with ``G(0) = 1`` (:mod:`hwid.identify.g_structure`).

The type, the structure (poles, pairs, zeros) and the degree of h_bar are chosen together by an
information criterion that charges F's, G's and the initial states' parameters as BIC does
(``ln n`` each) and h_bar's coefficients as AIC does (2 each): a degree too low biases the borders
and their intervals then miss the truth (with BIC throughout, a cubic h_bar was fitted as a
quadratic in one run in seven and the 95 % intervals of d^+ held the truth in 82 % of 60 runs),
while a degree too high only widens them; AIC throughout added needless poles to G.
Intervals: 95 %, from the Gauss-Newton covariance of all parameters (h_bar's coefficients
included) with the residual variance, widened by the residual's correlation time when the residual
is not white (a misfit, or coloured noise); the borders' and the slope's joined with those of the fit
one degree of h_bar higher (:meth:`WholeModelFit._result` says why).
"""
from __future__ import annotations

from dataclasses import replace
from typing import Sequence

import numpy as np
from scipy import optimize, special

from hwid import HwidError
from hwid.identify import determinable, readings
from hwid.identify.defaults import MAX_DEGREE, MAX_NFEV
from hwid.identify.g_structure import STRUCTURES, Structure, g_from_params, g_params_from, structure_of  # noqa: F401
from hwid.identify.result import WholeResult
from hwid.identify.whole_problem import Problem, best_states, border_grid, extent, table_row
from hwid.identify.whole_stats import central_grad, central_jacobian, correlation_time
from hwid.model import HWModel
from hwid.threads import forked_map, workers


class WholeModelFit:
    """Output-error fit of the whole normalised model (module docstring).

    Parameters
    ----------
    max_degree : int
        Highest degree of h_bar tried (degrees 1..max_degree, chosen by AIC).
    structures : sequence of Structure, optional
        G structures tried (default :data:`STRUCTURES`).
    delay : bool
        Also fit a pure delay of G; the selected fit keeps it only where it fits the records better
        than one more real pole or pole pair in its place
        (:func:`hwid.identify.whole_delay.pole_for_delay`). Without it, a selected G with zeros in
        the right half plane is tried with one more pole or pair the same way
        (:func:`~hwid.identify.whole_delay.pole_for_rhp_zero`).
    types : sequence of str
        Input nonlinearity types tried (``"backlash"``, ``"backlash_inverse"``).
    staged : bool
        Without a start: choose the type and G structure at h_bar's highest degree first, then only
        that pair's degrees (about a quarter of the fits of the full search, which tries every
        type, structure and degree).
    """

    def __init__(self, max_degree: int = MAX_DEGREE, structures: Sequence[Structure] | None = None,
                 delay: bool = False, types: Sequence[str] = ("backlash", "backlash_inverse"), max_nfev: int = MAX_NFEV,
                 staged: bool = False):
        self.max_degree = max_degree
        self.staged = staged
        self.structures = structures
        self.delay = delay
        self.types = types
        self.max_nfev = max_nfev

    def variant(self, structures=None, delay: bool | None = None, types=None) -> "WholeModelFit":
        """The same estimator with its structures, delay or types replaced (None: kept)."""
        return WholeModelFit(self.max_degree, self.structures if structures is None else structures,
                             self.delay if delay is None else delay, self.types if types is None else types,
                             self.max_nfev, self.staged)

    @classmethod
    def from_config(cls, cfg, staged: bool = False) -> "WholeModelFit":
        """The estimator of ``cfg.identification.whole``."""
        whole = cfg.identification.whole
        types = ("backlash", "backlash_inverse") if whole.input_type == "auto" else (whole.input_type,)
        return cls(max_degree=whole.max_degree, structures=[s for s in STRUCTURES if s.order <= whole.max_order],
                   delay=whole.delay, types=types, staged=staged)

    def fit(self, records, start: HWModel | None = None, borders=None) -> "WholeModelFit":
        """Fit on ``records`` (each with ``u``, ``y``, ``dt``); ``start`` (a normalised model, e.g.
        from the two stages) starts the search, otherwise a coarse grid over the borders does.

        From a start, the start's type, G structure (where :data:`STRUCTURES` holds it) and the
        degrees next to its h_bar's are tried; otherwise every type, structure and degree.
        ``borders`` (an input nonlinearity, e.g. stage 1 from the records' levels) fixes the type
        and starts the borders in place of the coarse grid, for every structure and degree."""
        records = [r for r in records if r.y is not None and r.u.size > 10]
        if not records:
            raise HwidError("the whole-model fit needs at least one experiment of more than 10 samples")
        borders = borders if start is None else None
        types = (start.input.type,) if start is not None else \
            ((borders.type,) if borders is not None else tuple(self.types))
        structures = list(self.structures or STRUCTURES)
        degrees = range(1, self.max_degree + 1)
        if start is not None:
            own = structure_of(start.linear)
            if own is not None:
                structures = [own]
            p = min(len(start.output.coefficients) - 1, self.max_degree)   # a start of a higher degree: the highest
            degrees = range(max(1, p - 1), min(self.max_degree, p + 1) + 1)
        search = _Search(self, records, start, borders)
        pairs = [(kind, structure) for kind in types for structure in structures]
        if self.staged and start is None and len(pairs) > 1:
            # type and G structure at h_bar's highest degree (a lower one misranks them where h_bar
            # is far from monotonic: the paper's quintic read as a cubic picked a wrong G and gap),
            # then every degree for the best of them
            mid = max(degrees)
            scored = [(rows[0]["aic"], kind, structure)
                      for rows, (kind, structure) in zip(search.paths([(k, g, [mid]) for k, g in pairs]), pairs)]
            pairs = [min(scored, key=lambda x: x[0])[1:]]
            # the winner's row at that degree is fitted again on its degree path below
            search.table[:] = [r for r in search.table
                               if (r["type"], r["structure"]) != (pairs[0][0], self._label(pairs[0][1]))]
        search.paths([(kind, structure, list(degrees)) for kind, structure in pairs])
        prob, theta, _ = search.best()
        lo, hi = prob.bounds(search.width, search.span, search.dt)
        moved = _other_origin(prob, theta, lo, hi, self.max_nfev)
        if moved is not None:
            search.again(prob, list(degrees), moved)
            prob, theta, _ = search.best()
        solutions = {k: v[:2] for k, v in search.solutions.items()}
        from hwid.identify.whole_delay import pole_for_delay, pole_for_rhp_zero
        pole = (pole_for_delay if self.delay else pole_for_rhp_zero)(prob, theta, search.width, search.span,
                                                                      search.dt, self.max_nfev)
        table = search.table
        if pole is not None:
            prob, theta, rss = pole
            table.append(table_row(prob, rss))
        self.hold(prob, theta, table, richer=solutions.get((prob.type, prob.structure, prob.degree + 1)))
        return self

    def _label(self, structure: Structure) -> str:
        """A selection-table row's structure: marked ``+delay`` where G's delay was fitted too."""
        return str(structure) + ("+delay" if self.delay else "")

    def fit_delay_added(self, records, borders=None) -> "WholeModelFit":
        """:meth:`fit` without a delay, then with G's delay where it can only improve on that
        (:func:`hwid.identify.whole_delay.fit_delay_added`)."""
        from hwid.identify.whole_delay import fit_delay_added
        return fit_delay_added(self, records, borders)

    def fit_rate_added(self) -> float | None:
        """After a fit: the input's slew rate added where the criterion prefers it
        (:func:`hwid.identify.whole_rate.fit_rate_added`); the rate kept, or None."""
        from hwid.identify.whole_rate import fit_rate_added
        return fit_rate_added(self)

    def fit_clip_added(self) -> tuple[float, float] | None:
        """After a fit: the input's limits added where the criterion prefers them
        (:func:`hwid.identify.whole_clip.fit_clip_added`); the limits kept, or None."""
        from hwid.identify.whole_clip import fit_clip_added
        return fit_clip_added(self)

    def fit_rate_first(self, records) -> "WholeModelFit":
        """The fit with the input's slew rate from the start, where the records say the input did
        not follow (:func:`hwid.identify.whole_rate.fit_rate_first`)."""
        from hwid.identify.whole_rate import fit_rate_first
        fit_rate_first(self, records)
        return self

    def fit_actuated(self, records, borders=None) -> "WholeModelFit":
        """The whole fit with every step the records may ask for, in order: G's delay by name
        (:meth:`fit_delay_added`), then the input's slew rate (:meth:`fit_rate_added`: a slow
        actuator the fit without it mimics with a G many times slower than the plant's), then its
        clip (:meth:`fit_clip_added`: an actuator that stops short, which the fit without it mimics
        with a bent F, G and h and a slew; its limits replace a rate that stood in for them). The
        selected fit keeps what it found (:meth:`WholeResult.model` with its actuator)."""
        self.fit_delay_added(records, borders)
        self.fit_rate_added()
        self.fit_clip_added()
        return self

    def start_values(self, records, kind, structure, start: HWModel | None, borders=None) -> np.ndarray:
        """Outer start values: from ``start`` where given, else from ``borders`` (G at its default
        start), else the best of a coarse border grid (h_bar of the highest degree solved for, G at
        its default start)."""
        if start is not None:
            f = start.input
            return np.array([f.d_plus, np.log(f.slope_down), np.log(max(f.d_plus - f.d_minus, 1e-6)),
                             *self._rest(records, structure, start.linear)], float)
        prob = Problem(records, kind, structure, self.max_degree, self.delay)
        grid = self.grid(records, structure)
        if borders is not None:
            # the borders (stage 1 from the levels) compete with the grid: from few levels they can
            # be far off while fitting those levels exactly, and the moving records then say so
            f = borders
            grid.insert(0, np.array([f.d_plus, np.log(f.slope_down), np.log(max(f.d_plus - f.d_minus, 1e-6)),
                                     *self._rest(records, structure)], float))
        costs = [float(np.sum(prob.residual(t) ** 2)) for t in grid]
        return grid[int(np.argmin(costs))]

    def grid(self, records, structure) -> list[np.ndarray]:
        """The coarse border grid's outer starts (:func:`border_grid`; G at its default start, each
        record's gear mid-play and G at rest at its first inputs)."""
        rest = self._rest(records, structure)
        return [np.array([d_plus, 0.0, log_gap, *rest]) for d_plus, log_gap in border_grid(records)]

    def _rest(self, records, structure, linear=None) -> list[float]:
        """The outer start values after F's three: G's (from ``linear``, else its default), the
        delay's, and each record's gear mid-play with G at rest at its first inputs."""
        span = max(r.u.size * r.dt for r in records)
        out = list(g_params_from(structure, linear, span, records[0].dt)) + ([0.0] if self.delay else [])
        for r in records:
            out += [0.0, float(np.median(r.u[: max(3, r.u.size // 50)]))]
        return out

    def hold(self, prob: Problem, theta, table, note: str = "", richer=None) -> None:
        """Make the fit ``theta`` of ``prob`` the selected one (``problem_``, ``theta_``, ``result_``
        with the selection ``table``), moved to the reading of h_bar's roots the paper's assumption
        picks (:func:`anchored`); ``note`` joins its warnings (what the model leaves out);
        ``richer`` as for :meth:`_result`."""
        theta, verdict, moved = anchored(prob, theta)
        self.problem_, self.theta_ = prob, theta
        res = self._result(prob, theta, table, richer, verdict)
        notes = tuple(n for n in (moved, note) if n)
        self.result_ = replace(res, warnings=res.warnings + notes) if notes else res

    def _result(self, prob: Problem, theta, table, richer=None, verdict=None) -> WholeResult:
        """The result of the selected fit; ``richer`` is ``(problem, theta)`` of the same type and
        structure with h_bar one degree higher, when it was fitted.

        The borders' and slope's intervals are the union of the selected fit's and the richer
        fit's: the criterion drops a weak top coefficient of h_bar now and then, the borders of
        a fit with too low a degree are biased and its intervals miss the truth, while the fit
        one degree up holds the truth's model and only widens them (post-selection honesty at
        the price of slightly wider intervals). ``verdict``: the fit's root-shifted readings
        (:func:`anchored`; found here when not given): where they are several, the borders and
        h_bar are undetermined and the result carries them."""
        verdict = verdict or anchored(prob, theta)[1]
        f, g, states = prob.unpack(theta)
        h = prob.h(theta)
        ci, s2, r, warnings, cov = self._intervals(prob, theta, h)
        if richer is not None:
            richer = (richer[0], _same_reading(*richer, f.d_plus))
            wider, *_ = self._intervals(*richer, richer[0].h(richer[1]))
            for name in ("d_plus", "d_minus", "slope_down"):
                ci[name] = (min(ci[name][0], wider[name][0]), max(ci[name][1], wider[name][1]))
        ci, why = _undetermined(prob, theta, ci, f, h)
        if not verdict.determined:
            why.update({k: v for k, v in verdict.undetermined().items() if k != "dead_band"})
            ci.update(d_plus=None, d_minus=None, h_coefficients=[None] * len(ci["h_coefficients"]))
        warnings += determinable.warning_lines(why)
        if prob.degree == self.max_degree:
            warnings.append(f"h_bar's degree is the highest tried ({self.max_degree}); a higher one may fit better")
        init = {rec.name: {"gear": gear, "rest": rest} for rec, (gear, rest) in zip(prob.records, states)}
        act = prob.actuator(theta)
        if act is not None and act.carried:
            for rec, pos in zip(prob.records, prob.positions(theta)):
                init[rec.name]["position"] = pos
        return WholeResult(f.type, f.slope_down, f.d_plus, f.d_minus, tuple(float(c) for c in h),
                           g.num, g.den, g.delay, str(prob.structure), ci, float(np.sqrt(s2)),
                           float(np.sqrt(np.mean(r * r))), int(r.size), init, tuple(table), tuple(warnings), act,
                           undetermined=why, readings=tuple(verdict.to_dicts(
                               f.type, np.r_[h[1:], f.d_plus, f.slope_down, f.d_minus], cov)))

    @staticmethod
    def _intervals(prob: Problem, theta, h) -> tuple[dict, float, np.ndarray, list, np.ndarray]:
        """95 % intervals of the borders, the slope and h_bar's coefficients ``h`` of the fit
        ``theta`` of ``prob``; with the residual variance, the residual, the warnings they raise and
        the covariance of ``(c_1..c_p, d^+, S^d, d^-)`` (for :mod:`hwid.identify.readings`)."""
        full = np.concatenate([theta, h[1:]])
        r = prob.full_residual(full)
        n, k = r.size, full.size
        s2 = float(r @ r) / max(n - k, 1)
        jac = central_jacobian(prob.full_residual, full)
        warnings = []
        # columns on one scale before inverting: h_bar's high powers make J's columns differ by many
        # orders of magnitude, and a pseudo-inverse would then zero whole directions (intervals of
        # width 0) instead of leaving them wide
        norms = np.sqrt(np.sum(jac * jac, axis=0))
        norms[norms == 0] = 1.0
        scaled = jac / norms
        try:
            cov = s2 * np.linalg.pinv(scaled.T @ scaled) / np.outer(norms, norms)
        except np.linalg.LinAlgError:
            cov = np.full((k, k), np.nan)
            warnings.append("the covariance could not be computed (singular Jacobian)")
        tau = correlation_time(r, [rec.u.size - int(rec.attrs.get("burn_in", 0)) for rec in prob.records])
        if tau > 1.5:
            warnings.append(f"the residual is correlated over {tau:.3g} samples (a misfit, or coloured noise): "
                            f"intervals widened by sqrt({tau:.3g}); the fit does not reach white noise")
        cov = cov * max(tau, 1.0)
        z = special.ndtri(0.975)
        # intervals of the reported quantities by the delta method on the outer parameters
        grads = {"d_plus": central_grad(lambda t: t[0], full),
                 "slope_down": central_grad(lambda t: np.exp(t[1]), full),
                 "d_minus": central_grad(lambda t: t[0] - np.exp(t[2]), full)}
        ci = {}
        for name, (value, grad) in grads.items():
            sd = float(np.sqrt(max(grad @ cov @ grad, 0.0)))
            ci[name] = (value - z * sd, value + z * sd)
        sd_h = np.sqrt(np.clip(np.diag(cov)[prob.n_outer:], 0, None))
        ci["h_coefficients"] = [None] + [(float(c - z * s), float(c + z * s)) for c, s in zip(h[1:], sd_h)]
        p = h.size - 1
        T = np.zeros((p + 3, full.size))
        T[np.arange(p), prob.n_outer + np.arange(p)] = 1.0
        T[p:] = [grads["d_plus"][1], grads["slope_down"][1], grads["d_minus"][1]]
        return ci, s2, r, warnings, T @ cov @ T.T



def _undetermined(prob: Problem, theta, ci: dict, f, h) -> tuple[dict, dict]:
    """``ci`` with every interval that cannot stand as one set to None, and ``{parameter: reason}``:
    not finite or of zero width (:func:`hwid.identify.determinable.interval_flaw`), not determined by
    records of stepped inputs (:func:`hwid.identify.determinable.whole_undetermined`), or the estimate
    at the edge of its search range (S^d at 0.05 or 20, the dead band at twice the input's range: the
    records do not bound it; a dead band at its floor is a plant without play, and stays)."""
    span, dt, width = extent(prob.records)
    lo, hi = prob.bounds(width, span, dt)
    why = {}
    for name, i in (("slope_down", 1), ("d_minus", 2)):
        margin = 1e-6 * (hi[i] - lo[i])
        if not (lo[i] + margin < theta[i] or i == 2) or not theta[i] < hi[i] - margin:
            why[name] = (f"the estimate sits at the edge of its search range [{np.exp(lo[i]):.4g}, "
                         f"{np.exp(hi[i]):.4g}] (of {'S^d' if i == 1 else 'd+ - d-'}): these records do not bound it")
    for name in ("d_plus", "d_minus", "slope_down"):
        flaw = determinable.interval_flaw(getattr(f, name), ci[name], positive=name == "slope_down")
        if flaw and name not in why:
            why[name] = flaw
    for i, (c, interval) in enumerate(zip(h, ci["h_coefficients"])):
        flaw = determinable.interval_flaw(c, interval) if i else None
        if flaw:
            why[f"c{i}"] = flaw
    for name, reason in determinable.whole_undetermined(prob.records, len(h) - 1).items():
        why.setdefault(name, reason)
    if not why:
        return ci, why
    out = {k: (None if k in why else v) for k, v in ci.items()}
    out["h_coefficients"] = [None if f"c{i}" in why else v for i, v in enumerate(ci["h_coefficients"])]
    return out, why


class _Search:
    """The selection's search in one :meth:`WholeModelFit.fit`: each type and structure's path over
    h_bar's degrees, the table of every fit tried (``table``) and the best fit of each type,
    structure and degree (``solutions``: ``(problem, theta, criterion)``)."""

    def __init__(self, fitter: WholeModelFit, records, start: HWModel | None, borders):
        self.fitter, self.records, self.start, self.borders = fitter, records, start, borders
        self.span, self.dt, self.width = extent(records)
        self.table: list = []
        self.solutions: dict = {}

    def path(self, kind, structure, degs, first=None) -> list:
        """Fits of h_bar's degrees ``degs`` in order, each from the start (``first``, or
        :meth:`WholeModelFit.start_values`'s) and from the one before."""
        fitter, records, delay = self.fitter, self.records, self.fitter.delay
        if first is None:
            first = best_states(Problem(records, kind, structure, max(degs), delay),
                                fitter.start_values(records, kind, structure, self.start, self.borders),
                                rest_at_gear=self.start is not None)
        theta0, rows = None, []
        for degree in degs:
            prob = Problem(records, kind, structure, degree, delay)
            lo, hi = prob.bounds(self.width, self.span, self.dt)
            # from the start and from the fit one degree lower: the cost is only piecewise
            # smooth in the borders (a sample switches between held and moving gear), and
            # either path alone can stop in a shallow local minimum
            sol = None
            for t0 in (first, theta0):
                if t0 is None:
                    continue
                trial = optimize.least_squares(prob.residual, np.clip(t0, lo + 1e-9, hi - 1e-9),
                                               bounds=(lo, hi), method="trf", x_scale=1.0,
                                               max_nfev=fitter.max_nfev)
                if sol is None or trial.cost < sol.cost:
                    sol = trial
            row = table_row(prob, float(sol.fun @ sol.fun))
            self._keep((kind, structure, degree), prob, sol.x, float(row["aic"]))
            rows.append(row)
            theta0 = sol.x
        self.table.extend(rows)
        return rows

    def _keep(self, key, prob, x, aic: float) -> None:
        if key not in self.solutions or aic < self.solutions[key][2]:
            self.solutions[key] = (prob, x, aic)

    def paths(self, jobs) -> list:
        """:meth:`path` for each ``(kind, structure, degrees)``, on every core
        (:func:`hwid.threads.forked_map`): each path's rows, in order, with the table and the
        solutions merged as one process would have them."""
        def one(job):
            before = {k: id(v) for k, v in self.solutions.items()}
            rows = self.path(*job)
            return rows, {k: v[1:] for k, v in self.solutions.items() if before.get(k) != id(v)}
        if min(workers(), len(jobs)) <= 1:
            return [self.path(*job) for job in jobs]
        out = []
        for rows, added in forked_map(one, jobs):      # the workers' rows and solutions, merged
            self.table.extend(rows)
            for (kind, structure, degree), (x, aic) in added.items():
                if (kind, structure, degree) not in self.solutions or aic < self.solutions[kind, structure, degree][2]:
                    self.solutions[kind, structure, degree] = (
                        Problem(self.records, kind, structure, degree, self.fitter.delay), x, aic)
            out.append(rows)
        return out

    def best(self) -> tuple:
        """``(problem, theta, criterion)`` of the best fit so far."""
        return self.solutions[min(self.solutions, key=lambda k: self.solutions[k][2])]

    def again(self, prob, degrees, moved) -> None:
        """The selected fit sat at another origin of h_bar: its type and structure's degree path
        again from the one found there (``moved``), so the degree is chosen among fits there."""
        own = (prob.type, prob.label)
        before = {r["degree"]: r for r in self.table if (r["type"], r["structure"]) == own}
        self.table[:] = [r for r in self.table if (r["type"], r["structure"]) != own]
        for row in self.path(prob.type, prob.structure, degrees, first=moved):
            old = before.get(row["degree"])
            if old is not None and old["aic"] < row["aic"]:   # the table keeps what solutions keeps
                self.table[self.table.index(row)] = old


def anchored(prob: Problem, theta):
    """``(theta, verdict, note)``: the fit ``theta`` moved (:func:`_moved`) to the reading of h_bar's
    real roots that the paper's assumption ``h^-1(0) = 0`` picks on the range of the fit's ``w``
    (:func:`hwid.identify.readings.assess`), and the warning line of a move (None without one).

    Each record's G starts at rest at a fitted level and its gear at a share of the band between
    the borders, and both move with F's output: a shift to another root is exactly equivalent on
    any records. Still, a reading counts as a rival only where its residual sum of squares is within
    ``chi2_{1, 0.95} s^2`` of the fit's; with no root in the range, only readings within the search
    range (the dead band's bounds, d+ within twice the input's range of it)."""
    w = prob.w(theta)
    f, _, _ = prob.unpack(theta)
    r = prob.residual(theta)
    rss = float(r @ r)
    s2 = rss / max(r.size - prob.n_outer - prob.degree, 1)
    span, dt, width = extent(prob.records)
    lo, hi = prob.bounds(width, span, dt)
    u = np.concatenate([rec.u for rec in prob.records])
    bound = special.chdtri(1, 0.05) * s2

    def admissible(rd):
        return (float(u.min()) - 2 * width <= rd.d_plus <= float(u.max()) + 2 * width and rd.dead_band > 0
                and lo[2] <= np.log(rd.dead_band) <= hi[2])

    def alike(rd):
        e = prob.residual(_moved(prob, theta, rd.shift))
        return float(e @ e) - rss <= bound

    verdict = readings.assess(f.type, f.slope_down, f.d_plus, f.d_minus, prob.h(theta),
                              (float(w.min()), float(w.max())), admissible, alike)
    if not verdict.shifted:
        return theta, verdict, None
    return _moved(prob, theta, verdict.chosen.shift), verdict, verdict.note(f.d_plus)


def _same_reading(prob: Problem, theta, d_plus: float) -> np.ndarray:
    """``theta`` moved to its reading (:func:`anchored`), or where that leaves several, to the one
    whose d+ is nearest ``d_plus``: the richer fit's intervals join the selected fit's in one reading."""
    moved, verdict, _ = anchored(prob, theta)
    if verdict.determined:
        return moved
    return _moved(prob, theta, min(verdict.readings, key=lambda r: abs(r.d_plus - d_plus)).shift)


def _origins(prob: Problem, theta) -> list[float]:
    """Other places ``x0`` of h_bar's argument where h_bar is nearly zero (a local minimum of
    ``|h_bar|`` under a tenth of its range) within what the fit's ``w`` spans.

    ``h_bar(0) = 0`` fixes the origin of h_bar's argument only up to h_bar's other (near) zeros: F
    moved by ``-x0`` at its output, G's rest levels with it, and h_bar moved by ``x0`` describe
    nearly the same records. The fit can settle at such a second origin (a quintic h_bar with a
    near-zero half the play away: the paper's plant from a lab log stopped there at 1.5x the noise
    with its borders moved by half the play)."""
    w = prob.w(theta)
    h = np.concatenate([[0.0], prob._solve(w)])
    xs = np.linspace(float(w.min()), float(w.max()), 401)
    hv = np.abs(np.polyval(h[::-1], xs))
    tol = 0.1 * float(hv.max())
    away = 0.05 * float(np.ptp(xs))
    return [float(xs[i]) for i in range(1, xs.size - 1)
            if hv[i] <= hv[i - 1] and hv[i] <= hv[i + 1] and hv[i] < tol and abs(xs[i]) > away]


def _moved(prob: Problem, theta, x0: float) -> np.ndarray:
    """``theta`` with the origin of h_bar's argument moved to ``x0``: F's output less ``x0``
    (a Backlash's borders at ``d + x0 / S``, a Backlash-Inverse's branches at ``d - x0``) and each
    record's G rest level less ``x0``; the gear's place in its band and G unchanged."""
    t = np.array(theta, float)
    d_plus, slope, d_minus = t[0], np.exp(t[1]), t[0] - np.exp(t[2])
    if prob.type == "backlash":
        d_plus, d_minus = d_plus + x0, d_minus + x0 / slope
    else:
        d_plus, d_minus = d_plus - x0, d_minus - x0
    t[0], t[2] = d_plus, np.log(max(d_plus - d_minus, 1e-9))
    j = prob.states_at
    t[j + 1::2] -= x0
    return t


def _other_origin(prob: Problem, theta, lo, hi, max_nfev: int):
    """The fit of ``prob`` from each of h_bar's other origins (:func:`_origins`); the outer
    parameters of the best, where it fits the records better than ``theta``, else None."""
    best = float(np.sum(prob.residual(theta) ** 2))
    found = None
    for x0 in _origins(prob, theta):
        t = best_states(prob, np.clip(_moved(prob, theta, x0), lo + 1e-9, hi - 1e-9))
        sol = optimize.least_squares(prob.residual, t, bounds=(lo, hi), method="trf", x_scale=1.0,
                                     max_nfev=max_nfev)
        if 2 * sol.cost < best * (1 - 1e-6):
            best, found = 2 * sol.cost, sol.x
    return found


def fit_records(records, periods: int = 3):
    """The experiments as the whole-model fit takes them: a sine experiment (attribute ``omega``)
    cut to its last ``periods`` periods, the first of them a burn-in left out of the cost (its
    steady state is what matters, and its length would dominate the cost); others whole."""
    out = []
    for r in records:
        omega = r.attrs.get("omega")
        if omega:
            n_period = int(np.ceil(2 * np.pi / float(omega) / r.dt))
            start = max(0, r.u.size - periods * n_period)
            attrs = {**r.attrs, "burn_in": min(n_period, r.u.size - start - 1)}
            r = replace(r, u=r.u[start:], y=r.y[start:], v=None, w=None, x=None, z=None, attrs=attrs)
        out.append(r)
    return out
