"""Stage 1 behind an input dead zone: the levels as F sees them, ``deadzone(U_j, delta)``.

An actuator that does not move for small commands puts a dead zone ahead of F. Each border of F,
read against the command, then has a flat step around zero; no polynomial h and straight borders
fit the staircases' steady states (eq. 9) within their noise, and stage 1's best fit is grossly
overdispersed (chi2/dof of 40 to 340 on the paper's plant behind dead zones of 0.12 to 0.22). The
model identified through such a fit has the wrong borders, and stage 2, whose pre-compensator is
built from them, reads a wrong G: what is left is no longer the dead zone alone, and the diagnosis
could not name it.

Where stage 1's fit is that far off (:data:`GROSS`), the same estimator is fitted to the levels
mapped through dead zones of widths up to :data:`SPAN` times the largest level (a grid, then a finer
one around its best); the width whose fit leaves the least misfit is kept where levels lie inside
it (:data:`MIN_INSIDE`) and stage 1's fit behind it is consistent (:data:`CONSISTENT`) and
:data:`GAIN` times better than the plain one. Stage 2 then drives the plant through the dead zone's
inverse ahead of its pre-compensator (:class:`ThroughDeadZone`), so that F sees the
pre-compensated sine, and G is read as the paper reads it. The model is F, G and h without the
dead zone: the diagnosis leaves it to ``input_deadzone``, started at the width found here.
"""
from __future__ import annotations

import dataclasses
from dataclasses import dataclass

import numpy as np
from scipy.optimize import minimize_scalar

from hwid import HwidError
from hwid.blocks.deadzone import deadzone, deadzone_inverse

#: stage 1's overdispersion (chi2/dof of its best fit) from which a dead zone ahead of F is tried;
#: in-class rigs of the blind check reach 5.6, the paper plant behind a dead zone 40 and more
GROSS = 20.0
#: the fit behind the dead zone is kept where its overdispersion is at most this ...
CONSISTENT = 5.0
#: ... and at most the plain fit's divided by this
GAIN = 5.0
#: levels inside the dead zone (where the actuator does not move) it needs: its width is
#: otherwise read from the step in the borders alone, which h's shape can trade against (a
#: saturation between G's lags fitted the paper's levels behind a dead zone of 0.077 that one
#: level lay in)
MIN_INSIDE = 2
#: widths tried: GRID of them up to SPAN x the largest |level| (the ``input_deadzone`` effect's
#: bound), then a bounded search within a grid step of the best, to FINE of a step, in at most
#: REFINE fits; each scored by the misfit of a fit with h of degree DEGREE. Stage 1's own choice
#: of degree trades off against the width: a degree-8 h behind any width from 0.06 to 0.18 fitted
#: the levels of the paper's plant behind a dead zone of 0.21 as well, by BIC, as the paper's
#: degree-5 h behind 0.2; at one moderate degree the misfit has one valley, at the width.
SPAN = 0.4
GRID = 16
FINE = 0.05
REFINE = 8
DEGREE = 6


@dataclass(frozen=True)
class DeadZoneAhead:
    """The dead zone stage 1's levels fit behind: its width, the overdispersion of stage 1's fit
    without and with it, and stage 1's result behind it (levels as F sees them)."""

    delta: float
    delta_ci: tuple
    overdispersion_plain: float
    overdispersion: float
    result: object

    def note(self) -> str:
        lo, hi = self.delta_ci
        return (f"stage 1's levels fit within their noise only behind a dead zone of {self.delta:.4g} "
                f"[{lo:.4g}, {hi:.4g}] ahead of F "
                f"(overdispersion {self.overdispersion_plain:.3g} without it, {self.overdispersion:.3g} with it): "
                f"the model is identified behind it and the dead zone is left to the diagnosis")

    def to_dict(self) -> dict:
        return {"delta": self.delta, "delta_ci": list(self.delta_ci), "overdispersion_plain": self.overdispersion_plain,
                "overdispersion": self.overdispersion}


def behind(stair, delta: float):
    """The staircase with its levels (and lead-in) as F sees them behind a dead zone of ``delta``;
    its input ``u``, which the plant received, is unchanged."""
    return dataclasses.replace(stair, levels=deadzone(stair.levels, delta), lead_in=deadzone(stair.lead_in, delta))


