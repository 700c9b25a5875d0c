"""The whole-model fit's problem (:mod:`hwid.identify.whole`): the data and fixed choices of one
fit (F's type, G's structure, h_bar's degree, G's delay, the actuator's slew rate and clip), its
outer parameters and bounds, the output error with h_bar solved for (variable projection), and the
steps every variant of the fit shares: descending from starts, placing each record's initial
gear, scoring a fit by the selection's criterion. :class:`hwid.identify.whole.WholeModelFit` and
its variants (:mod:`~hwid.identify.whole_delay`, :mod:`~hwid.identify.whole_rate`,
:mod:`~hwid.identify.whole_clip`, :mod:`~hwid.identify.whole_coarse`) build on it.
"""
from __future__ import annotations

from dataclasses import dataclass, field

import numpy as np
from numba import njit
from scipy import optimize

from hwid.blocks.slew import slewed
from hwid.identify.g_structure import Structure, g_from_params
from hwid.model import Actuator, InputNonlinearity
from hwid.threads import forked_map


#: the bound of each record's initial-gear parameter in a fit with the input's slew rate (the gear
#: at ``0.5 (1 + tanh(x / 2))`` of its band, :meth:`Problem._unpacked`; 30 without a rate): at 8
#: the gear comes within 3.4e-4 of the band of its border, and the cost's slope in it is still
#: 3.4e-4 of the band's. Further out the tanh is flat, and a descent that drives a gear there
#: while F's borders are still far off stops short, the gear no longer following the borders: a
#: test rig slewing at 0.06 units/s (bound 30) ended with a gear parameter at 21.9, G at its
#: start's 0.44 rad/s for the truth's 2 and 0.0643 units/s at 1.9x the noise; bounded at 8, the
#: same start reaches 0.0600 and the noise. Fits without a rate keep 30: bounded at 8 too, the
#: real friction damper's log came out unexplained, not friction.
GEAR_PLACE = 8.0


@dataclass
class Problem:
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
        gear = GEAR_PLACE if self.with_rate else 30.0
        for _ in self.records:
            lo += [-gear, -np.inf]
            hi += [gear, np.inf]
        return np.array(lo), np.array(hi)

    def residual(self, theta) -> np.ndarray:
        """The output error with h_bar solved for (variable projection)."""
        try:
            w = self.w(theta)
        except (np.linalg.LinAlgError, ValueError, FloatingPointError):
            return np.full(self.y.size, 1e6)
        if not np.all(np.isfinite(w)) or np.max(np.abs(w)) > 1e6:
            return np.full(self.y.size, 1e6)
        return poly_residual(w, self.y, self._solve(w))

    def _solve(self, w) -> np.ndarray:
        """h_bar's coefficients (powers 1..degree) for the argument ``w``: the normal equations of
        the design ``[w, w^2, ...]`` from w's power sums (one pass, no tall matrix), with the
        columns scaled to unit norm (p <= 9 columns)."""
        sums, rhs = power_sums(w, self.y, self.degree)
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


def border_grid(records) -> list[tuple[float, float]]:
    """The coarse grid of borders a fit without a start begins from: ``(d_plus, log(d_plus -
    d_minus))`` with ``d_plus`` across the middle half of the input's range about its median and
    the play 2 %, 10 %, 30 % and 60 % of the range."""
    u = np.concatenate([r.u for r in records])
    width, centre = float(np.ptp(u)) or 1.0, float(np.median(u))
    return [(centre + a * width, float(np.log(b * width)))
            for a in np.linspace(-0.25, 0.25, 7) for b in (0.02, 0.1, 0.3, 0.6)]


def extent(records) -> tuple[float, float, float]:
    """``(span, dt, width)``: the longest record (s), the shortest sampling time and the input's range."""
    return (max(r.u.size * r.dt for r in records), min(r.dt for r in records),
            float(np.ptp(np.concatenate([r.u for r in records]))) or 1.0)


