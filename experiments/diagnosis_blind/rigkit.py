"""The blind experiment's rig simulator: written apart from hwid (numpy/scipy only, its own
discretisations) so the diagnoser's effect models are not the rigs' formulas.

A rig is ``PARAMS`` (base plant + one effect or none) and a mutable ``STATE`` carried from call to
call like a real machine's (gear position, drift, elapsed time, noise generator). What the rig does
between calls is ``PARAMS["between_calls"]``:

* ``carry`` - the gear stays where the last call left it (G always starts at rest at the call's
  first input, as a rig left standing between calls does);
* ``parked`` - the gear rests against one border at the call's first input, drawn at random at
  every call (parked, homed, moved by hand);
* ``anywhere`` - the gear at a random point inside the play and G at rest at a random level of the
  working range (a rig left mid-move);

and ``PARAMS["actuator"]`` (``carry`` or ``reset``) whether an actuator with memory (a rate limit)
starts where it was left or at the call's first input.
"""
from __future__ import annotations

import numpy as np
from scipy import signal


def _gear(u, p, st):
    """Backlash (play between two borders) or Backlash-Inverse (direction map), with optional
    curved borders (``bow``) -- the rig's own implementation."""
    F = p["F"]
    su, sd, dp, dm = F["slope_up"], F["slope_down"], F["d_plus"], F["d_minus"]
    bow = p.get("bow")
    out = np.empty_like(u)
    if F["type"] == "backlash":
        g = st.get("gear", 0.0)
        for i, ui in enumerate(u):
            lo, hi = su * (ui - dp), sd * (ui - dm)
            if bow is not None:
                lo += _bow(ui, bow, "up")
                hi += _bow(ui, bow, "down")
            g = min(max(g, lo), max(hi, lo))
            out[i] = g
        st["gear"] = g
    else:
        g = st.get("gear", 0.0)
        prev = st.get("u_prev", u[0])
        for i, ui in enumerate(u):
            if ui > prev:
                g = ui / su + dp + (_bow(ui, bow, "up") if bow else 0.0)
            elif ui < prev:
                g = ui / sd + dm + (_bow(ui, bow, "down") if bow else 0.0)
            prev = ui
            out[i] = g
        st["gear"], st["u_prev"] = g, prev
    return out


def _bow(u, bow, side):
    """A border bent over the working range (``s`` from 0 to 1 across it), shaped as the case says:
    a sine bow, a parabola, an odd cubic, an S-curve (tanh), one-sided stiffening (an exponential
    rising at one end) or a local bump (a Gaussian at a third of the range); each of unit size at
    its largest within the range, times ``k`` and the range's width."""
    k = bow[side]
    lo, hi = bow["range"]
    s = (u - lo) / (hi - lo)
    shape = bow["shape"]
    if shape == "sine":
        f = np.sin(np.pi * s)
    elif shape == "parabola":
        f = (2 * s - 1) ** 2
    elif shape == "cubic":
        f = (2 * s - 1) ** 3
    elif shape == "s_curve":
        f = np.tanh(3.0 * (2 * s - 1)) / np.tanh(3.0)
    elif shape == "one_sided":
        f = np.expm1(3.0 * s) / np.expm1(3.0)
    elif shape == "bump":
        f = np.exp(-((s - 1.0 / 3.0) / 0.2) ** 2)
    else:
        raise ValueError(f"unknown bow shape {shape!r}")
    return k * (hi - lo) * f


def _lti(num, den, x, dt, method="zoh", start=None):
    b, a, _ = signal.cont2discrete((np.asarray(num, float), np.asarray(den, float)), dt, method=method)
    b = np.ravel(b)
    a = np.ravel(a)
    # start at the equilibrium of the first sample, or of ``start``
    x0 = x[0] if start is None else start
    g0 = np.polyval(num, 0.0) / np.polyval(den, 0.0)
    zi = signal.lfiltic(b, a, y=[g0 * x0] * (len(a) - 1), x=[x0] * (len(b) - 1))
    return signal.lfilter(b, a, x, zi=zi)[0]


