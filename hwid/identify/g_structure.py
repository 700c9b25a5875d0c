"""G of the whole-model fit (:mod:`hwid.identify.whole`) as a product of unit-gain factors, so every
G tried is stable with ``G(0) = 1``:

* a real pole ``a / (s + a)`` (``log a``),
* a pole pair ``wn^2 / (s^2 + 2 zeta wn s + wn^2)`` (``log wn``, ``log zeta``),
* a real zero ``tau s + 1`` (``tau`` any sign: a right-half-plane zero is allowed).

:class:`Structure` counts the factors; :func:`g_from_params` builds G from their parameters,
:func:`g_params_from` starts them from a given G, :func:`structure_of` reads a G's structure.
"""
from __future__ import annotations

from dataclasses import dataclass
from typing import Sequence

import numpy as np

from hwid.blocks.linear import LinearBlock


@dataclass(frozen=True)
class Structure:
    """G's factors: ``poles`` real poles, ``pairs`` pole pairs, ``zeros`` real zeros."""

    poles: int
    pairs: int
    zeros: int = 0

    @property
    def n_params(self) -> int:
        return self.poles + 2 * self.pairs + self.zeros

    @property
    def order(self) -> int:
        return self.poles + 2 * self.pairs

    def __str__(self) -> str:
        return f"{self.poles}p{self.pairs}q{self.zeros}z"


#: structures tried when no start says otherwise: orders 1-3, with or without a zero
STRUCTURES = (Structure(1, 0), Structure(2, 0), Structure(0, 1), Structure(2, 0, 1), Structure(0, 1, 1),
              Structure(1, 1), Structure(3, 0))


def g_from_params(structure: Structure, p: Sequence[float], delay: float = 0.0) -> LinearBlock:
    """The unit-gain G(s) of ``structure`` with factor parameters ``p`` (module docstring)."""
    num, den = np.array([1.0]), np.array([1.0])
    i = 0
    for _ in range(structure.poles):
        a = np.exp(p[i])
        den = np.convolve(den, [1.0 / a, 1.0])
        i += 1
    for _ in range(structure.pairs):
        wn, zeta = np.exp(p[i]), np.exp(p[i + 1])
        den = np.convolve(den, [1.0 / wn ** 2, 2 * zeta / wn, 1.0])
        i += 2
    for _ in range(structure.zeros):
        num = np.convolve(num, [p[i], 1.0])
        i += 1
    return LinearBlock(tuple(num.tolist()), tuple(den.tolist()), float(delay))


def structure_of(g: LinearBlock) -> Structure | None:
    """The :class:`Structure` of a stable ``g`` with real zeros (None when it has none of ours)."""
    poles = np.roots(g.den)
    zeros = np.roots(np.trim_zeros(np.asarray(g.num, float), "f"))
    if np.any(poles.real >= 0) or np.any(np.abs(zeros.imag) > 1e-9):
        return None
    real = int(np.sum(np.abs(poles.imag) < 1e-9))
    pairs = int(np.sum(poles.imag > 1e-9))
    return Structure(real, pairs, len(zeros))


def g_params_from(structure: Structure, g: LinearBlock | None, span_s: float, dt: float) -> np.ndarray:
    """Start values of ``structure``'s factors: from the poles and zeros of ``g`` where it has the
    same structure, else time constants spread between ``10 dt`` and a tenth of the record."""
    if g is not None:
        poles = np.roots(g.den)
        zeros = np.roots(np.trim_zeros(np.asarray(g.num, float), "f"))
        real = sorted(-poles[np.abs(poles.imag) < 1e-9].real)
        cplx = [q for q in poles if q.imag > 1e-9]
        if len(real) == structure.poles and len(cplx) == structure.pairs and all(r > 0 for r in real) \
                and len(zeros) >= structure.zeros:
            p = [np.log(r) for r in real]
            for q in cplx:
                wn = abs(q)
                p += [np.log(wn), np.log(max(-q.real / wn, 1e-3))]
            p += [float(-1.0 / z.real) if abs(z.real) > 1e-12 else 0.0 for z in zeros[:structure.zeros]]
            return np.array(p, float)
    rates = np.geomspace(1.0 / max(span_s / 10, 20 * dt), 1.0 / (10 * dt), structure.order + 2)[1:-1]
    p = [np.log(r) for r in rates[:structure.poles]]
    for k in range(structure.pairs):
        p += [np.log(rates[structure.poles + 2 * k]), np.log(0.5)]
    p += [0.0] * structure.zeros
    return np.array(p, float)
