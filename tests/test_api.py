"""The Python API (:mod:`hwid.api`): its docstring examples run, and its answers are checked
against a known plant: identify lands the truth within its intervals with an adequate residual,
compare finds the noise, save and load reproduce the model, Data.from_file reads what the recorded
plant reads, and the guide's example (docs/guide/python.md) runs as written."""
import doctest
import os
import re
from pathlib import Path

import numpy as np
import pytest
import yaml

import hwid
from hwid import HwidError
from hwid.blocks.linear import LinearBlock
from hwid.blocks.static import PolynomialH
from hwid.model import HWModel, InputNonlinearity

DT = 0.02
NOISE = 0.01
GUIDE = Path(__file__).parents[1] / "docs" / "guide" / "python.md"
#: a Backlash of unequal slopes, a first-order G (G(0) = 1) and a quadratic h: normalised already
TRUTH = HWModel(InputNonlinearity("backlash", 1.0, 1.3, 0.25, -0.2), LinearBlock((1.0,), (0.15, 1.0)),
                PolynomialH((0.0, 1.0, 0.5)))


def _levels(seed: int, n_levels: int, hold: int = 100):
    """Random held levels through the plant, with white noise of std NOISE."""
    rng = np.random.default_rng(seed)
    u = np.repeat(rng.uniform(-1.5, 1.5, n_levels), hold)
    return u, TRUTH.simulate(u, DT).x + NOISE * rng.standard_normal(u.size)


@pytest.fixture(scope="module")
def identified():
    """Two experiments (lists of arrays) of 18 levels each, identified with the structure known."""
    (u1, y1), (u2, y2) = _levels(100, 18), _levels(101, 18)
    data = hwid.Data([u1, u2], [y1, y2], DT, names=["a", "b"])
    return data, hwid.identify(data, input_type="backlash", max_order=1, max_degree=3)


def test_docstring_examples_run():
    """Every example in hwid.api's docstrings runs and gives what it shows."""
    import hwid.api
    result = doctest.testmod(hwid.api, optionflags=doctest.ELLIPSIS)
    assert result.attempted >= 20
    assert result.failed == 0


def test_identify_lands_the_truth_within_its_intervals(identified):
    """The whole fit's 95 % intervals hold the known borders, slope and h; the model is adequate and
    simulates the noise-free output to well within the noise."""
    data, model = identified
    assert model.route == "whole" and model.model.input.type == "backlash"
    iv = model.intervals
    for name in ("d_plus", "d_minus", "slope_down"):
        lo, hi = iv[name]
        assert lo <= getattr(TRUTH.input, name) <= hi, (name, lo, hi)
        assert hi - lo > 0, name
    for k, (lo, hi) in enumerate(iv["h_coefficients"][1:], start=1):
        assert lo <= TRUTH.output.coefficients[k] <= hi, (k, lo, hi)
    assert model.adequacy.verdict == "adequate", model.adequacy.reason
    u, _ = _levels(13, 10)
    err = model.simulate(u, DT) - TRUTH.simulate(u, DT).x
    assert np.sqrt(np.mean(err ** 2)) < 0.3 * NOISE


def test_compare_finds_the_noise(identified):
    """compare's RMS on fresh data is the noise (within the chi-square spread of its samples), its
    floor's interval holds the true noise, and the keys are those of ``hwid compare --json``."""
    _, model = identified
    u, y = _levels(14, 20)
    result = hwid.compare(model, hwid.Data(u, y, DT))
    assert {"fit_percent", "rms", "noise_floor", "rms_over_floor", "experiments", "residual", "model",
            "adequacy", "figures"} <= set(result)
    spread = 4 / np.sqrt(2 * u.size)          # four standard deviations of an RMS of n white samples
    assert abs(result["rms"] / NOISE - 1) < spread + 0.02
    lo, hi = result["adequacy"]["floor"]["interval"]
    assert lo <= NOISE <= hi
    assert result["adequacy"]["verdict"] == "adequate"
    assert result["experiments"][0]["samples"] == u.size


def test_save_and_load_reproduce_the_model(identified, tmp_path):
    """A saved run directory loads back to the same simulation (1e-12) and the same adequacy; it is
    the MODEL ``hwid compare`` reads."""
    _, model = identified
    out = model.save(tmp_path / "run")
    assert (out / "whole.h5").is_file() and (out / "identification.json").is_file()
    back = hwid.Model.load(out)
    u, _ = _levels(15, 8)
    assert np.max(np.abs(back.simulate(u, DT) - model.simulate(u, DT))) <= 1e-12
    assert back.adequacy == model.adequacy
    assert back.route == model.route
    from hwid.diagnose.sim_side import load_model
    assert load_model(str(out), echo=lambda *a: None)[0].to_dict() == model.model.to_dict()


