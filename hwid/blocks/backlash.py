"""Backlash operator B (eq. 1) and Backlash-Inverse operator B_inv (eq. 2), sampled.

Conventions (paper Fig. 2): the ascending border is ``v = S^a (u - d^+)``, the descending border is
``v = S^d (u - d^-)``, with ``d^+ > d^-``. For a sampled input the backlash of eq. (1) is the play
recursion ``v_k = min(max(v_{k-1}, S^a(u_k - d^+)), S^d(u_k - d^-))``, exact at the samples for any
input that is monotone between samples.

The Backlash-Inverse of eq. (2) follows the direction of its input: ``u = z/S^a + d^+`` while z
rises, ``u = z/S^d + d^-`` while z falls, and holds its last output while z is constant.

Lemma 1 in sampled time (tested in ``tests/test_backlash.py``):

* ``B(B_inv(z)) = z`` exactly, from the first sample on, once B starts at ``v_0 = z_0``;
* ``B_inv(B(z))`` equals z except while B crosses its gap after a reversal of z: B's output is then
  constant, so B_inv holds. The paper states both compositions as the identity; the second holds
  only outside those gap crossings. The exact sampled right inverse of B_inv is the *border map*
  (:func:`border_map`), which is B_inv with the parameters inverted; it leaves a one-sample
  switching transient at each reversal of z.
"""
from __future__ import annotations

import numpy as np
from numba import njit


@njit(cache=True)
def _play(u, su, sd, dp, dm, v0):
    n = u.shape[0]
    v = np.empty(n)
    prev = v0
    for k in range(n):
        lo = su * (u[k] - dp)
        hi = sd * (u[k] - dm)
        if prev < lo:
            prev = lo
        elif prev > hi:
            prev = hi
        v[k] = prev
    return v


@njit(cache=True)
def _direction_map(z, a_up, b_up, a_dn, b_dn, u0):
    n = z.shape[0]
    out = np.empty(n)
    prev = u0
    for k in range(n):
        if k > 0:
            dz = z[k] - z[k - 1]
            if dz > 0.0:
                prev = a_up * z[k] + b_up
            elif dz < 0.0:
                prev = a_dn * z[k] + b_dn
        out[k] = prev
    return out


def _check(slope_up: float, slope_down: float, d_plus: float, d_minus: float) -> None:
    if not (slope_up > 0 and slope_down > 0):
        raise ValueError("backlash slopes must be > 0")
    if not d_plus > d_minus:
        raise ValueError("backlash needs d_plus > d_minus")


def backlash(u, slope_up: float, slope_down: float, d_plus: float, d_minus: float,
             v0: float | None = None) -> np.ndarray:
    """Backlash operator ``B[v, u, u'](t)``, eq. (1), on a sampled input.

    Parameters
    ----------
    u : array_like
        Input samples.
    slope_up, slope_down, d_plus, d_minus : float
        ``S^a``, ``S^d``, ``d^+``, ``d^-`` of Fig. 2.
    v0 : float, optional
        Output before the first sample (the gear's initial position). Default: 0 clipped into the
        band between the borders at ``u[0]``.
    """
    _check(slope_up, slope_down, d_plus, d_minus)
    u = np.ascontiguousarray(u, dtype=float)
    if v0 is None:
        v0 = backlash_start(u, slope_up, slope_down, d_plus, d_minus)
    return _play(u, float(slope_up), float(slope_down), float(d_plus), float(d_minus), float(v0))


def backlash_start(u, slope_up: float, slope_down: float, d_plus: float, d_minus: float) -> float:
    """The Backlash's default gear position before ``u[0]``: 0 clipped into the band between the
    borders at ``u[0]``."""
    return 0.0 if len(u) == 0 else float(np.clip(0.0, slope_up * (u[0] - d_plus), slope_down * (u[0] - d_minus)))


def backlash_inverse_start(z, slope_up: float, slope_down: float, d_plus: float, d_minus: float) -> float:
    """The Backlash-Inverse's default output at ``z[0]``: the midpoint of its two branches there."""
    return 0.0 if len(z) == 0 else 0.5 * (z[0] / slope_up + d_plus + z[0] / slope_down + d_minus)


def backlash_inverse(z, slope_up: float, slope_down: float, d_plus: float, d_minus: float,
                     u0: float | None = None) -> np.ndarray:
    """Backlash-Inverse operator ``B_inv[u, z, z'](t)``, eq. (2), on a sampled input.

    ``u = z/S^a + d^+`` when z rises, ``z/S^d + d^-`` when it falls, the previous output otherwise.

    Parameters
    ----------
    u0 : float, optional
        Output held at the first sample (where the direction of z is not yet known). Default: the
        midpoint of the two branches at ``z[0]``.
    """
    _check(slope_up, slope_down, d_plus, d_minus)
    z = np.ascontiguousarray(z, dtype=float)
    if u0 is None:
        u0 = backlash_inverse_start(z, slope_up, slope_down, d_plus, d_minus)
    return _direction_map(z, 1.0 / slope_up, float(d_plus), 1.0 / slope_down, float(d_minus), float(u0))


def border_map(z, slope_up: float, slope_down: float, d_plus: float, d_minus: float,
               u0: float | None = None) -> np.ndarray:
    """Right inverse of the Backlash-Inverse: ``u = S^a (z - d^+)`` while z rises, ``S^d (z - d^-)``
    while it falls, held while z is constant.

    ``backlash_inverse(border_map(z, p), p) == z`` at every sample except the one sample at each
    reversal of z, where ``u`` jumps across the gap. This is the pre-compensator of Fig. 8 for a
    plant whose input nonlinearity is a Backlash-Inverse.
    """
    _check(slope_up, slope_down, d_plus, d_minus)
    z = np.ascontiguousarray(z, dtype=float)
    if u0 is None:
        u0 = 0.0 if z.size == 0 else 0.5 * (slope_up * (z[0] - d_plus) + slope_down * (z[0] - d_minus))
    return _direction_map(z, float(slope_up), -slope_up * d_plus, float(slope_down),
                          -slope_down * d_minus, float(u0))


def static_play(levels, slope_up: float, slope_down: float, d_plus: float, d_minus: float,
                v0: float) -> np.ndarray:
    """Steady-state backlash outputs ``V_j = F[U_j]`` for a sequence of constant levels (eqs. 7, 14)."""
    return _play(np.ascontiguousarray(levels, dtype=float), float(slope_up), float(slope_down),
                 float(d_plus), float(d_minus), float(v0))


def static_direction_map(levels, slope_up, slope_down, d_plus, d_minus, u0: float) -> np.ndarray:
    """Steady-state Backlash-Inverse outputs for a sequence of constant levels (Remark 1.4)."""
    return _direction_map(np.ascontiguousarray(levels, dtype=float), 1.0 / slope_up, float(d_plus),
                          1.0 / slope_down, float(d_minus), float(u0))
