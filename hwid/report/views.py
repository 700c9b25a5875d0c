"""What the report's figures and tables show, prepared from a run's data (:class:`RunData`).

* :func:`staircase_views`: each staircase with its levels, their spans, stage 1's averaging windows
  and ``X_hat_j`` (eq. 9) with 95 % half-widths, and the true ``X_j``.
* :func:`sine_views`: each sine's steady-state period folded (eq. 23a, :func:`fold_period`) and its
  harmonics ``C_k``, with the fitted model on the fold (eq. 21, :func:`harmonic_series`).
* :func:`points_on_w`, :func:`h_covariance`, :func:`parametric_block`, :func:`true_phase_lag`: the
  pieces of Fig. 12, the Bode plot and Table 2 that are not stored as such.

Most of it reads what the stages stored. Two functions analyse data, and say so in their names:
:func:`measured_harmonics` fits the harmonics of a sine's output when stage 2 has not run (its
stored fits are used when it has), and :func:`true_harmonics` those of a simulated plant's
noise-free ``x(t)``.
"""
from __future__ import annotations

import json
from dataclasses import dataclass

import numpy as np

from hwid.blocks.linear import LinearBlock
from hwid.blocks.static import PolynomialH
from hwid.identify.harmonics import fit_harmonics
from hwid.identify.result import LinearResult, NonlinearResult
from hwid.model import InputNonlinearity
from hwid.plant import Record
from hwid.report.rundir import RunData

DIRECTIONS = ("up", "down")


@dataclass(frozen=True)
class StaircaseView:
    """One staircase (eq. 6 ascending, eq. 13 descending) as Figs. 10-11, 13-14 and Table 1 show it."""

    name: str
    direction: str                    # "up" or "down"
    t: np.ndarray
    u: np.ndarray
    y: np.ndarray
    x: np.ndarray | None
    levels: np.ndarray                # U_j of the staircase proper (lead-in excluded)
    spans: list                       # (t0, t1) of each level, s
    stops: np.ndarray                 # one past the last sample of each level
    X_true: np.ndarray | None = None
    windows: list | None = None       # stage 1's averaging windows, s
    X_hat: np.ndarray | None = None
    X_ci: np.ndarray | None = None    # 95 % half-widths
    flat: int | None = None           # j_a or j_d: leading levels on the flat path (eqs. 7a, 14a)


@dataclass(frozen=True)
class SineView:
    """One sine experiment (eq. 15) as Figs. 15-16 show it."""

    name: str
    omega: float
    amplitude: float
    dt: float
    start: int                      # first steady-state sample (after the lead-in periods)
    t_fold: np.ndarray
    y_fold: np.ndarray
    x_fold: np.ndarray | None
    raw: tuple | None               # (t, y) of the first steady-state period
    ks: np.ndarray
    coef: np.ndarray                # measured C_k
    se: np.ndarray | None
    dc: float
    model: np.ndarray | None = None  # fitted model's C_k
    model_dc: float = 0.0
    truth_coef: np.ndarray | None = None
    truth_dc: float = 0.0

    def model_curve(self) -> np.ndarray | None:
        """The fitted harmonic model (eq. 20) on ``t_fold``; None without a stage-2 fit."""
        if self.model is None:
            return None
        return harmonic_series(self.t_fold, self.omega, self.model, self.model_dc, self.ks)


@dataclass(frozen=True)
class ReportViews:
    """The views of one run, prepared once for both the figures and the tables."""

    staircases: dict[str, StaircaseView]
    sines: list[SineView]
    notes: tuple[str, ...] = ()     # what could not be prepared


def prepare(run: RunData) -> ReportViews:
    """The staircase and sine views of ``run``, with a note for each staircase that cannot be shown."""
    staircases = staircase_views(run)
    notes = tuple(f"staircase_{d}: level attributes missing, cannot mark the levels"
                  for d in DIRECTIONS if f"staircase_{d}" in run.records and d not in staircases)
    return ReportViews(staircases, sine_views(run), notes)


# ---------------------------------------------------------------------------------- staircases

def record_levels(rec: Record, key: str) -> np.ndarray | None:
    """A level attribute of a staircase record (``levels``, ``lead_in``; JSON in the results file)."""
    value = rec.attrs.get(key)
    if value is None:
        return None
    if isinstance(value, bytes):
        value = value.decode()
    if isinstance(value, str):
        value = json.loads(value)
    return np.asarray(value, float)


