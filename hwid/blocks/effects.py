"""The catalogue's effects as parts of a model: each effect's signal map, and the chain of eqs.
(3a-c) with effects added at their blocks (:func:`run_chain_with_effects`).

The diagnosis (:mod:`hwid.diagnose.effects`, :mod:`hwid.diagnose.effects_after_gear`) fits these
maps to a plant; a model that carries them (:class:`hwid.model.HWModel` ``effects``, the config's
``plant.effects``, a diagnosis's ``corrected.yaml``) simulates them. Both run the very same code,
so a corrected model reproduces the diagnosis's own prediction with the effect added.

The chain with effects, each at its block and, within a block, in the order given::

    u -> [input_saturation, rate_limit, input_deadzone] -> F (curved_borders) -> [friction]
      -> G (time_delay, resonance, sensor_lag's absorbed share) -> [output_hysteresis] -> h
      -> [output_hysteresis after h, sensor_lag, sensor_saturation] -> y

A friction on the load (``fed_back`` 1) is not a stage before G but a feedback around it: G is
stepped with the force of its own output's motion (:mod:`hwid.blocks.friction`).

``drift`` is a disturbance estimated from a plant's measured output, not a map of the input: it has
no place here.
"""
from __future__ import annotations

from dataclasses import dataclass, replace

import numpy as np
from numba import njit

from hwid.blocks.deadzone import deadzone
from hwid.blocks.friction import fed_back_response
from hwid.blocks.hysteresis import PLAYS, pi_operator, play_sum  # noqa: F401  (play_sum: the effects' primitives)
from hwid.blocks.linear import LinearBlock
from hwid.blocks.slew import slewed

#: Each simulable effect's block and parameters, in the order the diagnosis fits and reports them
#: (``curved_borders``' bend terms depend on its degree: :func:`curve_params`).
PARAMS = {
    "input_saturation": ("input", ("u_lo", "u_hi")),
    "rate_limit": ("input", ("rate", "carried")),
    "input_deadzone": ("input", ("delta", "absorbed")),
    "curved_borders": ("input", ("c0",)),
    "time_delay": ("linear", ("delay_s",)),
    "resonance": ("linear", ("omega_n", "zeta")),
    "friction": ("linear", ("coulomb", "pre_sliding", "viscous")),     # and its form, FRICTION_FORM
    "sensor_lag": ("output", ("tau_s", "absorbed")),
    "sensor_saturation": ("output", ("y_lo", "y_hi")),
    "output_hysteresis": ("output", ("width", "weight", "shape")),   # and its place, HYSTERESIS_PLACE
}

#: ``friction``'s form beside its fitted parameters: 1 for the force on the load fed back
#: (:func:`hwid.blocks.friction.fed_back_response`), 0 for the force of the gear's own path added
#: to G's input (:func:`friction_drive`); left out, 0
FRICTION_FORM = "fed_back"
#: ``output_hysteresis``'s place beside its fitted parameters: 1 after h, 0 before h (left out, 0)
HYSTERESIS_PLACE = "after_h"
#: the plays of ``output_hysteresis`` (:mod:`hwid.blocks.hysteresis`)
HYSTERESIS_PLAYS = PLAYS


# ------------------------------------------------------------------------------ signal primitives

@njit(cache=True)
def play_arrays(lo, hi, v0):
    """A play between two border arrays: the output stays where it was unless a border pushes it."""
    out = np.empty_like(lo)
    prev = v0
    for k in range(lo.shape[0]):
        if prev < lo[k]:
            prev = lo[k]
        elif prev > hi[k]:
            prev = hi[k]
        out[k] = prev
    return out


@njit(cache=True)
def direction_arrays(z, up, dn, u0):
    """A direction map: ``up[k]`` while ``z`` rises, ``dn[k]`` while it falls, held while it rests."""
    out = np.empty_like(z)
    prev = u0
    for k in range(z.shape[0]):
        if k > 0:
            dz = z[k] - z[k - 1]
            if dz > 0.0:
                prev = up[k]
            elif dz < 0.0:
                prev = dn[k]
        out[k] = prev
    return out


