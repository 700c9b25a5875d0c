"""The search helpers of the effect fits (:class:`hwid.diagnose.rank.EffectFitter`): parameters
mapped to and from the unit box least squares works on (log scale where a parameter spans decades),
and the profile scan that finds a valley least squares did not start in."""
from __future__ import annotations

import numpy as np


def to_unit(theta, lo, hi, logs) -> np.ndarray:
    """``theta`` in the unit box of ``[lo, hi]`` (log scale where ``logs``), clipped to it."""
    t = np.asarray(theta, float)
    out = np.empty_like(t)
    for i, lg in enumerate(logs):
        if lg:
            out[i] = (np.log(t[i]) - np.log(lo[i])) / (np.log(hi[i]) - np.log(lo[i]))
        else:
            out[i] = (t[i] - lo[i]) / (hi[i] - lo[i]) if hi[i] > lo[i] else 0.0
    return np.clip(out, 0.0, 1.0)


def from_unit(x, lo, hi, logs) -> np.ndarray:
    """The inverse of :func:`to_unit`."""
    out = np.empty(len(logs))
    for i, lg in enumerate(logs):
        xi = float(np.clip(x[i], 0.0, 1.0))
        out[i] = np.exp(np.log(lo[i]) + xi * (np.log(hi[i]) - np.log(lo[i]))) if lg else lo[i] + xi * (hi[i] - lo[i])
    return out


def profile_scan(cost, best, best_cost, lo, hi, logs, n_own: int, n: int):
    """The first ``n_own`` parameters scanned one at a time (the others held at the best so far):
    ``n`` values over the whole range, then as many across the cells either side of the best of
    them; round again while that moves the best. Returns ``(best, best_cost)``.

    Least squares follows the slope it starts on; the cost of a clip, a deadzone or a slew seen
    through a steep output stage (the paper's h) is a narrow valley between ridges, and the
    coarse starting grid can miss it: an input clip 0.05 off its level on a paper-base rig left
    10x the noise floor where the true level leaves the floor itself. Each limit of a clip, the
    width of a deadzone or a rate acts mostly on its own, so a profile along each parameter
    finds the valley that least squares then descends."""
    best = np.asarray(best, float).copy()

    def along(k, grid):
        nonlocal best, best_cost
        moved = False
        for v in grid:
            th = best.copy()
            th[k] = v
            c = cost(th)
            if c < best_cost:
                best_cost, best, moved = c, th, True
        return moved

    for _ in range(2):
        moved = False
        for k in range(n_own):
            log = bool(logs[k]) and lo[k] > 0
            a, b = (np.log(lo[k]), np.log(hi[k])) if log else (lo[k], hi[k])
            coarse = np.linspace(a, b, n)
            moved |= along(k, np.exp(coarse) if log else coarse)
            c = np.log(best[k]) if log else best[k]
            step = (b - a) / (n - 1)
            fine = np.linspace(max(c - step, a), min(c + step, b), n + 2)[1:-1]
            moved |= along(k, np.exp(fine) if log else fine)
        if not moved:
            break
    return best, best_cost
