"""``plant.effects`` and the diagnosis's ``corrected.yaml`` against known truth.

The rigs are hwid's own simulated plants: the base plant of ``tests/diagnose_rigs.py`` (a backlash
of play 0.3, ``G = 2/((s+1)(s+2))``, ``h = w - 0.1 w^3``, white noise 0.01) carrying one catalogue
effect through the new key, diagnosed with the base plant as ``--model``.

* Each effect in a model runs the very code the diagnosis's effect does: on the same input, the
  model simulates what the diagnosis's effect predicts, to rounding (1e-12).
* Round trip: ``corrected.yaml``, simulated from each validation experiment's start the diagnosis
  noted (``diagnosis.h5``, ``start_after``), gives the diagnosis's own "after" prediction to 1e-9.
* Held out: ``hwid compare corrected.yaml`` on experiments the diagnosis never saw (another
  protocol, another seed) leaves at most 1.2x the noise floor (the simulated noise, known).
"""
from __future__ import annotations

import numpy as np
import pytest
import yaml

from hwid import config
from hwid.cli import main
from hwid.compare import compare
from hwid.diagnose import diagnose
from hwid.diagnose.effect_base import Scale
from hwid.diagnose.effects import catalogue
from hwid.diagnose.effects_after_gear import form_theta
from hwid.diagnose.modelsim import ModelSim
from hwid.diagnose.sim_side import model_from_yaml
from hwid.model import from_config
from hwid.results import read_diagnosis

import diagnose_rigs as R

DT = 0.04
NOISE = R.NOISE

#: each effect a plant can carry, at a size the base plant's experiments show well above the noise
EFFECTS = {
    "input_saturation": {"u_lo": -0.7, "u_hi": 0.6},
    "rate_limit": {"rate": 0.4},
    "input_deadzone": {"delta": 0.2},
    "curved_borders": {"c0": 0.0, "c1_up": 0.0, "c2_up": 0.06, "c1_down": 0.0, "c2_down": -0.04,
                       "u_centre": 0.0, "u_half_width": 1.0},
    "time_delay": {"delay_s": 0.3},
    "resonance": {"omega_n": 4.0, "zeta": 0.05},
    "sensor_lag": {"tau_s": 1.5},
    "sensor_saturation": {"y_lo": -0.55, "y_hi": 0.55},
    "friction": {"coulomb": 0.1, "pre_sliding": 0.05},
    "output_hysteresis": {"width": 0.1, "weight": 1.0},
}
FAST = ("sensor_lag",)      # one diagnosis in the fast suite; the others take 7-15 s each


def _plant(effect: str, params: dict | None = None) -> dict:
    return {**R.BASE, "effects": [{"effect": effect, **(EFFECTS[effect] if params is None else params)}]}


def _config(plant: dict, seed: int = 5, held_out: bool = False) -> dict:
    if held_out:        # another protocol: other levels, holds, amplitude and frequencies
        protocols = {"staircase": {"levels_up": [-0.9, -0.6, -0.3, 0.0, 0.3, 0.6, 0.9],
                                   "levels_down": [0.9, 0.6, 0.3, 0.0, -0.3, -0.6, -0.9], "hold": 6.0},
                     "sine": {"amplitude": 0.7, "frequencies": [0.7, 1.5], "periods": 3}}
    else:
        protocols = {"staircase": {"levels_up": [-1.0, -0.75, -0.5, -0.25, 0.0, 0.25, 0.5, 0.75, 1.0],
                                   "levels_down": [1.0, 0.75, 0.5, 0.25, 0.0, -0.25, -0.5, -0.75, -1.0], "hold": 8.0},
                     "sine": {"amplitude": 0.8, "frequencies": [0.5, 1.0, 2.0], "periods": 3}}
    return {"name": "rig", "seed": seed, "sampling": {"dt": DT}, "plant": plant, "protocols": protocols}


def _write(path, data) -> str:
    path.write_text(yaml.safe_dump(data))
    return str(path)


# ------------------------------------------------------------------------------------- the key

