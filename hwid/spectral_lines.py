"""Narrow-band components in what should be noise: a sinusoid at a frequency of its own (a periodic
load, a mains pick-up, a fan) in the differences of repeated records or in the scatter of settled
holds, which a noise floor must not take in.

The test (:func:`find_lines`) works on the pooled periodogram of ``P`` pieces (each less its mean,
zero-padded to one grid ``L`` samples long, ``OVERSAMPLE`` times the longest piece):

``T(omega) = sum_p |sum_t x_p(t) exp(-i omega t dt)|^2 / n_p``,

whose expectation is ``P S(omega)`` for noise of spectral density ``S`` (white or coloured: an AR
noise's smooth ``S``). ``S`` near ``omega`` is the mean of ``T`` over a window symmetric about it
(:data:`WINDOW` Fourier bins of the longest piece each side, beyond an exclusion of
:data:`EXCLUDE` bins that holds a line's main lobe): a smooth spectrum gives the window about the
value at its centre, and a convex one (a slow wander's ``1/omega^2``) more, never less. The ratio
``T / mean`` is then ``F(2P, 2Q)`` distributed for noise, ``Q`` the independent ordinates in the
window (Fisher's ``g`` test against a local, not a global, level: the latter rejects on every AR
spectrum). The smallest p-value, times the number of independent frequencies tested (Bonferroni;
the oversampled grid's largest ordinate counted as :data:`SCALLOP` times as many), is the family's:
below :data:`ALPHA` the peak is a line. Pieces that share noise (pairwise differences of three
repeats) are tested on an independent subset (:func:`disjoint`). Its frequency is refined on a fine
grid and a sinusoid at it (own amplitude and phase per piece: a load at its own frequency meets each
repeat at another phase) is fitted to every piece by least squares and taken out; the test is run
again on what is left, up to :data:`MAX_LINES` lines.

A line needs a few Fourier bins of the longest piece below it (the exclusion and the window's low
side: about 5 cycles over that piece): a load slower than that is not told from a wander here.
"""
from __future__ import annotations

from dataclasses import dataclass

import numpy as np
from scipy import stats

#: family-wise false-alarm rate of the line test, per set of pieces
ALPHA = 1e-3
#: most lines taken out of one set of pieces
MAX_LINES = 3
#: grid oversampling over the longest piece's Fourier spacing
OVERSAMPLE = 4
#: half-width (Fourier bins of the longest piece) of the main lobe left out of the local level
EXCLUDE = 2.0
#: Fourier bins of the longest piece each side of the local level's window
WINDOW = 12.0
#: the largest of the oversampled grid's ordinates is that of about this many times the independent
#: frequencies' (on white noise, 3 pieces of 300-5000 samples, 1000 trials each: 2-3 per 1000 false
#: lines at the nominal count and ALPHA 1e-3, so a factor 2.5 brings the rate to ALPHA)
SCALLOP = 2.5
#: an input's line (p at one frequency alone), whose frequency and harmonics a residual's line at
#: is the input's (:func:`find_lines` with ``inputs``)
INPUT_P = 1e-3
#: the harmonics of an input's line that are the input's too
HARMONICS = 5
#: fewest samples of a piece the test looks at
MIN_PIECE = 64


@dataclass(frozen=True)
class Line:
    """A narrow-band component found and taken out: its frequency ``omega`` (rad/s), its amplitude
    (the RMS over pieces of each piece's fitted sinusoid's amplitude, units of the pieces), the
    family-wise p-value of its test, and the share of the pieces' variance it took."""

    omega: float
    amplitude: float
    p_value: float
    variance_share: float

    def to_dict(self) -> dict:
        return {"kind": "narrow_band", "frequency_hz": float(self.omega / (2 * np.pi)), "rad_s": float(self.omega),
                "amplitude": float(self.amplitude), "p_value": float(self.p_value),
                "variance_share": float(self.variance_share)}


