"""hwid.adequacy against known truth: a simulated plant with a known noise sigma, the true model,
and models wrong by 20 % in one parameter."""
from __future__ import annotations

import numpy as np
import pytest

from hwid import adequacy
from hwid.blocks.linear import LinearBlock
from hwid.blocks.static import PolynomialH
from hwid.model import HWModel, InputNonlinearity
from hwid.plant import Record

SIGMA = 0.01
LEVELS = [-1, -.8, -.6, -.2, 0, .2, .4, .6, .8, 1, 1.2, .9, .7, .5, .3, .1, -.1, -.3, -.5, -.7, -.9, -1.1]


def model(d_plus: float = 0.4, pole: float = 2.0) -> HWModel:
    """An asymmetric backlash behind G = pole / (s + pole) (settling 2 s) and an odd quintic h."""
    return HWModel(InputNonlinearity("backlash", 1.0, 1.2, d_plus, -0.3), LinearBlock((pole,), (1.0, pole)),
                   PolynomialH((0, 0.5, 0, -0.2, 0, 0.1)))


def staircase(dt: float) -> np.ndarray:
    return np.repeat(np.asarray(LEVELS, float), int(round(6.0 / dt)))


def sine(dt: float, seconds: float = 16.0) -> np.ndarray:
    return 0.8 * np.sin(2 * np.pi * 0.5 * np.arange(int(round(seconds / dt))) * dt)


def record(name: str, u: np.ndarray, dt: float, rng, sigma: float = SIGMA, plant: HWModel | None = None) -> Record:
    x = (plant or model()).simulate(u, dt).x
    return Record(name, dt, u, x + sigma * rng.standard_normal(u.size))


@pytest.mark.parametrize("source", ["repeats", "holds", "smoother"])
@pytest.mark.parametrize("seed", [1, 2, 3])
def test_floor_within_its_interval_of_sigma(source, seed):
    rng = np.random.default_rng(seed)
    if source == "repeats":
        recs = [record("a", sine(0.05), 0.05, rng), record("b", sine(0.05), 0.05, rng),
                record("stairs", staircase(0.05), 0.05, rng)]
    elif source == "holds":
        recs = [record("stairs", staircase(0.05), 0.05, rng)]
    else:      # no repeat, no hold: a sine sampled fast against G
        recs = [record("sine", sine(0.01), 0.01, rng)]
    floor = adequacy.estimate_floor(recs)
    assert floor.source == source and floor.determined
    lo, hi = floor.interval(0.99)
    assert lo <= SIGMA <= hi, (floor, lo, hi)


def test_floor_never_above_the_outputs_spread():
    rng = np.random.default_rng(4)
    u = sine(0.01)
    noise_only = Record("flat", 0.01, u, 0.3 * rng.standard_normal(u.size))   # the output is noise
    floor = adequacy.estimate_floor([noise_only])
    assert not floor.determined and floor.interval() is None
    assert floor.sigma <= adequacy.output_spread([noise_only])
    assert "spread" in floor.reason


def _servo(u, dt, rng, sigma=SIGMA) -> Record:
    """A fast servo (G = 1 / (0.05 s + 1): half a sample at dt 0.1) that follows each step within a
    sample or two: its output is not smooth on the smoother's window."""
    fast = HWModel(InputNonlinearity("backlash", 1.0, 1.0, 0.01, -0.01), LinearBlock((20.0,), (1.0, 20.0)),
                   PolynomialH((0.0, 1.0)))
    return record("servo", u, dt, rng, sigma, plant=fast)


@pytest.mark.parametrize("seed", [1, 2])
def test_a_servo_stepping_often_leaves_the_floor_undetermined_not_its_steps(seed):
    """Steps every 1.5 s at dt 0.1 (15 samples, shorter than any hold the floor reads and than the
    smoother's window): the whole smoother residual is the servo's motion at its steps (before: a
    floor 20-40x sigma, on which any model was `adequate`); the floor is now undetermined."""
    rng = np.random.default_rng(seed)
    u = np.repeat(rng.uniform(-1.0, 1.0, 20), 15)
    rec = _servo(u, 0.1, rng)
    floor = adequacy.estimate_floor([rec])
    assert not floor.determined and floor.source == "none" and floor.interval() is None
    assert "do not determine" in floor.reason


