"""Rig drivers with known unmodelled effects, for ``tests/test_diagnose*.py``.

A small geared plant implemented here independently of hwid's blocks: a backlash (play 0.3 each
side, unit slopes), ``G(s) = 2/((s+1)(s+2))`` discretised with scipy's ZOH, ``h(w) = w - 0.1 w^3``,
white noise 0.01; the gear position and the drift carry over from call to call as on a real rig.
Each driver adds one effect (the truth the tests check against); :data:`BASE_YAML` is the base
plant as an hwid model. ``function(u, dt) -> y`` as ``plant.kind: external`` expects.
"""
from __future__ import annotations

import functools
import math
import zlib

import numpy as np
from scipy import signal

BASE = {"kind": "hammerstein_wiener",
        "input_nonlinearity": {"type": "backlash", "slope_up": 1.0, "slope_down": 1.0, "d_plus": 0.3, "d_minus": -0.3},
        "linear": {"num": [2.0], "den": [1.0, 3.0, 2.0]},
        "output_nonlinearity": {"polynomial": [0, 1.0, 0, -0.1]},
        "noise": {"std": 0.01}}
NOISE = 0.01
TRUTH = {"sensor_lag": {"tau_s": 1.5}, "rate_limit": {"rate": 0.4}, "rate_limit_slow": {"rate": 2.0 / 15.0}, "input_deadzone": {"delta": 0.2},
         "sensor_saturation": {"y_lo": -0.55, "y_hi": 0.55}, "resonance": {"omega_n": 4.0, "zeta": 0.05},
         "rate_limit_inverse": {"rate": 5.6}, "rate_limit_inverse_moderate": {"rate": 1.5}, "input_saturation_paper": {"u_lo": -1.23, "u_hi": 0.73},
         "bent_borders": {"up": 0.06, "down": -0.04}, "sensor_saturation_paper": {"y_lo": -1.3, "y_hi": 1.3},
         "input_deadzone_paper": {"delta": 0.21},
         "bowed_apart_inverse": {"bow": 0.1}}
# the paper's plant (Section 6) as an hwid model: the base of the paper-rig tests
PAPER = {"kind": "hammerstein_wiener",
         "input_nonlinearity": {"type": "backlash", "slope_up": 1.0, "slope_down": 1.0, "d_plus": 0.5, "d_minus": -0.5},
         "linear": {"num": [0.2], "den": [1.0, 0.7, 0.1]},
         "output_nonlinearity": {"polynomial": [0, 0.25, 0, -0.42, 0, 0.2]},
         "noise": {"std": 0.01}}


def paper_config(driver: str) -> dict:
    """A config of the paper-plant rig ``driver`` with the paper's staircases and sines; the rig
    starts afresh (its noise and state do not carry over from another test that ran it first in
    the same process, which made a test's verdict depend on the order pytest's workers took)."""
    _RIGS.pop(driver, None)
    return {"name": driver.replace("_", "-"), "seed": 11, "sampling": {"dt": 0.05},
            "plant": {"kind": "external", "callable": f"diagnose_rigs:{driver}"},
            "protocols": {"staircase": {"levels_up": [round(float(x), 4) for x in np.linspace(-1.4, 1.2, 10)],
                                        "levels_down": [round(float(x), 4) for x in np.linspace(1.2, -1.4, 11)[1:]],
                                        "hold": 30.0},
                          "sine": {"amplitude": 1.0, "frequencies": [0.02, 0.05, 0.1, 0.2], "periods": 3}}}


def base_config(driver: str, dt: float = 0.04) -> dict:
    """A config of the :data:`BASE`-plant rig ``driver`` with short staircases (holds of 8 s) and
    three sines, the rig started afresh (as :func:`paper_config`)."""
    _RIGS.pop(driver, None)
    return {"name": "rig", "seed": 5, "sampling": {"dt": dt},
            "plant": {"kind": "external", "callable": f"diagnose_rigs:{driver}"},
            "protocols": {"staircase": {"levels_up": [-1.0, -0.75, -0.5, -0.25, 0.0, 0.25, 0.5, 0.75, 1.0],
                                        "levels_down": [1.0, 0.75, 0.5, 0.25, 0.0, -0.25, -0.5, -0.75, -1.0],
                                        "hold": 8.0},
                          "sine": {"amplitude": 0.8, "frequencies": [0.5, 1.0, 2.0], "periods": 3}}}


def diagnose_base_rig(tmp, driver: str, dt: float = 0.04, model: bool = True, effects=None) -> dict:
    """``hwid diagnose`` of the rig ``driver`` (:func:`base_config`), with :data:`BASE` as the model
    (``model``) or identified, quietly."""
    from hwid import config
    from hwid.diagnose import diagnose
    import yaml
    (tmp / "c.yaml").write_text(yaml.safe_dump(base_config(driver, dt)))
    (tmp / "base.yaml").write_text(yaml.safe_dump({"plant": BASE}))
    return diagnose(config.load(tmp / "c.yaml"), tmp / "out", model=(tmp / "base.yaml") if model else None,
                    echo=lambda *a: None, effects=effects)


