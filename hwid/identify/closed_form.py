"""The paper's closed-form route for stage 1, eqs. (11)-(14): the horizontal paths ``j_a``, ``j_d``
by sequential tests (eqs. 7a, 14a), a weighted polynomial fit ``q(u) = h_bar(u - d^+)`` on the
ascending border with ``d^+`` from its real root (Remark 1.3) and ``h_bar(w) = q(w + d^+)``
(eq. 12), then ``S^d`` and ``d^-`` from the descending border (eq. 14).
"""
from __future__ import annotations

import math
from dataclasses import dataclass
from typing import Any, Optional

import numpy as np
from numba import njit
from numpy.polynomial import Polynomial
from scipy import special

from hwid.identify.lm import lm
from hwid.identify.stage1_model import (LevelData, ascending_index, descending_index, joint_chi2,
                                        path_memberships, pick_fit, real_roots)


def from_generic(kind: str, a: float, sigma: float, b: float) -> tuple[float, float, float]:
    """``(a, sigma, b)`` of ``asc = u - a``, ``desc = sigma (u - b)`` to ``(d^+, S^d, d^-)``."""
    if kind == "backlash":
        return a, sigma, b
    return -a, 1.0 / sigma, -sigma * b


def flat_run(x, se, ref_x: list, ref_se: list, alpha: float) -> tuple[int, list[float]]:
    """Number of leading points of ``x`` that stay on the horizontal path started by ``ref``.

    Each point is compared with the weighted mean of the path so far by a two-sided z test at the
    Bonferroni level ``alpha / len(x)``."""
    zc = -special.ndtri(alpha / (2 * max(len(x), 1)))
    mx, ms = list(ref_x), list(ref_se)
    zs: list[float] = []
    for xj, sj in zip(x, se):
        w = 1.0 / np.asarray(ms) ** 2
        m = float(np.sum(w * np.asarray(mx)) / np.sum(w))
        sm = float(np.sqrt(1.0 / np.sum(w)))
        z = (xj - m) / math.hypot(sj, sm)
        zs.append(float(z))
        if abs(z) > zc:
            return len(mx) - len(ref_x), zs
        mx.append(xj)
        ms.append(sj)
    return len(mx) - len(ref_x), zs


class TooFewLevels(Exception):
    pass


def weighted_polyfit(u, x, se, p: int) -> tuple[np.ndarray, float]:
    """Weighted LS polynomial of degree ``p`` in numpy's domain-scaled basis; power coefficients."""
    q = wpoly(u, x, se, p)
    return q.coef, q.chi2


_WPOLY_CACHE: dict = {}


def wpoly(u, x, se, p: int) -> "WeightedPoly":
    """:class:`WeightedPoly`, remembered for the last few hundred distinct inputs: the search over the
    horizontal paths and the roots of ``q`` (:func:`route_with_paths`) fits the same border points
    many times over."""
    u, x, se = (np.ascontiguousarray(a, dtype=float) for a in (u, x, se))
    key = (u.tobytes(), x.tobytes(), se.tobytes(), int(p))
    q = _WPOLY_CACHE.get(key)
    if q is None:
        if len(_WPOLY_CACHE) >= 512:
            _WPOLY_CACHE.clear()
        q = _WPOLY_CACHE[key] = WeightedPoly(u, x, se, p)
    return q


