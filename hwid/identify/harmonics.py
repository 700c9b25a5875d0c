"""Harmonic analysis of the steady-state sine response (paper Section 5, eqs. 18-28).

Two halves:

* **The harmonic model** of eq. (20) for *any* polynomial ``h`` (not the p = 5 formulas of eq. 35):
  with ``w(t) = r sin(omega t - phi)`` (eq. 17, ``r = U |G(j omega)|``) and ``alpha = omega t - phi``,
  ``h(w) = sum_k Im(D_k(r) e^{j k alpha})`` where ``D_k(r) = sum_i c_i r^i M[i, k]`` and ``M`` is the
  exact binomial expansion of ``sin^i`` (the power formulas 19a-b). Referred to the input's time
  origin the complex Fourier coefficient of harmonic ``k`` is ``C_k = D_k(r) e^{-j k phi}``, i.e.
  ``A_k = |D_k(r)|`` and ``beta_k = arg D_k(r) - k phi`` in eq. (20).
* **Harmonic least squares** (eqs. 23-26 without their restriction to an integer number of samples
  per period): the coefficients of ``1, cos(k omega t), sin(k omega t)`` are fitted by least squares at
  the exact frequencies ``k omega``, accumulating the normal equations period by period (the paper
  config has 3.1e6 samples at 0.01 rad/s), so no FFT bin leaks. With ``T/dt`` an integer this equals
  the period averaging of eq. (23) followed by eqs. (26a-e).

Convention: the complex coefficient of harmonic ``k`` is ``C_k = b_k + j a_k`` for the fitted
``a_k cos(k omega t) + b_k sin(k omega t)``, so ``a_k cos + b_k sin = s_k sin(k omega t + psi_k)`` with
``s_k = |C_k|`` and ``psi_k = arg C_k`` exactly as eqs. (26a-b).
"""
from __future__ import annotations

from dataclasses import dataclass, field
from functools import lru_cache
from math import comb

import numpy as np
from numba import njit
from scipy import special

from hwid.blocks.static import polyval


# ------------------------------------------------------------------------------------ harmonic model

def sine_power_matrix(degree: int) -> np.ndarray:
    """``M[i, k]`` with ``sin^i(a) = M[i, 0] + sum_{k>=1} Im(M[i, k] e^{j k a})``, eqs. (19a-b).

    ``M[i, k]`` is real for odd ``i`` (odd powers hold only sines, eq. 19b) and purely imaginary for
    even ``i`` and ``k >= 1`` (even powers hold only cosines, eq. 19a).

    Parameters
    ----------
    degree : int
        Highest power ``p``; the matrix is ``(p + 1) x (p + 1)`` (harmonics ``0..p``).
    """
    return _sine_power_matrix(int(degree)).copy()


@lru_cache(maxsize=64)
def _sine_power_matrix(degree: int) -> np.ndarray:
    """:func:`sine_power_matrix`, computed once per degree (read only: the cached array is shared)."""
    p = int(degree)
    if p < 0:
        raise ValueError("degree must be >= 0")
    M = np.zeros((p + 1, p + 1), dtype=complex)
    for i in range(p + 1):
        scale = (2j) ** (-i)
        for m in range(i + 1):
            n = 2 * m - i                     # exponent of e^{j n a}
            e = scale * comb(i, m) * (-1) ** (i - m)
            if n == 0:
                M[i, 0] += e.real
            elif n > 0:
                M[i, n] += 2j * e             # e_n e^{jna} + conj(e_n) e^{-jna} = Im(2j e_n e^{jna})
    M.flags.writeable = False
    return M


