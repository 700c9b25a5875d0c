"""Stage 1 from a recorded history (``hwid.identify.history``): levels in random order and of
uneven length, against the simulated truth; quantised outputs; short and unsettled levels; a plant
outside the model (misfit); the CLI on a recorded CSV; the real STS3215 log where present."""
import json
from pathlib import Path

import numpy as np
import pytest
import yaml

import logs
import rigs
from hwid import config
from hwid.cli import main
from hwid.identify.history import identify_history, settled_levels
from hwid.model import from_config
from hwid.plant import Record
from hwid.results import read_history

DT = 0.05
STS = Path(__file__).resolve().parents[2] / "shared" / "data" / "real" / "sts3215" / "motor_telemetry_single.csv"


def _truth(**changes):
    cfg = config.loads(yaml.safe_dump(rigs.small(**{"plant.output_nonlinearity.polynomial": [0, 1.0, 0.8, -0.6],
                                                    "plant.input_nonlinearity.slope_down": 1.3, **changes})))
    return from_config(cfg.plant)


def _history(rng, n_levels=30, shortest=100, longest=200):
    levels = rng.uniform(-1.2, 1.2, n_levels)
    return np.repeat(levels, rng.integers(shortest, longest, n_levels))


def _inside(res, norm):
    truth = {"d_plus": norm.d_plus, "d_minus": norm.d_minus, "slope_down": norm.slope_down,
             "dead_band": norm.d_plus - norm.d_minus}
    return {k: res.ci[k][0] <= v <= res.ci[k][1] for k, v in truth.items()}


@pytest.mark.parametrize("seed", [1, 2, 3])
def test_random_order_levels_hold_the_truth(seed):
    """30 levels in random order, holds of 5-10 s (G's time constant is 0.5 s): the borders, the
    slope and the dead band inside their 95 % intervals, no misfit, h_bar's cubic found."""
    truth = _truth()
    norm = truth.normalised()
    rng = np.random.default_rng(seed)
    u = _history(rng)
    y = truth.simulate(u, DT, gear=0.0).x + 0.01 * rng.standard_normal(u.size)
    res = identify_history([Record("log", DT, u, y)], types=("backlash",))
    assert res.type == "backlash" and not res.misfit
    assert all(_inside(res, norm.input).values()), (res.ci, norm.input)
    assert len(res.h_coefficients) == 4
    assert abs(res.dead_band - 1.0) < 0.02


def test_the_type_is_found_from_the_levels():
    """With both types tried, a backlash history is called a backlash."""
    truth = _truth()
    rng = np.random.default_rng(7)
    u = _history(rng)
    y = truth.simulate(u, DT, gear=0.0).x + 0.01 * rng.standard_normal(u.size)
    assert identify_history([Record("log", DT, u, y)]).type == "backlash"


def test_quantised_output_keeps_its_quantum_in_every_standard_error():
    """An output read to the nearest 0.02 with little noise: no level's standard error is below
    q / sqrt(12), however long its hold, and the truth stays inside the intervals."""
    truth = _truth()
    norm = truth.normalised()
    rng = np.random.default_rng(4)
    u = _history(rng)
    q = 0.02
    y = np.round((truth.simulate(u, DT, gear=0.0).x + 0.002 * rng.standard_normal(u.size)) / q) * q
    res = identify_history([Record("log", DT, u, y, attrs={"output_resolution": q})], types=("backlash",))
    assert min(lv.se for lv in res.levels) >= q / np.sqrt(12) * (1 - 1e-12)
    assert all(_inside(res, norm.input).values()), res.ci


def test_short_levels_taken_when_settled_and_left_out_with_a_reason_when_not():
    """Holds of 12 samples: settled ones (after a small move) are taken from their last half; one
    cut off mid-move is left out, and the warning says how many samples are needed."""
    rng = np.random.default_rng(0)
    y_steady = 0.3 + 0.001 * rng.standard_normal(12)
    y_moving = np.linspace(0.0, 1.0, 12)
    u = np.repeat([0.1, 0.2], 12)
    levels, warns = settled_levels([Record("log", DT, u, np.concatenate([y_steady, y_moving]))])
    settled = [lv for lv in levels if lv.scored]
    assert len(settled) == 1 and abs(settled[0].x - 0.3) < 0.002
    assert len(levels) == 2 and not levels[1].scored      # kept in the sequence, not scored
    assert any("still moving" in w and "at least 20 samples" in w for w in warns)


def test_a_plant_outside_the_model_is_a_misfit():
    """A dead zone after the backlash cannot be followed by a cubic h_bar with 30 well-settled
    levels: chi-square rejects, the result says misfit and widens its intervals."""
    truth = _truth(**{"plant.output_nonlinearity.polynomial": [0, 1.0]})
    rng = np.random.default_rng(5)
    u = _history(rng)
    x = truth.simulate(u, DT, gear=0.0).x
    y = np.where(np.abs(x) < 0.3, 0.0, x - 0.3 * np.sign(x)) + 0.002 * rng.standard_normal(u.size)
    res = identify_history([Record("log", DT, u, y)], max_degree=3, types=("backlash",))
    assert res.misfit and res.p_value < 0.01
    assert any(w.startswith("misfit") for w in res.warnings)


