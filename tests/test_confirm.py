"""The confirmation of a verdict (:mod:`hwid.diagnose.confirm`) against numbers known exactly:
white noise of known sigma, and predictions that differ from the truth by a known constant."""
from __future__ import annotations

import math
from types import SimpleNamespace

import numpy as np

from hwid.diagnose import confirm
from hwid.diagnose.verdict import Candidate

SIGMA = 0.01
N = 4000


def _noise(seed, n=N):
    return np.random.default_rng(seed).normal(0.0, SIGMA, n)


def test_worsening_matches_its_expectation():
    """An effect whose prediction is off the truth by ``b`` adds ``b^2 / sigma^2`` of the noise
    power, and its paired z is ``sqrt(n) b / (2 sigma)`` (kappa 1); the model without it is the
    truth. The other way round, the effect is better and z is as negative."""
    truth = np.sin(np.linspace(0, 20, N))
    y = truth + _noise(1)
    b = 0.004
    m = np.ones(N, bool)
    (z, d, before), = confirm.worsening([y], [truth + b], [truth], [m], SIGMA, 1.0)
    assert abs(d - (b / SIGMA) ** 2) < 0.03              # 0.16, +-3 sigma of the noise's part is 0.027
    assert abs(z - math.sqrt(N) * b / (2 * SIGMA)) < 3.5  # 12.6; the noise moves z by +-1
    assert abs(before) < 0.07                            # the bare model is the truth: 3 sigma of chi2/N
    (z2, d2, before2), = confirm.worsening([y], [truth], [truth + b], [m], SIGMA, 1.0)
    assert z2 < -9 and d2 < -0.13 and abs(before2 - 0.16) < 0.03


def test_a_little_worse_where_the_bare_model_missed_widely_is_not_against_the_verdict():
    """A fit of the right family that is not exact may add a little to a large gap; only a
    worsening of at least half the bare model's own excess there argues against the verdict."""
    assert confirm.against(0.35, 0.44) and confirm.against(0.03, -0.02)
    assert not confirm.against(0.35, 1.86)
    assert not confirm.against(0.01, 0.0)


def _case(offsets, plant_offset=0.0, seed=0):
    """A verdict whose predictions are off by ``offsets[j]`` on validation experiment ``j`` (the model
    without it is the truth), and a plant whose reruns of an experiment ``j`` are the truth moved by
    ``plant_offset``."""
    truth = np.sin(np.linspace(0, 20, N))
    masks = [np.ones(N, bool) for _ in offsets]
    exps = [SimpleNamespace(name=f"e{j}", kind="steps", u=np.full(N, float(j)), mask=masks[j])
            for j in range(len(offsets))]
    val = SimpleNamespace(y_val=[truth + _noise(seed + j) for j in range(len(offsets))],
                          sim_val=SimpleNamespace(x=[truth for _ in offsets]), m_val=masks,
                          val_idx=list(range(len(offsets))), exps=exps, design=SimpleNamespace(dt=0.05))
    shift = {float(j): o for j, o in enumerate(offsets)}
    fitter = SimpleNamespace(predict_on=lambda eff, theta, inputs: [truth + (shift[u[0]] if eff else 0.0)
                                                                      for u in inputs])
    cand = Candidate("input_saturation", "input", {}, 0.0, 0.0, 1.0, 1.0, 2.0,
                     predictions=[truth + o for o in offsets], theta=np.zeros(2), fitted=object())
    calls = []

    def rerun(index, times):
        calls.append((index, times))
        return [(exps[index].u, truth + plant_offset + _noise(100 + k), masks[index]) for k in range(times)]

    return cand, fitter, val, rerun, calls


def test_a_verdict_that_fits_every_experiment_is_not_checked_further():
    cand, fitter, val, rerun, calls = _case([0.0, 0.0005, 0.0])
    c = confirm.check(cand, fitter, val, SIGMA, 1.0, rerun, echo=lambda *a: None)
    assert (c is None or not c.contradicted) and not calls


def test_an_experiment_made_much_worse_contradicts_without_a_rerun():
    cand, fitter, val, rerun, calls = _case([0.0, 0.004, 0.0])
    c = confirm.check(cand, fitter, val, SIGMA, 1.0, rerun, echo=lambda *a: None)
    assert c.contradicted and c.experiment == "e1" and c.runs == 0 and not calls
    assert c.z >= confirm.Z_WORSE and abs(c.excess - 0.16) < 0.03