@dataclass(frozen=True)
class HarmonicModel:
    """The harmonics of ``h(r sin(omega t - phi))`` (eq. 20) for a polynomial ``h``.

    Parameters
    ----------
    h_coefficients : sequence of float
        ``c_0, ..., c_p`` of ``h``, ascending powers (eq. 18).
    """

    h_coefficients: tuple[float, ...]
    _M: np.ndarray = field(init=False, repr=False, compare=False)

    def __post_init__(self):
        c = tuple(float(x) for x in self.h_coefficients)
        if not c or not np.all(np.isfinite(c)):
            raise ValueError("h_coefficients must be a non-empty sequence of finite numbers")
        object.__setattr__(self, "h_coefficients", c)
        object.__setattr__(self, "_M", _sine_power_matrix(len(c) - 1))      # shared, read only

    @property
    def degree(self) -> int:
        return len(self.h_coefficients) - 1

    def relevant(self) -> np.ndarray:
        """Harmonics ``k >= 1`` whose coefficient ``D_k(r)`` is not identically zero."""
        c = np.asarray(self.h_coefficients)
        nz = (np.abs(c[:, None] * self._M) > 0).any(axis=0)
        return np.flatnonzero(nz[1:]) + 1

    def poly(self, k: int) -> np.ndarray:
        """Complex coefficients (ascending powers of r) of ``D_k(r)``."""
        k = int(k)
        if k > self.degree:
            return np.zeros(1, dtype=complex)
        return np.asarray(self.h_coefficients) * self._M[:, k]

    def D(self, r, ks) -> np.ndarray:
        """``D_k(r)`` for each ``k`` in ``ks`` (shape ``r.shape + (len(ks),)``)."""
        r = np.asarray(r, float)
        ks = np.atleast_1d(ks)
        out = np.zeros(r.shape + (ks.size,), dtype=complex)
        for j, k in enumerate(ks):
            out[..., j] = np.polynomial.polynomial.polyval(r, self.poly(k)) if k <= self.degree else 0.0
        return out

    def dD(self, r, ks) -> np.ndarray:
        """``d D_k / d r``."""
        r = np.asarray(r, float)
        ks = np.atleast_1d(ks)
        out = np.zeros(r.shape + (ks.size,), dtype=complex)
        for j, k in enumerate(ks):
            if k <= self.degree:
                out[..., j] = np.polynomial.polynomial.polyval(r, np.polynomial.polynomial.polyder(self.poly(k)))
        return out

    def coefficients(self, r: float, phi: float, ks) -> np.ndarray:
        """Complex Fourier coefficients ``C_k = D_k(r) e^{-j k phi}`` of ``h(r sin(omega t - phi))``."""
        ks = np.atleast_1d(ks)
        return self.D(r, ks) * np.exp(-1j * ks * phi)

    def amplitudes_phases(self, gain: float, phase: float, amplitude: float = 1.0, ks=None):
        """``A_k`` and ``beta_k`` of eq. (20) for ``|G| = gain``, ``phi = phase`` and ``U = amplitude``.

        Returns ``(ks, A, beta)``; ``x(t) = A_0 + sum_{k>=1} A_k sin(k omega t + beta_k)`` (``A_0`` is
        the signed mean, eq. 35e).
        """
        ks = np.arange(self.degree + 1) if ks is None else np.atleast_1d(ks)
        r = amplitude * gain
        D = self.D(r, ks)
        A = np.abs(D)
        beta = np.angle(D) - ks * phase
        dc = ks == 0
        A = np.where(dc, D.real, A)
        beta = np.where(dc, 0.0, beta)
        return ks, A, beta


class DistortedHarmonics:
    """The harmonic model of eq. (20) with a distorted input, evaluated numerically: the harmonics
    ``C_k`` of ``h(r sin(theta - phi) + d(theta))`` and their derivatives in ``r`` and ``phi``, by
    the FFT of one period of ``M`` points (``d = W_0 + sum_{k>=2} Im(W_k e^{j k theta})``: the
    input distortion). The grid, ``d`` and ``h'`` are prepared once; each call costs two
    polynomial evaluations and one real FFT of three rows (the same operations, value for value, as
    a fresh evaluation)."""

    def __init__(self, hm: HarmonicModel, W, ks, M: int | None = None):
        W = np.asarray(W, complex)
        self.ks = np.asarray(ks)
        if M is None:
            M = 1 << int(np.ceil(np.log2(8 * max(hm.degree, 1) * max(len(W), int(self.ks.max()) + 1))))
        self.M = M
        self.th = 2 * np.pi * np.arange(M) / M
        d = np.full(M, float(np.real(W[0])))
        E = _rotations(M, len(W))
        for k in range(2, len(W)):
            d += np.imag(W[k] * E[k])
        self.d = d
        self.c = np.asarray(hm.h_coefficients, float)
        self.dc = np.polynomial.polynomial.polyder(self.c)

    def __call__(self, r: float, phi: float):
        sn, cs = np.sin(self.th - phi), np.cos(self.th - phi)
        w = r * sn + self.d
        x = polyval(w, self.c)
        hp = polyval(w, self.dc)
        F = np.fft.rfft(np.stack([x, hp * sn, -hp * r * cs]), axis=1)[:, self.ks] / self.M
        C = -2 * F.imag + 2j * F.real
        return C[0], C[1], C[2]