def first_order(x, tau: float, dt: float) -> np.ndarray:
    """``1/(tau s + 1)`` applied to ``x`` (exact for a zero-order-held input), from equilibrium;
    a matrix is filtered column by column (a design matrix whose columns all pass the lag).

    The sampled lag is ``y[k+1] = a y[k] + (1 - a) x[k]``, ``a = exp(-dt/tau)``, ``y[0] = x[0]``."""
    x = np.asarray(x, float)
    if tau <= 0 or x.shape[0] == 0:
        return x
    y = _first_order_rows(np.ascontiguousarray(x.reshape(x.shape[0], -1)), float(np.exp(-dt / float(tau))))
    return y.reshape(x.shape)


@njit(cache=True)
def _first_order_rows(x, a):
    y = np.empty_like(x)
    y[0] = x[0]
    for k in range(1, x.shape[0]):
        y[k] = a * y[k - 1] + (1.0 - a) * x[k - 1]
    return y


@njit(cache=True)
def dahl_state(x, x_pre):
    """The normalised Dahl friction state ``z`` (in [-1, 1]) along the path ``x``.

    Dahl's law with exponent 1, ``dz/dx = (1 - z sgn(dx)) / x_pre``, solved exactly over each
    sample's move: ``z <- s + (z - s) exp(-|dx| / x_pre)``, ``s = sgn(dx)``, so ``z`` depends on the
    path only, never on how fast it was travelled. Starts at ``z = 0``."""
    out = np.empty_like(x)
    z = 0.0
    for k in range(x.shape[0]):
        if k > 0:
            dx = x[k] - x[k - 1]
            if dx > 0.0:
                z = 1.0 + (z - 1.0) * np.exp(-dx / x_pre)
            elif dx < 0.0:
                z = -1.0 + (z + 1.0) * np.exp(dx / x_pre)
        out[k] = z
    return out


# ------------------------------------------------------------------------------ each effect's map

def deadzone_borders(F, delta: float, absorbed: float):
    """F with the share ``absorbed`` of a dead zone of half-width ``delta`` taken back out of its
    borders (``d^+`` shrinks, ``d^-`` grows, by ``delta`` scaled by the slopes for a
    Backlash-Inverse); the borders meet, never cross."""
    kp = 1.0 if F.type == "backlash" else 1.0 / F.slope_up
    km = 1.0 if F.type == "backlash" else 1.0 / F.slope_down
    dp, dm = F.d_plus - absorbed * kp * delta, F.d_minus + absorbed * km * delta
    if dp <= dm:
        dp = dm = 0.5 * (dp + dm)
        dp += 1e-9
    return replace(F, d_plus=dp, d_minus=dm)


def delayed(G: LinearBlock, delay_s: float) -> LinearBlock:
    """G with a transport delay of ``delay_s`` added."""
    return LinearBlock(G.num, G.den, G.delay + max(float(delay_s), 0.0))


def with_mode(G: LinearBlock, omega_n: float, zeta: float) -> LinearBlock:
    """``G(s) wn^2/(s^2 + 2 zeta wn s + wn^2)``: a mode of unit static gain added to G."""
    wn, z = float(omega_n), float(zeta)
    # np.polymul's product without its poly1d objects (6 % of a profiled serial diagnosis)
    den = np.convolve(G.den, [1.0, 2 * z * wn, wn * wn])
    num = np.convolve(G.num, [wn * wn])
    return LinearBlock(tuple(num), tuple(den), G.delay)


def mode_poles(omega_n: float, zeta: float) -> np.ndarray:
    """The poles of :func:`with_mode`'s added mode."""
    wn, z = float(omega_n), float(zeta)
    return np.roots([1.0, 2 * z * wn, wn * wn])


def lag_given_up(G: LinearBlock, tau: float, absorbed: float) -> LinearBlock | None:
    """``G (absorbed tau s + 1)``: the share of a sensor lag a G identified with it has absorbed,
    given back; None where G is biproper (it cannot give up a lag) or nothing is absorbed."""
    if not absorbed > 0:
        return None
    num = np.convolve(G.num, [absorbed * tau, 1.0])
    return LinearBlock(tuple(num), G.den, G.delay) if num.size <= len(G.den) else None