class _Rig:
    def __init__(self, seed: int):
        self.gear = 0.0
        self.t = 0.0
        self.drift = 0.0
        self.rng = np.random.default_rng(np.random.SeedSequence(seed))

    def gear_out(self, u, play: float):
        """The gear's position through a backlash of ``play`` each side (unit slopes), carried over."""
        v = np.empty_like(u)
        g = self.gear
        for i, ui in enumerate(u):
            g = min(max(g, ui - play), ui + play)
            v[i] = g
        self.gear = g
        return v

    def base(self, u, dt, out_play: float = 0.0, mode=None, start=None):
        """G at rest at the gear's first position, or at ``start`` where given."""
        v = self.gear_out(u, 0.3)
        num, den = [2.0], [1.0, 3.0, 2.0]
        if mode is not None:        # a lightly damped mode wn^2 / (s^2 + 2 zeta wn s + wn^2)
            wn, z = mode
            num, den = np.polymul(num, [wn * wn]), np.polymul(den, [1.0, 2 * z * wn, wn * wn])
        b, a, _ = signal.cont2discrete((num, den), dt, method="zoh")[:3]
        b = np.ravel(b)
        v0 = v[0] if start is None else start
        zi = signal.lfiltic(b, a, y=[v0] * (len(a) - 1), x=[v0] * (len(b) - 1))
        w = signal.lfilter(b, a, v, zi=zi)[0]
        return w - 0.1 * w ** 3

    def noise(self, n):
        return NOISE * self.rng.standard_normal(n)


_RIGS: dict[str, _Rig] = {}


def _rig(name: str) -> _Rig:
    if name not in _RIGS:
        _RIGS[name] = _Rig(zlib.crc32(name.encode()))
    return _RIGS[name]


def plain(u, dt):
    r = _rig("plain")
    u = np.asarray(u, float)
    return r.base(u, dt) + r.noise(u.size)



def plain_at_rest(u, dt):
    """The plain plant on a rig that does not keep its state between calls: at every call the gear
    rests against one border at ``u[0]`` (drawn at random: the rig was parked, homed or moved by
    hand) and G is at rest there."""
    r = _rig("plain_at_rest")
    u = np.asarray(u, float)
    r.gear = float(u[0] + 0.3 * r.rng.choice([-1.0, 1.0]))
    return r.base(u, dt) + r.noise(u.size)


def plain_anywhere(u, dt):
    """The plain plant started anywhere at every call: the gear at a random point inside the play
    at ``u[0]`` and G at rest at a random level of the working range (a rig left mid-move)."""
    r = _rig("plain_anywhere")
    u = np.asarray(u, float)
    r.gear = float(u[0] + r.rng.uniform(-0.3, 0.3))
    level = r.rng.uniform(-1.0, 1.0)
    return r.base(u, dt, start=level) + r.noise(u.size)

def sensor_lag(u, dt):
    r = _rig("sensor_lag")
    u = np.asarray(u, float)
    x = r.base(u, dt)
    a = np.exp(-dt / TRUTH["sensor_lag"]["tau_s"])
    y = signal.lfilter([1 - a], [1, -a], x, zi=[a * x[0]])[0]
    return y + r.noise(u.size)


def rate_limit(u, dt):
    r = _rig("rate_limit")
    u = np.asarray(u, float)
    step = TRUTH["rate_limit"]["rate"] * dt
    ua = np.empty_like(u)
    p = u[0]
    for i, ui in enumerate(u):
        p += min(max(ui - p, -step), step)
        ua[i] = p
    return r.base(ua, dt) + r.noise(u.size)


def _carried_actuator(name: str, rate: float, u, dt):
    """The base plant behind an actuator slewing at most ``rate`` units/s whose position carries
    over from call to call, as on a physical rig."""
    r = _rig(name)
    u = np.asarray(u, float)
    step = rate * dt
    ua = np.empty_like(u)
    p = getattr(r, "actuator", u[0])
    for i, ui in enumerate(u):
        p += min(max(ui - p, -step), step)
        ua[i] = p
    r.actuator = p
    return r.base(ua, dt) + r.noise(u.size)


def rate_limit_carried(u, dt):
    """The same actuator, but its position carries over from call to call as on a physical rig
    (``rate_limit`` resets it to ``u[0]`` at every call, as a driver that homes it would)."""
    return _carried_actuator("rate_limit_carried", TRUTH["rate_limit"]["rate"], u, dt)


