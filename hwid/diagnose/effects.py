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

from dataclasses import dataclass, field

import numpy as np
from numba import njit
from scipy.ndimage import uniform_filter1d
from scipy.optimize import minimize_scalar



from hwid.blocks.linear import LinearBlock
from hwid.diagnose.experiments import settling_time
from hwid.model import HWModel, InputNonlinearity

CATALOGUE = ("input_saturation", "rate_limit", "input_deadzone", "curved_borders", "time_delay",
             "resonance", "sensor_lag", "sensor_saturation", "drift")


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

    @property
    def u_width(self) -> float:
        return max(self.u_max - self.u_min, 1e-12)

    @property
    def y_width(self) -> float:
        return max(self.y_max - self.y_min, 1e-12)

    @property
    def y_obs_width(self) -> float:
        """Range of the measured output (the model's when unknown)."""
        w = self.y_obs_max - self.y_obs_min
        return max(w, 1e-12) if np.isfinite(w) else self.y_width


# ------------------------------------------------------------------------------ signal primitives

@njit(cache=True)
def _rate_limit(u, step, u0):
    out = np.empty_like(u)
    prev = u0
    for k in range(u.shape[0]):
        d = u[k] - prev
        if d > step:
            d = step
        elif d < -step:
            d = -step
        prev = prev + d
        out[k] = prev
    return out


@njit(cache=True)
def _play_arrays(lo, hi, v0):
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
def _direction_arrays(z, up, dn, u0):
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


def rate_limited(u, rate: float, dt: float) -> np.ndarray:
    """An actuator slewing at most ``rate`` units/s, starting at ``u[0]``."""
    u = np.ascontiguousarray(u, float)
    return _rate_limit(u, float(rate) * dt, float(u[0])) if u.size else u.copy()


def _since_crossed(u, F: InputNonlinearity) -> int:
    """Samples back from the end of ``u`` to the start of the shortest tail over which ``u`` spans
    more than F's play (somewhere in it the input moved from one side of the play to the other, so
    the gear's state before it no longer matters); all of ``u`` if no tail does."""
    width = abs(float(F.d_plus - F.d_minus)) * (1.0 if F.type == "backlash" else 1.0 / max(F.slope_down, 1e-9))
    if u.size == 0 or width == 0:
        return 0
    r = u[::-1]
    hi = np.maximum.accumulate(r)
    lo = np.minimum.accumulate(r)
    done = np.flatnonzero(hi - lo > width)
    return int(done[0]) + 1 if done.size else int(u.size)


def deadzone(u, delta: float) -> np.ndarray:
    """0 for ``|u| < delta``, ``u - delta sign(u)`` beyond."""
    u = np.asarray(u, float)
    return np.sign(u) * np.maximum(np.abs(u) - delta, 0.0)


def first_order(x, tau: float, dt: float) -> np.ndarray:
    """``1/(tau s + 1)`` applied to ``x`` (exact for a zero-order-held input), from equilibrium."""
    if tau <= 0:
        return np.asarray(x, float)
    return simulate_linear(LinearBlock((1.0,), (float(tau), 1.0)), x, dt)


def smooth(r, width: int) -> np.ndarray:
    """Zero-phase moving average of ``width`` samples (edges: nearest value)."""
    r = np.asarray(r, float)
    if width <= 1 or r.size == 0:
        return r.copy()
    return uniform_filter1d(r, size=int(min(width, r.size)), mode="nearest")


def simulate_linear(G: LinearBlock, v, dt: float) -> np.ndarray:
    """:meth:`LinearBlock.simulate` (exact ZOH with fractional delay, from the equilibrium of
    ``v[0]``; its discretisation is cached, so the fits can simulate one G many times)."""
    return G.simulate(v, dt)


# ------------------------------------------------------------------------------------ the simulator

