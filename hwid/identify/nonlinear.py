"""Stage 1: the output nonlinearity h and the backlash borders from two staircases (paper Section 4).

The data
--------
The ascending staircase (eq. 6) and the descending one (eq. 13) are run after their lead-ins
(:mod:`hwid.protocols`). For each level the steady output ``X_hat_j`` is the mean of ``y`` after the
transient (eq. 9), with a standard error that holds under coloured noise (:mod:`hwid.identify.steady`).

The model
---------
Everything is estimated for the normalised model of eqs. (4a-c) (``slope_up = 1``, ``G(0) = 1``),
in which the steady output at a level is ``X_j = h_bar(F_bar[U_j])`` (eqs. 5, 8). For a Backlash
``F_bar`` has the borders ``u - d^+`` and ``S^d/S^a (u - d^-)``. For a Backlash-Inverse the same
normalisation (``F_bar = S^a F``) gives the branches ``u + S^a d^+`` (ascending) and
``(S^a/S^d) u + S^a d^-`` (descending); hwid reports it as ``slope_down = S^d/S^a``,
``d_plus = S^a d^+``, ``d_minus = S^a d^-`` (see :mod:`hwid.model`), so its branches read
``u + d_plus`` and ``u / slope_down + d_minus``.

In both cases the two branches are straight lines ``asc(u) = u - a`` and
``desc(u) = sigma (u - b)``, with ``(a, sigma, b) = (d^+, S^d, d^-)`` for a Backlash and
``(-d^+, 1/S^d, -S^d d^-)`` for a Backlash-Inverse; the paper's closed-form route works on
``(a, sigma, b)`` and maps back.

The estimator (:class:`NonlinearEstimator`)
-------------------------------------------
1. Steady states and standard errors of all levels.
2. ``j_a``, ``j_d`` (eqs. 7a, 14a) by sequential tests: a level belongs to the horizontal path while
   it equals the path's weighted mean within a Bonferroni-corrected two-sided z test (family level
   ``alpha`` per staircase). The descending path is referred to the last ascending level, whose
   steady state ``h(U_N - d^+)`` is the one the descending lead-in leaves. A staircase that never
   leaves the path means ``[u_m, u_M]`` is too narrow (Section 3, Fig. 6a): :class:`HwidError`.
3. The paper's route (eqs. 11-14): a weighted polynomial fit ``q(u) = h_bar(u - d^+)`` on the
   ascending border points in numpy's domain-scaled basis; ``d^+`` from a real root of ``q``
   (Remark 1.3: ``h^-1(0) = 0``), the root being the one whose whole model fits both staircases
   best; ``h_bar(w) = q(w + d^+)`` (eq. 12); on the descending border a fit ``r(u) = h_bar(S^d(u - d^-))``
   gives ``S^d = (r_p / c_p)^(1/p)`` from the leading coefficients and ``d^-`` from ``r``'s root
   (eq. 14).
4. ``method='nls'`` (default): all parameters ``(c_1..c_p, d^+, S^d, d^-)`` refined jointly by
   weighted least squares on both staircases, the model being ``h_bar`` of the steady-state
   recursion of ``F_bar`` over all levels including the lead-in, so which levels lie on the flat
   path or on a border follows the parameters. Started from step 3.
5. Degree ``p`` and type (Backlash / Backlash-Inverse, Remark 1.4) by BIC of the joint fit
   ``chi^2 + k ln n``, ``p`` limited by eq. (11) (``N - j_a >= p + 1``) unless the joint fit
   at that limit still misfits: then higher degrees are fitted jointly (both staircases sample
   ``h``) while the misfit lasts and each added coefficient passes an F test; each degree's fit
   also starts from the one below with ``c_p = 0``. A configured degree overrides the selection.
   Fits whose ``h_bar`` has another real zero where the data go are set aside while one that keeps
   Remark 1.3 exists. When no candidate fits within noise (the plant is
   not quite of this structure: a drift, curved borders), the type is chosen by the
   quasi-likelihood BIC ``chi^2 / c + k ln n`` with ``c`` the best fit's ``chi^2/dof``; the
   degree within the type still by the BIC.
6. 95 % intervals from the covariance ``(J^T W J)^-1`` (nls) or from the delta method through the
   closed form (paper), with t quantiles on the noise's degrees of freedom.
"""
from __future__ import annotations

import math
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any, Optional

import numpy as np
from numba import njit
from numpy.polynomial import Polynomial
from scipy import stats

from hwid import HwidError
from hwid.identify.lm import lm
from hwid.identify.result import NonlinearResult
from hwid.identify.steady import SteadyLevels, steady_levels
from hwid import paper
from hwid.model import InputNonlinearity

TYPES = ("backlash", "backlash_inverse")
_NEG = -1e300   # a gear state below every border: the first lead-in level puts it on the ascending one


class NonlinearIdentificationError(HwidError):
    """Stage 1 cannot proceed with these data (narrow working interval, too few levels, ...)."""


# ----------------------------------------------------------------------------------------- result

# ----------------------------------------------------------------------------------- the model

@dataclass(frozen=True)
class _Data:
    """The steady-state points of both staircases, with the level sequences the model needs."""

    all_up: np.ndarray       # lead-in + ascending levels
    all_down: np.ndarray     # lead-in + descending levels
    lead_up: int
    lead_down: int
    X: np.ndarray            # X_hat, ascending then descending
    se: np.ndarray

    @property
    def up(self) -> np.ndarray:
        return self.all_up[self.lead_up:]

    @property
    def down(self) -> np.ndarray:
        return self.all_down[self.lead_down:]

    @property
    def n_up(self) -> int:
        return self.up.size

    @property
    def U(self) -> np.ndarray:
        return np.concatenate([self.up, self.down])

    def with_X(self, X) -> "_Data":
        return _Data(self.all_up, self.all_down, self.lead_up, self.lead_down, np.asarray(X, float), self.se)


def _internal(kind: str, d_plus: float, slope_down: float, d_minus: float, data: _Data) -> np.ndarray:
    """Steady ``V_j = F_bar[U_j]`` of both staircases (eqs. 7a-b, 14a-b) from the lead-in on."""
    f = InputNonlinearity(kind, 1.0, slope_down, d_plus, d_minus)
    state = _NEG if kind == "backlash" else 0.0
    vu = f.steady(data.all_up, state)[data.lead_up:]
    vd = f.steady(data.all_down, state)[data.lead_down:]
    return np.concatenate([vu, vd])


def _predict(kind: str, theta: np.ndarray, data: _Data) -> np.ndarray:
    """``X_j(theta) = h_bar(F_bar[U_j])`` with ``theta = (c_1..c_p, d^+, S^d, d^-)``."""
    c = np.concatenate([[0.0], theta[:-3]])
    v = _internal(kind, theta[-3], theta[-2], theta[-1], data)
    return np.polynomial.polynomial.polyval(v, c)


def _chi2(kind: str, theta: np.ndarray, data: _Data) -> float:
    if not (theta[-2] > 0 and theta[-3] >= theta[-1] and np.all(np.isfinite(theta))):
        return np.inf
    with np.errstate(all="ignore"):
        r = (data.X - _predict(kind, theta, data)) / data.se
        c = float(r @ r)
    return c if np.isfinite(c) else np.inf