# parameters that reach every branch: the absorbed shares, a bend with its play free and a tangent
# beyond the fit range, a viscous term, a partial hysteresis weight
BRANCHES = {**EFFECTS, "input_deadzone": {"delta": 0.2, "absorbed": 0.5},
            "sensor_lag": {"tau_s": 1.5, "absorbed": 0.3},
            "curved_borders": {"c0": 0.01, "c1_up": 0.05, "c2_up": 0.2, "c1_down": -0.05, "c2_down": -0.15,
                               "play": 0.02, "u_centre": 0.0, "u_half_width": 1.0, "fit_lo": -0.8, "fit_hi": 0.8},
            "friction": {"coulomb": 0.1, "pre_sliding": 0.05, "viscous": 0.05},
            "output_hysteresis": {"width": 0.1, "weight": 0.7}}


@pytest.mark.parametrize("effect", sorted(EFFECTS))
def test_each_effect_in_a_model_is_the_diagnosis_s_own(effect):
    """The model with the effect from the config, and the diagnosis's effect at the same
    parameters on the plain model, simulate the same output."""
    params = BRANCHES[effect]
    model = from_config(config.parse_plant(_plant(effect, params), "test"))
    assert [e.effect for e in model.effects] == [effect]
    t = np.arange(0, 40, DT)
    u = np.r_[np.zeros(50), 1.1 * np.sin(0.6 * t) + 0.2 * np.sign(np.sin(2.1 * t))]
    plain = from_config(config.parse_plant(R.BASE, "test"))
    eff = catalogue(Scale(DT, -1.0, 1.0, -1.0, 1.0, 1.0, 4.0, 1.0, 40.0, u_fit_min=-0.8, u_fit_max=0.8))[effect]
    theta = model.effects[0].theta()
    if effect == "curved_borders":
        eff = eff._like(2, play=True)
    elif effect in ("friction", "output_hysteresis"):       # the form the spec is
        eff, theta = form_theta(model.effects[0])
    want = eff.simulate(ModelSim(plain, DT, [u]), theta, 0)
    got = model.simulate(u, DT).x
    assert np.all(np.isfinite(got))
    assert np.max(np.abs(got - want)) < 1e-12
    # and the effect is not a no-op: the plain model differs
    assert np.max(np.abs(got - plain.simulate(u, DT).x)) > 3 * NOISE


@pytest.mark.parametrize("effect", sorted(EFFECTS))
@pytest.mark.parametrize("kind", ["backlash", "backlash_inverse"])
def test_a_model_with_effects_normalised_gives_the_same_output(effect, kind):
    """Eqs. (4a-c) with effects: F's scale (S^a = 2) and G's gain (3) move into h, a friction's
    levels and a hysteresis's width into the normalised units; the output stays the same."""
    plant = {**_plant(effect, BRANCHES[effect]), "linear": {"num": [6.0], "den": [1.0, 3.0, 2.0]}}
    plant["input_nonlinearity"] = {**plant["input_nonlinearity"], "type": kind, "slope_up": 2.0, "slope_down": 1.5}
    model = from_config(config.parse_plant(plant, "test"))
    t = np.arange(0, 40, DT)
    u = np.r_[np.zeros(50), 1.1 * np.sin(0.6 * t) + 0.2 * np.sign(np.sin(2.1 * t))]
    x = model.simulate(u, DT).x
    assert np.max(np.abs(model.normalised().simulate(u, DT).x - x)) < 1e-9 * max(1.0, np.max(np.abs(x)))


def _cli(argv, capsys) -> tuple[int, str]:
    with pytest.raises(SystemExit) as exc:
        main([str(a) for a in argv])
    return exc.value.code, capsys.readouterr().err


