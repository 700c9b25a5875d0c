"""The identification results as plain frozen data: :class:`NonlinearResult` (stage 1, Section 4),
:class:`LinearResult` (stage 2, Section 5) and :class:`WholeResult` (the whole-model fit).

Each has a ``to_dict()`` that the JSON and HDF5 writers share (:mod:`hwid.results` stores and reads
them); nothing here computes an estimate.
"""
from __future__ import annotations

from dataclasses import dataclass, field
from typing import Any

import numpy as np

from hwid.blocks.linear import LinearBlock
from hwid.blocks.static import PolynomialH
from hwid.model import Actuator, HWModel, InputNonlinearity

#: the parameters the normalisation of eqs. (4a-c) fixes, never estimated: their interval is None
#: and this is why (``h_bar``'s constant ``c0``; ``slope_up`` where a result reports it)
FIXED = {"slope_up": "fixed by the normalisation S^a = 1", "c0": "fixed by the normalisation h(0) = 0"}


@dataclass(frozen=True)
class NonlinearResult:
    """Stage-1 estimates for the normalised model of eqs. (4a-c): ``slope_up = 1``, ``G(0) = 1``.

    ``ci`` maps each estimate to its 95 % interval: ``slope_down``, ``d_plus``, ``d_minus`` to
    ``(lo, hi)``, ``h_coefficients`` and ``X_hat`` to lists of pairs. ``cov`` is the covariance of
    ``param_names`` = ``(c1..cp, d_plus, slope_down, d_minus)``. ``levels``, ``X_hat``,
    ``X_hat_se`` hold the ascending staircase's levels then the descending one's (``fit['n_up']``
    of them ascending).
    """

    type: str
    slope_up: float
    slope_down: float
    d_plus: float
    d_minus: float
    h_coefficients: tuple[float, ...]
    degree: int
    w_range: tuple[float, float]
    ci: dict
    cov: np.ndarray
    param_names: tuple[str, ...]
    levels: tuple[float, ...]
    X_hat: tuple[float, ...]
    X_hat_se: tuple[float, ...]
    flat_up: int
    flat_down: int
    method: str
    evidence: str
    warnings: tuple[str, ...]
    fit: dict = field(default_factory=dict)   # diagnostics: chi2, dof, n_up, selection table, ...
    # {parameter: reason} for what the staircases cannot determine; its interval in ``ci`` is None
    undetermined: dict = field(default_factory=dict)
    # h_bar's root-shifted readings the levels cannot tell apart (:mod:`hwid.identify.readings`),
    # as plain dicts; empty when the reading is determined
    readings: tuple = field(default=())

    def input_nonlinearity(self) -> InputNonlinearity:
        """The normalised ``F_bar`` (eq. 4a) as an :class:`hwid.model.InputNonlinearity`."""
        return InputNonlinearity(self.type, 1.0, self.slope_down, self.d_plus, self.d_minus)

    def h(self, w) -> np.ndarray:
        """``h_bar(w)`` (eq. 4c), ascending-power coefficients ``h_coefficients``."""
        return np.polynomial.polynomial.polyval(np.asarray(w, float), self.h_coefficients)

    def to_dict(self) -> dict:
        """Plain data for JSON and HDF5 (the ``--json`` summary of ``hwid identify-nonlinear``)."""
        d: dict[str, Any] = {
            "type": self.type, "slope_up": self.slope_up, "slope_down": self.slope_down,
            "d_plus": self.d_plus, "d_minus": self.d_minus,
            "h_coefficients": list(self.h_coefficients), "degree": self.degree,
            "levels": list(self.levels), "X_hat": list(self.X_hat), "X_hat_se": list(self.X_hat_se),
            "flat_up": self.flat_up, "flat_down": self.flat_down,
            "n_up": int(self.fit.get("n_up", len(self.levels))),
        }
        for key, val in self.ci.items():
            d[f"{key}_ci"] = [_interval(v) for v in val] if key in ("h_coefficients", "X_hat") else _interval(val)
        d.update({"evidence": self.evidence, "warnings": list(self.warnings), "method": self.method,
                  "w_range": list(self.w_range), "param_names": list(self.param_names),
                  "cov": np.asarray(self.cov).tolist(), "fixed": dict(FIXED),
                  "undetermined": dict(self.undetermined), "readings": [dict(r) for r in self.readings]})
        d["fit"] = {k: v for k, v in self.fit.items()}
        return d

    @classmethod
    def from_dict(cls, d: dict) -> "NonlinearResult":
        """Inverse of :meth:`to_dict`; also reads a file written before the parameters fixed by the
        normalisation had no interval (``slope_up`` and h_bar's constant were ``[1, 1]``, ``[0, 0]``)."""
        undetermined = dict(d.get("undetermined") or {})
        ci = {}
        for key in ("slope_up", "slope_down", "d_plus", "d_minus"):
            if f"{key}_ci" in d:
                ci[key] = None if key in FIXED else stored_interval(d[f"{key}_ci"])
        for key in ("h_coefficients", "X_hat"):
            if f"{key}_ci" in d:
                v = d[f"{key}_ci"]
                ci[key] = [stored_interval(p) for p in (v if isinstance(v, (list, tuple)) else np.asarray(v))]
        if ci.get("h_coefficients"):
            ci["h_coefficients"][0] = None
        tup = lambda v: tuple(float(x) for x in np.ravel(v))  # noqa: E731
        return cls(type=str(d["type"]), slope_up=float(d["slope_up"]), slope_down=float(d["slope_down"]),
                   d_plus=float(d["d_plus"]), d_minus=float(d["d_minus"]),
                   h_coefficients=tup(d["h_coefficients"]), degree=int(d["degree"]),
                   w_range=tup(d["w_range"]), ci=ci, cov=np.asarray(d["cov"], float),
                   param_names=tuple(str(x) for x in d["param_names"]), levels=tup(d["levels"]),
                   X_hat=tup(d["X_hat"]), X_hat_se=tup(d["X_hat_se"]), flat_up=int(d["flat_up"]),
                   flat_down=int(d["flat_down"]), method=str(d["method"]), evidence=str(d["evidence"]),
                   warnings=tuple(str(w) for w in (d.get("warnings") or [])), fit=dict(d.get("fit") or {}),
                   undetermined=undetermined, readings=stored_readings(d.get("readings")))


