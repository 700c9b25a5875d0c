"""The catalogue of unmodelled effects (names fixed by issue 6), each as a wrapper around an
:class:`hwid.model.HWModel` simulation.

Every effect knows

* its ``block`` (``input``, ``linear``, ``output`` or ``noise``) and the stage of the model's chain
  ``u -> [input effects] -> F -> G -> h -> [output effects] -> y`` it acts on, so the simulator
  only recomputes what the effect changes;
* its parameters with bounds (:meth:`Effect.bounds`) and a coarse grid of starting points
  (:meth:`Effect.starts`), both scaled from the experiments and the model (:class:`Scale`), never
  from any particular plant;
* what it interacts with and must be re-estimated with it (``input_deadzone`` shifts the identified
  borders ``d^+, d^-``: a model identified on a rig with a deadzone has absorbed it into them).

``drift`` is a disturbance, not a deterministic map: its "simulation" adds to the model output a
slowly varying offset estimated from the measured residual by a zero-phase moving average of
width ``window_s``; its parameter count is the smoother's effective degrees of freedom.
"""
from __future__ import annotations

import numpy as np

from hwid.blocks import effects as maps
from hwid.blocks.deadzone import deadzone
from hwid.blocks.slew import slewed
from hwid.diagnose.effect_base import Effect, Scale  # noqa: F401  (Scale: the catalogue's sizes)
from hwid.diagnose.effect_base import grid as _grid
from hwid.diagnose.effects_after_gear import effects_after_gear
from hwid.diagnose.modelsim import since_crossed, smooth

CATALOGUE = ("input_saturation", "rate_limit", "input_deadzone", "curved_borders", "time_delay",
             "resonance", "sensor_lag", "sensor_saturation", "drift", "friction", "output_hysteresis")


class InputSaturation(Effect):
    kinked = True
    static_input = True

    def __init__(self):
        super().__init__("input_saturation", "input", ("u_lo", "u_hi"),
                         "the actuator clips u to [u_lo, u_hi] before F")

    def bounds(self, sc):
        c, W = 0.5 * (sc.u_min + sc.u_max), sc.u_width
        return np.array([sc.u_min - 0.05 * W, c]), np.array([c, sc.u_max + 0.05 * W])

    def starts(self, sc):
        lo, hi = self.bounds(sc)
        return _grid(np.linspace(lo[0], lo[1], 7)[:-1], np.linspace(hi[0], hi[1], 7)[1:])

    def simulate(self, sim, theta, i):
        return sim.from_input(sim.actuate(i, lambda u: np.clip(u, theta[0], theta[1])), i=i)


class RateLimit(Effect):
    """The actuator slews at most ``rate`` units/s.

    On a physical rig its position carries over from one experiment to the next, and a slow
    actuator may not reach the lead-in's far level before the experiment proper: the backlash is
    then where the previous input's last moves left it, not where a fresh start puts it. A rig
    driver may also reset the actuator at every call. ``carried`` in [0, 1] weighs the two: the
    output of the actuator started at ``u[0]`` (0) and that of the actuator run on through the end
    of the previous experiment's input (:meth:`ModelSim.before`) first (1)."""

    kinked = True

    def __init__(self):
        super().__init__("rate_limit", "input", ("rate", "carried"), "the actuator slews at most `rate` units/s")

    def log_params(self):
        return (True, False)

    #: the slowest actuator considered crosses the input range in this long at least, s (a real
    #: rig's may take a minute), or in 20 settling times of G where that is longer
    SLOWEST_CROSSING_S = 120.0

    def bounds(self, sc):
        slow = max(20 * sc.settle_s, self.SLOWEST_CROSSING_S)
        return np.array([sc.u_width / slow, 0.0]), np.array([sc.u_width / sc.dt, 1.0])

    def starts(self, sc):
        lo, hi = self.bounds(sc)
        return _grid(np.geomspace(lo[0], hi[0], 14), [0.0, 1.0])

    def other_readings(self, theta) -> list[np.ndarray]:
        """The actuator reset at every call and carried over, other than the fit's own reading:
        where each fit experiment starts at the input the one before ended on, the two are the
        same there, and only experiments that do not join tell them apart. Both ends, not the
        other side of one half: where the fit cannot tell, ``carried`` stays wherever the descent
        left it (a judged rig carrying its actuator was fitted at 0.51, its exact rate, and its
        multisine after another, the only validation experiment that starts away from where the
        one before ended, was left 6.5x the floor; at 1 it is 0.96x, at 0 13x)."""
        th = np.asarray(theta, float)
        return [np.r_[th[0], c] for c in (0.0, 1.0) if c != th[1]]

    def simulate(self, sim, theta, i):
        u, c, prev = sim.inputs[i], float(theta[1]), sim.before(i)
        fresh = sim.from_input(sim.actuate(i, lambda a: slewed(a, theta[0], sim.dt)), i=i)
        if c <= 0 or prev is None or not prev.size:
            return fresh
        # the actuator through the whole session before; the gear from the data where this call's
        # moves leave its start open (the rig may have parked it between calls), else the chain
        # from where the actuator last crossed the play both ways (before that, nothing it did is
        # remembered)
        act = slewed(np.concatenate([prev, u]), theta[0], sim.dt)
        call = act[prev.size:]
        sim.note_start(i, position=float(act[prev.size - 1]))
        g0 = sim.gear_start(call, i)
        if g0 is not None:
            carried = sim.from_v(sim.model.input.apply(call, g0))
        else:
            sim.note_start(i, carried_from_tail=True)     # the chain run through the tail: no (gear, rest) start
            k = max(sim.lead_samples(i), since_crossed(act[:prev.size], sim.model.input))
            carried = sim.from_input(act[prev.size - k:])[k:]
        return fresh + c * (carried - fresh)