def rate_limit_slow(u, dt):
    """A slow actuator: 15 s to cross the range [-1, 1] (G settles in 4 s), its position carried
    over from call to call."""
    return _carried_actuator("rate_limit_slow", TRUTH["rate_limit_slow"]["rate"], u, dt)


def rate_limit_slow_elsewhere(u, dt):
    """The same slow actuator, left at +0.9 by whatever ran before the first call (the diagnosis
    opens by commanding the far end of the range, -1.15)."""
    r = _rig("rate_limit_slow_elsewhere")
    if not hasattr(r, "actuator"):
        r.actuator = 0.9
    return _carried_actuator("rate_limit_slow_elsewhere", TRUTH["rate_limit_slow"]["rate"], u, dt)


def rate_limit_slow_b(u, dt):
    """The same slow actuator on a rig of its own (a test that must not start where another test's
    diagnosis left the first one's actuator)."""
    return _carried_actuator("rate_limit_slow_b", TRUTH["rate_limit_slow"]["rate"], u, dt)


def _play(r, lo, hi) -> np.ndarray:
    """The gear between the borders ``lo`` and ``hi`` (arrays over the samples), from and back into
    ``r.gear``: the rig's own play, written apart from hwid's."""
    v = np.empty_like(lo)
    g = r.gear
    for i in range(lo.size):
        g = min(max(g, lo[i]), hi[i])
        v[i] = g
    r.gear = g
    return v


def bent_borders(u, dt):
    """Borders bent as S-curves, not any polynomial: the ascending one by
    ``+0.06 tanh(2.5 u) / tanh(2.5)``, the descending one by ``-0.04`` times the same (the play
    narrows towards the ends), unit slopes and the base's play otherwise."""
    r = _rig("bent_borders")
    u = np.asarray(u, float)
    bend = np.tanh(2.5 * u) / np.tanh(2.5)
    lo, hi = u - 0.3 + TRUTH["bent_borders"]["up"] * bend, u + 0.3 + TRUTH["bent_borders"]["down"] * bend
    v = _play(r, lo, hi)
    return _base_g_h(v, dt) + r.noise(u.size)


def input_deadzone(u, dt):
    r = _rig("input_deadzone")
    u = np.asarray(u, float)
    dz = TRUTH["input_deadzone"]["delta"]
    ua = np.where(u > dz, u - dz, np.where(u < -dz, u + dz, 0.0))
    return r.base(ua, dt) + r.noise(u.size)


def output_friction(u, dt):
    """Outside the catalogue: stick-slip friction at the output shaft -- the measured position
    only follows the model's output once it has moved 0.04 away (a play on x)."""
    r = _rig("output_friction")
    u = np.asarray(u, float)
    x = r.base(u, dt)
    y = np.empty_like(x)
    p = x[0]
    for i, xi in enumerate(x):
        p = min(max(p, xi - 0.04), xi + 0.04)
        y[i] = p
    return y + r.noise(u.size)


def sensor_saturation(u, dt):
    """The sensor reads y clipped to [-0.55, 0.55] (h reaches +-0.67 on the working range)."""
    r = _rig("sensor_saturation")
    u = np.asarray(u, float)
    t = TRUTH["sensor_saturation"]
    return np.clip(r.base(u, dt) + r.noise(u.size), t["y_lo"], t["y_hi"])


def resonance(u, dt):
    """G with a lightly damped mode at 4 rad/s (zeta 0.05), above the sines' band (0.3-3 rad/s)."""
    r = _rig("resonance")
    u = np.asarray(u, float)
    t = TRUTH["resonance"]
    return r.base(u, dt, mode=(t["omega_n"], t["zeta"])) + r.noise(u.size)


class _InverseRig(_Rig):
    """A Backlash-Inverse geared plant (direction map: ``v = u / 1.0 + 0.2`` while u rises,
    ``u / 1.3 - 0.3`` while it falls), ``G(s) = 1/(0.8 s + 1)``, ``h(w) = 0.8 w - 0.1 w^3``, white
    noise 0.005; the actuator's position and the map's direction carry over from call to call."""

    NOISE = 0.005

    def __init__(self, seed: int):
        super().__init__(seed)
        self.u_prev = None
        self.actuator = None

    def inverse(self, u, dt, bow=None, shifts=None):
        """``bow``: per sample, how far each branch is moved away from the other; ``shifts``: per
        sample, how far the rising and the falling branch are moved up (a pair of arrays)."""
        v = np.empty_like(u)
        bow = np.zeros_like(u) if bow is None else bow
        up_shift, dn_shift = (np.zeros_like(u), np.zeros_like(u)) if shifts is None else shifts
        g, prev = self.gear, (u[0] if self.u_prev is None else self.u_prev)
        for i, ui in enumerate(u):
            if ui > prev:
                g = ui / 1.0 + 0.2 + bow[i] + up_shift[i]
            elif ui < prev:
                g = ui / 1.3 - 0.3 - bow[i] + dn_shift[i]
            prev = ui
            v[i] = g
        self.gear, self.u_prev = g, prev
        a = np.exp(-dt / 0.8)
        w = signal.lfilter([1 - a], [1, -a], np.r_[v[0], v[:-1]], zi=[a * v[0]])[0]
        return 0.8 * w - 0.1 * w ** 3



