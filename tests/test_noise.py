"""hwid.blocks.noise.add_white draws numpy's own stream: ``y`` equals ``x + std *
Generator.standard_normal(n)`` bit for bit, and the generator is left in the state that call leaves
it in, over the ziggurat's fast path, its wedges and its tail, for the installed numba and numpy."""
import numpy as np
import pytest

from hwid.blocks.noise import add_white

TAIL = 3.6541528853610088      # the ziggurat's base layer ends here: beyond it, the tail algorithm


def same_state(a, b) -> bool:
    """Two bit generators' ``state`` dicts hold the same values (Philox's hold arrays)."""
    if isinstance(a, dict):
        return isinstance(b, dict) and a.keys() == b.keys() and all(same_state(a[k], b[k]) for k in a)
    return bool(np.array_equal(a, b))


@pytest.mark.parametrize("seed", [0, 1, 20240611])
def test_the_stream_is_numpys(seed):
    ours, theirs = np.random.default_rng(seed), np.random.default_rng(seed)
    x = np.random.default_rng(seed + 1).uniform(-2.0, 2.0, 2_000_000)
    y = np.empty_like(x)
    add_white(x, ours, 0.37, y)
    e = theirs.standard_normal(x.size)
    assert y.tobytes() == (x + 0.37 * e).tobytes()
    assert np.sum(np.abs(e) > TAIL) > 100                     # the tail beyond the base layer was drawn
    assert same_state(ours.bit_generator.state, theirs.bit_generator.state)
    assert ours.standard_normal(5).tobytes() == theirs.standard_normal(5).tobytes()


def test_the_stream_is_numpys_for_another_bit_generator():
    ours, theirs = (np.random.Generator(np.random.Philox(7)) for _ in range(2))
    x = np.linspace(-1.0, 1.0, 300_000)
    y = np.empty_like(x)
    add_white(x, ours, 1.5, y)
    assert y.tobytes() == (x + 1.5 * theirs.standard_normal(x.size)).tobytes()
    assert same_state(ours.bit_generator.state, theirs.bit_generator.state)
    assert ours.standard_normal(5).tobytes() == theirs.standard_normal(5).tobytes()


def test_blocks_continue_one_stream():
    """Drawn block by block, as the chain does, the noise is the one call's: nothing is buffered
    between calls."""
    ours, theirs = np.random.default_rng(5), np.random.default_rng(5)
    x = np.zeros(10_007)
    y = np.empty_like(x)
    for s in range(0, x.size, 512):
        add_white(x[s:s + 512], ours, 1.0, y[s:s + 512])
    assert y.tobytes() == (x + theirs.standard_normal(x.size)).tobytes()
