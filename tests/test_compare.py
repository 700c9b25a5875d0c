"""``hwid compare``: the model's free run from an estimated initial state, against the truth."""
import json
import subprocess
import sys

import numpy as np
import pytest

import rigs
from hwid import config
from hwid.adequacy import input_correlation, ljung_box
from hwid.compare import compare_records, fit_percent, initial_state
from hwid.model import from_config
from hwid.plant import Record, make_plant
from hwid.simulate import run_protocols


def _small_cfg(tmp_path, **changes):
    return config.load(rigs.write(tmp_path / "small.yaml", rigs.small(**changes)))


def test_initial_state_found_from_the_data(tmp_path):
    """A record that starts with the gear inside its play and G at rest elsewhere: the estimated
    state reproduces the noiseless output, and the gear and rest level are those of the truth."""
    model = from_config(_small_cfg(tmp_path).plant)
    dt = 0.05
    t = np.arange(0, 30, dt)
    u = 0.8 * np.sin(0.4 * t) + 0.1
    gear_true, rest_true = -0.25, 0.6          # the play at u[0] = 0.1 spans [-0.4, 0.6]
    x = model.simulate(u, dt, gear=gear_true, rest=rest_true).x
    y = x + 0.01 * np.random.default_rng(1).standard_normal(x.size)
    gear, rest, y_hat = initial_state(model, u, y, dt)
    assert gear == pytest.approx(gear_true, abs=0.02)
    assert rest == pytest.approx(rest_true, abs=0.02)
    assert np.sqrt(np.mean((y_hat - x) ** 2)) < 0.002


def test_true_model_reaches_the_noise_floor_and_a_wrong_one_does_not(tmp_path):
    cfg = _small_cfg(tmp_path)
    records = run_protocols(cfg, make_plant(cfg), progress=False)
    truth = from_config(cfg.plant)
    good, _ = compare_records(truth, records, noise_floor=0.01)
    assert 0.95 < good.rms_over_floor < 1.05
    assert good.whiteness_p > 1e-3 and good.input_correlation_p > 1e-3
    assert all(e.fit_percent > 90 for e in good.experiments)
    wrong = from_config(_small_cfg(tmp_path, **{"plant.input_nonlinearity.d_plus": 0.2}).plant)
    bad, _ = compare_records(wrong, records, noise_floor=0.01)
    assert bad.rms_over_floor > 3 and bad.fit_percent < good.fit_percent
    assert bad.whiteness_p < 1e-6


def test_residual_statistics_on_known_signals():
    rng = np.random.default_rng(0)
    white = rng.standard_normal(4000)
    q, m = ljung_box(white)
    assert m == 25 and q < 60                     # chi2(25): 99.99 % quantile ~ 62
    coloured = np.convolve(white, np.ones(5) / 5, mode="same")
    assert ljung_box(coloured)[0] > 1000
    u = rng.standard_normal(4000)
    assert input_correlation(white, u)[0] < 60
    assert input_correlation(np.concatenate([[0.0, 0.0], u[:-2]]), u)[0] > 1000   # u two samples late
    assert fit_percent([1.0, 2.0, 3.0], [1.0, 2.0, 3.0]) == 100.0
    assert fit_percent([1.0, 2.0, 3.0], [2.0, 2.0, 2.0]) == pytest.approx(0.0)


