"""Monte Carlo check of the stage-1 intervals: over 250 noise realisations the 95 % intervals of
d^+, S^d, d^- must cover the truth between 90 % and 99 % of the time.

Cheap by design: the paper's h and backlash behind a fast G (time constant 0.2 s), 5 s holds,
AR(1) output noise (pole 0.5) so that the batch-means / AR standard errors are exercised, the degree
and type fixed (their selection is tested elsewhere). About 0.1 s a run.
"""
from __future__ import annotations

import numpy as np

import plants
from hwid import config
from hwid.identify.nonlinear import identify_nonlinear
from hwid.model import from_config
from hwid.plant import make_plant

CFG = plants.config_text(plants.PAPER_FAST_G, name="coverage", seed=0,
                         **{"plant.noise.ar": 0.5,
                            "identification": {"nonlinear": {"degree": 5, "input_type": "backlash"}}})
RUNS = 250


def test_interval_coverage_monte_carlo():
    cfg = config.loads(CFG)
    truth = from_config(cfg.plant).normalised().input
    keys = ("d_plus", "slope_down", "d_minus")
    hits = dict.fromkeys(keys, 0)
    z = {k: [] for k in keys}
    for ss in np.random.SeedSequence(20240905).spawn(RUNS):
        res, _ = identify_nonlinear(cfg, plant=make_plant(cfg, seed=ss))
        for k in keys:
            lo, hi = res.ci[k]
            t = getattr(truth, k)
            hits[k] += lo <= t <= hi
            z[k].append((getattr(res, k) - t) / ((hi - lo) / (2 * res.fit["t_quantile"])))
    cover = {k: hits[k] / RUNS for k in keys}
    print("coverage", cover, "std of standardised errors", {k: round(float(np.std(v)), 3) for k, v in z.items()})
    for k in keys:
        assert 0.90 <= cover[k] <= 0.99, (k, cover[k])
        assert abs(np.mean(z[k])) < 0.25, (k, np.mean(z[k]))     # no bias beyond MC error (~0.07)
