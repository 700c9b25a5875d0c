"""The diagnosis's fast paths give what the general-purpose code they stand in for gives: the
first-order lag on a whole design matrix, the curved borders' cached basis, h's Legendre basis,
h's joint fit built on the scored samples alone, and the effect fits handed to the workers longest
first."""
import numpy as np
import pytest

from hwid.blocks.linear import LinearBlock
from hwid.blocks.static import legendre_vander
from hwid.diagnose.effects import CurvedBorders
from hwid.blocks.effects import first_order
from hwid.threads import forked_map


@pytest.mark.parametrize("tau", [0.005, 0.3, 20.0])
def test_the_lag_on_a_matrix_is_the_exact_sampled_lag_of_each_column(tau):
    dt = 0.02
    x = np.random.default_rng(3).normal(size=(2000, 4)).cumsum(axis=0)
    exact = np.column_stack([LinearBlock((1.0,), (tau, 1.0)).simulate(x[:, k], dt) for k in range(4)])
    np.testing.assert_allclose(first_order(x, tau, dt), exact, rtol=0, atol=1e-11 * np.abs(x).max())
    np.testing.assert_allclose(first_order(x[:, 2], tau, dt), exact[:, 2], rtol=0, atol=1e-11 * np.abs(x).max())
    assert first_order(x[:0], tau, dt).shape == (0, 4)


@pytest.mark.parametrize("degree", [0, 1, 2, 7])
def test_h_basis_is_numpys_legendre_vandermonde_to_the_last_bit(degree):
    x = np.random.default_rng(4).uniform(-1.2, 1.2, 3001)
    assert np.array_equal(legendre_vander(x, degree), np.polynomial.legendre.legvander(x, degree))
    assert legendre_vander(x[:0], degree).shape == (0, degree + 1)


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


@pytest.mark.parametrize("refit_g", [False, True])
def test_h_refit_on_the_scored_samples_is_the_refit_on_whole_experiments_masked(refit_g):
    """The joint fits build h's design matrix only on the samples a residual is made of (scored,
    decimated on the fit part) where the effect's output stage is pointwise; through a linear
    stage with memory (a sensor lag) it is built whole and then sampled. Either way the residual is
    the one of the model simulated whole, h fitted by least squares on those samples."""
    from hwid.blocks.static import PolynomialH
    from hwid.diagnose.effects import InputDeadzone, Scale, SensorLag, SensorSaturation
    from hwid.diagnose.modelsim import ModelSim
    from hwid.diagnose.rank import EffectFitter
    from hwid.model import HWModel, InputNonlinearity
    dt = 0.05
    model = HWModel(InputNonlinearity("backlash", 1.0, 1.0, 0.2, -0.2), LinearBlock((1.0,), (1.5, 2.5, 1.0), 0.0),
                    PolynomialH((0.1, 1.0, 0.3, -0.2)))
    rng = np.random.default_rng(np.random.SeedSequence(21))
    t = np.arange(0, 120.0, dt)
    us = [1.3 * np.sin(2 * np.pi * t / p) + 0.2 * np.sin(2 * np.pi * t / 3.1) for p in (17.0, 29.0)]
    sim = ModelSim(model, dt, us)
    ys = [x + 0.01 * rng.standard_normal(x.size) for x in sim.x]
    masks = [t > 10.0, (t > 5.0) & (t < 100.0)]
    xs = np.concatenate(sim.x)
    sc = Scale(dt, -1.3, 1.3, float(xs.min()), float(xs.max()), 1.5, 15.0, 1.0, float(t[-1]))
    f = EffectFitter(sim, ys, masks, sim, ys, masks, ["a", "b"], sc, 0.01, 1.0, max_samples=2000,
                     refit_h=True, refit_g=refit_g)
    assert f.stride == 3
    g = f.g_p
    for eff, own in ((SensorLag(), [0.4]), (InputDeadzone(), [0.05]), (SensorSaturation(), [-0.6, 0.7])):
        theta = np.r_[own, np.zeros(len(eff.params) - len(own)), g] if refit_g else np.r_[own, np.zeros(len(eff.params) - len(own))]
        for which, st, y_, m_ in (("fit", 3, ys, masks), ("val", 1, ys, masks)):
            whole = f._refit_predict(eff, theta, which)          # every sample of every experiment
            want = np.concatenate([((y - x)[m])[::st] for y, x, m in zip(y_, whole, m_)])
            np.testing.assert_allclose(f._residual(eff, theta, which), want, rtol=0, atol=1e-12)
            assert all(x.size == y.size for x, y in zip(whole, y_))
        # h: least squares on the fit part's residual samples, the design built whole and sampled
        simw = f._g_sims(g)[0] if refit_g else f.sfw
        own_ = f._split(eff, theta)[0] if refit_g else theta
        full = f._phi(eff, own_, simw)
        A = np.concatenate([P[m][::3] for P, m in zip(full, masks)])
        b = np.concatenate([y[m][::3] for y, m in zip(ys, masks)])
        if eff.post_linear:
            np.testing.assert_allclose(f._h_coef(eff, own_, f._designs(eff, theta, "fit", scored=True)),
                                       np.linalg.lstsq(A, b, rcond=None)[0], rtol=1e-9, atol=1e-12)