def _other_zeros(kind: str, theta: np.ndarray, data: _Data) -> int:
    """Number of real zeros of ``h_bar`` other than 0 inside the range of ``w`` the data visit."""
    v = _internal(kind, theta[-3], theta[-2], theta[-1], data)
    lo, hi = float(v.min()), float(v.max())
    z = _real_roots(np.concatenate([[0.0], theta[:-3]]), lo, hi)
    tol = 1e-6 * max(1.0, hi - lo)
    return int(np.sum(np.abs(z) > tol))


def _pick(kind: str, fits: list, data: _Data) -> tuple[int, bool]:
    """Choose among fits ``(theta, chi2)`` started from different roots of ``q`` (Remark 1.3).

    Any real root of ``q(u) = h_bar(u - d^+)`` gives a model that reproduces the border points: if
    ``h_bar`` has another real zero ``w_0``, the shifted model ``(h_bar(. + w_0), d^+ + w_0, ...)``
    fits as well, and the paper's assumption ``h(w) = 0 <=> w = 0`` must decide. Among the fits
    within ``chi2_min + max(9, chi2_min)`` (the closed form's candidates differ by their separately
    fitted descending stage) the choice prefers, in this order: an ``h_bar`` with no other zero in the
    range of ``w`` the data visit; a root inside the ascending staircase's range (not an
    extrapolation); the smaller chi^2. The flag says whether distinct candidates tied on the first
    two criteria."""
    chis = np.array([f[1] for f in fits])
    if not np.any(np.isfinite(chis)):
        return 0, False
    best = float(np.min(chis))
    near = [int(i) for i in np.argsort(chis) if chis[i] <= best + max(9.0, best)]
    lo, hi = float(data.up.min()), float(data.up.max())

    def key(i):
        th = fits[i][0]
        a = th[-3] if kind == "backlash" else -th[-3]
        return (_other_zeros(kind, th, data) > 0, not (lo <= a <= hi))

    keys = {i: key(i) for i in near}
    first = min(near, key=lambda i: (keys[i], chis[i]))
    d0 = fits[first][0][-3]
    distinct = [i for i in near if keys[i] == keys[first] and abs(fits[i][0][-3] - d0) > 1e-3 * (1 + abs(d0))]
    return first, bool(distinct)


def _from_generic(kind: str, a: float, sigma: float, b: float) -> tuple[float, float, float]:
    """``(a, sigma, b)`` of ``asc = u - a``, ``desc = sigma (u - b)`` to ``(d^+, S^d, d^-)``."""
    if kind == "backlash":
        return a, sigma, b
    return -a, 1.0 / sigma, -sigma * b


# ------------------------------------------------------------------------- flat path (j_a, j_d)

def _flat_run(x, se, ref_x: list, ref_se: list, alpha: float) -> tuple[int, list[float]]:
    """Number of leading points of ``x`` that stay on the horizontal path started by ``ref``.

    Each point is compared with the weighted mean of the path so far by a two-sided z test at the
    Bonferroni level ``alpha / len(x)``."""
    zc = stats.norm.isf(alpha / (2 * max(len(x), 1)))
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


# ----------------------------------------------------------------------------- the paper's route

class _TooFew(Exception):
    pass


def _polyfit(u, x, se, p: int) -> tuple[np.ndarray, float]:
    """Weighted LS polynomial of degree ``p`` in numpy's domain-scaled basis; power coefficients."""
    q = _wpoly(u, x, se, p)
    return q.coef, q.chi2


_WPOLY_CACHE: dict = {}


def _wpoly(u, x, se, p: int) -> "_WPoly":
    """:class:`_WPoly`, remembered for the last few hundred distinct inputs: the search over the
    horizontal paths and the roots of ``q`` (:func:`_route_with_paths`) fits the same border points
    many times over."""
    u, x, se = (np.ascontiguousarray(a, dtype=float) for a in (u, x, se))
    key = (u.tobytes(), x.tobytes(), se.tobytes(), int(p))
    q = _WPOLY_CACHE.get(key)
    if q is None:
        if len(_WPOLY_CACHE) >= 512:
            _WPOLY_CACHE.clear()
        q = _WPOLY_CACHE[key] = _WPoly(u, x, se, p)
    return q


class _WPoly:
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
        rts = _real_roots(self.coef, lo, hi)
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


def _real_roots(c: np.ndarray, lo: float, hi: float) -> np.ndarray:
    c = np.trim_zeros(np.asarray(c, float), "b")
    if c.size < 2:
        return np.array([])
    rts = np.roots(c[::-1])
    scale = max(1.0, hi - lo)
    real = rts[np.abs(rts.imag) <= 1e-6 * scale + 1e-3 * np.abs(rts)].real
    return np.sort(real[(real >= lo) & (real <= hi)])


def _asc_index(kind: str, j_a: int, n_up: int) -> np.ndarray:
    # with the lead-in, the first ascending level sits on the descending branch for both types
    return np.arange(j_a if kind == "backlash" else 1, n_up)


def _desc_index(kind: str, j_d: int, n_down: int) -> np.ndarray:
    return np.arange(j_d if kind == "backlash" else 0, n_down)


@njit(cache=True)
def _border_model(t0, t1, u, x, se, hc, dhc, want_jac):
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


def _descending(hc: np.ndarray, p: int, u, x, se, b_ref: Optional[float] = None) -> tuple[float, float, str]:
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
        rc, _ = _polyfit(u, x, se, p)
        ratio = rc[p] / hc[p]
        if ratio > 0:
            sig = ratio ** (1.0 / p)
            cands = list(_real_roots(rc, lo, hi))
            if p >= 1:
                # r_{p-1} = c_p sig^p (-p b) + c_{p-1} sig^{p-1}
                cands.append((hc[p - 1] * sig ** (p - 1) - rc[p - 1]) / (p * hc[p] * sig ** p))
            if cands:
                key = sse(sig, cands) if b_ref is None else np.abs(np.asarray(cands) - b_ref)
                b = cands[int(np.argmin(key))]
                return float(sig), float(b), "closed form"
    if u.size < 2:
        raise _TooFew("descending")
    grid = np.linspace(lo, hi, 61)
    best = grid[np.argsort(sse(1.0, grid), kind="stable")[:2]]
    dhc = np.ascontiguousarray(np.polynomial.polynomial.polyder(hc), dtype=float)
    u, x, se = (np.ascontiguousarray(a, dtype=float) for a in (u, x, se))

    last: list = [None, None]

    def res(t):
        # MINPACK asks for the Jacobian where it last evaluated the residuals: both in one call
        last[0] = (float(t[0]), float(t[1]))
        r, last[1] = _border_model(t[0], t[1], u, x, se, hc, dhc, True)
        return r

    def jac(t):
        if last[0] == (float(t[0]), float(t[1])):
            return last[1]
        return _border_model(t[0], t[1], u, x, se, hc, dhc, True)[1]

    out = []
    for b0 in best:
        z, cost, _ = lm(res, jac, [0.0, float(b0)], max_nfev=300)
        out.append((2 * cost, float(np.exp(z[0])), float(z[1])))
    _, sig, b = min(out)
    return sig, b, "least squares (closed form not available)"


@dataclass
class _Route:
    theta: np.ndarray      # (c_1..c_p, d^+, S^d, d^-)
    a: float               # the root of q taken as d^+ (generic)
    b: float               # the descending border's root (generic)
    chi2: float
    desc_note: str


