"""Steady-state averages of a staircase's levels, eq. (9), with standard errors honest under coloured noise.

The settling time of G is unknown, so where each level's transient has died out is found from the
data, in two steps per level:

1. **MSER-5** (White 1997; the "marginal standard error rule" on means of 5 samples): discard the
   first ``d`` samples that minimise ``var(y[d:]) / (n - d)^2`` with ``d <= n/2``. This removes the
   bulk of a transient of G.
2. **Backward Geweke test**: MSER stops where the transient is about one batch-noise standard
   deviation, which can still bias a mean of thousands of samples by more than its standard error.
   So the retained part is tested for drift: the mean of its first 10 % against the mean of its
   last 50 %, with the long-run noise variance. While the difference is significant the
   truncation moves forward by 5 % of the level; a level still drifting at half its hold is flagged
   as not settled (``settled = False``).
3. **Margin**: where anything was cut, a further ``margin`` (20 %) of what is left is dropped, so the
   samples averaged are not the ones whose look decided the cut (without it the data-driven cut
   biases the mean by up to half a standard error and inflates its spread by 10-20 %; measured on
   the paper's plant over 120 runs, the 95 % interval's miss rate drops from 6.2 % to 5.1 %).
4. **Extrapolation**: levels still drifting at half their hold (a G slower than the hold) get their
   steady state from ``y = X + A exp(-t / tau)`` fitted to what is kept, one ``tau`` for them all,
   the standard error of ``X`` widened by ``tau``'s own uncertainty (:func:`_extrapolate`).

What follows is averaged (eq. 9). The standard error uses **batch means**: the retained samples
are cut into ``K`` batches, ``lrv = b var(batch means)`` estimates the long-run variance (the
spectral density of the noise at 0 times 2 pi), and ``se = sqrt(lrv / n)``. ``K`` starts at 32 and
is halved while the batch means are still autocorrelated (pooled lag-1 test), so the batches are
longer than the noise's memory; as batch means stay biased low when the holds are short against
that memory, an AR(k) spectral estimate at frequency 0 (Yule-Walker on pooled autocovariances, k by
AIC) is computed too and the larger of the two is used. As the paper's noise is stationary (Section 3), the long-run
variance is by default pooled over all levels of both staircases, which makes it precise; Bartlett's
test checks that assumption and falls back to per-level values (with a warning) when it fails.
"""
from __future__ import annotations

from dataclasses import dataclass, field

import numpy as np
from scipy import linalg

from hwid import HwidError


@dataclass(frozen=True)
class SteadyLevels:
    """Per-level steady-state estimates ``X_hat_j(M)`` (eq. 9) and their standard errors."""

    mean: np.ndarray          # X_hat_j
    se: np.ndarray            # standard error of X_hat_j
    first: np.ndarray         # first sample averaged (absolute index in the record)
    n: np.ndarray             # number of samples averaged (M of eq. 9)
    settled: np.ndarray       # False where the level still drifted at half its hold
    lrv: float                # pooled long-run noise variance (per sample)
    df: int                   # degrees of freedom of the standard errors
    n_batches: int            # batches per level used for the batch means
    pooled: bool              # whether the pooled long-run variance was used
    warnings: tuple[str, ...] = field(default=())


def mser5(y: np.ndarray, batch: int = 5, max_frac: float = 0.5) -> int:
    """Samples to discard at the start of ``y`` by the MSER-5 rule (at most ``max_frac`` of them)."""
    y = np.asarray(y, float)
    m = y.size // batch
    if m < 4:
        return 0
    z = y[: m * batch].reshape(m, batch).mean(axis=1)
    # suffix sums give var(z[d:]) for every d at once
    zr = z[::-1]
    cnt = np.arange(1, m + 1)
    s1 = np.cumsum(zr)[::-1]
    s2 = np.cumsum(zr * zr)[::-1]
    cnt = cnt[::-1].astype(float)
    var = np.maximum(s2 / cnt - (s1 / cnt) ** 2, 0.0)
    crit = var / cnt            # = sum of squares / (m - d)^2
    dmax = max(int(max_frac * m), 1)
    return int(np.argmin(crit[:dmax])) * batch


