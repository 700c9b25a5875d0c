"""The catalogue's effects after the gear: ``friction`` on the gear's output side, where the load is,
and ``output_hysteresis`` between G's output and the sensor (issue 48).

Both are rate-independent memories of the path a signal took, the kind of unmodelled effect real
geared drives, friction dampers and servos carry most often, and neither is in the paper's class:
F's play is before G, a static h has no memory. Each is an :class:`hwid.diagnose.effect_base.Effect`
like the other nine, its bounds and starting points scaled from the experiments and the model
(:class:`hwid.diagnose.effect_base.Scale`), never from a particular plant.
"""
from __future__ import annotations

import numpy as np

from hwid.blocks.effects import HYSTERESIS_PLAYS, dahl_state, friction_drive, hysteresis, play_sum  # noqa: F401
from hwid.diagnose.effect_base import Effect, Scale, grid


class Friction(Effect):
    """A friction force on the gear's output side: G receives
    ``v + coulomb z(v) + viscous dv/dt`` instead of ``v``, ``z`` the Dahl state of the gear's output
    path (:func:`dahl_state`), ``pre_sliding`` its pre-sliding displacement.

    Placement. In a geared drive or a driven damper the friction acts on the load, which moves with
    the gear's output ``v`` where the drive is stiff; the load's dynamics, G, are driven by what
    the gear transmits less the friction (or, where the output is the force read at the driven
    shaft, plus it). The force is therefore added to G's input in ``v``'s units (the force over the
    drive's stiffness), its sign free: ``coulomb > 0`` when friction adds to the output in the
    direction of motion (a force read at the driven shaft: a damper), ``< 0`` when it holds the
    load back (a position behind a compliant drive: the loop then looks like a smooth extra play).

    The law. Dahl's (Dahl 1968; 1976): one state, smooth, rate-independent pre-sliding whose
    stiffness ``coulomb / pre_sliding`` is the bristle stiffness ``sigma0``, reaching the Coulomb
    level after a few ``pre_sliding`` of travel; with the viscous term, Coulomb plus viscous plus
    pre-sliding in three parameters. LuGre (Canudas de Wit, Olsson, Astrom, Lischinsky 1995) adds a
    Stribeck curve and bristle damping: three or four parameters more that only velocities near
    zero with force measured at the contact determine, which a diagnosis from u and y through G
    does not see (Olsson et al. 1998 on its identification). Dahl is LuGre without them.

    ``viscous`` is a zero of G at ``-1/viscous``: a rate dependence, linear. What makes the fit a
    friction is the Coulomb level, the force that depends on the direction of motion: where its
    95 % interval holds zero (or it is undetermined) the fit is a zero of G standing in for the
    model's own dynamics (an identified G a little off takes it up), and it is not named
    (:meth:`stands_in`).
    """

    def __init__(self):
        super().__init__("friction", "linear", ("coulomb", "pre_sliding", "viscous"),
                         "a Dahl friction force (Coulomb, pre-sliding, viscous) on the gear's output side, "
                         "acting on G's input")

    def log_params(self):
        return (False, True, False)

    #: the largest Coulomb level, in multiples of the gear output's range (:meth:`bounds`)
    COULOMB_RANGES = 10.0

    def bounds(self, sc: Scale):
        """The Coulomb level up to :attr:`COULOMB_RANGES` times the gear output's range either way;
        the pre-sliding displacement from 1e-4 of that range (a Coulomb step within a sample of
        travel) to half of it; the viscous term up to the displacement's own at G's bandwidth.

        In ``v``'s units the Coulomb level is the friction force over the drive's elastic stiffness
        ``k``. Where the output is a position, more than the range would keep the load from moving
        at all; where it is a force read at the driven shaft, the force may be nearly all friction
        (a friction damper: ``k`` small), and the level then exceeds the range by as much as the
        friction force exceeds the elastic one (h re-estimated takes the scale back). A banded
        friction damper's log pressed a bound of half the range (its Coulomb level there 1.01, the
        range 2.0) and was fitted at 3.2 within ten."""
        W = sc.v_width
        b = 1.0 / sc.omega_c if np.isfinite(sc.omega_c) and sc.omega_c > 0 else sc.settle_s
        c = self.COULOMB_RANGES * W
        return np.array([-c, 1e-4 * W, -b]), np.array([c, 0.5 * W, b])

    def starts(self, sc: Scale):
        lo, hi = self.bounds(sc)
        W = sc.v_width
        return grid([f * W for f in (-4.0, -1.0, -0.2, -0.05, -0.01, 0.01, 0.05, 0.2, 1.0, 4.0)],
                    np.geomspace(lo[1], 0.25 * hi[1], 4), [0.0])

    def stands_in(self, intervals: dict | None) -> str | None:
        """A friction is its Coulomb level: none told from zero, and the fit is a rate dependence."""
        if not intervals or "coulomb" not in intervals:
            return None
        iv = intervals["coulomb"]
        if iv is None:
            return ("its Coulomb level is undetermined: what it fits is a rate dependence (its viscous term, a "
                    "zero of G), not friction")
        if iv[0] <= 0.0 <= iv[1]:
            return (f"its Coulomb level's 95 % interval [{iv[0]:.3g}, {iv[1]:.3g}] holds zero: what it fits is a "
                    "rate dependence (its viscous term, a zero of G), not friction")
        return None

    def drive(self, v, theta, dt: float) -> np.ndarray:
        """G's input: ``v`` with the friction force added."""
        return friction_drive(v, *(float(t) for t in theta), dt)

    def simulate(self, sim, theta, i):
        return sim.from_v(self.drive(sim.v[i], theta, sim.dt))


