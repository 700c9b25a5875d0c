"""The catalogue's effects after the gear: ``friction`` on the gear's output side, where the load is,
and ``output_hysteresis`` between G's output and the sensor (issue 48).

Each comes in forms the fit chooses between on the fit experiments (:meth:`Effect.forms`, the
lowest criterion kept): friction as a force on the load fed back to G's input, with Dahl's law
(:class:`Friction`, grown to LuGre's terms where they pay, :class:`LuGreFriction`) or the smooth
Coulomb law (:class:`SmoothFriction`), or as the force of the gear's own path
(:class:`GearFriction`); the hysteresis before h or after it (:class:`OutputHysteresisAfterH`).
Where a rig's memory of the path before a record still shows, its start is a nuisance parameter
like the gear's (:meth:`hwid.diagnose.modelsim.ModelSim.memory_start`).

Both are rate-independent memories of the path a signal took, the kind of unmodelled effect real
geared drives, friction dampers and servos carry most often, and neither is in the paper's class:
F's play is before G, a static h has no memory. Each is an :class:`hwid.diagnose.effect_base.Effect`
like the other nine, its bounds and starting points scaled from the experiments and the model
(:class:`hwid.diagnose.effect_base.Scale`), never from a particular plant.
"""
from __future__ import annotations

from functools import lru_cache

import numpy as np

from hwid.blocks.effects import (FRICTION_FORM, HYSTERESIS_PLACE, HYSTERESIS_PLAYS, dahl_state,  # noqa: F401
                                 friction_drive, hysteresis, play_sum)
from hwid.blocks.friction import fed_back_response
from hwid.blocks.hysteresis import start_shows
from hwid.blocks.linear import LinearBlock
from hwid.diagnose.experiments import settling_time
from hwid.diagnose.effect_base import Effect, Scale, grid


#: how far an identified model's refit may scale each of G's coefficients with an effect after the
#: gear (:meth:`hwid.diagnose.rank.EffectFitter._g_bounds`; the other effects: 5). Friction fed back
#: to G's input is a spring of stiffness ``coulomb / pre_sliding`` in G's loop while the load is
#: pre-sliding, and a play or loop after G lags its output by an amplitude's share: stage 2 then
#: identifies the loop, not G, and the plant's G may lie further than five times off in a
#: coefficient (a judged two-mass rig with Dahl friction: its identified G carried two zeros and a
#: slow pole the plant has not; within 5 its friction left 5.8 times the noise floor, within 50 1.3).
#: The refit's effect-free part is checked as any candidate's (:meth:`EffectFitter.best_effect_free`):
#: what G's freedom alone removes is credited to no effect.
G_FACTOR_AFTER_GEAR = 50.0


class _FrictionLaw(Effect):
    """What every friction form shares: the Coulomb level is what makes the fit a friction."""

    g_factor = G_FACTOR_AFTER_GEAR      # a class attribute, not a field

    def log_params(self):
        return (False, True, False)

    def stands_in(self, intervals: dict | None) -> str | None:
        """A friction is its Coulomb level: none told from zero, and the fit is a rate dependence."""
        if not intervals or "coulomb" not in intervals:
            return None
        iv = intervals["coulomb"]
        if iv is None:
            return ("its Coulomb level is undetermined: what it fits is a rate dependence (its viscous term), "
                    "not friction")
        if iv[0] <= 0.0 <= iv[1]:
            return (f"its Coulomb level's 95 % interval [{iv[0]:.3g}, {iv[1]:.3g}] holds zero: what it fits is a "
                    "rate dependence (its viscous term), not friction")
        return None


