"""The Hammerstein-Wiener model (eqs. 3a-c) and its normalised form (eqs. 4a-c), as plain data.

Normalisation. The triple (F, G, h) is only identifiable up to ``(F/k1, G/k2, h(k1 k2 .))``
(Section 3). hwid reports the unique representative with

* ``G(0) = 1`` (eq. 4b), and
* an ascending branch of unit slope: ``F_bar = F / k`` with ``k = S^a`` for a Backlash (eq. 4a),
  and ``k = 1/S^a`` for a Backlash-Inverse (whose ascending branch ``u/S^a + d^+`` then becomes
  ``u + S^a d^+``), and
* ``h_bar(w) = h(G(0) k w)`` (eq. 4c).

So a normalised Backlash has ``slope_up = 1``, ``slope_down = S^d/S^a`` and unchanged ``d^+, d^-``;
a normalised Backlash-Inverse has ``slope_up = 1``, ``slope_down = S^d/S^a``, ``d^+ -> S^a d^+`` and
``d^- -> S^a d^-``. In both cases the steady-state output is ``h_bar(F_bar[U])`` (eq. 5).
"""
from __future__ import annotations

from dataclasses import asdict, dataclass, replace
from typing import Literal

import numpy as np

from hwid.blocks import backlash as bl
from hwid.blocks.chain import run_chain
from hwid.blocks.effects import EffectSpec, at_the_gear, run_chain_with_effects, scaled_for_normalisation
from hwid.blocks.linear import LinearBlock, discretise, unit_rest
from hwid.blocks.static import PiecewiseH, PolynomialH

#: A gear state below every border: from it, a staircase's first lead-in level puts a Backlash on
#: its ascending border (the lead-ins of :mod:`hwid.protocols` make the state known).
BELOW_BORDERS = -1e300


