"""Friction fed back to G's input, diagnosed with an IDENTIFIED model (no ``--model``): the
identification takes the friction loop for G (the Dahl force is a spring in G's loop while the load
pre-slides), and the effect's joint refit must reach the plant's G again
(:data:`hwid.diagnose.effects_after_gear.G_FACTOR_AFTER_GEAR`).

The rig (``tests/diagnose_rigs.py::friction_on_load``, integrated apart from hwid over 40 substeps
a sample) is the base plant with a Dahl force on the load; the truth is
``diagnose_rigs.TRUTH["friction_on_load"]``. The plain base rig identified the same way is called
neither friction nor output hysteresis.
"""
from __future__ import annotations

import pytest
import yaml

from hwid import config
from hwid.diagnose import diagnose

import diagnose_rigs as R

DT = 0.04


def _identified(tmp_path, driver: str) -> dict:
    d = {"name": "rig", "seed": 5, "sampling": {"dt": DT},
         "plant": {"kind": "external", "callable": f"diagnose_rigs:{driver}"},
         "protocols": {"staircase": {"levels_up": [-1.0, -0.75, -0.5, -0.25, 0.0, 0.25, 0.5, 0.75, 1.0],
                                     "levels_down": [1.0, 0.75, 0.5, 0.25, 0.0, -0.25, -0.5, -0.75, -1.0],
                                     "hold": 8.0},
                       "sine": {"amplitude": 0.8, "frequencies": [0.5, 1.0, 2.0], "periods": 3}}}
    R._RIGS.pop(driver, None)
    (tmp_path / "cfg.yaml").write_text(yaml.safe_dump(d))
    return diagnose(config.load(tmp_path / "cfg.yaml"), tmp_path / "out", model=None, echo=lambda *a: None)


@pytest.mark.slow
def test_friction_on_the_load_named_from_an_identified_model(tmp_path):
    """Named friction on the load, its Coulomb level's 95 % interval covering the truth, and what
    is left within 1.3x the noise floor."""
    s = _identified(tmp_path, "friction_on_load")
    assert s["verdict"]["effect"] == "friction", s["verdict"]
    top = next(c for c in s["candidates"] if c["effect"] == "friction")
    assert top["params"]["fed_back"] == 1.0
    iv = top["intervals"]["coulomb"]
    truth = R.TRUTH["friction_on_load"]["coulomb"]
    assert iv is not None and iv[0] <= truth <= iv[1], (iv, top["params"])
    assert s["gap_after"] < 1.3 * s["noise_floor"], (s["gap_after"], s["noise_floor"])


@pytest.mark.slow
def test_a_plain_rig_identified_is_neither(tmp_path):
    """The base rig without an effect, identified: neither friction nor output hysteresis."""
    s = _identified(tmp_path, "plain")
    assert s["verdict"]["effect"] not in ("friction", "output_hysteresis"), s["verdict"]