def _paper_route(kind: str, p: int, data: _Data, j_a: int, j_d: int,
                 a_ref: Optional[float] = None, b_ref: Optional[float] = None) -> list[_Route]:
    """Candidates of the closed-form route (eqs. 11-14), the chosen one (:func:`_pick`) first.

    ``a_ref``, ``b_ref`` (delta method) keep the roots closest to a previous choice."""
    n_up = data.n_up
    ia = _asc_index(kind, j_a, n_up)
    idn = _desc_index(kind, j_d, data.down.size) + n_up
    if ia.size < p + 1:
        raise _TooFew("ascending")
    u, x, se = data.U[ia], data.X[ia], data.se[ia]
    qf = _wpoly(u, x, se, p)
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
            sig, b, note = _descending(hc, p, data.U[idn], data.X[idn], data.se[idn], b_ref)
        except _TooFew:
            raise
        dp, sd, dm = _from_generic(kind, float(a), sig, b)
        theta = np.concatenate([hc[1:], [dp, sd, dm]])
        out.append(_Route(theta, float(a), float(b), _chi2(kind, theta, data), note))
    if not out:
        return out
    first, _ = _pick(kind, [(r.theta, r.chi2) for r in out], data)
    rest = sorted((r for i, r in enumerate(out) if i != first), key=lambda r: r.chi2)
    return [out[first]] + rest


def _memberships(kind: str, theta: np.ndarray, data: _Data) -> tuple[int, int]:
    """``(j_a, j_d)`` that the parameters ``theta`` imply: levels on the horizontal paths (eqs. 7a, 14a)."""
    v = _internal(kind, theta[-3], theta[-2], theta[-1], data)
    n_up = data.n_up
    top = float(InputNonlinearity(kind, 1.0, theta[-2], theta[-3], theta[-1]).ascending(
        data.all_down[data.lead_down - 1]))
    ja = int(np.argmin(np.r_[np.abs(v[:n_up] - v[0]) <= 1e-12, False]))
    jd = int(np.argmin(np.r_[np.abs(v[n_up:] - top) <= 1e-12, False]))
    return ja, jd


def _route_with_paths(kind: str, p: int, data: _Data, j_a: int, j_d: int):
    """The closed-form route with horizontal paths that agree with the borders it finds.

    The tests of :func:`_flat_run` end a path at the first significant departure, so a false
    rejection (at the family level ``alpha``) would put flat levels among the border points, and a
    border level within noise of the path would stay on it. For a Backlash the route is tried with
    the tests' ``j_a`` (then ``j_d``); if the borders it finds put other levels on the path, every
    other value is tried and, among those whose borders agree with them, the one with the smallest
    joint chi^2 replaces the tests' value when it fits better.
    Returns ``(routes, j_a, j_d)``."""
    if kind != "backlash":
        return _paper_route(kind, p, data, j_a, j_d), j_a, j_d
    n_up, n_dn = data.n_up, data.down.size
    memo: dict[tuple[int, int], Any] = {}

    def route(ja, jd):
        # the descending search starts from the (j_a, j_d) the ascending one has already tried
        if (ja, jd) not in memo:
            try:
                memo[ja, jd] = _paper_route(kind, p, data, ja, jd)
            except _TooFew as err:
                memo[ja, jd] = err
        got = memo[ja, jd]
        if isinstance(got, _TooFew):
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
            except _TooFew:
                continue
            if not routes:
                continue
            agrees = _memberships(kind, routes[0].theta, data)[which] == j
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
        raise _TooFew("ascending")
    ja = got[0]
    got = first_consistent([j_d] + [j for j in by_distance(j_d, 0, n_dn - 2) if j != j_d],
                           lambda j: route(ja, j), 1)
    if got is None:
        raise _TooFew("descending")
    return got[1], ja, got[0]


# ------------------------------------------------------------------------------ joint NLS

@njit(cache=True)
def _steady_grad(backlash, levels, lead, dp, sd, dm, v, dv, at):
    """Steady ``V_j = F_bar[U_j]`` and ``dV_j / d(d^+, S^d, d^-)`` along one level sequence, written
    from row ``at`` of ``v``, ``dv`` on (levels from ``lead`` on).

    The recursion and its branch decisions are those of :func:`hwid.blocks.backlash.static_play`
    (from ``_NEG``) and :func:`~hwid.blocks.backlash.static_direction_map` (from 0) with
    ``slope_up = 1``: a level on the ascending border ``u - d^+`` (branch ``u + d^+``) depends on
    ``d^+`` only, one on the descending border ``S^d (u - d^-)`` (branch ``u / S^d + d^-``) on ``S^d``
    and ``d^-``, and a level on a horizontal path keeps the derivative of the state it holds
    (eqs. 7a-b, 14a-b)."""
    g0, g1, g2 = 0.0, 0.0, 0.0
    if backlash:
        prev = _NEG
        for k in range(levels.shape[0]):
            u = levels[k]
            lo = 1.0 * (u - dp)
            hi = sd * (u - dm)
            if prev < lo:
                prev = lo
                g0, g1, g2 = -1.0, 0.0, 0.0
            elif prev > hi:
                prev = hi
                g0, g1, g2 = 0.0, u - dm, -sd
            if k >= lead:
                i = at + k - lead
                v[i], dv[i, 0], dv[i, 1], dv[i, 2] = prev, g0, g1, g2
    else:
        a_dn = 1.0 / sd
        prev = 0.0
        for k in range(levels.shape[0]):
            if k > 0:
                dz = levels[k] - levels[k - 1]
                if dz > 0.0:
                    prev = 1.0 * levels[k] + dp
                    g0, g1, g2 = 1.0, 0.0, 0.0
                elif dz < 0.0:
                    prev = a_dn * levels[k] + dm
                    g0, g1, g2 = 0.0, -levels[k] / (sd * sd), 1.0
            if k >= lead:
                i = at + k - lead
                v[i], dv[i, 0], dv[i, 1], dv[i, 2] = prev, g0, g1, g2


@njit(cache=True)
def _joint_model(backlash, up, lead_up, down, lead_down, X, se, z, want_jac):
    """Weighted residuals ``(X_j - h_bar(V_j)) / se_j`` of the joint fit and, if ``want_jac``, their
    Jacobian in ``z = (c_1..c_p, d^+, ln S^d, ln(d^+ - d^-))`` (non-finite entries -> 1e12 / 0)."""
    p = z.shape[0] - 3
    dp = z[p]
    sd = np.exp(min(max(z[p + 1], -50.0), 50.0))
    gap = np.exp(min(max(z[p + 2], -50.0), 50.0))
    dm = dp - gap
    n = X.shape[0]
    v = np.empty(n)
    dv = np.empty((n, 3))
    _steady_grad(backlash, up, lead_up, dp, sd, dm, v, dv, 0)
    _steady_grad(backlash, down, lead_down, dp, sd, dm, v, dv, up.shape[0] - lead_up)
    r = np.empty(n)
    J = np.zeros((n, p + 3))
    for j in range(n):
        w = v[j]
        h = z[p - 1] if p > 0 else 0.0          # Horner on (0, c_1..c_p): same order as polyval
        for i in range(p - 2, -1, -1):
            h = z[i] + h * w
        h = 0.0 + h * w
        rj = (X[j] - h) / se[j]
        ok = np.isfinite(rj)
        r[j] = rj if ok else 1e12
        if want_jac and ok:
            hp = p * z[p - 1] if p > 0 else 0.0
            for i in range(p - 2, -1, -1):
                hp = (i + 1) * z[i] + hp * w
            wi = 1.0
            for i in range(p):
                wi = wi * w
                J[j, i] = -wi / se[j]
            db0, db1, db2 = hp * dv[j, 0], hp * dv[j, 1], hp * dv[j, 2]
            J[j, p] = -(db0 + db2) / se[j]
            J[j, p + 1] = -(db1 * sd) / se[j] if -50.0 < z[p + 1] < 50.0 else 0.0
            J[j, p + 2] = (db2 * gap) / se[j] if -50.0 < z[p + 2] < 50.0 else 0.0
            for i in range(p + 3):
                if not np.isfinite(J[j, i]):
                    J[j, i] = 0.0
    return r, J


