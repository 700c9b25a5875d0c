"""Monte Carlo check of stage 1 from a recorded history (``hwid.identify.history``): over 40 logs of
30 random-order levels (tests/test_history.py's plant: backlash +-0.5, S^d 1.3, G = 1/(s+2) with
time constant 0.5 s, cubic h, white noise 0.01), at holds of 5-10 s and of 2-6 s:

- each settled level's standardised error ``(X_k - truth) / se_k`` has sd 1 and no bias after a
  rise or a fall (the settle cut's leftover approach, and short levels read on their approach);
- the 95 % intervals of d^+, d^-, S^d and the dead band cover the truth within binomial limits
  (two-sided binomial test at 0.005 on the runs where the quantity is determined); at 2-6 s
  holds d+ can fall short (33/39 here, about 90 % over 100 logs): marked as a known failure.

experiments/interval_coverage/run.py measures the same on 100 logs for the docs. About 3 minutes.
"""
from __future__ import annotations

import functools

import numpy as np
import pytest
import yaml
from scipy import stats

import rigs
from hwid import config
from hwid.identify.history import HistoryFit, settled_levels
from hwid.model import from_config
from hwid.plant import Record

DT = 0.05
RUNS = 40
ALPHA = 0.005


def _truth():
    cfg = config.loads(yaml.safe_dump(rigs.small(**{"plant.output_nonlinearity.polynomial": [0, 1.0, 0.8, -0.6],
                                                    "plant.input_nonlinearity.slope_down": 1.3})))
    return from_config(cfg.plant)


@functools.lru_cache(maxsize=None)
def _study(shortest: int, longest: int):
    """The levels' standardised errors (all, after rises and after falls of over 0.5) and, per
    quantity, (runs covering the truth, runs where it is determined) over :data:`RUNS` logs."""
    truth = _truth()
    norm = truth.normalised().input
    want = {"d_plus": norm.d_plus, "d_minus": norm.d_minus, "slope_down": norm.slope_down,
            "dead_band": norm.d_plus - norm.d_minus}
    hits, counted = dict.fromkeys(want, 0), dict.fromkeys(want, 0)
    z_level, z_rise, z_fall = [], [], []
    for seed in range(RUNS):
        rng = np.random.default_rng(seed)
        holds = rng.integers(shortest, longest, 30)
        u = np.repeat(rng.uniform(-1.2, 1.2, 30), holds)
        y = truth.simulate(u, DT, gear=0.0).x + 0.01 * rng.standard_normal(u.size)
        levels, warns = settled_levels([Record("log", DT, u, y)])
        settled = truth.steady_output(u[np.cumsum(holds) - 1], 0.0)     # h(G(0) F[U_k]), eqs. 5, 8
        for k, lv in enumerate(levels):
            if lv.scored:
                z = (lv.x - settled[k]) / lv.se
                z_level.append(z)
                if k and abs(settled[k] - settled[k - 1]) > 0.5:
                    (z_rise if settled[k] > settled[k - 1] else z_fall).append(z)
        res = HistoryFit(types=("backlash",)).fit(levels, warns).result_
        for name, value in want.items():
            if res.ci[name] is not None:
                counted[name] += 1
                hits[name] += res.ci[name][0] <= value <= res.ci[name][1]
    print(f"holds {shortest}-{longest} samples: levels' standardised errors sd {np.std(z_level):.3f}, mean after a "
          f"rise {np.mean(z_rise):.3f}, after a fall {np.mean(z_fall):.3f}; coverage",
          {k: f"{hits[k]}/{counted[k]}" for k in want})
    return np.array(z_level), np.array(z_rise), np.array(z_fall), {k: (hits[k], counted[k]) for k in want}


HOLDS = [(100, 200), (40, 120)]
IDS = ["holds 5-10 s", "holds 2-6 s"]


@pytest.mark.slow
@pytest.mark.parametrize("shortest,longest", HOLDS, ids=IDS)
def test_settled_levels_are_unbiased_with_their_standard_errors(shortest, longest):
    z_level, z_rise, z_fall, _ = _study(shortest, longest)
    assert 0.9 < np.std(z_level) < 1.1                  # MC error of the sd over ~1000 levels: 0.02
    assert abs(np.mean(z_level)) < 0.1
    for side in (z_rise, z_fall):                       # ~60 levels each: MC error of the mean 0.13
        assert abs(np.mean(side)) < 0.45, side


@pytest.mark.slow
@pytest.mark.parametrize("shortest,longest", [
    HOLDS[0],
    pytest.param(*HOLDS[1], marks=pytest.mark.xfail(
        strict=False, reason="known: at 2-6 s holds d+ covers 33/39 on these logs (about 90 % "
                             "over 100) with unbiased levels; the cause is not found yet"))], ids=IDS)
def test_border_intervals_cover_the_truth(shortest, longest):
    *_, cover = _study(shortest, longest)
    for name, (hits, counted) in cover.items():
        assert counted >= 0.9 * RUNS, (name, counted)
        assert stats.binomtest(hits, counted, 0.95).pvalue > ALPHA, (name, hits, counted)
