"""A noise floor from what is noise: narrow-band components (a load at a frequency of its own) are
found in the repeats' differences, set aside and reported, against known truth; white and AR(1)
noise lose nothing.

Tolerances. The line test's family-wise false-alarm rate is 1e-3 (hwid.spectral_lines.ALPHA); the
seeds below are fixed, so a test on noise alone either passes or fails for good. A sinusoid of
amplitude A on pieces of n samples is located to about sqrt(6) sigma / (A n^1.5) rad/sample
(Cramer-Rao): far inside the 5 % asked for.
"""
from __future__ import annotations

import numpy as np
import pytest
from scipy import signal

from hwid import adequacy, config, spectral_lines
from hwid.diagnose import gap
from hwid.plant import Record

import diagnose_rigs as R
import test_adequacy as TA

DT = 0.04


def _ar1(rng, n: int, phi: float, sd: float = 1.0) -> np.ndarray:
    return sd * np.sqrt(1 - phi ** 2) * signal.lfilter([1.0], [1.0, -phi], rng.standard_normal(n))


@pytest.mark.parametrize("phi", [0.0, 0.5, 0.9])
def test_white_and_ar_noise_lose_nothing(phi):
    """Three pieces of 1100, 600 and 400 samples (the diagnosis's repeats), 30 seeds each: no line
    is found, and the pieces come back unchanged."""
    for seed in range(30):
        rng = np.random.default_rng(seed)
        pieces = [_ar1(rng, n, phi) for n in (1100, 600, 400)]
        cleaned, lines = spectral_lines.find_lines(pieces, DT)
        assert lines == [], (seed, lines)
        assert all(np.array_equal(a, b) for a, b in zip(pieces, cleaned))


def test_a_slow_wander_is_no_line():
    """Noise plus an Ornstein-Uhlenbeck wander (time constant 200 samples, its spread 3x the noise):
    a continuum rising to low frequencies, not a line."""
    for seed in range(30):
        rng = np.random.default_rng(seed)
        pieces = [rng.standard_normal(n) + 3.0 * _ar1(rng, n, np.exp(-1 / 200)) for n in (1100, 600, 400)]
        assert spectral_lines.find_lines(pieces, DT)[1] == [], seed


def test_a_sinusoid_at_its_own_phase_in_each_piece_is_found_and_taken_out():
    """A sinusoid of 4x the noise at 1.45 rad/s, at another phase in each piece, on AR(1) noise
    (0.5): its frequency within 1 %, its amplitude within 5 %, and what is left has the noise's
    spread within 5 %."""
    rng = np.random.default_rng(7)
    omega, amp = 1.45, 4.0
    pieces, noise = [], []
    for n in (1100, 600, 400):
        e = _ar1(rng, n, 0.5)
        noise.append(e)
        pieces.append(e + amp * np.sin(omega * DT * np.arange(n) + rng.uniform(0, 2 * np.pi)))
    cleaned, lines = spectral_lines.find_lines(pieces, DT)
    assert len(lines) == 1
    assert lines[0].omega == pytest.approx(omega, rel=0.01)
    assert lines[0].amplitude == pytest.approx(amp, rel=0.05)
    assert lines[0].p_value < 1e-10
    spread = np.std(np.concatenate(cleaned))
    assert spread == pytest.approx(np.std(np.concatenate(noise)), rel=0.05)
    assert lines[0].to_dict()["frequency_hz"] == pytest.approx(omega / (2 * np.pi), rel=0.01)


def _load_records(rng, load: float, phi: float = 0.0) -> list[Record]:
    """The adequacy tests' plant on its staircase, run four times (repeats), a load of ``load`` at
    1.3 rad/s added to its output at another phase each time, white or AR(1) noise of TA.SIGMA."""
    u = TA.staircase(0.05)
    x = TA.model().simulate(u, 0.05).x
    t = 0.05 * np.arange(u.size)
    return [Record(f"stairs{i}", 0.05, u, x + load * np.sin(1.3 * t + rng.uniform(0, 2 * np.pi))
                   + _ar1(rng, u.size, phi, TA.SIGMA)) for i in range(4)]


def test_data_floor_from_repeats_sets_a_load_aside():
    """hwid.adequacy's floor from repeats with a load of 5x the noise: without the line test it
    would read sqrt(1 + 25/2 E[2 sin^2]) ~ 5x the noise; it reads the noise within 20 %, and names
    the load's frequency within 5 %."""
    floor = adequacy.estimate_floor(_load_records(np.random.default_rng(3), 5 * TA.SIGMA))
    assert floor.source == "repeats"
    assert abs(floor.sigma / TA.SIGMA - 1) < 0.2
    (line,) = floor.set_aside
    assert line["kind"] == "narrow_band" and abs(line["rad_s"] / 1.3 - 1) < 0.05
    assert "set aside" in floor.reason and floor.to_dict()["set_aside"] == [line]


@pytest.mark.parametrize("phi", [0.0, 0.5])
def test_data_floor_of_plain_repeats_sets_nothing_aside(phi):
    """Four repeats of white or AR(1) noise: nothing set aside (the six pairwise differences share
    records, so the line test is run on two that do not), and the floor is the noise's: three
    independent differences of about 2100 samples give it to about 1 % (5 % is over 4 s.d.)."""
    for seed in range(5):
        floor = adequacy.estimate_floor(_load_records(np.random.default_rng(seed), 0.0, phi))
        assert floor.set_aside == () and floor.source == "repeats"
        assert abs(floor.sigma / TA.SIGMA - 1) < 0.05


