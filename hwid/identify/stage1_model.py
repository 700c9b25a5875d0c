"""The stage-1 level model (Section 4): the steady outputs ``X_j = h_bar(F_bar[U_j])`` of both
staircases (eqs. 5, 8a-b), with ``F_bar`` run as a steady-state recursion over all levels, lead-ins
included (eqs. 7a-b, 14a-b), so which levels lie on a horizontal path or on a border follows the
parameters ``theta = (c_1..c_p, d^+, S^d, d^-)``; its chi-square, gradients and the checks on a fit
(Remark 1.3: ``h_bar(w) = 0`` only at ``w = 0``).
"""
from __future__ import annotations

from dataclasses import dataclass

import numpy as np
from numba import njit

from hwid.model import BELOW_BORDERS, InputNonlinearity


@dataclass(frozen=True)
class LevelData:
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

    def with_X(self, X) -> "LevelData":
        return LevelData(self.all_up, self.all_down, self.lead_up, self.lead_down, np.asarray(X, float), self.se)


def internal_levels(kind: str, d_plus: float, slope_down: float, d_minus: float, data: LevelData) -> np.ndarray:
    """Steady ``V_j = F_bar[U_j]`` of both staircases (eqs. 7a-b, 14a-b) from the lead-in on."""
    f = InputNonlinearity(kind, 1.0, slope_down, d_plus, d_minus)
    state = BELOW_BORDERS if kind == "backlash" else 0.0
    vu = f.steady(data.all_up, state)[data.lead_up:]
    vd = f.steady(data.all_down, state)[data.lead_down:]
    return np.concatenate([vu, vd])


def predict_levels(kind: str, theta: np.ndarray, data: LevelData) -> np.ndarray:
    """``X_j(theta) = h_bar(F_bar[U_j])`` with ``theta = (c_1..c_p, d^+, S^d, d^-)``."""
    c = np.concatenate([[0.0], theta[:-3]])
    v = internal_levels(kind, theta[-3], theta[-2], theta[-1], data)
    return np.polynomial.polynomial.polyval(v, c)


def joint_chi2(kind: str, theta: np.ndarray, data: LevelData) -> float:
    if not (theta[-2] > 0 and theta[-3] >= theta[-1] and np.all(np.isfinite(theta))):
        return np.inf
    with np.errstate(all="ignore"):
        r = (data.X - predict_levels(kind, theta, data)) / data.se
        c = float(r @ r)
    return c if np.isfinite(c) else np.inf


def other_zeros(kind: str, theta: np.ndarray, data: LevelData) -> int:
    """Number of real zeros of ``h_bar`` other than 0 inside the range of ``w`` the data visit."""
    v = internal_levels(kind, theta[-3], theta[-2], theta[-1], data)
    lo, hi = float(v.min()), float(v.max())
    z = real_roots(np.concatenate([[0.0], theta[:-3]]), lo, hi)
    tol = 1e-6 * max(1.0, hi - lo)
    return int(np.sum(np.abs(z) > tol))


def pick_fit(kind: str, fits: list, data: LevelData) -> tuple[int, bool]:
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
        return (other_zeros(kind, th, data) > 0, not (lo <= a <= hi))

    keys = {i: key(i) for i in near}
    first = min(near, key=lambda i: (keys[i], chis[i]))
    d0 = fits[first][0][-3]
    distinct = [i for i in near if keys[i] == keys[first] and abs(fits[i][0][-3] - d0) > 1e-3 * (1 + abs(d0))]
    return first, bool(distinct)


def ascending_index(kind: str, j_a: int, n_up: int) -> np.ndarray:
    # with the lead-in, the first ascending level sits on the descending branch for both types
    return np.arange(j_a if kind == "backlash" else 1, n_up)


def descending_index(kind: str, j_d: int, n_down: int) -> np.ndarray:
    return np.arange(j_d if kind == "backlash" else 0, n_down)


def path_memberships(kind: str, theta: np.ndarray, data: LevelData) -> tuple[int, int]:
    """``(j_a, j_d)`` that the parameters ``theta`` imply: levels on the horizontal paths (eqs. 7a, 14a)."""
    v = internal_levels(kind, theta[-3], theta[-2], theta[-1], data)
    n_up = data.n_up
    top = float(InputNonlinearity(kind, 1.0, theta[-2], theta[-3], theta[-1]).ascending(
        data.all_down[data.lead_down - 1]))
    ja = int(np.argmin(np.r_[np.abs(v[:n_up] - v[0]) <= 1e-12, False]))
    jd = int(np.argmin(np.r_[np.abs(v[n_up:] - top) <= 1e-12, False]))
    return ja, jd


@njit(cache=True)
def steady_grad(backlash, levels, lead, dp, sd, dm, v, dv, at):
    """Steady ``V_j = F_bar[U_j]`` and ``dV_j / d(d^+, S^d, d^-)`` along one level sequence, written
    from row ``at`` of ``v``, ``dv`` on (levels from ``lead`` on).

    The recursion and its branch decisions are those of :func:`hwid.blocks.backlash.static_play`
    (from ``BELOW_BORDERS``) and :func:`~hwid.blocks.backlash.static_direction_map` (from 0) with
    ``slope_up = 1``: a level on the ascending border ``u - d^+`` (branch ``u + d^+``) depends on
    ``d^+`` only, one on the descending border ``S^d (u - d^-)`` (branch ``u / S^d + d^-``) on ``S^d``
    and ``d^-``, and a level on a horizontal path keeps the derivative of the state it holds
    (eqs. 7a-b, 14a-b)."""
    g0, g1, g2 = 0.0, 0.0, 0.0
    if backlash:
        prev = BELOW_BORDERS
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
def joint_model(backlash, up, lead_up, down, lead_down, X, se, z, want_jac):
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
    steady_grad(backlash, up, lead_up, dp, sd, dm, v, dv, 0)
    steady_grad(backlash, down, lead_down, dp, sd, dm, v, dv, up.shape[0] - lead_up)
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


def real_roots(c: np.ndarray, lo: float, hi: float) -> np.ndarray:
    c = np.trim_zeros(np.asarray(c, float), "b")
    if c.size < 2:
        return np.array([])
    rts = np.roots(c[::-1])
    scale = max(1.0, hi - lo)
    real = rts[np.abs(rts.imag) <= 1e-6 * scale + 1e-3 * np.abs(rts)].real
    return np.sort(real[(real >= lo) & (real <= hi)])
