"""Issue 45, item 6: the banded rotary friction damper's three files (../shared/data/real/brfd/),
each diagnosed from its plain recorded config (configs/brfd/), give `unexplained` or name an effect,
with the model's own fit on its records beside the verdict, never `none` from a model that fails
its records; the noise floor is never above the force's own spread (it was 35 kip on a force of
+-3 kip). Each takes 10 s to 2 min (the 0.5 Hz file's identification at 1024 Hz)."""
from __future__ import annotations

import os
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
