"""The catalogue's effects after the gear (issue 48): ``friction`` (a Dahl friction force on the
gear's output side) and ``output_hysteresis`` (Prandtl-Ishlinskii plays between G and h), against
known truth.

Rigs from ``tests/diagnose_rigs.py`` (the small geared plant implemented independently of hwid, its
gear, friction state, plays and G carried over between calls as on a real rig) diagnosed with the
base plant as ``--model``: the verdict names the effect, the fitted parameters' 95 % intervals
(:mod:`hwid.diagnose.intervals`) cover the truth, and what is left is noise (white, 0.01). A
plain rig is never called either (``tests/test_diagnose.py::test_plain_plant_is_none`` with both in
the catalogue; here, the two fitted on it explain nothing).
"""
from __future__ import annotations

import numpy as np
import pytest

from hwid.diagnose import BLOCK, CATALOGUE
from hwid.diagnose.effects import catalogue
from hwid.diagnose.effects_after_gear import Friction, OutputHysteresis, dahl_state, play_sum
from hwid.diagnose.intervals import param_intervals

import diagnose_rigs as R

DT = 0.04


def _diagnose(tmp_path, driver: str, model: bool = True, effects=None) -> dict:
    return R.diagnose_base_rig(tmp_path, driver, DT, model=model, effects=effects)


def _covers(cand: dict, truth: dict) -> None:
    for name, value in truth.items():
        iv = cand["intervals"][name]
        assert iv is not None, (name, cand["intervals"])
        assert iv[0] <= value <= iv[1], (name, value, iv, cand["params"][name])


def test_both_are_catalogue_peers():
    assert CATALOGUE[-2:] == ("friction", "output_hysteresis")
    assert BLOCK["friction"] == "linear" and BLOCK["output_hysteresis"] == "output"
    effs = catalogue()
    assert isinstance(effs["friction"], Friction) and isinstance(effs["output_hysteresis"], OutputHysteresis)


def test_dahl_state_is_rate_independent_and_bounded():
    """The state depends on the path only: the same path sampled twice as finely ends at the same
    state; it stays in [-1, 1] and reaches 1 - exp(-d / pre_sliding) after a move d from 0."""
    path = np.concatenate([np.linspace(0, 1, 50), np.linspace(1, -0.3, 40), np.linspace(-0.3, 0.2, 30)])
    fine = np.interp(np.linspace(0, path.size - 1, 2 * path.size - 1), np.arange(path.size), path)
    z, zf = dahl_state(path, 0.1), dahl_state(fine, 0.1)
    assert abs(z[-1] - zf[-1]) < 1e-12 and np.all(np.abs(z) <= 1.0)
    assert dahl_state(np.array([0.0, 0.25]), 0.1)[-1] == pytest.approx(1 - np.exp(-2.5), rel=1e-12)


def test_play_sum_is_the_mean_of_its_plays():
    x = np.sin(np.linspace(0, 12, 400)) * 2.0
    one = play_sum(x, 0.4, 1)
    p, out = x[0], []
    for xi in x:
        p = min(max(p, xi - 0.4), xi + 0.4)
        out.append(p)
    assert np.allclose(one, out)
    assert np.allclose(play_sum(x, 0.4, 2), 0.5 * (play_sum(x, 0.2, 1) + one))


def test_intervals_of_a_linear_fit_are_its_textbook_ones():
    """On a straight line with white noise the Gauss-Newton interval is ordinary least squares': the
    slope's 95 % interval is 1.96 s / sqrt(sum (t - mean t)^2)."""
    rng = np.random.default_rng(3)
    t = np.linspace(-1, 1, 2000)
    y = 0.7 * t + 0.05 * rng.standard_normal(t.size)
    A = np.column_stack([t, np.ones_like(t)])
    theta = np.linalg.lstsq(A, y, rcond=None)[0]
    iv = param_intervals(lambda th: y - A @ th, theta, [-5.0, -5.0], [5.0, 5.0], (False, False), ["slope"])
    s = np.sqrt(np.sum((y - A @ theta) ** 2) / (t.size - 2))
    half = 1.96 * s / np.sqrt(np.sum((t - t.mean()) ** 2))
    assert iv["slope"] == pytest.approx([theta[0] - half, theta[0] + half], rel=1e-3)
    # a parameter the residual does not depend on is undetermined, with the reason
    iv = param_intervals(lambda th: y - A @ th[:2], np.r_[theta, 0.0], [-5.0, -5.0, 0.0], [5.0, 5.0, 1.0],
                         (False, False, False), ["slope", "offset", "idle"])
    assert iv["idle"] is None and "idle" in iv["undetermined"]


@pytest.mark.parametrize("driver", ["friction", "friction_damper"])
def test_friction_named_with_intervals_covering_the_truth(tmp_path, driver):
    """Friction holding the load back (coulomb < 0, no viscous part) and adding to the output in the
    direction of motion with a viscous part (a force at the driven shaft)."""
    s = _diagnose(tmp_path, driver)
    assert s["verdict"]["effect"] == "friction"
    top = s["candidates"][0]
    assert top["effect"] == "friction"
    _covers(top, R.TRUTH[driver])
    assert s["gap_before"] > 5 * s["noise_floor"]
    assert s["gap_after"] < 1.1 * s["noise_floor"]


def test_output_hysteresis_named_with_intervals_covering_the_truth(tmp_path):
    s = _diagnose(tmp_path, "output_hysteresis")
    assert s["verdict"]["effect"] == "output_hysteresis"
    top = s["candidates"][0]
    assert top["effect"] == "output_hysteresis"
    _covers(top, R.TRUTH["output_hysteresis"])
    assert s["gap_before"] > 5 * s["noise_floor"]
    assert s["gap_after"] < 1.2 * s["noise_floor"]


