"""Whether a model is adequate for the records it is used on: its free-run residual against a noise
floor estimated from the data alone, with residual tests like the System Identification Toolbox's
``resid``.

The noise floor (:func:`estimate_floor`) comes, in this order, from

* repeats: records with identical inputs, whose outputs differ by noise alone once the start has
  been forgotten (``(y_a - y_b) / sqrt(2)``);
* settled holds: the second half of each stretch of constant input, where the output is constant
  but for noise and a slow drift (each block of at most :data:`BLOCK` samples less its own quadratic);
* a smoother: the residual of a local quartic (Savitzky-Golay, :data:`SMOOTHER_WINDOW` samples),
  whose variance is ``sigma^2 (1 - h_0)`` for white noise (``h_0`` the smoother's centre weight),
  away from the input's steps (:func:`quiet`);
* the quantum, where a quantised output rests on one value between most samples;

never below the output's quantum ``q / sqrt(12)`` and never above the output's own spread (a floor
that large is undetermined: the data cannot tell noise from signal). With none of these the floor
is undetermined. Narrow-band components of the
repeats' differences or of the holds' scatter (a load at a frequency of its own,
:func:`hwid.spectral_lines.find_lines`) are no noise: they are taken out before the floor is
estimated and listed in ``NoiseFloor.set_aside``.

The verdict (:func:`assess`): the model's mean-square residual over the floor's is ``F(n_eff, dof)``
distributed when the residual is noise (``n_eff`` the scored samples over the noise's correlation
time, ``dof`` the floor's degrees of freedom); above its ``1 - ALPHA`` quantile the model is a
misfit. A block whose variance or mean is an outlier against the others (a push on a hold, a step
inside the smoother's window) is left out of the floor before pooling.
"""
from __future__ import annotations

import dataclasses
from dataclasses import asdict, dataclass

import numpy as np
from scipy import signal, special, stats

from hwid import spectral_lines
from hwid.masks import runs

#: false-alarm rate of the misfit test on a correct model (per assessment)
ALPHA = 0.01
#: fewest scored samples to judge a model on
MIN_SCORED = 50
#: fewest degrees of freedom of a floor estimate from repeats or holds before the next source is tried
MIN_DOF = 30
#: longest block detrended by its own quadratic (samples): a slow drift is a parabola over it
BLOCK = 100
#: fewest samples of a hold's settled half, of a repeat, of a smoother block
MIN_BLOCK = 20
#: the smoother's window (samples) and polynomial order
SMOOTHER_WINDOW, SMOOTHER_ORDER = 21, 4
#: an input change larger than this many times the median change is a step (:func:`input_steps`)
STEP = 10.0
#: a block whose variance exceeds the median block's by this tail probability is left out of the floor
OUTLIER_P = 1e-3
#: Largest lag of the residual tests (whiteness and input correlation), as MATLAB's ``resid`` draws them;
#: the residual is decimated so that these lags span G's settling time (:func:`lag_step`).
MAX_LAG = 25


@dataclass(frozen=True)
class NoiseFloor:
    """The output-noise standard deviation ``sigma`` (units of y, > 0) and where it came from.

    ``dof`` are the degrees of freedom of ``sigma^2`` (0: not from data); ``kappa`` the noise's
    correlation time in samples (1: white); ``determined`` is False where the estimate came out at
    or above the output's own spread (``sigma`` is then that spread, and ``reason`` says so);
    ``set_aside`` the narrow-band components taken out of the source before the estimate
    (:meth:`hwid.spectral_lines.Line.to_dict` each)."""

    sigma: float
    source: str
    quantum: float
    dof: float = 0.0
    kappa: float = 1.0
    determined: bool = True
    reason: str = ""
    set_aside: tuple = ()

    def interval(self, level: float = 0.95) -> tuple[float, float] | None:
        """The ``level`` sampling interval of ``sigma`` (chi-square on ``dof``), None without dof."""
        if self.dof <= 0 or not self.determined:
            return None
        lo, hi = stats.chi2.ppf([(1 + level) / 2, (1 - level) / 2], self.dof)
        return float(self.sigma * np.sqrt(self.dof / lo)), float(self.sigma * np.sqrt(self.dof / hi))

    def to_dict(self) -> dict:
        iv = self.interval()
        return {**asdict(self), "set_aside": [dict(d) for d in self.set_aside],
                "interval": None if iv is None else list(iv)}