def friction_drive(v, coulomb: float, pre_sliding: float, viscous: float, dt: float) -> np.ndarray:
    """G's input: the gear's output ``v`` with a Dahl friction force added,
    ``v + coulomb z(v) + viscous dv/dt`` (:func:`dahl_state`)."""
    c, xp, b = float(coulomb), float(pre_sliding), float(viscous)
    out = v + c * dahl_state(np.ascontiguousarray(v, dtype=np.float64), max(xp, 1e-300))
    if b != 0.0 and v.size > 1:
        out = out + b * np.diff(v, prepend=v[0]) / dt
    return out


def hysteresis(w, width: float, weight: float, shape: float = 0.0, start: float = 0.0,
               from_sample: int = 0) -> np.ndarray:
    """``(1 - weight) w + weight P(w)``, ``P`` the Prandtl-Ishlinskii sum of :data:`HYSTERESIS_PLAYS`
    plays of largest half-width ``width`` and threshold density tilted by ``shape``
    (:func:`hwid.blocks.hysteresis.pi_operator`), the plays set to ``start`` (in [-1, 1]) at
    ``from_sample``."""
    return pi_operator(w, width, weight, shape, start, from_sample)


def hysteresis_of(spec: "EffectSpec", x, memory: dict | None = None) -> np.ndarray:
    """An ``output_hysteresis`` spec's operator on ``x``, its plays set at ``memory``
    (``{"from_sample", "start"}``; None: centred at the first sample)."""
    m = memory or {}
    return hysteresis(x, spec.get("width"), spec.get("weight", 1.0), spec.get("shape", 0.0),
                      float(m.get("start", 0.0)), int(m.get("from_sample", 0)))


def after_h(spec: "EffectSpec") -> bool:
    """Whether an ``output_hysteresis`` acts after h (:data:`HYSTERESIS_PLACE`)."""
    return spec.effect == "output_hysteresis" and spec.get(HYSTERESIS_PLACE, 0.0) >= 0.5


def fed_back(spec: "EffectSpec") -> bool:
    """Whether a ``friction`` is the force on the load fed back (:data:`FRICTION_FORM`)."""
    return spec.effect == "friction" and spec.get(FRICTION_FORM, 0.0) >= 0.5


def curve_params(degree: int, play: bool = False) -> tuple[str, ...]:
    """``curved_borders``' parameters for a bend of ``degree``: ``c0``, ``c1_up .. cK_up``,
    ``c1_down .. cK_down`` and, with the play's width free, ``play``."""
    k = int(degree)
    return (("c0",) + tuple(f"c{j}_{side}" for side in ("up", "down") for j in range(1, k + 1))
            + (("play",) if play else ()))


def bend_basis(u, degree: int, centre: float, half: float, span=(-np.inf, np.inf)) -> np.ndarray:
    """The bend's basis on the input ``u``: column ``j`` is the Legendre polynomial ``P_j(s)``,
    ``s = (u - centre) / half``, over ``span`` (in ``s``), continued along its tangent beyond it."""
    leg = np.polynomial.legendre
    a, b = span
    k = int(degree)
    s = (np.asarray(u, float) - centre) / half
    B = leg.legvander(np.clip(s, a, b), k)
    for end, beyond in ((a, np.minimum(s - a, 0.0)), (b, np.maximum(s - b, 0.0))):
        if np.isfinite(end):
            slopes = np.array([leg.legval(end, leg.legder(np.eye(k + 1)[j])) for j in range(k + 1)])
            B = B + np.outer(beyond, slopes)
    return B


