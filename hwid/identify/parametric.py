"""A stable rational model ``G(s) = B(s)/A(s) e^{-s tau}`` with ``G(0) = 1`` fitted to the stage 2
frequency-response estimates ``G_hat(j omega_i)`` and their covariances.

The paper leaves G nonparametric (Section 5); later stages need a model they can simulate in the
time domain, so this module fits one:

* parametrisation with ``G(0) = 1`` built in (eq. 4b): ``A(s) = 1 + a_1 s + ... + a_n s^n``,
  ``B(s) = 1 + b_1 s + ... + b_m s^m`` (``m < n``), optional delay ``tau >= 0``; ``s`` is scaled by
  the geometric mean of the frequencies for conditioning;
* initial values by Levy's linearised least squares refined by Sanathanan-Koerner iterations;
* weighted nonlinear least squares of the residuals whitened by each estimate's 2x2 (Re, Im)
  covariance (propagated from the (|G|, phi) covariance of stage 2) -- the ML fit given those
  uncertainties;
* orders ``1 <= n <= max_order``, ``0 <= m < n`` compared by the small-sample corrected Akaike
  criterion AICc (``chi^2 + 2k + 2k(k+1)/(2 N_freq - k - 1)``; BIC's ``k ln(2 N_freq)`` over-fits with
  the handful of frequencies of Table 2), among stable fits that leave a degree of freedom and
  have no pole or zero a decade below the lowest frequency (which the data cannot place: such a
  fit is a near-cancelling pole-zero pair at ``s ~ 0``, ``1e-8`` apart, that AICc can prefer by a
  fraction of a unit);
* poles with intervals by the delta method (``dp = -sum_i p^i da_i / A'(p)``).
"""
from __future__ import annotations

from dataclasses import dataclass

import numpy as np
from scipy import special

from hwid import HwidError
from hwid.identify.lm import lm


@dataclass(frozen=True)
class RationalFit:
    """A fitted ``G(s) = num(s)/den(s) e^{-s delay}`` (descending powers, ``den`` monic, ``G(0) = 1``)."""

    num: np.ndarray
    den: np.ndarray
    delay: float
    delay_se: float
    poles: np.ndarray
    poles_cov: np.ndarray          # (n, 2, 2) of (Re p, Im p)
    chi2: float
    dof: int
    order: tuple[int, int]         # (n = deg A, m = deg B)
    aicc: float
    candidates: tuple = ()
    warnings: tuple[str, ...] = ()
    confidence: float = 0.95

    def freqresp(self, omega) -> np.ndarray:
        s = 1j * np.asarray(omega, float)
        return np.polyval(self.num, s) / np.polyval(self.den, s) * np.exp(-s * self.delay)

    @property
    def poles_ci(self) -> np.ndarray:
        """``[[Re lo, Re hi, Im lo, Im hi], ...]`` at ``confidence``."""
        q = special.ndtri(0.5 + self.confidence / 2)
        se = np.sqrt(np.maximum(np.stack([self.poles_cov[:, 0, 0], self.poles_cov[:, 1, 1]], 1), 0))
        return np.column_stack([self.poles.real - q * se[:, 0], self.poles.real + q * se[:, 0],
                                self.poles.imag - q * se[:, 1], self.poles.imag + q * se[:, 1]])

    def _poles_ci_plain(self) -> list:
        """:attr:`poles_ci` as plain data; a real pole's imaginary part is 0 by the structure, not
        estimated: its interval is None (not ``[0, 0]``)."""
        return [row[:2] + ([None, None] if p.imag == 0.0 and row[2] == row[3] else row[2:])
                for p, row in zip(self.poles, self.poles_ci.tolist())]

    def to_dict(self) -> dict:
        se = np.sqrt(np.maximum(np.stack([self.poles_cov[:, 0, 0], self.poles_cov[:, 1, 1]], 1), 0)) \
            if self.poles.size else np.zeros((0, 2))
        return {"num": [float(x) for x in self.num], "den": [float(x) for x in self.den],
                "delay": float(self.delay), "delay_se": float(self.delay_se),
                "poles": [[float(p.real), float(p.imag)] for p in self.poles],
                "poles_se": se.tolist(), "poles_ci": self._poles_ci_plain(),
                "order": [int(self.order[0]), int(self.order[1])], "chi2": float(self.chi2),
                "dof": int(self.dof), "aicc": float(self.aicc), "criterion": "aicc",
                "candidates": list(self.candidates)}