def _as_pieces(pieces) -> list[tuple[np.ndarray, np.ndarray]]:
    """``(sample index, value)`` per piece: a bare array is indexed 0..n-1."""
    out = []
    for p in pieces:
        idx, x = p if isinstance(p, tuple) else (np.arange(np.size(p)), p)
        idx, x = np.asarray(idx, int), np.asarray(x, float)
        out.append((idx - idx[0] if idx.size else idx, x))
    return out


def _periodogram(pieces, L: int) -> np.ndarray:
    """``T`` on the grid ``2 pi k / (L dt)``, ``k = 0 .. L/2``."""
    T = np.zeros(L // 2 + 1)
    for idx, x in pieces:
        z = np.zeros(int(idx[-1]) + 1)
        z[idx] = x - x.mean()
        T += np.abs(np.fft.rfft(z, L)) ** 2 / x.size
    return T


def _ordinates(pieces, L: int):
    """Every testable grid index ``k``, the log p-value of its ordinate against the local level
    (one frequency alone) and the number of independent frequencies tested; None if none is."""
    n_min, n_max = min(x.size for _, x in pieces), max(int(i[-1]) + 1 for i, _ in pieces)
    T = _periodogram(pieces, L)
    per_bin = L / n_max                        # grid points per Fourier bin of the longest piece
    excl, win = int(np.ceil(EXCLUDE * per_bin)), int(np.ceil(WINDOW * per_bin))
    first = int(np.ceil(L / n_min))            # below one Fourier bin the mean's removal depresses T
    last = T.size - 2
    csum = np.concatenate([[0.0], np.cumsum(T)])
    k = np.arange(T.size)
    half = np.minimum(np.minimum(k - excl - first, last - k - excl), win)    # symmetric window
    ok = half >= int(np.ceil(2 * per_bin))
    k, half = k[ok], half[ok]
    if not k.size:
        return None
    lo = csum[k - excl] - csum[k - excl - half]
    hi = csum[k + excl + half + 1] - csum[k + excl + 1]
    level = (lo + hi) / (2 * half)
    # independent ordinates in the window, over the pieces (a piece of n samples: one per L / n)
    q = 2 * half * sum(x.size for _, x in pieces) / L
    P = len(pieces)
    with np.errstate(divide="ignore", invalid="ignore"):
        ratio = np.where(level > 0, T[k] / level, 0.0)
    tests = SCALLOP * max((k[-1] - k[0]) * n_max / L, 1.0)   # independent frequencies tested
    return k, stats.f.logsf(ratio, 2 * P, 2 * q), tests


def _peak(pieces, L: int, locked=None) -> tuple[int, float] | None:
    """The grid index of the most significant ordinate (not among ``locked``, a boolean array over
    the grid) and its family-wise p-value."""
    found = _ordinates(pieces, L)
    if found is None:
        return None
    k, logp, tests = found
    if locked is not None:
        keep = ~locked[k]
        k, logp = k[keep], logp[keep]
        if not k.size:
            return None
    j = int(np.argmin(logp))
    return int(k[j]), float(min(1.0, np.exp(logp[j]) * tests))


def _locked(inputs, L: int, harmonics: int = HARMONICS) -> np.ndarray | None:
    """Grid points at a line of the ``inputs`` (p below :data:`INPUT_P` at that frequency alone) or
    at a harmonic 2..``harmonics`` of one, widened by the exclusion: what the input drives there is
    the model's to explain, no disturbance of its own."""
    found = _ordinates(inputs, L)
    if found is None:
        return None
    k, logp, _ = found
    n_max = max(int(i[-1]) + 1 for i, _ in inputs)
    width = int(np.ceil(EXCLUDE * L / n_max))
    out = np.zeros(L // 2 + 1, bool)
    for kk in k[logp < np.log(INPUT_P)]:
        for m in range(1, harmonics + 1):
            c = int(round(m * kk))
            if c - width >= out.size:
                break
            out[max(c - width, 0):min(c + width + 1, out.size)] = True
    return out


def _fit(pieces, omega_dt: float) -> tuple[list[np.ndarray], float, float]:
    """Each piece's least-squares sinusoid at ``omega_dt`` (rad/sample), with its mean: the pieces
    less the sinusoids, the total sum of squares taken, and the RMS amplitude over pieces."""
    out, taken, amps = [], 0.0, []
    for idx, x in pieces:
        A = np.column_stack([np.ones(x.size), np.cos(omega_dt * idx), np.sin(omega_dt * idx)])
        coef, *_ = np.linalg.lstsq(A, x, rcond=None)
        wave = A[:, 1:] @ coef[1:]
        out.append(x - wave)
        taken += float(np.sum((x - coef[0]) ** 2) - np.sum((x - coef[0] - wave) ** 2))
        amps.append(float(np.hypot(coef[1], coef[2])))
    return out, taken, float(np.sqrt(np.mean(np.square(amps))))


def _refine(pieces, k: int, L: int) -> float:
    """The frequency (rad/sample) within one grid step of ``k`` that takes most from the pieces."""
    grid = 2 * np.pi * (k + np.linspace(-1.0, 1.0, 41)) / L
    return float(max(grid, key=lambda w: _fit(pieces, w)[1]))


def find_lines(pieces, dt: float, alpha: float = ALPHA, max_lines: int = MAX_LINES, independent=None, inputs=None):
    """The narrow-band components of ``pieces`` (arrays, or ``(sample index, value)`` pairs for
    pieces with gaps) sampled every ``dt`` s, and the pieces with them taken out (module docstring).

    ``independent``: the indices of the pieces whose noise is independent of each other's (the
    test's null distribution counts them as such; differences of three repeats pairwise share
    records), default all; a line found on them is taken out of every piece. ``inputs``: for
    pieces that are a model's residual, the input on the same samples (same form as ``pieces``):
    a residual's line at a line of the input, or at one of its harmonics (:func:`_locked`), is the
    model's error at what the input drives, not a disturbance, and is neither tested nor taken out.

    Returns ``(cleaned pieces, [Line, ...])``, the cleaned pieces as value arrays in the order
    given; pieces shorter than :data:`MIN_PIECE` samples or not finite are returned as they are and
    take no part.
    Nothing is taken out of noise alone but with probability about ``alpha``."""
    pieces = _as_pieces(pieces)
    chosen = set(range(len(pieces)) if independent is None else independent)
    use = [i for i, (idx, x) in enumerate(pieces) if x.size >= MIN_PIECE and np.all(np.isfinite(x))]
    test = [j for j, i in enumerate(use) if i in chosen]
    values = [x for _, x in pieces]
    if not test:
        return values, []
    work = [pieces[i] for i in use]
    L = 1 << int(np.ceil(np.log2(OVERSAMPLE * max(int(work[j][0][-1]) + 1 for j in test))))
    total = float(sum(np.sum((x - x.mean()) ** 2) for _, x in work))
    locked = None
    if inputs is not None:
        ins = [_as_pieces(inputs)[i] for i in use]
        locked = _locked([ins[j] for j in test], L)
    lines = []
    while len(lines) < max_lines and total > 0:
        found = _peak([work[j] for j in test], L, locked)
        if found is None or found[1] >= alpha:
            break
        omega_dt = _refine([work[j] for j in test], found[0], L)
        cleaned, taken, amp = _fit(work, omega_dt)
        lines.append(Line(omega_dt / dt, amp, found[1], taken / total))
        work = [(idx, x) for (idx, _), x in zip(work, cleaned)]
    for i, (_, x) in zip(use, work):
        values[i] = x
    return values, lines


def disjoint(pairs) -> list[int]:
    """Indices of a greedy set of ``pairs`` (two keys each) no two of which share a key: pieces that
    are differences of records, each record in at most one of them, are independent."""
    used, out = set(), []
    for i, (a, b) in enumerate(pairs):
        if a not in used and b not in used:
            used.update((a, b))
            out.append(i)
    return out
