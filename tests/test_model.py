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
