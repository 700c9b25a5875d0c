"""Input protocols: the self-initialising staircases of eqs. (6) and (13), and the sines of eq. (15).

Staircases. Each level is held ``hold`` seconds. A lead-in of two levels puts the input
nonlinearity on a known border whatever state the plant was left in, provided the working interval
closes the backlash cycle (Section 3):

* ascending (eq. 6): lead-in ``U_N, U_1``, then ``U_1 < ... < U_N``. After ``U_N`` the gear is on the
  ascending border; stepping down to ``U_1`` puts it on the descending border, so the flat path of
  eq. (7a) starts at ``V_1 = S^d (U_1 - d^-)``.
* descending (eq. 13): lead-in ``U_1, U_N`` (the ascending levels' ends), then ``levels_down``. The
  gear starts on the ascending border at ``U_N``, as in eq. (14a).

Sines. ``z(t) = U sin(omega t)`` (eq. 15) for ``lead_in_periods + periods`` periods; the lead-in lets
the transient of G die out. The pre-compensator of Fig. 8 is applied by the caller
(:meth:`hwid.model.InputNonlinearity.precompensator`), so the sine is the same for any plant.
"""
from __future__ import annotations

from dataclasses import dataclass, field

import numpy as np


@dataclass(frozen=True)
class Staircase:
    """A piecewise-constant experiment: ``u`` and where each level starts and stops (samples)."""

    name: str
    direction: str                  # "up" or "down"
    levels: np.ndarray              # the staircase levels (lead-in excluded)
    lead_in: np.ndarray             # lead-in levels, applied before ``levels``
    starts: np.ndarray              # first sample of each level (lead-in excluded)
    stops: np.ndarray               # one past the last sample of each level
    u: np.ndarray
    dt: float
    hold: float

    @property
    def all_levels(self) -> np.ndarray:
        return np.concatenate([self.lead_in, self.levels])


def staircase(levels, hold: float, dt: float, direction: str, lead_in) -> Staircase:
    """Piecewise-constant input holding each level ``hold`` seconds (eqs. 6, 13)."""
    levels = np.asarray(levels, float)
    lead_in = np.asarray(lead_in, float)
    n_hold = int(round(hold / dt))
    seq = np.concatenate([lead_in, levels])
    u = np.repeat(seq, n_hold)
    starts = (np.arange(levels.size) + lead_in.size) * n_hold
    return Staircase(f"staircase_{direction}", direction, levels, lead_in, starts, starts + n_hold,
                     u, dt, n_hold * dt)


def staircases(cfg) -> tuple[Staircase, Staircase]:
    """The ascending and descending staircases of ``cfg.protocols.staircase``."""
    st = cfg.protocols.staircase
    dt = cfg.sampling.dt
    up, down = st.levels_up, st.levels_down
    return (staircase(up, st.hold, dt, "up", [up[-1], up[0]]),
            staircase(down, st.hold, dt, "down", [up[0], up[-1]]))


@dataclass(frozen=True)
class Sine:
    """``z(t) = U sin(omega t)``, eq. (15), sampled; ``t`` starts at 0 with the lead-in."""

    name: str
    amplitude: float
    omega: float                     # rad/s
    periods: int
    lead_in_periods: int
    dt: float
    t: np.ndarray
    z: np.ndarray

    @property
    def period(self) -> float:
        return 2 * np.pi / self.omega

    @property
    def steady_start(self) -> int:
        """First sample after the lead-in periods."""
        return int(np.ceil(self.lead_in_periods * self.period / self.dt - 1e-9))


def sine(amplitude: float, omega: float, periods: int, lead_in_periods: int, dt: float,
         name: str | None = None) -> Sine:
    n = int(np.floor((periods + lead_in_periods) * 2 * np.pi / omega / dt + 1e-9))
    t = np.arange(n) * dt
    return Sine(name or f"sine_w{omega:g}", amplitude, omega, periods, lead_in_periods, dt, t,
                amplitude * np.sin(omega * t))


def sines(cfg) -> list[Sine]:
    sn = cfg.protocols.sine
    return [sine(sn.amplitude, w, sn.periods, sn.lead_in_periods, cfg.sampling.dt, name=f"sine_{i}")
            for i, w in enumerate(sn.frequencies)]
