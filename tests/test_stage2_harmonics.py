"""Stage 2 harmonic analysis: the model of eq. (20) and the exact-frequency least squares."""
import numpy as np
import pytest

from hwid.identify.harmonics import HarmonicModel, fit_harmonics, sine_power_matrix


def _fft_coefficients(x, ks):
    """C_k = b_k + j a_k of x sampled on a whole period (N points), by the FFT (exact for trig polys)."""
    F = np.fft.rfft(x) / x.size
    return -2 * F[ks].imag + 2j * F[ks].real


@pytest.mark.parametrize("coef", [(0, 0.5, 0, -3.36, 0, 6.4),               # eq. (30c)
                                  (0, 1.0, 0.7, -0.4, 0.3),                  # even terms
                                  (0, -0.2, 0.1, 0.05, -0.3, 0.2, 0.4, -0.1, 0.02)])
def test_harmonic_model_matches_fft_for_any_polynomial(coef):
    hm = HarmonicModel(coef)
    ks = np.arange(1, hm.degree + 1)
    N = 4096
    a = 2 * np.pi * np.arange(N) / N
    for r, phi in [(0.3, 0.2), (0.9, 1.16), (1.7, -2.5)]:
        x = np.polynomial.polynomial.polyval(r * np.sin(a - phi), coef)
        np.testing.assert_allclose(hm.coefficients(r, phi, ks), _fft_coefficients(x, ks), atol=1e-12)
        _, A, _ = hm.amplitudes_phases(r, phi, 1.0, ks=[0])
        assert A[0] == pytest.approx(x.mean(), abs=1e-12)


def test_amplitudes_phases_reduce_to_eq35_for_p5():
    c = np.array([0.0, 0.3, 0.8, -0.42, 0.5, 0.2])
    hm = HarmonicModel(tuple(c))
    g, phi, U = 0.87, 0.66, 1.3
    r = U * g
    ks, A, beta = hm.amplitudes_phases(g, phi, U)
    assert A[5] == pytest.approx(c[5] * r ** 5 / 16)                                  # (35a)
    assert np.angle(np.exp(1j * (beta[5] + 5 * phi))) == pytest.approx(0, abs=1e-12)
    assert A[4] == pytest.approx(c[4] * r ** 4 / 8)                                   # (35b)
    assert np.angle(np.exp(1j * (beta[4] + 4 * phi - np.pi / 2))) == pytest.approx(0, abs=1e-12)
    assert abs(A[3]) == pytest.approx(abs(-5 / 16 * c[5] * r ** 5 - c[3] * r ** 3 / 4))  # (35c)
    a_ = c[1] + 0.75 * c[3] * r ** 2 + 5 / 8 * c[5] * r ** 4                           # (35g)
    # (35f-g) add b = -c_4 r^3 / 8 to the fundamental; even powers of sin hold only even harmonics
    # (eq. 19a), so b is an erratum: A_1 = r |a| (the FFT test above confirms it)
    assert A[1] == pytest.approx(r * abs(a_))
    assert A[1] != pytest.approx(r * np.hypot(a_, -c[4] * r ** 3 / 8))
    assert A[0] == pytest.approx(0.5 * c[2] * r ** 2 + 3 / 8 * c[4] * r ** 4)          # (35e)


def test_sine_power_matrix_parity():
    M = sine_power_matrix(7)
    for i in range(8):
        for k in range(1, 8):
            if (i - k) % 2 or k > i:
                assert M[i, k] == 0
            elif i % 2:
                assert M[i, k].imag == 0
            else:
                assert M[i, k].real == 0


def test_exact_frequency_ls_noninteger_period_has_no_leakage():
    dt, w = 0.01, 0.2          # T/dt = 3141.59...: FFT bins of a record would leak
    hm = HarmonicModel((0, 0.5, 0.2, -3.36, 0, 6.4))
    t = np.arange(int(7 * 2 * np.pi / w / dt) + 1) * dt
    y = np.polynomial.polynomial.polyval(0.65 * np.sin(w * t - 1.16), hm.h_coefficients) + 0.123
    f = fit_harmonics(y, dt, w, 7, first_period=1)
    np.testing.assert_allclose(f.coef[:5], hm.coefficients(0.65, 1.16, np.arange(1, 6)), atol=1e-11)
    np.testing.assert_allclose(f.coef[5:], 0, atol=1e-11)
    assert f.dc == pytest.approx(0.123 + hm.amplitudes_phases(0.65, 1.16, 1, ks=[0])[1][0], abs=1e-11)
    assert f.periods == 6 and f.first_period == 1


def test_steady_state_check_drops_transient_periods():
    rng = np.random.default_rng(3)
    dt, w = 0.05, 1.0
    t = np.arange(int(30 * 2 * np.pi / w / dt)) * dt
    y = np.sin(w * t - 0.3) + 0.5 * np.exp(-t / 12.0) + 0.01 * rng.standard_normal(t.size)
    f = fit_harmonics(y, dt, w, 3, first_period=1)
    assert f.first_period > 4                          # the 12 s transient outlives the lead-in
    assert abs(f.coef[0] - np.exp(-0.3j)) < 4 * np.sqrt(f.var[0])


def test_standard_errors_honest_for_white_and_coloured_noise():
    from scipy import signal
    dt, w, P = 0.05, 2.0, 40
    t = np.arange(int((P + 1) * 2 * np.pi / w / dt)) * dt
    x = 0.7 * np.sin(w * t) - 0.2 * np.sin(3 * w * t + 0.4)
    rng = np.random.default_rng(11)
    for ar, model in [(0.0, "white"), (0.95, "periodic")]:
        errs, ses, models = [], [], []
        for _ in range(150):
            e = rng.standard_normal(t.size)
            n = 0.02 * (signal.lfilter([np.sqrt(1 - ar ** 2)], [1, -ar], e) if ar else e)
            f = fit_harmonics(x + n, dt, w, 3, first_period=1)
            errs.append(f.coef[0] - 0.7)
            ses.append(np.sqrt(f.var[0]))
            models.append(f.noise_model)
        errs = np.array(errs)
        emp = np.sqrt(0.5 * np.mean(np.abs(errs) ** 2))
        assert emp / np.mean(ses) == pytest.approx(1.0, abs=0.2), (ar, emp, np.mean(ses))
        assert np.mean([m == model for m in models]) > 0.9
