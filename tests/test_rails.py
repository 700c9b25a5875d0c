"""The sensor's rails (:mod:`hwid.identify.rails`): runs of one exact reading at the records'
extremes, told from a quantised sensor at rest and from a signal that mostly sits still."""
from __future__ import annotations

import numpy as np

from hwid.identify.rails import MIN_RUN, find_rails


def _sine(n=4000, amp=1.0, noise=0.01, seed=0):
    rng = np.random.default_rng(seed)
    t = np.arange(n) * 0.05
    return amp * np.sin(0.3 * t) + noise * rng.standard_normal(n)


def test_a_clipping_sensor_reads_its_two_rails():
    y = np.clip(_sine(), -0.8, 0.7)
    rails = find_rails([y[:2000], y[2000:]], ["a", "b"])
    assert [(r.side, r.value) for r in rails] == [("low", -0.8), ("high", 0.7)]
    for r in rails:
        at = y == r.value
        # the samples on the rail in runs of at least MIN_RUN (each peak's plateau; the noise's
        # brief touches at a plateau's edges are not counted)
        assert 0.98 * at.sum() <= r.samples <= at.sum() and r.runs >= 4 and r.records == ("a", "b")
        assert r.samples >= MIN_RUN * r.runs


def test_one_rail_only_where_one_side_clips():
    rails = find_rails([np.minimum(_sine(seed=1), 0.9)])
    assert [(r.side, r.value) for r in rails] == [("high", 0.9)]


def test_a_noisy_sensor_that_never_clips_has_no_rail():
    assert find_rails([_sine(seed=2), _sine(seed=3)]) == []


def test_a_quantised_sensor_at_rest_is_no_rail():
    """An encoder's counts: holds at the ends of a move read one count for as long as they last, as
    every other hold does, so a repeat there is no evidence of a rail."""
    moves = np.concatenate([np.linspace(0, 300, 400), np.full(300, 300.0), np.linspace(300, -200, 600),
                            np.full(300, -200.0), np.linspace(-200, 50, 300), np.full(200, 50.0)])
    counts = np.round(moves + 0.3 * np.random.default_rng(4).standard_normal(moves.size))
    assert find_rails([counts]) == []


def test_a_signal_that_mostly_sits_still_is_no_rail():
    """A temperature column that reads 35 throughout, with a few glitches: nothing tells its noise."""
    y = np.full(400, 35.0)
    y[[50, 120, 300]] = [36.0, 46.0, 72.0]
    assert find_rails([y]) == []
