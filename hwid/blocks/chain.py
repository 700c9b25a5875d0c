"""The F -> G -> h chain of eqs. (3a-c) in one pass over the samples, with the noise of ``y = x + xi``.

Three passes (the operator, the linear recursion, the polynomial) and the noise each read and write
every sample; :func:`run_chain` does them block by block (:data:`BLOCK` samples, which stay in the
L1 cache), with the same arithmetic, in the same order, as :func:`hwid.blocks.backlash._play` /
``_direction_map``, :func:`hwid.blocks.linear._ss_run` and :func:`hwid.blocks.static.horner_into`,
so its output is bit-identical to theirs. In a block, F and G's recursion run in one loop, then h
by Horner over the block (SIMD), then the noise. For a G of one or two states the state lives in
registers (:func:`_fg_one`, :func:`_fg_two`): a loop over a state array waits on memory at every
sample (about 9 ns a sample instead of 3 for the paper's second-order G). The kernel covers the
common case (no delay, polynomial h); :meth:`hwid.model.HWModel.simulate` uses the three passes
otherwise.

numba's cache keys a kernel on its own file only: after an edit to ``horner_into`` or
:func:`hwid.blocks.noise.add_white`, delete ``hwid/blocks/__pycache__`` or :func:`run_chain`
keeps running the old code.
"""
from __future__ import annotations

import numpy as np
from numba import njit

from hwid.blocks.noise import add_white
from hwid.blocks.static import horner_into

#: Samples per block: v, w, x and y of a block fit in the L1 cache together.
BLOCK = 512


@njit(cache=True)
def _f(uk, up, prev, inverse, a_up, b_up, a_dn, b_dn):
    """F at a sample of input ``uk`` from its output ``prev`` at the sample before, of input ``up``:
    the play of eq. (1) between the borders ``a_up (u - b_up)`` and ``a_dn (u - b_dn)``, or
    (``inverse``) the direction map of eq. (2), ``a_up u + b_up`` while u rises, ``a_dn u + b_dn``
    while it falls (``up = uk`` at the first sample: held)."""
    if inverse:
        du = uk - up
        if du > 0.0:
            return a_up * uk + b_up
        if du < 0.0:
            return a_dn * uk + b_dn
        return prev
    lo = a_up * (uk - b_up)
    hi = a_dn * (uk - b_dn)
    if prev < lo:
        return lo
    if prev > hi:
        return hi
    return prev


@njit(cache=True)
def _fg_one(u, up, f, prev, vp, state, Phi, G1, G0, C, D, v, w):
    """Eqs. (3a-b) on a block for a G with one state s: ``v = F[u]``, ``w = C s + D v``,
    ``s <- Phi s + Gamma1 v + Gamma0 v_prev``. ``f``: F's parameters (:func:`_f`); ``up``, ``prev``
    and ``vp``: F's input and output and G's input before the block. Returns F's last output;
    ``state`` is updated in place."""
    s0 = state[0]
    p00, g10, g00, c0 = Phi[0, 0], G1[0], G0[0], C[0]
    for k in range(u.shape[0]):
        prev = _f(u[k], up, prev, *f)
        up = u[k]
        v[k] = prev
        acc = D * prev
        acc += c0 * s0
        w[k] = acc
        n0 = g10 * prev + g00 * vp
        n0 += p00 * s0
        s0 = n0
        vp = prev
    state[0] = s0
    return prev


@njit(cache=True)
def _fg_two(u, up, f, prev, vp, state, Phi, G1, G0, C, D, v, w):
    """:func:`_fg_one` for a G with two states."""
    s0, s1 = state[0], state[1]
    p00, p01, p10, p11 = Phi[0, 0], Phi[0, 1], Phi[1, 0], Phi[1, 1]
    g10, g11, g00, g01, c0, c1 = G1[0], G1[1], G0[0], G0[1], C[0], C[1]
    for k in range(u.shape[0]):
        prev = _f(u[k], up, prev, *f)
        up = u[k]
        v[k] = prev
        acc = D * prev
        acc += c0 * s0
        acc += c1 * s1
        w[k] = acc
        n0 = g10 * prev + g00 * vp
        n0 += p00 * s0
        n0 += p01 * s1
        n1 = g11 * prev + g01 * vp
        n1 += p10 * s0
        n1 += p11 * s1
        s0, s1 = n0, n1
        vp = prev
    state[0], state[1] = s0, s1
    return prev


@njit(cache=True)
def _fg_any(u, up, f, prev, vp, state, Phi, G1, G0, C, D, v, w):
    """:func:`_fg_one` for a G with any number of states."""
    m = state.shape[0]
    nxt = np.empty(m)
    for k in range(u.shape[0]):
        prev = _f(u[k], up, prev, *f)
        up = u[k]
        v[k] = prev
        acc = D * prev
        for i in range(m):
            acc += C[i] * state[i]
        w[k] = acc
        for i in range(m):
            t = G1[i] * prev + G0[i] * vp
            for j in range(m):
                t += Phi[i, j] * state[j]
            nxt[i] = t
        for i in range(m):
            state[i] = nxt[i]
        vp = prev
    return prev


@njit(cache=True)
def run_chain(u, inverse, a_up, b_up, a_dn, b_dn, state0, Phi, G1, G0, C, D, x0, coef, rng, std, v, w, x, y):
    """Fill ``v = F[u]``, ``w = G * v``, ``x = h(w)`` (eqs. 3a-c) and, given a generator ``rng``,
    ``y = x + std e`` with ``e`` the generator's next ``n`` standard normal draws, so ``y`` is
    bit-identical to ``x + std * rng.standard_normal(n)``; ``rng = None`` leaves ``y`` alone.

    ``inverse = False``: the Backlash of eq. (1) with borders ``a_up (u - b_up)`` (ascending) and
    ``a_dn (u - b_dn)`` (descending) and gear position ``state0`` before the first sample;
    ``inverse = True``: the direction map of eq. (2), ``a_up z + b_up`` rising, ``a_dn z + b_dn``
    falling, output ``state0`` held at the first sample. ``Phi, G1, G0, C, D, x0``: G's sampled
    recursion and initial state (:func:`hwid.blocks.linear.discretise`); ``coef``: h's
    ascending-power coefficients; ``n >= 1`` samples. The outputs are the caller's arrays (numpy
    backs large ones with huge pages; numba's own allocations page-fault every 4 KiB). The blocks
    are slices, indexed from 0, so numba needs no negative-index wraparound and the loops vectorise."""
    n = u.shape[0]
    f = (inverse, a_up, b_up, a_dn, b_dn)
    m = x0.shape[0]
    state = x0.copy()
    prev = state0
    vp = _f(u[0], u[0], state0, *f)     # G's input before the first sample: at rest at v_0
    for s in range(0, n, BLOCK):
        e = min(s + BLOCK, n)
        ub, vb, wb, xb = u[s:e], v[s:e], w[s:e], x[s:e]
        up = u[max(s - 1, 0)]
        if m == 1:
            prev = _fg_one(ub, up, f, prev, vp, state, Phi, G1, G0, C, D, vb, wb)
        elif m == 2:
            prev = _fg_two(ub, up, f, prev, vp, state, Phi, G1, G0, C, D, vb, wb)
        else:
            prev = _fg_any(ub, up, f, prev, vp, state, Phi, G1, G0, C, D, vb, wb)
        vp = prev
        horner_into(wb, coef, xb)
        if rng is not None:
            add_white(xb, rng, std, y[s:e])
