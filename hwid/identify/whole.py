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

from dataclasses import dataclass, field, replace
from typing import Sequence

import numpy as np
from numba import njit
from scipy import optimize, special

from hwid import HwidError
from hwid.blocks.slew import slewed
from hwid.identify.g_structure import STRUCTURES, Structure, g_from_params, g_params_from, structure_of
from hwid.identify.result import WholeResult
from hwid.identify.whole_stats import central_grad, central_jacobian, correlation_time
from hwid.model import Actuator, HWModel, InputNonlinearity
from hwid.threads import forked_map, workers


@dataclass
class _Problem:
    """The data and the fixed choices of one fit (F type, G structure, h degree, delay or not)."""

    records: list
    type: str
    structure: Structure
    degree: int
    with_delay: bool
    #: the input slews at most a fitted rate before F (a slow actuator the records show; see
    #: :func:`hwid.identify.whole_rate.fit_rate_added`)
    with_rate: bool = False
    #: the input is clipped to a fitted ``[u_lo, u_hi]`` before F (an actuator that stops short of
    #: the commanded range; see :func:`hwid.identify.whole_clip.fit_clip_added`)
    with_clip: bool = False
    #: with a rate: the actuator's position carries over from each record to the next (the records
    #: in the order they were run, as on a rig whose actuator nobody resets), rather than starting
    #: at each record's first input
    carried: bool = False
    y: np.ndarray = field(init=False)

    def __post_init__(self):
        # a record's attribute "burn_in" (samples) leaves its first samples out of the cost: a
        # stretch cut from a longer experiment starts in a state the nuisance parameters only
        # approximate (the gear and G at rest)
        self.keep = np.concatenate([np.arange(r.u.size) >= int(r.attrs.get("burn_in", 0)) for r in self.records])
        self.y = np.concatenate([r.y for r in self.records])[self.keep]

    @property
    def n_outer(self) -> int:
        return self.states_at + 2 * len(self.records)

    @property
    def states_at(self) -> int:
        """Index of the first record's initial state in the outer parameters (after F's three,
        G's, the delay's, the rate's and the clip's two)."""
        return self.clip_at + 2 * int(self.with_clip)

    @property
    def clip_at(self) -> int:
        """Index of the clip's lower limit in the outer parameters (where it has one; the upper follows)."""
        return self.rate_at + int(self.with_rate)

    @property
    def rate_at(self) -> int:
        """Index of the slew rate's logarithm in the outer parameters (where it has one)."""
        return 3 + self.structure.n_params + int(self.with_delay)

    def unpack(self, theta):
        """``(F, G, [(gear, rest), ...])`` of the outer parameters ``theta``."""
        f, g, states, _ = self._unpacked(theta)
        return f, g, states

    def actuated(self, theta) -> list[np.ndarray]:
        """Each record's input as the actuator passes it on: clipped, then slewed (from the
        previous record's last position where it is ``carried``)."""
        rate, clip = self.rate(theta), self.clip(theta)
        out, last = [], None
        for r in self.records:
            u = r.u if clip is None else np.clip(r.u, *clip)
            if rate is not None:
                u = slewed(u, rate, r.dt, start=last if self.carried else None)
                last = float(u[-1]) if u.size else last
            out.append(u)
        return out

    def positions(self, theta) -> list[float | None]:
        """Where the slew starts each record (:meth:`actuated`): the previous record's last actuated
        input where it is ``carried`` (the first record's clipped first input), else None."""
        if self.rate(theta) is None or not self.carried:
            return [None] * len(self.records)
        clip = self.clip(theta)
        out, last = [], None
        for r, a in zip(self.records, self.actuated(theta)):
            first = float(r.u[0] if clip is None else np.clip(r.u[0], *clip)) if r.u.size else None
            out.append(first if last is None else last)
            last = float(a[-1]) if a.size else last
        return out

    def actuator(self, theta) -> Actuator | None:
        """The fit's actuator (:class:`hwid.model.Actuator`): its clip and slew rate, or None."""
        clip, rate = self.clip(theta), self.rate(theta)
        if clip is None and rate is None:
            return None
        return Actuator(clip=clip, rate=rate, carried=bool(self.carried and rate is not None))

    def _unpacked(self, theta):
        """``(F, G, states, actuated inputs)`` of ``theta``."""
        d_plus, log_sd, gap = theta[0], theta[1], theta[2]
        f = InputNonlinearity(self.type, 1.0, float(np.exp(log_sd)), float(d_plus), float(d_plus - np.exp(gap)))
        k = 3 + self.structure.n_params
        delay = float(abs(theta[k])) if self.with_delay else 0.0
        g = g_from_params(self.structure, theta[3:3 + self.structure.n_params], delay)
        inputs = self.actuated(theta)
        states = []
        j = self.states_at
        for u in inputs:
            # a Backlash-Inverse's start is anywhere its branches reach over the record, not only
            # between their values at u[0] (a record that opens with a hold shows it all along)
            lo, hi = f.start_band(u)
            frac = 0.5 * (1.0 + np.tanh(0.5 * theta[j]))
            states.append((lo + frac * (hi - lo), float(theta[j + 1])))
            j += 2
        return f, g, states, inputs

    def w(self, theta) -> np.ndarray:
        f, g, states, inputs = self._unpacked(theta)
        out = [g.simulate(f.apply(u, gear), r.dt, rest) for r, u, (gear, rest) in zip(self.records, inputs, states)]
        return np.concatenate(out)[self.keep]

    @property
    def label(self) -> str:
        """Its selection-table row's structure: G's, marked ``+delay``, ``+rate`` and ``+clip`` where
        those were fitted too."""
        return (str(self.structure) + "+delay" * self.with_delay + "+rate" * self.with_rate
                + " carried" * (self.with_rate and self.carried) + "+clip" * self.with_clip)

    def rate(self, theta) -> float | None:
        """The input's slew rate (units/s), or None without one."""
        if not self.with_rate:
            return None
        return float(np.exp(theta[self.rate_at]))

    def clip(self, theta) -> tuple[float, float] | None:
        """The input's limits ``(u_lo, u_hi)``, or None without them."""
        if not self.with_clip:
            return None
        return float(theta[self.clip_at]), float(theta[self.clip_at + 1])

    def clip_bounds(self) -> tuple[tuple[float, float], tuple[float, float]]:
        """Where the limits may go: ``u_lo`` from 5 % of the input's range below its least value to
        its centre, ``u_hi`` from the centre to 5 % above its greatest (beyond, a limit is no limit)."""
        u = np.concatenate([r.u for r in self.records])
        a, b = float(u.min()), float(u.max())
        c, m = 0.5 * (a + b), 0.05 * (b - a)
        return (a - m, c), (c, b + m)

    def design(self, w) -> np.ndarray:
        return np.vander(w, self.degree + 1, increasing=True)[:, 1:]

    def bounds(self, u_width: float, span_s: float, dt: float) -> tuple[np.ndarray, np.ndarray]:
        """Where the outer parameters may go: borders within twice the input's range, G's rates
        between a hundredth of the record's inverse length and ten times the sampling rate."""
        lo = [-np.inf, np.log(0.05), np.log(1e-6 * u_width)]
        hi = [np.inf, np.log(20.0), np.log(2.0 * u_width)]
        rate_lo, rate_hi = np.log(0.01 / span_s), np.log(10.0 / dt)
        for _ in range(self.structure.poles):
            lo.append(rate_lo)
            hi.append(rate_hi)
        for _ in range(self.structure.pairs):
            lo += [rate_lo, np.log(0.01)]
            hi += [rate_hi, np.log(10.0)]
        for _ in range(self.structure.zeros):
            lo.append(-span_s)
            hi.append(span_s)
        if self.with_delay:
            lo.append(0.0)
            hi.append(0.5 * span_s)
        if self.with_rate:     # from crossing the input's range in two minutes to in one sample
            lo.append(np.log(u_width / 120.0))
            hi.append(np.log(u_width / dt))
        if self.with_clip:
            (lo_a, lo_b), (hi_a, hi_b) = self.clip_bounds()
            lo += [lo_a, hi_a]
            hi += [lo_b, hi_b]
        for _ in self.records:
            lo += [-30.0, -np.inf]
            hi += [30.0, np.inf]
        return np.array(lo), np.array(hi)

    def residual(self, theta) -> np.ndarray:
        """The output error with h_bar solved for (variable projection)."""
        try:
            w = self.w(theta)
        except (np.linalg.LinAlgError, ValueError, FloatingPointError):
            return np.full(self.y.size, 1e6)
        if not np.all(np.isfinite(w)) or np.max(np.abs(w)) > 1e6:
            return np.full(self.y.size, 1e6)
        return _poly_residual(w, self.y, self._solve(w))

    def _solve(self, w) -> np.ndarray:
        """h_bar's coefficients (powers 1..degree) for the argument ``w``: the normal equations of
        the design ``[w, w^2, ...]`` from w's power sums (one pass, no tall matrix), with the
        columns scaled to unit norm (p <= 9 columns)."""
        sums, rhs = _power_sums(w, self.y, self.degree)
        p = self.degree
        gram = np.array([[sums[i + j] for j in range(1, p + 1)] for i in range(1, p + 1)])
        norms = np.sqrt(np.diag(gram).copy())
        norms[norms == 0] = 1.0
        try:
            c = np.linalg.solve(gram / np.outer(norms, norms), rhs / norms)
        except np.linalg.LinAlgError:
            scaled = self.design(w) / norms
            c = np.linalg.lstsq(scaled, self.y, rcond=None)[0]
        return c / norms

    def h(self, theta) -> np.ndarray:
        return np.concatenate([[0.0], self._solve(self.w(theta))])

    def full_residual(self, full) -> np.ndarray:
        """The output error of outer parameters and h_bar's coefficients together (for the covariance)."""
        theta, c = full[:self.n_outer], full[self.n_outer:]
        return self.y - self.design(self.w(theta)) @ c


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

    def __init__(self, max_degree: int = 5, structures: Sequence[Structure] | None = None, delay: bool = False,
                 types: Sequence[str] = ("backlash", "backlash_inverse"), max_nfev: int = 200,
                 staged: bool = False):
        self.max_degree = max_degree
        self.staged = staged
        self.structures = structures
        self.delay = delay
        self.types = types
        self.max_nfev = max_nfev

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
            p = len(start.output.coefficients) - 1
            degrees = range(max(1, p - 1), min(self.max_degree, p + 1) + 1)
        span, dt, width = _extent(records)
        table, solutions = [], {}

        def path(kind, structure, degs, first=None):
            """Fits of h_bar's degrees ``degs`` in order, each from the start (``first``, or
            :meth:`_start`'s) and from the one before."""
            if first is None:
                first = _best_states(_Problem(records, kind, structure, max(degs), self.delay),
                                     self._start(records, kind, structure, start, borders))
            theta0, rows = None, []
            for degree in degs:
                prob = _Problem(records, kind, structure, degree, self.delay)
                lo, hi = prob.bounds(width, span, dt)
                # from the start and from the fit one degree lower: the cost is only piecewise
                # smooth in the borders (a sample switches between held and moving gear), and
                # either path alone can stop in a shallow local minimum
                sol = None
                for t0 in (first, theta0):
                    if t0 is None:
                        continue
                    trial = optimize.least_squares(prob.residual, np.clip(t0, lo + 1e-9, hi - 1e-9),
                                                   bounds=(lo, hi), method="trf", x_scale=1.0,
                                                   max_nfev=self.max_nfev)
                    if sol is None or trial.cost < sol.cost:
                        sol = trial
                row = _row(prob, float(sol.fun @ sol.fun))
                aic = row["aic"]
                if (kind, structure, degree) not in solutions or aic < solutions[kind, structure, degree][2]:
                    solutions[kind, structure, degree] = (prob, sol.x, float(aic))
                rows.append(row)
                theta0 = sol.x
            table.extend(rows)
            return rows

        def paths(jobs):
            """:func:`path` for each ``(kind, structure, degrees)``, on every core
            (:func:`hwid.threads.forked_map`): each path's rows, in order, with the table and the
            solutions merged as one process would have them."""
            def one(job):
                before = {k: id(v) for k, v in solutions.items()}
                rows = path(*job)
                return rows, {k: v[1:] for k, v in solutions.items() if before.get(k) != id(v)}
            if min(workers(), len(jobs)) <= 1:
                return [path(*job) for job in jobs]
            out = []
            for rows, added in forked_map(one, jobs):      # the workers' rows and solutions, merged
                table.extend(rows)
                for (kind, structure, degree), (x, aic) in added.items():
                    if (kind, structure, degree) not in solutions or aic < solutions[kind, structure, degree][2]:
                        solutions[kind, structure, degree] = (_Problem(records, kind, structure, degree, self.delay),
                                                              x, aic)
                out.append(rows)
            return out

        pairs = [(kind, structure) for kind in types for structure in structures]
        if self.staged and start is None and len(pairs) > 1:
            # type and G structure at h_bar's highest degree (a lower one misranks them where h_bar
            # is far from monotonic: the paper's quintic read as a cubic picked a wrong G and gap),
            # then every degree for the best of them
            mid = max(degrees)
            scored = [(rows[0]["aic"], kind, structure)
                      for rows, (kind, structure) in zip(paths([(k, g, [mid]) for k, g in pairs]), pairs)]
            pairs = [min(scored, key=lambda x: x[0])[1:]]
            # the winner's row at that degree is fitted again on its degree path below
            table[:] = [r for r in table if (r["type"], r["structure"]) != (pairs[0][0], self._label(pairs[0][1]))]
        paths([(kind, structure, list(degrees)) for kind, structure in pairs])
        key = min(solutions, key=lambda k: solutions[k][2])
        prob, theta, _ = solutions[key]
        lo, hi = prob.bounds(width, span, dt)
        moved = _other_origin(prob, theta, lo, hi, self.max_nfev)
        if moved is not None:
            # the selected fit sat at another origin of h_bar: its type and structure's degree
            # path again from the one found there, so the degree is chosen among fits there
            own = (prob.type, prob.label)
            before = {r["degree"]: r for r in table if (r["type"], r["structure"]) == own}
            table[:] = [r for r in table if (r["type"], r["structure"]) != own]
            for row in path(prob.type, prob.structure, list(degrees), first=moved):
                old = before.get(row["degree"])
                if old is not None and old["aic"] < row["aic"]:   # the table keeps what solutions keeps
                    table[table.index(row)] = old
            key = min(solutions, key=lambda k: solutions[k][2])
        best = (solutions[key][2], solutions[key][0], solutions[key][1])
        solutions = {k: v[:2] for k, v in solutions.items()}
        _, prob, theta = best
        from hwid.identify.whole_delay import pole_for_delay, pole_for_rhp_zero
        pole = (pole_for_delay if self.delay else pole_for_rhp_zero)(prob, theta, width, span, dt, self.max_nfev)
        if pole is not None:
            prob, theta, rss = pole
            table.append(_row(prob, rss))
        self.problem_, self.theta_ = prob, theta
        self.result_ = self._result(prob, theta, table, solutions.get((prob.type, prob.structure, prob.degree + 1)))
        return self

    def _label(self, structure: Structure) -> str:
        """A selection-table row's structure: marked ``+delay`` where G's delay was fitted too."""
        return str(structure) + ("+delay" if self.delay else "")

    def fit_delay_added(self, records, borders=None) -> "WholeModelFit":
        """:meth:`fit` without a delay, then with G's delay where it can only improve on that
        (:func:`hwid.identify.whole_delay.fit_delay_added`)."""
        from hwid.identify.whole_delay import fit_delay_added
        return fit_delay_added(self, records, borders)

    def _start(self, records, kind, structure, start: HWModel | None, borders=None) -> np.ndarray:
        """Outer start values: from ``start`` where given, else from ``borders`` (G at its default
        start), else the best of a coarse border grid (h_bar of the highest degree solved for, G at
        its default start)."""
        if start is not None:
            f = start.input
            return np.array([f.d_plus, np.log(f.slope_down), np.log(max(f.d_plus - f.d_minus, 1e-6)),
                             *self._rest(records, structure, start.linear)], float)
        prob = _Problem(records, kind, structure, self.max_degree, self.delay)
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

    def hold(self, prob: _Problem, theta, table, note: str = "") -> None:
        """Make the fit ``theta`` of ``prob`` the selected one (``problem_``, ``theta_``, ``result_``
        with the selection ``table``); ``note`` joins its warnings (what the model leaves out)."""
        self.problem_, self.theta_ = prob, theta
        res = self._result(prob, theta, table)
        self.result_ = replace(res, warnings=res.warnings + (note,)) if note else res

    def _result(self, prob: _Problem, theta, table, richer=None) -> WholeResult:
        """The result of the selected fit; ``richer`` is ``(problem, theta)`` of the same type and
        structure with h_bar one degree higher, when it was fitted.

        The borders' and slope's intervals are the union of the selected fit's and the richer
        fit's: the criterion drops a weak top coefficient of h_bar now and then, the borders of
        a fit with too low a degree are biased and its intervals miss the truth, while the fit
        one degree up holds the truth's model and only widens them (post-selection honesty at
        the price of slightly wider intervals)."""
        f, g, states = prob.unpack(theta)
        h = prob.h(theta)
        ci, s2, r, warnings = self._intervals(prob, theta, h)
        if richer is not None:
            wider, *_ = self._intervals(*richer, richer[0].h(richer[1]))
            for name in ("d_plus", "d_minus", "slope_down"):
                ci[name] = (min(ci[name][0], wider[name][0]), max(ci[name][1], wider[name][1]))
        if prob.degree == self.max_degree:
            warnings.append(f"h_bar's degree is the highest tried ({self.max_degree}); a higher one may fit better")
        init = {rec.name: {"gear": gear, "rest": rest} for rec, (gear, rest) in zip(prob.records, states)}
        act = prob.actuator(theta)
        if act is not None and act.carried:
            for rec, pos in zip(prob.records, prob.positions(theta)):
                init[rec.name]["position"] = pos
        return WholeResult(f.type, f.slope_down, f.d_plus, f.d_minus, tuple(float(c) for c in h),
                           g.num, g.den, g.delay, str(prob.structure), ci, float(np.sqrt(s2)),
                           float(np.sqrt(np.mean(r * r))), int(r.size), init, tuple(table), tuple(warnings), act)

    @staticmethod
    def _intervals(prob: _Problem, theta, h) -> tuple[dict, float, np.ndarray, list]:
        """95 % intervals of the borders, the slope and h_bar's coefficients ``h`` of the fit
        ``theta`` of ``prob``; with the residual variance, the residual and the warnings they raise."""
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
        ci["h_coefficients"] = [(0.0, 0.0)] + [(float(c - z * s), float(c + z * s)) for c, s in zip(h[1:], sd_h)]
        return ci, s2, r, warnings