def _stage1_by_staircase(nl: NonlinearResult | None) -> dict[str, dict]:
    """Stage 1's per-level quantities split into the ascending staircase's and the descending one's
    (``fit['n_up']`` levels ascending): ``X_hat``, the 95 % half-widths, the averaging windows'
    first samples and lengths, and ``j_a``/``j_d``."""
    if nl is None:
        return {}
    n_up = int(nl.fit.get("n_up", len(nl.levels)))
    half = np.array([0.5 * (hi - lo) for lo, hi in nl.ci["X_hat"]])
    per_level = {"X_hat": np.asarray(nl.X_hat, float), "X_ci": half,
                 "first": np.asarray(nl.fit["first_sample"], float),
                 "count": np.asarray(nl.fit["n_averaged"], float)}
    return {"up": {**{k: v[:n_up] for k, v in per_level.items()}, "flat": nl.flat_up},
            "down": {**{k: v[n_up:] for k, v in per_level.items()}, "flat": nl.flat_down}}


def staircase_views(run: RunData) -> dict[str, StaircaseView]:
    """The staircase experiments with their levels and, when stage 1 ran, its windows and ``X_hat_j``.
    A staircase whose level attributes are missing is left out."""
    out = {}
    stage1 = _stage1_by_staircase(run.nonlinear)
    for direction in DIRECTIONS:
        rec = run.records.get(f"staircase_{direction}")
        if rec is None:
            continue
        levels, lead = record_levels(rec, "levels"), record_levels(rec, "lead_in")
        hold = float(rec.attrs.get("hold", np.nan))
        if levels is None or lead is None or not np.isfinite(hold):
            continue
        n_hold = int(round(hold / rec.dt))
        starts = (np.arange(levels.size) + lead.size) * n_hold
        stops = starts + n_hold
        if rec.x is not None:
            X_true = rec.x[stops - 1]
        else:
            X_true = run.truth.staircase_steady(lead, levels) if run.truth is not None else None
        estimates = {}
        est = stage1.get(direction)
        if est is not None and est["X_hat"].size == levels.size:
            estimates = {"X_hat": est["X_hat"], "X_ci": est["X_ci"], "flat": int(est["flat"]),
                         "windows": [(a * rec.dt, (a + n) * rec.dt) for a, n in zip(est["first"], est["count"])]}
        out[direction] = StaircaseView(rec.name, direction, rec.t, rec.u, rec.y, rec.x, levels,
                                       [(s * rec.dt, e * rec.dt) for s, e in zip(starts, stops)], stops,
                                       X_true, **estimates)
    return out


def points_on_w(run: RunData, staircases: dict[str, StaircaseView],
                f_est: InputNonlinearity) -> dict[str, tuple]:
    """Stage-1 points ``(F_hat[U_j], X_hat_j, ci_j)`` on the ``w`` axis (Fig. 12): ``W_j`` through the
    estimated operator along the whole level sequence, lead-in included (eqs. 5, 7a-b, 14a-b), i.e.
    ``U_j - d_hat^+`` on the ascending border and the flat path's ``W_1`` before ``j_a``."""
    points = {}
    for direction, label in (("up", r"ascending staircase $(\hat F[U_j],\ \hat X_j)$"),
                             ("down", r"descending staircase $(\hat F[U_j],\ \hat X_j)$")):
        view = staircases.get(direction)
        rec = run.records.get(f"staircase_{direction}")
        if view is None or view.X_hat is None or rec is None:
            continue
        levels, lead = record_levels(rec, "levels"), record_levels(rec, "lead_in")
        w = f_est.staircase_steady(lead, levels)
        if w.size == view.X_hat.size:
            points[label] = (w, view.X_hat, view.X_ci)
    return points


def h_covariance(nl: NonlinearResult) -> np.ndarray:
    """Covariance of ``h_bar``'s ascending coefficients ``c_0..c_p``, cut from the result's full
    covariance by ``param_names`` (``c1..cp``); ``c_0`` is fixed by ``h(0) = 0`` (Section 4)."""
    n = len(nl.h_coefficients)
    idx = [nl.param_names.index(f"c{i}") for i in range(1, n)]
    out = np.zeros((n, n))
    out[1:, 1:] = np.asarray(nl.cov, float)[np.ix_(idx, idx)]
    return out


# ---------------------------------------------------------------------------------------- sines