def test_a_plain_rig_is_neither(tmp_path):
    """The plain plant with its own simulator: neither effect explains anything, and the verdict is
    ``none``."""
    s = _diagnose(tmp_path, "plain", effects=["friction", "output_hysteresis"])
    assert s["verdict"]["effect"] == "none"
    for c in s["candidates"]:
        assert c["effect"] in ("friction", "output_hysteresis")
        assert c["explained_fraction"] < 0.2 and c["gap_after"] < 1.05 * s["noise_floor"]


@pytest.mark.slow
def test_friction_named_with_an_identified_model(tmp_path):
    """Live, the model identified from the rig first, F, G and h re-estimated with the effect:
    friction in the direction of motion is named, its intervals covering the truth. (Friction that
    holds the load back is a wider play to an identification: the same rig with ``coulomb = -0.12``
    was identified with 0.12 more play each side and left 1.4x the floor, which no effect took.)"""
    s = _diagnose(tmp_path, "friction_damper", model=False)
    assert s["verdict"]["effect"] == "friction"
    top = next(c for c in s["candidates"] if c["effect"] == "friction")
    _covers(top, R.TRUTH["friction_damper"])
    assert s["gap_after"] < 1.2 * s["noise_floor"]


def test_the_next_experiment_candidates_hold_a_reversal_and_two_amplitudes():
    """What separates friction from the gear's play and an output hysteresis from backlash: a
    reversal held at rest in small steps, and each sine at two amplitudes."""
    from types import SimpleNamespace
    from hwid.diagnose.next_experiment import candidates
    d = SimpleNamespace(width=2.0, centre=0.0, dt=0.04, settle_s=4.0, u_lo=-1.0, u_hi=1.0, omega_c=1.0)
    byname = {c[0]: c for c in candidates(d)}
    rev = byname["reversal held at rest"][1]["staircase"]
    assert rev["levels_down"][0] == rev["levels_up"][-1] == 1.0
    assert np.allclose(np.diff(rev["levels_down"]), -0.06)
    full = byname["sine at 1x the bandwidth"][1]["sine"]["amplitude"]
    third = byname["sine at 1x the bandwidth, a third of the amplitude"][1]["sine"]["amplitude"]
    assert third == pytest.approx(full / 3)


def test_friction_without_a_coulomb_level_is_never_the_verdict():
    """A friction fit whose Coulomb interval holds zero (or is undetermined) is a rate dependence, a
    zero of G: it stands in for something else and is not eligible, however much it explains; one
    whose Coulomb interval excludes zero (the damper's: 3.15 [1.66, 4.64]) is eligible."""
    from hwid.diagnose.verdict import Candidate, eligible
    f = Friction()
    holds_zero = {"coulomb": [-0.022, 0.016], "pre_sliding": None, "viscous": [0.15, 0.21]}
    undetermined = {"coulomb": None, "pre_sliding": None, "viscous": [0.15, 0.21]}
    damper = {"coulomb": [1.66, 4.64], "pre_sliding": [0.102, 0.175], "viscous": None}
    assert "holds zero" in f.stands_in(holds_zero) and "undetermined" in f.stands_in(undetermined)
    assert f.stands_in(damper) is None and f.stands_in(None) is None
    assert OutputHysteresis().stands_in(holds_zero) is None       # the rule is friction's own
    for intervals, named in ((holds_zero, False), (undetermined, False), (damper, True)):
        c = Candidate("friction", "linear", {}, 0.02, 0.0101, 1.0, 50.0, 3, intervals=intervals,
                      stands_in=f.stands_in(intervals))
        assert eligible(c, drift_plausible=False) is named


def test_a_placement_the_fit_experiments_cannot_tell_is_undetermined():
    """Of an effect's forms, one that fits the fit experiments alike (criterion within SAME_FIT)
    and acts elsewhere leaves the place undetermined (interval null, with the reason); one that
    fits clearly worse leaves it as fitted."""
    from hwid.diagnose.effects_after_gear import OutputHysteresis, OutputHysteresisAfterH
    from hwid.diagnose.intervals import forms_alike
    from hwid.diagnose.rank import SAME_FIT, EffectFitter
    from hwid.diagnose.verdict import Candidate

    n = 1000.0

    def cand(form, gap_fit):
        c = Candidate("output_hysteresis", "output", {"width": 0.1, **form.form_params()}, gap_fit, gap_fit, 0.9,
                      10.0, 2.0)
        c.fitted, c.intervals = form, {"width": [0.09, 0.11]}
        return c
    # n ln(gap^2): a gap 0.05 % larger costs 1 (alike); 1 % larger costs 20 (told apart)
    for other_gap, alike in ((0.010005, True), (0.0101, False)):
        best = cand(OutputHysteresis(), 0.01)
        other = cand(OutputHysteresisAfterH(), other_gap)
        assert (EffectFitter.fit_criterion(None, other, n) - EffectFitter.fit_criterion(None, best, n) < SAME_FIT) \
            == alike
        out = forms_alike(best, [best, other], lambda c: EffectFitter.fit_criterion(None, c, n), SAME_FIT)
        assert out is best and out.intervals["width"] == [0.09, 0.11]
        if alike:
            assert out.intervals["after_h"] is None and "after_h" in out.intervals["undetermined"]
            assert "after_h undetermined" in out.params_text()
        else:
            assert "after_h" not in out.intervals
            assert out.params_text() == "width 0.1 [0.09, 0.11], after_h 0"
