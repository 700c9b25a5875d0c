"""No credit without cause, and bends either way (issue 47, items 2 and 5).

* An effect is named only where it removes a practically relevant part of the gap
  (:data:`hwid.diagnose.verdict.RELEVANT`), measured from the baseline it was fitted against.
* A plant whose gain steps once, mid-session (``diagnose_rigs.gain_step``), identified across the
  step: its refit on the diagnosis's records reaches the floor while the identified model misses
  them many times over, and the verdict says the plant changed or the model was not adequate.
* Borders bent as cubics, inward and outward, at several strengths, diagnosed with the plain base
  plant as ``--model``: ``curved_borders`` is named and leaves at most 1.5x the floor.
"""
from __future__ import annotations

import numpy as np
import pytest
import yaml

from hwid import config
from hwid.diagnose import diagnose
from hwid.diagnose.conclude import Gaps, credit_from_the_model_as_identified, second_test
from hwid.diagnose.gap import NoiseFloor
from hwid.diagnose.verdict import RELEVANT, Candidate, Relevance, eligible, explained_fraction, verdict

import diagnose_rigs as R


def _cand(name, base, after, sigma, score=500.0, k=1.0):
    return Candidate(name, "linear", {}, after, after, explained_fraction(base, after, sigma), score, k)


def test_an_effect_that_takes_a_sliver_off_the_floor_is_not_named():
    """The issue's numbers: a refit left 1 % above the floor, a delay explains 73 % of that excess
    and takes 0.9 % of the floor off the gap. Its likelihood ratio on a long record is large, and
    the gap test takes what it leaves for noise; it is not named, by the verdict nor by the
    second test."""
    sigma = 0.0099
    base = 1.01 * sigma
    after = sigma * np.sqrt(1.0 + (0.27 * np.sqrt(1.01 ** 2 - 1.0)) ** 2)
    rel = Relevance(base, sigma)
    delay = _cand("time_delay", base, after, sigma, score=800.0)
    assert delay.explained_fraction == pytest.approx(0.73, abs=0.005)
    assert (base - after) / sigma < RELEVANT[1] and not rel(delay)
    assert not eligible(delay, False, leaves_noise=lambda g: True, relevant=rel)
    assert eligible(delay, False, leaves_noise=lambda g: True)      # what the rule changes
    assert verdict([delay], True, False, leaves_noise=lambda g: True, relevant=rel) == "unexplained"
    nf = NoiseFloor(sigma=sigma, kappa=1.0, n=4000, slow_rms=0.0, slow_z=0.0, surrogate=np.zeros(1))
    _, by = second_test([delay], base, nf, False, 200000.0, refloor_first=False, min_share=0.0, relevant=rel)
    assert by["likelihood_ratio"] > 25 and by["relevant"] is False and not by["significant"]
    assert "0.02 of the other" in rel.describe(delay)


def test_a_candidate_that_stands_in_for_something_else_does_not_make_the_gap_significant():
    """c18 of seed 10401 (a plain third-order rig, identified at 1.02x its floor): a friction whose
    Coulomb interval holds zero took 0.2 % of the gap with a likelihood ratio of 520. Standing in
    for a rate dependence (G's own error), it is not asked; the same fit as a friction would be."""
    sigma, base, after = 0.010055, 0.010194, 0.009962
    nf = NoiseFloor(sigma=sigma, kappa=1.0, n=4000, slow_rms=0.0, slow_z=0.0, surrogate=np.zeros(1))
    rel = Relevance(base, sigma)
    fric = _cand("friction", base, after, sigma, score=492.3, k=3.0)
    _, by = second_test([fric], base, nf, False, 20000.0, refloor_first=False, min_share=0.0, relevant=rel)
    assert by["significant"] and by["likelihood_ratio"] > 25
    fric.stands_in = "its Coulomb level's 95 % interval [-0.00939, 0.00664] holds zero"
    other = _cand("time_delay", base, 0.010193, sigma, score=-9.3)
    _, by = second_test([fric, other], base, nf, False, 20000.0, refloor_first=False, min_share=0.0, relevant=rel)
    assert by["effect"] == "time_delay" and not by["significant"]
    _, by = second_test([fric], base, nf, False, 20000.0, refloor_first=False, min_share=0.0, relevant=rel)
    assert by is None