def reim_covariance(gain, phase, cov) -> np.ndarray:
    """Covariance of ``(Re G, Im G)`` from that of ``(|G|, phi)``, ``G = |G| e^{-j phi}``."""
    g, p = np.asarray(gain, float), np.asarray(phase, float)
    J = np.empty(g.shape + (2, 2))
    J[..., 0, 0], J[..., 0, 1] = np.cos(p), -g * np.sin(p)
    J[..., 1, 0], J[..., 1, 1] = -np.sin(p), -g * np.cos(p)
    return J @ np.asarray(cov, float) @ np.swapaxes(J, -1, -2)


def _whiteners(C: np.ndarray) -> np.ndarray:
    W = np.empty_like(C)
    for i, c in enumerate(C):
        c = 0.5 * (c + c.T)
        floor = 1e-12 * max(np.trace(c), 1e-300)
        w_, V = np.linalg.eigh(c)
        w_ = np.maximum(w_, floor)
        W[i] = (V / np.sqrt(w_)) @ V.T            # C^{-1/2}
    return W


def _levy_sk(s, G, n, m, weight, iters=20):
    """Levy's linearised LS ``B - G A ~ 0`` (weighted), then Sanathanan-Koerner iterations."""
    Sa = s[:, None] ** np.arange(1, n + 1)          # a_1..a_n
    Sb = s[:, None] ** np.arange(1, m + 1)          # b_1..b_m
    d = np.ones(s.size)
    theta = np.zeros(n + m)
    for _ in range(iters):
        # B(s) - G A(s) = (1 - G) + sum b_i s^i - G sum a_i s^i
        M = np.hstack([-G[:, None] * Sa, Sb]) * (weight / d)[:, None]
        rhs = -(1 - G) * weight / d
        Mr = np.vstack([M.real, M.imag])
        rr = np.concatenate([rhs.real, rhs.imag])
        new, *_ = np.linalg.lstsq(Mr, rr, rcond=None)
        A = 1 + Sa @ new[:n]
        d = np.maximum(np.abs(A), 1e-12)
        if np.allclose(new, theta, rtol=1e-10, atol=1e-14):
            theta = new
            break
        theta = new
    return theta


def _model(theta, s, n, m, delay):
    a, b = theta[:n], theta[n:n + m]
    A = 1 + (s[:, None] ** np.arange(1, n + 1)) @ a
    B = 1 + ((s[:, None] ** np.arange(1, m + 1)) @ b if m else 0)
    return B / A * np.exp(-s * delay), A, B


def _poles_scaled(a):
    """Roots of ``1 + a_1 s + ... + a_n s^n``."""
    return np.polynomial.polynomial.polyroots(np.concatenate([[1.0], a]))


