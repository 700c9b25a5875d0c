"""hwid.results, the one storage module: every kind written and read back unchanged, checked on the
way in (kind, format, config hash), atomic."""
import json

import numpy as np
import pytest

import plants
from hwid.plant import Record
from hwid.results import (ResultsError, read_batch_runs, read_batch_summary, read_compare, read_diagnosis,
                          read_experiments, read_simulation, read_whole, write_batch, write_compare,
                          write_diagnosis, write_simulation, write_whole)


@pytest.fixture
def cfg():
    return plants.load(plants.BATCH)


def _record(name, n=50, seed=0):
    rng = np.random.default_rng(seed)
    return Record(name, 0.05, rng.standard_normal(n), rng.standard_normal(n), attrs={"omega": 0.5, "note": "x"})


def test_simulation_round_trip_and_kind_checked(cfg, tmp_path):
    recs = [_record("a"), _record("b", seed=1)]
    path = write_simulation(tmp_path / "simulation.h5", cfg, recs, {"model": {"k": 1.0}})
    back, truth = read_simulation(path, cfg)
    assert list(back) == ["a", "b"] and truth == {"model": {"k": 1.0}}
    assert np.array_equal(back["a"].y, recs[0].y) and back["a"].attrs["note"] == "x"
    assert set(read_experiments(path, "simulation")) == {"a", "b"}
    with pytest.raises(ResultsError, match="expected 'whole'"):
        read_whole(path)
    assert not (tmp_path / "simulation.h5.tmp").exists()


def test_diagnosis_round_trip(cfg, tmp_path):
    rows = [{"name": "e1", "u": np.arange(5.0), "y": np.ones(5), "y_model": np.zeros(5),
             "mask": np.array([0, 1, 1, 1, 0], bool), "region": np.arange(5), "z": None, "y_after": np.ones(5),
             "dt": 0.1, "kind": "steps", "role": "validation", "repeat_of": None, "variable": {"amp": 1.0}}]
    summary = {"verdict": {"effect": "none"}, "gap_before": np.float64(0.1)}
    back = read_diagnosis(write_diagnosis(tmp_path / "diagnosis.h5", cfg, summary, rows))
    assert back["summary"] == {"verdict": {"effect": "none"}, "gap_before": 0.1}
    e = back["experiments"]["e1"]
    assert e["mask"].tolist() == [False, True, True, True, False] and "z" not in e
    assert e["variable"] == {"amp": 1.0} and e["repeat_of"] is None and e["t"][-1] == pytest.approx(0.4)


def test_batch_round_trip(cfg, tmp_path):
    points = [{"overrides": {"plant.noise.std": 0.01}, "columns": {"run": np.array([0, 1]), "d_plus": np.array([0.4, 0.41])},
               "summary": {"d_plus": {"truth": 0.4, "bias": 0.005}}, "errors": []}]
    path = write_batch(tmp_path / "batch.h5", cfg, 2, points)
    summary = read_batch_summary(path)
    assert summary["sweep_keys"] == ["plant.noise.std"]
    assert summary["points"][0]["stats"]["d_plus"] == {"truth": 0.4, "bias": 0.005}
    assert read_batch_runs(path)["d_plus"].tolist() == [0.4, 0.41]


def test_compare_round_trip(cfg, tmp_path):
    recs = [_record("a")]
    path = write_compare(tmp_path / "compare.h5", cfg, {"fit_percent": 90.0}, recs, {"a": recs[0].y * 0.5})
    back = read_compare(path)
    assert back["summary"] == {"fit_percent": 90.0}
    assert np.array_equal(back["y_model"]["a"], recs[0].y * 0.5)
    assert json.dumps(back["summary"])


def test_whole_round_trip(tmp_path):
    from test_whole import _plant, _records
    from hwid.identify.whole import Structure, WholeModelFit
    cfg, truth = _plant()
    fit = WholeModelFit(max_degree=2, structures=[Structure(1, 0)], types=("backlash",)).fit(
        _records(truth, np.random.default_rng(3), 1))
    path = write_whole(tmp_path / "whole.h5", cfg, fit.result_)
    back = read_whole(path, cfg)
    assert back == fit.result_