@dataclass(frozen=True)
class LinearResult:
    """Stage 2 result: the frequency response estimates, their intervals, the bound and the
    parametric model. Plain data; ``to_dict()`` feeds both the JSON and the HDF5 writers.

    ``phase`` is ``phi(omega) = -arg G(j omega)`` in rad (Table 2), unwrapped across frequency
    from the principal value at the lowest one. ``crlb_gain``/``crlb_phase`` are *variance* bounds.
    """

    frequencies: np.ndarray
    amplitude: float
    gain: np.ndarray
    gain_ci: np.ndarray          # (n, 2)
    phase: np.ndarray
    phase_ci: np.ndarray
    cov: np.ndarray              # (n, 2, 2) of (gain, phase)
    method: str
    crlb_gain: np.ndarray
    crlb_phase: np.ndarray
    parametric: dict
    harmonics: tuple             # per frequency: dict (HarmonicFit.to_dict() + model + estimates)
    extrapolated: np.ndarray
    warnings: tuple[str, ...] = ()
    precompensator: str = "auto"

    @property
    def response(self) -> np.ndarray:
        """``G_hat(j omega) = |G| e^{-j phi}``."""
        return self.gain * np.exp(-1j * self.phase)

    def to_dict(self, full: bool = False) -> dict:
        """Plain Python data (JSON). ``full`` adds the per-frequency harmonic fits (HDF5)."""
        lst = lambda a: np.asarray(a, float).tolist()  # noqa: E731
        d = {"frequencies": lst(self.frequencies), "amplitude": float(self.amplitude),
             "gain": lst(self.gain), "gain_ci": lst(self.gain_ci), "phase": lst(self.phase),
             "phase_ci": lst(self.phase_ci), "gain_se": lst(np.sqrt(self.cov[:, 0, 0])),
             "phase_se": lst(np.sqrt(self.cov[:, 1, 1])), "method": self.method,
             "crlb_gain": lst(self.crlb_gain), "crlb_phase": lst(self.crlb_phase),
             "parametric": plain(self.parametric), "extrapolated": [bool(x) for x in self.extrapolated],
             "warnings": list(self.warnings), "precompensator": self.precompensator}
        if full:
            d["cov"] = np.asarray(self.cov, float)
            d["harmonics"] = {str(i): h for i, h in enumerate(self.harmonics)}
        else:
            d["estimates"] = [plain(h.get("estimates", {})) for h in self.harmonics]
        return d