class InputDeadzone(Effect):
    """``u -> 0`` for ``|u| < delta``, ``u - delta sign(u)`` beyond, before F.

    Interaction: a model identified on a rig with a deadzone has absorbed it into its borders
    (``d^+`` grows by ``delta``, ``d^-`` shrinks by ``delta``, scaled by the slopes for a
    Backlash-Inverse). ``absorbed`` in [0, 1] takes that share back out of the borders, so the
    deadzone never widens the model's play: ``absorbed = 0`` for a trusted simulator, 1 for a model
    identified on the same rig.
    """

    kinked = True
    static_input = True

    def __init__(self):
        super().__init__("input_deadzone", "input", ("delta", "absorbed"),
                         "the actuator does not move for |u| < delta; the borders d+, d- are re-estimated",
                         interacts=("d_plus", "d_minus"))

    def bounds(self, sc):
        a = max(abs(sc.u_min), abs(sc.u_max))
        return np.array([0.0, 0.0]), np.array([0.4 * a, 1.0])

    def starts(self, sc):
        lo, hi = self.bounds(sc)
        return _grid(np.linspace(0, hi[0], 10)[1:], [0.0, 1.0])

    def simulate(self, sim, theta, i):
        delta, a = float(theta[0]), float(theta[1])
        F2 = maps.deadzone_borders(sim.model.input, delta, a)
        return sim.from_input(sim.actuate(i, lambda u: deadzone(u, delta)), F2, i)