class ModelSim:
    """Simulates ``model`` on a list of experiments, caching the intermediate signals ``v, w, x``
    so an effect only recomputes the part of the chain after the stage it changes.

    Every experiment is simulated from the model's default initial state; the diagnosis
    experiments start with a lead-in (excluded from every gap) that makes the state irrelevant for
    the model itself. Where an effect keeps the lead-in from doing so, the state is estimated from
    the measured outputs attached by :meth:`measure` (:meth:`gear_start`, :meth:`rest_level`).
    ``u_before[i]`` is the input the plant received before experiment ``i`` (every experiment run
    before it, in order, or None): an actuator with memory (a rate limit) starts where that left
    it, not at the experiment's first sample, and may not reach the lead-in's far level in time;
    the backlash is then where that input's last moves put it. ``lead[i]`` is how much of it (the
    last samples) the chain after the actuator is run through before experiment ``i`` (default:
    all of it).
    """

    #: a nuisance start is looked for on this many points across its range first
    GEAR_POINTS = 9

    def __init__(self, model: HWModel, dt: float, inputs, u_before=None, lead=None):
        self.model = model
        self.dt = float(dt)
        self.inputs = [np.ascontiguousarray(u, float) for u in inputs]
        self.u_before = ([None if b is None else np.ascontiguousarray(b, float) for b in u_before]
                         if u_before is not None else None)
        self.lead = list(lead) if lead is not None else None
        self.measured = None
        self.v = [model.input.apply(u) for u in self.inputs]
        self.w = [simulate_linear(model.linear, v, self.dt) for v in self.v]
        self.x = [model.output(w) for w in self.w]

    def with_output(self, h) -> "ModelSim":
        """The same model and experiments with the output nonlinearity replaced by ``h`` (the
        intermediate ``v, w`` are shared, not recomputed)."""
        new = object.__new__(ModelSim)
        new.model = HWModel(self.model.input, self.model.linear, h)
        new.dt, new.inputs, new.v, new.w = self.dt, self.inputs, self.v, self.w
        new.u_before, new.lead, new.measured = self.u_before, self.lead, self.measured
        new.x = [h(w) for w in self.w]
        return new

    def measure(self, ys, masks, h, sigma: float) -> "ModelSim":
        """Attach the measured outputs, their scored samples, the output nonlinearity ``h`` to
        compare them through and the noise floor ``sigma`` (:meth:`gear_start`,
        :meth:`rest_level`); returns self."""
        self.measured = ([np.asarray(y, float) for y in ys], [np.asarray(m, bool) for m in masks], h, float(sigma))
        return self

    def from_input(self, u, F: InputNonlinearity | None = None, i: int | None = None) -> np.ndarray:
        """The chain after an input effect: ``u`` the actuator's output on experiment ``i`` (the
        gear's start from the data where ``u`` leaves it open, :meth:`gear_start`)."""
        F = F or self.model.input
        return self.from_v(F.apply(u, None if i is None else self.gear_start(u, i, F)))

    def gear_start(self, u, i: int, F: InputNonlinearity | None = None) -> float | None:
        """The gear's position before ``u[0]`` (``u`` the actuator's output on experiment ``i``)
        that fits the measured output best, where ``u`` has not crossed the play by the first
        scored sample; None where it has, for a Backlash-Inverse (its output follows the input's
        first move) or with nothing measured (:meth:`measure`).

        A rig may start a call with its gear anywhere in the play (parked, homed, left mid-move),
        and every lead-in crosses the play to put it against a known border -- but an effect of
        the actuator may keep it from doing so (a slow actuator turns back before it gets across).
        Started anywhere in the play, a backlash's output is ``clip(g0, v_lo, v_hi)`` with
        ``v_lo, v_hi`` its outputs from the play's two ends at ``u[0]``: one number per
        experiment, a nuisance parameter like the initial state ``hwid compare`` estimates."""
        F = F or self.model.input
        meas = self.measured
        if meas is None or F.type != "backlash" or u.size == 0:
            return None
        y, m, h = meas[0][i], meas[1][i], meas[2]
        if not m.any():
            return None
        lo, hi = float(F.ascending(u[0])), float(F.descending(u[0]))
        v_lo, v_hi = F.apply(u, lo), F.apply(u, hi)
        first = int(np.argmax(m))
        still = np.flatnonzero(v_hi - v_lo > 1e-9 * max(hi - lo, 1e-12))
        if not still.size or still[-1] < first:
            return None
        G = self.model.linear
        settle = settling_time(self.model)
        stop = min(u.size, int(still[-1]) + 1 + (int(np.ceil(settle / self.dt)) if np.isfinite(settle) else u.size))
        sel = m[:stop]
        ys = y[:stop][sel]

        def cost(g0):
            v = np.clip(g0, v_lo[:stop], v_hi[:stop])
            r = ys - h(simulate_linear(G, v, self.dt))[sel]
            return float(r @ r)

        return self._search(cost, lo, hi)

    def _search(self, cost, lo: float, hi: float) -> float:
        """The minimiser of ``cost`` over [lo, hi]: a grid, then Brent's bounded search across the
        best point's neighbours (to 1e-6 of the range)."""
        grid = np.linspace(lo, hi, self.GEAR_POINTS)
        k = int(np.argmin([cost(g) for g in grid]))
        a, b = grid[max(k - 1, 0)], grid[min(k + 1, grid.size - 1)]
        if b <= a:
            return float(grid[k])
        sol = minimize_scalar(cost, bounds=(a, b), method="bounded", options={"xatol": 1e-6 * (hi - lo)})
        return float(sol.x) if sol.fun <= cost(grid[k]) else float(grid[k])

    @property
    def v_span(self) -> tuple[float, float]:
        """The range of F's output over every experiment (the working range G may rest anywhere in)."""
        if getattr(self, "_v_span", None) is None:
            vs = [np.asarray(v) for v in self.v if len(v)]
            self._v_span = ((min(float(v.min()) for v in vs), max(float(v.max()) for v in vs)) if vs
                            else (0.0, 0.0))
        return self._v_span

    def rest_level(self, v, i: int, G: LinearBlock, w) -> np.ndarray | None:
        """``w`` (G's response to ``v`` on experiment ``i`` from rest at ``v[0]``) restarted from
        rest at the level that fits the measured output best, where that level still shows at the
        scored samples (by more than a tenth of the noise floor between the ends of the working
        range, :attr:`v_span`); None where it does not or with nothing measured (:meth:`measure`).

        A rig may start a call with G anywhere (left mid-move); every lead-in holds until the
        model's G has settled from any state, but an effect that slows G (a lightly damped mode)
        may ring longer. By superposition, G from rest at ``L`` gives ``w + (L - v[0]) f``, with
        ``f`` its response to a unit rest and no input: one number per experiment, a nuisance
        parameter like :meth:`gear_start`."""
        meas = self.measured
        if meas is None or v.size == 0:
            return None
        y, m, h, sigma = meas[0][i], meas[1][i], meas[2], meas[3]
        if not m.any():
            return None
        lo, hi = self.v_span
        lo, hi = min(lo, float(np.min(v))), max(hi, float(np.max(v)))
        d = G.simulate(np.zeros(v.size), self.dt, 1.0)      # f: from rest at 1, no input
        x_lo, x_hi = h(w + (lo - v[0]) * d), h(w + (hi - v[0]) * d)
        if not np.any(np.abs(x_hi - x_lo)[m] > 0.1 * sigma):
            return None
        ys = y[m]

        def cost(level):
            r = ys - h(w + (level - v[0]) * d)[m]
            return float(r @ r)

        return w + (self._search(cost, lo, hi) - v[0]) * d

    def before(self, i: int):
        """The input the plant received before experiment ``i`` (None if unknown)."""
        ub = getattr(self, "u_before", None)
        return None if ub is None else ub[i]

    def lead_samples(self, i: int) -> int:
        """How many of :meth:`before`'s last samples the chain after the actuator runs through."""
        prev = self.before(i)
        lead = getattr(self, "lead", None)
        n = 0 if prev is None else prev.size
        return n if lead is None or lead[i] is None else min(int(lead[i]), n)

    def from_v(self, v, G: LinearBlock | None = None, i: int | None = None) -> np.ndarray:
        """``h(G * v)``; with ``i``, G's starting level on experiment ``i`` from the data where it
        still shows (:meth:`rest_level`)."""
        G = G or self.model.linear
        w = simulate_linear(G, v, self.dt)
        if i is not None:
            w2 = self.rest_level(v, i, G, w)
            w = w if w2 is None else w2
        return self.model.output(w)