def ls_harmonics(sig, dt: float, omega: float, start: int, k_max: int):
    """Least-squares ``dc + sum_k Im(C_k e^{j k omega t})`` fit of ``sig`` over the whole periods from
    the period that begins at sample ``start`` on (exact frequencies, no leakage whatever ``T/dt``):
    stage 2's :func:`hwid.identify.harmonics.fit_harmonics` with white-noise standard errors and no
    further periods dropped. Returns ``(C_k for k = 1..k_max, dc, se)``, ``se`` the standard error of
    each real component of ``C_k`` (eqs. 26a-e in least-squares form); NaN without a whole period."""
    first = int(round(start * dt * omega / (2 * np.pi)))
    try:
        fit = fit_harmonics(sig, dt, omega, k_max, first_period=first, noise_model="white", steady_alpha=0.0)
    except ValueError:
        return np.full(k_max, np.nan + 0j), float("nan"), np.full(k_max, np.nan)
    return np.asarray(fit.coef), float(fit.dc), np.sqrt(np.asarray(fit.var))


def stored_harmonics(fit: dict):
    """``(ks, C_k, se, model C_k, dc)`` of one frequency's harmonic fit as stage 2 stored it
    (:attr:`LinearResult.harmonics`): the fitted model (eq. 20) at the harmonics it uses, zero at
    every other harmonic."""
    ks = np.asarray(fit["ks"]).astype(int)
    coef = np.asarray(fit["coef_re"]) + 1j * np.asarray(fit["coef_im"])
    se = np.sqrt(np.asarray(fit["var"], float))
    predicted = np.asarray(fit["predicted_re"], float) + 1j * np.asarray(fit["predicted_im"], float)
    model = np.zeros(ks.size, complex)
    for k, c in zip(np.ravel(np.asarray(fit["used_harmonics"], float).astype(int)), np.ravel(predicted)):
        model[ks == k] = c
    return ks, np.asarray(coef, complex), se, model, float(fit["dc"])


def measured_harmonics(rec: Record, omega: float, start: int, k_max: int):
    """Re-analysis for a run without stage 2: ``(C_k, dc, se)`` of the sine's measured output by
    :func:`ls_harmonics`, k = 1..``k_max``."""
    return ls_harmonics(rec.y, rec.dt, omega, start, k_max)


def true_harmonics(rec: Record, omega: float, start: int, k_max: int):
    """``(C_k, dc)`` of a simulated plant's noise-free, periodic ``x(t)``: its last two whole periods
    give them exactly (``x`` may be stored for the last periods only)."""
    period = 2 * np.pi / omega
    whole = int(np.floor((rec.x.size - start) * rec.dt / period + 1e-9))
    first = start + int(np.ceil(max(whole - 2, 0) * period / rec.dt - 1e-9))
    coef, dc, _ = ls_harmonics(rec.x, rec.dt, omega, first, k_max)
    return coef, dc


def fold_period(y, dt: float, omega: float, start: int = 0, bins: int | None = None):
    """Period average ``x_hat_N(t)`` of eq. (23a) for any ``T/dt``: samples from ``start`` on are
    binned by their phase ``(t mod T)/T`` into ``bins`` bins (default ``round(T/dt)``, at most 2000).

    Returns ``(t_bin, mean, count)`` with ``t_bin`` the bin centres in ``[0, T)``."""
    y = np.asarray(y, float)[start:]
    T = 2 * np.pi / omega
    bins = int(bins or min(max(round(T / dt), 8), 2000))
    t = (np.arange(y.size) + start) * dt
    k = np.minimum((np.mod(t, T) / T * bins).astype(int), bins - 1)
    ok = np.isfinite(y)                      # ground truth may be stored for the last periods only
    k, y = k[ok], y[ok]
    cnt = np.bincount(k, minlength=bins)
    s = np.bincount(k, weights=y, minlength=bins)
    with np.errstate(invalid="ignore", divide="ignore"):
        m = s / cnt
    return (np.arange(bins) + 0.5) * T / bins, m, cnt


def harmonic_series(t, omega: float, coef, dc: float = 0.0, ks=None):
    """``dc + sum_k Im(C_k e^{j k omega t})`` = ``dc + sum_k s_k sin(k omega t + psi_k)`` (eq. 21)."""
    coef = np.asarray(coef, complex)
    ks = np.arange(1, coef.size + 1) if ks is None else np.asarray(ks)
    t = np.asarray(t, float)
    return dc + np.imag(np.exp(1j * omega * np.outer(t, ks)) @ coef)


