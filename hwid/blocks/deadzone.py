"""An actuator that does not move for small commands: the dead zone ``u -> 0`` for ``|u| < delta``,
``u - delta sign(u)`` beyond, ahead of F. Used by the diagnosis's ``input_deadzone`` effect and by
stage 1 where its levels fit only behind one (:mod:`hwid.identify.deadzone_ahead`)."""
from __future__ import annotations

import numpy as np


def deadzone(u, delta: float) -> np.ndarray:
    """0 for ``|u| < delta``, ``u - delta sign(u)`` beyond."""
    u = np.asarray(u, float)
    return np.sign(u) * np.maximum(np.abs(u) - delta, 0.0)


def deadzone_inverse(v, delta: float) -> np.ndarray:
    """A command the dead zone passes as ``v``: ``v + delta sign(v)`` (0 stays 0), so that
    ``deadzone(deadzone_inverse(v, delta), delta) == v``."""
    v = np.asarray(v, float)
    return v + delta * np.sign(v)
