"""The diagnosis's fast paths give what the general-purpose code they stand in for gives: the
first-order lag on a whole design matrix, the curved borders' cached basis, and the effect fits
handed to the workers longest first."""
import numpy as np
import pytest

from hwid.blocks.linear import LinearBlock
from hwid.diagnose.effects import CurvedBorders
from hwid.diagnose.modelsim import first_order
from hwid.threads import forked_map


@pytest.mark.parametrize("tau", [0.005, 0.3, 20.0])
def test_the_lag_on_a_matrix_is_the_exact_sampled_lag_of_each_column(tau):
    dt = 0.02
    x = np.random.default_rng(3).normal(size=(2000, 4)).cumsum(axis=0)
    exact = np.column_stack([LinearBlock((1.0,), (tau, 1.0)).simulate(x[:, k], dt) for k in range(4)])
    np.testing.assert_allclose(first_order(x, tau, dt), exact, rtol=0, atol=1e-11 * np.abs(x).max())
    np.testing.assert_allclose(first_order(x[:, 2], tau, dt), exact[:, 2], rtol=0, atol=1e-11 * np.abs(x).max())
    assert first_order(x[:0], tau, dt).shape == (0, 4)


def test_the_curved_borders_basis_is_the_bend_continued_along_its_tangent():
    """A bend of coefficients ``c`` is ``sum c_j P_j(s)`` inside the fit span and its tangent at the
    span's ends beyond it; the cached basis times ``c`` gives exactly that, on the same array
    again (the cache) and on a new one."""
    leg = np.polynomial.legendre
    e = CurvedBorders(4)
    object.__setattr__(e, "_scale", (0.1, 1.3))
    object.__setattr__(e, "_fit_span", (-0.8, 0.9))
    u = np.random.default_rng(5).uniform(-2.5, 2.5, 3000)
    s = (u - 0.1) / 1.3
    c = np.array([0.01, -0.05, 0.08, 0.02, -0.03])
    a, b = -0.8, 0.9
    d = leg.legder(c)
    want = (leg.legval(np.clip(s, a, b), c) + leg.legval(a, d) * np.minimum(s - a, 0.0)
            + leg.legval(b, d) * np.maximum(s - b, 0.0))
    np.testing.assert_allclose(e._bend_basis(u) @ c, want, rtol=0, atol=1e-14)
    assert e._bend_basis(u) is e._bend_basis(u)
    np.testing.assert_allclose(e._bend_basis(u.copy()) @ c, want, rtol=0, atol=1e-14)
    import pickle
    back = pickle.loads(pickle.dumps(e))
    assert "_bases" not in back.__dict__ and back.degree == 4 and back._fit_span == (-0.8, 0.9)


def test_jobs_taken_longest_first_come_back_in_their_own_order(monkeypatch):
    monkeypatch.setenv("HWID_WORKERS", "2")
    jobs = [3, 1, 4, 1, 5, 9, 2, 6]
    assert forked_map(lambda j: j * j, jobs, cost=lambda j: j) == [j * j for j in jobs]
    monkeypatch.setenv("HWID_WORKERS", "1")
    assert forked_map(lambda j: j * j, jobs, cost=lambda j: j) == [j * j for j in jobs]
