"""Issue 45, item 6: the banded rotary friction damper's three files (../shared/data/real/brfd/),
each diagnosed from its plain recorded config (configs/brfd/), give `unexplained` or name an effect,
with the model's own fit on its records beside the verdict, never `none` from a model that fails
its records; the noise floor is never above the force's own spread (it was 35 kip on a force of
+-3 kip). Each takes 10 s to 2 min (the 0.5 Hz file's identification at 1024 Hz)."""
from __future__ import annotations

import os
import sys
from pathlib import Path

import numpy as np
import pytest
import yaml

from hwid import config
from hwid.diagnose import CATALOGUE, diagnose
from hwid.recorded import load_records

ROOT = Path(__file__).resolve().parents[1]
#: the real data: ``HWID_REAL_DATA`` where set (a checkout elsewhere), else ../shared/data/real
REAL = Path(os.environ.get("HWID_REAL_DATA", ROOT.parent / "shared" / "data" / "real"))
CONFIGS = sorted((ROOT / "configs" / "brfd").glob("*.yaml"))


def _config(path: Path, tmp_path: Path):
    """The config with its data file looked up in :data:`REAL` (skipped where it is absent)."""
    d = yaml.safe_load(path.read_text())
    for exp in d["plant"]["experiments"]:
        data = REAL / "brfd" / Path(exp["file"]).name
        if not data.is_file():
            pytest.skip(f"the real damper data ({data}) are not here")
        exp["file"] = str(data)
    out = tmp_path / path.name
    out.write_text(yaml.safe_dump(d, sort_keys=False))
    return config.load(out)


def test_one_config_per_damper_file():
    assert [p.stem for p in CONFIGS] == ["0.5hz_30lb", "1hz_0lb", "1hz_30lb"]


@pytest.mark.slow
@pytest.mark.parametrize("path", CONFIGS, ids=[p.stem for p in CONFIGS])
def test_damper_diagnosis_is_never_none_from_a_misfit(path, tmp_path):
    cfg = _config(path, tmp_path)
    lines = []
    s = diagnose(cfg, tmp_path / "out", echo=lines.append)
    effect = s["verdict"]["effect"]
    assert effect == "unexplained" or effect in CATALOGUE, effect
    ad = s["model_adequacy"]
    assert ad["verdict"] in ("adequate", "misfit", "undetermined") and ad["records"].startswith("its own records")
    assert np.isfinite(ad["rms_fit"]) and ad["floor"]["sigma"] > 0
    if ad["verdict"] == "misfit":
        assert effect != "none"
    records = load_records(cfg)
    spread = float(np.std(np.concatenate([r.y - r.y.mean() for r in records])))
    assert 0 < s["noise_floor"] <= spread
    assert ad["floor"]["sigma"] <= spread
    verdict_line = next(line for line in lines if line.startswith("verdict:"))
    assert f"RMS {ad['rms_fit']:.4g} = {ad['ratio']:.3g} x the floor" in verdict_line and ad["verdict"] in verdict_line


def _script():
    """experiments/real/damper_corrected.py, the script behind the tutorial's corrected-simulator
    section, as a module."""
    import importlib.util
    spec = importlib.util.spec_from_file_location("damper_corrected", ROOT / "experiments" / "real" / "damper_corrected.py")
    module = importlib.util.module_from_spec(spec)
    sys.modules[spec.name] = module          # its dataclass looks its module up while being defined
    spec.loader.exec_module(module)
    return module


@pytest.mark.slow
def test_damper_corrected_simulator_claims(tmp_path):
    """What docs/tutorials/damper.md says of the corrected simulator (issue 48, item 4): diagnosed
    from the 1 Hz, 30 lb log, the verdict is friction with its Coulomb level and pre-sliding
    displacement determined (intervals around the estimates, away from zero); its corrected.yaml
    carries it and beats the model without it on the fitted test and on the 0.5 Hz, 30 lb test it
    never saw; on the 1 Hz, 0 lb test neither model beats the force's mean, whose level is a third
    of the fitted test's (the band tension, which no input carries); and the model is the same at
    1024 Hz once the displacement's noise no longer reverses it at every sample."""
    if not (REAL / "brfd").is_dir():
        pytest.skip(f"the real damper data ({REAL / 'brfd'}) are not here")
    dc = _script()
    prep = dc.prepare(tmp_path, run=False)          # the run's model is the diagnosis's (the script checks)
    diagnosis = prep["diagnosis"]
    assert diagnosis["verdict"]["effect"] == "friction"
    assert diagnosis["gap_after"] < diagnosis["gap_before"]
    best = diagnosis["candidates"][0]
    assert best["effect"] == "friction"
    for name in ("coulomb", "pre_sliding"):
        lo, hi = best["intervals"][name]
        assert 0 < lo < best["params"][name] < hi
    assert best["intervals"]["viscous"] is None and "viscous" in best["intervals"]["undetermined"]
    plant = yaml.safe_load(prep["models"]["corrected"].read_text())
    assert [e["effect"] for e in plant["effects"]] == ["friction"]
    assert plant["effects"][0]["coulomb"] == pytest.approx(best["params"]["coulomb"], rel=1e-12)

    scores, records = dc.score_all(prep["models"], tmp_path / "configs")
    by = {(s.test, s.model): s for s in scores}
    for test in ("1 Hz, 30 lb", "0.5 Hz, 30 lb"):
        before, after = by[test, "whole fit"], by[test, "corrected"]
        assert after.rms < before.rms and after.fit_percent > before.fit_percent, test
    for model in ("whole fit", "corrected"):
        assert by["1 Hz, 0 lb", model].fit_percent < 0
    level = lambda y: np.percentile(np.abs(y - np.median(y)), 90)  # noqa: E731
    assert level(records["1 Hz, 0 lb"].y) < 0.5 * level(records["1 Hz, 30 lb"].y)

    check = dc.grid_check(prep["models"]["corrected"], tmp_path / "configs")
    assert abs(check["smoothed"]["fit_percent"] - by["1 Hz, 30 lb", "corrected"].fit_percent) < 1.0
    assert check["as recorded"]["fit_percent"] < check["smoothed"]["fit_percent"]
    assert check["as recorded"]["reversals"] > 2 * check["smoothed"]["reversals"]