@pytest.mark.parametrize("seed", [1, 2, 3])
def test_the_smoother_reads_the_noise_between_a_servos_steps(seed):
    """Steps every 8 s at dt 0.1 on a slow sine (no hold for the floor to read): away from each
    step the smoother's residual is noise, its floor within its interval of sigma. (A step smaller
    than ten median changes of the input is no step: its transient is as smooth as the sine.)"""
    rng = np.random.default_rng(seed)
    t = np.arange(1200) * 0.1
    u = 0.5 * np.sin(2 * np.pi * 0.02 * t) + np.repeat(rng.uniform(-0.5, 0.5, 15), 80)
    rec = _servo(u, 0.1, rng)
    assert 12 <= adequacy.input_steps(u).size <= 14
    floor = adequacy.estimate_floor([rec])
    assert floor.source == "smoother" and floor.determined
    lo, hi = floor.interval(0.99)
    assert lo <= SIGMA <= hi, (floor, lo, hi)


def test_floor_raised_to_the_quantum():
    rng = np.random.default_rng(5)
    rec = record("stairs", staircase(0.05), 0.05, rng, sigma=1e-4)
    floor = adequacy.estimate_floor([rec], quantum=0.01)
    assert floor.source == "quantum" and floor.sigma == pytest.approx(0.01 / np.sqrt(12))


def own_records(seed: int) -> list[Record]:
    rng = np.random.default_rng(seed)
    return [record("stairs", staircase(0.05), 0.05, rng), record("sine", sine(0.05), 0.05, rng)]


@pytest.mark.parametrize("seed", range(10, 18))
def test_true_model_adequate(seed):
    """alpha = 1 %: eight seeds all adequate (probability 0.92 for a correct test; fixed seeds)."""
    ad = adequacy.assess(model(), own_records(seed))
    assert ad.verdict == "adequate", ad.reason
    assert ad.rms_fit / ad.floor.sigma <= ad.bound


def test_false_alarm_rate():
    """Over 100 seeds the true model is called a misfit at about the stated rate (binomial 99.9 % bound)."""
    misfits = sum(adequacy.assess(model(), own_records(seed)).misfit for seed in range(100, 200))
    assert misfits <= 5


@pytest.mark.parametrize("wrong", [{"d_plus": 0.48}, {"pole": 2.4}, {"pole": 1.6}])
def test_wrong_by_20_percent_is_misfit(wrong):
    ad = adequacy.assess(model(**wrong), own_records(20))
    assert ad.verdict == "misfit", ad.reason
    assert ad.ratio > ad.bound
    assert f"{ad.rms_fit:.4g}" in ad.reason


def test_held_out_records_scored():
    recs = own_records(21)
    rng = np.random.default_rng(22)
    held = [record("held", sine(0.05), 0.05, rng, plant=model(d_plus=0.6))]   # the plant changed
    ad = adequacy.assess(model(), recs, held_out=held)
    assert ad.rms_held_out is not None and ad.rms_held_out > ad.rms_fit
    assert ad.verdict == "misfit" and "held-out" in ad.reason


def test_diverging_model_is_misfit():
    unstable = HWModel(model().input, LinearBlock((0.5,), (1.0, -0.5)), model().output)
    ad = adequacy.assess(unstable, own_records(23))
    assert ad.verdict == "misfit"
    assert "diverges" in ad.reason


def test_too_few_samples_undetermined():
    rng = np.random.default_rng(24)
    short = record("short", sine(0.05, seconds=2.5), 0.05, rng)
    ad = adequacy.assess(model(), [short])
    assert ad.verdict == "undetermined" and "scored samples" in ad.reason


