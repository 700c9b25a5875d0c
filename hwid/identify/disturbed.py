"""Disturbed holds: the output moves beyond the noise while the input holds still (a push, a load,
a slip), so the hold's average is not the settled output ``X = h_bar(F_bar[U])`` of eq. (9).

A settled hold is noise about one value (after the settle cut of :mod:`hwid.identify.history`,
what is left of G's approach is a monotone decay far smaller than at its start). A hold is
**disturbed** where, after its first samples, the output

(a) stays for at least :data:`SUSTAIN` samples beyond both the hold's opening value (median of
    its first tenth, at least 3 samples) and its closing value (median of its last tenth) by more
    than the threshold, on the same side of both: it went out and came back, or overshot where it
    ended (a monotone approach, however slow, stays between the two); or
(b) leaves an opening whose spread stayed within the threshold by a step: the first samples
    that stay beyond the threshold from the opening value lie more than the threshold from where
    the output was :data:`JUMP` samples before (at most the opening's length; the median of the
    three samples there). A decaying transient -- largest at the start -- cannot step after a flat
    opening, and a slow drift crosses the threshold a little at a time.

The threshold is ``max(K * sigma, Q_FLOOR * q)``: ``sigma`` the noise's standard deviation from
the quieter holds (:func:`noise_scale`: the lower quartile over holds of the robust scale of each
one's last half, so up to three quarters of the holds disturbed do not raise it), ``q`` the
output's quantum.
``K = 5`` (about 4.4 true sigma, :func:`noise_scale`): a Gaussian excursion beyond that for two
samples running has a probability of order 1e-10 per pair of samples. The part of the hold before the disturbance (its onset: the first
sample that leaves the opening value by more than the threshold, for :data:`SUSTAIN` samples) is
what the hold says about the settled output; the rest is left out (:func:`onset`).

Calibration (the constants below): on hwid's chain with white noise (tests/test_stage1_levels.py),
12 seeds of a 22-level staircase flag no hold, and pushes of 15 sigma and a slip of 10 sigma are
each found at their start to within 2 samples; on the six STS3215 logs (encoder counts, q = 1) every
home hold the pullers move by 2 counts or more is found. ``Q_FLOOR = 1.5``: a quantised reading
toggling between adjacent counts is not a move, one of 2 counts that stays is. These are the only
data the rules were set on; other rigs are their test.
"""
from __future__ import annotations

import numpy as np

#: threshold in noise standard deviations
K = 5.0
#: and at least this many output quanta (a quantised hold reads its value +- one count)
Q_FLOOR = 1.5
#: samples beyond the threshold in a row that make an excursion (one is an outlier)
SUSTAIN = 2
#: samples within which a move counts as a step (rule b; at most the opening's length)
JUMP = 5


def noise_scale(holds, quantum: float | None = None) -> float:
    """The output noise's standard deviation from the quieter holds: the lower quartile over holds
    of ``1.4826 MAD`` of each one's last half (at least 3 samples; where any approach is over)
    about its own median, at least ``quantum / sqrt(12)``. A quarter of the holds undisturbed
    suffice; over 20 undisturbed holds of 100 Gaussian samples it is 0.88 sigma (5-95 %: 0.80-0.96,
    2000 draws), so the threshold of ``K`` of it is about 4.4 true sigma."""
    tails = [np.asarray(y[len(y) // 2:], float) for y in holds]
    scales = [1.4826 * float(np.median(np.abs(y - np.median(y)))) for y in tails if y.size >= 3]
    floor = (quantum or 0.0) / np.sqrt(12.0)
    return max(float(np.percentile(scales, 25)) if scales else 0.0, floor)


def threshold(sigma: float, quantum: float | None = None) -> float:
    return max(K * sigma, Q_FLOOR * (quantum or 0.0))


def _runs_beyond(mask: np.ndarray) -> int | None:
    """The first index at which ``mask`` holds for :data:`SUSTAIN` samples in a row."""
    if mask.size < SUSTAIN:
        return None
    run = np.convolve(mask.astype(int), np.ones(SUSTAIN, int), "valid")
    hits = np.flatnonzero(run == SUSTAIN)
    return int(hits[0]) if hits.size else None


def onset(y: np.ndarray, thr: float) -> int | None:
    """The sample of ``y`` (a hold after its settle cut) at which a disturbance begins (module
    docstring, rules a and b), or None when the hold is noise about one value."""
    y = np.asarray(y, float)
    n = y.size
    m = max(3, n // 10)
    if n < 2 * m + SUSTAIN or thr <= 0:
        return None
    first, last = float(np.median(y[:m])), float(np.median(y[-m:]))
    away = _runs_beyond(np.abs(y[m:] - first) > thr)       # the first sustained excursion
    if away is None:
        return None
    k = m + away
    far = (y > max(first, last) + thr) | (y < min(first, last) - thr)
    if _runs_beyond(far[m:]) is not None:                  # rule (a)
        return k
    w = min(JUMP, m)
    step = abs(float(np.median(y[k:k + SUSTAIN])) - float(np.median(y[max(k - w - 1, 0):k - w + 2])))
    if np.ptp(y[:m]) <= thr and step > thr:                # rule (b)
        return k
    return None