@dataclass(frozen=True)
class Adequacy:
    """A model's residual on its records against the noise floor, and the verdict on it."""

    verdict: str
    rms_fit: float
    rms_held_out: float | None
    floor: NoiseFloor
    ratio: float
    whiteness_p: float | None
    input_correlation_p: float | None
    reason: str
    scored: int = 0
    bound: float | None = None

    @property
    def misfit(self) -> bool:
        return self.verdict == "misfit"

    @property
    def model_error(self) -> float | None:
        """The model's own error (RMS, units of y) beside the noise: ``sigma sqrt(ratio^2 - 1)``, the
        part of the worst residual the noise floor does not account for (0 within the floor; None
        where the ratio is not finite or the floor undetermined). A misfit over millions of samples
        may be a model error small beside the noise: this says how small."""
        if not (np.isfinite(self.ratio) and self.floor.determined):
            return None
        return float(self.floor.sigma * np.sqrt(max(self.ratio ** 2 - 1.0, 0.0)))

    def to_dict(self) -> dict:
        return {"verdict": self.verdict, "rms_fit": self.rms_fit, "rms_held_out": self.rms_held_out,
                "floor": self.floor.to_dict(), "ratio": self.ratio, "whiteness_p": self.whiteness_p,
                "input_correlation_p": self.input_correlation_p, "reason": self.reason, "scored": self.scored,
                "bound": self.bound, "model_error": self.model_error}

    @classmethod
    def from_dict(cls, d: dict | None) -> "Adequacy | None":
        """Inverse of :meth:`to_dict` (the derived ``model_error`` and the floor's ``interval`` are
        computed again, not read); None for None or an empty dict."""
        if not d:
            return None
        fields = {f.name for f in dataclasses.fields(NoiseFloor)}
        floor = NoiseFloor(**{k: tuple(v) if k == "set_aside" else v for k, v in d["floor"].items() if k in fields})
        own = {f.name for f in dataclasses.fields(cls)}
        return cls(**{k: v for k, v in d.items() if k in own and k != "floor"}, floor=floor)


# ----------------------------------------------------------------------------------------------
# the noise floor

def _quadratic_residual(x: np.ndarray) -> np.ndarray:
    """``x`` less its least-squares quadratic in time."""
    t = np.linspace(-1.0, 1.0, x.size)
    return x - np.polyval(np.polyfit(t, x, 2), t)


def _blocks(x: np.ndarray) -> list[np.ndarray]:
    """``x`` cut into near-equal blocks of at most :data:`BLOCK` samples (none below :data:`MIN_BLOCK`)."""
    if x.size < MIN_BLOCK:
        return []
    k = int(np.ceil(x.size / BLOCK))
    return [b for b in np.array_split(x, k) if b.size >= MIN_BLOCK]


def correlation_time(e: np.ndarray, lags: int = 50) -> float:
    """Integrated autocorrelation time of ``e`` in samples (1 for white noise; Sokal's window)."""
    e = np.asarray(e, float) - np.mean(e)
    c0 = float(e @ e)
    if e.size < 4 * lags or c0 == 0:
        return 1.0
    tau = 1.0
    for k in range(1, lags):
        tau += 2.0 * float(e[k:] @ e[:-k]) / c0
        if k >= 5 * tau:
            break
    return float(max(tau, 1.0))


def _not_outliers(var: np.ndarray, dof: np.ndarray) -> np.ndarray:
    """Which blocks to keep: those whose variance ``var`` (on ``dof`` degrees of freedom) is not an
    outlier above the median block's (:data:`OUTLIER_P`); a disturbance, not noise, makes one."""
    med = float(np.median(var))
    return (med == 0) | (var <= med * stats.chi2.ppf(1 - OUTLIER_P, dof) / dof)


def _pooled(pieces: list[tuple[float, float, float]]) -> tuple[float, float] | None:
    """Pooled variance and its dof from per-block ``(sum of squares, its expectation over sigma^2,
    dof)``, leaving out the outlying blocks (:func:`_not_outliers`)."""
    pieces = [p for p in pieces if p[1] > 0 and p[2] > 0]
    if not pieces:
        return None
    ss, n, dof = (np.array([p[k] for p in pieces], float) for k in range(3))
    keep = _not_outliers(ss / n, dof)
    return (float(ss[keep].sum() / n[keep].sum()), float(dof[keep].sum())) if n[keep].sum() > 0 else None


