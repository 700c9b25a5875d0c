"""An effect's other readings of one fit (``Effect.other_readings``): a rate limit's actuator reset
at every call or carried over, which the fit experiments may not tell apart. Where they fit those
experiments alike, the reading that predicts the validation experiments better is kept
(``EffectFitter._reading``)."""
from __future__ import annotations

from types import SimpleNamespace

import numpy as np
import pytest

from hwid.diagnose.effects import RateLimit
from hwid.diagnose.rank import SAME_FIT, EffectFitter


def test_a_rate_limits_other_readings_are_the_actuators_two_memories():
    eff = RateLimit()
    (other,) = eff.other_readings([1.48, 1.0])
    assert other.tolist() == [1.48, 0.0]
    # a fit the experiments could not tell left between the two: both are read
    assert [o.tolist() for o in eff.other_readings([0.3, 0.51])] == [[0.3, 0.0], [0.3, 1.0]]


class _Fitter:
    """``EffectFitter._reading`` on candidates whose fit criterion and validation gap are set."""

    _reading = EffectFitter._reading

    def __init__(self, scores: dict):
        self.scores = scores           # carried -> (fit criterion, validation gap)

    def _cand(self, theta):
        crit, gap = self.scores[float(theta[1])]
        return SimpleNamespace(theta=np.asarray(theta, float), k=2.0, crit=crit, gap_after=gap)

    def fit_criterion(self, c, n):
        return c.crit

    def _score(self, eff, theta, k):
        return self._cand(theta)


@pytest.mark.parametrize("other_fit, other_gap, kept", [
    (0.5 * SAME_FIT, 0.010, 0.0),     # fits alike, predicts better: the other reading
    (0.5 * SAME_FIT, 0.040, 1.0),     # fits alike, predicts worse: the fit's own
    (2.0 * SAME_FIT, 0.010, 1.0),     # the fit experiments tell them apart: the fit's own
])
def test_the_reading_kept(other_fit, other_gap, kept):
    f = _Fitter({1.0: (0.0, 0.037), 0.0: (other_fit, other_gap)})
    best = f._reading(RateLimit(), f._cand([1.48, 1.0]), 1000.0)
    assert best.theta[1] == kept


def test_a_reading_left_between_the_two_memories_is_read_at_both():
    """A judged rig carrying its actuator, fitted at ``carried`` 0.51 (the fit experiments alike at
    any value), left its validation multisine 6.5x the floor (0.033 against 0.0051); carried over
    (1) it predicts it at the floor, reset (0) at 13x. The carried reading is kept."""
    f = _Fitter({0.51: (0.0, 0.0100), 1.0: (0.0, 0.0051), 0.0: (0.0, 0.0190)})
    best = f._reading(RateLimit(), f._cand([1.508, 0.51]), 1000.0)
    assert best.theta.tolist() == [1.508, 1.0]