class Friction(_FrictionLaw):
    """A friction force on the load, opposing the load's motion and fed back to G's input: G receives
    ``v - coulomb z(w) - viscous dw/dt``, ``w`` G's output (the load's position), ``z`` the Dahl
    state of its path (:mod:`hwid.blocks.friction`, which gives the law and its references).

    Placement. In a geared drive the gear pushes the load and the load's dynamics are G: the
    friction acts where the load moves, so it depends on G's output and acts on G's input (in
    the gear's units: the force over the drive's stiffness). A law driven by the gear's own
    output (:class:`GearFriction`) never sees the load lag behind the gear or stop short of it,
    which is what a friction between the load and the frame does. ``coulomb > 0`` opposes the
    motion whatever G's sign (its interval decides whether a friction is there at all: one
    below zero drives the load along, no friction, :meth:`stands_in`), ``viscous >= 0`` likewise.

    The catalogue's ``friction`` is this form, :class:`SmoothFriction` and :class:`GearFriction`:
    each is fitted and the one of the lowest criterion on the fit experiments is kept
    (:meth:`forms`). A force read at the driven shaft of a displacement-driven damper is the
    gear's form (the damper's motion is imposed, the force adds to the reading): the real
    damper's log keeps it (Coulomb 3.15 [1.66, 4.65], as before the load's forms existed)."""

    def __init__(self):
        super().__init__("friction", "linear", ("coulomb", "pre_sliding", "viscous"),
                         "a Dahl friction force (Coulomb, pre-sliding, viscous) on the load, opposing its motion, "
                         "fed back to G's input")

    #: the largest Coulomb level, in multiples of the gear output's range: a force beyond it would
    #: hold the load still against any move the experiments make
    COULOMB_RANGES = 1.0
    #: the largest viscous force, in multiples of the gear output's range at G's output moving
    #: across its range in one time constant of G's bandwidth
    VISCOUS_RANGES = 5.0

    def forms(self, refit_h: bool = False) -> list[Effect]:
        """This form, the smooth Coulomb law's (:class:`SmoothFriction`) and the gear's
        (:class:`GearFriction`)."""
        return [self, SmoothFriction(), GearFriction()]

    def form_params(self) -> dict:
        return {FRICTION_FORM: 1.0}

    def stands_in(self, intervals: dict | None) -> str | None:
        """:class:`_FrictionLaw`'s rule, and a Coulomb level below zero (a force along the load's
        motion) is no friction either."""
        iv = (intervals or {}).get("coulomb")
        if iv is not None and iv[1] < 0.0:
            return (f"its Coulomb level's 95 % interval [{iv[0]:.3g}, {iv[1]:.3g}] is below zero: a force that "
                    "drives the load along its motion is not friction")
        return super().stands_in(intervals)

    spec_params = form_params

    def bounds(self, sc: Scale):
        """The Coulomb level up to :attr:`COULOMB_RANGES` times the gear output's range either way
        (the sign free: a fit that aids the motion is no friction, and its interval says so); the
        pre-sliding displacement from 1e-4 of G's output range (a Coulomb step within a sample of
        travel) to half of it; the viscous term up to :attr:`VISCOUS_RANGES` times the force that
        moving across G's output range at G's bandwidth takes."""
        V, W = sc.v_width, sc.w_width
        wc = sc.omega_c if np.isfinite(sc.omega_c) and sc.omega_c > 0 else 1.0 / max(sc.settle_s, sc.dt)
        object.__setattr__(self, "_stribeck_start", 0.1 * W * wc)
        object.__setattr__(self, "_damping_start", sc.dt)
        object.__setattr__(self, "_lugre_from", self.LUGRE_FROM * V)
        c = self.COULOMB_RANGES * V
        return np.array([-c, 1e-4 * W, 0.0]), np.array([c, 0.5 * W, self.VISCOUS_RANGES * V / (W * wc)])

    def starts(self, sc: Scale):
        lo, hi = self.bounds(sc)
        V = sc.v_width
        return grid([f * V for f in (-0.03, 0.01, 0.03, 0.1, 0.3)],
                    np.geomspace(1e-3 * sc.w_width, 0.1 * sc.w_width, 3), [0.0])

    def grow(self, theta):
        """LuGre's Stribeck level (:class:`LuGreFriction`) from this fit, started at 1.4 Coulomb
        levels below a tenth of the speed of G's output crossing its range at G's bandwidth (noted
        by :meth:`bounds`, which every fit calls first). None for a Coulomb level below
        :attr:`LUGRE_FROM` of the gear output's range, or below zero (a force along the motion is
        no friction, :meth:`stands_in`, and has no Stribeck level): LuGre's terms are shares of it."""
        if float(theta[0]) < self._lugre_from:
            return None
        return LuGreFriction(True, False), np.r_[np.asarray(theta, float)[:3], 1.4, self._stribeck_start]

    def loosen(self, theta):
        """LuGre's bristle damping (:class:`LuGreFriction`) from this fit, started at one sample
        (None as for :meth:`grow`)."""
        if float(theta[0]) < self._lugre_from:
            return None
        return LuGreFriction(False, True), np.r_[np.asarray(theta, float)[:3], self._damping_start]

    #: LuGre's terms are tried only from a Coulomb level of at least this share of the gear output's
    #: range: they are shares of that level, and on a plain dev rig (seed 11 none c03, thermal) a
    #: Stribeck fit from a Coulomb level of 1e-3 took 40 s of a 48 s diagnosis for nothing (the
    #: generator's frictions are 2-8 % of the range)
    LUGRE_FROM = 0.005
    _lugre_from = 0.0

    #: set by :meth:`bounds`: where a growth starts the Stribeck speed (a tenth of G's output
    #: crossing its range at G's bandwidth) and the bristle damping (one sample)
    _stribeck_start = 1.0
    _damping_start = 1.0

    #: a friction state's start is forgotten once the load has travelled this many pre-sliding
    #: displacements (two starts' states then differ by e^-10 of the Coulomb level)
    FORGOTTEN = 10.0

    def on_load(self, sim, i, coulomb, pre_sliding, viscous, **law) -> np.ndarray:
        """The model's output with the force on the load (:func:`fed_back_response`), the friction
        state at the start from the data where the load has not travelled :attr:`FORGOTTEN`
        pre-sliding displacements by the first scored sample (:meth:`ModelSim.memory_start`; a rig
        left at rest after a move keeps its load held off equilibrium)."""
        G, v, dt = sim.model.linear, sim.v[i], sim.dt
        w = fed_back_response(G, v, dt, coulomb, pre_sliding, viscous, **law)
        if "sliding_speed" in law or coulomb == 0.0:     # the smooth law has no state
            return sim.model.output(w)
        fs = max(float(law.get("stribeck", 1.0)), 1.0)
        def restart(first):
            return 0 if float(np.sum(np.abs(np.diff(w[:first + 1])))) < self.FORGOTTEN * pre_sliding * fs else None

        reach = 2.0 * abs(coulomb) * fs * peak_gain(G)
        mem = sim.memory_start(i, lambda z, k: fed_back_response(G, v, dt, coulomb, pre_sliding, viscous, memory=z,
                                                                 **law), -fs, fs, restart, reach=reach, base=w)
        if mem is not None:
            w = fed_back_response(G, v, dt, coulomb, pre_sliding, viscous, memory=mem["start"], **law)
        return sim.model.output(w)

    def simulate(self, sim, theta, i):
        c, xp, b = (float(t) for t in theta[:3])
        return self.on_load(sim, i, c, xp, b)


