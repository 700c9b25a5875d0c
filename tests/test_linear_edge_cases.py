"""G's edge cases, checked against hand-computed answers (eq. 3b with a ZOH input and a delay):

* a static gain ``G = K e^{-s tau}`` (num and den of degree 0) is ``w = K v`` delayed, the delay
  line holding the rest level (``v[0]`` by default): it used to fail with a singular matrix,
  because scipy's tf2ss pads a static gain with a dummy state (A = B = C = 0, so Phi = 1 and
  ``(I - Phi) x0 = ...`` had no solution), in LinearBlock.simulate and in HWModel's fused chain;
* an input shorter than the delay (in samples) gives a w as long as v, at the rest level: it used
  to come out longer than v.
"""
import numpy as np
import pytest
from scipy import signal

from hwid.blocks.linear import LinearBlock
from hwid.blocks.static import PiecewiseH, PolynomialH
from hwid.model import HWModel, InputNonlinearity
from hwid.plant import SimulatedPlant, experiment_rng

V = np.array([0.3, -1.2, 2.5, 0.7, 0.7, -0.4, 1.9, 3.1, -2.2, 0.05])


def shifted(v, k, start):
    """``v`` delayed by k samples, ``start`` before the first sample, as long as ``v``."""
    return np.array([start if j < k else v[j - k] for j in range(len(v))])


def first_order(v, dt, d, c, a, delay, start):
    """``G(s) = (d + c/(s + a)) e^{-s delay}`` on the ZOH input v, by the direct recursion of
    ``y' = -a y + c u(t - delay)``: over ``[k dt, (k+1) dt)`` the delayed input is ``v[k-l-1]``
    for the first ``f`` seconds and ``v[k-l]`` after (``delay = l dt + f``), ``w_k = d u(t_k - delay) + y_k``."""
    lag = int(np.floor(delay / dt + 1e-12))
    f = delay - lag * dt
    if f < 1e-12 * dt:
        f = 0.0
    at = lambda j: start if j < 0 else v[j]       # noqa: E731
    e, e1 = np.exp(-a * dt), np.exp(-a * (dt - f))
    y = c / a * start
    w = []
    for k in range(len(v)):
        w.append(d * (at(k - lag) if f == 0.0 else at(k - lag - 1)) + y)
        y = e * y + c / a * (e1 - e) * at(k - lag - 1) + c / a * (1 - e1) * at(k - lag)
    return np.array(w)


# --- a static gain --------------------------------------------------------------------------------

@pytest.mark.parametrize("num,den,K", [((2.0,), (1.0,), 2.0), ((3.0,), (4.0,), 0.75), ((-1.5,), (0.0, 1.0), -1.5)])
@pytest.mark.parametrize("rest", [None, 0.6])
def test_static_gain_is_k_times_v(num, den, K, rest):
    w = LinearBlock(num, den).simulate(V, 0.1, rest)
    np.testing.assert_allclose(w, K * V, rtol=0, atol=0)


@pytest.mark.parametrize("rest", [None, 0.6])
@pytest.mark.parametrize("delay,shift", [(1.5, 3), (0.75, 2), (0.5, 1), (0.25, 1), (4.0, 8), (5.0, 10), (7.5, 15)])
def test_static_gain_with_delay_is_the_delayed_sequence(delay, shift, rest):
    # dt = 0.5: delay 1.5 is 3 whole samples; delay 0.75 is 1.5 samples, so w_k = K v(t_k - 0.75) =
    # K v[k-2] under the ZOH; 5.0 and 7.5 delay V (10 samples) past its end: all at rest
    start = V[0] if rest is None else rest
    w = LinearBlock((2.0,), (1.0,), delay).simulate(V, 0.5, rest)
    assert w.shape == V.shape
    np.testing.assert_allclose(w, 2.0 * shifted(V, shift, start), rtol=0, atol=0)


@pytest.mark.parametrize("kind", ["backlash", "backlash_inverse"])
@pytest.mark.parametrize("h", [PolynomialH((0.1, 1.0, -0.2)), PiecewiseH((0.0,), ((0.0, 1.0), (0.0, 2.0)))],
                         ids=["polynomial", "piecewise"])
@pytest.mark.parametrize("delay,shift", [(0.0, 0), (0.03, 3), (0.013, 2)])
@pytest.mark.parametrize("gear,rest", [(None, None), (0.2, -0.4)])
def test_model_with_a_static_gain(kind, h, delay, shift, gear, rest):
    u = 2.0 * np.sin(np.arange(300) * 0.05)
    model = HWModel(InputNonlinearity(kind, 1.2, 0.8, 0.3, -0.2), LinearBlock((2.5,), (1.0,), delay), h)
    sig = model.simulate(u, 0.01, gear, rest, np.random.default_rng(3), 0.05)
    v = model.input.apply(u, gear)
    w = 2.5 * shifted(v, shift, v[0] if rest is None else rest)
    x = h(w)
    np.testing.assert_allclose(sig.v, v, rtol=0, atol=0)
    np.testing.assert_allclose(sig.w, w, rtol=0, atol=0)
    np.testing.assert_allclose(sig.x, x, rtol=0, atol=0)
    np.testing.assert_allclose(sig.y, x + 0.05 * np.random.default_rng(3).standard_normal(u.size), rtol=0, atol=0)