def border_grid(records) -> list[tuple[float, float]]:
    """The coarse grid of borders a fit without a start begins from: ``(d_plus, log(d_plus -
    d_minus))`` with ``d_plus`` across the middle half of the input's range about its median and
    the play 2 %, 10 %, 30 % and 60 % of the range."""
    u = np.concatenate([r.u for r in records])
    width, centre = float(np.ptp(u)) or 1.0, float(np.median(u))
    return [(centre + a * width, float(np.log(b * width)))
            for a in np.linspace(-0.25, 0.25, 7) for b in (0.02, 0.1, 0.3, 0.6)]


def _extent(records) -> tuple[float, float, float]:
    """``(span, dt, width)``: the longest record (s), the shortest sampling time and the input's range."""
    return (max(r.u.size * r.dt for r in records), min(r.dt for r in records),
            float(np.ptp(np.concatenate([r.u for r in records]))) or 1.0)


def _row(prob: _Problem, rss: float) -> dict:
    """A selection-table row of the fit of ``prob`` with residual sum of squares ``rss``."""
    k = prob.n_outer + prob.degree
    return {"type": prob.type, "structure": prob.label, "degree": prob.degree, "rss": rss, "parameters": k,
            "aic": _criterion(rss, prob.y.size, k, prob.degree)}


