"""Friction on the load, fed back: G driven by the gear's output less a friction force that opposes
the LOAD's motion, the load's position being G's output ``w`` (the ``friction`` effect's
``fed_back`` form, :class:`hwid.diagnose.effects_after_gear.Friction`).

The law. G's input is ``v - coulomb z - viscous dw/dt``, ``z`` the Dahl state of the load's path
(Dahl 1968; 1976; Olsson, Astrom, Canudas de Wit, Gafvert, Lischinsky 1998, "Friction models and
friction compensation", eq. 7 with exponent 1)::

    dz/dw = (1 - z sgn(dw/dt)) / pre_sliding,

so ``coulomb z`` rises smoothly from 0 after a reversal with the bristle stiffness
``coulomb / pre_sliding`` (the pre-sliding regime) and saturates at the Coulomb level after a few
``pre_sliding`` of travel; ``viscous dw/dt`` is linear viscous friction. Forces are in the gear's
output units (G's input), ``pre_sliding`` in G's output units, ``viscous`` in the gear's units per
unit of ``dw/dt``; both forces with the sign that opposes the motion whatever G's sign
(``coulomb > 0``, ``viscous >= 0``: each enters G's input times ``sgn G(0)``).

The smooth Coulomb law. A regularised Coulomb force ``coulomb tanh(dw/dt / sliding_speed)``
(Andersson, Soderberg, Bjorklund 2007, "Friction models for sliding dry, boundary and mixed
lubricated contacts"; Makkar, Dixon, Sawyer, Hu 2005): no pre-sliding memory, the force falls to
zero as the load comes to rest, so a load at rest is not held off its equilibrium as a Dahl
bristle holds it. The two tell apart on the holds after each move: Dahl's load stops short and
stays, the smooth law's creeps on to where G alone would put it.

LuGre's Stribeck level. LuGre (Canudas de Wit, Olsson, Astrom, Lischinsky 1995) is Dahl's state
whose level depends on the speed: ``dz/dt = dw/dt - |dw/dt| z sigma0 / g(dw/dt)``, ``g`` the
Stribeck curve ``Fc + (Fs - Fc) exp(-(v / v_s)^2)``; in Coulomb levels the state rises towards
``g / Fc`` (up to ``stribeck = Fs / Fc`` at rest) over ``pre_sliding g / Fc`` of travel. Its bristle
damping ``sigma1 dz/dt`` acts only within the pre-sliding travel (``dz/dt`` vanishes in sliding),
here as ``bristle_damping = sigma1 / sigma0`` in seconds, the force ``coulomb (z +
bristle_damping dz/dt)``. Seen through G from ``u`` to ``y``, both shape the samples after each
reversal and each start from rest, and their identification usually needs the friction force at
the contact (Olsson et al. 1998, sect. 6): the Stribeck pair and the damping are growths of the
Dahl law (:class:`hwid.diagnose.effects_after_gear.LuGreFriction`), each kept only where the fit
experiments' criterion pays for its parameters, their intervals saying whether the data
determine them.

Numerics. G (viscous friction folded in exactly: ``G / (1 + viscous s G)``, a linear feedback of
the load's velocity) is stepped per sample in the exact ZOH recursion of
:mod:`hwid.blocks.linear`, the force held over each sample at the trapezoidal mean of the Dahl
state at the sample's two ends. The end state solves ``z' = Dahl(z, w'(z') - w)`` (``w'`` linear
in ``z'``), a scalar equation on [-1, 1] whose left side minus ``z'`` is monotone for a friction
that opposes the motion: bisection finds its root to rounding. Implicit, the step is stable for
any bristle stiffness (a stiff pre-sliding in an explicit step rings at the Nyquist rate).
G's delay is taken to sit at its input (an actuator's dead time): the gear's output is delayed,
the friction acts on the load at once.
"""
from __future__ import annotations

from functools import lru_cache

import numpy as np
from numba import njit

from hwid.blocks.linear import LinearBlock, discretise, unit_rest

#: the most regula-falsi steps of the implicit Dahl state per sample (a handful reach rounding)
BISECTION_STEPS = 50


@njit(cache=True)
def _dahl_step(z, dw, x_pre):
    """Dahl's state after a move ``dw`` from ``z`` (exact for a monotone move)."""
    if dw > 0.0:
        return 1.0 + (z - 1.0) * np.exp(-dw / x_pre)
    if dw < 0.0:
        return -1.0 + (z + 1.0) * np.exp(dw / x_pre)
    return z