class CurvedBorders(Effect):
    """Each border of F becomes a curve: its straight line plus
    ``k (c0 + c1 P1(s) + ... + cK PK(s))``, Legendre polynomials of ``s`` (the input scaled to
    [-1, 1] over the experiments' range) up to the degree ``K``, ``k`` the border's scale (slope x
    half-range). ``c0`` (shared) and ``c1`` re-estimate the straight part the curve is measured
    against (a model's straight border is the best line through a curved one, not the curve's
    chord); the shift is shared by both borders so the curve never widens or narrows the play as a
    whole (that is a different backlash, or friction elsewhere).

    A real border bends in any smooth shape (a bow, an S, stiffening at one end, a local bump), so
    the degree is the data's choice: the fitter starts at :attr:`DEGREES`' first and moves to the
    next (:meth:`grow`, started from the fit so far) while an information criterion on the fit
    experiments improves (:meth:`hwid.diagnose.rank.EffectFitter.fit`). Beyond the fit
    experiments' input range the bend goes on along its tangent at the range's end: the data say
    nothing of it there, and a polynomial's own continuation runs away (an S-shaped bend on the
    paper's plant, fitted to 4x the floor, left 85x on validation levels 15 % further out)."""

    static_input = True

    #: the degrees tried, in order (each fit starts from the one before); beyond 6 the terms are
    #: ill-determined by a diagnosis's levels (degree 8 pressed its bounds on a tanh bend)
    DEGREES = (2, 4, 6)

    def __init__(self, degree: int = 2, play: bool = False):
        k = int(degree)
        super().__init__("curved_borders", "input", maps.curve_params(k, play),
                         "the borders of F are curves instead of straight lines", interacts=("d_plus", "d_minus"))
        object.__setattr__(self, "degree", k)
        object.__setattr__(self, "play", bool(play))

    def bounds(self, sc):
        n = len(self.params)
        return np.full(n, -0.4), np.full(n, 0.4)

    def starts(self, sc):
        """Straight borders, and both bowed either way (the second Legendre term)."""
        n, k = len(self.params), self.degree
        out = [np.zeros(n)]
        for c in (0.05, -0.05):
            z = np.zeros(n)
            z[[2, 2 + k]] = c
            out.append(z)
        return out

    def grow(self, theta) -> tuple["CurvedBorders", np.ndarray] | None:
        """The next degree of :attr:`DEGREES` and ``theta`` (this degree's fit) in its parameters,
        the new terms zero; None at the last."""
        later = [d for d in self.DEGREES if d > self.degree]
        if not later:
            return None
        e = self._like(later[0])
        th = np.asarray(theta, float)
        k, k2 = self.degree, e.degree
        out = np.zeros(len(e.params))
        out[0] = th[0]
        out[1:1 + k] = th[1:1 + k]
        out[1 + k2:1 + k2 + k] = th[1 + k:1 + 2 * k]
        if self.play:
            out[-1] = th[1 + 2 * k]
        return e, out

    def loosen(self, theta) -> tuple["CurvedBorders", np.ndarray] | None:
        """This degree with the play's width free as well (``play``: the borders' shifts apart,
        in the bend's units), started from this member's fit; None if it is free already.

        The bend's own terms keep the play's width as the model has it: a widening alone is a
        different backlash, or a dead zone's (:class:`InputDeadzone`). But a real border that bends
        does not keep its mean place, and where one border bends one way and the other the other,
        the play widens on average: the blind check's bent borders of a Backlash-Inverse, bowed
        apart, were `unexplained` from their logs with their own simulator as ``--model`` on four
        judged seeds (the bend explained 0.18-0.54, leaving 3.4-11x the floor), and taken to
        1.0-1.04x with the width free. Each step of the bend's growth tries the next degree and
        this, from the member so far, and takes the one the fit experiments' criterion prefers."""
        if self.play:
            return None
        return self._like(self.degree, play=True), np.r_[np.asarray(theta, float), 0.0]

    def _bend_basis(self, u) -> np.ndarray:
        """The bend's basis on the input ``u``: column ``j`` is ``P_j(s)`` over the fit span,
        continued along its tangent beyond it, so a bend is this matrix times its coefficients.
        Kept for each input array seen (a fit simulates the same experiments hundreds of times)."""
        cache = self.__dict__.setdefault("_bases", {})
        hit = cache.get(id(u))
        if hit is not None and hit[0] is u:
            return hit[1]
        B = maps.bend_basis(u, self.degree, self._scale[0], self._scale[1], self._fit_span)
        cache[id(u)] = (u, B)
        return B

    def __getstate__(self):
        """Without the bases (a fitted family travels back from a worker as its parameters)."""
        return {k: v for k, v in self.__dict__.items() if k != "_bases"}

    def simulate(self, sim, theta, i):
        u = sim.inputs[i]
        v = maps.curved_output(sim.model.input, u, self._bend_basis(u), theta, self.degree, self.play, self._scale[1])
        return sim.from_v(v)

    def spec_params(self) -> dict:
        """The input scaling a model carrying the bend needs beside its fitted terms
        (:class:`hwid.blocks.effects.EffectSpec`): the centre and half-width of the input range the
        Legendre polynomials are scaled to, and the fit experiments' range beyond which the bend
        goes on along its tangent (left out where unbounded)."""
        (c, half), (a, b) = self._scale, self._fit_span
        out = {"u_centre": float(c), "u_half_width": float(half)}
        if np.isfinite(a):
            out["fit_lo"] = float(c + a * half)
        if np.isfinite(b):
            out["fit_hi"] = float(c + b * half)
        return out

    _scale = (0.0, 1.0)              # centre and half-width of the input range: s = (u - centre) / half-width
    _fit_span = (-np.inf, np.inf)    # the fit experiments' input range in s

    def _like(self, degree: int, scale=None, fit_span=None, play=None) -> "CurvedBorders":
        """The family's member of ``degree`` on this one's input scaling (or the one given), with
        the play's width free as this one has it (or as given)."""
        e = CurvedBorders(degree, self.play if play is None else play)
        object.__setattr__(e, "_scale", self._scale if scale is None else scale)
        object.__setattr__(e, "_fit_span", self._fit_span if fit_span is None else fit_span)
        return e

    def with_scale(self, sc: Scale) -> "CurvedBorders":
        centre, half = 0.5 * (sc.u_min + sc.u_max), 0.5 * sc.u_width
        span = (-np.inf, np.inf)
        if np.isfinite(sc.u_fit_min) and np.isfinite(sc.u_fit_max) and sc.u_fit_max > sc.u_fit_min:
            span = ((sc.u_fit_min - centre) / half, (sc.u_fit_max - centre) / half)
        return self._like(self.degree, (centre, half), span)