def batch_means(y: np.ndarray, n_batches: int) -> tuple[np.ndarray, int]:
    """Means of ``n_batches`` consecutive equal batches of ``y`` (the first samples left over are
    dropped) and the batch size."""
    y = np.asarray(y, float)
    b = y.size // n_batches
    if b < 1:
        raise ValueError(f"{y.size} samples cannot make {n_batches} batches")
    return y[y.size - b * n_batches:].reshape(n_batches, b).mean(axis=1), b


def _lrv(y: np.ndarray, n_batches: int) -> float:
    bm, b = batch_means(y, n_batches)
    return float(b * np.var(bm, ddof=1))


def ar_long_run_variance(segments: list[np.ndarray], max_order: int = 20) -> float:
    """Long-run variance ``sigma_e^2 / (1 - sum phi_i)^2`` of an AR(k) model fitted to the
    (per-segment demeaned) segments by Yule-Walker with pooled autocovariances, ``k`` by AIC."""
    segs = [np.asarray(x, float) - np.mean(x) for x in segments if len(x) > 2]
    n = sum(x.size for x in segs)
    if n < 10:
        return 0.0
    kmax = int(min(max_order, max(1, min(x.size for x in segs) // 10)))
    acov = np.zeros(kmax + 1)
    for x in segs:
        for k in range(kmax + 1):
            # einsum's own loop, not BLAS: a threaded ddot of this size costs far more than it
            # saves on a loaded machine or inside a worker of a parallel batch
            acov[k] += float(np.einsum("i,i->", x[: x.size - k], x[k:]))
    acov /= n
    if acov[0] <= 0:
        return 0.0
    best = (n * np.log(acov[0]), 0, np.zeros(0), acov[0])
    for k in range(1, kmax + 1):
        try:
            phi = linalg.solve_toeplitz(acov[:k], acov[1:k + 1])
        except (np.linalg.LinAlgError, ValueError):
            break
        s2 = float(acov[0] - phi @ acov[1:k + 1])
        if s2 <= 0:
            break
        aic = n * np.log(s2) + 2 * k
        if aic < best[0]:
            best = (aic, k, phi, s2)
    _, _, phi, s2 = best
    denom = 1.0 - float(np.sum(phi))
    return float(s2 / denom ** 2) if denom > 1e-3 else float(s2 / 1e-6)


def geweke_z(y: np.ndarray, lrv: float, first: float = 0.1, last: float = 0.5) -> float:
    """Geweke's drift statistic: (mean of the first ``first`` fraction - mean of the last ``last``
    fraction) over its standard error from the long-run variance ``lrv``."""
    n = y.size
    na, nb = max(int(first * n), 1), max(int(last * n), 1)
    diff = y[:na].mean() - y[n - nb:].mean()
    se = np.sqrt(lrv / na + lrv / nb)
    return float(diff / se) if se > 0 else (0.0 if diff == 0 else np.inf)


def steady_levels(y_segments: list[np.ndarray], offsets=None, pool: bool = True, z_drift: float = 2.0,
                  max_batches: int = 32, min_batches: int = 8, rel_floor: float = 1e-7,
                  margin: float = 0.2) -> SteadyLevels:
    """Average each level after its transient (eq. 9) and give each average an honest standard error.

    Parameters
    ----------
    y_segments : list of arrays
        The output ``y`` during each constant level (one array per level, any lengths).
    offsets : array_like, optional
        The absolute sample index of each segment's first sample (for reporting ``first``).
    pool : bool
        Pool the long-run noise variance over all levels (stationary noise, Section 3).
    z_drift : float
        Threshold of the Geweke drift test that moves the truncation forward.
    margin : float
        Fraction of the samples left after the cut that is dropped as well (step 3 above).
    rel_floor : float
        Standard errors are floored at ``rel_floor`` times the output's range (noise-free data).
    """
    segs = [np.asarray(s, float) for s in y_segments]
    if not segs:
        raise HwidError("no levels to average")
    short = min(s.size for s in segs)
    if short < 20:
        raise HwidError(f"a level holds only {short} samples; at least 20 are needed to find its steady state")
    offsets = np.zeros(len(segs), int) if offsets is None else np.asarray(offsets, int)
    warns: list[str] = []
    span = max(float(np.ptp(np.concatenate(segs))), float(np.max(np.abs(np.concatenate(segs)))), 1e-300)
    floor = (rel_floor * span) ** 2

    # first pass: a rough long-run variance from each level's second half (surely settled or close)
    k0 = max(2, min(16, short // 2 // 5))
    lrv_half = np.array([_lrv(s[s.size // 2:], k0) for s in segs])
    lrv0 = max(float(np.median(lrv_half)), floor)

    # truncation: MSER-5, then move forward while the Geweke drift test rejects
    cut = np.zeros(len(segs), int)
    settled = np.ones(len(segs), bool)
    for i, s in enumerate(segs):
        n = s.size
        d = mser5(s)
        step = max(n // 20, 1)
        lrv_i = lrv0 if pool else max(lrv_half[i], floor)
        while abs(geweke_z(s[d:], lrv_i)) > z_drift:
            if d + step > n // 2:
                settled[i] = False
                d = n // 2
                break
            d += step
        cut[i] = min(d + int(margin * (n - d)), n // 2) if d > 0 else d

    kept = [s[d:] for s, d in zip(segs, cut)]
    nk = np.array([k.size for k in kept])
    # batches: halve K while the batch means are still correlated (pooled lag-1 autocorrelation)
    K = max(2, min(max_batches, int(nk.min()) // 5))
    while True:
        bms = [batch_means(k, K) for k in kept]
        dev = [bm - bm.mean() for bm, _ in bms]
        num = sum(float(np.dot(d_[:-1], d_[1:])) for d_ in dev)
        den = sum(float(np.dot(d_, d_)) for d_ in dev)
        rho = num / den if den > 0 else 0.0
        if rho <= 2.0 / np.sqrt(len(segs) * K) or K // 2 < min_batches:
            break
        K //= 2
    lrv_j = np.array([b * np.var(bm, ddof=1) for bm, b in bms])
    # batch means are biased low when batches are not much longer than the noise's memory (short
    # holds, strongly coloured noise); the AR(k) spectral estimate at frequency 0 does not need
    # long batches. The larger of the two is used.
    lrv = max(float(np.mean(lrv_j)), ar_long_run_variance(kept), floor)
    use_pool = pool and len(segs) > 1
    if use_pool and lrv > floor and np.all(lrv_j > 0):
        from scipy import stats   # here: scipy.stats costs half a second at start-up
        p = stats.bartlett(*[bm * np.sqrt(b) for bm, b in bms]).pvalue
        if p < 1e-3:
            use_pool = False
            warns.append(f"the output noise does not look stationary across levels (Bartlett p = {p:.1g}): "
                         "standard errors use each level's own noise variance")
    if use_pool:
        se = np.sqrt(lrv / nk)
        df = len(segs) * (K - 1)
    else:
        se = np.sqrt(np.maximum(lrv_j, floor) / nk)
        df = K - 1
    means = np.array([k.mean() for k in kept])
    if not settled.all():
        bad = ", ".join(str(i + 1) for i in np.flatnonzero(~settled))
        tail = _extrapolate(kept, ~settled)
        if tail is not None:
            means, se = np.where(~settled, tail[0], means), np.where(~settled, np.maximum(tail[1], se), se)
            warns.append(f"level(s) {bad} still drift at half their hold: the hold is too short for G to settle; "
                         f"their steady states are extrapolated from an exponential approach (time constant "
                         f"{tail[2]:.4g} samples, common to them), with wider standard errors; increase "
                         "protocols.staircase.hold")
        else:
            warns.append(f"level(s) {bad} still drift at half their hold: the hold is too short for G to settle; "
                         "increase protocols.staircase.hold")
    return SteadyLevels(means, se, offsets + cut, nk, settled, lrv, int(df), int(K), use_pool, tuple(warns))


def _extrapolate(kept, which, n_tau: int = 40):
    """Steady states of the levels ``which`` that did not settle: ``y = X + A exp(-t / tau)`` fitted
    to what is kept of each (its second half), ``tau`` common to them (G's slowest mode sets the
    tail), ``X`` and ``A`` per level by least squares. Returns ``(X, se, tau)`` for all levels (only
    ``which`` meaningful), or None when the best ``tau`` is at either end of its grid (a drift that
    an exponential does not resolve within the hold is not extrapolated). The standard error of
    ``X`` is that of the intercept with the long-run variance of the fit's residuals, plus what
    ``tau``'s own uncertainty (profile chi^2) carries into it.

    Without it a level 20 % short of its steady state (a 4.8 s sensor lag behind the paper's G with
    30 s holds) entered eq. (9) as it was, and the borders came out 0.2-0.3 off."""
    idx = np.flatnonzero(which)
    n_min = min(kept[i].size for i in idx)
    if n_min < 20:
        return None
    noise = np.ones(len(kept))

    def fit(tau):
        # chi^2 (residuals over each level's noise variance), intercepts, their variances, residuals
        chi2, X, v, res = 0.0, np.zeros(len(kept)), np.zeros(len(kept)), {}
        for i in idx:
            t = np.arange(kept[i].size, dtype=float)
            A = np.column_stack([np.ones_like(t), np.exp(-t / tau)])
            coef = np.linalg.lstsq(A, kept[i], rcond=None)[0]
            r = kept[i] - A @ coef
            chi2 += float(r @ r) / noise[i]
            X[i], v[i], res[i] = coef[0], noise[i] * np.linalg.inv(A.T @ A)[0, 0], r
        return chi2, X, v, res

    x = np.linspace(np.log(0.02 * n_min), np.log(2.0 * n_min), n_tau)      # log tau
    chis = np.array([fit(np.exp(xi))[0] for xi in x])
    k = int(np.argmin(chis))
    if k >= n_tau - 2 or k == 0:
        return None
    # the noise: the long-run variance of what the exponential leaves (the levels' own lrv, taken
    # from samples that still drift, counts the drift as noise)
    res = fit(np.exp(x[k]))[3]
    for i in idx:
        noise[i] = max(ar_long_run_variance([res[i]]), 1e-300)
    chis = np.array([fit(np.exp(xi))[0] for xi in x[k - 1:k + 2]])
    # the profile chi^2 near its minimum as a parabola in log tau: its vertex is the estimate and
    # its curvature the standard error (delta chi^2 = 1); tau's uncertainty reaches the intercepts
    # through dX/d(log tau), added to their own variance
    c2, c1, _ = np.polyfit(x[k - 1:k + 2], chis, 2)
    x0 = float(np.clip(-c1 / (2 * c2), x[k - 1], x[k + 1])) if c2 > 0 else float(x[k])
    se_x = float(np.sqrt(1.0 / c2)) if c2 > 0 else float(x[1] - x[0])
    tau = float(np.exp(x0))
    _, X, v, _ = fit(tau)
    dx = 0.01
    dX = (fit(np.exp(x0 + dx))[1] - fit(np.exp(x0 - dx))[1]) / (2 * dx)
    return X, np.sqrt(v + (dX * se_x) ** 2), tau
