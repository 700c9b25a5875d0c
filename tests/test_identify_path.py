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


def _cli(*argv) -> None:
    """``hwid ARGV`` in-process; it must succeed."""
    from hwid.cli import main
    with pytest.raises(SystemExit) as exit_:
        main([str(a) for a in argv])
    assert exit_.value.code in (0, None), argv


def test_the_stage_commands_take_the_paths_steps_on_a_simulated_plant(tmp_path, capsys):
    """A short paper config (the paper's backlash and h behind a fast G, two sines): ``hwid
    identify-nonlinear`` then ``hwid identify-linear`` write the stage results ``hwid run`` writes,
    to the last digit, and the two stages' model from them is ``run``'s model; the truth's borders
    lie within stage 1's intervals and G's gains within stage 2's."""
    import plants
    from hwid.identify.path import stages_model
    from hwid.pipeline import run
    from hwid.results import read_linear, read_nonlinear
    path = rigs.write(tmp_path / "paper.yaml", plants.config_text(plants.PAPER_FAST_G, **{
        "protocols.sine": {"amplitude": 1.0, "frequencies": [1.0, 4.0], "periods": 3, "lead_in_periods": 1}}))
    cfg = config.load(path)
    ident = run(cfg, tmp_path / "run", report=False, echo=lambda *a: None)["identification"]
    assert ident.route == "stages"
    _cli("identify-nonlinear", path, "--out", tmp_path / "st", "--json", tmp_path / "nl.json")
    said = capsys.readouterr().out
    assert said.startswith("stage 1: backlash, d+ = ") and "input nonlinearity: backlash" in said
    _cli("identify-linear", path, "--nonlinear", tmp_path / "st" / "nonlinear.h5", "--out", tmp_path / "st")
    assert "stage 2: G(jw) at 2 frequencies" in capsys.readouterr().out
    nl = read_nonlinear(tmp_path / "st" / "nonlinear.h5", cfg)
    lin = read_linear(tmp_path / "st" / "linear.h5", cfg)
    np.testing.assert_equal(nl.to_dict(), read_nonlinear(tmp_path / "run" / "nonlinear.h5", cfg).to_dict())
    np.testing.assert_equal(lin.to_dict(), read_linear(tmp_path / "run" / "linear.h5", cfg).to_dict())
    assert _params(stages_model(nl, lin)) == _params(ident.model)
    truth = from_config(cfg.plant).normalised()
    for name in ("d_plus", "slope_down", "d_minus"):
        lo, hi = nl.ci[name]
        assert lo <= getattr(truth.input, name) <= hi, name
    for g, (lo, hi) in zip(np.abs(truth.linear.freqresp(lin.frequencies)), lin.gain_ci):
        assert lo <= g <= hi


def test_the_stage_commands_take_the_paths_steps_on_a_log(tmp_path):
    """A recorded log of random levels and a sine of 12 periods (written as :func:`logs.write_log_csv` writes
    one): ``hwid identify-nonlinear`` (``history.h5``) and ``hwid identify-linear --nonlinear DIR``
    (``linear.h5``) give what ``hwid run`` reports beside its model, to the last digit; the truth's
    dead band lies within 3.29 standard errors of stage 1's estimate (its 99.9 % interval: one log at
    95 % misses one time in twenty by design; the 95 % coverage is tests/test_history_coverage.py's)."""
    from hwid.pipeline import run
    from hwid.results import read_history, read_linear
    cfg = config.loads(yaml.safe_dump(rigs.small()))
    truth = from_config(cfg.plant)
    rng = np.random.default_rng(4)
    t = np.arange(int(12 * 2 * np.pi / 1.0 / DT)) * DT    # held less than half the log: the sine is read
    u = np.concatenate([np.repeat(rng.uniform(-1.2, 1.2, 10), rng.integers(50, 70, 10)), 1.2 * np.sin(1.0 * t),
                        np.repeat(rng.uniform(-1.2, 1.2, 4), 60)])
    y = truth.simulate(u, DT, gear=0.0).x + 0.01 * rng.standard_normal(u.size)
    path = logs.write_log_csv(tmp_path, u, y, DT, whole_enabled=False)
    cfg = config.load(path)
    ident = run(cfg, tmp_path / "run", report=False, echo=lambda *a: None)["identification"]
    assert ident.history is not None and ident.linear is not None
    _cli("identify-nonlinear", path, "--out", tmp_path / "st")
    _cli("identify-linear", path, "--nonlinear", tmp_path / "st", "--out", tmp_path / "st")
    hist = read_history(tmp_path / "st" / "history.h5", cfg)
    assert hist.to_dict() == read_history(tmp_path / "run" / "history.h5", cfg).to_dict() == ident.history.to_dict()
    np.testing.assert_equal(read_linear(tmp_path / "st" / "linear.h5", cfg).to_dict(),
                            read_linear(tmp_path / "run" / "linear.h5", cfg).to_dict())
    norm = truth.normalised().input
    lo, hi = hist.ci["dead_band"]
    se = (hi - lo) / (2 * 1.959964)
    assert abs(hist.d_plus - hist.d_minus - (norm.d_plus - norm.d_minus)) <= 3.290527 * se


