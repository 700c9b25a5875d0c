"""h_bar's root-shifted readings (hwid/identify/readings.py): a fit landed on another real root of
h_bar moves to the reading the paper's h^-1(0) = 0 picks on the levels' range; where several roots
lie in that range the borders and h_bar are undetermined and the readings carried; the paper's
plant keeps one reading."""
from __future__ import annotations

import numpy as np
import pytest
import yaml

import plants
import rigs
from hwid import config
from hwid.identify import readings
from hwid.identify.history import HistoryFit, identify_history, settled_levels
from hwid.identify.result import HistoryResult, format_history
from hwid.model import from_config
from hwid.plant import Record

DT = 0.05
#: tests/test_history.py's plant: h_bar = 0.5 w + 0.2 w^2 - 0.075 w^3 (roots 0, -1.573, 4.239)
CUBIC = [0, 1.0, 0.8, -0.6]
#: h_bar = -0.2 w + 0.1 w^2 + w^3, roots 0, 0.40, -0.50 inside the levels' range: the paper's
#: assumption does not hold on the data
FOLDED = [0, -0.4, 0.4, 8.0]


def _plant(poly):
    return from_config(config.loads(yaml.safe_dump(rigs.small(**{
        "plant.output_nonlinearity.polynomial": poly, "plant.input_nonlinearity.slope_down": 1.3}))).plant)


def _log(truth, seed: int, shortest=100, longest=200):
    rng = np.random.default_rng(seed)
    u = np.repeat(rng.uniform(-1.2, 1.2, 30), rng.integers(shortest, longest, 30))
    return [Record("log", DT, u, truth.simulate(u, DT, gear=0.0).x + 0.01 * rng.standard_normal(u.size))]


def _covers(res, norm, keys=("d_plus", "d_minus", "slope_down", "dead_band")):
    truth = {"d_plus": norm.d_plus, "d_minus": norm.d_minus, "slope_down": norm.slope_down,
             "dead_band": norm.d_plus - norm.d_minus}
    return {k: res.ci[k][0] <= truth[k] <= res.ci[k][1] for k in keys}


def test_shift_is_exact_on_the_steady_levels():
    """The reading moved to another real root of h_bar predicts every steady level of a history as
    the truth does (eq. 5), for either type; S^d is the same, a Backlash's dead band moves by
    beta (1 - 1/S^d), a Backlash-Inverse's does not."""
    from hwid.model import InputNonlinearity
    coef = np.array([0.0, 0.5, 0.2, -0.075])
    u = np.random.default_rng(0).uniform(-1.2, 1.2, 40)
    for kind, state in (("backlash", 0.1), ("backlash_inverse", 0.0)):
        f = InputNonlinearity(kind, 1.0, 1.3, 0.5, -0.5)
        x = np.polynomial.polynomial.polyval(f.steady(u, state), coef)
        for beta in readings.real_roots(coef, 2.4)[[0, 2]]:
            r = readings.shifted(kind, 1.3, 0.5, -0.5, coef, beta)
            g = InputNonlinearity(kind, 1.0, r.slope_down, r.d_plus, r.d_minus)
            x2 = np.polynomial.polynomial.polyval(g.steady(u, state - beta), r.h_coefficients)
            assert np.max(np.abs(x2[1:] - x[1:])) < 1e-12
            band = 1.0 + beta * (1 - 1 / 1.3) if kind == "backlash" else 1.0
            assert r.dead_band == pytest.approx(band, abs=1e-12) and r.slope_down == 1.3


def test_a_fit_at_the_rival_reading_moves_back_to_the_truth():
    """The rival reading of the cubic plant (its h_bar's root -1.573 made the origin: d+ = -1.073)
    holds the levels' range [0.67, 2.25] with one root of its h_bar in it, the truth's origin:
    :func:`readings.assess` picks the truth's reading exactly, and the covariance carried there by
    :func:`readings.transform` equals the one the truth's own parametrisation gives to first order."""
    coef = np.array([0.0, 0.5, 0.2, -0.075])
    beta = readings.real_roots(coef, 2.4)[0]
    rival = readings.shifted("backlash", 1.3, 0.5, -0.5, coef, beta)
    verdict = readings.assess("backlash", 1.3, rival.d_plus, rival.d_minus, rival.h_coefficients,
                              (-0.91 - beta, 0.7 - beta))
    assert verdict.determined and verdict.shifted
    c = verdict.chosen
    assert (c.d_plus, c.d_minus) == pytest.approx((0.5, -0.5), abs=1e-12)
    assert c.h_coefficients == pytest.approx(coef, abs=1e-12)
    # a random covariance there and back: the map is its own inverse's inverse
    rng = np.random.default_rng(1)
    a = rng.standard_normal((6, 6)) * 1e-3
    cov = a @ a.T
    params = np.r_[coef[1:], 0.5, 1.3, -0.5]
    there, cov_there = readings.transform("backlash", params, cov, beta)
    back, cov_back = readings.transform("backlash", there, cov_there, -beta)
    assert back == pytest.approx(params, abs=1e-10)
    assert np.max(np.abs(cov_back - cov)) < 1e-8 * np.max(np.abs(cov))