class WeightedPoly:
    """Weighted least-squares polynomial fit in a Legendre basis on the data's scaled domain
    (well conditioned, unlike the raw Vandermonde inverse of eq. 31), with the coefficients'
    covariance so that ``sd(x)``, the standard error of the fitted value, is available."""

    def __init__(self, u, x, se, p: int):
        u, x, se = (np.asarray(a, float) for a in (u, x, se))
        self.mid = 0.5 * (u.max() + u.min())
        self.half = max(0.5 * (u.max() - u.min()), 1e-12)
        A = np.polynomial.legendre.legvander((u - self.mid) / self.half, p) / se[:, None]
        b = x / se
        coef, *_ = np.linalg.lstsq(A, b, rcond=None)
        self.leg = coef
        self.cov = np.linalg.pinv(A.T @ A)
        r = b - A @ coef
        self.chi2 = float(r @ r)
        self.p = p
        # power basis in u: compose the Legendre series with t = (u - mid) / half
        power = np.polynomial.legendre.leg2poly(coef)
        pw = Polynomial(power)(Polynomial([-self.mid / self.half, 1.0 / self.half])).coef
        self.coef = np.pad(pw, (0, p + 1 - pw.size))

    def __call__(self, x):
        return np.polynomial.legendre.legval((np.asarray(x, float) - self.mid) / self.half, self.leg)

    def sd(self, x) -> np.ndarray:
        V = np.polynomial.legendre.legvander((np.atleast_1d(np.asarray(x, float)) - self.mid) / self.half, self.p)
        return np.sqrt(np.maximum(np.einsum("ij,jk,ik->i", V, self.cov, V), 0.0))

    def zero_crossings(self, lo: float, hi: float, z: float = 3.0) -> np.ndarray:
        """Real roots in ``[lo, hi]`` that are significant sign changes (Remark 1.3).

        Noise can turn a near-zero minimum of ``q`` into a pair of close real roots. Adjacent roots
        between which ``q`` does not differ from 0 by ``z`` standard errors form a cluster; a
        cluster with an even number of roots is no sign change and is dropped, an odd one counts as
        one crossing at its middle root."""
        rts = real_roots(self.coef, lo, hi)
        if rts.size <= 1:
            return rts
        clusters = [[rts[0]]]
        for a, b in zip(rts[:-1], rts[1:]):
            m = 0.5 * (a + b)
            if abs(float(self(m))) < z * float(self.sd(m)[0]):
                clusters[-1].append(b)
            else:
                clusters.append([b])
        out = [c[len(c) // 2] for c in clusters if len(c) % 2 == 1]
        return np.array(out) if out else rts


@njit(cache=True)
def border_model(t0, t1, u, x, se, hc, dhc, want_jac):
    """Residuals ``(x - h_bar(e^t0 (u - t1))) / se`` of the descending border (eq. 14) and, if
    ``want_jac``, their Jacobian in ``(t0, t1)`` (Horner in polyval's order)."""
    s = np.exp(min(t0, 50.0))
    n = u.shape[0]
    r = np.empty(n)
    J = np.zeros((n, 2))
    for j in range(n):
        w = s * (u[j] - t1)
        h = hc[hc.shape[0] - 1]
        for i in range(hc.shape[0] - 2, -1, -1):
            h = hc[i] + h * w
        r[j] = (x[j] - h) / se[j]
        if want_jac:
            d = dhc[dhc.shape[0] - 1]
            for i in range(dhc.shape[0] - 2, -1, -1):
                d = dhc[i] + d * w
            d = d / se[j]
            J[j, 0] = -d * w if t0 < 50.0 else 0.0
            J[j, 1] = d * s
    return r, J


def descending_border(hc: np.ndarray, p: int, u, x, se, b_ref: Optional[float] = None) -> tuple[float, float, str]:
    """``(sigma, b)`` of ``r(u) = h_bar(sigma (u - b))`` on the descending border (eq. 14).

    Closed form: ``sigma = (r_p / c_p)^(1/p)``; ``b`` among the real roots of ``r`` and the value
    from the next coefficient, the one that fits best. If the closed form is impossible (too few
    points or a leading-coefficient ratio <= 0), a 2-parameter least-squares fit (Levenberg-Marquardt
    with the analytic Jacobian of eq. 14's border model, from the two best points of a grid in b)."""
    hp = np.polynomial.polynomial.polyval
    hc = np.ascontiguousarray(hc, dtype=float)

    def sse(sig, b):
        """Weighted SSE of ``h_bar(sig (u - b))`` for every ``b`` of an array at once."""
        r = (x - hp(sig * (u - np.asarray(b, float)[..., None]), hc)) / se
        return np.einsum("...i,...i->...", r, r)

    span = float(np.ptp(u)) if u.size > 1 else 1.0
    lo, hi = float(u.min()) - 2 * span - 1.0, float(u.max()) + 2 * span + 1.0
    if u.size >= p + 1 and hc[p] != 0:
        rc, _ = weighted_polyfit(u, x, se, p)
        ratio = rc[p] / hc[p]
        if ratio > 0:
            sig = ratio ** (1.0 / p)
            cands = list(real_roots(rc, lo, hi))
            if p >= 1:
                # r_{p-1} = c_p sig^p (-p b) + c_{p-1} sig^{p-1}
                cands.append((hc[p - 1] * sig ** (p - 1) - rc[p - 1]) / (p * hc[p] * sig ** p))
            if cands:
                key = sse(sig, cands) if b_ref is None else np.abs(np.asarray(cands) - b_ref)
                b = cands[int(np.argmin(key))]
                return float(sig), float(b), "closed form"
    if u.size < 2:
        raise TooFewLevels("descending")
    grid = np.linspace(lo, hi, 61)
    best = grid[np.argsort(sse(1.0, grid), kind="stable")[:2]]
    dhc = np.ascontiguousarray(np.polynomial.polynomial.polyder(hc), dtype=float)
    u, x, se = (np.ascontiguousarray(a, dtype=float) for a in (u, x, se))

    last: list = [None, None]

    def res(t):
        # MINPACK asks for the Jacobian where it last evaluated the residuals: both in one call
        last[0] = (float(t[0]), float(t[1]))
        r, last[1] = border_model(t[0], t[1], u, x, se, hc, dhc, True)
        return r

    def jac(t):
        if last[0] == (float(t[0]), float(t[1])):
            return last[1]
        return border_model(t[0], t[1], u, x, se, hc, dhc, True)[1]

    out = []
    for b0 in best:
        z, cost, _ = lm(res, jac, [0.0, float(b0)], max_nfev=300)
        out.append((2 * cost, float(np.exp(z[0])), float(z[1])))
    _, sig, b = min(out)
    return sig, b, "least squares (closed form not available)"


@dataclass
class Route:
    theta: np.ndarray      # (c_1..c_p, d^+, S^d, d^-)
    a: float               # the root of q taken as d^+ (generic)
    b: float               # the descending border's root (generic)
    chi2: float
    desc_note: str


def paper_route(kind: str, p: int, data: LevelData, j_a: int, j_d: int,
                 a_ref: Optional[float] = None, b_ref: Optional[float] = None) -> list[Route]:
    """Candidates of the closed-form route (eqs. 11-14), the chosen one (:func:`pick_fit`) first.

    ``a_ref``, ``b_ref`` (delta method) keep the roots closest to a previous choice."""
    n_up = data.n_up
    ia = ascending_index(kind, j_a, n_up)
    idn = descending_index(kind, j_d, data.down.size) + n_up
    if ia.size < p + 1:
        raise TooFewLevels("ascending")
    u, x, se = data.U[ia], data.X[ia], data.se[ia]
    qf = wpoly(u, x, se, p)
    qc = qf.coef
    U = data.U
    span = float(np.ptp(U))
    roots = qf.zero_crossings(float(U.min()) - span, float(U.max()) + span)
    if roots.size == 0:
        grid = np.linspace(U.min() - span, U.max() + span, 2001)
        roots = np.array([grid[np.argmin(np.abs(Polynomial(qc)(grid)))]])
    if a_ref is not None:
        roots = roots[[int(np.argmin(np.abs(roots - a_ref)))]]
    out = []
    for a in roots:
        hc = Polynomial(qc)(Polynomial([a, 1.0])).coef      # h_bar(w) = q(w + a), eq. (12)
        hc = np.pad(hc, (0, p + 1 - hc.size))
        hc[0] = 0.0
        try:
            sig, b, note = descending_border(hc, p, data.U[idn], data.X[idn], data.se[idn], b_ref)
        except TooFewLevels:
            raise
        dp, sd, dm = from_generic(kind, float(a), sig, b)
        theta = np.concatenate([hc[1:], [dp, sd, dm]])
        out.append(Route(theta, float(a), float(b), joint_chi2(kind, theta, data), note))
    if not out:
        return out
    first, _ = pick_fit(kind, [(r.theta, r.chi2) for r in out], data)
    rest = sorted((r for i, r in enumerate(out) if i != first), key=lambda r: r.chi2)
    return [out[first]] + rest


def route_with_paths(kind: str, p: int, data: LevelData, j_a: int, j_d: int):
    """The closed-form route with horizontal paths that agree with the borders it finds.

    The tests of :func:`flat_run` end a path at the first significant departure, so a false
    rejection (at the family level ``alpha``) would put flat levels among the border points, and a
    border level within noise of the path would stay on it. For a Backlash the route is tried with
    the tests' ``j_a`` (then ``j_d``); if the borders it finds put other levels on the path, every
    other value is tried and, among those whose borders agree with them, the one with the smallest
    joint chi^2 replaces the tests' value when it fits better.
    Returns ``(routes, j_a, j_d)``."""
    if kind != "backlash":
        return paper_route(kind, p, data, j_a, j_d), j_a, j_d
    n_up, n_dn = data.n_up, data.down.size
    memo: dict[tuple[int, int], Any] = {}

    def route(ja, jd):
        # the descending search starts from the (j_a, j_d) the ascending one has already tried
        if (ja, jd) not in memo:
            try:
                memo[ja, jd] = paper_route(kind, p, data, ja, jd)
            except TooFewLevels as err:
                memo[ja, jd] = err
        got = memo[ja, jd]
        if isinstance(got, TooFewLevels):
            raise got
        return got

    def by_distance(j, lo, hi):
        return sorted(range(lo, hi + 1), key=lambda k: (abs(k - j), k < j))

    def first_consistent(cands, make, which):
        # cands[0] is the tests' value: kept when its borders agree with it, else the agreeing
        # value with the smallest joint chi^2 if that fits better
        first, best = None, None
        for j in cands:
            try:
                routes = make(j)
            except TooFewLevels:
                continue
            if not routes:
                continue
            agrees = path_memberships(kind, routes[0].theta, data)[which] == j
            if j == cands[0]:
                first = (j, routes)
                if agrees:
                    return first
            elif agrees and (best is None or routes[0].chi2 < best[1][0].chi2):
                best = (j, routes)
        if best is not None and (first is None or best[1][0].chi2 < first[1][0].chi2):
            return best
        return first or best

    got = first_consistent([j_a] + [j for j in by_distance(j_a, 1, n_up - 2) if j != j_a],
                           lambda j: route(j, j_d), 0)
    if got is None:
        raise TooFewLevels("ascending")
    ja = got[0]
    got = first_consistent([j_d] + [j for j in by_distance(j_d, 0, n_dn - 2) if j != j_d],
                           lambda j: route(ja, j), 1)
    if got is None:
        raise TooFewLevels("descending")
    return got[1], ja, got[0]