def test_cli_on_a_recorded_csv(tmp_path, capsys):
    """``hwid identify-nonlinear`` on a recorded config: history.h5 and the JSON, the truth inside
    the intervals, and the HDF5 read back equal to the JSON."""
    truth = _truth()
    rng = np.random.default_rng(11)
    u = _history(rng)
    y = truth.simulate(u, DT, gear=0.0).x + 0.01 * rng.standard_normal(u.size)
    t = np.arange(u.size) * DT
    (tmp_path / "log.csv").write_text("t,cmd,pos\n" + "\n".join(f"{a:.3f},{b:.9g},{c:.9g}" for a, b, c in zip(t, u, y)))
    cfg = {"name": "log", "sampling": {"dt": DT},
           "plant": {"kind": "recorded", "experiments": [{"file": "log.csv", "time": {"column": "t"},
                                                          "input": {"column": "cmd"}, "output": {"column": "pos"}}]},
           "identification": {"nonlinear": {"input_type": "backlash", "max_degree": 5}}}
    (tmp_path / "log.yaml").write_text(yaml.safe_dump(cfg))
    with pytest.raises(SystemExit) as exit_:
        main(["identify-nonlinear", str(tmp_path / "log.yaml"), "--out", str(tmp_path / "out"),
              "--json", str(tmp_path / "h.json")])
    assert exit_.value.code in (0, None)
    d = json.loads((tmp_path / "h.json").read_text())
    assert {"type", "d_plus", "d_minus", "dead_band", "slope_down", "h_coefficients", "ci", "chi2", "dof",
            "p_value", "misfit", "levels", "selection", "warnings"} <= set(d)
    norm = truth.normalised().input
    assert d["ci"]["dead_band"][0] <= norm.d_plus - norm.d_minus <= d["ci"]["dead_band"][1]
    back = read_history(tmp_path / "out" / "history.h5")
    assert back.to_dict() == d
    assert "dead band" in capsys.readouterr().out
    # hwid run on the same config: stage 1 from the levels, and the report's section on it
    from hwid.pipeline import run
    run(config.load(tmp_path / "log.yaml"), tmp_path / "run", echo=lambda *a: None)
    page = (tmp_path / "run" / "report" / "report.html").read_text()
    assert "id='history'" in page and f"{d['dead_band']:.4g}" in page
    assert read_history(tmp_path / "run" / "history.h5").to_dict() == d


@pytest.mark.skipif(not STS.exists(), reason=f"the real STS3215 logs are not here ({STS.parent})")
def test_sts3215_log_levels_read_as_the_log_shows_them():
    """The real servo log (configs/recorded_sts3215.yaml): the settled levels at +-100 counts are
    the log's own settled readings (94-95 counts: the servo stops short of its target), each with at
    least the encoder's q / sqrt(12); the last level, cut off mid-move, is left out with a reason."""
    from hwid.recorded import load_records
    cfg = config.load(Path(__file__).resolve().parents[1] / "configs" / "recorded_sts3215.yaml")
    records = load_records(cfg)
    levels, warns = settled_levels(records)
    ends = [lv for lv in levels if abs(lv.u) == 100 and lv.scored]
    assert ends and all(93.5 <= abs(lv.x) <= 95.5 for lv in ends)
    assert all(lv.se >= 1 / np.sqrt(12) - 1e-12 for lv in levels if lv.scored)
    assert any("still moving" in w for w in warns)
    # with h_bar linear (three distinct targets), its gain is the slope of the log's own ascending
    # branch: the settled +100 reading minus the settled reading at 0 approached from below (read
    # before the pullers' pushes, which hwid leaves out), over the 100 counts between the targets
    res = identify_history(records, max_degree=1)
    up = np.mean([lv.x for lv in ends if lv.u > 0])
    below = [lv.x for prev, lv in zip(levels, levels[1:]) if lv.u == 0 and lv.scored and prev.u < 0]
    assert below and abs(abs(res.h_coefficients[1]) - (up - np.mean(below)) / 100) < 0.01


def test_recorded_run_with_the_whole_fit_is_a_model_for_compare(tmp_path):
    """``hwid run`` on a recorded log with identification.whole.enabled writes history.h5 and
    whole.h5; the run directory, holding no stages, is a MODEL for ``hwid compare``, which finds
    the log's own noise (0.01) in the residual."""
    truth = _truth()
    rng = np.random.default_rng(12)
    u = _history(rng, n_levels=12, shortest=40, longest=80)
    y = truth.simulate(u, DT, gear=0.0).x + 0.01 * rng.standard_normal(u.size)
    logs.write_log_csv(tmp_path, u, y, DT)
    for argv in (["run", str(tmp_path / "log.yaml"), "--out", str(tmp_path / "run")],
                 ["compare", str(tmp_path / "run"), str(tmp_path / "log.yaml"), "--out", str(tmp_path / "cmp"),
                  "--json", str(tmp_path / "cmp.json")]):
        with pytest.raises(SystemExit) as exit_:
            main(argv)
        assert exit_.value.code in (0, None)
    assert (tmp_path / "run" / "history.h5").exists() and (tmp_path / "run" / "whole.h5").exists()
    d = json.loads((tmp_path / "cmp.json").read_text())
    assert 0.0095 < d["rms"] < 0.0106
