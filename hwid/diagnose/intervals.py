"""Intervals of a fitted effect's own parameters (:func:`param_intervals`): the Gauss-Newton
covariance of the fit's residual at its optimum, with the model's re-estimated parameters (F's, G's)
fitted jointly and so marginalised, the residual's variance and its correlation time taken from the
residual itself; and, where the fit does not reach the noise floor, a delete-one-experiment
jackknife that carries what the model's own error does to the estimate.

Noise. For the fit's residual ``r(x)`` on the unit box ``x`` (log scale where a parameter spans
decades, :func:`hwid.diagnose.search.to_unit`), ``cov(x) = s^2 kappa_r (J^T J)^-1`` with ``J`` the
central finite-difference Jacobian (one-sided at a bound), ``s^2 = r^T r / (n - p)`` and ``kappa_r``
the residual's integrated autocorrelation time in its own samples (a misfit leaves a residual far more
correlated than the noise, and its samples are not independent).

Model error. A fit that leaves more than the noise (an identified model's G and h are not the
plant's) is biased by that error, and the bias depends on which records it sits in: the pre-sliding
displacement of a two-mass drive's friction, fitted jointly with its identified G (1.05x the floor
left on the fit experiments), came out 1.2 % below the truth with a noise interval of +-0.75 %.
Noise intervals, however the residual's variance and correlation are counted, say how far the
estimate moves with another draw of the noise, not with another choice of experiments, so they do
not carry it (on ``tests/test_intervals.py``'s line with a curvature the line does not model, its
amount drawn per experiment, they covered the slope in 61 % of 200 draws, the jackknife's in 96 %).
Where the fit's residual on the fit experiments exceeds the noise floor (:func:`misses_floor`, the
gap test's z-score), the interval is also the delete-one-experiment (grouped) jackknife's
(:func:`group_jackknife_sd`): the fit repeated with each fit experiment left out, its spread
measuring how much the estimate depends on which records the model error sits in. This is the
cluster jackknife (CRV3) of MacKinnon, Nielsen and Webb, "Cluster-robust inference: a guide to
empirical practice", J. Econometrics 232 (2023), and "Leverage, influence, and the jackknife in
clustered regression models" (arXiv:2205.03288, 2022), each experiment a cluster: ``V = (G-1)/G
sum_g (theta_(g) - theta)(theta_(g) - theta)^T`` over the ``G`` fit experiments, centred on the full
fit (the more conservative of their two forms), with Student's ``t`` of ``G - 1`` degrees of freedom
for the 95 % point (few clusters: their recommendation); survey sampling's delete-a-group jackknife
is the same estimator (Kott, J. Official Statistics 17 (2001) 521-526).

Each ``theta_(g)`` is the Gauss-Newton step from the full fit with experiment ``g``'s residual left
out, on the Jacobian already computed: exact for linear least squares, where it is CRV3 itself, and
the refit's first-order term otherwise. A refit per experiment is a joint fit per experiment per
candidate (7 s for the two-mass drive's friction over its 12 fit experiments); its standard
deviations there were the step's within 25 % (Coulomb level 1.5e-4 against 1.9e-4 of the unit box,
pre-sliding 1.13e-3 both), the step costing milliseconds. The half width taken is the larger of the
noise's and the jackknife's; where the fit reaches the floor the jackknife is not run and the
intervals are the noise's (a given model's friction rig at 0.99x the floor: unchanged, covering).
The jackknife measures how the estimate moves with the records: a bias every experiment shares
alike (a structure of G wrong the same way in each) it cannot see, nor can any interval computed
from the fit's own residual.

The box. The model's parameters fitted jointly with the effect (F's, G's) are held in a box around
the identified model (:meth:`hwid.diagnose.g_refit.GRefit._g_bounds`): a restriction the diagnosis
puts on the refit, not a bound of the plant. Where the fit leaves one of them on an end of its box
(:data:`ON_BOX`), the estimate is the best within the box, and the box's pull on the model is taken
up by the effect's parameters: a bias that neither the noise nor the jackknife sees (every
experiment shares it). The two-mass drive's friction, fitted with its identified G (two zeros and a
slow pole the plant has not) whose two zeros' coefficients ended on the box's lower end, came out
at a Coulomb level 2.8 % above and a pre-sliding displacement 3.3 % below the truth, both outside
their intervals (released: [0.1011, 0.1098] and [0.0935, 0.0999], holding 0.1045 and 0.0989, the
model's units). The box's bias to first order is the Gauss-Newton step from the fit with the pinned
parameters released (:func:`box_release`, on the Jacobian already computed; the effect's own
parameters on their own bounds, which are the catalogue's, held): the interval spans the estimate
and that released estimate, each with its half width.

The 95 % interval is ``x +- half`` (widened to the released estimate where the box binds) mapped
back to the parameter's units (asymmetric on a log scale), cut at the bounds. A parameter whose
interval would span more than half its range, or whose Jacobian column is null (or becomes so with
one experiment left out), is undetermined by the fit experiments: its interval is null, with the
reason.
"""
from __future__ import annotations

