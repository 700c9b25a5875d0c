"""Undetermined is a result (issue 45, item 3): what the levels cannot determine is reported as
such -- interval None and a reason naming the experiment that would determine it -- never as a
number with an interval of zero width or one clipped at a bound.

The plant: hwid's own chain (backlash S^a 1.2, S^d 0.8, d+ 0.4, d- -0.2; G a first-order lag of
0.05 s; h = w + 0.25 w^2), noise s.d. 0.02, levels held 2 s.
"""
from __future__ import annotations

import json

import numpy as np
import pytest

from hwid import HwidError
from hwid.identify.determinable import design
from hwid.identify.history import HistoryFit, settled_levels
from hwid.identify.result import HistoryResult, format_history
from test_stage1_levels import DT, TRUTH, _record


def _fit(levels_u, seed=0, **kw):
    u = np.repeat(np.asarray(levels_u, float), int(round(2.0 / DT)))
    levels, warns = settled_levels([_record(u, seed)])
    return HistoryFit(**kw).fit(levels, warns).result_


def test_a_design_without_the_descending_branch_leaves_it_undetermined():
    res = _fit(np.linspace(-1.5, 1.5, 12), max_degree=2, types=("backlash",))
    for name in ("slope_down", "d_minus", "dead_band"):
        assert res.ci[name] is None
        assert "approached from above" in res.undetermined[name]
        assert "hold at least 2 distinct levels below d- approached from above" in res.undetermined[name]
    lo, hi = res.ci["d_plus"]
    assert lo <= TRUTH["d_plus"] <= hi
    text = format_history(res)
    assert "dead band d+ - d- = undetermined" in text and "S^d = undetermined" in text


def test_undetermined_intervals_go_through_the_json():
    res = _fit(np.linspace(-1.5, 1.5, 12), max_degree=2, types=("backlash",))
    d = json.loads(json.dumps(res.to_dict(), allow_nan=False))
    assert d["ci"]["dead_band"] is None and d["undetermined"]["dead_band"]
    back = HistoryResult.from_dict(d)
    assert back.ci["dead_band"] is None and back.undetermined == res.undetermined


def test_levels_that_determine_nothing_are_one_clear_error():
    # what exclude windows around every move left: pieces that each open at a level and step to
    # u = 0, so every level with a known direction sits at u = 0
    n = int(round(2.0 / DT))
    records = [_record(np.repeat([start, 0.0], n), seed, name=f"piece{seed}")
               for seed, start in enumerate([1.0, 0.5, 1.2, 0.8, 1.4])]
    levels, warns = settled_levels(records)
    with pytest.raises(HwidError, match="0 distinct level.s. approached from below .none. and 1 from above .0."):
        HistoryFit().fit(levels, warns)


def test_three_targets_determine_the_borders_but_not_the_fit():
    """The STS3215 logs' design: targets 0, +100, -100 counts in turn. Four distinct (level,
    direction) points for h_bar of degree 1 and three borders: the estimates stand, the fit cannot
    be judged, and the type is undetermined."""
    res = _fit([0.0, 1.0, 0.0, -1.0] * 4 + [0.0], max_degree=3)
    assert len(res.h_coefficients) == 2
    assert "adequacy" in res.undetermined and "type" in res.undetermined
    assert "(fit UNDETERMINED" in format_history(res)


def test_a_rich_design_leaves_nothing_undetermined():
    levels = np.r_[np.linspace(-1.5, 1.5, 8), np.linspace(1.5, -1.5, 8)[1:], np.linspace(-1.5, 1.5, 8)[1:]]
    res = _fit(levels, max_degree=2)
    assert res.undetermined == {}
    for name, truth in TRUTH.items():
        lo, hi = res.ci[name]
        assert hi > lo


def test_design_counts_directions_through_the_passages():
    from hwid.identify.result import Level
    seq = [Level("r", 0, 0.0, 0, 1, 5), Level("r", 1, 1.0, 0, 1, 0, False), Level("r", 2, 0.5, 0, 1, 5),
           Level("r", 3, 0.8, 0, 1, 5), Level("r", 4, 0.8, 0, 1, 5)]
    des = design(seq)
    assert des.up == (0.8,) and des.down == (0.5,)