class SmoothFriction(Friction):
    """``friction`` on the load with the smooth Coulomb law: G receives
    ``v - coulomb tanh(dw/dt / sliding_speed) - viscous dw/dt`` (:mod:`hwid.blocks.friction` says
    where it differs from Dahl's: no force holds a load at rest)."""

    def __init__(self):
        _FrictionLaw.__init__(self, "friction", "linear", ("coulomb", "sliding_speed", "viscous"),
                              "a smooth Coulomb friction force (tanh of the load's velocity) and a viscous one on "
                              "the load, opposing its motion, fed back to G's input")

    def forms(self, refit_h: bool = False) -> list[Effect]:
        return [self]

    def grow(self, theta):
        return None

    def loosen(self, theta):
        return None

    @staticmethod
    def _speed(sc: Scale) -> float:
        """G's output crossing its range in one time constant of G's bandwidth, per s."""
        wc = sc.omega_c if np.isfinite(sc.omega_c) and sc.omega_c > 0 else 1.0 / max(sc.settle_s, sc.dt)
        return sc.w_width * wc

    def bounds(self, sc: Scale):
        """As :class:`Friction`'s, the sliding speed (where the force reaches 76 % of its Coulomb
        level) from 1e-4 to twice the speed of G's output crossing its range at G's bandwidth."""
        lo, hi = super().bounds(sc)
        V = self._speed(sc)
        return np.array([lo[0], 1e-4 * V, lo[2]]), np.array([hi[0], 2.0 * V, hi[2]])

    def starts(self, sc: Scale):
        return grid([f * sc.v_width for f in (-0.03, 0.01, 0.03, 0.1, 0.3)],
                    np.geomspace(1e-3, 0.3, 3) * self._speed(sc), [0.0])

    def simulate(self, sim, theta, i):
        c, speed, b = (float(t) for t in theta)
        return self.on_load(sim, i, c, 0.0, b, sliding_speed=speed)


