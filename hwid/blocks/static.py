"""Output nonlinearity h (eq. 3c): a polynomial, or piecewise polynomial over subintervals."""
from __future__ import annotations

from dataclasses import dataclass

import numpy as np
from numba import njit


@njit(cache=True)
def horner_into(w, c, out):
    """``out = sum_i c_i w^i`` by Horner's rule, the inner loop over the samples (SIMD); called on
    blocks of a few thousand samples, which stay in the L1 cache over the passes."""
    m = c.shape[0]
    n = w.shape[0]
    for k in range(n):
        out[k] = c[m - 1]
    for i in range(m - 2, -1, -1):
        ci = c[i]
        for k in range(n):
            out[k] = out[k] * w[k] + ci


@njit(cache=True)
def _horner(w, c):
    n = w.shape[0]
    out = np.empty(n)
    for s in range(0, n, 2048):
        e = min(s + 2048, n)
        horner_into(w[s:e], c, out[s:e])
    return out


def polyval(w, coefficients) -> np.ndarray:
    """``sum_i c_i w^i`` (ascending powers) by Horner's rule, any array shape."""
    w = np.asarray(w, dtype=float)
    c = np.ascontiguousarray(coefficients, dtype=float)
    return _horner(np.ascontiguousarray(w.ravel()), c).reshape(w.shape)


@njit(cache=True)
def _legendre_rows(x, degree, out):
    n = x.shape[0]
    for k in range(n):
        out[0, k] = 1.0
    if degree > 0:
        for k in range(n):
            out[1, k] = x[k]
    for i in range(2, degree + 1):
        a, b = 2.0 * i - 1.0, i - 1.0
        for k in range(n):
            out[i, k] = (out[i - 1, k] * x[k] * a - out[i - 2, k] * b) / i


def legendre_vander(x, degree: int) -> np.ndarray:
    """The Legendre polynomials ``P_0 .. P_degree`` at ``x`` (in [-1, 1]), one column each: the
    numbers of ``numpy.polynomial.legendre.legvander`` (Bonnet's recursion, the same operations in
    the same order), each polynomial in one vectorised pass over the samples."""
    x = np.ascontiguousarray(x, dtype=float).ravel()
    out = np.empty((int(degree) + 1, x.size))
    _legendre_rows(x, int(degree), out)
    return out.T


@dataclass(frozen=True)
class PolynomialH:
    """``h(w) = sum_i c_i w^i`` (ascending powers, as in the config's ``polynomial``)."""

    coefficients: tuple[float, ...]

    def __call__(self, w):
        return polyval(w, self.coefficients)

    def scaled(self, k: float) -> "PolynomialH":
        """``w -> h(k w)``, as in eq. (4c)."""
        c = np.asarray(self.coefficients) * k ** np.arange(len(self.coefficients))
        return PolynomialH(tuple(float(x) for x in c))

    def to_dict(self) -> dict:
        return {"polynomial": list(self.coefficients)}


@dataclass(frozen=True)
class PiecewiseH:
    """Piecewise polynomial h: piece i applies on ``[breaks[i], breaks[i+1])``; the first and last
    pieces extend to -inf / +inf. Each piece has its own degree and coefficients (paper Section 1)."""

    breaks: tuple[float, ...]          # interior breakpoints, increasing, len = n_pieces - 1
    pieces: tuple[tuple[float, ...], ...]

    def __call__(self, w):
        w = np.asarray(w, dtype=float)
        idx = np.searchsorted(np.asarray(self.breaks), w, side="right")
        out = np.empty_like(w)
        for i, c in enumerate(self.pieces):
            m = idx == i
            if np.any(m):
                out[m] = polyval(w[m], c)
        return out

    def scaled(self, k: float) -> "PiecewiseH":
        pieces = tuple(tuple(float(x) for x in np.asarray(c) * k ** np.arange(len(c))) for c in self.pieces)
        return PiecewiseH(tuple(float(b) / k for b in self.breaks), pieces)

    def to_dict(self) -> dict:
        return {"breaks": list(self.breaks), "pieces": [list(c) for c in self.pieces]}
