"""The diagnosis's product: ``OUT/corrected.yaml``, the model it diagnosed with plus the verdict's
effect at its fitted parameters, as a plant YAML (``kind: hammerstein_wiener``, F, G, h,
``effects``) that ``hwid compare``, ``hwid diagnose --model``, ``hwid simulate`` (as a config's
plant) and :meth:`hwid.api.Model.load` read.

The model is the one the verdict's prediction on the validation experiments is
(:func:`corrected`): with a given model, that model (its actuator and effects kept) with the effect
added; with an identified one, F and G as the effect's joint fit left them and h re-estimated with
it. An effect of the input acts on the command in place of the model's actuator, as in the
diagnosis. The model's actuator is written as the equivalent effects (``input_saturation``,
``rate_limit``, ``input_deadzone``): one representation in YAML. For ``none``, ``unexplained`` or
``drift`` (a disturbance no model simulates from its input) the model is written as it was, a
comment saying so.

Each validation experiment's start (the gear, G's rest level, a carried actuator's position) that
makes this model give the diagnosis's "after" prediction goes into ``diagnosis.h5``
(``start_after``, :func:`starts_after`): simulated from there, the corrected model reproduces it to
rounding, which ``tests/test_corrected.py`` checks.
"""
from __future__ import annotations

from dataclasses import replace
from pathlib import Path

import numpy as np
import yaml

from hwid import HwidError, config
from hwid.blocks.static import PiecewiseH, PolynomialH
from hwid.diagnose.verdict import Candidate
from hwid.model import HWModel
from hwid.results import write_text

NAME = "corrected.yaml"


def corrected(verdict, fitter, sim_model: HWModel) -> tuple[HWModel, bool]:
    """The model of the verdict's prediction and whether the verdict's effect is in it (False: the
    model as it was, for ``none``, ``unexplained`` or a disturbance)."""
    if not isinstance(verdict, Candidate) or verdict.fitted is None or verdict.fitted.disturbance:
        return _with_actuator_as_effects(sim_model), False
    eff, theta = verdict.fitted, np.asarray(verdict.theta, float)
    fitter = _fitter_of(verdict, fitter)
    if fitter.refit_h:
        F, G, h, own = fitter.refit_blocks(eff, theta)
        base = HWModel(F, G, h, sim_model.actuator, sim_model.effects)
    else:
        base, own = sim_model, theta
    if eff.block == "input":        # it acts on the command in place of the model's actuator
        base = base.without_actuator()
    base = _with_actuator_as_effects(base)
    return replace(base, effects=base.effects + (eff.spec(own),)), True


def _fitter_of(verdict, fitter):
    """The fitter whose baseline the verdict was fitted on: ``fitter``, or the one with the
    identified G's own modes taken out (:func:`hwid.diagnose.conclude.fit_effects`)."""
    return getattr(verdict, "own_fitter", None) or fitter


def _with_actuator_as_effects(model: HWModel) -> HWModel:
    if model.actuator is None:
        return model
    return replace(model, actuator=None, effects=model.actuator.as_effects() + model.effects)


def starts_after(verdict, fitter) -> dict[int, dict] | None:
    """Per validation experiment (index), the start of :func:`corrected`'s model that gives the
    verdict's prediction: ``gear``, ``rest``, ``position``, ``ringing``, ``memory`` (each None for the model's
    default; the arguments of :meth:`hwid.model.HWModel.simulate`), and ``exact`` False where the
    prediction used a start no model simulation takes (an actuator run on through the call before
    from where it last crossed the play, fresh and carried actuators from two gear starts). None
    without a deterministic verdict."""
    if not isinstance(verdict, Candidate) or verdict.fitted is None or verdict.fitted.disturbance:
        return None
    preds, seen = _fitter_of(verdict, fitter).noted_predictions(verdict.fitted, verdict.theta)
    share = float(verdict.params.get("carried", 0.0)) if verdict.effect == "rate_limit" else 0.0
    out = {}
    for i, pred in enumerate(preds):
        s = seen.get(i, {"gears": [], "rests": []})
        gears = s["gears"]
        # a rate limit that carries its position over: the carried actuator alone at carried = 1
        gear = gears[-1] if share >= 1.0 and gears else (gears[0] if gears else None)
        exact = not s.get("carried_from_tail")
        if 0.0 < share < 1.0 and len(gears) > 1 and gears[0] != gears[-1]:
            exact = False           # the fresh and the carried actuator start the gear apart
        same = bool(np.array_equal(pred, verdict.predictions[i]))
        out[i] = {"gear": gear, "rest": s["rests"][-1] if s["rests"] else None,
                  "position": s.get("position") if share > 0 else None, "ringing": s.get("ringing"),
                  "memory": s.get("memory"),
                  "exact": bool(exact and same)}
    return out


