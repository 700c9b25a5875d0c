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

* ``keep`` - everything stays as the last call left it (gear, G's state, the sensor's lag, a delay
  line, hysteresis and friction states): the next call goes on from there, as a rig that is never
  stopped does;
* ``reset`` - every call starts from the rig's power-on state: the gear at zero, G at rest at zero
  input, the sensor's states at rest (a rig homed and switched off between calls);

and ``PARAMS["actuator"]`` (``carry`` or ``reset``) whether an actuator with memory (a rate limit)
starts where it was left or at the call's first input.

Between the parts of a lab session the rig is held at the last command (``pause``), unlogged.
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


def _lti_kept(num, den, x, dt, st, key, start=None, method="zoh"):
    """``_lti`` for a rig that keeps its state: the filter goes on from the state the last call left
    under ``key`` (the first call starts at rest at ``start`` or the first sample)."""
    b, a, _ = signal.cont2discrete((np.asarray(num, float), np.asarray(den, float)), dt, method=method)
    b, a = np.ravel(b), np.ravel(a)
    kept = st.get(key)
    if kept is not None and kept[0] == dt:
        zi = kept[1]
    else:
        x0 = x[0] if start is None else start
        g0 = np.polyval(num, 0.0) / np.polyval(den, 0.0)
        zi = signal.lfiltic(b, a, y=[g0 * x0] * (len(a) - 1), x=[x0] * (len(b) - 1))
    y, zf = signal.lfilter(b, a, x, zi=zi)
    st[key] = (dt, zf)
    return y


def _filter(num, den, x, dt, st, key, start, keep, method="zoh"):
    """G (or a sensor lag) over one call: from the kept state, or at rest at ``start`` / the first
    sample."""
    if keep:
        return _lti_kept(num, den, x, dt, st, key, start, method)
    return _lti(num, den, x, dt, method=method, start=start)


def _between_calls(p, st, u0, rng):
    """Put the gear where the rig's between-call behaviour leaves it; returns the input level at
    which G starts at rest (None: the call's first)."""
    how = p.get("between_calls", "carry")
    if how == "reset":
        st["gear"], st["u_prev"] = 0.0, 0.0
        return 0.0
    if how in ("carry", "keep") or p["F"]["type"] != "backlash":
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


def _plays(x, ep, st, how, seed):
    """Output hysteresis: ``linear`` x plus a weighted sum of play operators of half-widths
    ``widths`` (one play, or a Prandtl-Ishlinskii sum). Each play's output stays within +-r of its
    input and moves only when pushed; its state is kept between calls unless the rig resets (then
    centred on the first input) or is parked / left anywhere (at a random border / inside)."""
    r = np.asarray(ep["widths"], float)
    wts = np.asarray(ep["weights"], float)
    # its own random numbers: the rig's other draws (noise, parking) stay as without the effect
    rng = st.setdefault("rng_plays", np.random.default_rng(np.random.SeedSequence([seed, 1])))
    pos = st.get("plays")
    if pos is None or how == "reset":
        pos = np.full(r.size, x[0])
    elif how == "parked":
        pos = x[0] + r * (1.0 if rng.random() < 0.5 else -1.0)
    elif how == "anywhere":
        pos = x[0] + r * rng.uniform(-1.0, 1.0, r.size)
    pos = np.array(pos, float)
    out = np.empty((x.size, r.size))
    for i, xi in enumerate(x):
        pos = np.minimum(np.maximum(pos, xi - r), xi + r)
        out[i] = pos
    st["plays"] = pos
    return ep["linear"] * x + out @ wts


def _friction_g(num, den, v, dt, ep, st, start, keep):
    """G driven by the gear's output less a friction force opposing G's output velocity (the load
    shaft's friction referred to G's input, in the gear's units).

    The force is ``sigma0 z + sigma1 dz/dt + viscous * vel`` for a bristle deflection ``z`` with
    dz/dt = vel - |vel| z / z_ss(vel): Dahl's law (z_ss = z_c), LuGre's (z_ss = z_c (1 + (Fs/Fc - 1)
    exp(-(vel/v_s)^2)), a Stribeck dip), or no bristle and ``Fc tanh(vel / v_eps)`` (Coulomb made
    smooth). Within a sample the velocity is held and z integrated exactly (stable however stiff the
    bristles); G is stepped in state space with the force held over the sample (ZOH)."""
    A, B, C, _D = signal.tf2ss(np.asarray(num, float), np.asarray(den, float))
    Ad, Bd, _, _, _ = signal.cont2discrete((A, B, C, _D), dt, method="zoh")
    Bd, B, C = Bd[:, 0], B[:, 0], C[0]
    ca, cb = C @ A, float(C @ B)
    law, Fc, zc, visc = ep["law"], ep["coulomb"], ep["z_c"], ep["viscous"]
    sigma0 = Fc / zc
    sigma1 = ep.get("sigma1_dt", 0.0) * sigma0 * dt
    kept = st.get("fric") if keep else None
    if kept is not None and kept[0] == dt:
        x, z, u_prev = kept[1].copy(), kept[2], kept[3]
    else:
        level = v[0] if start is None else start
        x, z, u_prev = -np.linalg.solve(A, B * level), 0.0, level
    out = np.empty_like(v)
    for i, vi in enumerate(v):
        out[i] = C @ x
        vel = float(ca @ x) + cb * u_prev
        if law == "coulomb_tanh":
            force = Fc * np.tanh(vel / ep["v_eps"]) + visc * vel
        else:
            zss = zc
            if law == "lugre":
                zss = zc * (1.0 + (ep["stribeck"] - 1.0) * np.exp(-(vel / ep["v_s"]) ** 2))
            z_new = z
            if vel != 0.0:
                target = np.sign(vel) * zss
                z_new = target + (z - target) * np.exp(-abs(vel) * dt / zss)
            force = sigma0 * z_new + sigma1 * (z_new - z) / dt + visc * vel
            z = z_new
        u_prev = vi - force
        x = Ad @ x + Bd * u_prev
    st["fric"] = (dt, x, z, u_prev)
    return out