@pytest.mark.parametrize("modes, hint, block, held", [
    ([(3.1, 0.19)], 0.0, 0.0, ("resonance",)),          # a two-mass drive's own mode in the identified G
    ([], 0.146, 0.0, ("time_delay",)),                   # excess phase as a 0.146 s delay in a rational G
    ([(3.1, 0.19)], 0.3, 0.3, ("resonance",)),           # a delay fitted as a block is no phase G holds
])
def test_what_the_identified_g_holds_is_indistinguishable_from_its_effect(modes, hint, block, held):
    """An identified model that predicts the validation records within the noise as it is, whose
    refit baseline took a mode or excess phase out of G and missed by more: every effect is measured
    against the model as it is, and the effect that would put back what G holds is the one the
    records cannot tell from `none` (G's own, or added to a G without it)."""
    from types import SimpleNamespace
    n, sigma = 20000, 0.01
    nf = NoiseFloor(sigma=sigma, kappa=1.0, n=n, slow_rms=0.0, slow_z=0.0, surrogate=np.zeros(1))
    fitter = SimpleNamespace(modes=modes, cancelled_pairs=[], delay_hint=hint, delay_block=block, gap_ref=1.8 * sigma)
    gaps = Gaps([], 1.0 * sigma, fitter.gap_ref, n, fitter, nf, 1.25)
    credit_from_the_model_as_identified(gaps, lambda *_: None)
    assert gaps.held_effects == held
    assert gaps.gap_ref == fitter.gap_ref == 1.0 * sigma and "the model's own" in gaps.as_identified
    # a model that misses the validation records as it is has nothing of its own to stand on
    missed = Gaps([], 1.5 * sigma, 1.8 * sigma, n, SimpleNamespace(**{**vars(fitter), "gap_ref": 1.8 * sigma}), nf, 1.25)
    credit_from_the_model_as_identified(missed, lambda *_: None)
    assert missed.held_effects == () and missed.as_identified == "" and missed.gap_ref == 1.8 * sigma


@pytest.mark.parametrize("base, after, sigma", [
    (0.1134, 0.00996, 0.00995),     # identified rate limit: the refit leaves most of the gap
    (0.01001, 0.00911, 0.00966),    # identified clipping sensor, held near the floor
    (0.0104422, 0.0101886, 0.0100832),  # identified 0.36 s delay near the floor (the second test)
    (0.1820, 0.01002, 0.01015),     # a given model: the baseline is the model itself
])
def test_effects_that_remove_the_gap_they_are_credited_with_stay_named(base, after, sigma):
    """Right names of the test and development rigs, each measured from its own baseline: each
    removes at least RELEVANT's share of the baseline's excess and its margin of the floor."""
    c = _cand("x", base, after, sigma)
    assert Relevance(base, sigma)(c)
    assert base ** 2 - after ** 2 >= RELEVANT[0] * (base ** 2 - sigma ** 2)
    assert base - after >= RELEVANT[1] * sigma


def test_the_share_is_of_the_baselines_excess_and_the_margin_of_the_floor():
    """Each clause alone turns a candidate away: a fall of 5 % of the floor that is 3 % of a large
    baseline's excess, and a fall that is all of a small baseline's excess but 1 % of the floor."""
    sigma = 0.01
    assert not Relevance(0.02, sigma)(_cand("x", 0.02, 0.0195, sigma))
    assert not Relevance(0.0101, sigma)(_cand("x", 0.0101, 0.0100, sigma))
    assert Relevance(0.0125, sigma)(_cand("x", 0.0125, 0.0100, sigma))


def _identified(tmp_path, driver: str) -> dict:
    lv = [-1.0, -0.75, -0.5, -0.25, 0.0, 0.25, 0.5, 0.75, 1.0]
    d = {"name": driver, "seed": 7, "sampling": {"dt": 0.04},
         "plant": {"kind": "external", "callable": f"diagnose_rigs:{driver}"},
         "protocols": {"staircase": {"levels_up": lv, "levels_down": lv[::-1], "hold": 6.0},
                       "sine": {"amplitude": 0.6, "frequencies": [0.3, 1.0, 3.0], "periods": 2}}}
    (tmp_path / "cfg.yaml").write_text(yaml.safe_dump(d))
    return diagnose(config.load(tmp_path / "cfg.yaml"), tmp_path / "out", model=None, echo=lambda *a: None)