def curved_output(F, u, B, theta, degree: int, play: bool, half: float, start: float | None = None) -> np.ndarray:
    """F's output with its borders bent: each border its straight line plus
    ``k (c0 + c1 P1(s) + ... + cK PK(s))`` (``B`` from :func:`bend_basis`, ``theta`` in the order
    of :func:`curve_params`, ``k`` the border's slope times ``half``; ``play`` widens the play by
    shifting the borders apart). ``start``: the gear's output before ``u[0]`` (None: 0 clipped into
    the play for a Backlash, the middle of the two branches for a Backlash-Inverse)."""
    th = np.asarray(theta, float)
    k = int(degree)
    wider = th[1 + 2 * k] if play else 0.0
    c_up, c_dn = np.r_[th[0] - wider, th[1:1 + k]], np.r_[th[0] + wider, th[1 + k:1 + 2 * k]]
    if F.type == "backlash":
        up = F.ascending(u) + F.slope_up * half * (B @ c_up)
        dn = F.descending(u) + F.slope_down * half * (B @ c_dn)
        if start is not None:
            v0 = float(start)
        else:
            v0 = float(np.clip(0.0, up[0], dn[0])) if dn[0] >= up[0] else 0.5 * (up[0] + dn[0])
        return play_arrays(np.ascontiguousarray(up), np.ascontiguousarray(np.maximum(dn, up)), v0)
    up = F.ascending(u) + half / F.slope_up * (B @ c_up)
    dn = F.descending(u) + half / F.slope_down * (B @ c_dn)
    v0 = 0.5 * (up[0] + dn[0]) if start is None else float(start)
    return direction_arrays(u, np.ascontiguousarray(up), np.ascontiguousarray(dn), v0)


def free_response(n: int, k0: int, dt: float, poles) -> np.ndarray:
    """The free response of G's modes ``poles`` (each with ``Im >= 0``) from sample ``k0`` on, as
    columns: ``exp(Re t) cos(Im t)`` and, for a complex pole, ``exp(Re t) sin(Im t)``,
    ``t = (k - k0) dt``, zero before ``k0``. Its amplitudes are a mode's state where a record's
    scored part begins (a ringing start, :meth:`hwid.diagnose.modelsim.ModelSim.ringing`)."""
    tau = (np.arange(n) - k0) * dt
    after = tau >= 0.0
    cols = []
    for lam in np.atleast_1d(np.asarray(poles, complex)):
        env = np.where(after, np.exp(lam.real * np.where(after, tau, 0.0)), 0.0)
        cols.append(env * np.cos(lam.imag * tau))
        if lam.imag > 0:
            cols.append(env * np.sin(lam.imag * tau))
    return np.column_stack(cols)


def with_ringing(w, dt: float, ringing: dict | None) -> np.ndarray:
    """``w`` with a ringing start added (``{"from_sample", "poles": [[re, im], ...], "amplitudes"}``,
    :func:`free_response`); ``w`` itself for None."""
    if not ringing:
        return w
    poles = [complex(re, im) for re, im in ringing["poles"]]
    return w + free_response(w.size, int(ringing["from_sample"]), dt, poles) @ np.asarray(ringing["amplitudes"], float)


# ------------------------------------------------------------------------------ an effect in a model

@dataclass(frozen=True)
class EffectSpec:
    """One effect of a model, as plain data: its catalogue name and its parameters by name
    (``curved_borders`` also carries its input scaling: ``u_centre``, ``u_half_width`` and the
    range ``fit_lo``, ``fit_hi`` beyond which its bend goes on along its tangent)."""

    effect: str
    params: tuple[tuple[str, float], ...]

    def __post_init__(self):
        if self.effect not in PARAMS:
            raise ValueError(f"{self.effect!r} is not an effect a model can carry "
                             f"(the simulable effects: {', '.join(PARAMS)})")
        object.__setattr__(self, "params", tuple((str(k), float(v)) for k, v in self.params))

    @classmethod
    def of(cls, effect: str, **params) -> "EffectSpec":
        return cls(effect, tuple(params.items()))

    @property
    def block(self) -> str:
        return PARAMS[self.effect][0]

    def get(self, name: str, default: float | None = None) -> float | None:
        return dict(self.params).get(name, default)

    @property
    def degree(self) -> int:
        """A ``curved_borders`` bend's degree (the highest ``cK_up`` given)."""
        return sum(1 for k, _ in self.params if k.endswith("_up"))

    def theta(self) -> np.ndarray:
        """The parameters in the diagnosis's order (``curved_borders``: :func:`curve_params`)."""
        d = dict(self.params)
        names = (curve_params(self.degree, "play" in d) if self.effect == "curved_borders"
                 else PARAMS[self.effect][1])
        return np.array([d[n] for n in names], float)

    def to_dict(self) -> dict:
        return {"effect": self.effect, **dict(self.params)}


