"""Linear block G(s) (eq. 3b), simulated exactly for a zero-order-held input, with a pure delay.

The input ``v_k`` is held over ``[k dt, (k+1) dt)``. With ``G(s) = C (sI - A)^{-1} B + D`` and a delay
``tau = l dt + tau'`` (``0 <= tau' < dt``), the exact sampled state recursion is

    x_{k+1} = Phi x_k + Gamma1 v_{k-l} + Gamma0 v_{k-l-1},
    Phi = e^{A dt},  Gamma1 = int_0^{dt-tau'} e^{As} ds B,  Gamma0 = e^{A(dt-tau')} int_0^{tau'} e^{As} ds B,

and ``w_k = C x_k + D v(t_k - tau)``. The state starts at the equilibrium of the first input sample,
so a constant input gives ``w = G(0) v`` to machine precision from the first sample.
"""
from __future__ import annotations

from dataclasses import dataclass
from functools import lru_cache

import numpy as np
from numba import njit
from scipy import linalg


@njit(cache=True)
def _ss_run(v, Phi, G1, G0, C, D, x0, v_prev):
    n = v.shape[0]
    m = x0.shape[0]
    w = np.empty(n)
    x = x0.copy()
    xn = np.empty(m)
    vp = v_prev
    for k in range(n):
        acc = D * v[k]
        for i in range(m):
            acc += C[i] * x[i]
        w[k] = acc
        for i in range(m):
            s = G1[i] * v[k] + G0[i] * vp
            for j in range(m):
                s += Phi[i, j] * x[j]
            xn[i] = s
        for i in range(m):
            x[i] = xn[i]
        vp = v[k]
    return w


def _int_expm(A: np.ndarray, B: np.ndarray, h: float) -> tuple[np.ndarray, np.ndarray]:
    """Return ``(e^{Ah}, int_0^h e^{As} ds B)`` via the augmented matrix exponential."""
    n = A.shape[0]
    M = np.zeros((n + 1, n + 1))
    M[:n, :n] = A
    M[:n, n] = B
    E = linalg.expm(M * h)
    return E[:n, :n], E[:n, n]


@dataclass(frozen=True)
class LinearBlock:
    """``G(s) = num(s)/den(s) e^{-s delay}``, coefficients in descending powers of s."""

    num: tuple[float, ...]
    den: tuple[float, ...]
    delay: float = 0.0

    @property
    def dc_gain(self) -> float:
        """``G(0)``."""
        return float(self.num[-1] / self.den[-1])

    def normalised(self) -> "LinearBlock":
        """``G(s)/G(0)``, eq. (4b)."""
        g0 = self.dc_gain
        return LinearBlock(tuple(float(c) / g0 for c in self.num), tuple(float(c) for c in self.den),
                           self.delay)

    def freqresp(self, omega) -> np.ndarray:
        """``G(j omega)`` (complex)."""
        s = 1j * np.asarray(omega, dtype=float)
        return np.polyval(self.num, s) / np.polyval(self.den, s) * np.exp(-s * self.delay)

    def poles(self) -> np.ndarray:
        return np.roots(self.den)

    def simulate(self, v, dt: float, rest: float | None = None) -> np.ndarray:
        """Exact ZOH response to the samples ``v``, from the equilibrium of the input level ``rest``
        (default ``v[0]``): G at rest with ``w = G(0) rest`` and the delay line holding ``rest``."""
        v = np.ascontiguousarray(v, dtype=float)
        if v.size == 0:
            return v.copy()
        key = (tuple(map(float, self.num)), tuple(map(float, self.den)), float(self.delay), float(dt))
        n, lag, frac, Phi, G1, G0, C, D = discretise(*key)
        start = v[0] if rest is None else float(rest)
        if n == 0:  # static gain: w_k = D v(t_k - tau), the delay line holding ``start``
            vd = _delayed(v, lag + (frac != 0.0), start)
            return D * vd
        x0 = unit_rest(key[0], key[1]) * start
        if rest is not None:
            vd = _delayed(v, lag, start) if lag else v
            w = _ss_run(vd, Phi, G1, G0, C, D if frac == 0.0 else 0.0, x0, start)
            if frac != 0.0 and D != 0.0:
                w = w + D * np.concatenate([[start], vd[:-1]])
            return w
        vd = _delayed(v, lag, v[0]) if lag else v
        if frac == 0.0:
            return _ss_run(vd, Phi, G1, G0, C, D, x0, vd[0])
        w = _ss_run(vd, Phi, G1, G0, C, 0.0, x0, vd[0])
        if D != 0.0:
            w = w + D * np.concatenate([[vd[0]], vd[:-1]])
        return w


