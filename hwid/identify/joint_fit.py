"""The joint weighted nonlinear least squares of stage 1: all of ``(c_1..c_p, d^+, S^d, d^-)``
refined together on both staircases (the level model of :mod:`hwid.identify.stage1_model`), its
starts (the closed form, a grid over the borders, the degree below with ``c_p = 0``) and its
covariance ``(J^T W J)^-1``.
"""
from __future__ import annotations

import math
from typing import Optional

import numpy as np
from scipy import special

from hwid.identify.lm import lm
from hwid.identify.stage1_model import LevelData, internal_levels, joint_chi2, joint_model, predict_levels


def nls_fit(kind: str, theta0: np.ndarray, data: LevelData) -> tuple[np.ndarray, float]:
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
        return joint_model(*args, z, False)[0]

    def jac(z):
        return joint_model(*args, z, True)[1]

    z0 = np.concatenate([theta0[:p], [theta0[-3], math.log(max(theta0[-2], 1e-6)),
                                      math.log(max(theta0[-3] - theta0[-1], 1e-6))]])
    try:
        z, _, _ = lm(fun, jac, z0, xtol=1e-10, ftol=1e-10, gtol=1e-10, max_nfev=60 * (p + 4))
    except ValueError:
        return theta0, np.inf
    th = to_theta(z)
    return th, joint_chi2(kind, th, data)


def numeric_jacobian(f, theta: np.ndarray, rel: float = 1e-6) -> np.ndarray:
    """Central differences of ``f`` at ``theta``."""
    cols = []
    for i in range(theta.size):
        h = rel * max(1.0, abs(theta[i]))
        tp, tm = theta.copy(), theta.copy()
        tp[i] += h
        tm[i] -= h
        cols.append((np.asarray(f(tp)) - np.asarray(f(tm))) / (2 * h))
    return np.column_stack(cols)


def nls_cov(kind: str, theta: np.ndarray, data: LevelData) -> np.ndarray:
    """``(J^T W J)^-1`` at the estimate (J of the weighted residuals)."""
    J = numeric_jacobian(lambda t: predict_levels(kind, t, data) / data.se, theta)
    return np.linalg.pinv(J.T @ J, rcond=1e-13)


def grid_V(kind: str, data: LevelData, n_d: int = 41, n_gap: int = 24, n_s: int = 9):
    """The borders of :func:`grid_starts`' grid ``(G, 3)`` and the steady states ``V`` they
    give ``(G, n)`` (independent of the degree, so computed once per type)."""
    U = np.concatenate([data.all_up, data.all_down])
    lo, hi = float(U.min()), float(U.max())
    W = max(hi - lo, 1e-12)
    dp, gap, sd = np.meshgrid(np.linspace(lo - 0.5 * W, hi + 0.5 * W, n_d), np.geomspace(1e-3 * W, 1.5 * W, n_gap),
                              np.geomspace(1 / 3, 3.0, n_s), indexing="ij")
    P = np.column_stack([dp.ravel(), sd.ravel(), (dp - gap).ravel()])
    V = np.stack([internal_levels(kind, a, b, c, data) for a, b, c in P])
    return P, V, 1.5 * W / (n_d - 1)


def grid_starts(kind: str, p: int, data: LevelData, grid=None, keep: int = 3) -> list[np.ndarray]:
    """Global starting points for the joint fit: a grid over the borders ``(d^+, S^d, d^+ - d^-)``
    with ``h_bar``'s coefficients profiled out (for fixed borders the steady states ``V_j`` are
    known and ``X_j = h_bar(V_j)`` is linear in ``c_1..c_p``: weighted least squares), the ``keep``
    best by chi^2, apart from each other by more than a grid step.

    Used when the closed form's starts leave a fit that does not describe the data (a local
    minimum of the joint chi^2: e.g. a non-monotone ``h_bar`` whose border points the closed form
    assigns to the wrong root). ``d^+`` spans the levels' range widened by half its width, the gap
    up to 1.5 times that width, ``S^d`` a factor 3 either way of 1."""
    P, V, step = grid if grid is not None else grid_V(kind, data)
    w = 1.0 / data.se
    A = (V[:, :, None] ** np.arange(1, p + 1)) * w[None, :, None]          # (G, n, p)
    b = data.X * w
    AtA = np.einsum("gni,gnj->gij", A, A) + 1e-12 * np.eye(p)
    Atb = np.einsum("gni,n->gi", A, b)
    with np.errstate(all="ignore"):
        try:
            C = np.linalg.solve(AtA, Atb[..., None])[..., 0]
        except np.linalg.LinAlgError:
            # a singular system anywhere in the grid (borders that put every level at one steady
            # state): the minimum-norm solutions of the whole stack at once, as lstsq's would be
            C = (np.linalg.pinv(AtA) @ Atb[..., None])[..., 0]
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


def one_degree_up(theta: np.ndarray) -> np.ndarray:
    """``(c_1..c_p, d^+, S^d, d^-)`` as the same model of degree ``p + 1`` (``c_{p+1} = 0``)."""
    return np.concatenate([theta[:-3], [0.0], theta[-3:]])


def overdispersion(cands, n: int) -> Optional[float]:
    """``chi2/dof`` of the best-fitting candidate when it misfits (p < 1e-3), else None."""
    ratios = [(c.chi2 / (n - c.p - 3), n - c.p - 3) for c in cands if n - c.p - 3 > 0]
    if not ratios:
        return None
    r, dof = min(ratios)
    return float(r) if special.chdtrc(dof, r * dof) < 1e-3 else None