# the Backlash-Inverse plant of :class:`_InverseRig` as an hwid model
INVERSE = {"kind": "hammerstein_wiener",
           "input_nonlinearity": {"type": "backlash_inverse", "slope_up": 1.0, "slope_down": 1.3,
                                  "d_plus": 0.2, "d_minus": -0.3},
           "linear": {"num": [1.0], "den": [0.8, 1.0]},
           "output_nonlinearity": {"polynomial": [0, 0.8, 0, -0.1]},
           "noise": {"std": _InverseRig.NOISE}}


def bowed_apart_inverse(u, dt):
    """The Backlash-Inverse plant with each branch of its direction map bowed away from the other
    by ``0.1 (1 - (u / 1.5)^2)`` (a parabola, most at u = 0, none at the range's ends): the jump
    between the branches is 0.2 larger in the middle and 0.13 larger on average, which no bend
    that keeps the mean jump reaches. State carried over."""
    if "bowed_apart_inverse" not in _RIGS:
        _RIGS["bowed_apart_inverse"] = _InverseRig(zlib.crc32(b"bowed_apart_inverse"))
    r = _RIGS["bowed_apart_inverse"]
    u = np.asarray(u, float)
    bow = TRUTH["bowed_apart_inverse"]["bow"] * (1.0 - (np.clip(u, -1.5, 1.5) / 1.5) ** 2)
    return r.inverse(u, dt, bow) + r.NOISE * r.rng.standard_normal(u.size)


def rate_limit_inverse(u, dt, name: str = "rate_limit_inverse"):
    """A fast actuator (5.6 units/s, carried over) before a Backlash-Inverse gear."""
    if name not in _RIGS:
        _RIGS[name] = _InverseRig(zlib.crc32(name.encode()))
    r = _RIGS[name]
    u = np.asarray(u, float)
    step = TRUTH[name]["rate"] * dt
    ua = np.empty_like(u)
    p = u[0] if r.actuator is None else r.actuator
    for i, ui in enumerate(u):
        p += min(max(ui - p, -step), step)
        ua[i] = p
    r.actuator = p
    return r.inverse(ua, dt) + r.NOISE * r.rng.standard_normal(u.size)


def rate_limit_inverse_moderate(u, dt):
    """The same at 1.5 units/s: the lead-ins' holds still bring it where each experiment starts,
    but not a jump between two experiments without one (the multisines)."""
    return rate_limit_inverse(u, dt, "rate_limit_inverse_moderate")


class _PaperRig(_Rig):
    """The paper's plant: a backlash (play 0.5 each side, unit slopes), ``G(s) = 0.2/(s^2 + 0.7 s +
    0.1)``, ``h(w) = 0.25 w - 0.42 w^3 + 0.2 w^5`` (not monotone, steep beyond |w| = 1.3), white
    noise 0.01; gear and G's state carry over from call to call."""

    def __init__(self, seed: int):
        super().__init__(seed)
        self.state = None

    def paper(self, u, dt):
        v = self.gear_out(u, 0.5)
        A, B, C, D, _ = signal.cont2discrete(signal.tf2ss([0.2], [1.0, 0.7, 0.1]), dt, method="zoh")
        x = np.linalg.solve(np.eye(2) - A, B[:, 0] * v[0]) if self.state is None else self.state
        w = np.empty_like(v)
        for i, vi in enumerate(v):
            w[i] = float(C[0] @ x + D[0, 0] * vi)
            x = A @ x + B[:, 0] * vi
        self.state = x
        return 0.25 * w - 0.42 * w ** 3 + 0.2 * w ** 5


def input_saturation_paper(u, dt):
    """The paper's plant behind an actuator that clips u to [-1.23, 0.73]."""
    if "input_saturation_paper" not in _RIGS:
        _RIGS["input_saturation_paper"] = _PaperRig(zlib.crc32(b"input_saturation_paper"))
    r = _RIGS["input_saturation_paper"]
    t = TRUTH["input_saturation_paper"]
    u = np.clip(np.asarray(u, float), t["u_lo"], t["u_hi"])
    return r.paper(u, dt) + r.noise(u.size)