class LuGreFriction(Friction):
    """``friction`` on the load with LuGre's terms beside Dahl's (:mod:`hwid.blocks.friction`): a
    Stribeck level (``stribeck`` Coulomb levels at rest, falling to the Coulomb level over
    ``stribeck_speed``) and/or the bristle damping ``bristle_damping``. Reached only by growing a
    Dahl fit (:meth:`Friction.grow`: the Stribeck pair; :meth:`Friction.loosen`: the damping) where
    the fit experiments' criterion pays for the parameters."""

    #: the largest Stribeck level, in Coulomb levels (measured ones reach 1.2-2)
    STRIBECK_MAX = 3.0

    def __init__(self, stribeck: bool, damping: bool):
        extra = (("stribeck", "stribeck_speed") if stribeck else ()) + (("bristle_damping",) if damping else ())
        terms = ", ".join((["Stribeck"] if stribeck else []) + (["bristle damping"] if damping else []))
        _FrictionLaw.__init__(self, "friction", "linear", ("coulomb", "pre_sliding", "viscous") + extra,
                              f"a LuGre friction force (Coulomb, pre-sliding, viscous, {terms}) on the load, "
                              "opposing its motion, fed back to G's input")
        object.__setattr__(self, "stribeck", stribeck)
        object.__setattr__(self, "damping", damping)

    def forms(self, refit_h: bool = False) -> list[Effect]:
        return [self]

    def grow(self, theta):
        """Both LuGre terms, from a fit with one of them."""
        if self.stribeck and self.damping:
            return None
        th = np.asarray(theta, float)
        if self.stribeck:
            return LuGreFriction(True, True), np.r_[th, self._damping_start]
        return LuGreFriction(True, True), np.r_[th[:3], 1.4, self._stribeck_start, th[3]]

    def loosen(self, theta):
        return None

    def log_params(self):
        return (False, True, False) + ((False, True) if self.stribeck else ()) + ((True,) if self.damping else ())

    def bounds(self, sc: Scale):
        """:class:`Friction`'s; the Stribeck level in [1, :attr:`STRIBECK_MAX`] Coulomb levels, its
        speed from 1e-4 to twice the speed of G's output crossing its range at G's bandwidth; the
        bristle damping from a thousandth of a sample to G's settling time."""
        lo, hi = super().bounds(sc)
        V = SmoothFriction._speed(sc)
        if self.stribeck:
            lo, hi = np.r_[lo, 1.0, 1e-4 * V], np.r_[hi, self.STRIBECK_MAX, 2.0 * V]
        if self.damping:
            lo, hi = np.r_[lo, 1e-3 * sc.dt], np.r_[hi, max(sc.settle_s, sc.dt)]
        return lo, hi

    def starts(self, sc: Scale):
        extra = (([1.4, 0.1 * SmoothFriction._speed(sc)] if self.stribeck else [])
                 + ([sc.dt] if self.damping else []))
        return [np.r_[s, extra] for s in super().starts(sc)]

    def simulate(self, sim, theta, i):
        th = [float(t) for t in theta]
        c, xp, b = th[:3]
        fs, vs = (th[3], th[4]) if self.stribeck else (1.0, 1.0)
        d = th[-1] if self.damping else 0.0
        return self.on_load(sim, i, c, xp, b, stribeck=fs, stribeck_speed=vs, bristle_damping=d)