@njit(cache=True)
def _law(z, dw, x_pre, smooth, fs, vs_dt):
    """The law's state after a move ``dw`` over one sample: Dahl's (:func:`_dahl_step`); with a
    Stribeck level ``fs > 1`` (in Coulomb levels, at the speed ``vs_dt / dt``) LuGre's state, which
    rises towards ``r = 1 + (fs - 1) exp(-(dw / vs_dt)^2)`` over ``x_pre r`` of travel (exact for a
    constant speed over the sample); for the smooth Coulomb law ``tanh(dw / x_pre)``, ``x_pre``
    then the sliding speed times dt."""
    if smooth:
        return np.tanh(dw / x_pre)
    if fs == 1.0 or dw == 0.0:
        return _dahl_step(z, dw, x_pre)
    q = dw / vs_dt
    r = 1.0 + (fs - 1.0) * np.exp(-q * q)
    if dw > 0.0:
        return r + (z - r) * np.exp(-dw / (x_pre * r))
    return -r + (z + r) * np.exp(dw / (x_pre * r))


@njit(cache=True)
def _root(z, a, g, x_pre, smooth, fs, vs_dt):
    """The root on [-fs, fs] of ``law(z, a + g z1) - z1`` (regula falsi, Illinois' variant, kept
    within its bracket: ``f(-fs) >= 0 >= f(fs)`` always, the law's state being in [-fs, fs])."""
    lo, hi = -fs, fs
    flo = _law(z, a + g * lo, x_pre, smooth, fs, vs_dt) - lo
    fhi = _law(z, a + g * hi, x_pre, smooth, fs, vs_dt) - hi
    if flo <= 0.0:
        return lo
    if fhi >= 0.0:
        return hi
    side = 0
    z1 = 0.0
    for _ in range(BISECTION_STEPS):
        z1 = (lo * fhi - hi * flo) / (fhi - flo)
        if not (lo < z1 < hi):
            z1 = 0.5 * (lo + hi)
        f = _law(z, a + g * z1, x_pre, smooth, fs, vs_dt) - z1
        if f == 0.0 or hi - lo < 1e-15:
            return z1
        if f > 0.0:
            lo, flo = z1, f
            if side == 1:
                fhi *= 0.5
            side = 1
        else:
            hi, fhi = z1, f
            if side == -1:
                flo *= 0.5
            side = -1
        if abs(f) < 1e-15:
            return z1
    return z1


@njit(cache=True)
def _fed_back_run(vd, Phi, G1, G0, C, D, x0, v_prev, coulomb, x_pre, d_prev, smooth, fs, vs_dt, damp_dt, z0):
    """The ZOH recursion of G with the Dahl force fed back; ``vd`` the delayed gear output, G0 the
    fractional delay's share of the previous sample (zero without one); ``d_prev``: G's direct
    term sees the sample before (a fractional delay holds it at the sampling instant); ``smooth``:
    the smooth Coulomb law, its force ``coulomb tanh(mean velocity / speed)`` held over the sample,
    in place of Dahl's trapezoidal mean; ``damp_dt``: LuGre's bristle damping over dt, its force
    ``coulomb damp_dt (z1 - z)`` over the sample. Returns ``w``."""
    al = 0.0 if smooth else 0.5 - damp_dt     # the force over a sample: coulomb (al z + be z1)
    be = 1.0 if smooth else 0.5 + damp_dt
    n = vd.shape[0]
    m = x0.shape[0]
    w = np.empty(n)
    x = x0.copy()
    base = np.empty(m)
    gam = np.empty(m)
    for i in range(m):
        gam[i] = G1[i] + G0[i]
    cg = 0.0
    for i in range(m):
        cg += C[i] * gam[i]
    z = z0
    vp = v_prev
    w[0] = D * (vd[0] - coulomb * z0)
    for i in range(m):
        w[0] += C[i] * x[i]
    for k in range(n - 1):
        # x_{k+1} = base - gam coulomb (z + z1)/2 ; w_{k+1} = a + g z1
        for i in range(m):
            s = G1[i] * vd[k] + G0[i] * vp
            for j in range(m):
                s += Phi[i, j] * x[j]
            base[i] = s - gam[i] * coulomb * al * z
        a = D * (vd[k] if d_prev else vd[k + 1])
        for i in range(m):
            a += C[i] * base[i]
        g = -be * coulomb * cg - D * coulomb
        z1 = _root(z, a - w[k], g, x_pre, smooth, fs, vs_dt)
        for i in range(m):
            x[i] = base[i] - gam[i] * coulomb * be * z1
        z = z1
        w[k + 1] = a + g * z1
        vp = vd[k]
    return w