class OutputHysteresis(Effect):
    """A rate-independent hysteresis between G's output and the sensor's static map h:
    ``y = h((1 - weight) w + weight P(w))``, ``P`` a Prandtl-Ishlinskii sum of
    :attr:`N_PLAYS` plays of half-widths ``width k / N_PLAYS`` (:func:`play_sum`).

    A sensor, a flexible coupling or a loose output shaft after the load's dynamics: its loop has
    the same width in G's output at every rate and amplitude beyond it, where F's play, before G,
    is filtered by G's dynamics (a faster input shrinks and turns its loop). ``weight`` 1 is a pure
    smoothed play, below 1 part of the output passes straight. Uniform threshold density gives
    the rounded loop of a real sensor's hysteresis (a single play's sharp corners are the
    ``weight = 1``, narrow-``width`` limit in shape only). ``width`` in G's output units (h sees
    it after the hysteresis), so h is re-estimated through it as through any other stage before h.
    """

    #: the plays summed; with 4 the loop's branches are within 1/16 of the width of the smooth
    #: uniform-density limit
    N_PLAYS = HYSTERESIS_PLAYS

    def __init__(self):
        super().__init__("output_hysteresis", "output", ("width", "weight"),
                         "a rate-independent hysteresis (Prandtl-Ishlinskii plays) between G's output and h")

    def log_params(self):
        return (True, False)

    def bounds(self, sc: Scale):
        """The largest play's half-width from 1e-3 to half of G's output range; the weight in [0, 1]."""
        W = sc.w_width
        return np.array([1e-3 * W, 0.0]), np.array([0.5 * W, 1.0])

    def starts(self, sc: Scale):
        lo, hi = self.bounds(sc)
        return grid(np.geomspace(lo[0], hi[0], 8), [0.3, 1.0])

    def hysteresis(self, w, theta) -> np.ndarray:
        return hysteresis(w, float(theta[0]), float(theta[1]))

    def simulate(self, sim, theta, i):
        return sim.model.output(self.hysteresis(sim.w[i], theta))


def effects_after_gear() -> list[Effect]:
    """The two effects, in the catalogue's order."""
    return [Friction(), OutputHysteresis()]
