"""The schema of ``plant.effects``: catalogue effects a simulated plant (or a model file such as a
diagnosis's ``corrected.yaml``) carries at their blocks of the chain, one pydantic model per effect,
told apart by ``effect``. Names and parameters are the diagnosis's (``hwid diagnose``'s JSON,
``verdict`` and ``candidates``); what each does is :mod:`hwid.blocks.effects`. Part of the schema of
:mod:`hwid.config`, which validates and reports them like every other key.
"""
from __future__ import annotations

from typing import Annotated, Literal, Optional, Union

from pydantic import BaseModel, ConfigDict, Field, model_validator

Finite = Annotated[float, Field(allow_inf_nan=False)]
Pos = Annotated[float, Field(gt=0, allow_inf_nan=False)]
NonNeg = Annotated[float, Field(ge=0, allow_inf_nan=False)]
Share = Annotated[float, Field(ge=0, le=1, allow_inf_nan=False)]

#: ``drift`` is a disturbance estimated from a plant's measured output, not a map of its input.
DRIFT_REFUSED = ("drift is a disturbance the diagnosis estimates from the measured output (a moving average of "
                 "the residual), not a map of the input: a plant cannot carry it; simulate the plant without it "
                 "(or add the drift to the output yourself)")


class _Effect(BaseModel):
    model_config = ConfigDict(extra="forbid", strict=True, frozen=True, allow_inf_nan=False)


def _ordered(lo: float, hi: float, what: str) -> None:
    if not lo < hi:
        raise ValueError(f"{what}: the lower limit ({lo}) must be below the upper ({hi})")


class InputSaturationCfg(_Effect):
    effect: Literal["input_saturation"] = Field(description="The actuator clips u to [u_lo, u_hi] before F.")
    u_lo: Finite = Field(description="input_saturation: lower limit of the actuator, input units.")
    u_hi: Finite = Field(description="input_saturation: upper limit of the actuator (above u_lo).")

    @model_validator(mode="after")
    def _order(self):
        _ordered(self.u_lo, self.u_hi, "input_saturation")
        return self


class RateLimitCfg(_Effect):
    effect: Literal["rate_limit"] = Field(description="The actuator slews at most `rate` input units per second.")
    rate: Pos = Field(description="rate_limit: the largest slew rate, input units/s.")
    carried: Share = Field(
        default=0.0, description="rate_limit: in [0, 1], how far the actuator's position carries over from the call "
                                 "before (0: set where each call begins; 1: where the last left it, given to the "
                                 "simulation as its start position). A simulated plant starts every call afresh.")


class InputDeadzoneCfg(_Effect):
    effect: Literal["input_deadzone"] = Field(
        description="The actuator does not move for |u| < delta, and passes u - delta sign(u) beyond, before F.")
    delta: NonNeg = Field(description="input_deadzone: half-width of the dead zone, input units.")
    absorbed: Share = Field(
        default=0.0, description="input_deadzone: in [0, 1], the share of the dead zone F's borders d+, d- already "
                                 "carry and give back (d+ - absorbed delta, d- + absorbed delta, scaled by the "
                                 "slopes for a Backlash-Inverse); 0 for borders measured without it.")


_BEND = "curved_borders: a Legendre coefficient of the {side} border's bend, degree {j} (give c1..cK on both sides)."