@lru_cache(maxsize=16)
def _rotations(M: int, K: int) -> np.ndarray:
    """``e^{j k theta}`` on the grid ``theta = 2 pi m / M``, rows ``k = 0..K-1`` (read only)."""
    th = 2 * np.pi * np.arange(M) / M
    E = np.array([np.exp(1j * k * th) for k in range(K)])
    E.flags.writeable = False
    return E


def distorted_harmonics(hm: HarmonicModel, r: float, phi: float, W, ks, M: int | None = None):
    """Harmonics ``C_k`` of ``h(r sin(theta - phi) + d(theta))`` and their derivatives in ``r`` and ``phi``,
    by the FFT of one period (``d = W_0 + sum_{k>=2} Im(W_k e^{j k theta})``: the input distortion)."""
    return DistortedHarmonics(hm, W, ks, M)(r, phi)


# ------------------------------------------------------------------------------- harmonic least squares

@dataclass(frozen=True)
class PeriodSums:
    """Normal equations of the harmonic regression, one set per whole period of the record.

    Regressors ``[1, cos(omega t), ..., cos(K omega t), sin(omega t), ..., sin(K omega t)]`` at the
    sample times ``t = n dt`` (absolute, so phases refer to the input's ``t = 0``). Period ``p`` holds
    the samples with ``p T <= t < (p + 1) T``."""

    omega: float
    dt: float
    k_max: int
    XtX: np.ndarray      # (P, m, m)
    Xty: np.ndarray      # (P, m)
    yty: np.ndarray      # (P,)
    n: np.ndarray        # (P,) samples per period

    @property
    def periods(self) -> int:
        return self.n.size


def _design(t: np.ndarray, omega: float, k_max: int) -> np.ndarray:
    """Regressors ``[1, cos(k omega t), sin(k omega t)]`` (eq. 23's model) as a dense matrix (tests,
    small records; :func:`period_sums` never forms it)."""
    t = np.asarray(t, float)
    X = np.empty((t.size, 2 * k_max + 1))
    X[:, 0] = 1.0
    for k in range(1, k_max + 1):
        X[:, k] = np.cos(k * omega * t)
        X[:, k_max + k] = np.sin(k * omega * t)
    return X


@njit(cache=True, fastmath={"reassoc", "contract"})
def _harmonic_sums(y, bounds, omega, dt, k_max, block, offset=0):
    """``sum y_n cos(k omega t_n)``, ``sum y_n sin(k omega t_n)`` (k = 1..K), ``sum y_n`` and
    ``sum y_n^2`` over each period ``[bounds[p], bounds[p + 1])`` in one pass over ``y``, with
    ``t_n = (n + offset) dt``.

    Rotation in blocks: ``e^{jk omega t_{n0 + m}} = e^{jk omega t_{n0}} e^{jk omega m dt}``; the
    second factor is one table of ``K x block`` values for the whole record, the first one value per
    block and harmonic, so every sample costs 2K multiply-adds (vectorised: the sums may be
    reassociated) and no exp, and no rounding error accumulates along the record (both factors are
    evaluated directly)."""
    P = bounds.shape[0] - 1
    K = k_max
    tc = np.empty((K, block))
    ts = np.empty((K, block))
    for k in range(K):
        for m in range(block):
            a = (k + 1) * omega * (m * dt)
            tc[k, m] = np.cos(a)
            ts[k, m] = np.sin(a)
    C = np.zeros((P, K))
    S = np.zeros((P, K))
    s1 = np.zeros(P)
    s2 = np.zeros(P)
    for p in range(P):
        for n0 in range(bounds[p], bounds[p + 1], block):
            L = min(block, bounds[p + 1] - n0)
            yb = y[n0:n0 + L]
            t1 = 0.0
            t2 = 0.0
            for m in range(L):
                t1 += yb[m]
                t2 += yb[m] * yb[m]
            for k in range(K):
                ac = 0.0
                asn = 0.0
                tck = tc[k]
                tsk = ts[k]
                for m in range(L):
                    ac += yb[m] * tck[m]
                    asn += yb[m] * tsk[m]
                a = (k + 1) * omega * ((n0 + offset) * dt)
                c, s = np.cos(a), np.sin(a)
                C[p, k] += c * ac - s * asn
                S[p, k] += s * ac + c * asn
            s1[p] += t1
            s2[p] += t2
    return C, S, s1, s2