@pytest.mark.parametrize("entry, fragment", [
    ({"effect": "rate_limit", "rate": -0.4}, "plant.effects[0].rate: must be greater than 0"),
    ({"effect": "resonance", "omega_n": 4.0, "zeta": 0.0}, "plant.effects[0].zeta: must be greater than 0"),
    ({"effect": "input_saturation", "u_lo": 0.6, "u_hi": -0.7}, "lower limit (0.6) must be below the upper"),
    ({"effect": "output_hysteresis", "width": 0.1, "weight": 1.5}, "plant.effects[0].weight"),
    ({"effect": "rate_limit", "rat": 0.4}, "unknown key 'rat' (did you mean 'rate'?)"),
    ({"effect": "rate_limt", "rate": 0.4}, "unknown effect 'rate_limt' (did you mean 'rate_limit'?"),
    ({"effect": "drift", "window_s": 3.0}, "drift is a disturbance"),
])
def test_a_bad_effect_is_one_line_and_exit_2(tmp_path, capsys, entry, fragment):
    plant = {**R.BASE, "effects": [entry]}
    code, err = _cli(["check", _write(tmp_path / "c.yaml", _config(plant))], capsys)
    lines = err.strip().splitlines()
    assert code == 2 and len(lines) == 1 and "Traceback" not in err, err
    assert fragment in lines[0], lines[0]


# ------------------------------------------------------------------------- diagnosis round trip

_DIAGNOSED: dict = {}


def _diagnosed(effect: str, tmp_path_factory):
    """The diagnosis of the base plant carrying ``effect``, its plain simulator as ``--model``
    (once per effect and session)."""
    if effect not in _DIAGNOSED:
        tmp = tmp_path_factory.mktemp(effect)
        base = _write(tmp / "base.yaml", {"plant": R.BASE})
        cfg = config.load(_write(tmp / "rig.yaml", _config(_plant(effect))))
        summary = diagnose(cfg, tmp / "out", model=base, echo=lambda *a: None)
        _DIAGNOSED[effect] = (summary, tmp)
    return _DIAGNOSED[effect]


def _cases(names):
    return [n if n in FAST else pytest.param(n, marks=pytest.mark.slow) for n in names]


@pytest.mark.parametrize("effect", _cases(["rate_limit", "time_delay", "sensor_lag", "resonance", "input_saturation",
                                            "curved_borders", "friction", "output_hysteresis"]))
def test_corrected_model_reproduces_the_diagnosis_s_after_prediction(effect, tmp_path_factory):
    summary, tmp = _diagnosed(effect, tmp_path_factory)
    assert summary["verdict"]["effect"] == effect
    text = (tmp / "out" / "corrected.yaml").read_text()
    assert text.startswith(f"# hwid diagnose: the model diagnosed with, plus {effect}")
    model = model_from_yaml(tmp / "out" / "corrected.yaml")
    assert [e.effect for e in model.effects] == [effect]
    fitted = next(c["params"] for c in summary["candidates"] if c["effect"] == effect)
    assert {k: v for k, v in model.effects[0].params if k in fitted} == pytest.approx(fitted, rel=1e-15)
    diag = read_diagnosis(tmp / "out" / "diagnosis.h5")
    val = [e for e in diag["experiments"].values() if e["role"] == "validation"]
    assert val
    for e in val:
        st = e["start_after"]
        assert st["exact"], e
        x = model.simulate(e["u"], e["dt"], gear=st["gear"], rest=st["rest"], position=st["position"],
                           ringing=st["ringing"], memory=st.get("memory")).x
        assert np.max(np.abs(x - e["y_after"])) < 1e-9


@pytest.mark.parametrize("effect", _cases(sorted(EFFECTS)))
def test_corrected_model_on_held_out_experiments_is_within_the_noise(effect, tmp_path_factory):
    """``hwid compare corrected.yaml`` on another protocol run on the same plant (another seed)."""
    summary, tmp = _diagnosed(effect, tmp_path_factory)
    assert summary["verdict"]["effect"] == effect
    held = config.load(_write(tmp / "held_out.yaml", _config(_plant(effect), seed=17, held_out=True)))
    before = compare(tmp / "base.yaml", held, tmp / "cmp_base", echo=lambda *a: None)
    after = compare(tmp / "out" / "corrected.yaml", held, tmp / "cmp_corrected", echo=lambda *a: None)
    assert after.noise_floor == pytest.approx(NOISE)
    assert after.rms_over_floor <= 1.2, (effect, before.rms_over_floor, after.rms_over_floor)
    assert before.rms_over_floor > after.rms_over_floor