def test_given_starts_score_the_whole_record():
    rng = np.random.default_rng(25)
    u = staircase(0.05)
    truth = model().simulate(u, 0.05, gear=0.2, rest=0.5).x
    rec = Record("stairs", 0.05, u, truth + SIGMA * rng.standard_normal(u.size))
    ad = adequacy.assess(model(), [rec], starts={"stairs": {"gear": 0.2, "rest": 0.5}})
    assert ad.scored == u.size and ad.verdict == "adequate", ad.reason


def test_to_dict_keys():
    d = adequacy.assess(model(), own_records(26)).to_dict()
    assert {"verdict", "rms_fit", "rms_held_out", "floor", "ratio", "whiteness_p", "input_correlation_p",
            "reason"} <= set(d)
    assert {"sigma", "source", "quantum"} <= set(d["floor"])


def test_model_error_is_the_error_beside_the_noise():
    """A model whose only error is known: the plant's h carries an offset b = 0.015 (1.5 sigma)
    that the model lacks. The misfit's ``model_error`` is b within sampling (the floor's
    interval sets the tolerance: b^2 = rms^2 - sigma^2, both from the data), and the reason says it."""
    b = 0.015
    plant = HWModel(model().input, model().linear, PolynomialH((b, 0.5, 0, -0.2, 0, 0.1)))
    rng = np.random.default_rng(27)
    recs = [record("stairs", staircase(0.05), 0.05, rng, plant=plant), record("sine", sine(0.05), 0.05, rng, plant=plant)]
    ad = adequacy.assess(model(), recs)
    assert ad.verdict == "misfit", ad.reason
    lo, hi = ad.floor.interval()
    # rms^2 = b^2 + sigma^2 exactly in expectation; the floor's 95 % interval bounds the estimate's spread
    assert np.sqrt(max(ad.rms_fit ** 2 - hi ** 2, 0)) <= b <= np.sqrt(ad.rms_fit ** 2 - lo ** 2)
    assert ad.model_error == pytest.approx(np.sqrt(ad.rms_fit ** 2 - ad.floor.sigma ** 2), rel=1e-12)
    assert f"{ad.model_error:.3g}" in ad.reason and ad.to_dict()["model_error"] == ad.model_error
    assert adequacy.assess(model(), own_records(28)).model_error < 0.5 * SIGMA


def _ar1(rng, n: int, phi: float, sd: float) -> np.ndarray:
    """AR(1) noise of coefficient ``phi`` and marginal standard deviation ``sd``."""
    from scipy import signal
    return sd * np.sqrt(1 - phi ** 2) * signal.lfilter([1.0], [1.0, -phi], rng.standard_normal(n))


def test_correlated_noise_floor_and_no_false_alarm():
    """AR(1) noise (coefficient 0.5, correlation time 3 samples) on the true model's output: the floor
    from the holds must not read the noise low (a quadratic fitted to each block takes about 3 kappa
    samples' worth of correlated noise, not 3). Over 40 seeds its 95 % interval holds the true
    sigma in at least 34 (binomial: expected 38, P(< 34) < 2 %), and the true model is a misfit in at
    most 3 (alpha = 1 %: P(>= 3 of 40) < 1 %). Before the correction: 14 of 40 covered, 17 misfits."""
    cover = misfits = 0
    for seed in range(40):
        rng = np.random.default_rng(seed)
        recs = []
        for name, u in (("stairs", staircase(0.05)), ("sine", sine(0.05))):
            recs.append(Record(name, 0.05, u, model().simulate(u, 0.05).x + _ar1(rng, u.size, 0.5, SIGMA)))
        floor = adequacy.estimate_floor(recs)
        assert floor.source == "holds"
        lo, hi = floor.interval(0.95)
        cover += lo <= SIGMA <= hi
        misfits += adequacy.assess(model(), recs).misfit
    assert cover >= 34 and misfits <= 3, (cover, misfits)


def test_from_dict_inverts_to_dict():
    ad = adequacy.assess(model(), own_records(29))
    back = adequacy.Adequacy.from_dict(ad.to_dict())
    assert back == ad and back.to_dict() == ad.to_dict()
    assert adequacy.Adequacy.from_dict(None) is None
