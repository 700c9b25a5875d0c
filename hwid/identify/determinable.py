"""What a set of held levels can determine, before stage 1 fits them (issue 45, item 3).

Stage 1's steady model ``X = h_bar(F_bar[U])`` (eqs. 5, 7a-b, 14a-b) reads each branch of F
through the levels that reach it: with ``slope_up = 1`` the ascending branch ``u - d^+`` (Backlash)
or ``u + d^+`` (Backlash-Inverse) through the levels approached from below, the descending one
``S^d (u - d^-)`` or ``u / S^d + d^-`` through those approached from above. A level is one point
``(u, direction)`` however often it is repeated; repeats measure the noise, not the model. So

* ``d^+`` and ``h_bar`` of degree ``p`` need ``p + 1`` distinct levels approached from below
  (eq. 11: ``N - j_a >= p + 1``);
* ``S^d`` and ``d^-`` need 2 distinct levels approached from above (given ``h_bar``);
* the dead band ``d^+ - d^-`` needs both;
* judging the fit (its chi-square against the levels' noise) needs more distinct points than the
  ``p + 3`` parameters: with as many, the model passes through every point and the chi-square
  measures only the repeats' scatter.

The direction of a level is that of the input's last move before it, in the recorded sequence (the
passages between levels included); a record's first level has none (its state is a nuisance
parameter) and counts for no branch. These are upper bounds: a level approached from below whose
step stayed inside the play sits on a horizontal path, not on the border.

Both stage 1 paths (a recorded history, :mod:`hwid.identify.history`; the paper's staircases,
:mod:`hwid.identify.nonlinear`) count their levels here, refuse a design that cannot determine F or
h_bar at all with the same line (:func:`refusal`), and after the fit report as undetermined every
interval that cannot stand as one (:func:`interval_flaw`).
"""
from __future__ import annotations

from dataclasses import dataclass

import numpy as np


@dataclass(frozen=True)
class Design:
    """The distinct inputs of the scored levels on each branch."""

    up: tuple            # distinct u of scored levels approached from below
    down: tuple          # distinct u of scored levels approached from above

    @property
    def points(self) -> int:
        return len(self.up) + len(self.down)

    def max_degree(self) -> int:
        """The highest degree of h_bar the design determines with one degree of freedom left to
        judge the fit, at least 1 (below that nothing is judged; :meth:`undetermined` says so)."""
        return max(1, min(len(self.up) - 1, self.points - 4))

    def lack_of_fit_dof(self, degree: int) -> int:
        """Distinct points left over after the ``degree + 3`` parameters."""
        return self.points - (degree + 3)

    def undetermined(self, degree: int) -> dict:
        """``{parameter: reason}`` for every parameter (and ``"adequacy"``: the fit's own check) these
        levels cannot determine with h_bar of ``degree``; each reason names the experiment that would."""
        out = {}
        n_up, n_dn = len(self.up), len(self.down)
        if n_up < degree + 1:
            why = (f"{n_up} distinct level(s) approached from below ({describe(self.up)}); hold at least "
                   f"p + 1 = {degree + 1} distinct levels above d+ approached from below")
            out["d_plus"] = why
            out["h_coefficients"] = why
        if n_dn < 2:
            why = (f"{n_dn} distinct level(s) approached from above ({describe(self.down)}); hold at least 2 "
                   "distinct levels below d- approached from above")
            out["slope_down"] = why
            out["d_minus"] = why
        if "d_plus" in out or "d_minus" in out:
            out["dead_band"] = "; ".join(dict.fromkeys(out[k] for k in ("d_plus", "d_minus") if k in out))
        lof = self.lack_of_fit_dof(degree)
        if lof < 1:
            out["adequacy"] = (f"{self.points} distinct (level, direction) points for {degree + 3} parameters: the "
                               "model passes through every point, so its chi-square measures only the repeats' "
                               "scatter and cannot judge the model; hold at least one more distinct level on "
                               "either branch")
        return out


def describe(values) -> str:
    return ", ".join(f"{v:.6g}" for v in values) if values else "none"


def design(levels) -> Design:
    """The :class:`Design` of stage 1's levels (in recorded order, unscored ones included: they
    carry the input's path)."""
    up, down = set(), set()
    last_u, last_dir = {}, {}
    for lv in levels:
        before = last_u.get(lv.record)
        if before is not None and lv.u != before:
            last_dir[lv.record] = up if lv.u > before else down
        last_u[lv.record] = lv.u
        if lv.scored and lv.record in last_dir:
            last_dir[lv.record].add(lv.u)
    return Design(tuple(sorted(up)), tuple(sorted(down)))


