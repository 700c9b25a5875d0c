"""Root-shifted readings of a stage-1 fit: where ``h_bar`` has more than one real zero (Section 3).

With the normalisation ``S^a = 1``, ``G(0) = 1``, ``h_bar(0) = 0`` (eqs. 4a-c), the triple
``(F_bar, G, h_bar)`` is still not unique when ``h_bar`` has another real zero ``beta``: moving F's
output by ``-beta`` and h_bar's argument by ``+beta``,

* a Backlash: ``d^+ -> d^+ + beta``, ``d^- -> d^- + beta / S^d`` (its borders ``u - d^+`` and
  ``S^d (u - d^-)`` both lowered by ``beta``), so the dead band ``d^+ - d^-`` moves by
  ``beta (1 - 1/S^d)``;
* a Backlash-Inverse: ``d^+ -> d^+ - beta``, ``d^- -> d^- - beta`` (branches ``u + d^+`` and
  ``u / S^d + d^-``), its dead band unchanged;
* ``h_bar'(x) = h_bar(x + beta)``, again with ``h_bar'(0) = 0`` and of the same degree,

predicts every steady level ``h_bar(F_bar[U])`` (eq. 5) identically, and every output through G
wherever G starts at a steady state that moves with F's output. ``S^d`` is the same in every reading.

The paper assumes ``h^-1(0) = 0`` (Section 1): h_bar vanishes only at 0. h_bar is only known on
the working range W its argument visits, so the assumption is read there: the reading shifted to
the root ``beta`` keeps it iff ``beta`` lies in W (widened by :data:`MARGIN` of W's width each side)
and no other real root of h_bar does. :func:`assess` sorts the fitted h_bar's real roots that way:

* exactly one root in W: that reading is *the* reading (the fit moves there if it landed on another);
* two or more: the levels violate the assumption, or h_bar has zeros the data cannot rule out; the
  borders and h_bar are determined only up to the shift, and every such reading is returned;
* none: every reading whose borders stay within the fit's search range (``admissible``) is one the
  data allow; more than one is undetermined as above.
"""
from __future__ import annotations

from dataclasses import dataclass
from math import comb

import numpy as np

#: W widened by this share of its width on each side when a root is looked for in it: a zero of
#: h_bar at the very edge of the levels (a level held at ``h_bar = 0``) belongs to the range
MARGIN = 0.05
#: a root of h_bar counts as real when its imaginary part is below this share of W's width
IMAG = 1e-3


@dataclass(frozen=True)
class Reading:
    """One root-shifted reading: the fitted model moved to the root ``shift`` of its h_bar."""

    shift: float
    d_plus: float
    d_minus: float
    slope_down: float
    h_coefficients: tuple

    @property
    def dead_band(self) -> float:
        return self.d_plus - self.d_minus

    def to_dict(self) -> dict:
        return {"shift": float(self.shift), "d_plus": float(self.d_plus), "d_minus": float(self.d_minus),
                "dead_band": float(self.dead_band), "slope_down": float(self.slope_down),
                "h_coefficients": [float(c) for c in self.h_coefficients]}


