"""Output nonlinearity h (eq. 3c): a polynomial, or piecewise polynomial over subintervals."""
from __future__ import annotations

from dataclasses import dataclass

import numpy as np


@dataclass(frozen=True)
class PolynomialH:
    """``h(w) = sum_i c_i w^i`` (ascending powers, as in the config's ``polynomial``)."""

    coefficients: tuple[float, ...]

    def __call__(self, w):
        return np.polynomial.polynomial.polyval(np.asarray(w, dtype=float), self.coefficients)

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
                out[m] = np.polynomial.polynomial.polyval(w[m], c)
        return out

    def scaled(self, k: float) -> "PiecewiseH":
        pieces = tuple(tuple(float(x) for x in np.asarray(c) * k ** np.arange(len(c))) for c in self.pieces)
        return PiecewiseH(tuple(float(b) / k for b in self.breaks), pieces)

    def to_dict(self) -> dict:
        return {"breaks": list(self.breaks), "pieces": [list(c) for c in self.pieces]}