def _nls(kind: str, theta0: np.ndarray, data: _Data) -> tuple[np.ndarray, float]:
    """Weighted nonlinear least squares of all parameters on both staircases, from ``theta0``.

    Levenberg-Marquardt on ``(c_1..c_p, d^+, ln S^d, ln(d^+ - d^-))``, so that ``S^d > 0`` and
    ``d^+ > d^-`` hold without bounds, with the analytic Jacobian of ``h_bar(F_bar[U_j])``
    (eqs. 5, 8: ``dX_j/dc_i = V_j^i``, ``dX_j/d border = h_bar'(V_j) dV_j/d border``)."""
    p = theta0.size - 3
    args = (kind == "backlash", data.all_up, data.lead_up, data.all_down, data.lead_down, data.X, data.se)

    def to_theta(z):
        return np.concatenate([z[:p], [z[p], math.exp(min(max(z[p + 1], -50.0), 50.0)),
                                       z[p] - math.exp(min(max(z[p + 2], -50.0), 50.0))]])

    def fun(z):
        return _joint_model(*args, z, False)[0]

    def jac(z):
        return _joint_model(*args, z, True)[1]

    z0 = np.concatenate([theta0[:p], [theta0[-3], math.log(max(theta0[-2], 1e-6)),
                                      math.log(max(theta0[-3] - theta0[-1], 1e-6))]])
    try:
        z, _, _ = lm(fun, jac, z0, xtol=1e-10, ftol=1e-10, gtol=1e-10, max_nfev=60 * (p + 4))
    except ValueError:
        return theta0, np.inf
    th = to_theta(z)
    return th, _chi2(kind, th, data)


def _jacobian(f, theta: np.ndarray, rel: float = 1e-6) -> np.ndarray:
    """Central differences of ``f`` at ``theta``."""
    cols = []
    for i in range(theta.size):
        h = rel * max(1.0, abs(theta[i]))
        tp, tm = theta.copy(), theta.copy()
        tp[i] += h
        tm[i] -= h
        cols.append((np.asarray(f(tp)) - np.asarray(f(tm))) / (2 * h))
    return np.column_stack(cols)


def _nls_cov(kind: str, theta: np.ndarray, data: _Data) -> np.ndarray:
    """``(J^T W J)^-1`` at the estimate (J of the weighted residuals)."""
    J = _jacobian(lambda t: _predict(kind, t, data) / data.se, theta)
    return np.linalg.pinv(J.T @ J, rcond=1e-13)


def _grid_V(kind: str, data: _Data, n_d: int = 41, n_gap: int = 24, n_s: int = 9):
    """The borders of :func:`_grid_starts`' grid ``(G, 3)`` and the steady states ``V`` they
    give ``(G, n)`` (independent of the degree, so computed once per type)."""
    U = np.concatenate([data.all_up, data.all_down])
    lo, hi = float(U.min()), float(U.max())
    W = max(hi - lo, 1e-12)
    dp, gap, sd = np.meshgrid(np.linspace(lo - 0.5 * W, hi + 0.5 * W, n_d), np.geomspace(1e-3 * W, 1.5 * W, n_gap),
                              np.geomspace(1 / 3, 3.0, n_s), indexing="ij")
    P = np.column_stack([dp.ravel(), sd.ravel(), (dp - gap).ravel()])
    V = np.stack([_internal(kind, a, b, c, data) for a, b, c in P])
    return P, V, 1.5 * W / (n_d - 1)


def _grid_starts(kind: str, p: int, data: _Data, grid=None, keep: int = 3) -> list[np.ndarray]:
    """Global starting points for the joint fit: a grid over the borders ``(d^+, S^d, d^+ - d^-)``
    with ``h_bar``'s coefficients profiled out (for fixed borders the steady states ``V_j`` are
    known and ``X_j = h_bar(V_j)`` is linear in ``c_1..c_p``: weighted least squares), the ``keep``
    best by chi^2, apart from each other by more than a grid step.

    Used when the closed form's starts leave a fit that does not describe the data (a local
    minimum of the joint chi^2: e.g. a non-monotone ``h_bar`` whose border points the closed form
    assigns to the wrong root). ``d^+`` spans the levels' range widened by half its width, the gap
    up to 1.5 times that width, ``S^d`` a factor 3 either way of 1."""
    P, V, step = grid if grid is not None else _grid_V(kind, data)
    w = 1.0 / data.se
    A = (V[:, :, None] ** np.arange(1, p + 1)) * w[None, :, None]          # (G, n, p)
    b = data.X * w
    AtA = np.einsum("gni,gnj->gij", A, A) + 1e-12 * np.eye(p)
    Atb = np.einsum("gni,n->gi", A, b)
    with np.errstate(all="ignore"):
        try:
            C = np.linalg.solve(AtA, Atb[..., None])[..., 0]
        except np.linalg.LinAlgError:
            C = np.stack([np.linalg.lstsq(a, b, rcond=None)[0] for a in A])
        r = b[None, :] - np.einsum("gni,gi->gn", A, C)
        chi2 = np.einsum("gn,gn->g", r, r)
    chi2 = np.where(np.isfinite(chi2), chi2, np.inf)
    out: list[np.ndarray] = []
    for g in np.argsort(chi2):
        if not np.isfinite(chi2[g]):
            break
        th = np.concatenate([C[g], P[g]])
        if all(abs(th[-3] - o[-3]) > step or abs(th[-1] - o[-1]) > step for o in out):
            out.append(th)
        if len(out) >= keep:
            break
    return out


def _one_degree_up(theta: np.ndarray) -> np.ndarray:
    """``(c_1..c_p, d^+, S^d, d^-)`` as the same model of degree ``p + 1`` (``c_{p+1} = 0``)."""
    return np.concatenate([theta[:-3], [0.0], theta[-3:]])


# ------------------------------------------------------------------------------- the estimator

def _overdispersion(cands, n: int) -> Optional[float]:
    """``chi2/dof`` of the best-fitting candidate when it misfits (p < 1e-3), else None."""
    ratios = [(c.chi2 / (n - c.p - 3), n - c.p - 3) for c in cands if n - c.p - 3 > 0]
    if not ratios:
        return None
    r, dof = min(ratios)
    return float(r) if stats.chi2.sf(r * dof, dof) < 1e-3 else None


@dataclass
class _Candidate:
    kind: str
    p: int
    theta: np.ndarray
    chi2: float
    bic: float
    route: Optional[_Route] = None
    ambiguous: bool = False      # other roots of q fit as well (h has another zero in range)
    j_a: int = 0                 # horizontal paths the closed form used
    j_d: int = 0
    qbic: float = float("nan")   # the type's criterion: BIC, or quasi-likelihood BIC under a misfit
    other_zeros: int = -1        # real zeros of h_bar other than 0 where the data go (-1: not computed)