@dataclass(frozen=True)
class Verdict:
    """The readings :func:`assess` found: ``chosen`` the one the paper's assumption picks (None
    when it cannot pick one), ``readings`` every reading the data allow, ``working`` the range W."""

    readings: tuple
    chosen: Reading | None
    working: tuple

    @property
    def determined(self) -> bool:
        return self.chosen is not None

    @property
    def shifted(self) -> bool:
        return self.chosen is not None and self.chosen.shift != 0.0

    def reason(self) -> str:
        """Why the borders and h_bar are undetermined (one sentence naming the readings)."""
        roots = " and ".join(f"{r.shift:.3g}" for r in self.readings)
        where = "in the levels' range" if self.in_range else "outside the levels' range, each within the search range"
        return (f"h_bar vanishes at {roots} {where} [{self.working[0]:.4g}, {self.working[1]:.4g}]: F and h_bar "
                "are determined only up to a shift to any of these roots (d+ "
                + " or ".join(f"{r.d_plus:.4g}" for r in self.readings) + ", dead band "
                + " or ".join(f"{r.dead_band:.4g}" for r in self.readings)
                + "); the paper's assumption h^-1(0) = 0 on the working range cannot pick one")

    @property
    def in_range(self) -> bool:
        lo, hi = widened(self.working)
        return all(lo <= r.shift <= hi for r in self.readings)

    def note(self, d_plus: float) -> str:
        """The warning line of a fit moved to the chosen reading from ``d_plus``."""
        c = self.chosen
        return (f"the fit's h_bar vanished at {c.shift:.4g} in the levels' range [{self.working[0]:.4g}, "
                f"{self.working[1]:.4g}] and not at its own 0 there: by the paper's assumption h^-1(0) = 0 the "
                f"reading is shifted to that root (d+ {d_plus:.4g} -> {c.d_plus:.4g}, an exactly equivalent model)")

    def undetermined(self, dead_band_ci=None) -> dict:
        """``{parameter: reason}`` of an undetermined verdict: the borders and h_bar's coefficients,
        and the dead band where the readings' dead bands do not all lie in ``dead_band_ci``."""
        if self.determined:
            return {}
        why = self.reason()
        out = {"d_plus": why, "d_minus": why, "h_coefficients": why}
        bands = [r.dead_band for r in self.readings]
        if dead_band_ci is None or not all(dead_band_ci[0] <= b <= dead_band_ci[1] for b in bands):
            out["dead_band"] = why
        return out

    def to_dicts(self, kind: str | None = None, params=None, cov=None, z: float = 1.959963984540054) -> list:
        """The readings as plain data (empty when the verdict is determined: one reading, the
        result's own). Given the fit's ``params`` ``(c_1..c_p, d^+, S^d, d^-)`` and their ``cov``,
        each carries the intervals (``ci``, half-width ``z`` standard deviations) of its borders,
        dead band and slope, the covariance carried to it by :func:`transform`."""
        if self.determined:
            return []
        out = []
        for r in self.readings:
            d = r.to_dict()
            if cov is not None and np.size(cov) and np.all(np.isfinite(cov)):
                _, c = transform(kind, params, cov, r.shift)
                sd = {"d_plus": c[-3, -3], "slope_down": c[-2, -2], "d_minus": c[-1, -1],
                      "dead_band": c[-3, -3] + c[-1, -1] - 2 * c[-3, -1]}
                d["ci"] = {k: [float(d[k] - z * np.sqrt(max(v, 0.0))), float(d[k] + z * np.sqrt(max(v, 0.0)))]
                           for k, v in sd.items()}
            out.append(d)
        return out


def widened(working) -> tuple[float, float]:
    lo, hi = (float(x) for x in working)
    m = MARGIN * max(hi - lo, 0.0)
    return lo - m, hi + m


def real_roots(coef, width: float) -> np.ndarray:
    """The real roots of the polynomial with ascending coefficients ``coef`` (a root whose imaginary
    part is below :data:`IMAG` of ``width`` counts as real, at its real part; roots closer than that
    count once), sorted; 0 is exact where ``coef[0] == 0``."""
    c = np.trim_zeros(np.asarray(coef, float), "b")
    if c.size < 2:
        return np.array([0.0])
    zeros = int(np.argmax(c != 0))              # exact roots at 0 (h_bar(0) = 0)
    rest = np.roots(c[zeros:][::-1]) if c.size - zeros > 1 else np.array([])
    tol = IMAG * max(width, 1e-300)
    real = np.sort(rest[np.abs(rest.imag) <= tol].real)
    out = [0.0] if zeros else []
    for r in real:          # a multiple root (to within tol) is one shift; 0 stands for those at 0
        if not any(abs(r - o) <= tol for o in out):
            out.append(float(r))
    return np.sort(np.array(out))


