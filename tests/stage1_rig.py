"""A test rig for ``plant.kind: external`` in the stage-1 tests: a :class:`hwid.plant.SimulatedPlant`
of known truth behind the rig interface ``function(u, dt) -> y``.

Like a real rig it keeps its gear's position from one call to the next and knows nothing of
experiment names; its noise comes from one Generator seeded at import. ``MODEL`` is the truth the
tests compare with (an asymmetric Backlash, G with a zero, h with an even term).
"""
from __future__ import annotations

import numpy as np

from hwid.blocks.linear import LinearBlock
from hwid.blocks.static import PolynomialH
from hwid.model import HWModel, InputNonlinearity
from hwid.plant import SimulatedPlant, noise

MODEL = HWModel(InputNonlinearity("backlash", 0.9, 1.2, 0.25, -0.35),
                LinearBlock((0.5, 1.0), (1.0, 3.0, 2.0)),        # G(s) = (0.5 s + 1)/((s + 1)(s + 2)), G(0) = 0.5
                PolynomialH((0.0, 2.0, 1.5, -1.0)))
NOISE_STD = 0.01
_PLANT = SimulatedPlant(MODEL, dt=0.01, noise_std=0.0)
_RNG = np.random.default_rng(np.random.SeedSequence(20240601))
CALLS: list[int] = []


def rig(u, dt):
    """The rig: ``y = h(G * F[u]) + noise`` for the input samples ``u`` at sample time ``dt``."""
    if dt != _PLANT.dt:
        raise ValueError(f"this rig samples at dt = {_PLANT.dt}, asked for {dt}")
    CALLS.append(len(u))
    rec = _PLANT.run("rig", np.asarray(u, float))
    return rec.y + noise(_RNG, rec.y.size, NOISE_STD)