def _tf2ss(num: tuple, den: tuple):
    """The controllable canonical form of a proper ``num/den`` (scipy's ``tf2ss`` convention,
    without its per-call overhead, which dominated the whole fit's residual): ``(A, B, C, D)``
    with ``B`` and ``C`` as vectors; a static gain has no state (``A`` is 0 x 0)."""
    den = np.asarray(den, float)
    num = np.asarray(num, float)
    nz = np.flatnonzero(den)
    if nz.size == 0:
        raise ValueError("G's denominator is zero")
    den = den[nz[0]:]
    num = num[np.flatnonzero(num)[0]:] if np.any(num) else np.zeros(1)
    if num.size > den.size:
        raise ValueError("G(s) must be proper: the numerator's degree exceeds the denominator's")
    num, den = num / den[0], den / den[0]
    n = den.size - 1
    num = np.concatenate([np.zeros(n + 1 - num.size), num])
    D = float(num[0])
    if n == 0:
        return np.zeros((0, 0)), np.zeros(0), np.zeros(0), D
    A = np.zeros((n, n))
    A[0, :] = -den[1:]
    A[1:, :-1] = np.eye(n - 1)
    B = np.zeros(n)
    B[0] = 1.0
    C = np.ascontiguousarray(num[1:] - D * den[1:])
    return A, B, C, D


def _delayed(v: np.ndarray, lag: int, start: float) -> np.ndarray:
    """``v`` delayed by ``lag`` samples, the delay line holding ``start``: as long as ``v`` (all
    ``start`` when ``lag >= len(v)``)."""
    k = min(lag, v.size)
    return np.concatenate([np.full(k, start), v[: v.size - k]])


@lru_cache(maxsize=256)
def unit_rest(num: tuple, den: tuple) -> np.ndarray:
    """The recursion's state at rest under a unit input, cached (a fit simulates one G on every
    record: solving it each time cost as much as the simulation). It depends on G alone, not on
    the step or the delay.

    The fixed point of ``x = Phi x + (Gamma1 + Gamma0)`` is the continuous state at rest,
    ``-A^-1 B``, solved from ``A`` rather than ``I - Phi``: a pole within 1e-16/dt of zero (a G
    identified from sines the plant did not follow, ``1.5e-15/(s + 1.5e-15)``) rounds ``Phi`` to 1
    and ``I - Phi`` to singular, while ``A`` keeps it. A pole exactly at zero (an integrator) has no
    rest state: its state starts at zero (least squares)."""
    A, B, _, _ = _tf2ss(num, den)
    if A.shape[0] == 0:
        return np.zeros(0)
    try:
        x = np.linalg.solve(A, -B)
    except np.linalg.LinAlgError:
        x = np.linalg.lstsq(A, -B, rcond=None)[0]
    return np.ascontiguousarray(x)


@lru_cache(maxsize=256)
def discretise(num: tuple, den: tuple, delay: float, dt: float):
    """The exact sampled recursion of the module docstring, cached (fits simulate one G many times).

    Returns ``(n, lag, frac, Phi, Gamma1, Gamma0, C, D)``."""
    A, B, C, D = _tf2ss(num, den)
    n = A.shape[0]
    lag = int(np.floor(delay / dt + 1e-12))
    frac = delay - lag * dt
    if frac < 1e-12 * dt:
        frac = 0.0
    if n == 0:
        return n, lag, frac, None, None, None, np.zeros(0), D
    A = np.ascontiguousarray(A)
    Phi, Gfull = _int_expm(A, B, dt)
    if frac == 0.0:
        G1, G0 = Gfull, np.zeros(n)
    else:
        P1, G1 = _int_expm(A, B, dt - frac)
        _, Gf = _int_expm(A, B, frac)
        G0 = P1 @ Gf
    return n, lag, frac, np.ascontiguousarray(Phi), np.ascontiguousarray(G1), np.ascontiguousarray(G0), C, D
