"""The diagnosis never says ``none`` with a model that fails its own records
(:mod:`hwid.diagnose.model_check`), and a log's noise floor is never above what the data alone give
(:func:`hwid.diagnose.from_logs.bounded_floor`): a lab log of a known rig (noise s.d. 0.02) with a
grossly wrong ``--model`` (G a lightly damped pair at 10 rad/s where the rig's is well damped at
2 rad/s)."""
from __future__ import annotations

import copy
from dataclasses import replace

import numpy as np
import pytest
import yaml

import logs
from hwid import config
from hwid.diagnose import diagnose, from_logs
from hwid.diagnose import logs as diag_logs

INFLATE = 2.0       # times the output's spread: the floor a model's residual gave on the damper was ~20x


def _wrong_model(tmp_path) -> str:
    m = copy.deepcopy(logs.MODEL)
    m["plant"]["linear"] = {"num": [100.0], "den": [1.0, 0.04, 100.0]}
    path = tmp_path / "wrong.yaml"
    path.write_text(yaml.safe_dump(m, sort_keys=False))
    return str(path)


def _inflated_floor(monkeypatch):
    """floor_from_logs returning INFLATE times the output's spread: what a model whose residual
    carries more than noise gives (the damper's exploding free run)."""
    from hwid.adequacy import output_spread
    original = diag_logs.floor_from_logs

    def inflated(exps, recs, *args):
        floor, source, pairs = original(exps, recs, *args)
        return replace(floor, sigma=INFLATE * output_spread(recs)), source, pairs

    monkeypatch.setattr(diag_logs, "floor_from_logs", inflated)


def test_a_misfit_model_is_never_none_where_the_floor_swallows_its_gap(tmp_path, monkeypatch):
    """The floor is kept inflated (bounded_floor switched off): the gap test then finds the wrong
    model's gap within noise, and only the model's adequacy on its records stops a `none`."""
    _inflated_floor(monkeypatch)
    monkeypatch.setattr(from_logs, "bounded_floor", lambda floor, source, records: (floor, source))
    lines = []
    s = diagnose(config.load(logs.write_lab(tmp_path, seed=4)), tmp_path / "out", model=_wrong_model(tmp_path),
                 echo=lines.append)
    assert s["gap_before"] < s["noise_floor"]                 # the floor swallows the gap
    ad = s["model_adequacy"]
    assert ad["verdict"] == "misfit" and ad["ratio"] > 10
    # the adequacy's floor, from the data alone, covers the rig's noise
    assert ad["floor"]["interval"][0] <= logs.SIGMA <= ad["floor"]["interval"][1] / 0.97
    assert s["verdict"]["effect"] == "unexplained"
    assert "not adequate" in s["verdict"]["why"] and f"{ad['ratio']:.3g} x the floor" in s["verdict"]["why"]
    text = "\n".join(lines)
    assert "consistent with noise" not in text
    assert "the model is not adequate on the validation records" in text


def test_a_floor_above_the_datas_own_is_replaced(tmp_path, monkeypatch):
    """With the floor above the output's spread and bounded_floor on: the floor used is the data's,
    which covers the rig's noise, and the gap is then more than noise."""
    _inflated_floor(monkeypatch)
    cfg = config.load(logs.write_lab(tmp_path, seed=4))
    s = diagnose(cfg, tmp_path / "out", model=_wrong_model(tmp_path), echo=lambda *a: None)
    from hwid.recorded import load_records
    spread = float(np.std(np.concatenate([r.y - r.y.mean() for r in load_records(cfg)])))
    assert s["noise_floor"] <= spread
    assert s["noise_floor"] == pytest.approx(logs.SIGMA, rel=0.1)
    assert "used instead" in s["data"]["noise_source"]
    assert s["verdict"]["effect"] != "none" and s["test"]["significant"]


def test_the_true_model_is_adequate_and_keeps_none(tmp_path):
    """The rig's own model as --model: adequate on the validation records, and the verdict `none`."""
    path = tmp_path / "true.yaml"
    path.write_text(yaml.safe_dump(logs.MODEL, sort_keys=False))
    s = diagnose(config.load(logs.write_lab(tmp_path, seed=4)), tmp_path / "out", model=str(path),
                 echo=lambda *a: None)
    assert s["model_adequacy"]["verdict"] == "adequate", s["model_adequacy"]["reason"]
    assert s["verdict"]["effect"] == "none"


def test_none_from_a_floor_that_is_the_models_own_residual_is_unexplained():
    """A log with no repeat, settled hold or smooth stretch: the diagnosis's floor is the model's
    own residual's high-frequency part. With the data-alone floor undetermined, a gap within it is
    no `none`; where the data determine a floor and the model is adequate on it, `none` stands."""
    from types import SimpleNamespace

    from hwid import adequacy
    from hwid.diagnose.gap import NoiseFloor
    from hwid.diagnose.model_check import not_none_from_a_misfit

    said = []

    def ctx(determined: bool):
        floor = adequacy.NoiseFloor(0.3 if determined else 4e-5, "holds" if determined else "none", 0.0,
                                    40.0 if determined else 0.0, 1.0, determined)
        ad = adequacy.Adequacy("adequate" if determined else "undetermined", 0.31, None, floor, 1.03, None, None, "")
        return SimpleNamespace(floor_from_model=True, model_adequacy=ad, echo=said.append,
                               floor=NoiseFloor(2.85, 1.0, 100, 0.0, 0.0, np.zeros(0)))
    verdict, why = not_none_from_a_misfit(ctx(False), "none", "", 1.25)
    assert verdict == "unexplained" and "model's own residual" in why and said == [why]
    assert not_none_from_a_misfit(ctx(True), "none", "", 1.25) == ("none", "")
    assert not_none_from_a_misfit(ctx(False), "drift", "", 1.25) == ("drift", "")
