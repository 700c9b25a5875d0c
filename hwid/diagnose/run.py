"""``diagnose()`` as its steps: the sim side, the validation experiments on the plant, the noise floor
from their repeats, then :func:`hwid.diagnose.conclude.conclude` (the model's adequacy, the gap test,
the effects fitted and ranked, the verdict and its checks); a recorded plant's diagnosis is
:func:`hwid.diagnose.from_logs.diagnose_recorded`.
"""
from __future__ import annotations

import dataclasses
import time
from pathlib import Path

import numpy as np

from hwid import adequacy, protocols
from hwid.diagnose import experiments, gap
from hwid.diagnose.conclude import conclude
from hwid.diagnose.context import Context, Validation, drift_additivity, scale_of, sine_band
from hwid.diagnose.modelsim import ModelSim
from hwid.diagnose.sim_side import check_diagnosable, load_model
from hwid.plant import make_plant


def diagnose(cfg, out_dir, model=None, json_path=None, echo=print, effects=None) -> dict:
    """Diagnose the gap between the plant of ``cfg`` and a model; write ``OUT/diagnosis.h5`` and the
    JSON summary (``json_path``, default ``OUT/diagnosis.json``); return the summary
    (:meth:`hwid.diagnose.result.DiagnosisResult.to_dict`).

    Parameters
    ----------
    cfg : hwid.config.Config
    out_dir : path
        Output directory (``rig_journal/`` for resuming, ``diagnosis.h5``, ``diagnosis.json``).
    model : path or None
        The sim side (YAML plant, ``hwid run`` directory), or None to identify it first.
    effects : sequence of str, optional
        Catalogue subset to try (default: all).
    """
    if cfg.plant.kind == "recorded":
        from hwid.diagnose.from_logs import diagnose_recorded
        return diagnose_recorded(cfg, out_dir, model=model, json_path=json_path, echo=echo, effects=effects)
    t_start = time.perf_counter()
    out = Path(out_dir)
    out.mkdir(parents=True, exist_ok=True)
    plant = make_plant(cfg, journal_dir=out / "rig_journal")
    calls_start = plant.calls
    sim_model, origin = load_model(model, cfg, plant, out, echo)
    check_diagnosable(sim_model, origin, cfg.sampling.dt)
    calls_identified = plant.calls
    seconds_model = time.perf_counter() - t_start
    identified = origin.get("source") == "identified"
    band = sine_band(cfg)
    if identified and band is not None:
        from hwid.diagnose.logs import without_slow_pairs
        sim_model, notes = without_slow_pairs(sim_model, band[0], echo, "the identification's sines")
        origin["notes"] = list(origin.get("notes", [])) + notes

    val = run_validation(cfg, plant, sim_model, origin, identified, echo)
    calls_all = plant.calls
    floor, pairs = noise_floor(val)
    additive = drift_additivity(pairs, val.design, floor.sigma)
    cost = {"plant_calls_identification": calls_identified - calls_start,
            "plant_calls_validation": calls_all - calls_identified,
            "plant_calls_reused": plant.reused,
            "rig_seconds_validation": val.rig_seconds,
            "rig_seconds_identification": _identification_rig_seconds(cfg, origin),
            "seconds_model": seconds_model, "seconds_rig_validation": val.seconds_rig}

    def rerun(index: int, times: int) -> list:
        return [(x.u, plant.run(x.name, x.u, z=x.z).y, x.mask)
                for x in experiments.again(val.design, sim_model, val.exps[index], times)]

    return conclude(Context(cfg, out, json_path, val, floor, additive, sim_model, origin, effects, cost, t_start,
                            echo, rerun=rerun))


# ------------------------------------------------------------------------------------------ steps

def run_validation(cfg, plant, sim_model, origin, identified: bool, echo) -> Validation:
    """Design the diagnosis's experiments, run them on the plant (journalled), and simulate the
    model on them, each from where the plant's input was left before it (a rate-limited actuator
    carries over)."""
    design = experiments.design_from(cfg, sim_model, origin if identified else None)
    exps = experiments.design(cfg, sim_model, design)
    rig_seconds = sum(e.n for e in exps) * design.dt
    echo(f"running {len(exps)} validation experiments ({rig_seconds:.0f} rig-seconds)")
    t0 = time.perf_counter()
    records = experiments.run(plant, exps)
    seconds_rig = time.perf_counter() - t0
    fit_idx = [i for i, e in enumerate(exps) if e.role == "fit"]
    val_idx = [i for i, e in enumerate(exps) if e.role == "validation"]
    # the input the plant received before each experiment (they run in this order, after the
    # identification's records when the model was identified here): all of it for an actuator
    # with memory, whose position a slow slew carries across many experiments; the gear and G
    # after it are run through the experiment before (or the identification's last moves and hold)
    keep = max(int(round(4 * design.settle_s / design.dt)), 1)
    ids = [np.asarray(r.u, float) for r in origin.get("records", []) if np.size(getattr(r, "u", None))]
    pieces = ([ids[-1][-keep:]] if ids else []) + [e.u for e in exps]
    session = np.concatenate(pieces)                  # one array; what came before is a prefix of it
    ends = np.cumsum([p.size for p in pieces])
    first = len(pieces) - len(exps)                   # index of the first experiment among the pieces
    u_before = [session[:ends[first + i - 1]] if first + i > 0 else None for i in range(len(exps))]
    lead = [pieces[first + i - 1].size if first + i > 0 else None for i in range(len(exps))]
    sim_fit = ModelSim(sim_model, design.dt, [exps[i].u for i in fit_idx], [u_before[i] for i in fit_idx],
                       [lead[i] for i in fit_idx])
    sim_val = ModelSim(sim_model, design.dt, [exps[i].u for i in val_idx], [u_before[i] for i in val_idx],
                       [lead[i] for i in val_idx])
    scale = scale_of(design, exps, sim_fit, sim_val, records)
    return Validation(design, exps, records, fit_idx, val_idx, sim_fit, sim_val, scale, rig_seconds, seconds_rig)


def noise_floor(val: Validation):
    """The noise floor from the repeated experiments, and the repeat pairs ``(y, y_repeat, mask)``;
    never above the output's own spread (a plant that does not repeat itself at all)."""
    by_name = {e.name: (e, r) for e, r in zip(val.exps, val.records)}
    pairs = [(r.y, by_name[e.repeat_of][1].y, e.mask) for e, r in zip(val.exps, val.records) if e.repeat_of]
    floor = gap.noise_floor(pairs, int(round(2 * val.design.settle_s / val.design.dt)), val.scale.y_obs_width,
                          val.design.dt)
    spread = adequacy.output_spread([r for r in val.records if getattr(r, "y", None) is not None])
    if 0 < spread < floor.sigma:
        floor = dataclasses.replace(floor, sigma=spread)
    return floor, pairs


def _identification_rig_seconds(cfg, origin) -> float:
    if origin.get("source") != "identified":
        return 0.0
    dt = cfg.sampling.dt
    seconds = sum(st.u.size for st in protocols.staircases(cfg)) * dt
    seconds += sum(sn.z.size for sn in protocols.sines(cfg)) * dt
    return float(seconds)