class TimeDelay(Effect):
    kinked = True

    def __init__(self):
        super().__init__("time_delay", "linear", ("delay_s",), "a transport delay added to G")

    def bounds(self, sc):
        return np.array([0.0]), np.array([max(0.5 * sc.settle_s, 5 * sc.dt)])

    def starts(self, sc):
        hi = self.bounds(sc)[1][0]
        return [np.array([d]) for d in np.linspace(0, hi, 21)[1:]]

    def simulate(self, sim, theta, i):
        return sim.from_v(sim.v[i], maps.delayed(sim.model.linear, float(theta[0])))


# a complex pole pair is a lightly damped mode below this damping ratio (a resonant peak of |G| of
# at least 1.75, +4.9 dB); better damped, a second-order factor is a low-pass that would stand in
# for a delay or a lag, not a resonance
ZETA_LIGHT = 0.3


class Resonance(Effect):
    """``G(s) wn^2/(s^2 + 2 zeta wn s + wn^2)``: a lightly damped mode (``zeta <= ZETA_LIGHT``),
    unit static gain."""

    def __init__(self):
        super().__init__("resonance", "linear", ("omega_n", "zeta"), "a lightly damped mode of G")

    def log_params(self):
        return (True, True)

    def bounds(self, sc):
        nyq = np.pi / sc.dt
        return np.array([0.3 * sc.omega_c, 0.005]), np.array([0.5 * nyq, ZETA_LIGHT])

    def starts(self, sc):
        lo, hi = self.bounds(sc)
        return _grid(np.geomspace(lo[0], hi[0], 40), [0.03, 0.1, ZETA_LIGHT])

    def at_defining_bound(self, theta) -> bool:
        return float(theta[1]) >= 0.97 * ZETA_LIGHT

    def simulate(self, sim, theta, i):
        wn, z = float(theta[0]), float(theta[1])
        # its own mode, which may ring past the lead-in
        return sim.from_v(sim.v[i], maps.with_mode(sim.model.linear, wn, z), i, ringing=maps.mode_poles(wn, z))


class SensorLag(Effect):
    """``1/(tau s + 1)`` after h (the structure becomes Wiener-Hammerstein).

    Interaction: a G identified on a rig with a sensor lag has absorbed part of it (exactly when h
    is linear); ``absorbed`` in [0, 1] takes that share back out, ``G -> G (absorbed tau s + 1)``."""

    def __init__(self):
        super().__init__("sensor_lag", "output", ("tau_s", "absorbed"),
                         "first-order sensor dynamics 1/(tau s + 1) after h; G re-estimated", interacts=("G",))

    def log_params(self):
        return (True, False)

    def bounds(self, sc):
        return np.array([0.5 * sc.dt, 0.0]), np.array([2.0 * sc.settle_s, 1.0])

    def starts(self, sc):
        lo, hi = self.bounds(sc)
        return _grid(np.geomspace(lo[0], hi[0], 14), [0.0, 1.0])

    def pre(self, sim_w, theta, i):
        return self._before_filter(sim_w, theta, i)

    def post(self, x, theta, dt):
        return maps.first_order(x, float(theta[0]), dt)

    def simulate(self, sim, theta, i):
        return maps.first_order(self._before_filter(sim, theta, i), float(theta[0]), sim.dt)

    def _before_filter(self, sim, theta, i):
        # a biproper G cannot give up a lag: kept as it is
        G = maps.lag_given_up(sim.model.linear, float(theta[0]), float(theta[1]))
        return sim.x[i] if G is None else sim.from_v(sim.v[i], G)