def input_deadzone_paper(u, dt):
    """The paper's plant behind an actuator that does not move for |u| < 0.21: the play of 0.5
    each side spans zero, so every border, read against u, has a flat step in it."""
    if "input_deadzone_paper" not in _RIGS:
        _RIGS["input_deadzone_paper"] = _PaperRig(zlib.crc32(b"input_deadzone_paper"))
    r = _RIGS["input_deadzone_paper"]
    dz = TRUTH["input_deadzone_paper"]["delta"]
    u = np.asarray(u, float)
    return r.paper(np.sign(u) * np.maximum(np.abs(u) - dz, 0.0), dt) + r.noise(u.size)


def sensor_saturation_paper(u, dt):
    """The paper's plant behind a sensor that reads y clipped to [-1.3, 1.3], its rails exactly (an
    ADC's end codes): the ascending staircase's horizontal path from u = -1.4 (h = -1.78 there)
    and the amplitude-1 sines' peaks read the rails."""
    if "sensor_saturation_paper" not in _RIGS:
        _RIGS["sensor_saturation_paper"] = _PaperRig(zlib.crc32(b"sensor_saturation_paper"))
    r = _RIGS["sensor_saturation_paper"]
    t = TRUTH["sensor_saturation_paper"]
    return np.clip(r.paper(np.asarray(u, float), dt) + r.noise(len(u)), t["y_lo"], t["y_hi"])


def paper_kept(u, dt):
    """The paper's plant on a rig never stopped: gear and G's state carry over from call to call."""
    if "paper_kept" not in _RIGS:
        _RIGS["paper_kept"] = _PaperRig(zlib.crc32(b"paper_kept"))
    r = _RIGS["paper_kept"]
    return r.paper(np.asarray(u, float), dt) + r.noise(len(u))


def paper_at_rest(u, dt):
    """The paper's plant on a rig parked between calls: at every call the gear rests against a
    border at ``u[0]`` drawn at random and G is at rest there (nothing carried over)."""
    if "paper_at_rest" not in _RIGS:
        _RIGS["paper_at_rest"] = _PaperRig(zlib.crc32(b"paper_at_rest"))
    r = _RIGS["paper_at_rest"]
    u = np.asarray(u, float)
    r.gear = float(u[0] + 0.5 * r.rng.choice([-1.0, 1.0]))
    r.state = None
    return r.paper(u, dt) + r.noise(u.size)


def clip_between_lags(u, dt):
    """The paper's plant with its G split into its two lags, ``1/(2s+1)`` then ``2/(5s+1)``, and a
    clip at +-0.5 between them (a current limit inside a motor's drive, say): no catalogue effect,
    and at rest the same as a bend of the borders. State carried over."""
    if "clip_between_lags" not in _RIGS:
        r = _RIGS["clip_between_lags"] = _PaperRig(zlib.crc32(b"clip_between_lags"))
        r.lags = None
    r = _RIGS["clip_between_lags"]
    u = np.asarray(u, float)
    v = r.gear_out(u, 0.5)
    a1, a2 = np.exp(-dt / 2.0), np.exp(-dt / 5.0)
    x1, x2 = r.lags if r.lags is not None else (v[0], 2.0 * float(np.clip(v[0], -0.5, 0.5)))
    w = np.empty_like(v)
    for i, vi in enumerate(v):
        w[i] = x2
        c = min(max(x1, -0.5), 0.5)
        x1 = a1 * x1 + (1 - a1) * vi
        x2 = a2 * x2 + (1 - a2) * 2.0 * c
    r.lags = (x1, x2)
    return 0.25 * w - 0.42 * w ** 3 + 0.2 * w ** 5 + r.noise(u.size)


# ------------------------------------------------------------------ effects after the gear (issue 48)

TRUTH["friction"] = {"coulomb": -0.12, "pre_sliding": 0.05, "viscous": 0.0}
TRUTH["friction_damper"] = {"coulomb": 0.15, "pre_sliding": 0.03, "viscous": 0.1}
TRUTH["output_hysteresis"] = {"width": 0.2, "weight": 0.7}


def _zoh(dt, num=(2.0,), den=(1.0, 3.0, 2.0)):
    b, a, _ = signal.cont2discrete((list(num), list(den)), dt, method="zoh")[:3]
    return np.ravel(b), a


def _base_g_h(v, dt) -> np.ndarray:
    """:data:`BASE`'s G (from rest at ``v[0]``) and h, driven by the gear's output ``v``."""
    b, a = _zoh(dt)
    zi = signal.lfiltic(b, a, y=[v[0]] * (len(a) - 1), x=[v[0]] * (len(b) - 1))
    w = signal.lfilter(b, a, v, zi=zi)[0]
    return w - 0.1 * w ** 3


def _carried_g(r, u, dt):
    """The base plant's G driven by the gear's output (play 0.3), its state carried over between calls
    (from rest at the first call's input)."""
    v = r.gear_out(u, 0.3)
    b, a = _zoh(dt)
    zi = getattr(r, "zi", None)
    if zi is None:
        zi = signal.lfiltic(b, a, y=[v[0]] * (len(a) - 1), x=[v[0]] * (len(b) - 1))
    w, r.zi = signal.lfilter(b, a, v, zi=zi)
    return w