def harmonic_gram(bounds: np.ndarray, omega: float, dt: float, k_max: int) -> np.ndarray:
    """``X^T X`` of the regressors ``[1, cos(k omega t), sin(k omega t)]`` over each period
    ``[bounds[p], bounds[p + 1])`` of samples ``t_n = n dt``, in closed form, shape ``(P, m, m)``.

    It does not depend on the data: with ``S_q = sum_n e^{jq omega t_n}`` (a geometric sum,
    ``e^{jq omega dt (a + b - 1)/2} sin(q omega dt N / 2) / sin(q omega dt / 2)`` over ``N = b - a``
    samples), ``sum cos k cos l = Re(S_{k-l} + S_{k+l}) / 2``, ``sum sin k sin l = Re(S_{k-l} -
    S_{k+l}) / 2`` and ``sum cos k sin l = Im(S_{k+l} + S_{l-k}) / 2``."""
    bounds = np.asarray(bounds, np.int64)
    a, b = bounds[:-1].astype(float), bounds[1:].astype(float)
    N = b - a
    K = int(k_max)
    q = np.arange(1, 2 * K + 1, dtype=float)
    half = 0.5 * q * omega * dt                                              # (2K,)
    ratio = np.sin(half[None, :] * N[:, None]) / np.sin(half)[None, :]      # (P, 2K)
    ang = q[None, :] * omega * (0.5 * (a + b - 1.0) * dt)[:, None]
    Sq = np.empty((N.size, 2 * K + 1), complex)
    Sq[:, 0] = N
    Sq[:, 1:] = ratio * np.exp(1j * ang)
    k = np.arange(1, K + 1)
    d = np.abs(k[:, None] - k[None, :])                                      # |k - l|
    s = k[:, None] + k[None, :]                                              # k + l
    sign = np.sign(k[None, :] - k[:, None])                                  # sign(l - k)
    m = 2 * K + 1
    G = np.empty((N.size, m, m))
    G[:, 0, 0] = N
    G[:, 0, 1:K + 1] = G[:, 1:K + 1, 0] = Sq[:, 1:K + 1].real
    G[:, 0, K + 1:] = G[:, K + 1:, 0] = Sq[:, 1:K + 1].imag
    G[:, 1:K + 1, 1:K + 1] = 0.5 * (Sq[:, d].real + Sq[:, s].real)
    G[:, K + 1:, K + 1:] = 0.5 * (Sq[:, d].real - Sq[:, s].real)
    cs = 0.5 * (Sq[:, s].imag + sign * Sq[:, d].imag)                       # rows cos k, columns sin l
    G[:, 1:K + 1, K + 1:] = cs
    G[:, K + 1:, 1:K + 1] = np.swapaxes(cs, 1, 2)
    return G


def span_projector(start: int, stop: int, omega: float, dt: float, k_max: int):
    """Least-squares harmonic coefficients over samples ``start..stop-1`` (``t_n = n dt``) as a
    function of the data: returns ``fit(v) -> [dc, a_1..a_K, b_1..b_K]`` for ``v`` of length
    ``stop - start``, equal to ``pinv(X) @ v`` but without forming ``X`` (the Gram matrix is
    factorised once, ``X^T v`` is one pass of :func:`_harmonic_sums`)."""
    from scipy.linalg import LinAlgError, cho_factor, cho_solve
    K = int(k_max)
    G = harmonic_gram(np.array([start, stop]), float(omega), float(dt), K)[0]
    try:
        cf = cho_factor(G)
    except LinAlgError:              # a harmonic at Nyquist or too few samples: the pseudo-inverse
        P = np.linalg.pinv(_design(np.arange(start, stop) * dt, omega, K))
        return lambda v: P @ np.asarray(v, float)
    bounds = np.array([0, stop - start], np.int64)

    def fit(v):
        v = np.ascontiguousarray(v, dtype=float)
        if v.size != stop - start:
            raise ValueError(f"expected {stop - start} samples, got {v.size}")
        C, S, s1, _ = _harmonic_sums(v, bounds, float(omega), float(dt), K, 512, int(start))
        return cho_solve(cf, np.concatenate([s1, C[0], S[0]]))

    return fit


