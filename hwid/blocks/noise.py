"""The measurement noise xi of ``y = x + xi`` (eqs. 3a-c), drawn inside numba kernels.

:func:`add_white` draws from the caller's ``numpy.random.Generator`` through numba's documented
support for Generator objects in nopython code (since numba 0.56): the Generator is passed to the
jitted function and its ``standard_normal()`` called there, which numba implements with NumPy's
algorithm on the Generator's own bit generator, so the draws and the generator's state after them
are those of the same calls from Python. No private module of numba or numpy is used. In the
chain's pass a draw and its sum cost about 3 ns a sample on the benchmark machine, where numpy's
vectorised ``standard_normal`` alone takes 11 ns a draw. ``tests/test_noise.py`` checks the
stream and the state after it against numpy's, bit for bit, for the installed versions;
``benchmarks/check_oldest.sh`` runs it on the oldest numba and numpy the lower bounds allow.
"""
from __future__ import annotations

from numba import njit


@njit(cache=True)
def add_white(x, rng, std, y):
    """``y = x + std e`` elementwise, ``e`` the next ``x.size`` draws of ``rng.standard_normal()``:
    bit-identical to ``x + std * rng.standard_normal(x.size)`` called from Python, and ``rng``
    left where that call leaves it."""
    for k in range(x.shape[0]):
        y[k] = x[k] + std * rng.standard_normal()