def test_simulated_plant_with_a_static_gain():
    model = HWModel(InputNonlinearity("backlash", 1.0, 1.0, 0.5, -0.5), LinearBlock((2.0,), (1.0,)),
                    PolynomialH((0.0, 1.0, 0.5)))
    plant = SimulatedPlant(model, 0.01, noise_std=0.02, seed=11, initial_state=0.0)
    u = np.r_[np.linspace(0.0, 2.0, 100), np.linspace(2.0, -1.0, 100)]
    gear = 0.0
    for name in ("a", "b"):                      # the gear carries over from one experiment to the next
        rec = plant.run(name, u)
        v = np.empty(u.size)
        for k, uk in enumerate(u):               # the play of eq. (1) with unit slopes, d+ = 0.5, d- = -0.5
            gear = min(max(gear, uk - 0.5), uk + 0.5)
            v[k] = gear
        np.testing.assert_allclose(rec.v, v, rtol=0, atol=0)
        np.testing.assert_allclose(rec.w, 2.0 * v, rtol=0, atol=0)
        np.testing.assert_allclose(rec.x, 2.0 * v + 0.5 * (2.0 * v) ** 2, rtol=0, atol=1e-15)
        e = experiment_rng(plant.seed_seq, name).standard_normal(u.size)
        np.testing.assert_allclose(rec.y, rec.x + 0.02 * e, rtol=0, atol=0)


# --- a first-order G with a delay -------------------------------------------------------------------

@pytest.mark.parametrize("d,c,a", [(0.0, 3.0, 2.0), (1.0, 2.0, 1.0)], ids=["strictly proper", "biproper"])
@pytest.mark.parametrize("delay", [0.0, 0.3, 0.25, 0.07])
@pytest.mark.parametrize("rest", [None, -0.8])
def test_first_order_with_delay_matches_the_direct_recursion(d, c, a, delay, rest):
    dt = 0.1
    v = np.cumsum(np.random.default_rng(1).standard_normal(200)) * 0.3
    num = (d, d * a + c) if d else (c,)
    w = LinearBlock(num, (1.0, a), delay).simulate(v, dt, rest)
    start = v[0] if rest is None else rest
    np.testing.assert_allclose(w, first_order(v, dt, d, c, a, delay, start), rtol=0, atol=1e-12)


@pytest.mark.parametrize("rest", [None, -0.8])
def test_first_order_with_whole_sample_delay_matches_scipy_zoh(rest):
    dt, a, c = 0.1, 2.0, 3.0
    v = np.cumsum(np.random.default_rng(2).standard_normal(200)) * 0.3
    w = LinearBlock((c,), (1.0, a), 0.3).simulate(v, dt, rest)          # 3 samples of delay
    Ad, Bd, Cd, Dd, _ = signal.cont2discrete(signal.tf2ss([c], [1.0, a]), dt, method="zoh")
    start = v[0] if rest is None else rest
    vd = shifted(v, 3, start)
    x = np.linalg.solve(np.eye(1) - Ad, Bd[:, 0] * start)
    ref = []
    for vk in vd:
        ref.append(float(Cd[0] @ x + Dd[0, 0] * vk))
        x = Ad @ x + Bd[:, 0] * vk
    np.testing.assert_allclose(w, ref, rtol=0, atol=1e-12)


# --- an input shorter than the delay ------------------------------------------------------------------

@pytest.mark.parametrize("g", [LinearBlock((3.0,), (1.0, 2.0), 0.5), LinearBlock((1.0, 3.0), (1.0, 1.0), 0.47),
                               LinearBlock((0.2,), (1.0, 0.7, 0.1), 0.37), LinearBlock((2.0,), (1.0,), 0.47)],
                         ids=["first order, 5 samples", "biproper, 4.7 samples", "second order, 3.7 samples",
                              "static gain, 4.7 samples"])
@pytest.mark.parametrize("rest", [None, -0.8])
def test_input_shorter_than_the_delay(g, rest):
    dt = 0.1
    v = np.cumsum(np.random.default_rng(4).standard_normal(30))
    lag = int(np.floor(g.delay / dt + 1e-12))
    whole = g.simulate(v, dt, rest)
    for m in range(1, 12):
        start = v[0] if rest is None else rest
        w = g.simulate(v[:m], dt, rest)
        assert w.shape == (m,)
        # G is causal: the first m samples of the response do not depend on the input after them
        np.testing.assert_allclose(w, whole[:m], rtol=0, atol=0)
        # within the delay G is at rest: w = G(0) times the rest level
        np.testing.assert_allclose(w[:min(m, lag)], g.dc_gain * start, rtol=0, atol=1e-12)


@pytest.mark.parametrize("rest", [None, -0.8])
def test_first_order_on_an_input_shorter_than_the_delay_matches_the_recursion(rest):
    v = np.array([1.0, -2.0, 0.5])
    for delay in (0.5, 0.47, 0.3):                  # 5, 4.7 and exactly 3 samples: longer than v or as long
        w = LinearBlock((3.0,), (1.0, 2.0), delay).simulate(v, 0.1, rest)
        start = v[0] if rest is None else rest
        np.testing.assert_allclose(w, first_order(v, 0.1, 0.0, 3.0, 2.0, delay, start), rtol=0, atol=1e-12)
        np.testing.assert_allclose(w, 1.5 * start, rtol=0, atol=1e-12)