@pytest.mark.slow      # an identified diagnosis (about a minute on a loaded machine)
def test_a_plant_whose_gain_steps_mid_session_is_not_credited_to_an_effect(tmp_path, monkeypatch):
    """The gain of G steps by 1.6 after stage 1's two staircases: stage 2 and every validation
    experiment see the new plant. The identified model misses its own records and the validation
    records many times over; the refit on the diagnosis's records reaches the floor (the plant is
    still a model of the same structure). The verdict is `unexplained`, saying the plant changed or
    the model was not adequate, and no effect takes the credit: the gap after is the gap before,
    never below what any candidate removed from its own baseline."""
    monkeypatch.setitem(R.GAIN_STEP, "after_calls", 2)
    monkeypatch.setitem(R.GAIN_STEP, "factor", 1.6)
    R._RIGS.pop("gain_step", None)
    s = _identified(tmp_path, "gain_step")
    floor = s["noise_floor"]
    assert abs(floor - R.NOISE) < 0.15 * R.NOISE
    assert s["gap_before"] > 5 * floor and s["gap_model_refit"] < 1.1 * floor
    assert s["model_adequacy"]["verdict"] == "misfit"
    assert s["verdict"]["effect"] == "unexplained"
    assert "changed" in s["verdict"]["why"] and "not adequate" in s["verdict"]["why"]
    assert s["gap_after"] == s["gap_before"]
    for c in s["candidates"]:
        removed = max(s["gap_model_refit"] ** 2 - c["gap_after"] ** 2, 0.0)
        assert s["gap_after"] >= np.sqrt(max(s["gap_before"] ** 2 - removed, 0.0))


def _given(tmp_path, driver: str) -> dict:
    import test_diagnose as T
    (tmp_path / "base.yaml").write_text(yaml.safe_dump({"plant": R.BASE}))
    return diagnose(config.load(T._cfg(tmp_path, driver)), tmp_path / "out", model=tmp_path / "base.yaml",
                    echo=lambda *a: None)


@pytest.mark.slow      # a diagnosis each (15-60 s on a loaded machine)
@pytest.mark.parametrize("driver", ["cubic_in", "cubic_in_weak", "cubic_in_strong", "cubic_out", "cubic_out_weak",
                                    "cubic_closing", "cubic_closing_strong", "cubic_opening", "bow_in", "bow_out"])
def test_cubic_borders_bent_either_way_are_named(tmp_path, driver):
    """Borders bent either way (``diagnose_rigs.CUBIC``): cubics of their own arguments inward
    (flattening, the play narrowing towards the ends) and outward (steepening, widening) at three
    strengths up to the monotone limit; added cubics opposed (closing the play at one end nearly to
    nothing, opening it at the other); bows narrowing and widening the play towards both ends. With
    the straight-bordered plant as ``--model``, `curved_borders` is named and leaves at most 1.5x
    the floor, the rig's own noise."""
    s = _given(tmp_path, driver)
    assert s["verdict"]["effect"] == "curved_borders"
    assert s["gap_before"] > 2 * s["noise_floor"]      # the weakest bends: 2.1x
    assert s["gap_after"] <= 1.5 * s["noise_floor"]
    assert abs(s["noise_floor"] - R.NOISE) < 0.15 * R.NOISE


@pytest.mark.slow      # a diagnosis each (10-30 s on a loaded machine)
@pytest.mark.parametrize("driver", ["inverse_cubic_in", "inverse_cubic_out"])
def test_cubic_branches_of_a_backlash_inverse_bent_either_way_are_named(tmp_path, driver):
    """The Backlash-Inverse plant whose branches are cubics of their own arguments, the jump
    between them shrinking (inward) or growing (outward) towards the ends of the range, with its
    straight-branched simulator as ``--model``: `curved_borders` named, at most 1.5x the floor."""
    import test_diagnose as T
    d = {"name": "cubic", "seed": 3, "sampling": {"dt": 0.04},
         "plant": {"kind": "external", "callable": f"diagnose_rigs:{driver}"},
         "protocols": {"staircase": {"levels_up": [-1.5, -1.0, -0.5, 0.0, 0.5, 1.0, 1.5],
                                     "levels_down": [1.5, 1.0, 0.5, 0.0, -0.5, -1.0, -1.5], "hold": 5.0},
                       "sine": {"amplitude": 1.0, "frequencies": [0.3, 1.0, 3.0], "periods": 2}}}
    s = T._inverse_rig_diagnosed(tmp_path, d)
    assert s["verdict"]["effect"] == "curved_borders"
    assert s["gap_before"] > 3 * s["noise_floor"]
    assert s["gap_after"] <= 1.5 * s["noise_floor"]
    assert abs(s["noise_floor"] - R._InverseRig.NOISE) < 0.15 * R._InverseRig.NOISE