def plain(x):
    if isinstance(x, dict):
        return {str(k): plain(v) for k, v in x.items()}
    if isinstance(x, (list, tuple)):
        return [plain(v) for v in x]
    if isinstance(x, np.ndarray):
        return plain(x.tolist())
    if isinstance(x, (np.floating, np.integer, np.bool_)):
        return x.item()
    if isinstance(x, complex):
        return [x.real, x.imag]
    return x


@dataclass(frozen=True)
class WholeResult:
    """The whole-model fit: the normalised model, 95 % intervals, the selection table.
    ``actuator``: the input's clip and slew rate where the selected fit has them (F, G and h were
    fitted behind them, and :meth:`model` keeps them); ``initial_states`` holds each record's
    ``gear`` and ``rest``, and with a slew carried from record to record, its ``position``."""

    type: str
    slope_down: float
    d_plus: float
    d_minus: float
    h_coefficients: tuple[float, ...]
    num: tuple[float, ...]
    den: tuple[float, ...]
    delay: float
    structure: str
    ci: dict
    sigma: float
    rms: float
    samples: int
    initial_states: dict
    selection: tuple[dict, ...]
    warnings: tuple[str, ...] = ()
    actuator: Actuator | None = None
    # {parameter: reason} for what the records cannot determine; its interval in ``ci`` is None
    undetermined: dict = field(default_factory=dict)
    # h_bar's root-shifted readings the records cannot tell apart (:mod:`hwid.identify.readings`)
    readings: tuple = field(default=())

    def model(self) -> HWModel:
        """The model that was fitted: F, G (with its delay), h_bar and the actuator ahead of F."""
        return HWModel(InputNonlinearity(self.type, 1.0, self.slope_down, self.d_plus, self.d_minus),
                       LinearBlock(self.num, self.den, self.delay), PolynomialH(self.h_coefficients), self.actuator)

    def to_dict(self) -> dict:
        """Plain data for JSON and ``whole.h5``."""
        return {"type": self.type, "slope_up": 1.0, "slope_down": self.slope_down, "d_plus": self.d_plus,
                "d_minus": self.d_minus, "h_coefficients": list(self.h_coefficients),
                "degree": len(self.h_coefficients) - 1, "num": list(self.num), "den": list(self.den),
                "delay": self.delay, "structure": self.structure,
                **{f"{k}_ci": [_interval(x) for x in v] if k == "h_coefficients" else _interval(v)
                   for k, v in self.ci.items()},
                "fixed": dict(FIXED), "undetermined": dict(self.undetermined),
                "sigma": self.sigma, "rms": self.rms, "samples": self.samples,
                "initial_states": self.initial_states, "selection": list(self.selection),
                "warnings": list(self.warnings),
                "actuator": None if self.actuator is None else self.actuator.to_dict(),
                "readings": [dict(r) for r in self.readings]}

    @classmethod
    def from_dict(cls, d: dict) -> "WholeResult":
        """Inverse of :meth:`to_dict` (h_bar's constant, ``[0, 0]`` in older files, has no interval)."""
        ci = {k: stored_interval(d[f"{k}_ci"]) for k in ("slope_down", "d_plus", "d_minus")}
        ci["h_coefficients"] = [None] + [stored_interval(p) for p in d["h_coefficients_ci"][1:]]
        return cls(str(d["type"]), float(d["slope_down"]), float(d["d_plus"]), float(d["d_minus"]),
                   tuple(d["h_coefficients"]), tuple(d["num"]), tuple(d["den"]), float(d["delay"]),
                   str(d["structure"]), ci, float(d["sigma"]), float(d["rms"]), int(d["samples"]),
                   dict(d["initial_states"]), tuple(d["selection"]), tuple(d.get("warnings", ())),
                   Actuator.from_dict(d.get("actuator")), dict(d.get("undetermined") or {}),
                   stored_readings(d.get("readings")))