def test_identify_a_config_by_the_stages(tmp_path):
    """A config's simulated plant identified as ``hwid run`` does (the small rig: staircases and
    sines, the stages' route): stage 1's intervals hold the truth's borders, the model is adequate,
    and its saved run directory (nonlinear.h5, linear.h5) loads back to the same simulation."""
    import rigs
    from hwid import config
    from hwid.model import from_config
    path = rigs.write(tmp_path / "small.yaml", rigs.small())
    model = hwid.identify(path)
    assert model.route == "stages" and model.adequacy.verdict == "adequate"
    truth = from_config(config.load(path).plant).normalised().input
    for name in ("d_plus", "d_minus"):
        lo, hi = model.intervals[name]
        assert lo <= getattr(truth, name) <= hi, name
    out = model.save(tmp_path / "run")
    assert (out / "nonlinear.h5").is_file() and (out / "linear.h5").is_file()
    u = np.repeat(np.linspace(-1.0, 1.0, 7), 50)
    assert np.max(np.abs(hwid.Model.load(out).simulate(u, 0.05) - model.simulate(u, 0.05))) <= 1e-12


def test_load_a_plant_yaml(tmp_path):
    """A plant YAML loads to the config's own model."""
    from hwid.model import from_config
    from hwid import config
    plant = {"kind": "hammerstein_wiener",
             "input_nonlinearity": {"type": "backlash", "slope_up": 1.0, "slope_down": 1.3, "d_plus": 0.25,
                                    "d_minus": -0.2},
             "linear": {"num": [1.0], "den": [0.15, 1.0]}, "output_nonlinearity": {"polynomial": [0.0, 1.0, 0.5]}}
    (tmp_path / "plant.yaml").write_text(yaml.safe_dump(plant))
    model = hwid.Model.load(tmp_path / "plant.yaml")
    u, _ = _levels(16, 5)
    expected = from_config(config.parse_plant(plant, "plant")).simulate(u, DT).x
    assert np.max(np.abs(model.simulate(u, DT) - expected)) == 0.0
    assert np.max(np.abs(model.simulate(u, DT) - TRUTH.simulate(u, DT).x)) <= 1e-12


def test_data_from_file_is_the_recorded_plants_record(tmp_path):
    """Data.from_file on a CSV gives the records ``hwid run`` reads from a config naming the same
    file (arrays, attributes, provenance), and arrays given directly get the same levels."""
    from hwid import config
    from hwid.recorded import load_records
    u, y = _levels(17, 6, hold=60)
    t = np.arange(u.size) * DT
    (tmp_path / "log.csv").write_text("t,cmd,pos\n" + "\n".join(f"{a:.6f},{b:.9g},{c:.9g}" for a, b, c in zip(t, u, y)))
    d = {"name": "log", "sampling": {"dt": DT},
         "plant": {"kind": "recorded", "experiments": [{"file": "log.csv", "time": {"column": "t"},
                                                        "input": {"column": "cmd"}, "output": {"column": "pos"}}]}}
    (tmp_path / "log.yaml").write_text(yaml.safe_dump(d))
    expected = load_records(config.load(tmp_path / "log.yaml"))
    data = hwid.Data.from_file(tmp_path / "log.csv", input="cmd", output="pos", time="t")
    assert data.dt == pytest.approx(DT, rel=1e-9)
    assert len(data.records) == len(expected) == 1
    got, want = data.records[0], expected[0]
    assert got.name == want.name
    np.testing.assert_array_equal(got.u, want.u)
    np.testing.assert_array_equal(got.y, want.y)
    assert got.attrs == want.attrs
    arrays = hwid.Data(want.u, want.y, DT).records[0]
    assert arrays.attrs["segments"] == want.attrs["segments"]


def test_bad_input_is_one_line():
    """Wrong options and shapes raise HwidError with one line naming the problem."""
    u, y = _levels(18, 4)
    cases = [(lambda: hwid.Data(u, y[:-1], DT), "samples"),
             (lambda: hwid.Data(u, y, -1.0), "dt"),
             (lambda: hwid.identify(hwid.Data(u, y, DT), max_ordr=2), "max_ordr"),
             (lambda: hwid.identify(hwid.Data(u, y, DT), max_order=7), "max_order"),
             (lambda: hwid.compare(TRUTH, (u, y)), "hwid.Data")]
    for call, word in cases:
        with pytest.raises(HwidError) as err:
            call()
        assert word in str(err.value) and "\n" not in str(err.value)


def test_hwid_identify_is_the_package_and_the_function():
    """``hwid.identify`` stays callable after modules of the subpackage are imported, and ``import
    hwid`` alone loads neither the API nor numba."""
    import subprocess
    import sys
    code = ("import sys, hwid; assert 'hwid.api' not in sys.modules and 'numba' not in sys.modules; "
            "import hwid.identify.path; assert callable(hwid.identify); print(sorted(hwid.__all__))")
    env = {**os.environ, "PYTHONPATH": str(Path(__file__).parents[1])}
    out = subprocess.run([sys.executable, "-c", code], capture_output=True, text=True, env=env)
    assert out.returncode == 0, out.stderr
    assert "identify" in out.stdout and "Data" in out.stdout