def refusal(des: Design, what: str, remedy: str = "") -> str | None:
    """The one line for a design that cannot determine F or h_bar at all -- fewer than 2 distinct
    levels on a branch: the parameters it leaves undetermined and the levels that would determine
    them (``what``: whose stage 1; ``remedy``: where to add them); None when each branch has 2."""
    if len(des.up) >= 2 and len(des.down) >= 2:
        return None
    names = (["d_plus", "h_bar"] if len(des.up) < 2 else []) + (["slope_down", "d_minus"] if len(des.down) < 2 else [])
    return (f"{what} cannot determine {', '.join(names)} from these levels: {len(des.up)} distinct level(s) "
            f"approached from below ({describe(des.up)}) and {len(des.down)} from above ({describe(des.down)}); "
            "hold at least 2 distinct levels above d+ approached from below and 2 below d- approached from above"
            f"{remedy}")


def interval_flaw(value: float, interval, width: float | None = None, positive: bool = False) -> str | None:
    """Why ``interval`` cannot stand as the 95 % interval of the estimate ``value``: not finite, of
    zero width (the fit is exact or the direction unseen), for a border (given ``width``, that of
    the input range the levels explore) wider than that whole range (the levels do not place it),
    for a slope (``positive``) reaching zero or below (eq. 1 needs S^d > 0); None when it can."""
    if interval is None:
        return None
    lo, hi = (float(x) for x in interval)
    if not (np.isfinite(lo) and np.isfinite(hi) and np.isfinite(value)):
        return "its 95 % interval is not finite: the levels leave it unconstrained"
    if not hi - lo > 1e-9 * (1.0 + abs(lo)):
        return "its 95 % interval has zero width: the levels leave it unconstrained or exactly fitted"
    if width is not None and hi - lo > width:
        return (f"its 95 % interval [{lo:.4g}, {hi:.4g}] is wider than the whole input range the levels explore "
                f"({width:.4g}): they do not place it")
    if positive and lo <= 0.0:
        return (f"its 95 % interval [{lo:.4g}, {hi:.4g}] reaches zero or below, where no slope lies: the levels "
                "do not bound it")
    return None


@dataclass(frozen=True)
class _Step:
    record: str
    u: float
    scored: bool = True


#: largest share of samples at which a "stepped" input may change (:func:`stepped_design`)
STEPPED = 0.05


def stepped_design(records) -> Design | None:
    """The :class:`Design` of the whole fit's records where every input is piecewise constant (it
    changes at no more than :data:`STEPPED` of its samples), else None.

    A stepped input leaves F's output piecewise constant too, so F is seen only at the values the
    input holds, settled or not: G's transients between them trace h_bar over a continuum of its
    argument, but only up to an affine change of that argument, which the ascending branch's slope
    (``S^a = 1``) and place fix through two distinct held values reached from below, and the
    descending branch's through two reached from above. So with fewer than 2 on the ascending
    branch, ``d^+`` and h_bar's scale are undetermined; fewer than 2 on the descending one leave
    ``S^d`` and ``d^-`` undetermined (:func:`whole_undetermined`). A record's first value has no
    direction (its gear state is a nuisance parameter). With sines or ramps the input sweeps the
    borders and this count does not apply."""
    steps = []
    for r in records:
        u = np.asarray(r.u, float)
        moves = np.flatnonzero(np.diff(u))
        if u.size < 2 or moves.size > STEPPED * u.size:
            return None
        steps += [_Step(r.name, float(x)) for x in u[np.r_[0, moves + 1]]]
    return design(steps)


def whole_undetermined(records, degree: int) -> dict:
    """``{parameter: reason}`` for the whole fit's F and h_bar (names ``d_plus``, ``slope_down``,
    ``d_minus``, ``c1`` ... ``c<degree>``) that records of stepped inputs cannot determine
    (:func:`stepped_design`); empty where the inputs sweep or the steps suffice."""
    des = stepped_design(records)
    if des is None:
        return {}
    out = {}
    if len(des.up) < 2:
        why = (f"the inputs are steps, and {len(des.up)} distinct held value(s) are reached from below "
               f"({describe(des.up)}); F's ascending branch and h_bar's scale need at least 2")
        out.update({"d_plus": why, **{f"c{i}": why for i in range(1, degree + 1)}})
    if len(des.down) < 2:
        why = (f"the inputs are steps, and {len(des.down)} distinct held value(s) are reached from above "
               f"({describe(des.down)}); S^d and d- need at least 2")
        out.update({"slope_down": why, "d_minus": why})
    return out


def warning_lines(why: dict) -> list[str]:
    """One ``undetermined ...: reason`` line per distinct reason in ``{parameter: reason}``, naming
    every parameter that shares it (in their order)."""
    by_reason: dict = {}
    for name, reason in why.items():
        by_reason.setdefault(reason, []).append(name)
    return [f"undetermined {', '.join(names)}: {reason}" for reason, names in by_reason.items()]
