"""``hwid diagnose`` on a recorded plant (:func:`diagnose_recorded`): the steps of
:mod:`hwid.diagnose.logs` (split, model, starts, noise floor) joined to the diagnosis's last steps
(:func:`hwid.diagnose.conclude.conclude`).
"""
from __future__ import annotations

import time
from dataclasses import replace
from pathlib import Path

import numpy as np

from hwid import HwidError, adequacy
from hwid.diagnose import experiments, logs
from hwid.diagnose.conclude import conclude
from hwid.diagnose.context import Context, Validation, drift_additivity, scale_of
from hwid.diagnose.effects import catalogue
from hwid.diagnose.modelsim import ModelSim
from hwid.diagnose.next_experiment import AFTER_GEAR, propose, propose_against_play
from hwid.diagnose.sim_side import check_diagnosable, load_model
from hwid.identify.split import plan
from hwid.recorded import load_records


def diagnose_recorded(cfg, out_dir, model=None, json_path=None, echo=print, effects=None) -> dict:
    """:func:`hwid.diagnose.diagnose` for ``plant.kind: recorded``; the same JSON, plus
    ``indistinguishable``, ``next_experiment`` and ``data`` (split and noise source)."""
    t_start = time.perf_counter()
    out = Path(out_dir)
    out.mkdir(parents=True, exist_ok=True)
    records = [r for r in load_records(cfg) if r.y is not None]
    parts, how = plan(records)
    if model is not None:
        sim_model, origin = load_model(model, echo=echo)
        check_diagnosable(sim_model, origin, cfg.sampling.dt)
    else:
        sim_model, origin = logs.identify_from_logs(cfg, records, out, echo)
    seconds_model = time.perf_counter() - t_start
    val, found = validation_from_logs(cfg, records, parts, sim_model, echo, model is None)
    floor, source, pairs = logs.floor_from_logs(val.exps, val.records, val.x_model, sim_model.input, val.design)
    floor, source = bounded_floor(floor, source, records)
    echo(f"records split by {how}: fit {', '.join(val.exps[i].name for i in val.fit_idx)}; validation "
         f"{', '.join(val.exps[i].name for i in val.val_idx)}; noise floor {floor.sigma:.4g} from the {source}")
    data = {"split": how, "fit": [val.exps[i].name for i in val.fit_idx],
            "validation": [val.exps[i].name for i in val.val_idx],
            "scored_samples": {e.name: int(e.mask.sum()) for e in val.exps}, "noise_source": source,
            "starts": found,
            "records": [{"name": r.name, "samples": int(r.u.size), "seconds": float(r.u.size * cfg.sampling.dt)}
                        for r in records]}
    cost = {"plant_calls_identification": 0, "plant_calls_validation": 0, "plant_calls_reused": 0,
            "rig_seconds_validation": 0.0, "rig_seconds_identification": 0.0, "seconds_model": seconds_model,
            "seconds_rig_validation": 0.0}
    ctx = Context(cfg, out, json_path, val, floor, drift_additivity(pairs, val.design, floor.sigma), sim_model,
                  origin, effects, cost, t_start, echo, band=logs.NO_BAND, from_logs=True)
    ctx.floor_from_model = source.startswith(logs.RESIDUAL_FLOOR)
    ctx.extra = _extra(ctx, data)
    ctx.wander = _wander(val)
    return conclude(ctx)


def validation_from_logs(cfg, records, parts, sim_model, echo, identified: bool) -> tuple[Validation, dict]:
    """The log's fit and validation parts as the diagnosis's experiments, each record's start found
    (:func:`hwid.diagnose.logs.with_starts`), and the model simulated on them; returns the
    :class:`Validation` and the starts found."""
    dt = cfg.sampling.dt
    u_all = np.concatenate([r.u for r in records])
    settle_s = logs.step_settling_time(sim_model)
    design = experiments.Design(dt, float(u_all.min()), float(u_all.max()), 0.0, settle_s,
                                experiments.bandwidth(sim_model, dt), int(cfg.seed))
    scored_parts, found = logs.with_starts(parts, sim_model, dt, settle_s, echo, identified=identified)
    exps, recs = logs.split(scored_parts, design)
    fit_idx = [i for i, e in enumerate(exps) if e.role == "fit"]
    val_idx = [i for i, e in enumerate(exps) if e.role == "validation"]
    if not val_idx or not fit_idx:
        raise HwidError(f"diagnose: the records leave no {'validation' if fit_idx else 'fit'} part of "
                        f"{logs.MIN_SCORED} samples")
    pre = [int(r.attrs.get("pre", 0)) for r in recs]
    before = logs.history(recs, records)

    def sim(idx):
        return ModelSim(sim_model, dt, [exps[i].u for i in idx], [before[i] for i in idx], [0] * len(idx),
                        pre=[pre[i] for i in idx])

    sim_fit, sim_val = sim(fit_idx), sim(val_idx)
    scale = scale_of(design, exps, sim_fit, sim_val, recs)
    return Validation(design, exps, recs, fit_idx, val_idx, sim_fit, sim_val, scale, 0.0, 0.0), found