def _descend(probs, starts, max_nfev: int) -> list[tuple[np.ndarray, float]]:
    """Each ``probs[i]`` fitted from ``starts[i]`` within its bounds, on every core: ``(theta, rss)``."""
    span, dt, width = _extent(probs[0].records)

    def one(i):
        lo, hi = probs[i].bounds(width, span, dt)
        sol = optimize.least_squares(probs[i].residual, np.clip(starts[i], lo + 1e-9, hi - 1e-9), bounds=(lo, hi),
                                     method="trf", x_scale=1.0, max_nfev=max_nfev)
        return sol.x, float(sol.fun @ sol.fun)
    return forked_map(one, range(len(probs)))


def _criterion(rss: float, n: int, k: int, degree: int) -> float:
    """The selection's criterion of a fit with ``k`` parameters, ``degree`` of them h_bar's: BIC's
    penalty on F, G and the initial states, AIC's on h_bar's coefficients (the module docstring
    says why)."""
    return float(n * np.log(rss / n) + (k - degree) * np.log(n) + 2 * degree)


def _best_states(prob: _Problem, theta) -> np.ndarray:
    """``theta`` with each experiment's initial gear put where it fits best of: against the lower
    border, in the middle of the play, against the upper one (a Backlash-Inverse: nine places
    across its branches' range; one experiment at a time). The gear's
    place enters through a tanh: started on the wrong side, the search stalls where the tanh is flat."""
    theta = np.array(theta, float)
    j = prob.states_at
    best = float(np.sum(prob.residual(theta) ** 2))
    # a Backlash-Inverse's start spans its branches' whole range (_Problem.unpack): finer steps
    places = (-6.0, 0.0, 6.0) if prob.type == "backlash" else \
        tuple(float(np.clip(2 * np.arctanh(2 * q - 1), -6, 6)) if 0 < q < 1 else 6.0 * np.sign(q - 0.5)
              for q in np.linspace(0, 1, 9))
    for _ in prob.records:
        for frac in places:
            trial = theta.copy()
            trial[j] = frac
            cost = float(np.sum(prob.residual(trial) ** 2))
            if cost < best:
                best, theta = cost, trial
        j += 2
    return theta