class NonlinearEstimator:
    """Stage-1 estimator (Section 4) in the scikit-learn manner.

    Parameters
    ----------
    method : {"nls", "paper"}
        ``"nls"``: joint weighted nonlinear least squares started from the closed form;
        ``"paper"``: the closed-form route of eqs. (11-14) only.
    degree : int, optional
        Degree ``p`` of ``h``; selected by BIC when None.
    max_degree : int
        Highest degree tried by the selection.
    input_type : {"auto", "backlash", "backlash_inverse"}
        Type of F; decided from the data when "auto" (Remark 1.4).
    alpha : float
        Family-wise level of the flat-path tests per staircase (j_a, j_d).
    pool_noise : bool
        Pool the long-run noise variance over levels (stationary noise).
    confidence : float
        Level of the reported intervals.

    Attributes (after ``fit``)
    --------------------------
    result_ : NonlinearResult
    steady_ : hwid.identify.steady.SteadyLevels
    type_, degree_, d_plus_, slope_down_, d_minus_, h_coef_, flat_up_, flat_down_, selection_
    """

    def __init__(self, method: str = "nls", degree: Optional[int] = None, max_degree: int = 9,
                 input_type: str = "auto", alpha: float = 0.01, pool_noise: bool = True,
                 confidence: float = 0.95):
        self.method = method
        self.degree = degree
        self.max_degree = max_degree
        self.input_type = input_type
        self.alpha = alpha
        self.pool_noise = pool_noise
        self.confidence = confidence

    @classmethod
    def from_config(cls, cfg) -> "NonlinearEstimator":
        """Settings from ``cfg.identification.nonlinear``."""
        n = cfg.identification.nonlinear
        return cls(method=n.method, degree=n.degree, max_degree=n.max_degree,
                   input_type=getattr(n, "input_type", "auto"), alpha=getattr(n, "alpha", 0.01),
                   pool_noise=getattr(n, "pool_noise", True))

    # -------------------------------------------------------------------------------- fit
    def _check_settings(self):
        if self.method not in ("nls", "paper"):
            raise ValueError(f"method must be 'nls' or 'paper', got {self.method!r}")
        if self.input_type not in ("auto",) + TYPES:
            raise ValueError(f"input_type must be 'auto', 'backlash' or 'backlash_inverse', got {self.input_type!r}")
        if self.degree is not None and not (isinstance(self.degree, (int, np.integer)) and self.degree >= 1):
            raise ValueError(f"degree must be a positive integer or None, got {self.degree!r}")
        if not (isinstance(self.max_degree, (int, np.integer)) and self.max_degree >= 1):
            raise ValueError(f"max_degree must be a positive integer, got {self.max_degree!r}")
        if not 0 < self.alpha < 1 or not 0 < self.confidence < 1:
            raise ValueError("alpha and confidence must lie in (0, 1)")

    @staticmethod
    def _segments(record, stair, label):
        y = np.asarray(record.y, float)
        if y.ndim != 1 or y.size != stair.u.size:
            raise NonlinearIdentificationError(
                f"the {label} staircase record has {y.size} samples but the staircase has {stair.u.size}; "
                "the data do not belong to this config's protocols.staircase")
        u = getattr(record, "u", None)
        if u is not None and (np.shape(u) != stair.u.shape or not np.allclose(u, stair.u)):
            raise NonlinearIdentificationError(
                f"the {label} staircase record's input differs from this config's protocols.staircase")
        if not np.all(np.isfinite(y)):
            raise NonlinearIdentificationError(f"the {label} staircase output contains NaN or inf")
        return [y[a:b] for a, b in zip(stair.starts, stair.stops)], list(stair.starts)

    def fit(self, up_record, down_record, up_staircase, down_staircase) -> "NonlinearEstimator":
        """Identify h and the borders from the two staircase records (Section 4)."""
        self._check_settings()
        warns: list[str] = []
        su, ou = self._segments(up_record, up_staircase, "ascending")
        sd, od = self._segments(down_record, down_staircase, "descending")
        try:
            st = steady_levels(su + sd, offsets=ou + od, pool=self.pool_noise)
        except ValueError as err:
            raise NonlinearIdentificationError(f"{err} (protocols.staircase.hold)") from None
        warns += st.warnings
        self.steady_ = st
        n_up, n_dn = len(su), len(sd)
        data = _Data(np.asarray(up_staircase.all_levels, float), np.asarray(down_staircase.all_levels, float),
                     len(up_staircase.lead_in), len(down_staircase.lead_in), st.mean.copy(), st.se.copy())
        Xu, Xd, eu, ed = data.X[:n_up], data.X[n_up:], data.se[:n_up], data.se[n_up:]

        # j_a, j_d: the horizontal paths (eqs. 7a, 14a)
        ja_extra, zu = _flat_run(Xu[1:], eu[1:], [Xu[0]], [eu[0]], self.alpha)
        j_a = 1 + ja_extra
        j_d, zd = _flat_run(Xd, ed, [Xu[-1]], [eu[-1]], self.alpha)
        lo, hi = float(min(data.U.min(), data.all_up.min())), float(max(data.U.max(), data.all_up.max()))
        if j_a >= n_up:
            raise NonlinearIdentificationError(
                f"the output never leaves the horizontal path on the ascending staircase (all {n_up} levels give "
                f"the same steady output within noise): the working interval [u_m, u_M] = [{lo:g}, {hi:g}] is too "
                "narrow to reach the backlash borders (Section 3, Fig. 6a); widen protocols.staircase levels")
        if j_d >= n_dn:
            raise NonlinearIdentificationError(
                f"the output never leaves the horizontal path on the descending staircase (all {n_dn} levels give "
                f"the same steady output within noise): the working interval [u_m, u_M] = [{lo:g}, {hi:g}] is too "
                "narrow to reach the descending border (Section 3, Fig. 6a); widen protocols.staircase levels")

        n_border_up = n_up - j_a      # j_a >= 1: the first level sits on the descending border
        n_border_dn = n_dn - j_d
        if n_border_up < 2:
            raise NonlinearIdentificationError(
                f"only {n_border_up} ascending level(s) lie on the border (N - j_a = {n_up} - {j_a}): eq. (11) "
                "needs at least p + 1 >= 2; add levels above the horizontal path")
        if n_border_dn < 2:
            raise NonlinearIdentificationError(
                f"only {n_border_dn} descending level(s) lie on the border ({n_dn} levels, j_d = {j_d}): at least "
                "2 are needed for S^d and d^- (eq. 14); add levels below the horizontal path")
        pmax_up = n_border_up - 1
        if self.degree is not None:
            p = int(self.degree)
            if p > pmax_up:
                raise NonlinearIdentificationError(
                    f"the ascending staircase has N - j_a = {n_border_up} levels on the border, too few for degree "
                    f"{p}: eq. (11) needs N - j_a >= p + 1 = {p + 1}; add levels or lower "
                    "identification.nonlinear.degree")
            if p > n_border_dn - 1:
                msg = (f"the descending staircase has {n_border_dn} levels on the border, fewer than p + 1 = {p + 1} "
                       "(eq. 11 applied to eq. 14)")
                if self.method == "paper":
                    raise NonlinearIdentificationError(msg + ": the closed form cannot fit r(u); add levels, lower "
                                                       "the degree or use method: nls")
                warns.append(msg + ": S^d and d^- rest on the joint fit")
            degrees = [p]
        else:
            top = min(self.max_degree, pmax_up)
            if self.method == "paper":
                top = min(top, n_border_dn - 1)
                if top < 1:
                    raise NonlinearIdentificationError(
                        "too few border levels on the descending staircase for the closed form; use method: nls")
            degrees = list(range(1, top + 1))

        kinds = list(TYPES) if self.input_type == "auto" else [self.input_type]
        n = data.X.size
        table: list[_Candidate] = []
        grids: dict = {}
        for kind in kinds:
            for p in degrees:
                try:
                    routes, ja_p, jd_p = _route_with_paths(kind, p, data, j_a, j_d)
                except _TooFew:
                    continue
                if self.method == "paper":
                    best = routes[0]
                    theta, chi2 = best.theta, best.chi2
                    _, amb = _pick(kind, [(r.theta, r.chi2) for r in routes], data)
                    # the closed form is judged on the ascending fit, as the paper does
                    ia = _asc_index(kind, ja_p, n_up)
                    _, chi2_sel = _polyfit(data.U[ia], data.X[ia], data.se[ia], p)
                    crit = chi2_sel + (p + 1) * math.log(max(ia.size, 2))
                    table.append(_Candidate(kind, p, theta, chi2, crit, best, amb, ja_p, jd_p))
                else:
                    fits = [_nls(kind, r.theta, data) for r in routes[:4]]
                    dof_p = n - (p + 3)
                    if dof_p > 0 and min(f[1] for f in fits) > stats.chi2.isf(1e-3, dof_p):
                        # the closed form's starts leave a misfit: look for a better minimum
                        if kind not in grids:
                            grids[kind] = _grid_V(kind, data)
                        fits += [_nls(kind, th, data) for th in _grid_starts(kind, p, data, grids[kind])]
                    below = [c for c in table if c.kind == kind and c.p == p - 1 and np.isfinite(c.chi2)]
                    if below and min(f[1] for f in fits) > below[0].chi2:
                        # nested: degree p - 1 with c_p = 0 is a degree-p model, so the fit never
                        # ends worse than the one below (a start in another basin had left 4386 vs 2502)
                        fits.append(_nls(kind, _one_degree_up(below[0].theta), data))
                    i, amb = _pick(kind, fits, data)
                    theta, chi2 = fits[i]
                    table.append(_Candidate(kind, p, theta, chi2, chi2 + (p + 3) * math.log(n),
                                            routes[0], amb, ja_p, jd_p))
            if self.method == "nls" and self.degree is None:
                table += self._beyond_eq11(kind, [c for c in table if c.kind == kind], data, grids)
        if not table:
            raise NonlinearIdentificationError("no model could be fitted to the staircase data")

        # Remark 1.3: h(w) = 0 only at w = 0 is what makes the borders identifiable; a fit whose h
        # crosses zero elsewhere where the data go (a high degree that buys its fit with borders
        # shifted far out, when the plant is not quite of the model's structure) is set aside while a
        # fit that keeps the assumption exists. Over-dispersion: when even the best fit leaves a
        # misfit (chi2/dof >> 1: a disturbance, a level that did not settle, an h no polynomial of
        # this degree follows), chi^2 differences are inflated by c = chi2/dof and the type is chosen
        # by chi2/c (quasi-likelihood BIC, Burnham & Anderson 2002, Sec. 2.5); otherwise a few per
        # cent of a misfit chooses the type by chance
        self.c_hat_ = 1.0
        pool = [c for c in table if np.isfinite(c.chi2)]
        for c in pool:
            c.other_zeros = _other_zeros(c.kind, c.theta, data)
        adm = [c for c in pool if c.other_zeros == 0]
        if adm and len(adm) < len(pool):
            warns.append(f"{len(pool) - len(adm)} fit(s) whose h has another zero where the data go (Remark 1.3 "
                         "needs h(w) = 0 only at w = 0) were set aside")
            pool = adm
        if self.method == "nls":
            c_hat = _overdispersion(pool, n)
            if c_hat is not None:
                self.c_hat_ = float(c_hat)
        for c in pool:
            c.qbic = c.chi2 / self.c_hat_ + (c.p + 3) * math.log(n) if self.method == "nls" else c.bic

        # type: the best of each kind by the (quasi-likelihood) BIC; degree: BIC within the chosen kind.
        # Under a misfit the degree is still chosen by the plain BIC: the misfit is structured, not
        # noise, and a higher degree follows it where the data go (h of degree 1 for a cubic otherwise)
        per_kind = {}
        for kind in kinds:
            cands = [c for c in pool if c.kind == kind]
            if cands:
                per_kind[kind] = min(cands, key=lambda c: c.qbic)
        if not per_kind:
            raise NonlinearIdentificationError("every fit of the staircase data failed (non-finite chi-square)")
        if self.method == "paper":
            # for the type decision the closed forms are compared by the joint chi^2 they leave
            kind = min(per_kind, key=lambda k: per_kind[k].chi2 + (per_kind[k].p + 3) * math.log(n))
        else:
            kind = min(per_kind, key=lambda k: per_kind[k].qbic)
        best = min((c for c in pool if c.kind == kind), key=lambda c: c.bic)
        p = best.p
        theta = best.theta
        if self.degree is None and p == pmax_up and p < self.max_degree and not any(c.p > p for c in pool):
            warns.append(f"the selected degree p = {p} is the highest the N - j_a = {n_border_up} ascending border "
                         "levels support (eq. 11); a higher degree could not be tested: add levels to check it")
        elif p > pmax_up:
            warns.append(f"the selected degree p = {p} is above the {pmax_up} that the N - j_a = {n_border_up} "
                         "ascending border levels support alone (eq. 11): it rests on the joint fit of both "
                         "staircases; add ascending levels to check it")

        if best.ambiguous:
            warns.append("several roots of the fitted h(u - d^+) give equally good models whose h has no other zero "
                         "in the working range: d^+ is ambiguous (Remark 1.3 needs h(w) = 0 only at w = 0)")

        # covariance
        dof = n - (p + 3)
        if self.method == "nls":
            cov = _nls_cov(kind, theta, data)
        else:
            cov = self._paper_cov(kind, p, data, best.j_a, best.j_d, best.route.a, best.route.b)
        chi2 = _chi2(kind, theta, data)
        gof_p = float(stats.chi2.sf(chi2, dof)) if dof > 0 else float("nan")
        if self.method == "nls" and dof > 0 and gof_p < 1e-3:
            warns.append(f"the model does not fit the staircase data within their standard errors (chi2 = {chi2:.4g} "
                         f"for {dof} dof, p = {gof_p:.1g}): h may not be a polynomial of degree <= {p} on this range, "
                         "or a level did not settle; intervals are widened by sqrt(chi2/dof)")
            cov = cov * (chi2 / dof)

        # evidence for the type (Remark 1.4)
        evidence = self._evidence(kind, per_kind, j_a, zu, n, Xu, eu)
        if len(per_kind) == 2:
            other = [k for k in per_kind if k != kind][0]
            dbic = per_kind[other].qbic - per_kind[kind].qbic if self.method == "nls" else \
                per_kind[other].chi2 - per_kind[kind].chi2
            if dbic < 10:
                warns.append(f"the data barely distinguish Backlash from Backlash-Inverse (delta = {dbic:.3g} < 10); "
                             "widen the working interval or add levels")

        # flat paths reported: the tests (Backlash); none for a Backlash-Inverse (Remark 1.4)
        V = _internal(kind, theta[-3], theta[-2], theta[-1], data)
        if kind == "backlash":
            if (best.j_a, best.j_d) != (j_a, j_d):
                warns.append(f"the flat-path tests gave j_a = {j_a}, j_d = {j_d}; the borders fit best and agree with "
                             f"j_a = {best.j_a}, j_d = {best.j_d}, which are reported")
            j_a, j_d = best.j_a, best.j_d
            flat_up, flat_down = j_a, j_d
            ja_model, jd_model = _memberships(kind, theta, data)
            if (ja_model, jd_model) != (j_a, j_d):
                warns.append(f"the tests put j_a = {j_a}, j_d = {j_d}; the fitted borders put j_a = {ja_model}, "
                             f"j_d = {jd_model} (a level lies within noise of the horizontal path)")
        else:
            flat_up, flat_down = 0, 0

        self.result_ = self._result(kind, p, theta, cov, data, st, flat_up, flat_down, V, evidence, warns,
                                    {"chi2": chi2, "dof": dof, "gof_p": gof_p, "n_up": n_up,
                                     "j_a_test": j_a, "j_d_test": j_d, "overdispersion": self.c_hat_,
                                     "noise_lrv": st.lrv, "noise_df": st.df, "noise_batches": st.n_batches,
                                     "first_sample": st.first.tolist(), "n_averaged": st.n.tolist(),
                                     "selection": [{"type": c.kind, "degree": c.p, "chi2": c.chi2,
                                                    "criterion": c.bic, "type_criterion": c.qbic,
                                                    "d_plus": float(c.theta[-3]),
                                                    "slope_down": float(c.theta[-2]),
                                                    "d_minus": float(c.theta[-1]),
                                                    "other_zeros": c.other_zeros}
                                                   for c in table]})
        r = self.result_
        self.type_, self.degree_ = r.type, r.degree
        self.d_plus_, self.slope_down_, self.d_minus_ = r.d_plus, r.slope_down, r.d_minus
        self.h_coef_ = np.asarray(r.h_coefficients)
        self.flat_up_, self.flat_down_ = r.flat_up, r.flat_down
        self.selection_ = table
        return self

    def _beyond_eq11(self, kind, done, data, grids) -> list:
        """Degrees above eq. (11)'s limit, for the joint fit only, while the highest degree fitted
        still misfits (chi2 p < 1e-3).

        Eq. (11) bounds ``p`` by the ascending border levels because the closed form fits ``h``
        on them alone; the joint fit also sees the descending border, whose levels sample ``h`` at
        other ``w``. When the borders leave few ascending levels (a deadzone or a bent border moving
        a level onto the horizontal path), a quintic ``h`` was cut to degree 4 and every later stage
        inherited the misfit. Each further degree starts from the one below (``c_p = 0``) and from
        the grid of :func:`_grid_starts`, and is kept while its coefficient is significant by the F
        test of nested fits (level ``alpha``; the scale is the misfit, chi2/dof: a level that did not
        settle made BIC add four degrees for a drop of chi2 from 73 to 34, and the degree-9 ``h``
        extrapolated wildly); at most ``max_degree``, and ``n - p - 3 >= 2`` dof."""
        out: list[_Candidate] = []
        n = data.X.size
        if not done:
            return out
        last = max(done, key=lambda c: c.p)
        while True:
            p = last.p + 1
            dof_last = n - (last.p + 3)
            if p > self.max_degree or n - (p + 3) < 2 or not np.isfinite(last.chi2) \
                    or last.chi2 <= stats.chi2.isf(1e-3, dof_last):
                return out
            if kind not in grids:
                grids[kind] = _grid_V(kind, data)
            starts = [_one_degree_up(last.theta)] + _grid_starts(kind, p, data, grids[kind])
            fits = [_nls(kind, th, data) for th in starts]
            i, amb = _pick(kind, fits, data)
            theta, chi2 = fits[i]
            # the added coefficient must be significant by the F test of nested fits, whose scale is
            # the misfit itself (chi2 / dof), not the noise: under a misfit BIC takes any small drop
            dof = n - (p + 3)
            if not (np.isfinite(chi2) and chi2 < last.chi2
                    and stats.f.sf((last.chi2 - chi2) / max(chi2 / dof, 1e-300), 1, dof) < self.alpha):
                return out
            last = _Candidate(kind, p, theta, chi2, chi2 + (p + 3) * math.log(n), last.route, amb, last.j_a, last.j_d)
            out.append(last)

    def _paper_cov(self, kind, p, data, j_a, j_d, a, b) -> np.ndarray:
        """Delta method through the closed form: ``J diag(se^2) J^T`` with ``J = d theta / d X_hat``."""
        def theta_of(X):
            return _paper_route(kind, p, data.with_X(X), j_a, j_d, a_ref=a, b_ref=b)[0].theta
        J = []
        for k in range(data.X.size):
            h = 1e-3 * data.se[k]
            Xp, Xm = data.X.copy(), data.X.copy()
            Xp[k] += h
            Xm[k] -= h
            J.append((theta_of(Xp) - theta_of(Xm)) / (2 * h))
        J = np.column_stack(J)
        return J @ np.diag(data.se ** 2) @ J.T

    def _evidence(self, kind, per_kind, j_a, zu, n, Xu, eu) -> str:
        parts = []
        if j_a >= 2:
            x, s = Xu[:j_a], eu[:j_a]
            w = 1 / s ** 2
            m = np.sum(w * x) / np.sum(w)
            q = float(np.sum(w * (x - m) ** 2))
            pv = float(stats.chi2.sf(q, j_a - 1))
            parts.append(f"X_1..X_{j_a} of the ascending staircase lie on one horizontal path (homogeneity "
                         f"chi2 = {q:.3g} on {j_a - 1} dof, p = {pv:.2g}), which only a Backlash produces")
        else:
            parts.append(f"no horizontal path: X_2 differs from X_1 (z = {zu[0]:.3g})" if zu else "no horizontal path")
        fits = "; ".join(f"{k}: chi2 = {c.chi2:.4g} for {n - c.p - 3} dof at degree {c.p}"
                         for k, c in per_kind.items())
        parts.append(f"joint fit {fits}")
        if len(per_kind) == 2:
            other = [k for k in per_kind if k != kind][0]
            if self.method == "nls":
                parts.append(f"BIC prefers {kind} by {per_kind[other].qbic - per_kind[kind].qbic:.4g}")
            else:
                parts.append(f"the closed form's joint chi2 prefers {kind} by "
                             f"{per_kind[other].chi2 - per_kind[kind].chi2:.4g}")
        else:
            parts.append(f"type fixed to {kind} by identification.nonlinear.input_type")
        return f"{kind}: " + "; ".join(parts)

    def _result(self, kind, p, theta, cov, data, st: SteadyLevels, flat_up, flat_down, V, evidence, warns, fit):
        df = max(int(st.df), 1)
        tq = float(stats.t.ppf(0.5 + self.confidence / 2, df))
        sd = np.sqrt(np.maximum(np.diag(cov), 0.0))
        names = tuple(f"c{i}" for i in range(1, p + 1)) + ("d_plus", "slope_down", "d_minus")
        iv = {nm: (float(theta[i] - tq * sd[i]), float(theta[i] + tq * sd[i])) for i, nm in enumerate(names)}
        ci = {"slope_up": (1.0, 1.0), "slope_down": iv["slope_down"], "d_plus": iv["d_plus"],
              "d_minus": iv["d_minus"],
              "h_coefficients": [(0.0, 0.0)] + [iv[f"c{i}"] for i in range(1, p + 1)],
              "X_hat": [(float(x - tq * s), float(x + tq * s)) for x, s in zip(data.X, data.se)]}
        fit = dict(fit, t_quantile=tq, confidence=self.confidence, param_se=sd.tolist())
        return NonlinearResult(
            type=kind, slope_up=1.0, slope_down=float(theta[-2]), d_plus=float(theta[-3]), d_minus=float(theta[-1]),
            h_coefficients=(0.0,) + tuple(float(c) for c in theta[:p]), degree=int(p),
            w_range=(float(V.min()), float(V.max())), ci=ci, cov=np.asarray(cov, float), param_names=names,
            levels=tuple(float(u) for u in data.U), X_hat=tuple(float(x) for x in data.X),
            X_hat_se=tuple(float(s) for s in data.se), flat_up=int(flat_up), flat_down=int(flat_down),
            method=self.method, evidence=evidence, warnings=tuple(dict.fromkeys(warns)), fit=fit)