@dataclass(frozen=True)
class InputNonlinearity:
    """F in {B, B_inv} with its four parameters (Fig. 2 / Fig. 5)."""

    type: Literal["backlash", "backlash_inverse"]
    slope_up: float
    slope_down: float
    d_plus: float
    d_minus: float

    @property
    def scale(self) -> float:
        """k of eq. (4a): ``F_bar = F / k``."""
        return self.slope_up if self.type == "backlash" else 1.0 / self.slope_up

    def normalised(self) -> "InputNonlinearity":
        """``F / k`` (eq. 4a, extended to the Backlash-Inverse as in the module docstring)."""
        r = self.slope_down / self.slope_up
        if self.type == "backlash":
            return InputNonlinearity(self.type, 1.0, r, self.d_plus, self.d_minus)
        return InputNonlinearity(self.type, 1.0, r, self.slope_up * self.d_plus, self.slope_up * self.d_minus)

    def apply(self, u, state: float | None = None) -> np.ndarray:
        """Run the operator on a sampled input (eq. 1 or eq. 2)."""
        f = bl.backlash if self.type == "backlash" else bl.backlash_inverse
        return f(u, self.slope_up, self.slope_down, self.d_plus, self.d_minus, state)

    def steady(self, levels, state: float) -> np.ndarray:
        """Steady-state outputs ``F[U_j]`` along a sequence of constant levels."""
        f = bl.static_play if self.type == "backlash" else bl.static_direction_map
        return f(levels, self.slope_up, self.slope_down, self.d_plus, self.d_minus, state)

    def staircase_steady(self, lead_in, levels) -> np.ndarray:
        """``W_j = F_bar[U_j]`` at each level of a staircase, after its lead-in (eqs. 5, 7a-b, 14a-b):
        on a border, or on the flat path before it; the lead-in starts from :data:`BELOW_BORDERS`
        (Backlash) or 0 (Backlash-Inverse)."""
        lead_in = np.asarray(lead_in, float)
        state = BELOW_BORDERS if self.type == "backlash" else 0.0
        return np.asarray(self.steady(np.concatenate([lead_in, np.asarray(levels, float)]), state),
                          float)[lead_in.size:]

    def ascending(self, u):
        """The ascending border / branch as a function of u."""
        u = np.asarray(u, float)
        if self.type == "backlash":
            return self.slope_up * (u - self.d_plus)
        return u / self.slope_up + self.d_plus

    def descending(self, u):
        u = np.asarray(u, float)
        if self.type == "backlash":
            return self.slope_down * (u - self.d_minus)
        return u / self.slope_down + self.d_minus

    def start_band(self, u) -> tuple[float, float]:
        """The states the operator may start a record ``u`` in: a Backlash's gear between its two
        borders at ``u[0]`` (eq. 1); a Backlash-Inverse's output, which holds whatever it was until
        the input first moves, anywhere its two branches (eq. 2) reach over the record (both rise
        with ``u``, so their ends are at the record's extreme inputs)."""
        u = np.atleast_1d(np.asarray(u, float))
        if self.type == "backlash":
            a, b = float(self.ascending(u[0])), float(self.descending(u[0]))
            return (min(a, b), max(a, b))
        lo, hi = float(u.min()), float(u.max())
        return (float(min(self.ascending(lo), self.descending(lo))),
                float(max(self.ascending(hi), self.descending(hi))))

    def precompensator(self, z, kind: str = "auto") -> np.ndarray:
        """The pre-compensator of Fig. 8 that makes ``F[P[z]] = z`` (Section 5, Lemma 1).

        ``kind='auto'``: the Backlash-Inverse (eq. 2) for a Backlash plant (exact), the border map
        (:func:`hwid.blocks.backlash.border_map`) for a Backlash-Inverse plant (exact but for one
        sample per reversal). ``kind='backlash'`` uses the Backlash of eq. (1) for a
        Backlash-Inverse plant, literally as the paper's Lemma 1 suggests (holds through the gap).
        """
        p = (self.slope_up, self.slope_down, self.d_plus, self.d_minus)
        z = np.asarray(z, float)
        if self.type == "backlash":
            return bl.backlash_inverse(z, *p, u0=z[0] / p[0] + p[2])
        if kind == "backlash":
            return bl.backlash(z, *p, v0=p[0] * (z[0] - p[2]))
        return bl.border_map(z, *p, u0=p[0] * (z[0] - p[2]))

    def to_dict(self) -> dict:
        return asdict(self)