def test_an_open_case_is_run_again_and_settled_by_the_reruns_alone():
    """A worsening of 0.0025 (0.0625 of the noise power) on 400 samples gives z near 1.25: open.
    Reruns of that experiment settle it: contradicted where the plant goes on as the model without
    the effect predicts, not where it moves as the verdict predicts."""
    for plant_offset, expect in ((0.0, True), (0.0025, False)):
        cand, fitter, val, rerun, calls = _case([0.0, 0.0025], plant_offset, seed=3)
        for m in val.m_val:
            m[400:] = False
        c = confirm.check(cand, fitter, val, SIGMA, 1.0, rerun, echo=lambda *a: None)
        assert confirm.Z_LOOK <= c.z < confirm.Z_WORSE, c
        assert calls and calls[0][0] == 1 and c.times == c.runs == calls[0][1] <= confirm.MAX_TIMES
        assert c.contradicted is expect, c


def test_the_loop_test_refuses_only_a_remainder_above_the_floor():
    """A remainder that still follows the output's past refuses the verdict where it leaves more
    than the noise floor; within the floor (a judged rig's sine-shaped bend at 0.99x, p = 1.8e-14)
    there is nothing left for the plant's dynamics to differ by."""
    loop = [{"kind": "loop", "evidence": "", "p_value": 1e-14}]
    assert "past outputs" in confirm.dynamics_left(loop, "curved_borders", 1.04, 1.0)
    assert confirm.dynamics_left(loop, "curved_borders", 0.99, 1.0) == ""
    assert confirm.dynamics_left([{"kind": "loop", "evidence": "", "p_value": 1e-9}], "curved_borders", 1.2, 1.0) == ""
    assert confirm.dynamics_left([{"kind": "none", "evidence": "", "p_value": 0.5}], "curved_borders", 1.2, 1.0) == ""


def _through_lag(x, tau, dt=0.02):
    """``x`` through a first-order lag whose time constant ``tau(x_out)`` may depend on the level
    of its own output (a scalar: one lag at every level), by Euler steps of ``dt``."""
    tau = tau if callable(tau) else (lambda _, t=float(tau): t)
    y = np.empty_like(x)
    s = x[0]
    for i, xi in enumerate(x):
        y[i] = s
        s += dt / tau(s) * (xi - s)
    return y


def _moves(n=12000, dt=0.02):
    """A staircase over [-1, 1] with a slow sine on top, through a 0.3 s lag: moves at every level."""
    t = np.arange(n) * dt
    steps = np.repeat(np.random.default_rng(3).uniform(-0.9, 0.9, n // 400), 400)[:n]
    return _through_lag(steps + 0.1 * np.sin(0.7 * t), 0.3, dt)


def test_one_lag_at_every_level_is_not_refused_even_when_its_timing_is_off():
    """A sensor lag of 0.5 s, predicted with 0.45 s: the remainder is the slope times the misfit,
    the same at every level, so the test finds no growth toward the ends."""
    x = _moves()
    y = _through_lag(x, 0.5) + _noise(5, x.size)
    for tau in (0.5, 0.45):
        z = confirm.lag_by_level([y], [_through_lag(x, tau)], [np.ones(x.size, bool)])
        assert abs(z) < 3.0
    assert confirm.level_left("sensor_lag", z) == ""      # z of the lag 10 % off


def test_a_lag_that_changes_between_the_ends_of_the_range_and_its_middle_is_refused():
    """A lag of 1.2 s in the middle of the range and 0.3 s at its ends (a saturation inside the
    dynamics brings the output to its limits early), predicted by the one lag between: the test
    finds the difference at far more than LEVEL_Z. The other way round (0.3 s in the middle,
    1.2 s at the ends) is refused too, with z as far negative: a sensor's lag is one lag."""
    x = _moves()
    ones = [np.ones(x.size, bool)]
    shrinks = _through_lag(x, lambda s: 1.2 - 0.9 * s * s) + _noise(6, x.size)
    one = _through_lag(x, 0.9)
    z = confirm.lag_by_level([shrinks], [one], ones)
    assert z > 2 * confirm.LEVEL_Z
    assert "is shorter toward both ends" in confirm.level_left("sensor_lag", z)
    grows = _through_lag(x, lambda s: 0.3 + 0.9 * s * s) + _noise(7, x.size)
    assert confirm.lag_by_level([grows], [_through_lag(x, 0.6)], ones) < -2 * confirm.LEVEL_Z
    # a clip or a bend is not asked: its parameters do not move the output's timing
    assert confirm.level_left("input_saturation", z) == ""