# ---------------------------------------------------------------------------- run, save, load

def _records_from(data, up, down) -> tuple[Any, Any]:
    """The two staircase records from a ``simulation.h5`` path or a mapping name -> Record."""
    if isinstance(data, (str, Path)):
        from hwid.results import open_results, read_records
        with open_results(data, ("simulation", "nonlinear")) as f:
            if "experiments" not in f:
                raise NonlinearIdentificationError(f"{data}: holds no experiments")
            recs = read_records(f["experiments"])
    else:
        recs = dict(data)
    missing = [s.name for s in (up, down) if s.name not in recs]
    if missing:
        raise NonlinearIdentificationError(
            f"{data if isinstance(data, (str, Path)) else 'the data'} hold no experiment "
            f"{' or '.join(repr(m) for m in missing)}; run hwid simulate with a config that has protocols.staircase")
    return recs[up.name], recs[down.name]


def identify_nonlinear(cfg, plant=None, data=None, journal_dir=None):
    """Stage 1 on the config's staircases: run them on ``plant`` (default: the config's plant) or read
    them from ``data`` (a ``simulation.h5`` path or a mapping of records); return ``(result, records)``."""
    from hwid import protocols
    if cfg.protocols.staircase is None:
        raise NonlinearIdentificationError(
            "the config has no protocols.staircase: stage 1 needs the ascending and descending staircases (Section 4)")
    up, down = protocols.staircases(cfg)
    if data is not None:
        ru, rd = _records_from(data, up, down)
    else:
        if plant is None:
            from hwid.plant import make_plant
            plant = make_plant(cfg, journal_dir=journal_dir)
        ru = plant.run(up.name, up.u)
        rd = plant.run(down.name, down.u)
        for r, s in ((ru, up), (rd, down)):
            r.attrs.update({"direction": s.direction, "hold": s.hold, "levels": s.levels.tolist(),
                            "lead_in": s.lead_in.tolist()})
    est = NonlinearEstimator.from_config(cfg).fit(ru, rd, up, down)
    return est.result_, [ru, rd]