def _fold(rec: Record, omega: float, start: int):
    """``(t, y, x, raw)``: the period average of ``y`` (eq. 23a), ``x`` on the same phase grid, and
    the first steady-state period of ``y`` (None if the record is shorter)."""
    period = 2 * np.pi / omega
    t_fold, y_fold, _ = fold_period(rec.y, rec.dt, omega, start)
    x_fold = None
    if rec.x is not None:
        # x is noise-free and T-periodic: interpolate it on phase (it may be stored for the last
        # periods only, which would leave phase bins empty if folded)
        idx = np.flatnonzero(np.isfinite(rec.x))
        idx = idx[idx >= start]
        if idx.size:
            phase = np.mod(idx * rec.dt, period)
            order = np.argsort(phase)
            x_fold = np.interp(t_fold, phase[order], rec.x[idx][order], period=period)
    n_period = int(np.ceil(period / rec.dt))
    raw = (np.arange(n_period) * rec.dt, rec.y[start:start + n_period]) if rec.y.size >= start + n_period else None
    return t_fold, y_fold, x_fold, raw


def _h_degree(run: RunData) -> int | None:
    """Degree of h: stage 1's, else the true polynomial's (None for a piecewise truth)."""
    if run.nonlinear is not None:
        return run.nonlinear.degree
    if run.truth is not None and isinstance(run.truth.output, PolynomialH):
        return len(run.truth.output.coefficients) - 1 or None
    return None


def sine_views(run: RunData) -> list[SineView]:
    """The sine experiments by frequency: folded, with stage 2's stored harmonic fit at that
    frequency (:func:`measured_harmonics` without one) and the truth's harmonics when ``x`` is known."""
    records = sorted((r for n, r in run.records.items() if n.startswith("sine_")),
                     key=lambda r: float(r.attrs.get("omega", 0)))
    frequencies = run.linear.frequencies if run.linear is not None else np.array([])
    degree = _h_degree(run)
    out = []
    for rec in records:
        omega = float(rec.attrs["omega"])
        period = 2 * np.pi / omega
        start = int(np.ceil(int(rec.attrs.get("lead_in_periods", 0)) * period / rec.dt - 1e-9))
        t_fold, y_fold, x_fold, raw = _fold(rec, omega, start)
        k_max = int(max(3, min((degree or 5) + 2, np.floor(np.pi / (omega * rec.dt)) - 1)))
        at = np.flatnonzero(np.isclose(frequencies, omega, rtol=1e-9))
        if at.size:
            ks, coef, se, model, dc = stored_harmonics(run.linear.harmonics[int(at[0])])
            model_dc = dc
        else:
            ks = np.arange(1, k_max + 1)
            coef, dc, se = measured_harmonics(rec, omega, start, k_max)
            model, model_dc = None, 0.0
        truth_coef, truth_dc = None, 0.0
        if rec.x is not None:
            coef_x, truth_dc = true_harmonics(rec, omega, start, int(ks.max()))
            truth_coef = coef_x[ks - 1]
        out.append(SineView(rec.name, omega, float(rec.attrs.get("amplitude", 1.0)), rec.dt, start, t_fold,
                            y_fold, x_fold, raw, ks, coef, se, dc, model, model_dc, truth_coef, truth_dc))
    return out


# --------------------------------------------------------------------------------- stage 2, truth

def parametric_block(lin: LinearResult) -> LinearBlock | None:
    """Stage 2's parametric fit as a :class:`LinearBlock`; None when it made none (``parametric`` is
    empty when the fit was not asked for, and has empty ``num`` with an ``error`` when it failed)."""
    par = lin.parametric
    if np.size(par.get("num", [])) == 0 or np.size(par.get("den", [])) == 0:
        return None
    return LinearBlock(tuple(float(c) for c in np.ravel(par["num"])), tuple(float(c) for c in np.ravel(par["den"])),
                       float(par["delay"]))


def true_phase_lag(block: LinearBlock, omegas) -> np.ndarray:
    """``phi(omega) = -arg G(j omega)`` of a known ``G``, unwrapped along ``(0, omega]`` (Table 2)."""
    return np.array([float(-np.unwrap(np.angle(block.freqresp(np.linspace(0, w, 512)[1:])))[-1])
                     for w in omegas])