@dataclass(frozen=True)
class Actuator:
    """The actuator ahead of F: the command clipped to ``clip = (lo, hi)``, then slewed at most
    ``rate`` units/s (:func:`hwid.blocks.slew.slewed`), then through a dead zone of half-width
    ``deadzone`` (:func:`hwid.blocks.deadzone.deadzone`); each None (or 0 for the dead zone) where
    the actuator has no such block. Not in the paper's structure (eqs. 3a-c start at F): the whole
    fit (:mod:`hwid.identify.whole`) and stage 1 behind a dead zone
    (:mod:`hwid.identify.deadzone_ahead`) fit them where the records show one, and the model keeps
    them, so the model written is the model that was fitted. ``carried``: the fit carried the slew's
    position over from record to record (a record's start is then given to
    :meth:`HWModel.simulate` as ``position``)."""

    clip: tuple[float, float] | None = None
    rate: float | None = None
    deadzone: float = 0.0
    carried: bool = False

    def __post_init__(self):
        if self.clip is not None:
            lo, hi = (float(c) for c in self.clip)
            if not lo <= hi:
                raise ValueError(f"an actuator's clip needs lo <= hi, not [{lo}, {hi}]")
            object.__setattr__(self, "clip", (lo, hi))
        if self.rate is not None and not float(self.rate) > 0:
            raise ValueError(f"an actuator's slew rate must be positive, not {self.rate}")
        if not float(self.deadzone) >= 0:
            raise ValueError(f"an actuator's dead zone must be >= 0, not {self.deadzone}")

    @property
    def empty(self) -> bool:
        return self.clip is None and self.rate is None and not self.deadzone

    def apply(self, u, dt: float, position: float | None = None) -> np.ndarray:
        """The command ``u`` as F receives it: clipped, slewed from ``position`` (None: ``u[0]``
        after the clip, an actuator a driver sets where the record begins), then the dead zone."""
        from hwid.blocks.deadzone import deadzone
        from hwid.blocks.slew import slewed
        u = np.ascontiguousarray(u, dtype=float)
        if self.clip is not None:
            u = np.clip(u, *self.clip)
        if self.rate is not None:
            u = slewed(u, self.rate, dt, start=position)
        if self.deadzone:
            u = deadzone(u, self.deadzone)
        return u

    def to_dict(self) -> dict:
        return {"clip": None if self.clip is None else list(self.clip), "rate": self.rate,
                "deadzone": float(self.deadzone), "carried": bool(self.carried)}

    def as_effects(self) -> tuple[EffectSpec, ...]:
        """The same actuator as catalogue effects (``input_saturation``, ``rate_limit``,
        ``input_deadzone``, in the actuator's order): how a model file writes it."""
        out = []
        if self.clip is not None:
            out.append(EffectSpec.of("input_saturation", u_lo=self.clip[0], u_hi=self.clip[1]))
        if self.rate is not None:
            out.append(EffectSpec.of("rate_limit", rate=self.rate, carried=1.0 if self.carried else 0.0))
        if self.deadzone:
            out.append(EffectSpec.of("input_deadzone", delta=self.deadzone, absorbed=0.0))
        return tuple(out)

    @classmethod
    def from_dict(cls, d: dict | None) -> "Actuator | None":
        """Inverse of :meth:`to_dict`; None for None or an empty actuator."""
        if not d:
            return None
        clip = d.get("clip")
        clip = None if clip is None or np.size(clip) == 0 else tuple(float(c) for c in np.ravel(clip))
        rate = d.get("rate")
        rate = None if rate is None or not np.isfinite(float(rate)) else float(rate)
        act = cls(clip, rate, float(d.get("deadzone", 0.0) or 0.0), bool(d.get("carried", False)))
        return None if act.empty else act


@dataclass(frozen=True)
class Signals:
    """The chain's signals on one experiment (eqs. 3a-c): ``v = F[u]``, ``w = G * v``, ``x = h(w)``;
    ``gear`` is F's state after the last sample (None if empty); ``y = x + xi`` when
    :meth:`HWModel.simulate` was given a noise generator, else None."""

    v: np.ndarray
    w: np.ndarray
    x: np.ndarray
    gear: float | None
    y: np.ndarray | None = None