def first_order_fallback(lin: LinearResult) -> tuple[list, list]:
    """``G(s) = 1/(tau s + 1)`` fitted to the stage 2 estimates ``G_hat(j omega_i)`` (relative
    least squares over ``log tau``): a stable G when stage 2 found no parametric model."""
    from scipy.optimize import minimize_scalar
    w = np.asarray(lin.frequencies, float)
    G = np.asarray(lin.gain, float) * np.exp(-1j * np.asarray(lin.phase, float))
    ok = np.isfinite(G) & (np.abs(G) > 0) & (w > 0)
    if not np.any(ok):
        from hwid import HwidError
        raise HwidError("the stage 2 result has no finite frequency response; no G(s) can be built from it")
    w, G = w[ok], G[ok]

    def cost(lt):
        return float(np.sum(np.abs(1.0 / (1.0 + 1j * w * np.exp(lt)) / G - 1.0) ** 2))
    lo, hi = np.log(0.01 / w.max()), np.log(100.0 / w.min())
    tau = float(np.exp(minimize_scalar(cost, bounds=(lo, hi), method="bounded").x))
    return [1.0], [tau, 1.0]


def model_from_stages(nl: NonlinearResult, lin: LinearResult, notes: list | None = None) -> HWModel:
    """The normalised HW model of a stage 1 result and a stage 2 result: F and h_bar from stage 1,
    stage 2's parametric G (when stage 2 found none, a first-order G fitted to its estimates, said
    in ``notes``)."""
    par = dict(lin.parametric or {})
    num = np.atleast_1d(np.asarray(par.get("num", []), float))
    den = np.atleast_1d(np.asarray(par.get("den", []), float))
    if num.size == 0 or den.size == 0 or not np.all(np.isfinite(num)) or not np.all(np.isfinite(den)):
        n1, d1 = first_order_fallback(lin)
        num, den = np.asarray(n1), np.asarray(d1)
        why, par = par.get("error", "no num/den"), {"delay": 0.0}
        if notes is not None:
            notes.append(f"stage 2 found no parametric G(s) ({why}); the model "
                         f"uses G(s) = 1/({den[0]:.4g} s + 1) fitted to the estimates G(j omega)")
    num = np.trim_zeros(num, "f")
    den = np.trim_zeros(den, "f")
    return HWModel(nl.input_nonlinearity(), LinearBlock(tuple(num.tolist()), tuple(den.tolist()),
                                                        float(par.get("delay", 0.0) or 0.0)),
                   PolynomialH(tuple(float(c) for c in np.asarray(nl.h_coefficients, float))))