def _between_calls(p, st, u0, rng):
    """Put the gear (and G's starting level) where the rig's between-call behaviour leaves it."""
    how = p.get("between_calls", "carry")
    if how == "carry" or p["F"]["type"] != "backlash":
        return None
    F = p["F"]
    lo, hi = F["slope_up"] * (u0 - F["d_plus"]), F["slope_down"] * (u0 - F["d_minus"])
    lo, hi = min(lo, hi), max(lo, hi)
    if how == "parked":
        st["gear"] = float(lo if rng.random() < 0.5 else hi)
        return None
    st["gear"] = float(rng.uniform(lo, hi))
    return float(rng.uniform(F["slope_down"] * (min(p.get("levels", (u0, u0))) - F["d_minus"]),
                             F["slope_up"] * (max(p.get("levels", (u0, u0))) - F["d_plus"])))


def run(p: dict, st: dict, u, dt: float) -> np.ndarray:
    """One call of the rig: ``u`` (samples every ``dt`` s) in, measured ``y`` out."""
    u = np.asarray(u, float).copy()
    n = u.size
    if "rng" not in st:
        st["rng"] = np.random.default_rng(np.random.SeedSequence(p["seed"]))
        st["t"] = 0.0
        st["drift"] = 0.0
    rng = st["rng"]
    e, ep = p["effect"], p.get("effect_params", {})
    t = st["t"] + np.arange(n) * dt
    # ------------------------------------------------------------ actuator
    if e == "input_saturation":
        u = np.minimum(np.maximum(u, ep["lo"]), ep["hi"])
    elif e == "rate_limit":
        r = ep["rate"] * dt
        pos = st.get("act", u[0]) if p.get("actuator", "carry") == "carry" else u[0]
        for i in range(n):
            pos += min(max(u[i] - pos, -r), r)
            u[i] = pos
        st["act"] = pos
    elif e == "input_deadzone":
        d = ep["delta"]
        u = np.where(np.abs(u) <= d, 0.0, u - d * np.sign(u))
    w_start = _between_calls(p, st, float(u[0]), rng) if n else None
    v = _gear(u, {**p, "bow": ep if e == "curved_borders" else None}, st)
    # ------------------------------------------------------------ dynamics
    num, den = list(p["G"]["num"]), list(p["G"]["den"])
    if e == "resonance":
        wn, z = ep["omega_n"], ep["zeta"]
        num, den = np.polymul(num, [wn * wn]), np.polymul(den, [1, 2 * z * wn, wn * wn])
    if e == "second_nonlinearity":
        w1 = _lti(ep["num1"], ep["den1"], v, dt)
        w1 = ep["level"] * np.tanh(w1 / ep["level"])
        w = _lti(ep["num2"], ep["den2"], w1, dt)
    else:
        w = _lti(num, den, v, dt, start=w_start)
    delay = p["G"].get("delay", 0.0) + (ep["delay"] if e == "time_delay" else 0.0)
    if delay > 0:
        k = delay / dt
        idx = np.arange(n) - k
        w = np.interp(idx, np.arange(n), w, left=w[0])
    x = np.polyval(p["h"][::-1], w)
    # ------------------------------------------------------------ sensor and disturbances
    if e == "sensor_lag":
        x = _lti([1.0], [ep["tau"], 1.0], x, dt, method="bilinear")
    if e == "hysteretic_friction":
        y = np.empty_like(x)
        pos = st.get("shaft", x[0])
        for i in range(n):
            pos = min(max(pos, x[i] - ep["width"]), x[i] + ep["width"])
            y[i] = pos
        st["shaft"] = pos
        x = y
    if e == "gain_drift":
        x = x * (1 + ep["amp"] * np.sin(2 * np.pi * t / ep["period"] + ep["phase"]))
    noise = p["noise"]["std"] * rng.standard_normal(n)
    if p["noise"].get("ar", 0.0):
        a = p["noise"]["ar"]
        noise = signal.lfilter([np.sqrt(1 - a * a)], [1, -a], noise)
    y = x + noise
    if e == "drift":
        # an Ornstein-Uhlenbeck wander with a time constant of minutes, carried across calls
        tc, s = ep["time_s"], ep["std"]
        a = np.exp(-dt / tc)
        inc = s * np.sqrt(1 - a * a) * rng.standard_normal(n)
        dr = signal.lfilter([1.0], [1, -a], inc, zi=[a * st["drift"]])[0]
        st["drift"] = dr[-1]
        y = y + dr
    if e == "sensor_saturation":
        if ep.get("rail", "exact") == "noisy":     # the clip before the noise: the rails are noisy too
            y = np.minimum(np.maximum(y - noise, ep["lo"]), ep["hi"]) + noise
        else:
            y = np.minimum(np.maximum(y, ep["lo"]), ep["hi"])
    st["t"] = t[-1] + dt if n else st["t"]
    return y
