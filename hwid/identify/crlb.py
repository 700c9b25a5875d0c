"""The Cramer-Rao bound of stage 2 (Section 5): the Fisher information of ``(|G(j omega)|, phi)``
carried by the harmonic coefficients ``C_k`` of the steady output (the harmonic model of eq. 20),
and the bound on their variances that :mod:`hwid.identify.linear`'s maximum-likelihood estimator
reaches (``benchmarks/bench_stage2_efficiency.py``).
"""
from __future__ import annotations

import numpy as np

from hwid.identify.harmonics import HarmonicModel


def fisher(h_coefficients, amplitude: float, gain: float, phase: float, component_var, harmonics=None,
           input_gain: float = 1.0) -> np.ndarray:
    """Fisher information of ``(|G|, phi)`` from the harmonic coefficients ``C_k`` (eq. 20).

    ``component_var`` is the variance of Re C_k and Im C_k (scalar or one per harmonic)."""
    hm = HarmonicModel(tuple(h_coefficients))
    ks = hm.relevant() if harmonics is None else np.atleast_1d(harmonics).astype(int)
    ks = ks[(ks >= 1) & (ks <= hm.degree)]
    rho = amplitude * input_gain
    v = np.broadcast_to(np.asarray(component_var, float), ks.shape)
    C = hm.coefficients(rho * gain, phase, ks)
    dg = rho * hm.dD(rho * gain, ks) * np.exp(-1j * ks * phase)
    dp = -1j * ks * C
    J = np.stack([dg, dp], axis=-1)                        # (K, 2) complex
    return np.einsum("ki,kj->ij", J.conj(), J / v[:, None]).real


def crlb(h_coefficients, amplitude: float, gain: float, phase: float, sigma: float, n_samples: int,
         harmonics=None, input_gain: float = 1.0, component_var=None) -> tuple[float, float]:
    """Cramer-Rao lower bounds on the variances of ``|G(j omega)|`` and ``phi(omega)``.

    The output is ``y = h(U |G| sin(omega t - phi)) + offset + xi`` (eqs. 17, 18, 22) over
    ``n_samples`` samples spanning whole periods, with white Gaussian ``xi`` of standard deviation
    ``sigma`` and an unknown offset. The harmonic coefficients are then sufficient with component
    variance ``2 sigma^2 / n_samples``, and the information is that of the model of eq. (20).

    Parameters
    ----------
    h_coefficients : sequence of float
        ``h`` (normalised, ascending powers).
    amplitude : float
        ``U`` of eq. (15).
    gain, phase : float
        ``|G(j omega)|`` and ``phi(omega)`` where the bound is evaluated.
    sigma : float
        Noise standard deviation.
    n_samples : int
        Number of samples used (whole periods).
    harmonics : sequence of int, optional
        Harmonics used (default: every harmonic the model predicts).
    input_gain : float
        ``|kappa|``, the input correction (hold, residual input nonlinearity); 1 by default.
    component_var : array_like, optional
        Per-harmonic variance of Re/Im C_k; overrides ``sigma`` and ``n_samples`` (coloured noise).

    Returns
    -------
    (var_gain, var_phase) : tuple of float
    """
    if component_var is None:
        if not (sigma > 0 and n_samples > 0):
            raise ValueError("sigma and n_samples must be positive")
        component_var = 2 * sigma ** 2 / n_samples
    F = fisher(h_coefficients, amplitude, gain, phase, component_var, harmonics, input_gain)
    try:
        C = np.linalg.inv(F)
    except np.linalg.LinAlgError:
        return float("inf"), float("inf")
    return float(C[0, 0]), float(C[1, 1])