@njit(cache=True)
def _power_sums(w, y, p):
    """``sum w^k`` for k = 0..2p and ``sum y w^k`` for k = 1..p."""
    sums = np.zeros(2 * p + 1)
    rhs = np.zeros(p)
    for i in range(w.shape[0]):
        x = w[i]
        q = 1.0
        for k in range(2 * p + 1):
            sums[k] += q
            if 1 <= k <= p:
                rhs[k - 1] += y[i] * q
            q *= x
    return sums, rhs


@njit(cache=True)
def _poly_residual(w, y, c):
    """``y - sum_k c[k-1] w^k`` (Horner)."""
    out = np.empty(w.shape[0])
    p = c.shape[0]
    for i in range(w.shape[0]):
        acc = 0.0
        for k in range(p - 1, -1, -1):
            acc = (acc + c[k]) * w[i]
        out[i] = y[i] - acc
    return out


def _origins(prob: _Problem, theta) -> list[float]:
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


def _moved(prob: _Problem, theta, x0: float) -> np.ndarray:
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


def _other_origin(prob: _Problem, theta, lo, hi, max_nfev: int):
    """The fit of ``prob`` from each of h_bar's other origins (:func:`_origins`); the outer
    parameters of the best, where it fits the records better than ``theta``, else None."""
    best = float(np.sum(prob.residual(theta) ** 2))
    found = None
    for x0 in _origins(prob, theta):
        t = _best_states(prob, np.clip(_moved(prob, theta, x0), lo + 1e-9, hi - 1e-9))
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