def shift_h(coef, beta: float) -> np.ndarray:
    """Ascending coefficients of ``h(x + beta)``; the constant set to 0 (``beta`` a root of h)."""
    c = np.asarray(coef, float)
    out = np.array([sum(c[k] * comb(k, j) * beta ** (k - j) for k in range(j, c.size)) for j in range(c.size)])
    out[0] = 0.0
    return out


def shifted(kind: str, slope_down: float, d_plus: float, d_minus: float, coef, beta: float) -> Reading:
    """The reading moved to the root ``beta`` of h_bar (module docstring)."""
    if kind == "backlash":
        dp, dm = d_plus + beta, d_minus + beta / slope_down
    else:
        dp, dm = d_plus - beta, d_minus - beta
    return Reading(float(beta), float(dp), float(dm), float(slope_down),
                   tuple(float(x) for x in shift_h(coef, beta)))


def assess(kind: str, slope_down: float, d_plus: float, d_minus: float, coef, working,
           admissible=None, alike=None) -> Verdict:
    """Every root-shifted reading of a fit and the one the paper's assumption picks (module
    docstring). ``coef``: h_bar's ascending coefficients (``coef[0] = 0``); ``working``: ``(lo, hi)``
    of h_bar's argument over the scored data; ``admissible(reading) -> bool``: whether a reading
    stays within the fit's search range (used only when no root lies in W; default: all);
    ``alike(reading) -> bool``: whether the data fit a reading as well as the fitted one (where the
    model is not exactly invariant under the shift, e.g. a record starting from a fixed state;
    default: all are)."""
    lo, hi = widened(working)
    width = float(working[1]) - float(working[0])
    fitted = Reading(0.0, float(d_plus), float(d_minus), float(slope_down), tuple(float(x) for x in coef))
    cands = [fitted if r == 0.0 else shifted(kind, slope_down, d_plus, d_minus, coef, float(r))
             for r in real_roots(coef, width)]
    cands = [r for r in cands if (r.d_plus > r.d_minus or kind != "backlash")
             and (r is fitted or alike is None or alike(r))]
    inside = [r for r in cands if lo <= r.shift <= hi]
    if len(inside) == 1:
        return Verdict(tuple(inside), inside[0], (float(working[0]), float(working[1])))
    if not inside:
        inside = [r for r in cands if r is fitted or admissible is None or admissible(r)]
        if len(inside) <= 1:
            return Verdict((fitted,), fitted, (float(working[0]), float(working[1])))
    return Verdict(tuple(inside), None, (float(working[0]), float(working[1])))


def transform(kind: str, params, cov, beta: float, rel: float = 1e-6) -> tuple[np.ndarray, np.ndarray]:
    """``(params', cov')``: the parameters ``(c_1..c_p, d^+, S^d, d^-)`` moved to the root ``beta``
    of their h_bar and their covariance carried through the map's Jacobian (central differences;
    the root follows the coefficients, ``d beta / d c_k = -beta^k / h_bar'(beta)``)."""
    params = np.asarray(params, float)

    def move(p):
        c = np.concatenate([[0.0], p[:-3]])
        b = beta
        dc = np.polynomial.polynomial.polyder(c)
        for _ in range(30):         # Newton from beta: the root of the perturbed h_bar next to it
            step = np.polynomial.polynomial.polyval(b, c) / np.polynomial.polynomial.polyval(b, dc)
            b -= step
            if abs(step) <= 1e-15 * (1.0 + abs(b)):
                break
        r = shifted(kind, p[-2], p[-3], p[-1], c, b)
        return np.concatenate([r.h_coefficients[1:], [r.d_plus, r.slope_down, r.d_minus]])

    out = move(params)
    jac = np.empty((out.size, params.size))
    for i in range(params.size):
        h = rel * (1.0 + abs(params[i]))
        a, b = params.copy(), params.copy()
        a[i] += h
        b[i] -= h
        jac[:, i] = (move(a) - move(b)) / (2 * h)
    return out, jac @ np.asarray(cov, float) @ jac.T