@dataclass(frozen=True)
class HWModel:
    """A complete (F, G, h) model; ``normalised()`` gives the representative of eqs. (4a-c).
    ``actuator``: the blocks ahead of F where one was fitted (:class:`Actuator`), else None.
    ``effects``: catalogue effects at their blocks of the chain (:class:`hwid.blocks.effects.EffectSpec`;
    the config's ``plant.effects``, a diagnosis's ``corrected.yaml``), after the actuator."""

    input: InputNonlinearity
    linear: LinearBlock
    output: PolynomialH | PiecewiseH
    actuator: Actuator | None = None
    effects: tuple[EffectSpec, ...] = ()

    def __post_init__(self):
        object.__setattr__(self, "effects", tuple(self.effects))

    def normalised(self) -> "HWModel":
        """The representative of eqs. (4a-c); the actuator acts on the command, ahead of F's scale,
        and is kept as it is; the effects in the normalised units
        (:func:`hwid.blocks.effects.scaled_for_normalisation`)."""
        k = self.input.scale * self.linear.dc_gain
        effects = tuple(scaled_for_normalisation(e, self.input.scale, k) for e in self.effects)
        return HWModel(self.input.normalised(), self.linear.normalised(), self.output.scaled(k), self.actuator,
                       effects)

    def without_actuator(self) -> "HWModel":
        """The model without its actuator (F, G and h alone where it carries no effects)."""
        return replace(self, actuator=None)

    def actuate(self, u, dt: float, position: float | None = None) -> np.ndarray:
        """``u`` as F receives it: through the actuator where the model has one, else as it is."""
        if self.actuator is None:
            return np.ascontiguousarray(u, dtype=float)
        return self.actuator.apply(u, dt, position)

    def simulate(self, u, dt: float, gear: float | None = None, rest: float | None = None,
                 noise_rng: np.random.Generator | None = None, noise_std: float = 0.0,
                 position: float | None = None, ringing: dict | None = None,
                 memory: dict | None = None) -> Signals:
        """The chain of eqs. (3a-c) on a sampled input, behind the actuator where the model has one
        (``u`` through :meth:`Actuator.apply` first, its slew from ``position``): ``v = F[u]`` from the gear state
        ``gear`` (None: the operator's default start at ``u[0]``), ``w`` the exact ZOH response of
        G from rest at the input level ``rest`` (None: the equilibrium of ``v[0]``), ``x = h(w)``.
        With ``noise_rng``, also ``y = x + xi``, xi white with standard deviation ``noise_std``:
        bit-identical to ``x + noise_std * noise_rng.standard_normal(n)``, drawn in the chain's own
        pass where it is fused. Every simulation of a model in hwid runs here.

        With ``effects``, the chain runs them at their blocks
        (:func:`hwid.blocks.effects.run_chain_with_effects`: ``w`` is G's output, ``x`` the output
        through every effect; ``position`` is also where a rate limit that carries its position
        over starts). ``ringing``: a free response of G's modes from a given sample on, added to G's
        output (a record started with a mode still ringing, :func:`hwid.blocks.effects.with_ringing`).
        ``memory``: where a friction on the load or an output hysteresis starts its state
        (``{"from_sample", "start"}``: a record started with the rig's memory held from before;
        None: their defaults).
        """
        if self.effects or ringing:
            return self._with_effects(u, dt, gear, rest, noise_rng, noise_std, position, ringing, memory)
        u = self.actuate(u, dt, position)
        fused = self._fused(u, dt, gear, rest, noise_rng, float(noise_std))
        if fused is not None:
            return fused
        v = self.input.apply(u, gear)
        w = self.linear.simulate(v, dt, rest)
        x = self.output(w)
        y = None if noise_rng is None else x + noise_std * noise_rng.standard_normal(u.size)
        return Signals(v, w, x, float(v[-1]) if v.size else gear, y)

    def at_the_gear(self, u, dt: float) -> tuple[InputNonlinearity, np.ndarray]:
        """F as the model's effects leave it and the input it receives on the command ``u``
        (through the actuator and the input effects, :func:`hwid.blocks.effects.at_the_gear`)."""
        u = self.actuate(u, dt)
        return at_the_gear(self.input, self.effects, u, dt) if self.effects else (self.input, u)

    def _with_effects(self, u, dt, gear, rest, noise_rng, noise_std, position, ringing, memory=None) -> Signals:
        """:meth:`simulate` with the model's effects (the three-pass chain, never the fused one)."""
        u = self.actuate(u, dt, position if self.actuator is not None else None)
        v, w, x = run_chain_with_effects(self.input, self.linear, self.output, self.effects, u, dt, gear, rest,
                                         position, ringing, memory)
        y = None if noise_rng is None else x + noise_std * noise_rng.standard_normal(u.size)
        return Signals(v, w, x, float(v[-1]) if v.size else gear, y)

    def _fused(self, u, dt: float, gear: float | None, rest: float | None, noise_rng: np.random.Generator | None,
               noise_std: float) -> Signals | None:
        """The chain in one pass (:func:`hwid.blocks.chain.run_chain`, bit-identical to the three
        passes) where it applies: no delay, a polynomial h, a G with states; else None."""
        f, g = self.input, self.linear
        if u.size == 0 or g.delay != 0.0 or not isinstance(self.output, PolynomialH):
            return None
        n_states, _, _, Phi, G1, G0, C, D = discretise(tuple(map(float, g.num)), tuple(map(float, g.den)), 0.0,
                                                       float(dt))
        if n_states == 0:
            return None
        p = (f.slope_up, f.slope_down, f.d_plus, f.d_minus)
        if f.type == "backlash":
            start = bl.backlash_start(u, *p) if gear is None else float(gear)
            v0 = min(max(start, p[0] * (u[0] - p[2])), p[1] * (u[0] - p[3]))
            args = (False, p[0], p[2], p[1], p[3], start)
        else:
            start = bl.backlash_inverse_start(u, *p) if gear is None else float(gear)
            v0 = start
            args = (True, 1.0 / p[0], p[2], 1.0 / p[1], p[3], start)
        level = v0 if rest is None else float(rest)
        x0 = unit_rest(tuple(map(float, g.num)), tuple(map(float, g.den))) * level
        coef = np.ascontiguousarray(self.output.coefficients, dtype=float)
        # one allocation for the signals: at 10^6 samples malloc hands the block of the last
        # experiment back whole, where four 8 MB arrays go back to the system and fault in anew
        sig = np.empty((3 if noise_rng is None else 4, u.size))
        v, w, x = sig[0], sig[1], sig[2]
        y = sig[3] if noise_rng is not None else np.empty(0)
        run_chain(u, *args, Phi, G1, G0, C, D, x0, coef, noise_rng, noise_std, v, w, x, y)
        return Signals(v, w, x, float(v[-1]), None if noise_rng is None else y)

    def staircase_steady(self, lead_in, levels) -> np.ndarray:
        """``X_j = h(G(0) F[U_j])`` at each level of a staircase after its lead-in (eqs. 5, 8a-b)."""
        return self.output(self.linear.dc_gain * self.input.staircase_steady(lead_in, levels))

    def steady_output(self, levels, state: float) -> np.ndarray:
        """``X_j = h(G(0) F[U_j])`` for a level sequence (eqs. 5, 8)."""
        return self.output(self.linear.dc_gain * self.input.steady(levels, state))

    def to_dict(self) -> dict:
        d = {"input_nonlinearity": self.input.to_dict(),
             "linear": {"num": list(self.linear.num), "den": list(self.linear.den), "delay": self.linear.delay},
             "output_nonlinearity": self.output.to_dict()}
        if self.actuator is not None:
            d["actuator"] = self.actuator.to_dict()
        if self.effects:
            d["effects"] = [e.to_dict() for e in self.effects]
        return d


def from_config(plant_cfg) -> HWModel:
    """The plant's (un-normalised) model from ``cfg.plant`` (a hammerstein_wiener plant)."""
    f = plant_cfg.input_nonlinearity
    lin = plant_cfg.linear
    on = plant_cfg.output_nonlinearity
    if on.polynomial is not None:
        h = PolynomialH(tuple(float(c) for c in on.polynomial))
    else:
        h = PiecewiseH(tuple(float(p.upper) for p in on.pieces[:-1]),
                       tuple(tuple(float(c) for c in p.polynomial) for p in on.pieces))
    num = np.trim_zeros(np.asarray(lin.num, float), "f")
    den = np.trim_zeros(np.asarray(lin.den, float), "f")
    effects = tuple(EffectSpec(e.effect, tuple((k, v) for k, v in e.model_dump().items()
                                               if k != "effect" and v is not None))
                    for e in (getattr(plant_cfg, "effects", None) or ()))
    return HWModel(InputNonlinearity(f.type, f.slope_up, f.slope_down, f.d_plus, f.d_minus),
                   LinearBlock(tuple(num.tolist()), tuple(den.tolist()), float(lin.delay)), h, None, effects)
