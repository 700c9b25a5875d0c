"""Stage 1 behind an input dead zone (:mod:`hwid.identify.deadzone_ahead`), against the paper's
plant behind a dead zone of 0.21 (``tests/diagnose_rigs.py``): the borders, read against u, have a
flat step; the plain stage 1 is grossly overdispersed, and behind the dead zone it finds, the
paper's borders and h come back."""
from __future__ import annotations

import numpy as np
import pytest
import yaml

from hwid import config
from hwid.blocks.deadzone import deadzone, deadzone_inverse
from hwid.diagnose import diagnose
from hwid.identify import deadzone_ahead
from hwid.identify.nonlinear import identify_nonlinear
from hwid.plant import Record

import diagnose_rigs as R


def _cfg(tmp_path, rig: str):
    d = {"name": f"paper-{rig}", "seed": 5, "sampling": {"dt": 0.05},
         "plant": {"kind": "external", "callable": f"diagnose_rigs:{rig}"},
         "protocols": {"staircase": {"levels_up": [round(float(x), 4) for x in np.linspace(-1.4, 1.2, 10)],
                                     "levels_down": [round(float(x), 4) for x in np.linspace(1.2, -1.4, 11)[1:]],
                                     "hold": 30.0},
                       "sine": {"amplitude": 1.0, "frequencies": [0.02, 0.05, 0.1, 0.2], "periods": 3}}}
    (tmp_path / "cfg.yaml").write_text(yaml.safe_dump(d))
    return config.load(tmp_path / "cfg.yaml")


def test_the_inverse_passes_through_the_dead_zone():
    v = np.linspace(-1, 1, 41)
    assert np.allclose(deadzone(deadzone_inverse(v, 0.3), 0.3), v)
    assert deadzone_inverse(np.array([0.0]), 0.3)[0] == 0.0


@pytest.fixture(scope="module")
def stage1(tmp_path_factory):
    cfg = _cfg(tmp_path_factory.mktemp("dz"), "input_deadzone_paper")
    plain, records = identify_nonlinear(cfg)
    return cfg, plain, records


def test_stage_1_behind_the_dead_zone_finds_it_and_the_papers_borders(stage1):
    cfg, plain, records = stage1
    assert plain.fit["overdispersion"] > deadzone_ahead.GROSS
    found = deadzone_ahead.find_deadzone(cfg, plain, records)
    assert found is not None
    assert abs(found.delta - R.TRUTH["input_deadzone_paper"]["delta"]) < 0.015
    assert found.overdispersion <= deadzone_ahead.CONSISTENT
    r = found.result
    assert r.type == "backlash" and r.degree == 5
    # the paper's borders (d+ = 0.5, S^d = 1, d- = -0.5) within their intervals
    for name, true in (("d_plus", 0.5), ("slope_down", 1.0), ("d_minus", -0.5)):
        lo, hi = r.ci[name]
        assert lo <= true <= hi, (name, lo, hi)


def test_stage_1_tells_its_user_of_the_dead_zone(stage1, tmp_path):
    """Stage 1 as `hwid identify-nonlinear` and `hwid run` take it (:func:`hwid.identify.path.stage1`):
    the result behind the dead zone it finds, marked so, in ``nonlinear.h5`` too, for the stage 2
    `hwid identify-linear` reads from it (driven through the dead zone's inverse) and the model; and said."""
    from hwid.identify import path
    from hwid.results import read_nonlinear
    cfg, plain, records = stage1
    said = []
    one = path.stage1(cfg, data={rec.name: rec for rec in records}, out_dir=tmp_path, echo=said.append)
    r = one.result
    assert path.deadzone_behind(read_nonlinear(one.paths["nonlinear"], cfg)) == path.deadzone_behind(r) > 0
    assert any("behind a dead zone" in line for line in said)
    assert "behind a dead zone" in r.warnings[-1]
    found = r.fit["deadzone_ahead"]
    assert found["behind"] and path.deadzone_behind(r) == found["delta"]
    lo, hi = found["delta_ci"]
    assert lo <= R.TRUTH["input_deadzone_paper"]["delta"] <= hi
    assert r.type == "backlash" and r.degree == 5
    for name, true in (("d_plus", 0.5), ("slope_down", 1.0), ("d_minus", -0.5)):
        lo, hi = r.ci[name]
        assert lo <= true <= hi, (name, lo, hi)


def test_a_plant_without_a_dead_zone_is_left_alone(tmp_path):
    cfg = _cfg(tmp_path, "sensor_saturation_paper")
    plain, records = identify_nonlinear(cfg)
    assert plain.fit["overdispersion"] < deadzone_ahead.GROSS
    assert deadzone_ahead.find_deadzone(cfg, plain, records) is None


def test_a_clip_that_stage_1_cannot_fit_is_not_taken_for_a_dead_zone(tmp_path):
    """The paper's plant behind an input clip: stage 1 is as far off as behind a dead zone, so the
    search runs, and no width makes the levels fit."""
    cfg = _cfg(tmp_path, "input_saturation_paper")
    plain, records = identify_nonlinear(cfg)
    assert plain.fit["overdispersion"] > deadzone_ahead.GROSS
    assert deadzone_ahead.find_deadzone(cfg, plain, records) is None


def test_stage_2_drives_the_plant_through_the_inverse():
    class Plant:
        def __init__(self):
            self.calls = 0

        def run(self, name, u, z=None):
            self.calls += 1
            return Record(name, 0.1, np.asarray(u, float), np.zeros(len(u)))

    plant = Plant()
    through = deadzone_ahead.ThroughDeadZone(plant, 0.2)
    v = np.array([-0.5, 0.0, 0.3])
    rec = through.run("sine_0", v)
    assert np.array_equal(rec.u, v)
    assert np.allclose(through.sent["sine_0"].u, [-0.7, 0.0, 0.5])
    assert through.calls == 1


@pytest.mark.filterwarnings("ignore")
def test_the_dead_zone_is_named_with_the_model_identified_behind_it(tmp_path):
    """Identified through the plain stage 1, the paper's plant behind a dead zone was `unexplained`
    at 26-36x the floor on judged seeds (the borders and G wrong); behind the dead zone stage 1
    finds, the model is the paper's and the dead zone is named with its width."""
    said = []
    s = diagnose(_cfg(tmp_path, "input_deadzone_paper"), tmp_path / "out", echo=said.append)
    assert any("behind a dead zone" in line for line in said)
    assert s["model"]["input_deadzone_taken_out"] > 0
    assert s["verdict"]["effect"] == "input_deadzone"
    top = s["candidates"][0]
    assert abs(top["params"]["delta"] - R.TRUTH["input_deadzone_paper"]["delta"]) < 0.01
    assert s["gap_before"] > 5 * s["noise_floor"] and s["gap_after"] < 1.5 * s["noise_floor"]
    den = np.asarray(s["model"]["linear"]["den"]) / s["model"]["linear"]["den"][0]
    assert np.allclose(den, [1.0, 0.7, 0.1], atol=0.02)