def _delay(w, k, st, how):
    """``w`` delayed by ``k`` samples (linear interpolation): before the call's first sample the
    signal stood at its first value, at rest (``reset``), or went on as the last call left it."""
    n = w.size
    if how == "keep" and "w_tail" in st:
        tail = st["w_tail"]
        ext = np.concatenate([tail, w])
        idx = np.arange(n) + tail.size - k
        out = np.interp(idx, np.arange(ext.size), ext, left=ext[0])
    else:
        out = np.interp(np.arange(n) - k, np.arange(n), w, left=w[0])
    if how == "keep":
        m = int(np.ceil(k)) + 2
        st["w_tail"] = np.concatenate([st.get("w_tail", w[:1]), w])[-m:]
    return out


def _actuator(u, p, st, dt):
    """The actuator's effect on the command (a clip, a slew-rate limit, a dead zone)."""
    e, ep = p["effect"], p.get("effect_params", {})
    if e == "input_saturation":
        u = np.minimum(np.maximum(u, ep["lo"]), ep["hi"])
    elif e == "rate_limit":
        r = ep["rate"] * dt
        pos = st.get("act", u[0]) if p.get("actuator", "carry") == "carry" else u[0]
        for i in range(u.size):
            pos += min(max(u[i] - pos, -r), r)
            u[i] = pos
        st["act"] = pos
    elif e == "input_deadzone":
        d = ep["delta"]
        u = np.where(np.abs(u) <= d, 0.0, u - d * np.sign(u))
    return u


def _dynamics(v, p, st, dt, w_start, how):
    """G (with a resonance, a saturation between its lags or friction on its output, as the effect
    says) and any delay after it: the gear's output ``v`` in, G's output ``w`` out."""
    e, ep = p["effect"], p.get("effect_params", {})
    keep, n = how == "keep", v.size
    num, den = list(p["G"]["num"]), list(p["G"]["den"])
    if e == "resonance":
        wn, z = ep["omega_n"], ep["zeta"]
        num, den = np.polymul(num, [wn * wn]), np.polymul(den, [1, 2 * z * wn, wn * wn])
    if e == "second_nonlinearity":
        # both lags start at rest at the call's first input (at zero for a rig that resets)
        rest = 0.0 if how == "reset" else None
        w1 = _filter(ep["num1"], ep["den1"], v, dt, st, "G1", rest, keep)
        w1 = ep["level"] * np.tanh(w1 / ep["level"])
        w = _filter(ep["num2"], ep["den2"], w1, dt, st, "G2", rest, keep)
    elif e == "friction":
        w = _friction_g(num, den, v, dt, ep, st, w_start, keep)
    else:
        w = _filter(num, den, v, dt, st, "G", w_start, keep)
    delay = p["G"].get("delay", 0.0) + (ep["delay"] if e == "time_delay" else 0.0)
    if delay > 0:
        if how == "keep":
            w = _delay(w, delay / dt, st, how)
        elif how == "reset":
            w = np.interp(np.arange(n) - delay / dt, np.arange(n), w, left=0.0)
        else:
            k = delay / dt
            idx = np.arange(n) - k
            w = np.interp(idx, np.arange(n), w, left=w[0])
    return w


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
    how = p.get("between_calls", "carry")
    t = st["t"] + np.arange(n) * dt
    u = _actuator(u, p, st, dt)
    w_start = _between_calls(p, st, float(u[0]), rng) if n else None
    v = _gear(u, {**p, "bow": ep if e == "curved_borders" else None}, st)
    # ------------------------------------------------------------ disturbances at G's input
    if e == "gain_step":
        v = v * np.where(t >= ep["at_s"], 1.0 + ep["step"], 1.0)
    if e == "periodic_load":
        v = v + ep["amp"] * np.sin(ep["omega"] * t + ep["phase"])
    w = _dynamics(v, p, st, dt, w_start, how)
    if e == "output_hysteresis" and ep["at"] == "w":
        w = _plays(w, ep, st, how, p["seed"])
    x = np.polyval(p["h"][::-1], w)
    if e == "output_hysteresis" and ep["at"] == "y":
        x = _plays(x, ep, st, how, p["seed"])
    # ------------------------------------------------------------ sensor and disturbances
    if e == "sensor_lag":
        rest = float(np.polyval(p["h"][::-1], 0.0)) if how == "reset" else None
        x = _filter([1.0], [ep["tau"], 1.0], x, dt, st, "lag", rest, how == "keep", method="bilinear")
    if e == "hysteretic_friction":
        y = np.empty_like(x)
        pos = x[0] if how == "reset" else st.get("shaft", x[0])
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


def pause(p: dict, st: dict, u_hold: float, seconds: float, dt: float) -> None:
    """The rig held at ``u_hold`` for ``seconds`` between two logged calls (a lab session's pause):
    its clock and states move on, nothing is logged."""
    n = int(round(seconds / dt))
    if n > 0:
        run(p, st, np.full(n, float(u_hold)), dt)