def test_history_landed_on_the_rival_is_shifted_back():
    """Seed 13 of experiments/interval_coverage (30 levels, 5-10 s holds): the fit lands on the rival
    reading (d+ = -1.069 [-1.102, -1.036], chi2 34.267 against 34.265 at the truth's); it is moved to
    the truth's with one warning line naming the assumption, and the truth is inside every interval."""
    truth = _plant(CUBIC)
    res = identify_history(_log(truth, 13), types=("backlash",))
    assert any("h^-1(0) = 0" in w and "shifted" in w for w in res.warnings)
    assert all(_covers(res, truth.normalised().input).values()), res.ci
    assert res.readings == () and not res.undetermined
    assert len(res.h_coefficients) == 4
    assert res.h_coefficients[1:] == pytest.approx([0.5, 0.2, -0.075], abs=0.02)


def test_history_forced_at_the_rival_start_is_shifted_back(monkeypatch):
    """The same plant on seed 1 with the fit's search started only at the rival reading: the result
    is the truth's reading (the same as from the ordinary starts), the truth inside every interval."""
    from hwid.identify import history
    truth = _plant(CUBIC)
    levels, warns = settled_levels(_log(truth, 1))
    plain = HistoryFit(3, ("backlash",)).fit(levels, warns).result_
    beta = readings.real_roots(plain.h_coefficients, 2.4)[0]
    rival = readings.shifted("backlash", plain.slope_down, plain.d_plus, plain.d_minus, plain.h_coefficients, beta)
    orig = history._Problem.starts
    monkeypatch.setattr(history._Problem, "starts", lambda self, width, keep=6: [
        np.r_[rival.d_plus, np.log(rival.slope_down), np.log(rival.dead_band), s[3:]] for s in orig(self, width, 1)])
    res = HistoryFit(3, ("backlash",)).fit(levels, warns).result_
    assert any("reading is shifted" in w for w in res.warnings)
    assert res.d_plus == pytest.approx(plain.d_plus, abs=1e-5)
    assert res.dead_band == pytest.approx(plain.dead_band, abs=1e-5)
    assert all(_covers(res, truth.normalised().input).values()), res.ci


def test_roots_in_the_levels_range_leave_the_borders_undetermined(tmp_path):
    """h_bar vanishing at -0.5, 0 and 0.4, all where the levels go: d+, d-, the dead band and h_bar
    are undetermined (interval None, the readings named in the reason), S^d is not and holds the
    truth; one reading is the truth's, within its intervals; the readings survive history.h5 and a
    file written without them reads back with none."""
    from hwid.results import read_history, write_history
    truth = _plant(FOLDED)
    norm = truth.normalised().input
    res = identify_history(_log(truth, 1), types=("backlash",))
    for k in ("d_plus", "d_minus", "dead_band", "h_coefficients"):
        assert k in res.undetermined and "h_bar vanishes at" in res.undetermined[k]
    assert res.ci["d_plus"] is None and res.ci["dead_band"] is None
    assert all(c is None for c in res.ci["h_coefficients"])
    assert res.ci["slope_down"][0] <= norm.slope_down <= res.ci["slope_down"][1]
    assert len(res.readings) == 3
    hits = [r for r in res.readings
            if all(r["ci"][k][0] <= v <= r["ci"][k][1]
                   for k, v in (("d_plus", 0.5), ("d_minus", -0.5), ("dead_band", 1.0)))]
    assert len(hits) == 1
    assert hits[0]["h_coefficients"][1:] == pytest.approx([-0.2, 0.1, 1.0], abs=0.03)
    assert "reading undetermined" in format_history(res)
    path = write_history(tmp_path / "history.h5", None, res)
    assert read_history(path).to_dict() == res.to_dict()
    old = res.to_dict()
    old.pop("readings")
    assert HistoryResult.from_dict(old).readings == ()


def test_whole_fit_with_roots_in_range_is_undetermined_and_exact():
    """The whole fit on levels joined by ramps of the folded plant: the readings are exact (each
    record's G starts at a fitted rest level that moves with F's output: the same residual), so the
    borders and h_bar are undetermined and one reading's d+ interval holds the truth's (it did on 7 of
    the noise seeds 1-8)."""
    from hwid.identify.whole import Structure, WholeModelFit
    rng = np.random.default_rng(0)
    u, current = [], 0.0
    for _ in range(24):
        target = rng.uniform(-1.2, 1.2)
        u += list(np.linspace(current, target, 10)) + [target] * 40
        current = target
    u = np.array(u)
    truth = _plant(FOLDED)
    y = truth.simulate(u, DT, gear=0.0).x + 0.01 * np.random.default_rng(1).standard_normal(u.size)
    res = WholeModelFit(max_degree=3, structures=[Structure(1, 0)], types=("backlash",)).fit(
        [Record("levels", DT, u, y)]).result_
    assert res.ci["d_plus"] is None and "h_bar vanishes at" in res.undetermined["d_plus"]
    assert len(res.readings) >= 2
    assert any(r["ci"]["d_plus"][0] <= 0.5 <= r["ci"]["d_plus"][1] for r in res.readings), res.readings


def test_the_papers_plant_keeps_one_reading():
    """The paper's quintic (29b) has no other real root: the staircases give one reading, nothing
    undetermined, the truth inside the intervals."""
    from hwid.identify.nonlinear import identify_nonlinear
    cfg = config.loads(plants.config_text(plants.PAPER_FAST_G, name="paper", seed=3))
    res, _ = identify_nonlinear(cfg)
    assert res.readings == () and not res.undetermined
    assert not any("reading is shifted" in w for w in res.warnings)
    truth = from_config(cfg.plant).normalised().input
    for k in ("d_plus", "d_minus", "slope_down"):
        assert res.ci[k][0] <= getattr(truth, k) <= res.ci[k][1], k