def period_sums(y, dt: float, omega: float, k_max: int, block: int = 512) -> PeriodSums:
    """Accumulate the harmonic normal equations per whole period of ``y`` (eqs. 23-26, LS form).

    ``X^T y`` and ``y^T y`` come from one pass over ``y`` (:func:`_harmonic_sums`, no design
    matrix is formed), ``X^T X`` in closed form (:func:`harmonic_gram`).

    Parameters
    ----------
    y : array_like
        The measured output, sampled at ``t = n dt`` from the start of the sine (eq. 22).
    dt : float
        Sample time, s.
    omega : float
        Fundamental frequency of the input, rad/s.
    k_max : int
        Highest harmonic fitted (capped by the caller below Nyquist).
    block : int
        Samples per block of the rotation (size of the kernel's table).
    """
    y = np.ascontiguousarray(y, dtype=float)
    T = 2 * np.pi / omega
    n_tot = y.size
    P = int(np.floor(n_tot * dt / T + 1e-9))
    if P < 1:
        raise ValueError(f"the record holds less than one period of {T:g} s")
    # first sample of each period: ceil(p T / dt)
    bounds = np.ceil(np.arange(P + 1) * T / dt - 1e-9).astype(np.int64)
    bounds[-1] = min(bounds[-1], n_tot)
    k_max = int(k_max)
    C, S, s1, s2 = _harmonic_sums(y, bounds, float(omega), float(dt), k_max, int(block))
    Xty = np.concatenate([s1[:, None], C, S], axis=1)
    XtX = harmonic_gram(bounds, float(omega), float(dt), k_max)
    return PeriodSums(float(omega), float(dt), k_max, XtX, Xty, s2, np.diff(bounds))


def _complex(theta: np.ndarray, k_max: int) -> np.ndarray:
    """``C_k = b_k + j a_k`` for ``k = 1..K`` from ``[dc, a_1..a_K, b_1..b_K]``."""
    return theta[..., k_max + 1:] + 1j * theta[..., 1:k_max + 1]


@dataclass(frozen=True)
class HarmonicFit:
    """Least-squares harmonic coefficients of the steady-state response over whole periods.

    Attributes
    ----------
    ks : array of int
        Harmonics ``1..K``.
    coef : complex array
        ``C_k = s_k e^{j psi_k}`` (eqs. 26a-b).
    var : array
        Variance of each real component (Re and Im) of ``C_k``, per harmonic.
    dc, dc_var : float
        The mean ``s_0`` (eq. 26c) and its variance.
    noise_model : str
        ``"white"`` (variances from the residual sample variance) or ``"periodic"`` (from the spread
        of the per-period estimates, honest for coloured noise).
    dof : float
        Degrees of freedom of the variance estimate (``inf`` for white).
    sigma : float
        Residual standard deviation (white-noise estimate).
    first_period, periods, n_samples : int
        The periods used (after the steady-state check) and their number of samples.
    periodicity_p : float
        p-value of the test "first half of the used periods == second half".
    steady_p : float
        p-value of the test of the first used period against the late periods.
    white_p : float
        p-value of the whiteness check that chose ``noise_model``.
    block_coef : complex array (periods, K)
        Per-period estimates (for diagnostics and the Fig. 15 overlay).
    """

    omega: float
    ks: np.ndarray
    coef: np.ndarray
    var: np.ndarray
    dc: float
    dc_var: float
    noise_model: str
    dof: float
    sigma: float
    first_period: int
    periods: int
    n_samples: int
    periodicity_p: float
    steady_p: float
    white_p: float
    var_white: np.ndarray
    var_periodic: np.ndarray
    block_coef: np.ndarray = field(repr=False)

    @property
    def se(self) -> np.ndarray:
        return np.sqrt(self.var)

    @property
    def amplitude(self) -> np.ndarray:
        """``s_k``, eq. (26a)."""
        return np.abs(self.coef)

    @property
    def phase(self) -> np.ndarray:
        """``psi_k``, eq. (26b)."""
        return np.angle(self.coef)

    def significant(self, alpha: float = 1e-3) -> np.ndarray:
        """Harmonics whose amplitude is detectably nonzero (``|C_k|^2 / var_k`` against chi^2_2)."""
        stat = np.abs(self.coef) ** 2 / self.var
        return self.ks[stat > 2 * special.fdtri(2, self.dof if np.isfinite(self.dof) else 1e9, 1 - alpha)]

    def to_dict(self) -> dict:
        return {"omega": self.omega, "ks": self.ks.astype(float), "coef_re": self.coef.real,
                "coef_im": self.coef.imag, "var": self.var, "dc": self.dc, "dc_var": self.dc_var,
                "noise_model": self.noise_model, "dof": float(self.dof), "sigma": self.sigma,
                "first_period": self.first_period, "periods": self.periods, "n_samples": self.n_samples,
                "periodicity_p": self.periodicity_p, "steady_p": self.steady_p, "white_p": self.white_p,
                "var_white": self.var_white, "var_periodic": self.var_periodic,
                "block_coef_re": self.block_coef.real, "block_coef_im": self.block_coef.imag}

    @classmethod
    def from_dict(cls, d: dict) -> "HarmonicFit":
        return cls(float(d["omega"]), np.asarray(d["ks"]).astype(int),
                   np.asarray(d["coef_re"]) + 1j * np.asarray(d["coef_im"]), np.asarray(d["var"]),
                   float(d["dc"]), float(d["dc_var"]), str(d["noise_model"]), float(d["dof"]),
                   float(d["sigma"]), int(d["first_period"]), int(d["periods"]), int(d["n_samples"]),
                   float(d["periodicity_p"]), float(d["steady_p"]), float(d["white_p"]),
                   np.asarray(d["var_white"]), np.asarray(d["var_periodic"]),
                   np.asarray(d["block_coef_re"]) + 1j * np.asarray(d["block_coef_im"]))


