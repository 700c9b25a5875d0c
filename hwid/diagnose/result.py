"""The diagnosis's result as plain frozen data; ``to_dict()`` is the fixed JSON of ``hwid diagnose``."""
from __future__ import annotations

from dataclasses import dataclass


@dataclass(frozen=True)
class DiagnosisResult:
    """What ``hwid diagnose`` found (the JSON keys are a fixed interface).

    ``verdict``: ``{"effect", "block", "explained_fraction"}``; ``gap_before``/``gap_after``: RMS gap
    on the validation experiments without and with the verdict's effect; ``noise_floor``: the noise
    RMS from the repeats; ``gap_model_refit``: the gap with h (and F, G) re-estimated; ``where``: per
    experiment, region, frequency, trend and repeatability; ``candidates``: every catalogue effect
    fitted and scored, best first; ``test``, ``noise``, ``model``, ``design``, ``cost``: how the
    verdict was reached and what it cost; ``indistinguishable``: groups of effects that fit the
    validation data equally well within the noise (``verdict.indistinguishable_from`` lists the
    verdict's fellows); ``next_experiment``: for a recorded plant, the input that would separate the
    leading group on the live rig; ``data``: for a recorded plant, how the records were split and
    where the noise floor came from; ``confirmation``: with a given model, whether the verdict makes any
    experiment worse than the model without it (:mod:`hwid.diagnose.confirm`; ``None``: nothing to
    check); ``output_rails``: the ends of the sensor's range the measured output rested on
    (:mod:`hwid.identify.rails`; ``side``, ``value``, ``samples``, ``runs``, ``records``)."""

    verdict: dict
    gap_before: float
    gap_after: float
    noise_floor: float
    gap_model_refit: float
    model_refit: dict | None
    where: dict
    candidates: list
    test: dict
    noise: dict
    model: dict
    design: dict
    cost: dict
    residual_structure: list
    indistinguishable: list = ()
    next_experiment: dict | None = None
    data: dict | None = None
    confirmation: dict | None = None
    output_rails: list = ()

    def to_dict(self) -> dict:
        return {"verdict": self.verdict, "gap_before": self.gap_before, "gap_after": self.gap_after,
                "noise_floor": self.noise_floor, "gap_model_refit": self.gap_model_refit,
                "model_refit": self.model_refit, "where": self.where, "candidates": self.candidates,
                "test": self.test, "noise": self.noise, "model": self.model, "design": self.design,
                "cost": self.cost, "residual_structure": self.residual_structure,
                "indistinguishable": list(self.indistinguishable), "next_experiment": self.next_experiment,
                "confirmation": self.confirmation, "output_rails": list(self.output_rails),
                **({"data": self.data} if self.data is not None else {})}
