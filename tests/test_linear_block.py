"""G(s) simulated exactly for a zero-order-held input (eq. 3b)."""
import numpy as np
import pytest

from hwid.blocks.linear import LinearBlock

G = LinearBlock((0.2,), (1.0, 0.7, 0.1))     # eq. (29a)


def step_truth(t):
    # 0.2/((s+0.5)(s+0.2)) step response: 2 [1 - (0.5 e^{-0.2t} - 0.2 e^{-0.5t}) / 0.3]
    t = np.asarray(t)
    return np.where(t >= 0, 2 * (1 - (0.5 * np.exp(-0.2 * t) - 0.2 * np.exp(-0.5 * t)) / 0.3), 0.0)


def test_zoh_step_exact_at_samples():
    dt = 0.1
    v = np.r_[0.0, np.ones(400)]
    w = G.simulate(v, dt)
    t = np.arange(v.size) * dt
    np.testing.assert_allclose(w, step_truth(t - dt), atol=1e-12)


@pytest.mark.parametrize("delay", [0.3, 0.37, 1.0])
def test_fractional_delay_exact(delay):
    dt = 0.1
    v = np.r_[0.0, np.ones(400)]
    w = LinearBlock(G.num, G.den, delay).simulate(v, dt)
    t = np.arange(v.size) * dt
    np.testing.assert_allclose(w, step_truth(t - dt - delay), atol=1e-12)


def test_constant_input_is_steady_from_first_sample():
    for v0 in (-1.3, 0.0, 0.7):
        w = G.simulate(np.full(1000, v0), 0.01)
        np.testing.assert_allclose(w, G.dc_gain * v0, rtol=0, atol=1e-13)


def test_biproper_with_zero_and_normalisation():
    g = LinearBlock((1.0, 2.0), (1.0, 3.0, 2.0))      # (s+2)/((s+1)(s+2)) = 1/(s+1)
    w = g.simulate(np.r_[0.0, np.ones(200)], 0.05)
    t = np.arange(201) * 0.05 - 0.05
    np.testing.assert_allclose(w, np.where(t >= 0, 1 - np.exp(-t), 0), atol=1e-12)
    gn = LinearBlock((2.0,), (1.0, 0.7, 0.1)).normalised()
    assert gn.dc_gain == pytest.approx(1.0)
    assert abs(gn.freqresp(0.2)) == pytest.approx(0.6565, abs=1e-4)   # Table 2, |G(j0.2)|


def test_freqresp_delay_phase():
    g = LinearBlock((1.0,), (1.0, 1.0), 0.5)
    np.testing.assert_allclose(np.angle(g.freqresp(1.0)), -np.pi / 4 - 0.5)


def test_a_pole_next_to_zero_still_has_its_rest_state():
    """``1.5e-15/(s + 1.5e-15)`` (a G identified from sines the plant did not follow) rounds the
    sampled recursion's ``Phi`` to 1: its rest state comes from the continuous ``A`` (unit gain, so
    a held input of 2 gives 2); an integrator has no rest state and starts at zero."""
    from hwid.blocks.linear import LinearBlock
    near = LinearBlock((1.5e-15,), (1.0, 1.5e-15))
    assert near.simulate(np.full(5, 2.0), 0.05) == pytest.approx(np.full(5, 2.0))
    assert LinearBlock((1.0,), (1.0, 0.0)).simulate(np.ones(4), 0.05) == pytest.approx(0.05 * np.arange(4))
