"""Nuisance starts held across a least-squares Jacobian (hwid.diagnose.held_starts)."""
import numpy as np
from scipy.optimize import least_squares
from scipy.optimize._numdiff import approx_derivative

from hwid.diagnose.held_starts import HeldJacobian, nuisance
from hwid.diagnose.starts import search_1d

T = np.linspace(0.0, 6.0, 200)
TRUTH = np.array([0.8, 0.25])       # amplitude and offset, on the unit box
PHASE = 0.3                         # the record's start: a nuisance searched in every residual
Y = TRUTH[0] * np.sin(T + PHASE) + TRUTH[1]


class Counted:
    """The residual of a record whose phase is searched (as a gear's place is) at every call."""

    def __init__(self):
        self.searches = 0

    def __call__(self, x):
        def search():
            self.searches += 1
            return search_1d(lambda s: float(np.sum((Y - x[0] * np.sin(T + s) - x[1]) ** 2)), -1.0, 1.0)
        s = nuisance(search, ("phase", 0))
        return Y - x[0] * np.sin(T + s) - x[1]


def test_without_a_nuisance_the_jacobian_is_scipys_own():
    rng = np.random.default_rng(1)
    A = rng.normal(size=(40, 3))

    def f(x):
        return np.sin(A @ x) + x[0] ** 2
    for x in (rng.uniform(size=3), np.array([0.0, 1.0, 0.5]), np.array([1e-12, 0.9995, 1.0 - 1e-12])):
        for step in (1e-3, 1e-2):
            held = HeldJacobian(f, step)
            assert not held.searched(x)
            assert np.array_equal(held.jac(x), approx_derivative(f, x, rel_step=step, method="2-point",
                                                                 bounds=(0.0, 1.0)))


def test_the_columns_reuse_the_start_and_the_gradient_is_the_full_ones():
    """At a point, the start is searched once for the Jacobian (not once per column), and the
    gradient J^T r equals the cost's gradient with the start re-searched at every step."""
    f = Counted()
    x = np.array([0.6, 0.4])
    held = HeldJacobian(f, 1e-6)
    assert held.searched(x)
    n = f.searches
    J = held.jac(x)
    assert f.searches == n                   # the columns replayed the start found at x
    r = held.fun(x)
    cost = lambda z: 0.5 * float(np.sum(f(z) ** 2))      # the start searched at every point
    g_full = approx_derivative(cost, x, rel_step=1e-6, method="3-point")
    assert np.allclose(J.T @ r, g_full, rtol=1e-3, atol=1e-5)


def test_least_squares_with_the_held_jacobian_reaches_the_truth():
    f = Counted()
    held = HeldJacobian(f, 1e-3)
    sol = least_squares(held.fun, np.array([0.3, 0.6]), jac=held.jac, bounds=(0.0, 1.0), diff_step=1e-3)
    assert np.allclose(sol.x, TRUTH, atol=1e-6)
    # and without holding: the same answer, at more searches per iteration
    g = Counted()
    sol2 = least_squares(g, np.array([0.3, 0.6]), bounds=(0.0, 1.0), diff_step=1e-3)
    assert np.allclose(sol2.x, TRUTH, atol=1e-6)
    assert f.searches < g.searches


def test_a_start_on_an_end_of_its_range_follows_the_end_and_the_gradient_is_the_full_ones():
    """A start whose minimiser lies beyond its range is found on the range's end, and that end moves
    with the parameters: there the cost's slope in the start is not zero, the start follows the end,
    and holding its value would take that share out of the gradient. Each column takes the end
    where its parameters put it, without a search."""
    searches = []

    def f(x):
        hi = x[1] - 1.0                       # the range [-1, x1 - 1] ends short of the phase 0.3

        def search():
            searches.append(1)
            return search_1d(lambda s: float(np.sum((Y - x[0] * np.sin(T + s)) ** 2)), -1.0, hi)
        s = nuisance(search, ("phase", 0), (-1.0, hi))
        return Y - x[0] * np.sin(T + s)
    x = np.array([0.6, 0.7])
    held = HeldJacobian(f, 1e-6)
    assert held.searched(x)
    r = held.fun(x)
    n = len(searches)
    J = held.jac(x)
    in_columns = len(searches) - n
    cost = lambda z: 0.5 * float(np.sum(f(z) ** 2))
    g_full = approx_derivative(cost, x, rel_step=1e-6, method="3-point")
    assert abs(g_full[1]) > 1.0                # the end's move is most of the gradient
    assert np.allclose(J.T @ r, g_full, rtol=1e-3, atol=1e-5)
    assert in_columns == 0                     # the columns took the range's end, not a search