import numpy as np
from scipy import stats

from hwid.diagnose import search
from hwid.diagnose.gap import correlation_time

Z95 = 1.96
#: a parameter whose 95 % interval spans more than this share of its unit range is undetermined
UNDETERMINED_SPAN = 0.5
#: the jackknife needs at least this many fit experiments (with two, ``t_1`` is 12.7 and the spread
#: is one difference)
JACKKNIFE_MIN_GROUPS = 3
#: a fit misses the noise floor where its residual's mean square exceeds the floor's by this z-score
#: (the gap test's, :func:`hwid.diagnose.gap.gap_test`, without its 10 % share: that share says
#: whether a gap matters to a simulator's user; any misfit the data show biases the estimate)
MISFIT_Z = 5.0
#: a direction of the Jacobian whose singular value is below this share of the largest is not seen
SEEN = 1e-8
#: a parameter within this share of its unit range from an end of it is on that end (here and for
#: the baseline's refit box, :meth:`hwid.diagnose.g_refit.GRefit._recentre`)
ON_BOX = 1e-3


def misses_floor(r, sigma: float, kappa: float) -> bool:
    """Whether the residual ``r`` is more than noise of standard deviation ``sigma`` and correlation
    time ``kappa`` (samples of ``r``): its mean square over ``sigma^2`` above 1 by a z-score above
    :data:`MISFIT_Z`, the relative standard error ``sqrt(2 kappa / n)``."""
    r = np.asarray(r, float)
    if sigma <= 0 or r.size == 0:
        return False
    ratio = float(r @ r) / r.size / sigma ** 2
    z = (ratio - 1.0) / np.sqrt(2.0 * max(kappa, 1.0) / r.size)
    return bool(z > MISFIT_Z)


def jacobian(residual, theta, lo, hi, logs, step: float):
    """``(x0, r0, J)``: ``theta`` on the unit box, the residual there and its central
    finite-difference Jacobian in the unit box's coordinates (one-sided at a bound; a fixed
    parameter's column zero)."""
    x0 = search.to_unit(theta, lo, hi, logs)
    r0 = np.asarray(residual(theta), float)
    J = np.zeros((r0.size, theta.size))
    for j in range(theta.size):
        if hi[j] <= lo[j]:
            continue
        a, b = max(x0[j] - step, 0.0), min(x0[j] + step, 1.0)
        xa, xb = x0.copy(), x0.copy()
        xa[j], xb[j] = a, b
        ra = r0 if a == x0[j] else residual(search.from_unit(xa, lo, hi, logs))
        rb = r0 if b == x0[j] else residual(search.from_unit(xb, lo, hi, logs))
        J[:, j] = (np.asarray(rb) - np.asarray(ra)) / max(b - a, 1e-15)
    return x0, r0, J


def _seen(J):
    """``(free, Vs, sv, blind)``: the parameters the residual moves with, the right singular
    vectors of their Jacobian it sees (rows, a singular value above :data:`SEEN` of the largest)
    and those values, and which free parameters involve an unseen direction."""
    free = np.flatnonzero(np.any(J != 0.0, axis=0))
    if not free.size:
        return free, np.zeros((0, 0)), np.zeros(0), np.zeros(0, bool)
    _, sv, Vt = np.linalg.svd(J[:, free], full_matrices=False)
    seen = sv > SEEN * sv[0] if sv.size and sv[0] > 0 else np.zeros(sv.size, bool)
    blind = np.any(np.abs(Vt[~seen]) > 1e-6, axis=0) if (~seen).any() else np.zeros(free.size, bool)
    return free, Vt[seen], sv[seen], blind


