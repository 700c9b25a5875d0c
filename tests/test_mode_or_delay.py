"""A fast mode or a delay (hwid.diagnose.mode_or_delay): rigs with known truth, each named right
or both listed as indistinguishable with a sine near the fitted mode as the next experiment, never
the wrong one alone; and the comparison's two branches on constructed candidates."""
from __future__ import annotations

import numpy as np
import pytest

from hwid.diagnose import mode_or_delay
from hwid.diagnose.experiments import Design
from hwid.diagnose.next_experiment import mode_sines
from hwid.diagnose.verdict import Candidate, Relevance

import diagnose_rigs as R

DT = 0.04


def _cand(effect: str, gap_after: float, prediction, score: float = 50.0) -> Candidate:
    return Candidate(effect, "linear", {"omega_n": 14.0} if effect == "resonance" else {"delay_s": 0.05}, gap_after,
                     gap_after, 0.9, score, 2.0 if effect == "resonance" else 1.0, predictions=[prediction])


def test_alike_on_the_data_both_listed():
    """Predictions 0.002 apart (a fifth of the noise) on 400 samples: the paired test cannot tell
    them apart (its z's spread is 1 under the hypothesis that both fit alike), so the delay stays
    named with the mode beside it."""
    rng = np.random.default_rng(0)
    y = 0.01 * rng.standard_normal(400)
    delay, mode = _cand("time_delay", 0.0100, np.zeros(400)), _cand("resonance", 0.0101, np.full(400, 0.002))
    cmp = mode_or_delay.compare(delay, [delay, mode], Relevance(0.02, 0.01), [y], [np.ones(400, bool)], 0.01, 1.0)
    assert cmp is not None and not cmp.separable and cmp.z < 3
    verdict, groups = mode_or_delay.settle(delay, [], [delay, mode], cmp)
    assert verdict is delay and groups[0]["effects"] == ["time_delay", "resonance"]


def test_separated_by_the_data_the_better_named():
    """The plant's output is the mode's prediction (a sinusoid of 5x the noise) plus noise: the
    delay's prediction (zero) misses it by far, and the mode replaces a delay verdict."""
    rng = np.random.default_rng(1)
    wave = 0.05 * np.sin(0.3 * np.arange(2000))
    y = wave + 0.01 * rng.standard_normal(2000)
    delay, mode = _cand("time_delay", 0.036, np.zeros(2000)), _cand("resonance", 0.0100, wave)
    cmp = mode_or_delay.compare(delay, [delay, mode], Relevance(0.06, 0.01), [y], [np.ones(2000, bool)], 0.01, 1.0)
    assert cmp.separable and cmp.better == "resonance"
    verdict, _ = mode_or_delay.settle(delay, [], [delay, mode], cmp)
    assert verdict is mode


def test_an_irrelevant_other_is_not_compared():
    """A mode that removes nothing of the gap (its gap after is the baseline's) is not a rival."""
    delay, mode = _cand("time_delay", 0.0100, np.zeros(10)), _cand("resonance", 0.02, np.zeros(10))
    assert mode_or_delay.compare(delay, [delay, mode], Relevance(0.02, 0.01), [np.zeros(10)],
                                 [np.ones(10, bool)], 0.01, 1.0) is None


def test_mode_sines_at_the_mode_within_the_range():
    d = Design(dt=0.01, u_lo=-1.5, u_hi=1.2, amplitude=1.0, settle_s=4.0, omega_c=1.0, seed=1)
    sines = mode_sines(d, 14.0)
    freqs = {frag["sine"]["frequencies"][0] for _, frag, _, _ in sines}
    assert 14.0 in freqs and all(0.8 * 14 - 1e-9 <= f <= 1.25 * 14 + 1e-9 for f in freqs)
    assert all(0 < frag["sine"]["amplitude"] <= 1.2 for _, frag, _, _ in sines)
    # a mode beyond a quarter of the Nyquist frequency cannot be driven by a sine: none proposed
    assert mode_sines(d, 0.4 * np.pi / 0.01) == []


def _diagnose(tmp, driver: str, identified: bool) -> dict:
    return R.diagnose_base_rig(tmp, driver, DT, model=not identified)


@pytest.mark.slow
@pytest.mark.parametrize("identified", [False, True])
@pytest.mark.parametrize("driver, truth", [("fast_mode", "resonance"), ("pure_delay", "time_delay")])
def test_mode_and_delay_rigs_never_the_wrong_one_alone(tmp_path, driver, truth, identified):
    """A 14 rad/s mode (zeta 0.03) far above the sines' band (0.5-2 rad/s), and a pure delay of
    0.2 s, each diagnosed with the base plant given and identified: the right effect is named, or
    the verdict is one of the two with the other in ``indistinguishable_from`` and a sine near the
    fitted mode as the next experiment. A resonance named for the delay rig (or a delay for the
    mode's) with nothing beside it fails. Identified, the model may carry the truth in its G and
    predict within the noise as it is: then the verdict is `none`, its reason naming what G
    carries, at the truth (the delay as G's excess phase, the mode as a lightly damped pair)."""
    s = _diagnose(tmp_path, driver, identified)
    name, alike = s["verdict"]["effect"], s["verdict"]["indistinguishable_from"]
    if identified and name == "none":
        assert s["gap_before"] <= 1.1 * s["noise_floor"]
        assert truth in alike       # the effect that would put back what G holds: G's own or added, unknown
        refit = s["model_refit"]
        if truth == "time_delay":
            assert "excess phase" in s["verdict"]["why"]
            assert abs(refit["excess_phase_taken_out_s"] - R.DELAY["delay_s"]) < 2 * DT
        else:
            assert "lightly damped mode" in s["verdict"]["why"]
            assert any(abs(m["omega_n"] / R.FAST_MODE["omega_n"] - 1) < 0.05 for m in refit["modes_taken_out"])
        return
    if name == truth:
        if truth == "resonance":
            mode = next(c for c in s["candidates"] if c["effect"] == "resonance")
            assert abs(mode["params"]["omega_n"] / R.FAST_MODE["omega_n"] - 1) < 0.05
        else:
            delay = next(c for c in s["candidates"] if c["effect"] == "time_delay")
            assert abs(delay["params"]["delay_s"] - R.DELAY["delay_s"]) < 2 * DT
        return
    assert name in mode_or_delay.PAIR and truth in alike, (name, alike)
    mode = next(c for c in s["candidates"] if c["effect"] == "resonance")
    sine = s["next_experiment"]["config"]["protocols"]["sine"]
    assert 0.8 * mode["params"]["omega_n"] - 1e-9 <= sine["frequencies"][0] <= 1.25 * mode["params"]["omega_n"] + 1e-9
    assert 0 < sine["amplitude"] <= 1.0


def test_a_mode_at_the_damping_bound_is_no_rival():
    """A resonance pressed against zeta's bound is a low-pass standing in for a lag: even where it
    fits like the delay, the two are not compared as a mode and a delay."""
    import dataclasses
    y = 0.01 * np.random.default_rng(2).standard_normal(400)
    delay = _cand("time_delay", 0.0100, np.zeros(400))
    mode = dataclasses.replace(_cand("resonance", 0.0101, np.full(400, 0.002)), at_bound=True)
    assert mode_or_delay.compare(delay, [delay, mode], Relevance(0.02, 0.01), [y], [np.ones(400, bool)],
                                 0.01, 1.0) is None
