"""hwid.blocks.noise.standard_normal draws numpy's own stream: every draw and the generator's state
after them equal ``Generator.standard_normal``'s, bit for bit, over the ziggurat's fast path, its
wedges and its tail."""
import numpy as np
import pytest
from numba import njit

from hwid.blocks.noise import standard_normal


@njit
def _draws(rng, n):
    out = np.empty(n)
    bitgen = rng.bit_generator
    for k in range(n):
        out[k] = standard_normal(bitgen)
    return out


@pytest.mark.parametrize("seed", [0, 1, 20240611])
def test_the_stream_is_numpys(seed):
    ours, theirs = np.random.default_rng(seed), np.random.default_rng(seed)
    e = _draws(ours, 2_000_000)
    assert e.tobytes() == theirs.standard_normal(e.size).tobytes()
    assert np.sum(np.abs(e) > 3.6541528853610088) > 100      # the tail beyond the base layer was drawn
    assert ours.bit_generator.state == theirs.bit_generator.state
    assert ours.standard_normal(5).tobytes() == theirs.standard_normal(5).tobytes()


def test_the_stream_is_numpys_for_another_bit_generator():
    ours, theirs = (np.random.Generator(np.random.Philox(7)) for _ in range(2))
    assert _draws(ours, 300_000).tobytes() == theirs.standard_normal(300_000).tobytes()
