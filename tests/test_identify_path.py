"""The one identification path (:func:`hwid.identify.path.identify`): ``hwid run`` and ``hwid
diagnose`` identify the same model from one config, simulated and recorded; a recorded run always
ends with a model ``hwid compare`` accepts; a diagnosis never takes out an actuator whose absence
makes the model's free run explode."""
import numpy as np
import pytest
import yaml

import logs
import rigs
from hwid import config
from hwid.model import Actuator, from_config
from hwid.plant import Record, make_plant

DT = 0.05


def _params(model) -> dict:
    return model.to_dict()


def test_run_and_diagnose_identify_the_same_model_of_a_simulated_plant(tmp_path):
    """The small rig: the model ``hwid run`` writes (its run directory read as a MODEL) and the one
    ``hwid diagnose`` identifies before it diagnoses are the same to the last digit, by the stages'
    route, and the truth's borders lie within stage 1's intervals."""
    from hwid.diagnose.sim_side import identified_model, model_from_run
    from hwid.pipeline import run
    cfg = config.load(rigs.write(tmp_path / "small.yaml", rigs.small()))
    done = run(cfg, tmp_path / "run", report=False, echo=lambda *a: None)
    assert done["identification"].route == "stages"
    from_run, _ = model_from_run(tmp_path / "run", echo=lambda *a: None)
    from_diagnose, origin = identified_model(cfg, make_plant(cfg, journal_dir=tmp_path / "d" / "rig_journal"),
                                             tmp_path / "d", echo=lambda *a: None)
    assert origin["route"] == "stages"
    assert _params(from_diagnose) == _params(from_run) == _params(done["identification"].model)
    nl = done["identification"].nonlinear
    truth = from_config(cfg.plant).normalised().input
    for name in ("d_plus", "d_minus"):
        lo, hi = nl.ci[name]
        assert lo <= getattr(truth, name) <= hi, name


def _lab_config(tmp_path, whole_enabled: bool) -> config.Config:
    """A recorded log of 16 random levels held 2-4 s (the small rig's plant, h cubic, noise 0.01)."""
    cfg = config.loads(yaml.safe_dump(rigs.small(**{"plant.output_nonlinearity.polynomial": [0, 1.0, 0.8, -0.6],
                                                    "plant.input_nonlinearity.slope_down": 1.3})))
    truth = from_config(cfg.plant)
    rng = np.random.default_rng(12)
    u = np.repeat(rng.uniform(-1.2, 1.2, 16), rng.integers(40, 80, 16))
    y = truth.simulate(u, DT, gear=0.0).x + 0.01 * rng.standard_normal(u.size)
    return config.load(logs.write_log_csv(tmp_path, u, y, DT, whole_enabled))


