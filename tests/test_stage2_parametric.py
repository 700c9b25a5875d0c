"""The rational G(s) fit to G_hat(j omega_i) with uncertainties."""
import numpy as np
import pytest

from hwid.identify.parametric import fit_rational, reim_covariance


def _noisy(num, den, delay, w, sd_g, sd_p, rng):
    s = 1j * w
    G = np.polyval(num, s) / np.polyval(den, s) * np.exp(-s * delay)
    g = np.abs(G) + sd_g * rng.standard_normal(w.size)
    p = -np.unwrap(np.angle(G)) + sd_p * rng.standard_normal(w.size)
    cov = np.zeros((w.size, 2, 2))
    cov[:, 0, 0], cov[:, 1, 1] = sd_g ** 2, sd_p ** 2
    return g * np.exp(-1j * p), g, p, cov


def test_reim_covariance_is_a_rotation_of_polar_uncertainty():
    C = reim_covariance(np.array([2.0]), np.array([0.0]), np.array([np.diag([1e-4, 1e-2])]))
    np.testing.assert_allclose(C[0], np.diag([1e-4, 4e-2]), atol=1e-15)


def test_paper_g_order_and_pole_coverage():
    """Eq. (30b), G_bar = 0.1/((s+0.5)(s+0.2)): order 2 chosen, poles inside their intervals."""
    rng = np.random.default_rng(7)
    w = np.array([0.01, 0.02, 0.05, 0.1, 0.2])
    hits, orders = 0, []
    for _ in range(40):
        G, g, p, cov = _noisy([0.1], [1, 0.7, 0.1], 0.0, w, 2e-4, 5e-4, rng)
        f = fit_rational(w, G, cov, gain=g, phase=p)
        orders.append(f.order)
        ci = f.poles_ci
        hits += int(ci[0, 0] <= -0.5 <= ci[0, 1]) + int(ci[1, 0] <= -0.2 <= ci[1, 1])
        assert abs(f.freqresp(np.array([1e-9]))[0] - 1) < 1e-6          # G(0) = 1
    assert np.mean([o == (2, 0) for o in orders]) > 0.8
    assert hits / 80 > 0.85


def test_delay_and_resonant_pair():
    rng = np.random.default_rng(9)
    wn, z, tau = 0.5, 0.1, 1.5
    w = np.array([0.1, 0.25, 0.4, 0.5, 0.6, 0.8, 1.2])
    G, g, p, cov = _noisy([wn ** 2], [1, 2 * z * wn, wn ** 2], tau, w, 1e-3, 1e-3, rng)
    f = fit_rational(w, G, cov, gain=g, phase=p, max_order=3, fit_delay=True)
    assert f.order[0] == 2
    assert abs(f.delay - tau) < 4 * f.delay_se
    true = np.roots([1, 2 * z * wn, wn ** 2])
    true = true[np.argsort(true.imag)]
    se = np.sqrt(np.stack([f.poles_cov[:, 0, 0], f.poles_cov[:, 1, 1]], 1))
    order = np.argsort(f.poles.imag)
    for pole, sd, t in zip(f.poles[order], se[order], true):
        assert abs(pole.real - t.real) < 4 * sd[0] and abs(pole.imag - t.imag) < 4 * sd[1]