def _input_stage(specs, u, dt: float, position: float | None):
    """The input effects in order on the command ``u``: ``(u_fresh, u_carried, carried)``, the
    second the actuator slewed from ``position`` (a rate limit that carries its position over),
    None where there is none."""
    fresh, carried, share = u, None, 0.0
    for s in specs:
        if s.effect == "input_saturation":
            fresh = np.clip(fresh, s.get("u_lo"), s.get("u_hi"))
            carried = None if carried is None else np.clip(carried, s.get("u_lo"), s.get("u_hi"))
        elif s.effect == "rate_limit":
            share = float(s.get("carried", 0.0))
            if share > 0 and position is not None:
                carried = slewed(fresh, s.get("rate"), dt, start=position)
            fresh = slewed(fresh, s.get("rate"), dt)
        elif s.effect == "input_deadzone":
            fresh = deadzone(fresh, s.get("delta"))
            carried = None if carried is None else deadzone(carried, s.get("delta"))
    return fresh, carried, share


def at_the_gear(F, specs, u, dt: float):
    """What F is and receives on the command ``u``: ``(F, u_F)``, F with a dead zone's absorbed
    share out of its borders, ``u_F`` through the input effects (a rate limit slewing from
    ``u[0]``). Where an initial state is searched (:func:`hwid.compare.initial_state`), the gear's
    band is that of ``u_F``."""
    specs = tuple(specs)
    return effective_blocks(F, LinearBlock((1.0,), (1.0,)), specs)[0], _input_stage(specs, u, dt, None)[0]


def effective_blocks(F, G: LinearBlock, specs):
    """F and G as the effects change them: the dead zone's absorbed share out of F's borders; the
    delay, the mode and the sensor lag's absorbed share in G."""
    for s in specs:
        if s.effect == "input_deadzone" and s.get("absorbed", 0.0):
            F = deadzone_borders(F, s.get("delta"), s.get("absorbed"))
        elif s.effect == "time_delay":
            G = delayed(G, s.get("delay_s"))
        elif s.effect == "resonance":
            G = with_mode(G, s.get("omega_n"), s.get("zeta"))
        elif s.effect == "sensor_lag":
            G = lag_given_up(G, s.get("tau_s"), s.get("absorbed", 0.0)) or G
    return F, G


def _after_input(F, G, h, specs, u, dt, gear, rest, ringing=None, memory=None):
    """``(v, w, x)`` of the chain after the input effects, on the actuator's output ``u`` (G's
    output with a ringing start added, :func:`with_ringing`; a friction on the load or the plays
    of an output hysteresis started from ``memory``, ``{"from_sample", "start"}``, None: their
    defaults)."""
    curve = next((s for s in specs if s.effect == "curved_borders"), None)
    if curve is not None:
        d = dict(curve.params)
        half = d["u_half_width"]
        span = (d.get("fit_lo", -np.inf), d.get("fit_hi", np.inf))
        span = tuple((e - d["u_centre"]) / half if np.isfinite(e) else e for e in span)
        B = bend_basis(u, curve.degree, d["u_centre"], half, span)
        v = curved_output(F, u, B, curve.theta(), curve.degree, "play" in d, half, gear)
    else:
        v = F.apply(u, gear)
    drive = v
    load = None
    for s in specs:
        if fed_back(s):
            load = s
        elif s.effect == "friction":
            drive = friction_drive(drive, s.get("coulomb"), s.get("pre_sliding"), s.get("viscous", 0.0), dt)
    if load is None:
        w = G.simulate(drive, dt, rest)
    else:
        w = fed_back_response(G, drive, dt, load.get("coulomb"), load.get("pre_sliding", 0.0),
                              load.get("viscous", 0.0), rest, load.get("sliding_speed"), load.get("stribeck", 1.0),
                              load.get("stribeck_speed", 1.0), load.get("bristle_damping", 0.0),
                              (memory or {}).get("start", 0.0))
    w = with_ringing(w, dt, ringing)
    return v, w, OutputStage(h, specs, dt, memory)(w)