def find_deadzone(cfg, plain, records) -> DeadZoneAhead | None:
    """The dead zone ahead of F behind which stage 1's levels fit (module docstring), or None where
    ``plain`` (stage 1's result on the config's staircase ``records``) fits well enough or no dead
    zone makes it fit."""
    from hwid import protocols
    from hwid.identify.nonlinear import NonlinearEstimator
    c_plain = float(plain.fit.get("overdispersion", 1.0))
    if not c_plain >= GROSS or len(records) != 2:
        return None
    up, down = protocols.staircases(cfg)
    ru, rd = records

    def fit(delta: float, kind: str = "auto", degree: int | None = None):
        est = NonlinearEstimator.from_config(cfg)
        est.input_type = kind if est.input_type == "auto" else est.input_type
        est.degree = degree if degree is not None else est.degree
        try:
            return est.fit(ru, rd, behind(up, delta), behind(down, delta))
        except (HwidError, ValueError, np.linalg.LinAlgError, FloatingPointError):
            return None

    def chi2(delta: float, degree: int = DEGREE) -> float:
        """The levels' misfit behind ``delta`` with h of ``degree`` (or the highest the border's
        levels allow below it) and F of the plain fit's type."""
        for p in range(degree, 0, -1):
            est = fit(delta, plain.type, p)
            if est is not None:
                return float(est.result_.fit["chi2"])
        return np.inf

    top = float(np.max(np.abs(np.concatenate([up.all_levels, down.all_levels]))))
    grid = np.linspace(0.0, SPAN * top, GRID + 1)[1:]
    step = float(grid[1] - grid[0])
    values = [chi2(float(d)) for d in grid]
    k = int(np.argmin(values))
    if not np.isfinite(values[k]):
        return None
    lo, hi = max(float(grid[k]) - step, 0.0), float(grid[k]) + step
    found = minimize_scalar(chi2, bounds=(lo, hi), method="bounded", options={"xatol": FINE * step, "maxiter": REFINE})
    best = float(found.x) if found.fun < values[k] else float(grid[k])
    inside = int(np.sum(np.abs(np.concatenate([up.levels, down.levels])) < best))
    if inside < MIN_INSIDE:
        return None
    est = fit(best)          # h's degree and F's type selected behind it as stage 1 selects them
    if est is None or not (est.c_hat_ <= CONSISTENT and est.c_hat_ * GAIN <= c_plain):
        return None
    delta_ci, result = _with_width_uncertain(est, best, step, lambda d: fit(d, est.result_.type, est.result_.degree))
    return DeadZoneAhead(best, delta_ci, c_plain, float(est.c_hat_), result)


def _with_width_uncertain(est, best: float, step: float, fit_at) -> tuple:
    """The width's 95 % interval, from the curvature of the levels' chi2 at ``best`` (scaled by the
    fit's overdispersion), and stage 1's result with the intervals of its borders widened to those
    behind the widths of that interval: the borders are fitted for a width
    estimated from the same levels, and move with it (``d^+`` by about as much as the width): each
    border's interval is the union of its intervals behind the two ends."""
    from scipy import stats
    r = est.result_
    h = 0.25 * step
    around = [fit_at(d) for d in (best - h, best + h)]
    if any(e is None for e in around) or best - h <= 0:
        return (max(best - step, 0.0), best + step), r
    f0, fm, fp = (float(e.result_.fit["chi2"]) for e in (est, *around))
    curv = (fp - 2 * f0 + fm) / (h * h)
    half = float(stats.norm.ppf(0.975) * np.sqrt(2 * max(est.c_hat_, 1.0) / curv)) if curv > 0 else step
    half = min(half, step)
    ends = [e for e in (fit_at(best - half), fit_at(best + half)) if e is not None and best - half > 0]
    ci = dict(r.ci)
    for name in ("d_plus", "slope_down", "d_minus"):
        if ci[name] is None or any(e.result_.ci[name] is None for e in ends):
            ci[name] = None     # undetermined at the best width or at an end of its interval
            continue
        ci[name] = (float(min([ci[name][0]] + [e.result_.ci[name][0] for e in ends])),
                    float(max([ci[name][1]] + [e.result_.ci[name][1] for e in ends])))
    return (max(best - half, 0.0), best + half), dataclasses.replace(r, ci=ci)


class ThroughDeadZone:
    """A plant driven through the inverse of a dead zone of ``delta``: each command ``v`` reaches the
    plant as :func:`deadzone_inverse` of it, so that F behind the dead zone sees ``v``. Its records
    hold ``v`` as the input (what stage 2 reads against F); :attr:`sent` holds the plant's own, by
    name."""

    def __init__(self, plant, delta: float):
        self.plant = plant
        self.delta = float(delta)
        self.sent: dict = {}

    def run(self, name: str, u, z=None):
        v = np.asarray(u, float)
        rec = self.plant.run(name, deadzone_inverse(v, self.delta), z=z)
        self.sent[name] = rec
        return dataclasses.replace(rec, u=v)

    def __getattr__(self, key):
        return getattr(self.plant, key)