def plant_dict(model: HWModel) -> dict:
    """``model`` as a plant mapping (the config's ``plant``), floats written exactly."""
    F, G, h = model.input, model.linear, model.output
    plant = {"kind": "hammerstein_wiener",
             "input_nonlinearity": {"type": F.type, "slope_up": float(F.slope_up), "slope_down": float(F.slope_down),
                                    "d_plus": float(F.d_plus), "d_minus": float(F.d_minus)},
             "linear": {"num": [float(c) for c in G.num], "den": [float(c) for c in G.den], "delay": float(G.delay)}}
    if isinstance(h, PolynomialH) and h.coefficients[0] == 0.0:
        plant["output_nonlinearity"] = {"polynomial": [float(c) for c in h.coefficients]}
    elif isinstance(h, PolynomialH):     # h(0) != 0 (re-estimated with an offset): one piece says it as it is
        plant["output_nonlinearity"] = {"pieces": [{"polynomial": [float(c) for c in h.coefficients]}]}
    elif isinstance(h, PiecewiseH):
        ups = [float(b) for b in h.breaks] + [None]
        plant["output_nonlinearity"] = {"pieces": [{"polynomial": [float(c) for c in p], **({"upper": b} if b is not None else {})}
                                                   for p, b in zip(h.pieces, ups)]}
    if model.effects:
        plant["effects"] = [{k: (float(v) if k != "effect" else v) for k, v in e.to_dict().items()}
                            for e in model.effects]
    return plant


def write(out_dir, model: HWModel, comment: str) -> Path:
    """Write ``OUT/corrected.yaml`` (atomic), after checking that it reads back as a plant: the
    comment lines first, then the plant mapping."""
    plant = plant_dict(model)
    path = Path(out_dir) / NAME
    try:
        config.parse_plant(plant, str(path))
    except HwidError as err:
        raise HwidError(f"{path}: the corrected model is not a valid plant ({err})") from None
    head = "".join(f"# {line}\n" for line in comment.splitlines())
    return write_text(path, head + yaml.safe_dump(plant, sort_keys=False, default_flow_style=None))


def comment_for(verdict, added: bool, gap_before: float, gap_after: float, sigma: float) -> str:
    """What the file is, in a comment: the verdict's effect added, or why the model is as it was."""
    if added:
        params = ", ".join(f"{k} = {v:.6g}" for k, v in verdict.params.items())
        return (f"hwid diagnose: the model diagnosed with, plus {verdict.effect} ({verdict.block} block) at its "
                f"fitted parameters ({params}).\nOn the validation experiments: gap {gap_before:.4g} -> "
                f"{gap_after:.4g}, noise floor {sigma:.4g}.")
    name = verdict.effect if isinstance(verdict, Candidate) else str(verdict)
    why = ("a disturbance estimated from the measured output: no model simulates it from its input"
           if name == "drift" else "no effect is added")
    return f"hwid diagnose: verdict {name}: the model as it was diagnosed ({why})."


def write_for(out_dir, verdict, fitter, sim_model: HWModel, summary: dict, echo=print) -> dict[int, dict] | None:
    """:func:`corrected`'s model written to ``OUT/corrected.yaml`` (:func:`write`), or a line
    saying why it cannot be; returns :func:`starts_after` for ``diagnosis.h5``."""
    model, added = corrected(verdict, fitter, sim_model)
    starts = starts_after(verdict, fitter) if added else None
    try:
        path = write(out_dir, model, comment_for(verdict, added, summary["gap_before"], summary["gap_after"],
                                                 summary["noise_floor"]))
    except HwidError as err:
        (Path(out_dir) / NAME).unlink(missing_ok=True)      # never a model of an earlier diagnosis
        echo(f"corrected model not written: {err}")
        return None
    echo(f"corrected model: {path}" + (f" ({verdict.effect} added)" if added else " (the model as it was)"))
    return starts
