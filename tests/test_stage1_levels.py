"""Stage 1's held levels from records of any make (issue 45, item 7).

A record cut out of a longer one keeps its parent's level list (its sample numbers then point past
its end); holds shorter than the settle cut are extrapolated, read from an evidently steady tail or
left out with one line naming time, level and why; too few levels is a :class:`hwid.HwidError`.
The plant: hwid's own chain, first-order G of time constant 0.05 s, noise s.d. 0.02.
"""
from __future__ import annotations

import json
from dataclasses import replace

import numpy as np
import pytest

from hwid import HwidError
from hwid.blocks.linear import LinearBlock
from hwid.blocks.static import PolynomialH
from hwid.identify.history import HistoryFit, record_levels, settled_levels
from hwid.model import HWModel, InputNonlinearity
from hwid.plant import Record
from hwid.recorded import level_segments

DT, SIGMA = 0.02, 0.02
PLANT = HWModel(InputNonlinearity("backlash", 1.2, 0.8, 0.4, -0.2), LinearBlock((1.0,), (0.05, 1.0), 0.0),
                PolynomialH((0.0, 1.0, 0.25)))
NORM = PLANT.normalised().input
TRUTH = {"slope_down": NORM.slope_down, "d_plus": NORM.d_plus, "d_minus": NORM.d_minus}


def _record(u, seed=0, name="lab"):
    y = PLANT.simulate(u, DT, gear=0.0).x + SIGMA * np.random.default_rng(seed).standard_normal(u.size)
    return Record(name, DT, u, y, attrs={"segments": json.dumps(level_segments(u))})


def _staircase(hold_s):
    levels = np.r_[np.linspace(-1.5, 1.5, 8), np.linspace(1.5, -1.5, 8)[1:], np.linspace(-1.5, 1.5, 8)[1:]]
    return np.repeat(levels, int(round(hold_s / DT)))


def test_a_block_cut_out_of_a_record_finds_its_own_levels():
    whole = _record(_staircase(2.0))
    half = whole.u.size // 2
    block = replace(whole, name="lab:fit", u=whole.u[half:], y=whole.y[half:], attrs=dict(whole.attrs))
    segs = record_levels(block)
    assert segs == level_segments(block.u)
    levels, _ = settled_levels([block])
    assert sum(lv.scored for lv in levels) >= 10


def test_holds_shorter_than_the_cut_are_named_and_the_truth_is_covered():
    """Holds of 2-3 samples (0.1-0.2 settling times) between settled ones: the one of 3 samples is
    a level left out with one line giving its time and level; the one of 2 is part of the input's
    passage between levels, whose turning points F's recursion runs over. Over 12 noise seeds the
    95 % intervals cover the truth at least 9 times each (a binomial 95 % coverage falls below that
    with probability 2e-3)."""
    long = _staircase(2.0)
    u = np.concatenate([long[:400], np.full(3, 0.7), long[400:800], np.full(2, -0.9), long[800:]])
    covered = dict.fromkeys(TRUTH, 0)
    for seed in range(12):
        levels, warns = settled_levels([_record(u, seed)])
        short = [w for w in warns if "not scored" in w]
        assert len(short) == 1 and "u = 0.7 (t = 8-8.06 s" in short[0], short
        assert [lv.u for lv in levels if lv.n == 0] == [0.7, -0.9]
        res = HistoryFit(max_degree=2, types=("backlash",)).fit(levels, warns).result_
        for name, truth in TRUTH.items():
            covered[name] += res.ci[name][0] <= truth <= res.ci[name][1]
    assert min(covered.values()) >= 9, covered


def test_too_few_levels_is_a_hwid_error():
    u = np.repeat([0.0, 1.0, 0.0], 100)
    levels, warns = settled_levels([_record(u)])
    with pytest.raises(HwidError, match="at least 4 settled levels"):
        HistoryFit().fit(levels, warns)


def _pushed(seed):
    """The staircase record with pushes added to y while u holds: +0.3 (15 noise s.d.) over 30
    samples in the middle of holds 3, 8, 12 and 17, and a slip of -0.2 that stays from 60 % of
    hold 10 on. Returns the record and the times (s) where the disturbances begin."""
    u = _staircase(2.0)
    rec = _record(u, seed)
    y, hold, starts = rec.y.copy(), 100, []
    for j in (3, 8, 12, 17):
        a = j * hold + 50
        y[a:a + 30] += 0.3
        starts.append(a * DT)
    a = 10 * hold + 60
    y[a:(10 + 1) * hold] -= 0.2
    starts.append(a * DT)
    return replace(rec, y=y), sorted(starts)


def test_pushed_holds_are_detected_and_the_truth_is_covered():
    """Every injected disturbance is named (where it begins, to a sample or two) and no other;
    with the disturbed parts left out the intervals cover the truth in at least 9 of 12 seeds."""
    covered = dict.fromkeys(TRUTH, 0)
    for seed in range(12):
        rec, starts = _pushed(seed)
        levels, warns = settled_levels([rec])
        named = [float(w.split("from t = ")[1].split(" s")[0]) for w in warns if "the output moved by" in w]
        assert len(named) == len(starts), warns
        assert np.allclose(named, starts, atol=2 * DT), (named, starts)
        res = HistoryFit(max_degree=2, types=("backlash",)).fit(levels, warns).result_
        for name, truth in TRUTH.items():
            covered[name] += res.ci[name][0] <= truth <= res.ci[name][1]
    assert min(covered.values()) >= 9, covered


def test_undisturbed_holds_are_not_flagged():
    for seed in range(12):
        _, warns = settled_levels([_record(_staircase(2.0), seed)])
        assert not [w for w in warns if "the output moved by" in w], warns
