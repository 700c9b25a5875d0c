"""A rate-independent hysteresis as a Prandtl-Ishlinskii operator: a weighted sum of play operators
beside a linear part (the ``output_hysteresis`` effect, :class:`hwid.diagnose.effects_after_gear.OutputHysteresis`).

The operator (Brokate and Sprekels 1996, ch. 2; Kuhnen 2003, "Modeling, identification and
compensation of complex hysteretic nonlinearities", eq. 2)::

    H[x] = (1 - weight) x + weight sum_j p_j P_{r_j}[x],   sum_j p_j = 1,

``P_r`` the play of half-width ``r``, on :data:`PLAYS` thresholds ``r_j = width j / PLAYS`` and a
threshold density ``p_j ~ exp(shape (j - PLAYS) / PLAYS)``: ``shape = 0`` is the uniform density
(a loop rounded at each reversal), a large ``shape`` puts the weight on the widest play (one play's
sharp-cornered loop), a negative one on the narrow plays (a loop that closes fast after each
reversal). Identifying PI operators fits the density on a fixed threshold grid (Kuhnen 2003;
Al Janaideh et al. 2009); with a handful of weights free, a diagnosis's records determine only a
few of them, so the density here is one exponential tilt: the width of its largest play, the
share through the plays and the tilt are the three numbers the loop's size, height and corner
shape show.
"""
from __future__ import annotations

import numpy as np
from numba import njit

#: the plays on the threshold grid: with 4, ``shape = 0`` is the operator of four equal plays
#: (a loop whose branches are within 1/16 of the width of the smooth uniform-density limit), and
#: at ``shape = 40`` the widest play carries all but 5e-5 of the weight
PLAYS = 4


@njit(cache=True)
def play_sum(x, width, n_plays):
    """The mean of ``n_plays`` play operators of half-widths ``width k / n_plays`` (k = 1..n) on
    ``x``, each started at ``x[0]``: a Prandtl-Ishlinskii operator of uniform threshold density."""
    out = np.zeros_like(x)
    for j in range(1, n_plays + 1):
        r = width * j / n_plays
        p = x[0]
        for k in range(x.shape[0]):
            if p < x[k] - r:
                p = x[k] - r
            elif p > x[k] + r:
                p = x[k] + r
            out[k] += p
    return out / n_plays


@njit(cache=True)
def weighted_plays(x, radii, weights, start, k0):
    """``sum_j weights[j] P_{radii[j]}[x]``, play ``j`` started at ``x[0]``, and set to
    ``x[k0] + start radii[j]`` at sample ``k0`` (``k0 = 0``: started there)."""
    out = np.zeros_like(x)
    for j in range(radii.shape[0]):
        r = radii[j]
        p = x[0]
        for k in range(x.shape[0]):
            if k == k0:
                p = x[k0] + start * r
            if p < x[k] - r:
                p = x[k] - r
            elif p > x[k] + r:
                p = x[k] + r
            out[k] += weights[j] * p
    return out


def density(shape: float, n: int = PLAYS) -> np.ndarray:
    """The thresholds' weights ``p_j ~ exp(shape (j - n) / n)``, j = 1..n, summing to 1."""
    j = np.arange(1, n + 1, dtype=float)
    p = np.exp(float(shape) * (j - n) / n)
    return p / p.sum()


def pi_operator(x, width: float, weight: float, shape: float = 0.0, start: float = 0.0,
                from_sample: int = 0) -> np.ndarray:
    """The Prandtl-Ishlinskii operator of the module docstring on ``x``, each play set to
    ``x[from_sample] + start r_j`` at ``from_sample`` (``start`` in [-1, 1]: 0 centred, -1 as after
    a long rise, 1 after a long fall: the memory a rig may hold from before a record)."""
    x = np.ascontiguousarray(x, dtype=np.float64)
    radii = max(float(width), 0.0) * np.arange(1, PLAYS + 1) / PLAYS
    a = float(weight)
    return (1.0 - a) * x + a * weighted_plays(x, radii, density(shape), float(np.clip(start, -1.0, 1.0)),
                                              int(from_sample))


def start_shows(x, upto: int, width: float) -> bool:
    """Whether the plays' start still shows at sample ``upto`` of ``x``: unless ``x`` has spanned
    twice the widest half-width by then, some start in [-1, 1] has not been pushed by a border
    (a play started at ``x0 + s r`` is pushed once ``x`` rises ``(1 + s) r`` or falls ``(1 - s) r``)."""
    seg = np.asarray(x[: max(int(upto), 1)], float)
    return bool(float(seg.max() - seg.min()) < 2.0 * float(width))