class CurvedBordersCfg(_Effect):
    effect: Literal["curved_borders"] = Field(
        description="Each border of F is its straight line plus k (c0 + c1 P1(s) + ... + cK PK(s)), Legendre "
                    "polynomials of s = (u - u_centre) / u_half_width, k the border's slope times u_half_width.")
    c0: Finite = Field(description="curved_borders: the shift both borders share (in the bend's units).")
    c1_up: Finite = Field(description=_BEND.format(side="ascending", j=1))
    c2_up: Optional[Finite] = Field(default=None, description=_BEND.format(side="ascending", j=2))
    c3_up: Optional[Finite] = Field(default=None, description=_BEND.format(side="ascending", j=3))
    c4_up: Optional[Finite] = Field(default=None, description=_BEND.format(side="ascending", j=4))
    c5_up: Optional[Finite] = Field(default=None, description=_BEND.format(side="ascending", j=5))
    c6_up: Optional[Finite] = Field(default=None, description=_BEND.format(side="ascending", j=6))
    c1_down: Finite = Field(description=_BEND.format(side="descending", j=1))
    c2_down: Optional[Finite] = Field(default=None, description=_BEND.format(side="descending", j=2))
    c3_down: Optional[Finite] = Field(default=None, description=_BEND.format(side="descending", j=3))
    c4_down: Optional[Finite] = Field(default=None, description=_BEND.format(side="descending", j=4))
    c5_down: Optional[Finite] = Field(default=None, description=_BEND.format(side="descending", j=5))
    c6_down: Optional[Finite] = Field(default=None, description=_BEND.format(side="descending", j=6))
    play: Optional[Finite] = Field(
        default=None, description="curved_borders: the borders shifted apart by this much (the play widened, in the "
                                  "bend's units); left out: the play's width as F has it.")
    u_centre: Finite = Field(description="curved_borders: centre of the input range s is scaled to.")
    u_half_width: Pos = Field(description="curved_borders: half-width of the input range s is scaled to.")
    fit_lo: Optional[Finite] = Field(
        default=None, description="curved_borders: below this input the bend goes on along its tangent "
                                  "(left out: the polynomials everywhere).")
    fit_hi: Optional[Finite] = Field(
        default=None, description="curved_borders: above this input the bend goes on along its tangent "
                                  "(left out: the polynomials everywhere).")

    @model_validator(mode="after")
    def _degree(self):
        for side in ("up", "down"):
            given = [getattr(self, f"c{j}_{side}") is not None for j in range(1, 7)]
            k = sum(given)
            if given != [True] * k + [False] * (6 - k):
                raise ValueError(f"curved_borders: give c1_{side} .. cK_{side} without gaps")
        if self.degree_of("up") != self.degree_of("down"):
            raise ValueError("curved_borders: both borders need the same degree (c1..cK on each)")
        if self.fit_lo is not None and self.fit_hi is not None:
            _ordered(self.fit_lo, self.fit_hi, "curved_borders fit_lo, fit_hi")
        return self

    def degree_of(self, side: str) -> int:
        return sum(getattr(self, f"c{j}_{side}") is not None for j in range(1, 7))


class TimeDelayCfg(_Effect):
    effect: Literal["time_delay"] = Field(description="A transport delay added to G.")
    delay_s: NonNeg = Field(description="time_delay: the delay added, s.")


class ResonanceCfg(_Effect):
    effect: Literal["resonance"] = Field(
        description="A mode of G: G(s) omega_n^2 / (s^2 + 2 zeta omega_n s + omega_n^2), unit static gain.")
    omega_n: Pos = Field(description="resonance: the mode's natural frequency, rad/s.")
    zeta: Pos = Field(description="resonance: the mode's damping ratio (> 0).")


class SensorLagCfg(_Effect):
    effect: Literal["sensor_lag"] = Field(description="First-order sensor dynamics 1/(tau_s s + 1) after h.")
    tau_s: Pos = Field(description="sensor_lag: the sensor's time constant, s.")
    absorbed: Share = Field(
        default=0.0, description="sensor_lag: in [0, 1], the share of the lag G already carries and gives back "
                                 "(G times (absorbed tau_s s + 1) where G is strictly proper); 0 for a G measured "
                                 "without it.")


class SensorSaturationCfg(_Effect):
    effect: Literal["sensor_saturation"] = Field(description="The sensor clips y to [y_lo, y_hi].")
    y_lo: Finite = Field(description="sensor_saturation: lower limit of the sensor, output units.")
    y_hi: Finite = Field(description="sensor_saturation: upper limit of the sensor (above y_lo).")

    @model_validator(mode="after")
    def _order(self):
        _ordered(self.y_lo, self.y_hi, "sensor_saturation")
        return self


def _either(value: float, what: str) -> None:
    if value not in (0.0, 1.0):
        raise ValueError(f"{what} is 0 or 1 (got {value})")