class GearFriction(_FrictionLaw):
    """The gear's form of ``friction``: G receives ``v + coulomb z(v) + viscous dv/dt``, ``z`` the Dahl
    state of the gear's output path (:func:`dahl_state`), ``pre_sliding`` its pre-sliding
    displacement.

    Where the drive is stiff enough that the load moves with the gear (a displacement-driven
    damper), the friction depends on the gear's path and adds to what is read at the driven shaft
    (``coulomb > 0``: in the direction of motion), or holds a load behind a compliant drive back
    (``< 0``: the loop then looks like a smooth extra play). ``viscous`` is then a zero of G at
    ``-1/viscous``: a rate dependence, linear; what makes the fit a friction is its Coulomb level
    (:meth:`stands_in`)."""

    def __init__(self):
        super().__init__("friction", "linear", ("coulomb", "pre_sliding", "viscous"),
                         "a Dahl friction force (Coulomb, pre-sliding, viscous) of the gear's output path, "
                         "acting on G's input")

    #: the largest Coulomb level, in multiples of the gear output's range (:meth:`bounds`)
    COULOMB_RANGES = 10.0
    #: no force fed back from the load: G's loop is the plant's, and the refit's G keeps the other
    #: effects' bounds (a sharp Coulomb step of the gear's path is a jump at every reversal of F's
    #: output, which a Backlash-Inverse F makes too: more freedom in G only lets it stand in better)
    g_factor = None

    def form_params(self) -> dict:
        return {FRICTION_FORM: 0.0}

    spec_params = form_params

    def bounds(self, sc: Scale):
        """The Coulomb level up to :attr:`COULOMB_RANGES` times the gear output's range either way;
        the pre-sliding displacement from 1e-4 of that range (a Coulomb step within a sample of
        travel) to half of it; the viscous term up to the displacement's own at G's bandwidth.

        In ``v``'s units the Coulomb level is the friction force over the drive's elastic stiffness
        ``k``. Where the output is a position, more than the range would keep the load from moving
        at all; where it is a force read at the driven shaft, the force may be nearly all friction
        (a friction damper: ``k`` small), and the level then exceeds the range by as much as the
        friction force exceeds the elastic one (h re-estimated takes the scale back). A banded
        friction damper's log pressed a bound of half the range (its Coulomb level there 1.01, the
        range 2.0) and was fitted at 3.2 within ten."""
        W = sc.v_width
        b = 1.0 / sc.omega_c if np.isfinite(sc.omega_c) and sc.omega_c > 0 else sc.settle_s
        c = self.COULOMB_RANGES * W
        return np.array([-c, 1e-4 * W, -b]), np.array([c, 0.5 * W, b])

    def starts(self, sc: Scale):
        lo, hi = self.bounds(sc)
        W = sc.v_width
        return grid([f * W for f in (-4.0, -1.0, -0.2, -0.05, -0.01, 0.01, 0.05, 0.2, 1.0, 4.0)],
                    np.geomspace(lo[1], 0.25 * hi[1], 4), [0.0])

    def drive(self, v, theta, dt: float) -> np.ndarray:
        """G's input: ``v`` with the friction force added."""
        return friction_drive(v, *(float(t) for t in theta), dt)

    def simulate(self, sim, theta, i):
        return sim.from_v(self.drive(sim.v[i], theta, sim.dt))


class OutputHysteresis(Effect):
    """A rate-independent hysteresis between G's output and the sensor's static map h:
    ``y = h((1 - weight) w + weight P(w))``, ``P`` a Prandtl-Ishlinskii sum of
    :attr:`N_PLAYS` plays of half-widths ``width k / N_PLAYS`` with a threshold density tilted by
    ``shape`` (:mod:`hwid.blocks.hysteresis`); or the same operator on h's output
    (:class:`OutputHysteresisAfterH`), the fit choosing the place (:meth:`forms`).

    A sensor, a flexible coupling or a loose output shaft after the load's dynamics: its loop has
    the same width in G's output at every rate and amplitude beyond it, where F's play, before G,
    is filtered by G's dynamics (a faster input shrinks and turns its loop). ``weight`` 1 is the
    plays alone, below 1 part of the signal passes straight (the PI operator's linear part);
    ``shape`` 0 weighs the plays equally (the rounded loop of a real sensor's hysteresis), a large
    one leaves the widest play alone (one play's sharp corners), a negative one closes the loop
    soon after each reversal. Before h, ``width`` is in G's output units and h is re-estimated
    through it as through any other stage before h; after h, the loop's size in the output does
    not follow h's slope, which is what tells the two places apart where h is curved.
    """

    #: the plays summed
    N_PLAYS = HYSTERESIS_PLAYS
    g_factor = G_FACTOR_AFTER_GEAR
    #: the tilt's range: at 40 the widest play carries all but 5e-5 of the weight
    SHAPE_MAX = 40.0

    def __init__(self, name_block=("output_hysteresis", "output")):
        super().__init__(*name_block, ("width", "weight", "shape"),
                         "a rate-independent hysteresis (a Prandtl-Ishlinskii sum of plays) between G's output and h")

    def log_params(self):
        return (True, False, False)

    def forms(self, refit_h: bool = False) -> list[Effect]:
        """This place and after h; before h only where h is re-estimated with the effect (a play
        after h makes h's least squares non-linear)."""
        return [self] if refit_h else [self, OutputHysteresisAfterH()]

    def form_params(self) -> dict:
        return {HYSTERESIS_PLACE: 0.0}

    spec_params = form_params

    def width_of(self, sc: Scale) -> float:
        return sc.w_width

    def bounds(self, sc: Scale):
        """The largest play's half-width from 1e-3 to half of the signal's range; the weight in
        [0, 1]; the tilt within ±:attr:`SHAPE_MAX`."""
        W = self.width_of(sc)
        return np.array([1e-3 * W, 0.0, -self.SHAPE_MAX]), np.array([0.5 * W, 1.0, self.SHAPE_MAX])

    def starts(self, sc: Scale):
        lo, hi = self.bounds(sc)
        return grid(np.geomspace(0.01 * hi[0], hi[0], 6), [0.3, 1.0], [0.0, self.SHAPE_MAX])

    def hysteresis(self, w, theta, start: float = 0.0, from_sample: int = 0) -> np.ndarray:
        return hysteresis(w, float(theta[0]), float(theta[1]), float(theta[2]), start, from_sample)

    def with_memory(self, sim, x, theta, i, through_h: bool) -> np.ndarray:
        """The plays on ``x``, set where G has settled from the model's own start (one settling
        time in, or the first scored sample if sooner) to the place that fits the data, where
        ``x`` has not spanned the loop by the first scored sample (:func:`start_shows`,
        :meth:`ModelSim.memory_start`). A rig holds its plays where its own history left them: the
        model's G starts at rest at the first input, and the travel it makes settling from there
        is not the rig's (a rig that keeps its state between records, a record whose lead-in
        moves less than the loop: a fast sine, G's output hardly moving)."""
        settled = int(np.ceil(settling_time(sim.model) / sim.dt))

        def restart(first):
            k = min(settled, first)
            return k if start_shows(x[k:], first + 1 - k, float(theta[0])) else None

        mem = sim.memory_start(i, lambda s, k: self.hysteresis(x, theta, s, k), -1.0, 1.0, restart, through_h,
                               reach=2.0 * abs(float(theta[0])) * float(theta[1]), base=x)
        return self.hysteresis(x, theta) if mem is None else self.hysteresis(x, theta, mem["start"], mem["from_sample"])

    def simulate(self, sim, theta, i):
        return sim.model.output(self.with_memory(sim, sim.w[i], theta, i, True))


