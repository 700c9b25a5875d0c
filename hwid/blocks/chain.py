"""The F -> G -> h chain of eqs. (3a-c) in one pass over the samples.

Three passes (the operator, the linear recursion, the polynomial) each read and write every
sample; this kernel does the three in one loop with the same arithmetic, in the same order, as
:func:`hwid.blocks.backlash._play` / ``_direction_map``, :func:`hwid.blocks.linear._ss_run` and
:func:`hwid.blocks.static._horner`, so its output is bit-identical to theirs. It covers the common
case (no delay, polynomial h); :meth:`hwid.model.HWModel.simulate` uses the three passes otherwise.
"""
from __future__ import annotations

import numpy as np
from numba import njit


@njit(cache=True)
def run_chain(u, inverse, a_up, b_up, a_dn, b_dn, state0, Phi, G1, G0, C, D, x0, coef):
    """``(v, w, x)`` of the chain on ``u``.

    ``inverse = False``: the Backlash of eq. (1) with borders ``a_up (u - b_up)`` (ascending) and
    ``a_dn (u - b_dn)`` (descending) and gear position ``state0`` before the first sample;
    ``inverse = True``: the direction map of eq. (2), ``a_up z + b_up`` rising, ``a_dn z + b_dn``
    falling, output ``state0`` held at the first sample. ``Phi, G1, G0, C, D, x0``: G's sampled
    recursion and initial state (:func:`hwid.blocks.linear.discretise`); ``coef``: h's
    ascending-power coefficients."""
    n = u.shape[0]
    m = x0.shape[0]
    k_coef = coef.shape[0]
    v = np.empty(n)
    w = np.empty(n)
    x = np.empty(n)
    state = x0.copy()
    nxt = np.empty(m)
    prev = state0
    vp = 0.0
    for k in range(n):
        if inverse:
            if k > 0:
                dz = u[k] - u[k - 1]
                if dz > 0.0:
                    prev = a_up * u[k] + b_up
                elif dz < 0.0:
                    prev = a_dn * u[k] + b_dn
        else:
            lo = a_up * (u[k] - b_up)
            hi = a_dn * (u[k] - b_dn)
            if prev < lo:
                prev = lo
            elif prev > hi:
                prev = hi
        vk = prev
        v[k] = vk
        if k == 0:
            vp = vk
        acc = D * vk
        for i in range(m):
            acc += C[i] * state[i]
        w[k] = acc
        for i in range(m):
            s = G1[i] * vk + G0[i] * vp
            for j in range(m):
                s += Phi[i, j] * state[j]
            nxt[i] = s
        for i in range(m):
            state[i] = nxt[i]
        vp = vk
        out = coef[k_coef - 1]
        for i in range(k_coef - 2, -1, -1):
            out = out * acc + coef[i]
        x[k] = out
    return v, w, x
