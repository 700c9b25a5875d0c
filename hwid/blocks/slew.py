"""An actuator that slews at most a given rate (units/s): the input block of a slow actuator, used
by the diagnosis's ``rate_limit`` effect and by the whole fit from logs where the records show one."""
from __future__ import annotations

import numpy as np
from numba import njit


@njit(cache=True)
def _slew(u, step, u0):
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


def slewed(u, rate: float, dt: float, start: float | None = None) -> np.ndarray:
    """``u`` through an actuator slewing at most ``rate`` units/s, starting at ``start`` (default
    ``u[0]``: an actuator a driver sets where the record begins)."""
    u = np.ascontiguousarray(u, float)
    if not u.size:
        return u.copy()
    return _slew(u, float(rate) * dt, float(u[0] if start is None else start))