def _friction_rig(name: str, u, dt):
    """The base plant with a Dahl friction force on the gear's output side: G is driven by
    ``v + coulomb z + viscous dv/dt``, ``dz/dv = (1 - z sgn dv) / pre_sliding`` (solved exactly over
    each sample's move), the gear, the friction state and G's state carried over between calls."""
    t = TRUTH[name]
    r = _rig(name)
    u = np.asarray(u, float)
    v = r.gear_out(u, 0.3)
    z = getattr(r, "z", 0.0)
    prev = getattr(r, "v_last", v[0])
    drive = np.empty_like(v)
    for k, vk in enumerate(v):
        dv = vk - prev
        if dv != 0.0:
            s = 1.0 if dv > 0 else -1.0
            z = s + (z - s) * math.exp(-abs(dv) / t["pre_sliding"])
        drive[k] = vk + t["coulomb"] * z + t["viscous"] * dv / dt
        prev = vk
    r.z, r.v_last = z, prev
    b, a = _zoh(dt)
    zi = getattr(r, "zi", None)
    if zi is None:
        zi = signal.lfiltic(b, a, y=[drive[0]] * (len(a) - 1), x=[drive[0]] * (len(b) - 1))
    w, r.zi = signal.lfilter(b, a, drive, zi=zi)
    return w - 0.1 * w ** 3 + r.noise(u.size)


def friction(u, dt):
    """Friction holding the load back (a position behind a compliant drive): ``coulomb < 0``."""
    return _friction_rig("friction", u, dt)


def friction_damper(u, dt):
    """Friction adding to the output in the direction of motion (a force at the driven shaft), with
    a viscous part."""
    return _friction_rig("friction_damper", u, dt)


def output_hysteresis(u, dt):
    """The base plant with a rate-independent hysteresis between G and h: four plays of
    half-widths ``width k / 4`` averaged, mixed with ``weight``; plays and G carried over."""
    t = TRUTH["output_hysteresis"]
    r = _rig("output_hysteresis")
    u = np.asarray(u, float)
    w = _carried_g(r, u, dt)
    plays = getattr(r, "plays", None) or [float(w[0])] * 4
    out = np.empty_like(w)
    for k, wk in enumerate(w):
        for j in range(4):
            half = t["width"] * (j + 1) / 4
            plays[j] = min(max(plays[j], wk - half), wk + half)
        out[k] = (1 - t["weight"]) * wk + t["weight"] * sum(plays) / 4
    r.plays = plays
    return out - 0.1 * out ** 3 + r.noise(u.size)


TRUTH["friction_on_load"] = {"coulomb": 0.08, "pre_sliding": 0.02, "viscous": 0.1}
#: a Prandtl-Ishlinskii operator of three unequal plays beside a linear part, between G and h
PI_PLAYS = {"radii": (0.05, 0.12, 0.2), "weights": (0.2, 0.3, 0.5), "through_plays": 0.6}
#: the operator's loop half-height on a move far beyond its widest play: sum(weights * radii) * share
PI_HALF_HEIGHT = PI_PLAYS["through_plays"] * sum(r * p for r, p in zip(PI_PLAYS["radii"], PI_PLAYS["weights"]))
#: substeps of the friction rig's integration per sample
SUBSTEPS = 40


def friction_on_load(u, dt):
    """The base plant with a Dahl friction force on the load, fed back: G's input is
    ``v - coulomb z - viscous dw/dt``, ``w`` G's output (the load's position), ``dz/dw = (1 - z sgn
    dw) / pre_sliding``. Integrated over :data:`SUBSTEPS` substeps per sample (G's state exact over
    each substep for the force held there, the force from the substep's start), everything carried
    over between calls."""
    t = TRUTH["friction_on_load"]
    r = _rig("friction_on_load")
    u = np.asarray(u, float)
    v = r.gear_out(u, 0.3)
    h = dt / SUBSTEPS
    A = np.array([[-3.0, -2.0], [1.0, 0.0]])
    B = np.array([1.0, 0.0])
    C = np.array([0.0, 2.0])
    Ad, Bd = _expm_pair(A, B, h)
    x = getattr(r, "x", None)
    if x is None:
        x = np.linalg.solve(A, -B) * v[0]
    z = getattr(r, "z", 0.0)
    out = np.empty_like(v)
    for k, vk in enumerate(v):
        out[k] = C @ x
        for _ in range(SUBSTEPS):
            w0 = C @ x
            wdot = C @ (A @ x)          # C B = 0: the velocity does not depend on the force
            x = Ad @ x + Bd * (vk - t["coulomb"] * z - t["viscous"] * wdot)
            dw = C @ x - w0
            if dw != 0.0:
                sg = 1.0 if dw > 0 else -1.0
                z = sg + (z - sg) * math.exp(-abs(dw) / t["pre_sliding"])
    r.x, r.z = x, z
    return out - 0.1 * out ** 3 + r.noise(u.size)


