"""The runs of a boolean mask (hwid.masks), against runs counted by hand on small masks."""
import numpy as np

from hwid.masks import run_lengths, runs


def test_runs_and_their_lengths():
    m = np.array([1, 1, 0, 0, 1, 0, 1, 1, 1], bool)
    assert runs(m) == [(0, 2), (4, 5), (6, 9)]
    assert run_lengths(m).tolist() == [2, 1, 3]
    assert runs(np.zeros(4, bool)) == [] and run_lengths(np.zeros(4, bool)).size == 0
    assert runs(np.ones(3, bool)) == [(0, 3)]


def test_runs_rebuild_the_mask():
    rng = np.random.default_rng(np.random.SeedSequence(5))
    m = rng.random(500) < 0.4
    back = np.zeros_like(m)
    for a, b in runs(m):
        assert a < b and m[a:b].all()
        back[a:b] = True
    assert (back == m).all()