def _detrending(n: int) -> np.ndarray:
    """``I - P`` for a block of ``n`` samples, ``P`` the projection onto a quadratic in time."""
    t = np.linspace(-1.0, 1.0, n)
    q, _ = np.linalg.qr(np.vander(t, 3))
    return np.eye(n) - q @ q.T


def _lag_sums(r: np.ndarray, lags: int) -> np.ndarray:
    """``sum_t r(t) r(t + k)`` for ``k = 0 .. lags``."""
    return np.array([float(r[:r.size - k] @ r[k:]) for k in range(lags + 1)])


def _moments(blocks: list[np.ndarray], lags: int) -> tuple[np.ndarray, np.ndarray]:
    """The method-of-moments system for the noise's autocovariances ``gamma_0 .. gamma_lags`` from
    blocks each detrended by its own quadratic: ``sums[k] = sum_t r(t) r(t+k)`` over the blocks and
    ``design[k, j] = tr(D_k M A_j M)`` summed over them (``M`` the detrending, ``A_j`` ones on the
    diagonals ``+-j``, ``D_k`` ones on diagonal ``k``), so that ``E[sums] = design @ gamma``. With
    ``gamma_j = 0`` beyond some ``K <= lags`` the system is its leading ``K + 1`` rows and columns
    (:func:`_autocovariances`)."""
    sums, design = np.zeros(lags + 1), np.zeros((lags + 1, lags + 1))
    by_size: dict[int, list[np.ndarray]] = {}
    for b in blocks:
        by_size.setdefault(b.size, []).append(b)
    for n, group in by_size.items():
        m = _detrending(n)
        for b in group:
            sums += _lag_sums(m @ b, lags)
        for j in range(lags + 1):
            b_j = m @ (np.eye(n, k=j) + (np.eye(n, k=-j) if j else 0.0)) @ m
            design[:, j] += len(group) * np.array([np.trace(b_j, offset=k) for k in range(lags + 1)])
    return sums, design


def _autocovariances(sums: np.ndarray, design: np.ndarray, lags: int) -> np.ndarray | None:
    """``gamma_0 .. gamma_lags`` of :func:`_moments`' system with ``gamma_j = 0`` beyond ``lags``;
    None where it is singular or ``gamma_0`` is not positive."""
    k = lags + 1
    try:
        gamma = np.linalg.solve(design[:k, :k], sums[:k])
    except np.linalg.LinAlgError:
        return None
    return gamma if gamma[0] > 0 else None