def test_run_and_diagnose_identify_the_same_model_from_a_log(tmp_path):
    """A recorded log, ``identification.whole.enabled`` left false: ``hwid run`` still ends with a
    model (``whole.h5``, said to be the whole fit's), fitted on the fit part of the split the
    diagnosis makes; the diagnosis's identification gives the same parameters, and ``hwid compare``
    accepts the run directory and finds the log's own noise (0.01) in the residual."""
    from hwid.diagnose.logs import identify_from_logs
    from hwid.diagnose.sim_side import model_from_run
    from hwid.pipeline import run
    from hwid.recorded import load_records
    from hwid.results import read_whole
    cfg = _lab_config(tmp_path, whole_enabled=False)
    said = []
    done = run(cfg, tmp_path / "run", report=False, echo=said.append)
    ident = done["identification"]
    assert ident.route == "whole" and ident.held_out and ident.split
    assert not {r.name for r in ident.held_out} & {r.name for r in ident.records}   # no held-out block takes a fit start
    # each held-out block from where the fitted model, run through the fit blocks before it, puts
    # the gear and G: the model predicts the held-out part to the log's noise (0.01)
    res = []
    for r in ident.held_out:
        st = ident.starts[r.name]
        res.append(r.y - ident.model.simulate(r.u, r.dt, st["gear"], st["rest"], position=st.get("position")).x)
    assert float(np.sqrt(np.mean(np.concatenate(res) ** 2))) < 0.0115
    assert any(line.startswith("model: whole") for line in said)
    from_run, _ = model_from_run(tmp_path / "run", echo=lambda *a: None)
    records = [r for r in load_records(cfg) if r.y is not None]
    _, origin = identify_from_logs(cfg, records, tmp_path / "d", echo=lambda *a: None)
    assert origin["route"] == "whole"
    assert [r.name for r in origin["records"]] == [r.name for r in ident.records]
    assert _params(read_whole(tmp_path / "d" / "whole.h5").model()) == _params(from_run)
    from hwid.cli import main
    with pytest.raises(SystemExit) as exit_:
        main(["compare", str(tmp_path / "run"), str(tmp_path / "log.yaml"), "--out", str(tmp_path / "cmp"),
              "--json", str(tmp_path / "cmp.json")])
    assert exit_.value.code in (0, None)
    import json
    assert 0.0095 < json.loads((tmp_path / "cmp.json").read_text())["rms"] < 0.0115


def test_an_actuator_whose_absence_explodes_the_model_stays_in_the_baseline():
    """The damper's failure: h fitted behind a clip to [-0.60, 0.13] and run without it. A model
    whose h is steep beyond the clip (what such a fit gives) describes its records with the clip,
    and misses them by far more than their spread without it: the diagnosis keeps it whole and
    says why; an actuator that stops a little short of a sine of 1.2 (at -1.1 and 1.0), with a
    gentle h, is taken out and handed to input_saturation."""
    from dataclasses import replace

    from hwid.blocks.static import PolynomialH
    from hwid.diagnose.sim_side import diagnosis_baseline, free_run_explodes
    cfg = config.loads(yaml.safe_dump(rigs.small()))
    base = from_config(cfg.plant)
    u = 1.2 * np.sin(2 * np.pi * 0.2 * np.arange(2000) * DT)
    for coef, clip, explodes in (((0.0, 1.0, 0.0, 400.0), (-0.6, 0.13), True),
                                 ((0.0, 1.0, 0.0, -0.1), (-1.1, 1.0), False)):
        model = replace(base, output=PolynomialH(coef), actuator=Actuator(clip=clip))
        y = model.simulate(u, DT).x
        rec = Record("sine", DT, u, y)
        assert free_run_explodes(model, [rec]) == ""
        baseline, taken, notes = diagnosis_baseline(model, [rec], None, echo=lambda *a: None)
        if explodes:
            assert baseline is model and taken["baseline"] == "complete"
            assert "above the output's own spread" in notes[0]
        else:
            assert baseline.actuator is None and taken["input_clip_taken_out"] == list(clip)


@pytest.mark.slow
def test_a_recorded_runs_model_is_one_diagnose_accepts(tmp_path):
    """``hwid diagnose --model RUN_DIR`` on the run directory of a recorded config whose stages
    give no model (levels only, the whole fit not enabled): the diagnosis reads the run's whole
    fit and, the log being the plant's own with white noise, names nothing."""
    from hwid.cli import main
    _lab_config(tmp_path, whole_enabled=False)
    for argv in (["run", str(tmp_path / "log.yaml"), "--out", str(tmp_path / "run")],
                 ["diagnose", str(tmp_path / "log.yaml"), "--model", str(tmp_path / "run"), "--out",
                  str(tmp_path / "d"), "--json", str(tmp_path / "d.json")]):
        with pytest.raises(SystemExit) as exit_:
            main(argv)
        assert exit_.value.code in (0, None)
    import json
    s = json.loads((tmp_path / "d.json").read_text())
    assert s["model"]["fit"] == "whole" and s["model"]["source"] == "results"
    assert s["verdict"]["effect"] == "none"