def bounded_floor(floor, source: str, records) -> tuple:
    """The diagnosis's noise floor never above the output's own spread: a floor that large came from
    a model's residual that carries more than noise (a model whose free run explodes gave a floor of
    35 kip on a force that swings 3 kip), and is replaced by what the data alone give
    (:func:`hwid.adequacy.estimate_floor` on the records; the spread itself where the data do not
    determine it); the source says so. Returns ``(floor, source)``.

    A floor below the spread is kept even where the data's own estimate is lower: a model's residual
    floor 1.6x the data's (short records of a rate-limited rig, truth 0.02, data 0.0202, residual
    0.0324) is what the diagnosis's thresholds were set against; whether the model itself is off its
    records is :mod:`hwid.diagnose.model_check`'s to say."""
    spread = adequacy.output_spread(records)
    if not 0 < spread < floor.sigma:
        return floor, source
    try:
        data = adequacy.estimate_floor(records)
    except ValueError:
        data = None
    sigma = float(min(data.sigma, spread)) if data is not None and data.determined else float(spread)
    surrogate = floor.surrogate * (sigma / floor.sigma) if np.size(floor.surrogate) else floor.surrogate
    what = f"the data alone give {data.sigma:.4g} from the {data.source}" if data is not None else "no data floor"
    note = f" gave {floor.sigma:.4g}, above the output's own spread {spread:.4g} ({what}): {sigma:.4g} used instead"
    return replace(floor, sigma=sigma, surrogate=surrogate), source + note


def _extra(ctx: Context, data: dict):
    """What a log's diagnosis adds to the summary: the data split, and for a leading group of
    effects the validation data cannot tell apart, the experiment that would."""
    available = catalogue(ctx.val.scale)

    def extra(fitter, cands, verdict, groups, summary):
        summary["data"] = data
        lead = groups[0] if groups else None
        name = summary["verdict"]["effect"]
        if lead is None or name not in lead["effects"]:
            _against_play(fitter, cands, name, summary)
            return
        members = [next(c for c in cands if c.effect == e) for e in lead["effects"]]
        members = [c for c in members if c.theta is not None]
        if len(members) >= 2:
            summary["next_experiment"] = propose(fitter, members, available, ctx.val.design, ctx.floor.sigma,
                                                 ctx.floor.kappa)
            ctx.echo(f"next experiment: {summary['next_experiment']['why']}")

    def _against_play(fitter, cands, name, summary):
        """A friction or an output hysteresis named, or the best candidate of an ``unexplained``
        verdict: the experiment that tells it from the model's own play (:func:`propose_against_play`)."""
        top = next((c for c in cands if c.effect == name), None) if name in AFTER_GEAR else (
            cands[0] if name == "unexplained" and cands and cands[0].effect in AFTER_GEAR
            and cands[0].explained_fraction > 0 else None)
        prop = propose_against_play(fitter, top, ctx.val.design, ctx.floor.sigma, ctx.floor.kappa) if top else None
        if prop is not None:
            summary["next_experiment"] = prop
            ctx.echo(f"next experiment: {prop['why']}")

    return extra


def _wander(val: Validation):
    """How far the validation holds wander from a model's outputs (:func:`hwid.diagnose.logs.holds_floor`)."""
    def wander(outputs) -> float:
        held = logs.holds_floor([val.exps[i] for i in val.val_idx], [val.records[i] for i in val.val_idx], outputs,
                                val.design)
        return float(held[0].slow_z) if held is not None else float("nan")

    return wander