# ---------------------------------------------------------------------------------- Table 1

def table1_rows(cfg, result: NonlinearResult) -> dict:
    """Table 1 side by side for a simulated config: for every level j (1-based over both staircases)
    ``U_j``, the paper's ``X_j`` and ``X_hat_j(M)`` where the paper gives them, the true ``X_j`` of the
    normalised plant, ours and its interval; and the borders (paper, truth, ours, interval)."""
    from hwid import protocols
    from hwid.model import from_config
    truth = from_config(cfg.plant).normalised()
    up, down = protocols.staircases(cfg)
    Xt = np.concatenate([truth.staircase_steady(up.lead_in, up.levels),
                         truth.staircase_steady(down.lead_in, down.levels)])
    published = {r.j: (r.X, r.X_hat) for r in paper.TABLE1}
    # simultaneous (Sidak) 95 % intervals over all levels of the table: each pointwise interval
    # widened from z_{0.975} to z_{(1 + 0.95^{1/n})/2}, so all n hold the truth together w.p. 95 %
    from scipy import stats
    n = len(result.X_hat)
    widen = stats.norm.ppf(0.5 + 0.5 * 0.95 ** (1.0 / n)) / stats.norm.ppf(0.975)
    rows = []
    for j, (u, x, ci, xt) in enumerate(zip(result.levels, result.X_hat, result.ci["X_hat"], Xt), start=1):
        px, pxh = published.get(j, (None, None))
        half = 0.5 * (ci[1] - ci[0]) * widen
        cj = (x - half, x + half)
        rows.append({"j": j, "U": u, "paper_X": px, "paper_X_hat": pxh, "true_X": float(xt), "X_hat": x,
                     "ci": tuple(ci), "inside": bool(ci[0] <= xt <= ci[1]),
                     "ci_joint": cj, "inside_joint": bool(cj[0] <= xt <= cj[1])})
    true_b = {"d_plus": truth.input.d_plus, "slope_down": truth.input.slope_down, "d_minus": truth.input.d_minus}
    borders = []
    for k in ("d_plus", "slope_down", "d_minus"):
        ci = result.ci[k]
        borders.append({"name": k, "paper": paper.BORDERS[k], "true": float(true_b[k]),
                        "ours": float(getattr(result, k)), "ci": tuple(ci),
                        "inside": bool(ci[0] <= true_b[k] <= ci[1])})
    return {"rows": rows, "borders": borders}