def _expm_pair(A, B, h):
    from scipy.linalg import expm
    n = A.shape[0]
    M = np.zeros((n + 1, n + 1))
    M[:n, :n], M[:n, n] = A, B
    E = expm(M * h)
    return E[:n, :n], E[:n, n]


def output_hysteresis_pi(u, dt):
    """The base plant with :data:`PI_PLAYS` between G and h: three plays of unequal weights beside
    a linear part; plays and G carried over."""
    r = _rig("output_hysteresis_pi")
    u = np.asarray(u, float)
    w = _carried_g(r, u, dt)
    plays = getattr(r, "plays", None) or [float(w[0])] * 3
    share = PI_PLAYS["through_plays"]
    out = np.empty_like(w)
    for k, wk in enumerate(w):
        acc = 0.0
        for j, (rad, p) in enumerate(zip(PI_PLAYS["radii"], PI_PLAYS["weights"])):
            plays[j] = min(max(plays[j], wk - rad), wk + rad)
            acc += p * plays[j]
        out[k] = (1 - share) * wk + share * acc
    r.plays = plays
    return out - 0.1 * out ** 3 + r.noise(u.size)


# ------------------------------------------------------------------ a plant that changes once (issue 47)

#: the gain step of :func:`gain_step`: G's gain times ``factor`` from call ``after_calls`` on (0-based)
GAIN_STEP = {"after_calls": 2, "factor": 1.6}


def gain_step(u, dt):
    """The plain base plant whose G's gain steps once, by :data:`GAIN_STEP` ``factor``, at the
    start of call ``after_calls``: a plant that changed mid-session (a load added, a supply
    switched), not an effect of the catalogue. The gear and the call count carry over."""
    r = _rig("gain_step")
    u = np.asarray(u, float)
    calls = getattr(r, "calls", 0)
    r.calls = calls + 1
    v = r.gear_out(u, 0.3)
    gain = GAIN_STEP["factor"] if calls >= GAIN_STEP["after_calls"] else 1.0
    b, a = _zoh(dt, num=(2.0 * gain,))
    zi = signal.lfiltic(b, a, y=[gain * v[0]] * (len(a) - 1), x=[v[0]] * (len(b) - 1))
    w = signal.lfilter(b, a, v, zi=zi)[0]
    return w - 0.1 * w ** 3 + r.noise(u.size)


# ------------------------------------------------------------------ cubic-bent borders (issue 47)

#: borders bent either way, by driver: ``(kappa_up, kappa_down, kind)`` of :func:`_cubic_gear`
CUBIC = {"cubic_in": (-0.15, -0.15, "own"), "cubic_in_weak": (-0.07, -0.07, "own"),
         "cubic_in_strong": (-0.19, -0.19, "own"), "cubic_out": (0.15, 0.15, "own"),
         "cubic_out_weak": (0.07, 0.07, "own"), "cubic_closing": (0.25, -0.25, "added"),
         "cubic_closing_strong": (0.29, -0.29, "added"), "cubic_opening": (-0.25, 0.25, "added"),
         "bow_in": (0.25, -0.25, "bow"), "bow_out": (-0.25, 0.25, "bow")}


def _cubic_gear(r: _Rig, u, play: float, bend: tuple):
    """The gear's position between two bent borders, carried over in ``r``. ``bend = (kappa_up,
    kappa_down, kind)``:

    * ``own``: each border a cubic of its own argument, ``(u - play) + kappa_up (u - play)^3`` and
      ``(u + play) + kappa_down (u + play)^3``; with ``kappa < 0`` both flatten towards the ends of
      the range and the play narrows there by ``|kappa| (6 play u^2 + 2 play^3)`` (bent inward),
      with ``kappa > 0`` they steepen and the play widens (outward);
    * ``added``: ``kappa u^3`` added to each straight border (opposite signs close the play at one
      end of the range and open it at the other);
    * ``bow``: ``kappa u^2`` added to each (opposite signs: the play narrows, or widens, towards
      both ends)."""
    ku, kd, kind = bend
    if kind == "own":
        lo, hi = (u - play) + ku * (u - play) ** 3, (u + play) + kd * (u + play) ** 3
    else:
        p = 3 if kind == "added" else 2
        lo, hi = (u - play) + ku * u ** p, (u + play) + kd * u ** p
    v = _play(r, lo, hi)
    return v