def noise_sd(J, r0, kappa_min: float = 1.0, seen=None) -> np.ndarray:
    """Each parameter's standard deviation on the unit box from the noise, ``s^2 kappa_r (J^T J)^-1``
    (module docstring); ``inf`` where the residual does not see it. ``seen``: ``J``'s :func:`_seen`,
    where already taken."""
    n, p = J.shape
    s2 = float(r0 @ r0) / max(n - p, 1)
    kappa = max(float(correlation_time(r0)), float(kappa_min), 1.0)
    sd = np.full(p, np.inf)
    free, Vs, sv, blind = _seen(J) if seen is None else seen
    if free.size:
        var = np.sum((Vs.T / sv) ** 2, axis=1) * s2 * kappa
        sd[free] = np.where(blind, np.inf, np.sqrt(var))
    return sd


def group_jackknife_sd(J, r0, groups, seen=None) -> np.ndarray:
    """Each parameter's standard deviation on the unit box by the delete-one-group jackknife (CRV3,
    module docstring): ``groups`` the sizes of the residual's consecutive parts (one per fit
    experiment). ``theta_(g) - theta`` is the Gauss-Newton step with part ``g`` left out less the
    full data's step (which is zero at an interior optimum). ``inf`` for a parameter the residual
    does not see, or does not see with one part left out. ``seen``: as for :func:`noise_sd`."""
    p = J.shape[1]
    sizes = np.asarray(groups, int)
    if sizes.sum() != r0.size:
        raise ValueError(f"the groups' sizes add up to {int(sizes.sum())}, the residual has {r0.size} samples")
    sizes = sizes[sizes > 0]
    sd = np.full(p, np.inf)
    free, Vs, sv, blind = _seen(J) if seen is None else seen
    if not free.size:
        return sd
    A = J[:, free] @ Vs.T                   # the seen directions' columns, mutually orthogonal
    M, b = A.T @ A, A.T @ r0
    full = -np.linalg.solve(M, b)
    ends = np.r_[0, np.cumsum(sizes)]
    shifts, lost = [], np.zeros(free.size, bool)
    for a, e in zip(ends[:-1], ends[1:]):
        Ag, rg = A[a:e], r0[a:e]
        w, Q = np.linalg.eigh(M - Ag.T @ Ag)
        keep = w > (SEEN * sv[0]) ** 2
        # a direction only this experiment sees: the others cannot tell the parameters in it
        lost |= np.any(np.abs(Vs.T @ Q[:, ~keep]) > 1e-6, axis=1) if (~keep).any() else False
        step = -(Q[:, keep] / w[keep]) @ (Q[:, keep].T @ (b - Ag.T @ rg))
        shifts.append(Vs.T @ (step - full))
    d = np.array(shifts)
    G = len(shifts)
    var = (G - 1) / G * np.sum(d * d, axis=0)
    sd[free] = np.where(blind | lost, np.inf, np.sqrt(var))
    return sd


def box_release(J, r0, x0, n_own: int) -> np.ndarray:
    """The step on the unit box from the fit ``x0`` to the linearised optimum with the model's
    parameters (those after the effect's own ``n_own``) that lie on an end of their box
    (:data:`ON_BOX`) released (module docstring): the Gauss-Newton step ``min |r0 + J d|`` over the
    parameters the residual moves with, those of the effect's own on their own bounds held (a
    least-norm step along directions the residual does not see, :data:`SEEN`). Zero where no model
    parameter is on its box, or where the step takes none of those outwards (the box does not bind)."""
    x0 = np.asarray(x0, float)
    p = x0.size
    moves = np.any(J != 0.0, axis=0)
    at_lo, at_hi = x0 <= ON_BOX, x0 >= 1.0 - ON_BOX
    model = np.arange(p) >= n_own
    pinned = model & moves & (at_lo | at_hi)
    d = np.zeros(p)
    if not pinned.any():
        return d
    free = moves & ~(~model & (at_lo | at_hi))
    d[free] = np.linalg.lstsq(J[:, free], -np.asarray(r0, float), rcond=SEEN)[0]
    outwards = (at_lo & (d < 0.0)) | (at_hi & (d > 0.0))
    return d if np.any(pinned & outwards) else np.zeros(p)