class OutputHysteresisAfterH(OutputHysteresis):
    """``output_hysteresis`` after h: ``y = (1 - weight) h(w) + weight P(h(w))``, ``width`` in the
    output's units (:class:`OutputHysteresis`)."""

    def __init__(self):
        super().__init__()
        object.__setattr__(self, "description", "a rate-independent hysteresis (a Prandtl-Ishlinskii sum of plays) "
                                                "on h's output")

    def forms(self, refit_h: bool = False) -> list[Effect]:
        return [self]

    def form_params(self) -> dict:
        return {HYSTERESIS_PLACE: 1.0}

    spec_params = form_params

    def width_of(self, sc: Scale) -> float:
        return sc.y_width

    def simulate(self, sim, theta, i):
        return self.with_memory(sim, sim.x[i], theta, i, False)


def peak_gain(G) -> float:
    """The largest ``|G(j omega)|`` (on 200 frequencies across G's poles' range, and at 0): what a
    force at G's input moves its output by at most."""
    return _peak_gain(tuple(map(float, G.num)), tuple(map(float, G.den)))


@lru_cache(maxsize=256)
def _peak_gain(num, den) -> float:
    G = LinearBlock(num, den)
    p = np.abs(G.poles())
    lo, hi = (float(np.min(p[p > 0])) / 100, float(np.max(p)) * 100) if np.any(p > 0) else (1e-3, 1e3)
    return float(max(abs(G.dc_gain), np.max(np.abs(G.freqresp(np.geomspace(lo, hi, 200))))))


def effects_after_gear() -> list[Effect]:
    """The two effects, in the catalogue's order."""
    return [Friction(), OutputHysteresis()]


def form_of(spec) -> Effect:
    """The catalogue's form that simulates a model's ``friction`` or ``output_hysteresis``
    (:class:`hwid.blocks.effects.EffectSpec`): the form a diagnosis fitted it with."""
    d = dict(spec.params)
    if spec.effect == "output_hysteresis":
        return OutputHysteresisAfterH() if d.get(HYSTERESIS_PLACE, 0.0) >= 0.5 else OutputHysteresis()
    if spec.effect != "friction":
        raise ValueError(f"{spec.effect!r} has one form")
    if d.get(FRICTION_FORM, 0.0) < 0.5:
        return GearFriction()
    if "sliding_speed" in d:
        return SmoothFriction()
    stribeck, damping = "stribeck" in d, "bristle_damping" in d
    return LuGreFriction(stribeck, damping) if stribeck or damping else Friction()


def form_theta(spec) -> tuple[Effect, np.ndarray]:
    """:func:`form_of` and the spec's parameters in its order (missing ones: 0)."""
    eff = form_of(spec)
    d = dict(spec.params)
    return eff, np.array([d.get(p, 0.0) for p in eff.params], float)