def table_row(prob: Problem, rss: float) -> dict:
    """A selection-table row of the fit of ``prob`` with residual sum of squares ``rss``."""
    k = prob.n_outer + prob.degree
    return {"type": prob.type, "structure": prob.label, "degree": prob.degree, "rss": rss, "parameters": k,
            "aic": criterion(rss, prob.y.size, k, prob.degree)}


def descend(probs, starts, max_nfev: int) -> list[tuple[np.ndarray, float]]:
    """Each ``probs[i]`` fitted from ``starts[i]`` within its bounds, on every core: ``(theta, rss)``."""
    span, dt, width = extent(probs[0].records)

    def one(i):
        lo, hi = probs[i].bounds(width, span, dt)
        sol = optimize.least_squares(probs[i].residual, np.clip(starts[i], lo + 1e-9, hi - 1e-9), bounds=(lo, hi),
                                     method="trf", x_scale=1.0, max_nfev=max_nfev)
        return sol.x, float(sol.fun @ sol.fun)
    return forked_map(one, range(len(probs)))


def criterion(rss: float, n: int, k: int, degree: int) -> float:
    """The selection's criterion of a fit with ``k`` parameters, ``degree`` of them h_bar's: BIC's
    penalty on F, G and the initial states, AIC's on h_bar's coefficients (the module docstring
    says why)."""
    return float(n * np.log(rss / n) + (k - degree) * np.log(n) + 2 * degree)


def best_states(prob: Problem, theta, rest_at_gear: bool = False) -> np.ndarray:
    """``theta`` with each experiment's initial gear put where it fits best of: against the lower
    border, in the middle of the play, against the upper one (a Backlash-Inverse: nine places
    across its branches' range; one experiment at a time). The gear's
    place enters through a tanh: started on the wrong side, the search stalls where the tanh is flat.

    ``rest_at_gear``: each place tried with G at rest at the gear's value there (G(0) = 1), the
    state a record starts in after a hold; for a start from a model (the two stages), whose F
    places the gear: G left at rest at the input's level instead put a staircase's first samples
    half a play or more away, where the start's h_bar, extrapolated, spoilt the start (the paper's
    plant: an RMS of 0.42 at the start for the stages' 0.023)."""
    theta = np.array(theta, float)
    j = prob.states_at
    if rest_at_gear:
        theta = _rest_at_gear(prob, theta)
    best = float(np.sum(prob.residual(theta) ** 2))
    # a Backlash-Inverse's start spans its branches' whole range (Problem.unpack): finer steps
    places = (-6.0, 0.0, 6.0) if prob.type == "backlash" else \
        tuple(float(np.clip(2 * np.arctanh(2 * q - 1), -6, 6)) if 0 < q < 1 else 6.0 * np.sign(q - 0.5)
              for q in np.linspace(0, 1, 9))
    for _ in prob.records:
        for frac in places:
            trial = theta.copy()
            trial[j] = frac
            if rest_at_gear:
                trial = _rest_at_gear(prob, trial, only=(j - prob.states_at) // 2)
            cost = float(np.sum(prob.residual(trial) ** 2))
            if cost < best:
                best, theta = cost, trial
        j += 2
    return theta


def _rest_at_gear(prob: Problem, theta, only: int | None = None) -> np.ndarray:
    """``theta`` with each record's G at rest at its initial gear (``only``: that record alone)."""
    theta = np.array(theta, float)
    states = prob._unpacked(theta)[2]
    for i, (gear, _) in enumerate(states):
        if only is None or i == only:
            theta[prob.states_at + 2 * i + 1] = gear
    return theta


@njit(cache=True)
def power_sums(w, y, p):
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
def poly_residual(w, y, c):
    """``y - sum_k c[k-1] w^k`` (Horner)."""
    out = np.empty(w.shape[0])
    p = c.shape[0]
    for i in range(w.shape[0]):
        acc = 0.0
        for k in range(p - 1, -1, -1):
            acc = (acc + c[k]) * w[i]
        out[i] = y[i] - acc
    return out