# ------------------------------------------------------------------------------------------ effects

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
    interacts: tuple[str, ...] = field(default=())

    def bounds(self, sc: Scale) -> tuple[np.ndarray, np.ndarray]:
        raise NotImplementedError

    def starts(self, sc: Scale) -> list[np.ndarray]:
        raise NotImplementedError

    def simulate(self, sim: ModelSim, theta, i: int) -> np.ndarray:
        raise NotImplementedError

    def log_params(self) -> tuple[bool, ...]:
        """Which parameters are fitted on a log scale."""
        return (False,) * len(self.params)

    def grow(self, theta) -> tuple["Effect", np.ndarray] | None:
        """For a family of nested effects (a degree chosen from the data): the next member and
        ``theta`` (this member's fitted parameters) in its parameters; None for a single effect."""
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
        return x


def _grid(*axes) -> list[np.ndarray]:
    mesh = np.meshgrid(*axes, indexing="ij")
    return [np.array(p, float) for p in zip(*(m.ravel() for m in mesh))]


class InputSaturation(Effect):
    kinked = True

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
        return sim.from_input(np.clip(sim.inputs[i], theta[0], theta[1]), i=i)


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

    def simulate(self, sim, theta, i):
        u, c, prev = sim.inputs[i], float(theta[1]), sim.before(i)
        fresh = sim.from_input(rate_limited(u, theta[0], sim.dt), i=i)
        if c <= 0 or prev is None or not prev.size:
            return fresh
        # the actuator through the whole session before; the gear from the data where this call's
        # moves leave its start open (the rig may have parked it between calls), else the chain
        # from where the actuator last crossed the play both ways (before that, nothing it did is
        # remembered)
        act = rate_limited(np.concatenate([prev, u]), theta[0], sim.dt)
        call = act[prev.size:]
        g0 = sim.gear_start(call, i)
        if g0 is not None:
            carried = sim.from_v(sim.model.input.apply(call, g0))
        else:
            k = max(sim.lead_samples(i), _since_crossed(act[:prev.size], sim.model.input))
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
        F = sim.model.input
        delta, a = float(theta[0]), float(theta[1])
        kp = 1.0 if F.type == "backlash" else 1.0 / F.slope_up
        km = 1.0 if F.type == "backlash" else 1.0 / F.slope_down
        dp, dm = F.d_plus - a * kp * delta, F.d_minus + a * km * delta
        if dp <= dm:
            dp = dm = 0.5 * (dp + dm)
            dp += 1e-9
        F2 = InputNonlinearity(F.type, F.slope_up, F.slope_down, dp, dm)
        return sim.from_input(deadzone(sim.inputs[i], delta), F2, i)


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

    #: the degrees tried, in order (each fit starts from the one before); beyond 6 the terms are
    #: ill-determined by a diagnosis's levels (degree 8 pressed its bounds on a tanh bend)
    DEGREES = (2, 4, 6)

    def __init__(self, degree: int = 2):
        k = int(degree)
        super().__init__("curved_borders", "input",
                         ("c0",) + tuple(f"c{j}_{side}" for side in ("up", "down") for j in range(1, k + 1)),
                         "the borders of F are curves instead of straight lines", interacts=("d_plus", "d_minus"))
        object.__setattr__(self, "degree", k)

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
        e = CurvedBorders(later[0])
        object.__setattr__(e, "_scale", self._scale)
        object.__setattr__(e, "_fit_span", self._fit_span)
        th = np.asarray(theta, float)
        k, k2 = self.degree, e.degree
        out = np.zeros(len(e.params))
        out[0] = th[0]
        out[1:1 + k] = th[1:1 + k]
        out[1 + k2:1 + k2 + k] = th[1 + k:1 + 2 * k]
        return e, out

    def _bend(self, s, c):
        """``sum c_j P_j(s)`` over the fit span, continued along its tangent beyond it."""
        leg = np.polynomial.legendre
        a, b = self._fit_span
        inside = np.clip(s, a, b)
        out = leg.legval(inside, c)
        d = leg.legder(c)
        return out + leg.legval(a, d) * np.minimum(s - a, 0.0) + leg.legval(b, d) * np.maximum(s - b, 0.0)

    def simulate(self, sim, theta, i):
        F = sim.model.input
        u = sim.inputs[i]
        sc = self._scale
        s = (u - sc[0]) / sc[1]
        th = np.asarray(theta, float)
        k = self.degree
        c_up, c_dn = np.r_[th[0], th[1:1 + k]], np.r_[th[0], th[1 + k:1 + 2 * k]]
        if F.type == "backlash":
            up = F.ascending(u) + F.slope_up * sc[1] * self._bend(s, c_up)
            dn = F.descending(u) + F.slope_down * sc[1] * self._bend(s, c_dn)
            v0 = float(np.clip(0.0, up[0], dn[0])) if dn[0] >= up[0] else 0.5 * (up[0] + dn[0])
            v = _play_arrays(np.ascontiguousarray(up), np.ascontiguousarray(np.maximum(dn, up)), v0)
        else:
            up = F.ascending(u) + sc[1] / F.slope_up * self._bend(s, c_up)
            dn = F.descending(u) + sc[1] / F.slope_down * self._bend(s, c_dn)
            v = _direction_arrays(u, np.ascontiguousarray(up), np.ascontiguousarray(dn), 0.5 * (up[0] + dn[0]))
        return sim.from_v(v)

    _scale = (0.0, 1.0)              # centre and half-width of the input range: s = (u - centre) / half-width
    _fit_span = (-np.inf, np.inf)    # the fit experiments' input range in s

    def with_scale(self, sc: Scale) -> "CurvedBorders":
        e = CurvedBorders(self.degree)
        centre, half = 0.5 * (sc.u_min + sc.u_max), 0.5 * sc.u_width
        object.__setattr__(e, "_scale", (centre, half))
        if np.isfinite(sc.u_fit_min) and np.isfinite(sc.u_fit_max) and sc.u_fit_max > sc.u_fit_min:
            object.__setattr__(e, "_fit_span", ((sc.u_fit_min - centre) / half, (sc.u_fit_max - centre) / half))
        return e


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
        G = sim.model.linear
        return sim.from_v(sim.v[i], LinearBlock(G.num, G.den, G.delay + max(float(theta[0]), 0.0)))


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
        G = sim.model.linear
        wn, z = float(theta[0]), float(theta[1])
        den = np.polymul(G.den, [1.0, 2 * z * wn, wn * wn])
        num = np.polymul(G.num, [wn * wn])
        return sim.from_v(sim.v[i], LinearBlock(tuple(num), tuple(den), G.delay), i)


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
        return first_order(x, float(theta[0]), dt)

    def simulate(self, sim, theta, i):
        return first_order(self._before_filter(sim, theta, i), float(theta[0]), sim.dt)

    def _before_filter(self, sim, theta, i):
        tau, a = float(theta[0]), float(theta[1])
        if a > 0:
            G = sim.model.linear
            num = np.polymul(G.num, [a * tau, 1.0])
            # a biproper G cannot give up a lag: keep it as it is
            x = sim.from_v(sim.v[i], LinearBlock(tuple(num), G.den, G.delay)) if num.size <= len(G.den) else sim.x[i]
        else:
            x = sim.x[i]
        return x


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
            SensorLag(), SensorSaturation(), Drift()]
    return {e.name: e for e in effs}


BLOCK = {name: e.block for name, e in catalogue().items()}
