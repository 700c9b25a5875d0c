"""What stage 2 needs from stage 1 (:class:`NonlinearLike`), and a stand-in built from a known
normalised model (:class:`KnownNonlinear`: tests, the paper reproduction, and the base of stage 1
from a recorded history, :mod:`hwid.identify.periodic`)."""
from __future__ import annotations

from dataclasses import dataclass
from typing import Any, Protocol, Sequence

import numpy as np

from hwid import HwidError


class NonlinearLike(Protocol):
    """What stage 2 needs from a stage 1 result (:class:`hwid.identify.nonlinear.NonlinearResult`)."""

    h_coefficients: Sequence[float]
    w_range: tuple[float, float]

    def input_nonlinearity(self): ...


@dataclass(frozen=True)
class KnownNonlinear:
    """A stage 1 stand-in built from a known normalised model (tests, the paper reproduction).

    ``w_range`` is the range of ``w`` the config's staircases visit (where stage 1 would identify h).
    """

    input: Any                                   # hwid.model.InputNonlinearity (normalised)
    h_coefficients: tuple[float, ...]
    w_range: tuple[float, float] = (-np.inf, np.inf)

    def input_nonlinearity(self):
        return self.input

    def h(self, w):
        return np.polynomial.polynomial.polyval(np.asarray(w, float), self.h_coefficients)

    @classmethod
    def from_config(cls, cfg) -> "KnownNonlinear":
        """The true normalised ``(F_bar, h_bar)`` of ``cfg.plant`` (eqs. 4a-c)."""
        from hwid import protocols
        from hwid.blocks.static import PolynomialH
        from hwid.model import from_config
        if cfg.plant.kind != "hammerstein_wiener":
            raise HwidError("the true nonlinearity is only known for a simulated (hammerstein_wiener) plant")
        m = from_config(cfg.plant).normalised()
        if not isinstance(m.output, PolynomialH):
            raise HwidError("stage 2 needs a polynomial h (the config gives a piecewise one)")
        w_range = (-np.inf, np.inf)
        if cfg.protocols.staircase is not None:
            ws = []
            for st in protocols.staircases(cfg):
                v = m.input.steady(st.all_levels, 0.0)[st.lead_in.size:]
                ws.append(v)
            ws = np.concatenate(ws)
            w_range = (float(ws.min()), float(ws.max()))
        return cls(m.input, tuple(m.output.coefficients), w_range)