def format_summary(result: NonlinearResult) -> str:
    """A readable summary of a stage-1 result (what ``hwid identify-nonlinear`` prints): each
    estimate with its interval, or ``undetermined`` with the reason where the staircases do not
    determine it."""
    def pm(key):
        return interval_text(getattr(result, key), result.ci[key])
    conf = result.fit.get("confidence", 0.95)
    lines = [f"input nonlinearity: {result.type}   ({result.evidence})",
             f"normalised model (eqs. 4a-c), {100 * conf:g} % intervals; method {result.method}:",
             f"  slope_up   = 1 ({FIXED['slope_up']})",
             f"  slope_down = {pm('slope_down')}",
             f"  d_plus     = {pm('d_plus')}",
             f"  d_minus    = {pm('d_minus')}",
             f"  h degree p = {result.degree}" + ("" if "chi2" not in result.fit else
                                                  f"   (joint chi2 = {result.fit['chi2']:.4g} for {result.fit['dof']} dof)"),
             "  h coefficients (ascending powers):",
             f"    c0 = 0 ({FIXED['c0']})"]
    for i, (c, ci) in enumerate(zip(result.h_coefficients, result.ci["h_coefficients"])):
        if i:
            lines.append(f"    c{i} = {interval_text(c, ci)}")
    for name, why in result.undetermined.items():
        lines.append(f"  undetermined {name}: {why}")
    line = readings_line(result.readings)
    if line:
        lines.append(line)
    if result.type == "backlash":
        lines.append(f"  horizontal paths: j_a = {result.flat_up}, j_d = {result.flat_down}")
    else:
        lines.append("  horizontal paths: none (Backlash-Inverse, Remark 1.4): j_a = j_d = 0")
    lines.append(f"  w range identified: [{result.w_range[0]:.4g}, {result.w_range[1]:.4g}]")
    n_up = int(result.fit.get("n_up", len(result.levels)))
    lines.append("  steady states (eq. 9):   j       U_j       X_hat_j         se")
    for j, (u, x, s) in enumerate(zip(result.levels, result.X_hat, result.X_hat_se), start=1):
        tag = "up  " if j <= n_up else "down"
        lines.append(f"    {tag:>20} {j:3d}  {u:+8.4f}  {x:+12.6f}  {s:9.2e}")
    return "\n".join(lines)


@dataclass(frozen=True)
class Level:
    """One settled level: the record it belongs to, its place in that record's sequence, the
    input, the settled output and its standard error, and the samples averaged."""

    record: str
    index: int
    u: float
    x: float
    se: float
    n: int
    scored: bool = True


@dataclass(frozen=True)
class HistoryResult:
    """Stage 1 from a recorded history (:mod:`hwid.identify.history`); ``to_dict()`` is its JSON:
    the borders, ``dead_band = d_plus - d_minus``, h_bar, 95 % intervals (``ci``), the chi-square of
    the levels against their own standard errors with ``misfit`` when it rejects, every level used
    and the selection table."""

    type: str
    slope_down: float
    d_plus: float
    d_minus: float
    h_coefficients: tuple
    ci: dict
    chi2: float
    dof: int
    p_value: float
    misfit: bool
    levels: tuple
    table: tuple
    warnings: tuple = field(default=())
    # covariance of (c1..cp, d_plus, slope_down, d_minus), for stage 2's delta method
    cov: tuple = field(default=())
    param_names: tuple = field(default=())
    # {parameter (or "type", "adequacy"): reason} for what the levels cannot determine; such a
    # parameter's interval in ``ci`` is None (:mod:`hwid.identify.determinable`)
    undetermined: dict = field(default_factory=dict)
    # h_bar's root-shifted readings the levels cannot tell apart (:mod:`hwid.identify.readings`)
    readings: tuple = field(default=())

    @property
    def dead_band(self) -> float:
        return self.d_plus - self.d_minus

    def to_dict(self) -> dict:
        return {"type": self.type, "slope_up": 1.0, "slope_down": self.slope_down, "d_plus": self.d_plus,
                "d_minus": self.d_minus, "dead_band": self.dead_band, "h_coefficients": list(self.h_coefficients),
                "ci": {k: ([_interval(p) for p in v] if k == "h_coefficients" else _interval(v))
                       for k, v in self.ci.items()},
                "chi2": self.chi2, "dof": self.dof,
                "p_value": self.p_value, "misfit": self.misfit,
                "levels": [vars(lv) for lv in self.levels], "selection": list(self.table),
                "warnings": list(self.warnings), "cov": [list(row) for row in self.cov],
                "param_names": list(self.param_names), "fixed": dict(FIXED), "undetermined": dict(self.undetermined),
                "readings": [dict(r) for r in self.readings]}

    @classmethod
    def from_dict(cls, d: dict) -> "HistoryResult":
        ci = {k: _interval(v) for k, v in d["ci"].items() if k != "h_coefficients"}
        ci["h_coefficients"] = [None] + [_interval(v) for v in d["ci"]["h_coefficients"][1:]]
        return cls(d["type"], float(d["slope_down"]), float(d["d_plus"]), float(d["d_minus"]),
                   tuple(d["h_coefficients"]), ci, float(d["chi2"]), int(d["dof"]), float(d["p_value"]),
                   bool(d["misfit"]), tuple(Level(**lv) for lv in d["levels"]), tuple(d["selection"]),
                   tuple(d["warnings"]), tuple(tuple(row) for row in d.get("cov", ())),
                   tuple(d.get("param_names", ())), dict(d.get("undetermined", {})),
                   stored_readings(d.get("readings")))