def format_summary(result: NonlinearResult) -> str:
    """A readable summary of a stage-1 result (what ``hwid identify-nonlinear`` prints)."""
    def pm(key):
        v = getattr(result, key)
        lo, hi = result.ci[key]
        return f"{v:.6g}  [{lo:.6g}, {hi:.6g}]"
    conf = result.fit.get("confidence", 0.95)
    lines = [f"input nonlinearity: {result.type}   ({result.evidence})",
             f"normalised model (eqs. 4a-c), {100 * conf:g} % intervals; method {result.method}:",
             "  slope_up   = 1 (normalisation)",
             f"  slope_down = {pm('slope_down')}",
             f"  d_plus     = {pm('d_plus')}",
             f"  d_minus    = {pm('d_minus')}",
             f"  h degree p = {result.degree}" + ("" if "chi2" not in result.fit else
                                                  f"   (joint chi2 = {result.fit['chi2']:.4g} for {result.fit['dof']} dof)"),
             "  h coefficients (ascending powers):"]
    for i, (c, (lo, hi)) in enumerate(zip(result.h_coefficients, result.ci["h_coefficients"])):
        if i:
            lines.append(f"    c{i} = {c:.6g}  [{lo:.6g}, {hi:.6g}]")
    if result.type == "backlash":
        lines.append(f"  horizontal paths: j_a = {result.flat_up}, j_d = {result.flat_down}")
    else:
        lines.append("  horizontal paths: none (Backlash-Inverse, Remark 1.4): j_a = j_d = 0")
    lines.append(f"  w range identified: [{result.w_range[0]:.4g}, {result.w_range[1]:.4g}]")
    n_up = int(result.fit.get("n_up", len(result.levels)))
    lines.append("  steady states (eq. 9):   j       U_j       X_hat_j         se")
    for j, (u, x, s) in enumerate(zip(result.levels, result.X_hat, result.X_hat_se), start=1):
        tag = "up  " if j <= n_up else "down"
        lines.append(f"    {tag:>20} {j:3d}  {u:+8.4f}  {x:+12.6f}  {s:9.2e}")
    return "\n".join(lines)