class SensorSaturation(Effect):
    """The sensor clips y to ``[y_lo, y_hi]`` (``±y_max`` when symmetric)."""

    kinked = True

    def __init__(self):
        super().__init__("sensor_saturation", "output", ("y_lo", "y_hi"), "the sensor clips y")

    def bounds(self, sc):
        c, R = 0.5 * (sc.y_min + sc.y_max), sc.y_width
        lo, hi = sc.y_min - 0.05 * R, sc.y_max + 0.05 * R
        if np.isfinite(sc.y_obs_min) and np.isfinite(sc.y_obs_max):
            lo, hi = min(lo, sc.y_obs_min - 0.05 * R), max(hi, sc.y_obs_max + 0.05 * R)
        return np.array([lo, c]), np.array([c, hi])

    def starts(self, sc):
        """A grid over both limits, and the measured extremes: a clipping sensor reads its limits
        exactly, so the samples pile up at the largest and smallest values measured (the limits'
        maximum-likelihood estimates when the clip is reached), each with the other limit out of
        reach."""
        lo, hi = self.bounds(sc)
        out = _grid(np.linspace(lo[0], lo[1], 7)[:-1], np.linspace(hi[0], hi[1], 7)[1:])
        if np.isfinite(sc.y_obs_min) and np.isfinite(sc.y_obs_max):
            out += _grid([sc.y_obs_min, lo[0]], [sc.y_obs_max, hi[1]])
        return out

    post_linear = False

    def pre(self, sim_w, theta, i):
        return sim_w.w[i]

    def post(self, x, theta, dt):
        return np.clip(x, theta[0], theta[1])

    def simulate(self, sim, theta, i):
        return np.clip(sim.x[i], theta[0], theta[1])


class Drift(Effect):
    """A slow additive offset in y, estimated from the measured residual by a zero-phase moving
    average of ``window_s`` seconds (a disturbance model: its state comes from each experiment's
    own output, its one parameter from the fit data)."""

    def __init__(self):
        super().__init__("drift", "noise", ("window_s",), "a slow additive offset wandering in y",
                         disturbance=True)

    def log_params(self):
        return (True,)

    def bounds(self, sc):
        return np.array([0.5 * sc.settle_s]), np.array([max(4 * sc.duration_s, sc.settle_s)])

    def starts(self, sc):
        lo, hi = self.bounds(sc)
        return [np.array([t]) for t in np.geomspace(lo[0], hi[0], 12)]

    def width(self, theta, dt) -> int:
        return max(int(round(float(theta[0]) / dt)), 1)

    def simulate(self, sim, theta, i, y=None, mask=None):
        x = sim.x[i]
        if y is None:
            return x
        r = np.where(mask, y - x, 0.0) if mask is not None else y - x
        wgt = mask.astype(float) if mask is not None else np.ones_like(x)
        m = self.width(theta, sim.dt)
        num, den = smooth(r, m), smooth(wgt, m)
        return x + np.where(den > 1e-9, num / np.maximum(den, 1e-9), 0.0)

    def dof(self, theta, n_samples: int, dt: float) -> float:
        """Effective degrees of freedom of the smoother (trace of its hat matrix) on n samples."""
        return float(n_samples) / self.width(theta, dt)


def catalogue(sc: Scale | None = None) -> dict[str, Effect]:
    """Every catalogue effect by name (``curved_borders`` scaled to the working range)."""
    cb = CurvedBorders().with_scale(sc) if sc is not None else CurvedBorders()
    effs = [InputSaturation(), RateLimit(), InputDeadzone(), cb, TimeDelay(), Resonance(),
            SensorLag(), SensorSaturation(), Drift(), *effects_after_gear()]
    return {e.name: e for e in effs}


BLOCK = {name: e.block for name, e in catalogue().items()}