def stored_readings(v) -> tuple:
    """Root-shifted readings as read back (None or absent in a file written before: none)."""
    if v is None or isinstance(v, str):
        return ()
    return tuple(dict(r) for r in v)


def readings_line(readings) -> str | None:
    """The one summary line of undetermined readings (None when there are none)."""
    if len(readings) < 2:
        return None
    return ("  reading undetermined: h_bar vanishes at " + " and ".join(f"{r['shift']:.4g}" for r in readings)
            + "; equivalent readings d+ = " + " or ".join(f"{r['d_plus']:.4g}" for r in readings)
            + ", dead band " + " or ".join(f"{r['dead_band']:.4g}" for r in readings)
            + " (the paper's h^-1(0) = 0 picks none)")


def _interval(v):
    """An interval as JSON: ``[lo, hi]``, or None where the parameter is not estimated."""
    return None if v is None else [float(x) for x in v]


def stored_interval(v) -> tuple[float, float] | None:
    """An interval as read back from JSON or HDF5: ``(lo, hi)``, or None for ``null`` and for the
    ``[NaN, NaN]`` that stands for "no interval" in a numeric dataset."""
    if v is None:
        return None
    lo, hi = (float(x) for x in np.ravel(np.asarray(v, float)))
    return None if np.isnan(lo) and np.isnan(hi) else (lo, hi)


def point_text(value: float, interval, digits: int = 4) -> str:
    """``value`` for a one-line echo, or ``undetermined (fitted value)`` where its interval is None."""
    return f"{value:.{digits}g}" if interval is not None else f"undetermined (fitted {value:.{digits}g})"


def interval_text(value: float, interval, digits: int = 6) -> str:
    """``value  [lo, hi]``, or ``undetermined`` where the interval is None."""
    if interval is None:
        return f"undetermined (fitted {value:.{digits}g}, not a measurement)"
    return f"{value:.{digits}g}  [{interval[0]:.{digits}g}, {interval[1]:.{digits}g}]"


def format_history(res: HistoryResult) -> str:
    """The CLI's text summary of stage 1 from a recorded history."""
    ci, und = res.ci, res.undetermined
    flag = "  (MISFIT: see the warning)" if res.misfit else ""
    if "adequacy" in und:
        flag += "  (fit UNDETERMINED: it cannot be judged, see the warning)"
    lines = [f"stage 1 from the recorded levels: {res.type}{' (type undetermined)' if 'type' in und else ''}{flag}",
             f"  d+ = {interval_text(res.d_plus, ci['d_plus'])}",
             f"  d- = {interval_text(res.d_minus, ci['d_minus'])}",
             f"  dead band d+ - d- = {interval_text(res.dead_band, ci['dead_band'])}",
             f"  S^d = {interval_text(res.slope_down, ci['slope_down'])}",
             f"  h_bar degree {len(res.h_coefficients) - 1}: {', '.join(f'{c:.4g}' for c in res.h_coefficients)}"
             f"  (c0 {FIXED['c0']})" + ("  (undetermined)" if "h_coefficients" in und else "")
             + "".join(f"  ({k} undetermined)" for k in und if k[:1] == "c" and k[1:].isdigit()),
             f"  {sum(lv.scored for lv in res.levels)} levels scored; chi2 = {res.chi2:.4g} on {res.dof} dof "
             f"(p = {res.p_value:.2g})"]
    line = readings_line(res.readings)
    return "\n".join(lines + ([line] if line else []))