def test_an_unexplained_or_none_verdict_writes_the_model_as_it_was(tmp_path):
    """The plain plant diagnosed with its own simulator: verdict none, the model written unchanged."""
    base = _write(tmp_path / "base.yaml", {"plant": R.BASE})
    cfg = config.load(_write(tmp_path / "rig.yaml", _config(R.BASE)))
    summary = diagnose(cfg, tmp_path / "out", model=base, echo=lambda *a: None)
    assert summary["verdict"]["effect"] == "none"
    text = (tmp_path / "out" / "corrected.yaml").read_text()
    assert text.startswith("# hwid diagnose: verdict none: the model as it was diagnosed")
    assert model_from_yaml(tmp_path / "out" / "corrected.yaml") == model_from_yaml(tmp_path / "base.yaml")


def _round_trip_error(out) -> float:
    """The largest difference between ``OUT/corrected.yaml`` simulated from the noted starts and the
    diagnosis's after-prediction, over the validation experiments (each start must be exact)."""
    model = model_from_yaml(out / "corrected.yaml")
    worst = 0.0
    for e in read_diagnosis(out / "diagnosis.h5")["experiments"].values():
        if e["role"] != "validation":
            continue
        st = e["start_after"]
        assert st["exact"], e["start_after"]
        x = model.simulate(e["u"], e["dt"], gear=st["gear"], rest=st["rest"], position=st["position"],
                           ringing=st["ringing"], memory=st.get("memory")).x
        worst = max(worst, float(np.max(np.abs(x - e["y_after"]))))
    return worst


@pytest.mark.slow
def test_an_identified_model_s_corrected_yaml_round_trips(tmp_path):
    """Without ``--model``: F and G as the effect's joint fit left them, h re-estimated with it and
    written in powers of w, reproduce the after-prediction as well. A delay: an identified rational
    G cannot take it up (a sensor lag it can: stage 2 then fits one more pole, and the verdict is
    rightly ``none``)."""
    cfg = config.load(_write(tmp_path / "rig.yaml", _config(_plant("time_delay"))))
    summary = diagnose(cfg, tmp_path / "out", echo=lambda *a: None)
    assert summary["verdict"]["effect"] == "time_delay"
    assert _round_trip_error(tmp_path / "out") < 1e-9


@pytest.mark.slow
def test_corrected_yaml_as_model_again_leaves_nothing_to_name(tmp_path_factory):
    """The time-delay rig diagnosed again with its corrected model as ``--model``: none."""
    _, tmp = _diagnosed("time_delay", tmp_path_factory)
    cfg = config.load(tmp / "rig.yaml")
    again = diagnose(cfg, tmp / "again", model=tmp / "out" / "corrected.yaml", echo=lambda *a: None)
    assert again["verdict"]["effect"] == "none"
    assert again["gap_before"] / again["noise_floor"] < 1.1


def test_corrected_yaml_loads_through_the_api_and_a_friction_model_is_refused_as_model(tmp_path, capsys):
    import hwid
    plant = _plant("friction")
    path = tmp_path / "corrected.yaml"
    _write(path, plant)
    u = np.r_[np.zeros(20), np.linspace(0, 1, 200), np.ones(100), np.linspace(1, -1, 300)]
    want = from_config(config.parse_plant(plant, "test")).simulate(u, DT).x
    assert np.array_equal(hwid.Model.load(path).simulate(u, DT), want)
    cfg = _write(tmp_path / "rig.yaml", _config(R.BASE))
    code, err = _cli(["diagnose", cfg, "--model", path, "--out", tmp_path / "out"], capsys)
    assert code == 2 and err.count("\n") == 1 and "cannot be diagnosed further" in err, err
