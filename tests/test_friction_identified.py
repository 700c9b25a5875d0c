"""Friction fed back to G's input, diagnosed with an IDENTIFIED model (no ``--model``): the
identification takes the friction loop for G (the Dahl force is a spring in G's loop while the load
pre-slides), and the effect's joint refit must reach the plant's G again
(:data:`hwid.diagnose.effects_after_gear.G_FACTOR_AFTER_GEAR`).

Rigs simulated apart from hwid: the base plant of ``tests/diagnose_rigs.py`` with a Dahl force on
the load (``friction_on_load``), and a two-mass drive with a Dahl force on its load drawn by the
blind check's generator (``experiments/diagnosis_blind/rigkit.py``; development seed 10313's c13,
its config as generated), whose identified G carries two zeros and a slow pole the plant has not.
The plain base rig identified the same way is called neither friction nor output hysteresis.
"""
from __future__ import annotations

import sys
from pathlib import Path

import pytest
import yaml

from hwid import config
from hwid.diagnose import diagnose

import diagnose_rigs as R

DT = 0.04
BLIND = Path(__file__).resolve().parents[1] / "experiments" / "diagnosis_blind"
#: the blind generator's two-mass rig with Dahl friction on the load (seed 10313, c13): F, G, h,
#: noise, the friction's truth (``z_c``: the pre-sliding displacement), every state reset between
#: calls
TWO_MASS = {"F": {"type": "backlash", "slope_up": 1.0727, "slope_down": 1.0841, "d_plus": 0.0729,
                  "d_minus": -0.0532},
            "G": {"num": [7.5603], "den": [0.402, 1.3236, 3.8443, 7.5603]}, "h": [0, 1.0, 0.1729, -0.0028],
            "noise": {"std": 0.01, "ar": 0.288}, "effect": "friction",
            "effect_params": {"law": "dahl", "coulomb": 0.11212629714881872, "z_c": 0.1060547574685791,
                              "viscous": 0.008567973564489543},
            "seed": 2452957040, "between_calls": "reset", "actuator": "reset", "levels": [-1.5, 1.5]}
TWO_MASS_CONFIG = {"name": "two-mass", "seed": 20, "sampling": {"dt": 0.02},
                   "protocols": {"staircase": {"levels_up": [-1.5, -1.1667, -0.8333, -0.5, -0.1667, 0.1667, 0.5,
                                                             0.8333, 1.1667, 1.5],
                                               "levels_down": [1.5, 1.2, 0.9, 0.6, 0.3, 0.0, -0.3, -0.6, -0.9, -1.2,
                                                               -1.5], "hold": 12.4},
                                 "sine": {"amplitude": 1.0, "frequencies": [0.4, 1.2, 1.9247, 4.1244], "periods": 4,
                                          "lead_in_periods": 1}}}
_STATE: dict = {}
_DONE: dict = {}


def two_mass_dahl(u, dt):
    """:data:`TWO_MASS` on the generator's simulator."""
    if str(BLIND) not in sys.path:
        sys.path.insert(0, str(BLIND))
    import rigkit
    return rigkit.run(TWO_MASS, _STATE, u, dt)


def _identified(tmp_path, driver: str) -> dict:
    if driver == "two_mass_dahl":
        _STATE.clear()
        d = dict(TWO_MASS_CONFIG, plant={"kind": "external", "callable": f"{__name__}:two_mass_dahl"})
    else:
        d = {"name": "rig", "seed": 5, "sampling": {"dt": DT},
             "plant": {"kind": "external", "callable": f"diagnose_rigs:{driver}"},
             "protocols": {"staircase": {"levels_up": [-1.0, -0.75, -0.5, -0.25, 0.0, 0.25, 0.5, 0.75, 1.0],
                                         "levels_down": [1.0, 0.75, 0.5, 0.25, 0.0, -0.25, -0.5, -0.75, -1.0],
                                         "hold": 8.0},
                           "sine": {"amplitude": 0.8, "frequencies": [0.5, 1.0, 2.0], "periods": 3}}}
        R._RIGS.pop(driver, None)
    (tmp_path / "cfg.yaml").write_text(yaml.safe_dump(d))
    return diagnose(config.load(tmp_path / "cfg.yaml"), tmp_path / "out", model=None, echo=lambda *a: None)


def _two_mass(tmp_path_factory) -> dict:
    if "two_mass" not in _DONE:
        _DONE["two_mass"] = _identified(tmp_path_factory.mktemp("two_mass"), "two_mass_dahl")
    return _DONE["two_mass"]


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
def test_friction_on_a_two_mass_drive_named_from_an_identified_model(tmp_path_factory):
    """The two-mass rig: friction on the load named, what is left within 1.3x the noise floor
    (refit within a factor 5 of the identified G's coefficients it left 5.8x and was unexplained)."""
    s = _two_mass(tmp_path_factory)
    assert s["verdict"]["effect"] == "friction", s["verdict"]
    top = next(c for c in s["candidates"] if c["effect"] == "friction")
    assert top["params"]["fed_back"] == 1.0
    assert s["gap_after"] < 1.3 * s["noise_floor"], (s["gap_after"], s["noise_floor"])


def normalised_truth(plant: dict) -> dict:
    """The generator's friction in the units of the identified model, which is normalised (eqs.
    4a-c): F's output divided by its ascending slope ``k_v`` (a Backlash's ``slope_up``), G's by
    ``k_w = k_v G(0)``. The force acts on G's input (``v``'s units: the Coulomb level over
    ``k_v``), the pre-sliding displacement is a travel of G's output (``w``'s: over ``k_w``), the
    viscous term a force per velocity of G's output (times ``k_w / k_v``)."""
    k_v = plant["F"]["slope_up"]
    k_w = k_v * plant["G"]["num"][-1] / plant["G"]["den"][-1]
    p = plant["effect_params"]
    return {"coulomb": p["coulomb"] / k_v, "pre_sliding": p["z_c"] / k_w, "viscous": p["viscous"] * k_w / k_v}


@pytest.mark.slow
def test_friction_on_a_two_mass_drive_intervals_cover_the_truth(tmp_path_factory):
    """The friction's 95 % intervals cover the truth in the model's units (:func:`normalised_truth`).
    The fit leaves more than the floor on its own experiments (the identified G's structure is not
    the plant's), so the intervals also carry the delete-one-experiment jackknife
    (:mod:`hwid.diagnose.intervals`): the noise's alone held the pre-sliding displacement to
    +-0.75 %. Two of G's coefficients (the identified G's zeros) end on the refit's box, whose pull
    the friction takes up (Coulomb 2.8 % high, pre-sliding 3.3 % low): the intervals reach the fit
    with the box released."""
    s = _two_mass(tmp_path_factory)
    top = next(c for c in s["candidates"] if c["effect"] == "friction")
    for name, value in normalised_truth(TWO_MASS).items():
        iv = top["intervals"][name]
        assert iv is not None and iv[0] <= value <= iv[1], (name, value, iv, top["params"])


@pytest.mark.slow
def test_a_plain_rig_identified_is_neither(tmp_path):
    """The base rig without an effect, identified: neither friction nor output hysteresis."""
    s = _identified(tmp_path, "plain")
    assert s["verdict"]["effect"] not in ("friction", "output_hysteresis"), s["verdict"]