def param_intervals(residual, theta, lo, hi, logs, names, kappa_min: float = 1.0, step: float = 1e-3,
                    groups=None, sigma: float = 0.0) -> dict:
    """``{name: [low, high] or None}`` for the first ``len(names)`` parameters of ``theta``, and
    ``{name: reason}`` under ``"undetermined"`` for each null one.

    Parameters
    ----------
    residual : callable
        ``residual(theta) -> r`` on the fit experiments (every parameter, the effect's first).
    theta, lo, hi : arrays
        The fit and its bounds.
    logs : tuple of bool
        Which parameters are fitted on a log scale.
    names : sequence of str
        The effect's own parameters.
    kappa_min : float
        The noise's correlation time in the residual's samples (the least ``kappa_r`` taken).
    step : float
        Finite-difference step on the unit box.
    groups : sequence of int, optional
        The residual's parts, one per fit experiment, by their sizes in order: with ``sigma``, the
        jackknife's half width where the fit misses the floor (module docstring).
    sigma : float
        The noise floor's standard deviation, the residual's units (0: the noise's intervals alone).
    """
    theta = np.asarray(theta, float)
    lo, hi = np.asarray(lo, float), np.asarray(hi, float)
    x0, r0, J = jacobian(residual, theta, lo, hi, logs, step)
    seen = _seen(J)
    half = Z95 * noise_sd(J, r0, kappa_min, seen)
    n_groups = 0 if groups is None else int(np.count_nonzero(np.asarray(groups, int)))
    if n_groups >= JACKKNIFE_MIN_GROUPS and misses_floor(r0, sigma, kappa_min):
        t95 = float(stats.t.ppf(0.975, n_groups - 1))
        half = np.maximum(half, t95 * group_jackknife_sd(J, r0, groups, seen))
    return _from_half_widths(x0, half, lo, hi, logs, names, box_release(J, r0, x0, len(names)))


def _from_half_widths(x0, half, lo, hi, logs, names, shift=None) -> dict:
    """The intervals from ``min(x0, x0 + shift) - half`` to ``max(x0, x0 + shift) + half`` on the
    unit box (``shift``: :func:`box_release`'s, default none) in the parameters' units, null where
    wider than :data:`UNDETERMINED_SPAN` or infinite."""
    out, why = {}, {}
    shift = np.zeros(len(x0)) if shift is None else np.asarray(shift, float)
    for j, name in enumerate(names):
        h = float(half[j]) if np.isfinite(half[j]) and half[j] >= 0 else np.inf
        span = 2 * h + abs(float(shift[j]))
        if not np.isfinite(span) or span > UNDETERMINED_SPAN:
            out[name] = None
            why[name] = ("the fit experiments do not move the residual with it" if not np.isfinite(h) else
                         f"its 95 % interval spans {min(span, 99.0):.2g} of its range: the fit experiments "
                         "do not determine it")
            continue
        ends = []
        a, b = min(x0[j], x0[j] + shift[j]), max(x0[j], x0[j] + shift[j])
        for xj in (max(a - h, 0.0), min(b + h, 1.0)):
            x = x0.copy()
            x[j] = xj
            ends.append(float(search.from_unit(x, lo, hi, logs)[j]))
        out[name] = [min(ends), max(ends)]
    if why:
        out["undetermined"] = why
    return out


def forms_alike(best, fits, criterion, same_fit: float):
    """``best`` (a :class:`hwid.diagnose.verdict.Candidate`, one of an effect's forms ``fits``) with
    each form parameter (:meth:`Effect.form_params`: friction's ``fed_back``, the hysteresis's
    ``after_h``) in which another form that fits the fit experiments alike (its ``criterion`` within
    ``same_fit`` of ``best``'s) differs marked undetermined in its intervals: the experiments cannot
    tell where the effect acts, and the next experiment should."""
    mine = best.fitted.form_params()
    for other in fits:
        if other is best or criterion(other) - criterion(best) >= same_fit:
            continue
        theirs = other.fitted.form_params()
        for key in (k for k in mine if k in theirs and theirs[k] != mine[k]):
            best.intervals = dict(best.intervals or {})
            best.intervals[key] = None
            best.intervals.setdefault("undetermined", {})[key] = (
                f"the fit experiments fit {key} = {mine[key]:g} and {key} = {theirs[key]:g} alike (criteria "
                f"within {same_fit:g}); {mine[key]:g} is the lower")
    return best