class FrictionCfg(_Effect):
    effect: Literal["friction"] = Field(
        description="A Dahl friction force on the gear's output side. fed_back 1: a force on the load, opposing "
                    "its motion: G receives v - coulomb z(w) - viscous dw/dt, z the Dahl state of the path of G's "
                    "output w (the load's position). fed_back 0: the force of the gear's own path: G receives "
                    "v + coulomb z(v) + viscous dv/dt, z the Dahl state of v's path (in [-1, 1]).")
    coulomb: Finite = Field(
        description="friction: the Coulomb level in F's output units (fed_back 1: > 0 opposes the load's motion; "
                    "fed_back 0: > 0 adds to the output in the direction of motion, < 0 holds the load back).")
    pre_sliding: Optional[Pos] = Field(
        default=None, description="friction: the pre-sliding displacement (Dahl's law), in G's output units "
                                  "(fed_back 1) or F's (fed_back 0).")
    sliding_speed: Optional[Pos] = Field(
        default=None, description="friction, fed_back 1 only: the smooth Coulomb law coulomb tanh(dw/dt / "
                                  "sliding_speed) in place of Dahl's, in G's output units per s (give it or "
                                  "pre_sliding).")
    viscous: Finite = Field(default=0.0, description="friction: the viscous term (fed_back 1: F's output units per "
                                                     "unit of G's output velocity, >= 0, opposing the motion; "
                                                     "fed_back 0: s, a zero of G at -1/viscous).")
    stribeck: Optional[Annotated[float, Field(ge=1, allow_inf_nan=False)]] = Field(
        default=None, description="friction, fed_back 1 with pre_sliding only: LuGre's Stribeck level at rest, in "
                                  "Coulomb levels (>= 1; left out: Dahl's law, 1).")
    stribeck_speed: Optional[Pos] = Field(
        default=None, description="friction: the speed over which the Stribeck level falls to the Coulomb level, in "
                                  "G's output units per s (given with stribeck).")
    bristle_damping: Optional[Pos] = Field(
        default=None, description="friction, fed_back 1 with pre_sliding only: LuGre's bristle damping sigma1/sigma0, "
                                  "s: the force coulomb (z + bristle_damping dz/dt) (left out: none).")
    fed_back: Share = Field(default=0.0, description="friction: 1 for the force on the load fed back to G's input, "
                                                     "0 for the force of the gear's own path (the default).")

    @model_validator(mode="after")
    def _form(self):
        _either(self.fed_back, "friction fed_back")
        if (self.pre_sliding is None) == (self.sliding_speed is None):
            raise ValueError("friction: give pre_sliding (Dahl's law) or sliding_speed (the smooth Coulomb law), "
                             "one of them")
        if (self.stribeck is None) != (self.stribeck_speed is None):
            raise ValueError("friction: give stribeck and stribeck_speed together")
        if self.stribeck is not None and (self.fed_back != 1.0 or self.pre_sliding is None):
            raise ValueError("friction: a Stribeck level is LuGre's, of the load's velocity with Dahl's pre-sliding: "
                             "fed_back 1 and pre_sliding only")
        if self.bristle_damping is not None and (self.fed_back != 1.0 or self.pre_sliding is None):
            raise ValueError("friction: bristle damping is LuGre's, of the load's Dahl state: fed_back 1 and "
                             "pre_sliding only")
        if self.sliding_speed is not None and self.fed_back != 1.0:
            raise ValueError("friction: sliding_speed (the smooth Coulomb law) is a law of the load's velocity: "
                             "fed_back 1 only")
        if self.fed_back == 1.0 and self.viscous < 0:
            raise ValueError(f"friction viscous: a viscous force on the load opposes its motion (>= 0, got "
                             f"{self.viscous})")
        return self


class OutputHysteresisCfg(_Effect):
    effect: Literal["output_hysteresis"] = Field(
        description="A rate-independent hysteresis between G's output w and h (after_h 0) or on h's output "
                    "(after_h 1): (1 - weight) x + weight P(x), P a Prandtl-Ishlinskii sum of 4 plays of "
                    "half-widths width/4 .. width, the j-th weighted in proportion to exp(shape (j - 4) / 4).")
    width: NonNeg = Field(description="output_hysteresis: the largest play's half-width, in the units of the "
                                      "signal it acts on (G's output before h, the output after it).")
    weight: Share = Field(default=1.0, description="output_hysteresis: in [0, 1], the share through the plays.")
    shape: Annotated[float, Field(ge=-60, le=60, allow_inf_nan=False)] = Field(
        default=0.0, description="output_hysteresis: the tilt of the plays' weights (0: equal; large: the widest "
                                 "play alone; negative: the narrow plays).")
    after_h: Share = Field(default=0.0, description="output_hysteresis: 1 after h, 0 between G and h (the "
                                                    "default).")

    @model_validator(mode="after")
    def _place(self):
        _either(self.after_h, "output_hysteresis after_h")
        return self


EffectCfg = Annotated[
    Union[InputSaturationCfg, RateLimitCfg, InputDeadzoneCfg, CurvedBordersCfg, TimeDelayCfg, ResonanceCfg,
          SensorLagCfg, SensorSaturationCfg, FrictionCfg, OutputHysteresisCfg],
    Field(discriminator="effect")]


#: each effect's schema by its name (the tag ``effect``)
EFFECT_MODELS = {m.model_fields["effect"].annotation.__args__[0]: m
                 for m in (InputSaturationCfg, RateLimitCfg, InputDeadzoneCfg, CurvedBordersCfg, TimeDelayCfg,
                           ResonanceCfg, SensorLagCfg, SensorSaturationCfg, FrictionCfg, OutputHysteresisCfg)}


def refuse_drift(value):
    """A ``plant.effects`` list with ``drift`` in it is refused in one line (:data:`DRIFT_REFUSED`)."""
    if isinstance(value, list) and any(isinstance(e, dict) and e.get("effect") == "drift" for e in value):
        raise ValueError(DRIFT_REFUSED)
    return value