def run_chain_with_effects(F, G: LinearBlock, h, specs, u, dt: float, gear: float | None = None,
                           rest: float | None = None, position: float | None = None, ringing: dict | None = None,
                           memory: dict | None = None):
    """The chain of eqs. (3a-c) with the effects ``specs`` at their blocks on the command ``u``:
    ``(v, w, x)``, ``v`` F's output (the gear), ``w`` G's output (before an output hysteresis),
    ``x`` the noise-free output. ``gear``, ``rest``: F's and G's starts as in
    :meth:`hwid.model.HWModel.simulate`; ``position``: where a rate limit that carries its position
    over (``carried`` > 0) starts its slew (None: at ``u[0]``, as a fresh call), its output then
    ``x_fresh + carried (x_carried - x_fresh)``; ``memory``: where a friction on the load or an
    output hysteresis starts its state, ``{"from_sample", "start"}`` (the friction's from the
    first sample; None: no friction force, the plays centred)."""
    specs = tuple(specs)
    F, G = effective_blocks(F, G, specs)
    fresh, carried, share = _input_stage(specs, np.ascontiguousarray(u, float), dt, position)
    if carried is not None and share >= 1.0:       # the carried actuator alone
        return _after_input(F, G, h, specs, carried, dt, gear, rest, ringing, memory)
    v, w, x = _after_input(F, G, h, specs, fresh, dt, gear, rest, ringing, memory)
    if carried is not None:
        _, _, xc = _after_input(F, G, h, specs, carried, dt, gear, rest, ringing, memory)
        x = x + share * (xc - x)
    return v, w, x


@dataclass(frozen=True)
class OutputStage:
    """h with the effects between G's output and the sensor's reading: ``w -> [output_hysteresis]
    -> h -> [sensor_lag, sensor_saturation]``, called as h is (on whole records: a sensor lag has
    memory, from equilibrium at the first sample)."""

    h: object
    specs: tuple
    dt: float
    memory: dict | None = None      # where an output hysteresis's plays start (None: centred)

    def __post_init__(self):
        object.__setattr__(self, "specs", tuple(self.specs))

    def __call__(self, w):
        for s in self.specs:
            if s.effect == "output_hysteresis" and not after_h(s):
                w = hysteresis_of(s, w, self.memory)
        x = self.h(w)
        for s in self.specs:
            if after_h(s):
                x = hysteresis_of(s, x, self.memory)
            elif s.effect == "sensor_lag":
                x = first_order(x, s.get("tau_s"), self.dt)
            elif s.effect == "sensor_saturation":
                x = np.clip(x, s.get("y_lo"), s.get("y_hi"))
        return x


def scaled_for_normalisation(spec: EffectSpec, k_v: float, k_w: float) -> EffectSpec:
    """``spec`` in the units of the normalised model (eqs. 4a-c), whose F's output is ``v / k_v``
    and G's ``w / k_w``: a friction's levels (in v's units) and an output hysteresis's width before
    h (in w's) scale; a fed-back friction's pre-sliding is in w's units, its forces oppose the
    motion whatever the signs, its viscous term a force (v's units) per w's velocity; every other effect's
    parameters are in u's, y's or seconds, or in units the normalisation keeps (a bend's, scaled
    by the border's own slope; a hysteresis after h, in y's)."""
    d = dict(spec.params)
    if fed_back(spec):      # forces opposing the motion whatever G's sign
        d["coulomb"] /= abs(k_v)
        for key in ("pre_sliding", "sliding_speed", "stribeck_speed"):
            if key in d:
                d[key] /= abs(k_w)
        d["viscous"] = d.get("viscous", 0.0) * abs(k_w / k_v)
    elif spec.effect == "friction":
        d["coulomb"] /= k_v
        d["pre_sliding"] /= abs(k_v)
    elif spec.effect == "output_hysteresis" and not after_h(spec):
        d["width"] /= abs(k_w)
    return EffectSpec(spec.effect, tuple(d.items()))
