"""The measurement noise xi of ``y = x + xi`` (eqs. 3a-c), drawn inside numba kernels.

:func:`standard_normal` gives exactly the stream of ``numpy.random.Generator.standard_normal``: the
same 256-layer ziggurat (numpy's ``random_standard_normal``), with numpy's tables and the bit
generator's ``next_uint64`` / ``next_double`` as numba's port of numpy's generators exposes them
(``numba.np.random``, internal modules of numba), the same draws in the same order and the same
arithmetic. Two things differ, neither in the numbers: the sign is applied by multiplying by +-1
(exact) instead of by a branch the processor mispredicts on every other draw, and the rejection
step (1.5 % of the draws) is a call out of the hot path. A draw costs about 4 ns instead of
numpy's 11 ns and numba's own ``rng.standard_normal()`` 9 ns on the benchmark machine (README,
Benchmarks). ``tests/test_noise.py`` checks the stream and the generator's state after it against
numpy's.
"""
from __future__ import annotations

import numpy as np
from numba import njit
from numba.np.random._constants import fi_double, ki_double, wi_double, ziggurat_nor_inv_r, ziggurat_nor_r
from numba.np.random.generator_core import next_double, next_uint64


@njit(cache=True)
def _layer(r):
    """A 64-bit draw split as the ziggurat reads it: ``(layer, |mantissa|, signed value)``."""
    idx = r & 0xFF
    r >>= 8
    rabs = (r >> 1) & 0x000FFFFFFFFFFFFF
    return idx, rabs, np.int64(rabs) * wi_double[idx] * (1.0 - 2.0 * np.float64(r & 0x1))


@njit(cache=True)
def _rejection(bitgen, idx, rabs, x):
    """The ziggurat's slow path, from a draw outside layer ``idx``'s rectangle until one is accepted:
    the tail beyond ``ziggurat_nor_r`` for the base layer, else the wedge test, then new draws."""
    while True:
        if idx == 0:
            while True:
                xx = -ziggurat_nor_inv_r * np.log1p(-next_double(bitgen))
                yy = -np.log1p(-next_double(bitgen))
                if yy + yy > xx * xx:
                    if (rabs >> 8) & 0x1:
                        return -(ziggurat_nor_r + xx)
                    return ziggurat_nor_r + xx
        if (fi_double[idx - 1] - fi_double[idx]) * next_double(bitgen) + fi_double[idx] < np.exp(-0.5 * x * x):
            return x
        idx, rabs, x = _layer(next_uint64(bitgen))
        if rabs < ki_double[idx]:
            return x


@njit(cache=True)
def standard_normal(bitgen):
    """One draw of ``Generator.standard_normal`` from ``bitgen`` (a Generator's ``bit_generator``
    inside ``@njit`` code); draw after draw, the generator's own stream."""
    idx, rabs, x = _layer(next_uint64(bitgen))
    if rabs < ki_double[idx]:
        return x
    return _rejection(bitgen, idx, rabs, x)