#: the guide's Python blocks: the ten-line example (also the README's), arrays, defaults, a log on disk
TEN_LINES, ARRAYS, DEFAULTS, LOG = range(4)


def _python_blocks(path: Path) -> list[str]:
    return re.findall(r"```python\n(.*?)```", path.read_text(encoding="utf-8"), flags=re.S)


def _guide_blocks() -> list[str]:
    return _python_blocks(GUIDE)


def test_guide_example_runs(capsys):
    """The guide's example on arrays runs and says what its comments say."""
    namespace: dict = {}
    exec(compile(_guide_blocks()[ARRAYS], str(GUIDE), "exec"), namespace)
    model, truth = namespace["model"], namespace["truth"]
    lo, hi = model.intervals["d_plus"]
    assert lo <= truth.input.d_plus <= hi
    assert abs(model.model.input.d_plus - 0.3) < 0.002 and abs(model.model.input.d_minus + 0.3) < 0.002
    assert model.adequacy.verdict == "adequate"
    printed = capsys.readouterr().out.split("\n")
    assert printed[2] == "adequate"
    assert abs(float(printed[3]) - 0.01) < 0.001


@pytest.mark.slow
def test_guide_log_example_runs(tmp_path, monkeypatch):
    """The guide's log example on a CSV of the first example's data, with identify's defaults: the
    same model class is chosen (a Backlash, G of first order, h quadratic) with the truth in its
    intervals, and the saved run loads back."""
    blocks = _guide_blocks()
    namespace: dict = {}
    exec(compile(blocks[ARRAYS], str(GUIDE), "exec"), namespace)
    u, y = namespace["u"], namespace["y"]
    t = np.arange(u.size) * 0.02
    (tmp_path / "servo.csv").write_text("t,cmd,pos\n" + "\n".join(f"{a:.6f},{b:.9g},{c:.9g}" for a, b, c in zip(t, u, y)))
    monkeypatch.chdir(tmp_path)
    exec(compile(blocks[LOG], str(GUIDE), "exec"), namespace)
    model, same = namespace["model"], namespace["same"]
    assert model.model.input.type == "backlash" and len(model.model.linear.den) == 2
    assert len(model.model.output.coefficients) == 3
    for name, true in (("d_plus", 0.3), ("d_minus", -0.3)):
        lo, hi = model.intervals[name]
        assert lo <= true <= hi, name
    assert namespace["result"]["adequacy"]["verdict"] == "adequate"
    assert np.max(np.abs(same.simulate(u, 0.02) - model.simulate(u, 0.02))) <= 1e-12


def test_diagnose_a_plain_log_is_no_false_alarm(tmp_path):
    """hwid.diagnose on a lab's log of a plant without any effect (tests/logs.py), the sim side a
    Model loaded from the rig's own YAML: no effect is named, the gap is the noise, and the dict is
    the diagnosis JSON written beside it."""
    import json
    import logs
    model = hwid.Model.load(logs.write_model(tmp_path))
    s = hwid.diagnose(logs.write_lab(tmp_path, "plain", seed=4), model=model, out_dir=tmp_path / "out")
    assert s["verdict"]["effect"] == "none"
    assert s["gap_before"] <= 1.1 * s["noise_floor"]
    assert json.loads((tmp_path / "out" / "diagnosis.json").read_text()) == json.loads(json.dumps(s))


def _ten_lines(path: Path, block: str, monkeypatch) -> dict:
    """Run a ten-line example from the repository's root: the truth's borders (``truth``, a
    :class:`hwid.Model`, normalised) lie within the identified model's intervals, and it is adequate."""
    monkeypatch.chdir(Path(__file__).parents[1])
    namespace: dict = {}
    exec(compile(block, str(path), "exec"), namespace)
    model, truth = namespace["model"], namespace["truth"].model.normalised().input
    assert model.model.input.type == truth.type
    for name in ("d_plus", "d_minus"):
        lo, hi = model.intervals[name]
        assert lo <= getattr(truth, name) <= hi, (name, lo, hi)
    assert model.adequacy.verdict == "adequate", model.adequacy.reason
    return namespace


@pytest.mark.slow
def test_guide_ten_lines_run(capsys, monkeypatch):
    """The guide's ten-line example (the paper's plant identified from 12000 samples, ~90 s) gives
    what the page says: d+ within its interval of 0.5, adequate, the RMS of the noise 0.01."""
    _ten_lines(GUIDE, _guide_blocks()[TEN_LINES], monkeypatch)
    printed = capsys.readouterr().out.strip().split("\n")
    assert printed[1].endswith("adequate")
    assert abs(float(printed[2]) - 0.01) < 0.001


@pytest.mark.slow
def test_readme_python_example_runs(monkeypatch):
    """The README's Python example, where it has one, runs: its truth within the intervals, adequate."""
    readme = Path(__file__).parents[1] / "README.md"
    blocks = [b for b in _python_blocks(readme) if "hwid.identify" in b]
    if not blocks:
        pytest.skip("README.md has no Python example calling hwid.identify")
    _ten_lines(readme, blocks[0], monkeypatch)
