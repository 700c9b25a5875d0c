"""The model written is the model that was fitted: a whole fit behind a slow actuator and one behind
an actuator that stops short, written to ``whole.h5`` and read back, simulated on the fit's own
records from the fit's own starts, reproduce the fit's prediction to 1e-12."""
import numpy as np
import pytest

from hwid.blocks.slew import slewed
from hwid.identify.whole import Structure, WholeModelFit
from hwid.model import Actuator
from hwid.plant import Record
from hwid.results import read_whole, write_whole
from test_whole import _levels_with_ramps, _plant


def _records(truth, rng, actuate, n_levels, hold, dt=0.05, sigma=0.01):
    out = []
    for i in range(2):
        u = _levels_with_ramps(rng, n_levels, hold, 1.0, dt)
        out.append(Record(f"levels_{i}", dt, u, truth.simulate(actuate(u), dt).x + sigma * rng.standard_normal(u.size)))
    return out


def _round_trip(fit, cfg, tmp_path) -> float:
    """The largest difference between the fit's own prediction of its records and the read-back
    model's free run on them from the fit's starts."""
    prob, theta = fit.problem_, fit.theta_
    h = prob.h(theta)
    predicted = prob.y - prob.full_residual(np.concatenate([theta, h[1:]]))
    write_whole(tmp_path / "whole.h5", cfg, fit.result_)
    res = read_whole(tmp_path / "whole.h5")
    assert res == fit.result_
    model = res.model()
    sims = []
    for r in prob.records:
        start = res.initial_states[r.name]
        sims.append(model.simulate(r.u, r.dt, gear=start["gear"], rest=start["rest"], position=start.get("position")).x)
    return float(np.max(np.abs(np.concatenate(sims)[prob.keep] - predicted)))


def test_a_fit_behind_a_slow_actuator_is_written_with_its_rate(tmp_path):
    """An actuator slewing at 0.06 units/s: the model read back carries the fitted rate (0.0643 on
    these six levels a record, within 10 % of the truth) and reproduces the fit to 1e-12; the model
    without it misses its records by more than twice as much."""
    from hwid.identify.whole_rate import fit_rate_first
    cfg, truth = _plant()
    out = _records(truth, np.random.default_rng(5), lambda u: slewed(u, 0.06, 0.05), 6, 20.0)
    fit = WholeModelFit(max_degree=3, structures=[Structure(1, 0)], types=("backlash",))
    rate = fit_rate_first(fit, out)
    assert rate == pytest.approx(0.06, rel=0.1)
    act = fit.result_.model().actuator
    assert act is not None and act.rate == rate and act.clip is None
    assert _round_trip(fit, cfg, tmp_path) < 1e-12
    res = read_whole(tmp_path / "whole.h5")
    r, s = out[0], res.initial_states[out[0].name]
    rms = {name: float(np.sqrt(np.mean((m.simulate(r.u, r.dt, s["gear"], s["rest"], position=s.get("position")).x
                                        - r.y) ** 2)))
           for name, m in (("complete", res.model()), ("bare", res.model().without_actuator()))}
    assert rms["bare"] > 2 * rms["complete"]


def test_a_fit_behind_an_actuator_that_stops_short_is_written_with_its_limits(tmp_path):
    """An actuator that stops at -0.9 and 0.7: the model read back carries the fitted limits
    (within 0.01) and reproduces the fit to 1e-12."""
    from hwid.identify.whole_clip import fit_clip_added
    cfg, truth = _plant()
    limits = (-0.9, 0.7)
    out = _records(truth, np.random.default_rng(21), lambda u: np.clip(u, *limits), 20, 3.0)
    fit = WholeModelFit(max_degree=3, structures=[Structure(1, 0)], types=("backlash",)).fit(out)
    found = fit_clip_added(fit)
    assert found == pytest.approx(limits, abs=0.01)
    assert fit.result_.model().actuator.clip == found
    assert _round_trip(fit, cfg, tmp_path) < 1e-12


def test_the_actuator_runs_ahead_of_the_chain_and_survives_normalisation():
    """``simulate`` with an actuator is the chain without it on the actuated input (clip, slew,
    dead zone in that order), in the fused path and the three-pass one (a delay); ``normalised``
    and ``to_dict`` keep it."""
    from dataclasses import replace

    from hwid.blocks.deadzone import deadzone
    _, truth = _plant()
    dt = 0.05
    u = _levels_with_ramps(np.random.default_rng(3), 8, 2.0, 0.5, dt)
    act = Actuator(clip=(-0.8, 0.9), rate=0.5, deadzone=0.1)
    by_hand = deadzone(slewed(np.clip(u, -0.8, 0.9), 0.5, dt, start=0.2), 0.1)
    for plain in (truth, replace(truth, linear=replace(truth.linear, delay=0.12))):
        model = replace(plain, actuator=act)
        np.testing.assert_array_equal(model.simulate(u, dt, position=0.2).x, plain.simulate(by_hand, dt).x)
    norm = replace(truth, actuator=act).normalised()
    assert norm.actuator == act
    assert Actuator.from_dict(replace(truth, actuator=act).to_dict()["actuator"]) == act
    with pytest.raises(ValueError):
        Actuator(clip=(1.0, -1.0))