def test_cli_compare_json_keys(tmp_path):
    path = rigs.write(tmp_path / "small.yaml", rigs.small())
    js = tmp_path / "c.json"
    p = subprocess.run([sys.executable, "-m", "hwid", "compare", str(path), str(path), "--out", str(tmp_path / "out"),
                        "--json", str(js)], capture_output=True, text=True, timeout=300)
    assert p.returncode == 0, p.stderr
    d = json.loads(js.read_text())
    assert {"fit_percent", "rms", "experiments", "residual"} <= set(d)
    assert {"whiteness_p", "input_correlation_p"} <= set(d["residual"])
    assert len(d["experiments"]) == rigs.N_EXPERIMENTS
    assert all({"name", "fit_percent", "rms", "samples"} <= set(e) for e in d["experiments"])
    assert 0.95 < d["rms_over_floor"] < 1.05
    from hwid.results import read_compare
    back = read_compare(tmp_path / "out" / "compare.h5")
    assert set(back["y_model"]) == {e["name"] for e in d["experiments"]}
    from hwid.report.html import write_report
    page = write_report(tmp_path / "out").read_text()
    assert "id='compare'" in page and "fig-compare_residual_tests" in page
    assert all(f"fig-compare_{e['name']}" in page for e in d["experiments"])


def test_cli_compare_bad_model_is_one_line(tmp_path):
    path = rigs.write(tmp_path / "small.yaml", rigs.small())
    p = subprocess.run([sys.executable, "-m", "hwid", "compare", str(tmp_path / "nope"), str(path), "--out",
                        str(tmp_path / "out")], capture_output=True, text=True, timeout=120)
    assert p.returncode == 2 and p.stderr.count("\n") == 1 and "nope" in p.stderr


def _lab_and_models(tmp_path, d_plus: float):
    """A recorded lab log of :mod:`logs`' rig, and a model YAML of that rig with ``d_plus`` for d+."""
    import copy

    import yaml

    import logs
    cfg_path = logs.write_lab(tmp_path, seed=3)
    m = copy.deepcopy(logs.MODEL)
    m["plant"]["input_nonlinearity"]["d_plus"] = d_plus
    model_path = tmp_path / f"model_{d_plus}.yaml"
    model_path.write_text(yaml.safe_dump(m, sort_keys=False))
    return cfg_path, model_path


def _cli_compare(tmp_path, model_path, cfg_path):
    js = tmp_path / f"{model_path.stem}.json"
    p = subprocess.run([sys.executable, "-m", "hwid", "compare", str(model_path), str(cfg_path), "--out",
                        str(tmp_path / model_path.stem), "--json", str(js)], capture_output=True, text=True,
                       timeout=300)
    assert p.returncode == 0, p.stderr
    return json.loads(js.read_text()), p.stdout


def test_cli_compare_recorded_floor_and_adequacy(tmp_path):
    """On a recorded log of a known rig (noise s.d. 0.02): the floor estimated from the data alone
    covers 0.02 in its 99 % interval, the true model is adequate at about 1x that floor, and a model
    whose d+ is 20 % off is called a misfit in the JSON and in the summary, by the same numbers."""
    import logs
    cfg_path, true_path = _lab_and_models(tmp_path, logs.F["d_plus"])
    d, out = _cli_compare(tmp_path, true_path, cfg_path)
    ad = d["adequacy"]
    assert {"fit_percent", "rms", "noise_floor", "rms_over_floor", "experiments", "residual", "model"} <= set(d)
    lo, hi = ad["floor"]["interval"]
    # the log's output is linearly interpolated onto the grid from jittered (+-3 %) times: its noise
    # s.d. lies between 0.97 and 1 times the rig's
    assert lo <= logs.SIGMA and 0.97 * logs.SIGMA <= hi, ad["floor"]
    assert d["noise_floor"] == pytest.approx(ad["floor"]["sigma"])
    assert d["rms_over_floor"] == pytest.approx(d["rms"] / d["noise_floor"])
    assert ad["verdict"] == "adequate", ad["reason"]
    assert "adequacy: adequate" in out and "misfit" not in out
    _, wrong_path = _lab_and_models(tmp_path, 1.2 * logs.F["d_plus"])
    d, out = _cli_compare(tmp_path, wrong_path, cfg_path)
    assert d["adequacy"]["verdict"] == "misfit"
    assert d["adequacy"]["ratio"] > d["adequacy"]["bound"]
    assert "adequacy: misfit" in out