def _solve(XtX, Xty):
    return np.linalg.solve(XtX, Xty[..., None])[..., 0]


def _component_var(theta_blocks: np.ndarray, k_max: int) -> tuple[np.ndarray, float, int]:
    """Per-harmonic variance of one real component of a *single* block estimate, pooled over Re/Im."""
    B = theta_blocks.shape[0]
    d = theta_blocks - theta_blocks.mean(axis=0)
    ss = (d ** 2).sum(axis=0) / (B - 1)
    return 0.5 * (ss[1:k_max + 1] + ss[k_max + 1:]), float(ss[0]), B - 1


def _steady_start(theta_p, start: int, k_max: int, steady_alpha: float, min_periods: int) -> tuple[int, float]:
    """The first steady period from ``start`` on and its p-value: leading periods are dropped while
    their harmonic coefficients (``theta_p``, one row per period) differ from the late half's mean
    (an F test on all of them, level ``steady_alpha``)."""
    P, m = theta_p.shape[0], 2 * k_max + 1
    late = np.arange(max(start + 1, P - max((P - start) // 2, 1)), P)
    steady_p = 1.0
    if late.size >= 3:
        vk, v0, df_l = _component_var(theta_p[late], k_max)
        vfull = np.concatenate([[v0], vk, vk])
        vfull = np.where(vfull > 0, vfull, np.finfo(float).tiny)
        ref = theta_p[late].mean(axis=0)
        while True:
            stat = float(np.sum((theta_p[start] - ref) ** 2 / (vfull * (1 + 1 / late.size)))) / m
            steady_p = float(special.fdtrc(m, max(df_l * 2, 1), stat))
            if steady_p >= steady_alpha or P - (start + 1) < max(min_periods, late.size):
                break
            start += 1
    return start, steady_p


def _periodicity_p(S: PeriodSums, used, var, dc_var: float, dof: float) -> float:
    """Periodicity check: the first half of the ``used`` periods against the second half (F test on
    every coefficient with the variances ``var``, ``dc_var`` of their mean); 1 with fewer than 4."""
    Pu = used.size
    if Pu < 4:
        return 1.0
    m = S.XtX.shape[-1]
    h = Pu // 2
    t1 = np.linalg.solve(S.XtX[used[:h]].sum(0), S.Xty[used[:h]].sum(0))
    t2 = np.linalg.solve(S.XtX[used[h:]].sum(0), S.Xty[used[h:]].sum(0))
    vfull = np.concatenate([[dc_var], var, var]) * Pu * (1 / h + 1 / (Pu - h))
    vfull = np.where(vfull > 0, vfull, np.finfo(float).tiny)      # a noise-free signal
    stat = float(np.sum((t1 - t2) ** 2 / vfull)) / m
    return float(special.fdtrc(m, dof if np.isfinite(dof) else 1e9, stat))


def fit_harmonics(y, dt: float, omega: float, k_max: int, first_period: int = 0,
                  sums: PeriodSums | None = None, steady_alpha: float = 1e-3, white_alpha: float = 1e-3,
                  noise_model: str = "auto", min_periods: int = 2) -> HarmonicFit:
    """Harmonic coefficients of the steady-state response over whole periods (eqs. 23-26, LS form).

    Steady state: starting at ``first_period`` (the lead-in periods are discarded), the first
    remaining period is compared with the mean of the late half of the record (an F test on all
    harmonic coefficients, level ``steady_alpha``); while it differs it is dropped too. The remaining
    whole periods are fitted jointly; the first half of them is tested against the second half
    (``periodicity_p``, a warning sign when small).

    Standard errors: ``"white"`` uses ``sigma^2 (X^T X)^{-1}`` with the residual variance;
    ``"periodic"`` uses the spread of the per-period estimates (each harmonic gets the noise level
    near its own frequency, honest for coloured noise; Student-t with ``2(P - 1)`` degrees of
    freedom); ``"auto"`` uses white unless the per-harmonic spreads reject it (F test, level
    ``white_alpha``, Bonferroni over harmonics).

    Parameters
    ----------
    y : array_like
        Output samples from ``t = 0`` (the start of the sine, lead-in included).
    dt, omega : float
        Sample time (s) and fundamental (rad/s).
    k_max : int
        Highest harmonic fitted.
    first_period : int
        Periods to discard at least (the protocol's lead-in).
    """
    if noise_model not in ("auto", "white", "periodic"):
        raise ValueError(f"noise_model must be 'auto', 'white' or 'periodic', got {noise_model!r}")
    k_max = int(k_max)
    S = sums if sums is not None else period_sums(y, dt, omega, k_max)
    P = S.periods
    if P - first_period < 1:
        raise ValueError(f"no whole period left after {first_period} lead-in periods ({P} in the record)")
    theta_p = _solve(S.XtX, S.Xty)                       # per-period estimates (P, m)
    m = 2 * k_max + 1

    start, steady_p = _steady_start(theta_p, int(first_period), k_max, steady_alpha, min_periods)
    used = np.arange(start, P)
    Pu = used.size

    XtX = S.XtX[used].sum(axis=0)
    Xty = S.Xty[used].sum(axis=0)
    yty = S.yty[used].sum()
    n = int(S.n[used].sum())
    theta = np.linalg.solve(XtX, Xty)
    rss = max(float(yty - theta @ Xty), 0.0)
    sigma2 = rss / max(n - m, 1)
    inv = np.linalg.inv(XtX)
    d = np.diag(inv)
    var_white = sigma2 * 0.5 * (d[1:k_max + 1] + d[k_max + 1:])
    dc_var_white = sigma2 * d[0]

    # -- per-period spread: the variance of the mean of Pu periods
    white_p = 1.0
    if Pu >= 2:
        vk, v0, dfb = _component_var(theta_p[used], k_max)
        var_per = vk / Pu
        dc_var_per = v0 / Pu
        dfk = 2 * dfb
        # white hypothesis: var_per / var_white ~ chi2(dfk)/dfk
        ratio = var_per / np.where(var_white > 0, var_white, np.finfo(float).tiny)
        pv = 2 * np.minimum(special.chdtrc(dfk, ratio * dfk), special.chdtr(dfk, ratio * dfk))
        white_p = float(min(1.0, pv.min() * k_max))
    else:
        var_per, dc_var_per, dfk = var_white.copy(), dc_var_white, np.inf

    if noise_model == "white" or Pu < 2 or (noise_model == "auto" and white_p >= white_alpha):
        model, var, dc_var, dof = "white", var_white, dc_var_white, np.inf
    else:
        model, var, dc_var, dof = "periodic", var_per, dc_var_per, float(dfk)

    periodicity_p = _periodicity_p(S, used, var, dc_var, dof)

    return HarmonicFit(float(omega), np.arange(1, k_max + 1), _complex(theta, k_max), np.asarray(var),
                       float(theta[0]), float(dc_var), model, float(dof), float(np.sqrt(sigma2)), int(start),
                       int(Pu), n, periodicity_p, steady_p, white_p, np.asarray(var_white),
                       np.asarray(var_per), _complex(theta_p[used], k_max))