def _fit_one(s, Gd, W, n, m, fit_delay, tau0):
    """LM fit of one order; returns (theta, tau, chi2, jac) in the scaled variable."""
    weight = np.sqrt(0.5 * np.einsum("kij,kij->k", W, W))      # ~ 1 / (standard error of G_i)

    def residual(x):
        tau = x[n + m] if fit_delay else tau0
        Gm, _, _ = _model(x[:n + m], s, n, m, tau)
        e = Gd - Gm
        r = np.einsum("kij,kj->ki", W, np.stack([e.real, e.imag], 1))
        return r.ravel()

    def jac(x):
        tau = x[n + m] if fit_delay else tau0
        Gm, A, B = _model(x[:n + m], s, n, m, tau)
        cols = [-Gm * s ** i / A for i in range(1, n + 1)]
        cols += [s ** i * np.exp(-s * tau) / A for i in range(1, m + 1)]
        if fit_delay:
            cols.append(-s * Gm)
        dG = np.stack(cols, 1)                      # d G_model / d x
        out = -np.einsum("kij,kjp->kip", W, np.stack([dG.real, dG.imag], 1))
        return out.reshape(-1, dG.shape[1])

    best = None
    taus = [tau0] if not fit_delay else list(np.unique(np.concatenate([[tau0], tau0 * np.array([0, 0.5, 1.5])])))
    for t0 in taus:
        th0 = _levy_sk(s, Gd * np.exp(s * t0), n, m, weight)
        x0 = np.concatenate([th0, [t0]]) if fit_delay else th0
        try:
            x, _, _ = lm(residual, jac, x0, xtol=1e-13, ftol=1e-13, max_nfev=2000)
        except (ValueError, np.linalg.LinAlgError):
            continue
        p = _poles_scaled(x[:n])
        if np.any(p.real >= 0):                   # reflect unstable poles and refit once
            p = np.where(p.real >= 0, -np.abs(p.real) - 1e-3 + 1j * p.imag, p)
            a = np.real(np.poly(p)[::-1])
            a = a / a[0]
            x0 = np.concatenate([a[1:], x[n:]])
            try:
                x, _, _ = lm(residual, jac, x0, xtol=1e-13, ftol=1e-13, max_nfev=2000)
            except (ValueError, np.linalg.LinAlgError):
                continue
        chi2 = float(np.sum(residual(x) ** 2))
        if not (np.isfinite(chi2) and np.all(np.isfinite(x)) and x[n - 1] != 0):
            continue                              # degenerate: not a denominator of degree n
        if best is None or chi2 < best[1]:
            best = (x, chi2, jac(x))
    return best


def _delay_start(s, G, n: int, m: int, w_scaled) -> float:
    """The delay's initial value (in the scaled time): the slope of the excess phase of an
    ``(n, m)`` Levy fit without delay, at least 0."""
    th = _levy_sk(s, G, n, m, np.ones(G.size))
    Gm, _, _ = _model(th, s, n, m, 0.0)
    ex = np.unwrap(np.angle(Gm) - np.angle(G))
    return max(float(np.polyfit(w_scaled, ex, 1)[0]) if G.size > 1 else 0.0, 0.0)


def _pole_covariance(a, cov_a) -> tuple[np.ndarray, np.ndarray]:
    """The roots of ``1 + a_1 s + ... + a_n s^n`` (unscaled) and the covariance of each root's
    ``(Re, Im)`` from ``cov_a`` by the delta method (``dp/da_i = -p^i / A'(p)``), sorted by real then
    imaginary part."""
    n = len(a)
    poles = _poles_scaled(a)
    dA = np.polynomial.polynomial.polyder(np.concatenate([[1.0], a]))
    pc = np.zeros((n, 2, 2))
    for i, p in enumerate(poles):
        g = -(p ** np.arange(1, n + 1)) / np.polynomial.polynomial.polyval(p, dA)   # dp/da
        Jr = np.vstack([g.real, g.imag])
        with np.errstate(invalid="ignore", over="ignore"):   # a singular fit: intervals are NaN/inf
            pc[i] = Jr @ cov_a @ Jr.T
    order = np.lexsort((poles.imag, poles.real))
    return poles[order], pc[order]


