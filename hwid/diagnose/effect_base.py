"""What every catalogue effect is (:class:`Effect`) and the sizes its bounds and starting points are
scaled from (:class:`Scale`): the base the catalogue's modules (:mod:`hwid.diagnose.effects`,
:mod:`hwid.diagnose.effects_after_gear`) build on.
"""
from __future__ import annotations

from dataclasses import dataclass, field

import numpy as np

from hwid.blocks.effects import EffectSpec
from hwid.diagnose.modelsim import ModelSim


@dataclass(frozen=True)
class Scale:
    """The sizes every effect's bounds and starting points are scaled from.

    Attributes
    ----------
    dt : float
        Sample time, s.
    u_min, u_max : float
        Range of the plant input over the diagnosis experiments.
    y_min, y_max : float
        Range of the model's output over them.
    v_scale : float
        Largest ``|v|`` (output of F) of the model over them.
    settle_s : float
        Settling time of the model's G (2 % of the step response), s.
    omega_c : float
        Bandwidth of G (-3 dB), rad/s.
    duration_s : float
        Longest experiment, s.
    y_obs_min, y_obs_max : float
        Range of the plant's measured output over the scored samples (NaN: unknown).
    u_fit_min, u_fit_max : float
        Range of the plant input over the fit experiments (NaN: that of every experiment).
    v_min, v_max : float
        Range of F's output ``v`` over every experiment (NaN: ``±v_scale``).
    w_min, w_max : float
        Range of G's output ``w`` over every experiment (NaN: that of the model's output).
    """

    dt: float
    u_min: float
    u_max: float
    y_min: float
    y_max: float
    v_scale: float
    settle_s: float
    omega_c: float
    duration_s: float
    y_obs_min: float = float("nan")
    y_obs_max: float = float("nan")
    u_fit_min: float = float("nan")
    u_fit_max: float = float("nan")
    v_min: float = float("nan")
    v_max: float = float("nan")
    w_min: float = float("nan")
    w_max: float = float("nan")

    @property
    def u_width(self) -> float:
        return max(self.u_max - self.u_min, 1e-12)

    @property
    def y_width(self) -> float:
        return max(self.y_max - self.y_min, 1e-12)

    @property
    def v_width(self) -> float:
        """Range of F's output (``2 v_scale`` when unknown)."""
        w = self.v_max - self.v_min
        return max(w, 1e-12) if np.isfinite(w) else max(2.0 * self.v_scale, 1e-12)

    @property
    def w_width(self) -> float:
        """Range of G's output (the model output's when unknown)."""
        w = self.w_max - self.w_min
        return max(w, 1e-12) if np.isfinite(w) else self.y_width

    @property
    def y_obs_width(self) -> float:
        """Range of the measured output (the model's when unknown)."""
        w = self.y_obs_max - self.y_obs_min
        return max(w, 1e-12) if np.isfinite(w) else self.y_width


@dataclass(frozen=True)
class Effect:
    """One catalogue entry: ``simulate(sim, theta, i)`` gives the model output of experiment ``i``
    with the effect added, ``theta`` in the order of ``params``."""

    name: str
    block: str
    params: tuple[str, ...]
    description: str = ""
    disturbance: bool = False        # needs the measured output (drift)
    # its output moves in sample-sized kinks as a parameter changes (a slew, a clip, a fractional
    # delay): fitted with coarse finite differences first
    kinked = False      # a class attribute, not a field
    # a memoryless change of the input's map (clip, dead zone, bent borders): with an identified
    # model it is confirmed like a verdict with a given one (:func:`hwid.diagnose.confirm.check`)
    static_input = False
    interacts: tuple[str, ...] = field(default=())

    def bounds(self, sc: Scale) -> tuple[np.ndarray, np.ndarray]:
        raise NotImplementedError

    def starts(self, sc: Scale) -> list[np.ndarray]:
        raise NotImplementedError

    def simulate(self, sim: ModelSim, theta, i: int) -> np.ndarray:
        raise NotImplementedError

    def spec(self, theta) -> EffectSpec | None:
        """The effect at ``theta`` as a model carries it (:class:`hwid.blocks.effects.EffectSpec`),
        the parameters named as the diagnosis reports them; None for a disturbance, which no model
        simulates from its input alone."""
        if self.disturbance:
            return None
        extra = self.spec_params() if hasattr(self, "spec_params") else {}
        return EffectSpec(self.name, tuple(zip(self.params, map(float, theta))) + tuple(extra.items()))

    def forms(self, refit_h: bool = False) -> list["Effect"]:
        """The effect's forms, each fitted and the one that fits the fit experiments better kept
        (:meth:`hwid.diagnose.rank.EffectFitter.fit`; a friction on the load or on the gear's
        path, a hysteresis before or after h); ``refit_h``: h is re-estimated with the effect.
        Most effects have one."""
        return [self]

    def form_params(self) -> dict:
        """Which of :meth:`forms` this is, as the model carries it (reported beside the fitted
        parameters, without intervals: a choice, not an estimate); empty for a single form."""
        return {}

    def log_params(self) -> tuple[bool, ...]:
        """Which parameters are fitted on a log scale."""
        return (False,) * len(self.params)

    def grow(self, theta) -> tuple["Effect", np.ndarray] | None:
        """For a family of nested effects (a degree chosen from the data): the next member and
        ``theta`` (this member's fitted parameters) in its parameters; None for a single effect."""
        return None

    def loosen(self, theta) -> tuple["Effect", np.ndarray] | None:
        """For a family with one freedom beyond its degree: the member with it, in the parameters
        of ``theta`` (this member's fit, the new parameter zero); None where there is none or it is
        free already. Tried against a given model only (:meth:`hwid.diagnose.rank.EffectFitter.fit`)."""
        return None

    def other_readings(self, theta) -> list[np.ndarray]:
        """The effect's other readings of the same fit (``theta``) that the fit experiments may not
        tell from it: a choice about the rig, not a parameter that moves smoothly
        (:meth:`hwid.diagnose.rank.EffectFitter.fit`). Empty for most effects."""
        return []

    def stands_in(self, intervals: dict | None) -> str | None:
        """Why the fit, read from its parameters' 95 % intervals (:mod:`hwid.diagnose.intervals`), is
        not this effect but stands in for something else (a clause for the verdict's ``why``); None
        where it may be the effect or there are no intervals. Such a fit is never the verdict."""
        return None

    def at_defining_bound(self, theta) -> bool:
        """Whether the fit pressed against a bound that defines the effect (a "lightly damped"
        mode at the largest damping allowed): it then stands in for something else."""
        return False

    # h re-estimated with the effect: ``y = post(h(pre(...)))``; ``pre`` is the signal entering h
    # (simulated with h = identity), ``post`` the output stage after h (identity by default).
    def pre(self, sim_w: ModelSim, theta, i: int) -> np.ndarray:
        """The signal entering h, ``sim_w`` being the model with h = identity."""
        return self.simulate(sim_w, theta, i)

    post_linear = True

    def post(self, x, theta, dt: float) -> np.ndarray:
        """The output stage on ``x`` along its first axis (where ``post_linear``, h's design matrix
        passes through it whole, each column alike)."""
        return x


def grid(*axes) -> list[np.ndarray]:
    mesh = np.meshgrid(*axes, indexing="ij")
    return [np.array(p, float) for p in zip(*(m.ravel() for m in mesh))]
