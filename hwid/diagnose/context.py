"""What the diagnosis's last steps share, below both the live and the log diagnosis: the experiments
as run and the model simulated on them (:class:`Validation`), the sizes the effects are scaled from
(:func:`scale_of`), whether a drift is additive (:func:`drift_additivity`), and everything
:func:`hwid.diagnose.conclude.conclude` works from (:class:`Context`).
"""
from __future__ import annotations

from dataclasses import dataclass
from functools import cached_property
from pathlib import Path
from typing import Callable

import numpy as np

from hwid.diagnose import experiments, gap, residual_structure
from hwid.diagnose.effects import Scale
from hwid.diagnose.modelsim import ModelSim


@dataclass
class Validation:
    """The diagnosis's experiments as run on the plant, and the model simulated on them."""

    design: experiments.Design
    exps: list
    records: list
    fit_idx: list
    val_idx: list
    sim_fit: ModelSim
    sim_val: ModelSim
    scale: Scale
    rig_seconds: float
    seconds_rig: float

    @property
    def y_val(self) -> list:
        return [self.records[i].y for i in self.val_idx]

    @property
    def m_val(self) -> list:
        return [self.exps[i].mask for i in self.val_idx]

    @cached_property
    def remainder(self) -> list[dict]:
        """What the model's validation residual looks like, from the tests on it
        (:mod:`hwid.diagnose.residual_structure`); computed once, asked by the drift from a log's
        residual, the generalisation veto and the result."""
        return self.remainder_of(self.sim_val.x)

    def remainder_of(self, predictions, F=None) -> list[dict]:
        """The tests on the validation residual left by ``predictions`` (a candidate's outputs).
        With ``F`` (the model's input block), a record whose start was estimated from its opening
        (:func:`hwid.diagnose.logs.with_starts`, fitted without the effect) is tested only from where
        its start no longer matters: the input has spanned the play and G has settled 1.5 times."""
        masks = [self.exps[i].mask for i in self.val_idx]
        if F is not None:
            from hwid.diagnose.logs import known_from
            burn = max(int(round(1.5 * self.design.settle_s / self.design.dt)), 1)
            for j, i in enumerate(self.val_idx):
                pre = int(self.records[i].attrs.get("pre", 0)) if hasattr(self.records[i], "attrs") else 0
                if pre:
                    masks[j] = masks[j].copy()
                    masks[j][:pre + known_from(self.exps[i].u[pre:], F, burn)] = False
        segments = [residual_structure.Segment(self.exps[i].u, y, x, self.design.dt, m,
                                               self.exps[i].variable.get("omega"))
                    for i, y, x, m in zip(self.val_idx, self.y_val, predictions, masks)]
        return residual_structure.residual_structure(segments)

    @property
    def x_model(self) -> list:
        """The model's output on every experiment, in the experiments' order."""
        xs = dict(zip(self.fit_idx, self.sim_fit.x)) | dict(zip(self.val_idx, self.sim_val.x))
        return [xs[i] for i in range(len(self.exps))]


def drift_additivity(pairs, design, sigma: float) -> dict:
    """Whether what changes between repeats is an additive drift (:func:`hwid.diagnose.gap.drift_is_additive`,
    each pair against its own mean output); without repeats nothing tells it from a wandering gain:
    the shares are unknown (NaN) and a drift is not ruled out."""
    if not pairs:
        return {"output_share": float("nan"), "fast_share": float("nan"), "additive": True}
    return gap.drift_is_additive(pairs, [0.5 * (np.asarray(a, float) + np.asarray(b, float)) for a, b, _ in pairs],
                                 max(int(round(design.settle_s / (2 * design.dt))), 5), sigma)


def scale_of(design, exps, sim_fit, sim_val, records) -> Scale:
    """The sizes the effects' bounds and starts are scaled from: input, model output, gear and G ranges,
    the settling time and bandwidth, the longest experiment, the measured output's range."""
    us = np.concatenate([e.u for e in exps])
    uf = np.concatenate(list(sim_fit.inputs))
    xs = np.concatenate(list(sim_fit.x) + list(sim_val.x))
    vs = np.concatenate(list(sim_fit.v) + list(sim_val.v))
    ws = np.concatenate(list(sim_fit.w) + list(sim_val.w))
    ys = np.concatenate([np.asarray(r.y, float)[e.mask] for e, r in zip(exps, records)]) if records else xs
    return Scale(design.dt, float(us.min()), float(us.max()), float(xs.min()), float(xs.max()),
                 float(np.max(np.abs(vs))), design.settle_s, design.omega_c, float(max(e.n for e in exps) * design.dt),
                 float(ys.min()), float(ys.max()), float(uf.min()), float(uf.max()),
                 float(vs.min()), float(vs.max()), float(ws.min()), float(ws.max()))


def sine_band(cfg):
    """``(omega_min, omega_max)`` of the sines that identified G (stage 2), rad/s."""
    sine = cfg.protocols.sine
    if sine is None or not sine.frequencies:
        return None
    return float(min(sine.frequencies)), float(max(sine.frequencies))


@dataclass
class Context:
    """Everything the gap test, the effects and the verdict work from (:func:`hwid.diagnose.conclude.conclude`).

    ``floor``: the noise floor (:class:`hwid.diagnose.gap.NoiseFloor`); ``additive``: what
    :func:`drift_additivity` found; ``origin``: where the model came from (``source``, and for an
    identified model its ``records`` and ``starts``); ``cost``: the rig's and the clock's costs so
    far; ``band``: the frequencies that identified G (default the config's sine band);
    ``from_logs``: the experiments are a log's parts; ``extra(fitter, cands, verdict, groups,
    summary)``: what a caller adds to the summary; ``wander(outputs)``: how far a log's holds wander
    from a model's outputs; ``rerun(index, times)``: the live plant's records of a validation
    experiment run again; ``model_adequacy``: the model on its own records
    (:class:`hwid.adequacy.Adequacy`), or None where nothing was assessed; ``adequacy_on``: which
    records those were, in words; ``floor_from_model``: the floor came from the model's own
    residual (its high-frequency part), not from repeats or holds of the data."""

    cfg: object
    out: Path
    json_path: object
    val: Validation
    floor: gap.NoiseFloor
    additive: dict
    sim_model: object
    origin: dict
    effects: object
    cost: dict
    t_start: float
    echo: Callable
    extra: Callable | None = None
    band: object = None
    from_logs: bool = False
    wander: Callable | None = None
    rerun: Callable | None = None
    model_adequacy: object = None
    adequacy_on: str = ""
    floor_from_model: bool = False

    @property
    def identified(self) -> bool:
        return self.origin.get("source") == "identified"