def _cubic_rig(name: str, u, dt):
    """The base plant whose borders are bent (:data:`CUBIC`, :func:`_cubic_gear`). On the working
    range [-1, 1] the borders stay monotone (``kappa > -1 / (3 * 1.3^2) = -0.197`` for cubics of
    their own arguments, ``|kappa| < 1/3`` for added cubics, ``< 1/2`` for bows) and never cross
    (``|kappa| < 0.3`` for opposed added cubics, 0.29 closing the play from 0.6 to 0.02 at the end
    where they meet; a bow of 0.25 narrows it to 0.1 at both ends)."""
    r = _rig(name)
    u = np.asarray(u, float)
    v = _cubic_gear(r, u, 0.3, CUBIC[name])
    return _base_g_h(v, dt) + r.noise(u.size)


# the drivers, one per bend of ``CUBIC`` (``plant.callable: diagnose_rigs:cubic_in``, ...)
for _name in ("cubic_closing", "cubic_opening", "cubic_in", "cubic_in_weak", "cubic_out", "cubic_out_weak",
              "cubic_in_strong", "cubic_closing_strong"):
    globals()[_name] = functools.partial(_cubic_rig, _name)


#: the Backlash-Inverse plant with cubic branches (levels -1.5 to 1.5): monotone there while
#: ``kappa > -1 / (3 * 1.7^2) = -0.115``
CUBIC.update({"inverse_cubic_in": (-0.1, -0.1, "own"), "inverse_cubic_out": (0.1, 0.1, "own")})


def _inverse_cubic(name: str, u, dt):
    """The Backlash-Inverse plant (:class:`_InverseRig`) whose branches are cubics of their own
    arguments: ``a + kappa a^3`` with ``a = u + 0.2`` rising, ``b + kappa b^3`` with
    ``b = u / 1.3 - 0.3`` falling (inward, ``kappa < 0``: the jump between them shrinks towards
    the ends of the range; outward, it grows)."""
    if name not in _RIGS:
        _RIGS[name] = _InverseRig(zlib.crc32(name.encode()))
    r = _RIGS[name]
    u = np.asarray(u, float)
    ku, kd, _ = CUBIC[name]
    shifts = (ku * (u + 0.2) ** 3, kd * (u / 1.3 - 0.3) ** 3)
    return r.inverse(u, dt, shifts=shifts) + r.NOISE * r.rng.standard_normal(u.size)


def inverse_cubic_in(u, dt):
    return _inverse_cubic("inverse_cubic_in", u, dt)


def inverse_cubic_out(u, dt):
    return _inverse_cubic("inverse_cubic_out", u, dt)


def bow_in(u, dt):
    return _cubic_rig("bow_in", u, dt)


def bow_out(u, dt):
    return _cubic_rig("bow_out", u, dt)


# ------------------------------------------------------------------ a load at its own frequency; a fast mode, a delay (issue 47)

#: a periodic load at G's input at its own frequency (rad/s; not a protocol sine's 0.5, 1, 2), its
#: amplitude at G's input (about 6x the noise at the output) and phase at the rig's time zero
PERIODIC_LOAD = {"omega": 1.45, "amp": 0.12, "phase": 0.7}
#: a lightly damped mode far above the sines' band (0.5-2 rad/s), and a pure delay (s)
FAST_MODE = {"omega_n": 14.0, "zeta": 0.03}
DELAY = {"delay_s": 0.2}


def periodic_load(u, dt):
    """The plain base plant with a sinusoidal load :data:`PERIODIC_LOAD` added to the gear's output
    (G's input), running in the rig's own time across calls: a disturbance at its own frequency,
    not an effect of the catalogue. Repeats of one input see it at different phases."""
    r = _rig("periodic_load")
    u = np.asarray(u, float)
    p = PERIODIC_LOAD
    t = r.t + np.arange(u.size) * dt
    r.t = float(t[-1] + dt) if u.size else r.t
    v = r.gear_out(u, 0.3) + p["amp"] * np.sin(p["omega"] * t + p["phase"])
    return _base_g_h(v, dt) + r.noise(u.size)


def fast_mode(u, dt):
    """G with a lightly damped mode :data:`FAST_MODE` (14 rad/s, zeta 0.03) above the band."""
    r = _rig("fast_mode")
    u = np.asarray(u, float)
    t = FAST_MODE
    return r.base(u, dt, mode=(t["omega_n"], t["zeta"])) + r.noise(u.size)


def pure_delay(u, dt):
    """The plain base plant whose output lags by :data:`DELAY` (whole samples at dt = 0.04 s: 5),
    the delay line carried over from call to call."""
    r = _rig("pure_delay")
    u = np.asarray(u, float)
    k = int(round(DELAY["delay_s"] / dt))
    x = r.base(u, dt)
    line = getattr(r, "line", None)
    line = np.full(k, x[0]) if line is None or line.size != k else line
    full = np.concatenate([line, x])
    r.line = full[full.size - k:]
    return full[:u.size] + r.noise(u.size)