def with_viscous(G: LinearBlock, viscous: float) -> LinearBlock:
    """``G / (1 + b s G)``, ``b = viscous sgn G(0)``: G with a viscous force on its output's velocity
    fed back to its input (opposing the motion for ``viscous > 0``), without G's delay (which sits
    at the input, :func:`fed_back_response`)."""
    b = float(viscous) * (1.0 if G.dc_gain >= 0 else -1.0)
    num = np.asarray(G.num, float)
    den = np.asarray(G.den, float)
    if b != 0.0:
        sn = np.concatenate([num, [0.0]]) * b
        n = max(den.size, sn.size)
        den = np.concatenate([np.zeros(n - den.size), den]) + np.concatenate([np.zeros(n - sn.size), sn])
    return LinearBlock(tuple(num), tuple(den), 0.0)


@lru_cache(maxsize=1024)
def _made_unstable(den: tuple, den_viscous: tuple) -> bool:
    """Whether the viscous feedback puts a pole of a stable G in the closed right half-plane."""
    return bool(np.any(np.roots(den_viscous).real >= 0.0) and not np.any(np.roots(den).real >= 0.0))


def fed_back_response(G: LinearBlock, v, dt: float, coulomb: float, pre_sliding: float, viscous: float,
                      rest: float | None = None, sliding_speed: float | None = None, stribeck: float = 1.0,
                      stribeck_speed: float = 1.0, bristle_damping: float = 0.0, memory: float = 0.0) -> np.ndarray:
    """G's output ``w`` driven by ``v - coulomb z(w) - viscous dw/dt`` (module docstring), from rest
    at the input level ``rest`` (default ``v[0]``) with no friction force (``z = 0``); with
    ``sliding_speed``, the smooth Coulomb law ``z = tanh(dw/dt / sliding_speed)`` in place of
    Dahl's (``pre_sliding`` unused); with ``stribeck > 1``, LuGre's Stribeck level (in Coulomb
    levels) at low speed, falling to the Coulomb level over ``stribeck_speed`` (G's output units per
    s); ``bristle_damping`` (s), LuGre's ``sigma1`` over ``sigma0``: the force
    ``coulomb (z + bristle_damping dz/dt)``. ``memory``: the friction state at the start (in
    Coulomb levels; 0: none), G then at rest under the input less that force (a load held off its
    equilibrium by the friction, as a rig left at rest after a move). Where the
    viscous feedback leaves G unstable (a G whose phase lets ``s G`` reach -1), a constant far
    beyond the data (1e6 times the input's size): a fit never picks it."""
    v = np.ascontiguousarray(v, dtype=float)
    if v.size == 0:
        return v.copy()
    coulomb = float(coulomb) * (1.0 if G.dc_gain >= 0 else -1.0)      # opposing the motion
    Gv = with_viscous(G, viscous)
    start = float(v[0]) if rest is None else float(rest)
    if _made_unstable(tuple(map(float, G.den)), tuple(map(float, Gv.den))):
        return np.full(v.size, 1e6 * (1.0 + float(np.max(np.abs(v)))))
    key = (tuple(map(float, Gv.num)), tuple(map(float, Gv.den)), float(G.delay), float(dt))
    n, lag, frac, Phi, G1, G0, C, D = discretise(*key)
    k = min(lag, v.size)
    vd = np.concatenate([np.full(k, start), v[: v.size - k]]) if lag else v
    if n == 0:      # a static G: w = D (v - coulomb z(w)) solved sample by sample as a one-state G would be
        Phi, G1, G0, C = np.zeros((0, 0)), np.zeros(0), np.zeros(0), np.zeros(0)
    smooth = sliding_speed is not None
    z0 = 0.0 if smooth else float(np.clip(memory, -max(float(stribeck), 1.0), max(float(stribeck), 1.0)))
    x0 = unit_rest(key[0], key[1]) * (start - float(coulomb) * z0) if n else np.zeros(0)
    scale = float(sliding_speed) * dt if smooth else float(pre_sliding)
    return _fed_back_run(vd, np.ascontiguousarray(Phi), np.ascontiguousarray(G1), np.ascontiguousarray(G0),
                         np.ascontiguousarray(C, dtype=float), float(D), np.ascontiguousarray(x0, dtype=float),
                         start, float(coulomb), max(float(scale), 1e-300), frac != 0.0, smooth,
                         max(float(stribeck), 1.0), max(float(stribeck_speed), 1e-300) * dt,
                         max(float(bristle_damping), 0.0) / dt, z0)
