"""The one F -> G -> h chain (HWModel.simulate): the fused kernel equals the three blocks run one
after another, bit for bit, for both operator types, any start state and any rest level of G."""
import numpy as np
import pytest

from hwid.blocks.linear import LinearBlock
from hwid.blocks.static import PiecewiseH, PolynomialH
from hwid.model import HWModel, InputNonlinearity

H = PolynomialH((0, 0.25, 0.1, -0.42, 0, 0.2))
GS = [LinearBlock((0.2,), (1.0, 0.7, 0.1)), LinearBlock((0.3, 1.0), (1.0, 0.7, 0.1, 0.05)),
      LinearBlock((2.0, 1.0), (1.0, 3.0)), LinearBlock((0.2,), (1.0, 0.7, 0.1), 0.013)]


@pytest.mark.parametrize("kind", ["backlash", "backlash_inverse"])
@pytest.mark.parametrize("g", GS, ids=["2nd order", "3rd order with zero", "biproper", "delayed"])
@pytest.mark.parametrize("gear,rest", [(None, None), (0.1, None), (None, 0.5), (0.2, -0.3)])
def test_chain_is_the_three_blocks(kind, g, gear, rest):
    u = np.cumsum(np.random.default_rng(0).standard_normal(5000)) * 0.05
    model = HWModel(InputNonlinearity(kind, 1.2, 0.8, 0.4, -0.3), g, H)
    sig = model.simulate(u, 0.01, gear, rest)
    v = model.input.apply(u, gear)
    w = model.linear.simulate(v, 0.01, rest)
    assert np.array_equal(sig.v, v) and np.array_equal(sig.w, w) and np.array_equal(sig.x, H(w))
    assert sig.gear == v[-1]


def test_chain_with_a_piecewise_h_and_rest_level():
    h = PiecewiseH((0.0,), ((0.0, 1.0), (0.0, 2.0)))
    model = HWModel(InputNonlinearity("backlash", 1.0, 1.0, 0.5, -0.5), LinearBlock((1.0,), (1.0, 1.0)), h)
    sig = model.simulate(np.full(2000, 2.0), 0.01, gear=1.5, rest=-1.0)
    assert sig.w[0] == pytest.approx(-1.0) and sig.x[0] == pytest.approx(-1.0)     # at rest at -1
    assert sig.w[-1] == pytest.approx(1.5, abs=1e-6) and sig.x[-1] == pytest.approx(3.0, abs=1e-5)


def test_staircase_truth_after_the_lead_in():
    model = HWModel(InputNonlinearity("backlash", 1.0, 1.0, 0.5, -0.5), LinearBlock((2.0,), (1.0, 2.0)),
                    PolynomialH((0.0, 1.0)))
    # from below every border, rising levels push the gear along the ascending border (eq. 7b)
    X = model.staircase_steady([-2.0], [-1.0, 0.0, 1.0])
    assert X.tolist() == pytest.approx([-1.5, -0.5, 0.5])


def test_no_parametric_g_falls_back_to_a_first_order_fit():
    """Stage 2 found no stable rational G: the model is built with
    1/(tau s + 1) fitted to the estimates; for estimates of 1/(2 s + 1), tau = 2."""
    from types import SimpleNamespace

    from hwid.identify.result import model_from_stages
    w = np.array([0.1, 0.3, 1.0, 3.0])
    G = 1.0 / (1.0 + 2j * w)
    lin = SimpleNamespace(frequencies=w, gain=np.abs(G), phase=-np.angle(G),
                          parametric={"num": [], "den": [], "delay": 0.0, "error": "no stable rational model"})
    from hwid.model import InputNonlinearity
    nl = SimpleNamespace(input_nonlinearity=lambda: InputNonlinearity("backlash", 1.0, 1.0, 0.3, -0.3),
                         h_coefficients=[0.0, 1.0, 0.0, -0.1])
    notes: list = []
    m = model_from_stages(nl, lin, notes)
    assert m.linear.den[0] == pytest.approx(2.0, rel=1e-4) and m.linear.num == (1.0,)
    assert len(notes) == 1 and "no stable rational model" in notes[0]


def test_normalisation_backlash_inverse_keeps_steady_output():
    """eq. (4a) extended to the Backlash-Inverse: the normalised model has the same steady outputs."""
    m = HWModel(InputNonlinearity("backlash_inverse", 2.0, 1.5, 0.3, -0.4), LinearBlock((3.0,), (1.0, 2.0)),
                PolynomialH((0, 1.0, 0.3, 0.2)))
    n = m.normalised()
    lv = np.array([1.0, -1.0, -0.5, 0.0, 0.5, 1.0, 0.2, -0.7])
    np.testing.assert_allclose(m.steady_output(lv, 0.0), n.steady_output(lv, 0.0 * m.input.scale), atol=1e-12)
    assert n.input.slope_up == 1.0 and n.input.d_plus == pytest.approx(0.6) and n.linear.dc_gain == pytest.approx(1)