def fit_rational(omega, G, cov, gain=None, phase=None, max_order: int = 4, fit_delay: bool = False,
                 confidence: float = 0.95, orders=None) -> RationalFit:
    """Fit a stable ``G(s)`` with ``G(0) = 1`` to ``G_hat(j omega_i)`` with their uncertainties.

    Parameters
    ----------
    omega : array (N,)
        Frequencies, rad/s.
    G : complex array (N,)
        ``G_hat(j omega_i)`` (normalised).
    cov : array (N, 2, 2)
        Covariance of ``(|G|, phi)`` per frequency (stage 2).
    gain, phase : array (N,), optional
        ``|G|`` and ``phi``; default from ``G``.
    max_order : int
        Highest denominator degree tried.
    fit_delay : bool
        Also fit a pure delay ``tau >= 0``.
    orders : list of (n, m), optional
        Orders to try instead of all ``1 <= n <= max_order, 0 <= m < n``.
    """
    w = np.asarray(omega, float)
    G = np.asarray(G, complex)
    if w.ndim != 1 or G.shape != w.shape or np.any(w <= 0):
        raise ValueError("omega must be positive and match G")
    gain = np.abs(G) if gain is None else np.asarray(gain, float)
    phase = -np.angle(G) if phase is None else np.asarray(phase, float)
    Cri = reim_covariance(gain, phase, cov)
    if not np.all(np.isfinite(Cri)):
        raise HwidError("the frequency-response estimates have non-finite uncertainties")
    W = _whiteners(Cri)
    w_ref = float(np.exp(np.mean(np.log(w))))
    s = 1j * w / w_ref
    N2 = 2 * w.size
    cands = []
    fits = []
    if orders is None:
        orders = [(n, m) for n in range(1, max_order + 1) for m in range(n)]
    for n, m in orders:
        k = n + m + (1 if fit_delay else 0)
        if N2 - k < 1:
            continue
        tau0 = _delay_start(s, G, n, m, w / w_ref) if fit_delay else 0.0
        r = _fit_one(s, G, W, n, m, fit_delay, tau0)
        if r is None:
            continue
        x, chi2, J = r
        poles = _poles_scaled(x[:n]) * w_ref
        zeros = _poles_scaled(x[n:n + m]) * w_ref if m else np.zeros(0)
        stable = bool(np.all(poles.real < 0)) and (not fit_delay or x[n + m] >= 0)
        # a pole or zero a decade below the lowest frequency is not identified by the data: with
        # G(0) = 1 it is a near-cancelling pair (or a gain step) far below the band, an artefact
        # of an order too high that a simulation would turn into a slow creep
        slow = bool(np.any(np.abs(np.concatenate([poles, zeros])) < w.min() / 10))
        crit = chi2 + 2 * k + 2 * k * (k + 1) / (N2 - k - 1) if N2 - k - 1 > 0 else np.inf   # AICc
        cands.append({"n": n, "m": m, "chi2": chi2, "aicc": float(crit), "stable": stable,
                      "below_band": slow})
        if stable:
            fits.append((crit, n, m, x, chi2, J, slow))
    if not fits:
        raise HwidError("no stable rational model fits the frequency response (try a lower max_order "
                        "or more frequencies)")
    inband = [f for f in fits if not f[6]]
    crit, n, m, x, chi2, J, _ = min(inband or fits, key=lambda f: f[0])
    try:
        cov_x = np.linalg.inv(J.T @ J)
    except np.linalg.LinAlgError:
        cov_x = np.full((J.shape[1],) * 2, np.inf)
    # back to the unscaled variable: a_i -> a_i / w_ref^i
    sa = w_ref ** -np.arange(1, n + 1)
    sb = w_ref ** -np.arange(1, m + 1)
    a, b = x[:n] * sa, x[n:n + m] * sb
    scale = np.concatenate([sa, sb, [1.0 / w_ref] if fit_delay else []])
    cov_u = cov_x * np.outer(scale, scale)
    tau = float(x[n + m] / w_ref) if fit_delay else 0.0
    tau_se = float(np.sqrt(cov_u[-1, -1])) if fit_delay else 0.0
    poles, pc = _pole_covariance(a, cov_u[:n, :n])
    Ap = np.concatenate([[1.0], a])
    den = Ap[::-1] / Ap[-1]
    num = np.concatenate([[1.0], b])[::-1] / Ap[-1]
    warns = []
    dof = N2 - (n + m + (1 if fit_delay else 0))
    p_fit = float(special.chdtrc(dof, chi2))
    if p_fit < 1e-3:
        warns.append(f"parametric fit: the best model (n={n}, m={m}) leaves chi2 = {chi2:.3g} on {dof} dof "
                     f"(p = {p_fit:.2g}); it does not explain G_hat within its uncertainties")
    return RationalFit(num, den, tau, tau_se, poles, pc, chi2, dof, (n, m), float(crit), tuple(cands),
                       tuple(warns), confidence)