def test_identify_nonlinear_where_stage_1_cannot_be_read_points_to_run(tmp_path):
    """A log of two levels: stage 1 cannot be read from it, and ``hwid run`` would fit the whole
    model; ``hwid identify-nonlinear`` says so in one line, exit 2, and writes no stage 1."""
    import contextlib
    import io

    from hwid.cli import main
    cfg = config.loads(yaml.safe_dump(rigs.small()))
    rng = np.random.default_rng(5)
    u = np.concatenate([np.full(200, -0.8), 0.9 * np.sin(np.arange(800) * DT), np.full(200, 0.8)])
    y = from_config(cfg.plant).simulate(u, DT, gear=0.0).x + 0.01 * rng.standard_normal(u.size)
    path = logs.write_log_csv(tmp_path, u, y, DT)
    err = io.StringIO()
    with contextlib.redirect_stderr(err), pytest.raises(SystemExit) as exit_:
        main(["identify-nonlinear", str(path), "--out", str(tmp_path / "st")])
    assert exit_.value.code == 2
    lines = err.getvalue().strip("\n").split("\n")
    assert len(lines) == 1 and lines[0].startswith("hwid: error: ") and "hwid run" in lines[0]
    assert not (tmp_path / "st" / "history.h5").exists()


def test_identify_linear_behind_a_stage_1_that_did_not_identify_f_points_to_run(tmp_path, monkeypatch):
    """A stage 1 whose pre-compensator would command the plant 5e21 units (a slow actuator's
    unsettled levels): ``hwid run`` fits the whole model instead; ``hwid identify-linear`` says so
    in one line, exit 2, and writes no stage 2."""
    import contextlib
    import io
    from types import SimpleNamespace

    import hwid.results
    from hwid.cli import main
    from hwid.model import InputNonlinearity
    path = rigs.write(tmp_path / "small.yaml", rigs.small())
    bad = SimpleNamespace(slope_down=5.18e21, d_plus=0.547, d_minus=0.0979, fit={},
                          input_nonlinearity=lambda: InputNonlinearity("backlash_inverse", 1.0, 5.18e21, 0.547, 0.0979))
    monkeypatch.setattr(hwid.results, "read_nonlinear", lambda p, cfg=None: bad)
    err = io.StringIO()
    with contextlib.redirect_stderr(err), pytest.raises(SystemExit) as exit_:
        main(["identify-linear", str(path), "--nonlinear", str(tmp_path / "nonlinear.h5"),
              "--out", str(tmp_path / "st")])
    assert exit_.value.code == 2
    lines = err.getvalue().strip("\n").split("\n")
    assert len(lines) == 1 and "stage 2 is not run" in lines[0] and "'hwid run' fits the whole model" in lines[0]
    assert not (tmp_path / "st" / "linear.h5").exists()