def test_diagnosis_floor_of_ar_repeats_sets_nothing_aside():
    """gap.noise_floor on AR(1) (0.5) repeat differences: nothing set aside, the same floor as
    without the line test."""
    rng = np.random.default_rng(11)
    pairs = [(_ar1(rng, n, 0.5, 0.01), _ar1(rng, n, 0.5, 0.01), np.arange(n) >= 200) for n in (1300, 800, 600)]
    with_test, without = gap.noise_floor(pairs, 100, 1.0, DT), gap.noise_floor(pairs, 100, 1.0)
    assert with_test.lines == () and with_test.to_dict()["set_aside"] == []
    assert with_test.sigma == without.sigma and with_test.slow_z == without.slow_z


@pytest.fixture(scope="module")
def periodic_load_diagnosis(tmp_path_factory):
    return R.diagnose_base_rig(tmp_path_factory.mktemp("periodic_load"), "periodic_load", DT)


def test_periodic_load_is_set_aside_from_the_floor_and_unexplained(periodic_load_diagnosis):
    """The base plant with a load at G's input at 1.45 rad/s (no protocol sine's frequency),
    diagnosed with the base plant as the model: the floor is the sensor's noise within 20 % (it read
    0.048, 4.8x, when the repeats' differences were taken as noise), residual_structure names a
    narrow-band component within 5 % of the load's frequency, and no catalogue effect is named."""
    s = periodic_load_diagnosis
    assert abs(s["noise_floor"] / R.NOISE - 1) < 0.2
    assert s["verdict"]["effect"] == "unexplained"
    bands = [it for it in s["residual_structure"] if it["kind"] == "narrow_band"]
    assert bands and abs(bands[0]["rad_s"] / R.PERIODIC_LOAD["omega"] - 1) < 0.05
    assert abs(bands[0]["frequency_hz"] * 2 * np.pi / R.PERIODIC_LOAD["omega"] - 1) < 0.05
    assert s["noise"]["set_aside"][0]["rad_s"] == bands[0]["rad_s"]
    # the model's own check on the validation records uses a floor with the load set aside as well
    assert abs(s["model_adequacy"]["floor"]["sigma"] / R.NOISE - 1) < 0.2
    assert s["model_adequacy"]["floor"]["set_aside"]


def _floor_with_line(omega: float, slow_z: float = 0.0) -> gap.NoiseFloor:
    return gap.NoiseFloor(0.01, 1.0, 1000, 0.001, slow_z, np.zeros(0), (spectral_lines.Line(omega, 0.05, 1e-9, 0.9),))


def test_a_line_makes_none_and_other_effects_unexplained_but_not_its_own_mode():
    """A line in the repeats' differences: ``none`` and a delay become ``unexplained`` (no catalogue
    effect makes a line at a frequency of its own); a resonance whose omega_n is the line's (a mode
    still ringing from each repeat's start) keeps its name; one far from it does not."""
    from hwid.diagnose.floor_lines import structure_items, verdict_with_lines
    from hwid.diagnose.verdict import Candidate
    floor = _floor_with_line(1.45)
    assert verdict_with_lines("none", "", floor)[0] == "unexplained"
    assert "1.45 rad/s" in verdict_with_lines("none", "", floor)[1]
    delay = Candidate("time_delay", "linear", {"delay_s": 0.1}, 0.01, 0.01, 1.0, 50.0, 1.0)
    assert verdict_with_lines(delay, "", floor)[0] == "unexplained"
    near = Candidate("resonance", "linear", {"omega_n": 1.5, "zeta": 0.02}, 0.01, 0.01, 1.0, 50.0, 2.0)
    far = Candidate("resonance", "linear", {"omega_n": 4.0, "zeta": 0.02}, 0.01, 0.01, 1.0, 50.0, 2.0)
    assert verdict_with_lines(near, "", floor)[0] is near
    assert verdict_with_lines(far, "", floor)[0] == "unexplained"
    # nothing set aside: the verdict as it was
    plain = gap.NoiseFloor(0.01, 1.0, 1000, 0.001, 0.0, np.zeros(0))
    assert verdict_with_lines("none", "", plain) == ("none", "")
    assert structure_items(plain) == []
    kinds = [it["kind"] for it in structure_items(_floor_with_line(1.45, slow_z=40.0))]
    assert kinds == ["narrow_band", "wander"]


def test_a_residual_line_at_the_inputs_frequency_or_harmonic_is_the_models():
    """A model's residual with its error at an input sine (1 rad/s) and that sine's third harmonic,
    and a load at 0.68 rad/s of its own: given the input, only the load is a line (within 1 %);
    without it all three are."""
    rng = np.random.default_rng(0)
    n = 20000
    t = 0.02 * np.arange(n)
    u = np.sin(t) + np.repeat(rng.uniform(-1, 1, n // 500), 500)
    res = 0.05 * np.sin(t + 0.3) + 0.03 * np.sin(3 * t) + 0.04 * np.sin(0.68 * t) + 0.01 * rng.standard_normal(n)
    (line,) = spectral_lines.find_lines([res], 0.02, inputs=[u])[1]
    assert line.omega == pytest.approx(0.68, rel=0.01)
    found = sorted(ln.omega for ln in spectral_lines.find_lines([res], 0.02)[1])
    assert found == pytest.approx([0.68, 1.0, 3.0], rel=0.01)