def correlated_floor(blocks: list[np.ndarray], max_lag: int = 20) -> tuple[float, float, float] | None:
    """The noise variance, its degrees of freedom and its correlation time (samples) from blocks of
    noise plus a slow trend: ``(var, dof, kappa)``, or None with too few samples.

    Each block is detrended by its own quadratic; an outlying block (:func:`_not_outliers`) is left
    out. A quadratic fitted to correlated noise takes more of it than its three parameters' share
    (about ``3 kappa`` samples' worth, not 3: on AR(1) noise with coefficient 0.5 the plain estimate
    reads the noise 5 % low), so the variance and the autocorrelation are estimated together
    (:func:`_moments`), the lags summed up to Sokal's window (the smallest ``K >= 5 kappa_K``).
    ``dof``: the samples left after the trends, over ``kappa``."""
    blocks = [np.asarray(b, float) for b in blocks if np.size(b) >= MIN_BLOCK]
    if not blocks:
        return None
    ss = np.array([float(r @ r) for r in map(_quadratic_residual, blocks)])
    dof = np.array([b.size - 3.0 for b in blocks])
    kept = _not_outliers(ss / dof, dof)
    keep = [b for b, k in zip(blocks, kept) if k]
    n_free = float(dof[kept].sum())
    lags = int(min(max_lag, min(b.size for b in keep) // 3))
    system = _moments(keep, lags) if lags >= 1 else None
    gamma = None if system is None else _autocovariances(*system, lags)
    if gamma is None:
        return float(ss[kept].sum() / n_free), n_free, 1.0
    rho = gamma[1:] / gamma[0]
    kappa, window = 1.0, lags
    for k in range(1, lags + 1):
        kappa, window = 1.0 + 2.0 * float(np.sum(rho[:k])), k
        if k >= 5 * kappa:
            break
    kappa = float(max(kappa, 1.0))
    if window < lags:                               # the covariances within the window only
        gamma = _autocovariances(*system, window)
        if gamma is None:
            return None
    return float(gamma[0]), n_free / kappa, kappa


def _start(rec) -> int:
    return int(getattr(rec, "attrs", {}).get("pre", 0) or 0)


def _without_lines(pieces, records, independent=None) -> tuple[list[np.ndarray], tuple]:
    """``pieces`` with their narrow-band components taken out (:func:`hwid.spectral_lines.find_lines`,
    at the records' sample time, tested on the ``independent`` pieces), and those components as dicts."""
    dt = float(getattr(records[0], "dt", 0.0) or 0.0) if records else 0.0
    if not (pieces and dt > 0):
        return pieces, ()
    cleaned, lines = spectral_lines.find_lines(pieces, dt, independent=independent)
    return cleaned, tuple(ln.to_dict() for ln in lines)


def _lines_note(lines: tuple) -> str:
    if not lines:
        return ""
    return "; narrow-band component(s) at " + ", ".join(f"{ln['rad_s']:.4g} rad/s" for ln in lines) + " set aside"


def _repeats(records) -> tuple | None:
    """The floor from pairs of records with identical inputs: ``(var, dof, kappa, detail, set
    aside)`` or None."""
    diffs, pairs, who = [], 0, []
    for i, a in enumerate(records):
        ua = np.asarray(a.u, float)[_start(a):]
        for j, b in enumerate(records[i + 1:], i + 1):
            ub = np.asarray(b.u, float)[_start(b):]
            if ua.size != ub.size or ua.size < 5 * MIN_BLOCK or not np.array_equal(ua, ub):
                continue
            d = (np.asarray(a.y, float)[_start(a):] - np.asarray(b.y, float)[_start(b):]) / np.sqrt(2.0)
            diffs.append(d[d.size // 5:])         # the first fifth: the starts may differ
            who.append((i, j))
            pairs += 1
    diffs, lines = _without_lines(diffs, records, spectral_lines.disjoint(who))
    found = correlated_floor([b for d in diffs for b in _blocks(d)])
    if found is None or found[1] < MIN_DOF:
        return None
    return (*found, f"{pairs} pair(s) of repeated records{_lines_note(lines)}", lines)


def hold_segments(u: np.ndarray, min_samples: int = 2 * MIN_BLOCK) -> list[tuple[int, int]]:
    """``[start, stop)`` of each stretch of at least ``min_samples`` equal input samples."""
    u = np.asarray(u, float)
    if u.size < min_samples:
        return []
    change = np.flatnonzero(np.diff(u) != 0) + 1
    bounds = np.concatenate([[0], change, [u.size]])
    return [(int(a), int(b)) for a, b in zip(bounds[:-1], bounds[1:]) if b - a >= min_samples]


def _holds(records, off_rails: tuple = ()) -> tuple | None:
    """The floor from the settled half of each hold: ``(var, dof, kappa, detail, set aside)`` or None;
    a hold that reads a rail of ``off_rails`` is left out (a sensor there reads no noise)."""
    settled = []
    for r in records:
        y = np.asarray(r.y, float)
        settled += [y[(a + b) // 2:b] for a, b in hold_segments(r.u) if b - (a + b) // 2 >= MIN_BLOCK
                    and not np.isin(y[(a + b) // 2:b], off_rails).any()]
    settled, lines = _without_lines(settled, records)
    parts = [b for s in settled for b in _blocks(s)]
    found = correlated_floor(parts)
    if found is None or found[1] < MIN_DOF:
        return None
    return (*found, f"{len(settled)} hold(s){_lines_note(lines)}", lines)


def _smoother_kernel(window: int) -> tuple[float, float]:
    """The local polynomial's centre weight ``h_0`` and the dof per sample of its residual's
    mean square for white noise (``1 / sum_k rho_k^2``, ``rho`` the residual's autocorrelation)."""
    h = signal.savgol_coeffs(window, SMOOTHER_ORDER)
    g = -h
    g[window // 2] += 1.0
    acf = np.correlate(g, g, mode="full")
    acf /= acf[window - 1]
    return float(h[window // 2]), float(1.0 / np.sum(acf * acf))


def input_steps(u) -> np.ndarray:
    """Where the input steps: the samples ``k`` whose change from ``k - 1`` exceeds :data:`STEP`
    times the median absolute change (any change, where that median is 0: a piecewise constant
    input). A sine or a ramp, however fast, has none."""
    du = np.abs(np.diff(np.asarray(u, float)))
    if not du.size:
        return np.zeros(0, int)
    med = float(np.median(du))
    return np.flatnonzero(du > STEP * med if med > 0 else du > 0) + 1


def quiet(u, n: int, window: int) -> np.ndarray:
    """The samples of a record of ``n`` whose ``window`` (centred) neither holds an input step nor
    ends within a window after one: where a plant's response is smooth on the window's scale
    however fast it follows a step (:func:`input_steps`)."""
    m = np.ones(n, bool)
    if u is None:
        return m
    half = window // 2
    for k in input_steps(np.asarray(u, float)[:n]):
        m[max(k - half, 0): k + half + window] = False
    return m


def _smoother(records, off_rails: tuple = ()) -> tuple | None:
    """The floor from a local quartic's residual, its variance corrected by ``1 - h_0``, where the
    output is smooth on the quartic's window (:func:`quiet`): at a step, a servo that follows it
    within a sample or two leaves a residual that is its own motion (STS3215 log halves: 6.6-8.5
    counts from the whole residual, the encoder's quantum 0.29)."""
    pieces, used = [], 0
    for r in records:
        y = np.asarray(r.y, float)
        window = min(SMOOTHER_WINDOW, (y.size // 2) * 2 - 1)
        if window <= SMOOTHER_ORDER + 2:
            continue
        h0, per_sample = _smoother_kernel(window)
        res = y - signal.savgol_filter(y, window, SMOOTHER_ORDER)
        ok = quiet(getattr(r, "u", None), y.size, window) & ~np.isin(y, off_rails)
        ok[:window // 2] = ok[y.size - window // 2:] = False
        for a, b in runs(ok):
            for blk in _blocks(res[a:b]):
                pieces.append((float(blk @ blk), blk.size * (1.0 - h0), blk.size * per_sample))
        used += 1
    pooled = _pooled(pieces)
    if pooled is None:
        return None
    return pooled[0], pooled[1], 1.0, f"a local quartic over {SMOOTHER_WINDOW} samples on {used} record(s)", ()


def _still_on_the_quantum(records, q: float) -> bool:
    """Whether a quantised output rests on one value between most consecutive samples (the median
    absolute change is 0): its noise is then within the quantum."""
    if q <= 0:
        return False
    d = np.concatenate([np.abs(np.diff(np.asarray(r.y, float))) for r in records])
    return bool(d.size) and float(np.median(d)) == 0.0


def output_quantum(records, quantum: float = 0.0) -> float:
    """The output's resolution ``q``: ``quantum``, a record's ``output_resolution``, or 1 where every
    output sample is an integer (counts); the largest of these."""
    q = [float(quantum or 0.0)] + [float(getattr(r, "attrs", {}).get("output_resolution", 0.0) or 0.0)
                                   for r in records]
    y = np.concatenate([np.asarray(r.y, float) for r in records]) if records else np.zeros(0)
    if y.size and np.ptp(y) > 0 and np.all(y == np.round(y)):
        q.append(1.0)
    return max(q)


def output_spread(records) -> float:
    """The output's own standard deviation about each record's mean (units of y)."""
    return _spread([r.y for r in records])


def _spread(outputs) -> float:
    parts = [np.asarray(y, float) - np.mean(y) for y in outputs if np.size(y)]
    return float(np.std(np.concatenate(parts))) if parts else 0.0


def estimate_floor(records, quantum: float = 0.0, off_rails: tuple = ()) -> NoiseFloor:
    """The output-noise standard deviation from the data alone: repeats (identical inputs) where
    there are any; else the scatter within settled holds; else a local high-order smoother's
    residual; never below the quantum ``q / sqrt(12)``, never above the output's spread. Holds
    and smooth stretches that read a sensor's rail (``off_rails``) are left out.

    Raises ``ValueError`` when no record has an output."""
    records = [r for r in records if getattr(r, "y", None) is not None and np.size(r.y) > 0]
    if not records:
        raise ValueError("no record with an output to estimate the noise floor from")
    q = output_quantum(records, quantum)
    qf = q / np.sqrt(12.0)
    spread = output_spread(records)
    for source, how in (("repeats", _repeats), ("holds", lambda rs: _holds(rs, off_rails)),
                        ("smoother", lambda rs: _smoother(rs, off_rails))):
        found = how(records)
        if found is not None:
            var, dof, kappa, detail, aside = found
            break
    else:
        if not _still_on_the_quantum(records, q):
            sigma = float(qf) if qf > 0 else (1e-6 * spread if spread > 0 else 1e-12)
            return NoiseFloor(sigma, "none", float(qf), 0.0, 1.0, False,
                              "no repeat, settled hold or stretch smooth on the smoother's window to estimate it "
                              "from: the data do not determine the noise floor", ())
        source, var, dof, kappa, aside = "quantum", 0.0, 0.0, 1.0, ()
        detail = ("no repeat, settled hold or smooth stretch; the output rests on one value between most samples, "
                  "its noise within the quantum")
    sigma, reason = float(np.sqrt(var)), f"from {detail}"
    if sigma < qf:
        sigma, source, dof = float(qf), "quantum", 0.0
        reason += f"; raised to the output's quantum {q:.4g} / sqrt(12)"
    if sigma == 0.0:
        sigma = 1e-6 * spread if spread > 0 else 1e-12
        reason += "; no noise seen, floor set at 1e-6 of the output's spread"
    floor = NoiseFloor(sigma, source, float(qf), float(dof), float(kappa), True, reason, aside)
    upper = floor.interval(0.99)
    if sigma >= spread or (upper is not None and upper[1] >= spread):
        reason += (f"; the estimate {sigma:.4g} is not clearly below the output's own spread {spread:.4g}: the data "
                   "cannot tell noise from signal")
        return NoiseFloor(float(min(sigma, spread)) if spread > 0 else sigma, source, float(qf), 0.0, kappa, False,
                          reason, aside)
    return floor


# ----------------------------------------------------------------------------------------------
# residual tests

def _lags(n: int, max_lag: int) -> int:
    return int(max(1, min(max_lag, n // 4)))


def ljung_box(residual, max_lag: int = MAX_LAG) -> tuple[float, int]:
    """Ljung-Box statistic of ``residual`` over ``max_lag`` lags (fewer on short records) and its dof."""
    e = np.asarray(residual, float) - np.mean(residual)
    n, m = e.size, _lags(e.size, max_lag)
    c0 = float(e @ e)
    if c0 == 0:
        return 0.0, m
    r = np.array([float(e[k:] @ e[:-k]) / c0 for k in range(1, m + 1)])
    return float(n * (n + 2) * np.sum(r * r / (n - np.arange(1, m + 1)))), m


def input_correlation(residual, u, max_lag: int = MAX_LAG) -> tuple[float, int]:
    """``n sum_k rho_eu(k)^2`` over lags ``k = 0 .. max_lag-1`` (residual against past inputs),
    chi-square with that many degrees of freedom when the two are uncorrelated."""
    e = np.asarray(residual, float) - np.mean(residual)
    x = np.asarray(u, float) - np.mean(u)
    n, m = e.size, _lags(e.size, max_lag)
    scale = np.sqrt(float(e @ e) * float(x @ x))
    if scale == 0:
        return 0.0, m
    rho = np.array([float(e[k:] @ x[:n - k]) / scale for k in range(m)])
    return float(n * np.sum(rho * rho)), m


def settling_time(model) -> float:
    """2 % settling time of G (s) from its slowest stable pole and its delay; inf when G is unstable."""
    p = np.asarray(model.linear.poles())
    if p.size and np.max(p.real) >= 0:
        return float("inf")
    slow = np.min(np.abs(p.real)) if p.size else np.inf
    return float(4.0 / slow + model.linear.delay) if np.isfinite(slow) and slow > 0 else float(model.linear.delay)


def _scored(model, records, starts: dict | None, settle_s: float, off_rails: tuple = ()) -> list[tuple]:
    """``(residual, u)`` on each record's scored samples: all of it from a given start (the gear, G's
    rest level and, with a slewing actuator, its position: a Backlash-Inverse's output follows
    wherever the slew from there takes it), else after a burn-in of 1.5 settling times and the
    first fifth (the rig's state before the record); samples reading one of ``off_rails`` (a
    sensor's rails, :mod:`hwid.identify.rails`) left out."""
    out = []
    for r in records:
        u, y = np.asarray(r.u, float), np.asarray(r.y, float)
        if u.size < 10 or y.size != u.size:
            continue
        st = (starts or {}).get(r.name)
        with np.errstate(all="ignore"):
            if st is not None:
                x, k0 = model.simulate(u, r.dt, gear=st["gear"], rest=st["rest"], position=st.get("position")).x, 0
            else:
                x = model.simulate(u, r.dt).x
                burn = 1.5 * settle_s / r.dt if np.isfinite(settle_s) else 0.0
                k0 = int(max(round(burn), u.size // 5))
        keep = np.arange(u.size) >= k0
        for value in off_rails:
            keep &= y != value
        if keep.sum() > 10:
            out.append((y[keep] - x[keep], u[keep], y[keep]))
    return out


def lag_step(dt: float, settle_s: float, max_lag: int = MAX_LAG) -> int:
    """Decimation of the residual tests: every ``step``-th sample, so that ``max_lag`` lags span the
    settling time ``settle_s`` of G (``floor(settle_s / (max_lag dt))``, at least 1). No filter, so a
    white residual stays white; at the raw rate, 25 lags of a fast sampler see only the first instants
    of the model's memory."""
    if not (dt > 0 and np.isfinite(settle_s) and settle_s > 0):
        return 1
    return max(1, int(np.floor(settle_s / (max_lag * dt) + 1e-9)))


def residual_tests(residuals, inputs, step: int = 1, max_lag: int = MAX_LAG) -> tuple[float | None, float | None]:
    """The whiteness (Ljung-Box, :func:`ljung_box`) and input-correlation (:func:`input_correlation`)
    p-values pooled over records: each residual and its input decimated by ``step`` (less on a record
    too short to give ``5 max_lag`` samples after it), the chi-square statistics and their degrees of
    freedom summed. Records with fewer than ``4 max_lag`` samples after decimation, or a residual not
    finite, are left out; ``(None, None)`` where none is left. The one definition of these p-values:
    ``hwid compare``'s JSON, its figures and every adequacy verdict use it."""
    qw = qi = 0.0
    mw = mi = 0
    for e, u in zip(residuals, inputs):
        e, u = np.asarray(e, float), np.asarray(u, float)
        k = max(1, min(int(step), e.size // (5 * max_lag)))
        e, u = e[::k], u[::k]
        if e.size < 4 * max_lag or not np.all(np.isfinite(e)):
            continue
        a, m = ljung_box(e, max_lag)
        b, j = input_correlation(e, u, max_lag)
        qw, mw, qi, mi = qw + a, mw + m, qi + b, mi + j
    if not mw:
        return None, None
    return float(special.chdtrc(mw, qw)), float(special.chdtrc(mi, qi))


def _rms(scored) -> float | None:
    if not scored:
        return None
    e = np.concatenate([s[0] for s in scored])
    with np.errstate(all="ignore"):
        return float(np.sqrt(np.mean(e * e)))


def _bound(n: int, floor: NoiseFloor, alpha: float) -> float:
    """The largest RMS / floor a correct model reaches with probability ``1 - alpha``."""
    n_eff = max(n / max(floor.kappa, 1.0), 1.0)
    q = stats.chi2.ppf(1 - alpha, n_eff) / n_eff if floor.dof <= 0 else stats.f.ppf(1 - alpha, n_eff, floor.dof)
    return float(np.sqrt(q))


def assess(model, records, held_out=(), floor: NoiseFloor | None = None, starts: dict | None = None,
           alpha: float = ALPHA, label: str = "its own records", off_rails: tuple = ()) -> Adequacy:
    """Whether ``model`` (an :class:`hwid.model.HWModel`) explains ``records`` (and ``held_out``)
    down to the noise floor: the model's free run on each record (:func:`_scored`), judged by
    :func:`judge`.

    ``starts``: ``{record name: {"gear", "rest"}}`` as the whole fit estimates them; records without
    one are scored after a burn-in of 1.5 settling times and the first fifth. ``floor`` None:
    :func:`estimate_floor` on all records. ``label``: what ``records`` are, for the reason.
    ``off_rails``: readings of a sensor's rails, whose samples are not scored (no model of the
    paper's class clips its output; the identification sets them aside, :mod:`hwid.identify.rails`)."""
    records, held_out = list(records), list(held_out)
    if floor is None:
        floor = estimate_floor(records + held_out, off_rails=off_rails)
    settle = settling_time(model)
    fit, held = _scored(model, records, starts, settle, off_rails), _scored(model, held_out, starts, settle, off_rails)
    step = lag_step(records[0].dt, settle) if records else 1
    return judge(fit, floor, held, step, alpha, label)


def judge(scored, floor: NoiseFloor, held_out=(), step: int = 1, alpha: float = ALPHA,
          label: str = "its own records") -> Adequacy:
    """The verdict on a model's residuals: ``scored`` and ``held_out`` hold ``(residual, input,
    output)`` per record on its scored samples; ``step`` decimates the residual for the residual
    tests (:func:`lag_step`).

    ``misfit`` when a residual is not finite (the free run diverges), when the RMS exceeds the
    output's own spread (worse than the output's mean), or when the worst RMS over the floor exceeds
    its ``1 - alpha`` bound (:func:`_bound`, ``alpha`` split between the fit and held-out records);
    ``undetermined`` with fewer than :data:`MIN_SCORED` scored samples or an undetermined floor;
    else ``adequate``."""
    fit, held = list(scored), list(held_out)
    rms_fit, rms_held = _rms(fit), _rms(held)
    rms_fit = float("nan") if rms_fit is None else rms_fit
    n_scored = sum(s[0].size for s in fit + held)
    white_p, input_p = residual_tests([s[0] for s in fit + held], [s[1] for s in fit + held], step)
    parts = [(rms_fit, fit, label)] + ([(rms_held, held, "the held-out records")] if held else [])
    ratio = max(r for r, _, _ in parts) / floor.sigma
    spread = _spread([s[2] for s in fit + held])

    def result(verdict: str, reason: str, bound: float | None = None) -> Adequacy:
        return Adequacy(verdict, rms_fit, rms_held, floor, float(ratio), white_p, input_p, reason, int(n_scored),
                        bound)

    if n_scored < MIN_SCORED:
        return result("undetermined", f"only {n_scored} scored samples (at least {MIN_SCORED} are needed to judge "
                                      "the model)")
    worst = max(parts, key=lambda p: p[0] if np.isfinite(p[0]) else np.inf)
    if not np.isfinite(worst[0]):
        return result("misfit", f"the model's free run on {worst[2]} is not finite: it diverges")
    if worst[0] > spread and floor.determined or worst[0] > 2 * spread:
        return result("misfit", f"the model's free run misses {worst[2]} by RMS {worst[0]:.4g}, more than the "
                                f"output's own spread {spread:.4g} (worse than its mean): it diverges or is far off")
    if not floor.determined:
        return result("undetermined", f"RMS {worst[0]:.4g} on {worst[2]}, but the noise floor is undetermined "
                                      f"({floor.reason})")
    verdicts = []
    for rms, sc, what in parts:
        bound = _bound(sum(s[0].size for s in sc), floor, alpha / len(parts))
        verdicts.append((rms / floor.sigma > bound, rms, bound, what))
    bad = [v for v in verdicts if v[0]]
    if bad:
        _, rms, bound, what = max(bad, key=lambda v: v[1] / v[2])
        own = floor.sigma * np.sqrt(max((rms / floor.sigma) ** 2 - 1.0, 0.0))
        return result("misfit", f"RMS {rms:.4g} on {what} = {rms / floor.sigma:.3g} x the noise floor "
                                f"{floor.sigma:.4g} ({floor.source}), above the {bound:.4g} a correct model reaches "
                                f"(false-alarm rate {alpha:g}); the model's own error is about {own:.3g} RMS, "
                                f"{own / floor.sigma:.2g} x the noise", bound)
    bound = max(v[2] for v in verdicts)
    return result("adequate", f"RMS {worst[0]:.4g} on {worst[2]} = {ratio:.3g} x the noise floor {floor.sigma:.4g} "
                              f"({floor.source}), within the {bound:.4g} a correct model reaches", bound)
