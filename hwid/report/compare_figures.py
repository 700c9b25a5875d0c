"""``hwid compare``'s figures: the model's free run against each experiment, and the residual tests
drawn as the System Identification Toolbox's ``resid`` draws them.

* :func:`plot_experiment`: measured output and the model's free run overlaid, the residual
  ``e = y - y_hat`` beneath, time in seconds.
* :func:`residual_correlation` and :func:`plot_residual_tests`: the residual's autocorrelation
  (lags ``1..M``) and its cross-correlation with the input (lags ``-M..M``), pooled over the
  experiments, with their 99 % bands (:data:`Z99`):

  - autocorrelation: ``+-Z99 / sqrt(N)``, the band of a white sequence of ``N`` samples (a sample
    autocorrelation of white noise is asymptotically normal with variance ``1/N``);
  - cross-correlation: ``+-Z99 sqrt(P / N)`` with ``P = sum_k r_e(k) r_u(k)`` (Ljung, *System
    Identification*, 2nd ed., Section 16.6): the variance of ``r_eu`` when ``e`` is independent of
    ``u``; ``P = 1`` when the residual is white, so the band is then ``+-Z99 / sqrt(N)`` too.

  Where the sampling is much faster than the model's dynamics, 25 lags of ``dt`` see only the
  first instants of the model's memory; the residual and the input are then decimated (every
  ``step``-th sample, no filter, so a white residual stays white) so that the ``M`` lags span the
  settling time of G (:func:`hwid.adequacy.lag_step`), and the lag axis says so. The p-values
  are :func:`hwid.adequacy.residual_tests` on the same samples: the numbers of ``hwid compare``'s JSON.
* :func:`with_figures`: writes the figures into ``OUT/figures/`` (atomically) and returns the
  comparison with their paths under ``figures``.

Every plotting function returns a :class:`matplotlib.figure.Figure` made without ``pyplot`` (saved
through the Agg canvas) and never shows it.
"""
from __future__ import annotations

import dataclasses
import io
import os
import re
from dataclasses import dataclass
from pathlib import Path
from typing import Mapping, Sequence

import numpy as np
from matplotlib.figure import Figure

from hwid.adequacy import MAX_LAG, lag_step, residual_tests, settling_time
from hwid.report.figures import decimate_envelope

#: two-sided 99 % normal quantile: ``resid``'s confidence level
Z99 = 2.5758293035489004
#: figures' folder inside the output directory
FIGURES_DIR = "figures"


@dataclass(frozen=True)
class ResidualCorrelation:
    """The residual tests as drawn: pooled correlations, their 99 % bands, and the tests' p-values on
    the same (possibly decimated) samples."""

    auto_lags: np.ndarray           # 1..M
    auto: np.ndarray                # r_e(k)
    auto_band: float                # Z99 / sqrt(N)
    cross_lags: np.ndarray          # -M..M
    cross: np.ndarray               # r_eu(k): e(t) against u(t - k)
    cross_band: float               # Z99 sqrt(P / N)
    samples: int                    # N, after decimation, over the experiments drawn
    experiments: int                # experiments long enough to draw
    step: int                       # decimation: every step-th sample
    dt: float                       # the records' sample time, s
    whiteness_p: float              # Ljung-Box (hwid.adequacy.ljung_box) on the drawn samples
    input_correlation_p: float      # hwid.adequacy.input_correlation on the drawn samples

    def to_dict(self) -> dict:
        return {"auto_lags": self.auto_lags.tolist(), "auto": self.auto.tolist(), "auto_band": self.auto_band,
                "cross_lags": self.cross_lags.tolist(), "cross": self.cross.tolist(), "cross_band": self.cross_band,
                "samples": self.samples, "experiments": self.experiments, "step": self.step, "dt": self.dt,
                "whiteness_p": self.whiteness_p, "input_correlation_p": self.input_correlation_p}


# ------------------------------------------------------------------------------- the statistics

def _correlations(x: np.ndarray, z: np.ndarray, lags: np.ndarray) -> np.ndarray:
    """``sum_t x(t) z(t - k) / sqrt(sum x^2 sum z^2)`` for each lag ``k`` (means removed before)."""
    n = x.size
    scale = np.sqrt(float(x @ x) * float(z @ z)) or 1.0
    return np.array([float(x[k:] @ z[:n - k]) if k >= 0 else float(x[:n + k] @ z[-k:]) for k in lags]) / scale


def residual_correlation(residuals: Sequence, inputs: Sequence, step: int = 1, max_lag: int = MAX_LAG,
                         dt: float = 1.0) -> ResidualCorrelation:
    """The residuals' autocorrelation and cross-correlation with the inputs, one experiment per item,
    on every ``step``-th sample, pooled over the experiments (each weighted by its samples) with the
    99 % bands of the module's docstring; experiments with no more than ``2 max_lag`` samples after
    decimation are left out of the correlations. The p-values are
    :func:`hwid.adequacy.residual_tests` with the same ``step``: those of ``hwid compare``'s JSON."""
    auto_lags, cross_lags = np.arange(1, max_lag + 1), np.arange(-max_lag, max_lag + 1)
    auto, cross = np.zeros(max_lag), np.zeros(cross_lags.size)
    n_total, p_weighted, used = 0, 0.0, 0
    for e_full, u_full in zip(residuals, inputs):
        e = np.asarray(e_full, float)[::step]
        u = np.asarray(u_full, float)[::step]
        if e.size <= 2 * max_lag:
            continue
        e, u = e - e.mean(), u - u.mean()
        r_e = _correlations(e, e, np.arange(max_lag + 1))
        r_u = _correlations(u, u, np.arange(max_lag + 1))
        n = e.size
        auto += n * r_e[1:]
        cross += n * _correlations(e, u, cross_lags)
        p_weighted += n * max(0.0, float(r_e[0] * r_u[0] + 2.0 * np.sum(r_e[1:] * r_u[1:])))
        n_total += n
        used += 1
    if n_total:
        auto, cross = auto / n_total, cross / n_total
    n_eff = max(n_total, 1)
    white_p, input_p = residual_tests(residuals, inputs, step, max_lag)
    return ResidualCorrelation(
        auto_lags, auto, Z99 / np.sqrt(n_eff), cross_lags, cross, Z99 * np.sqrt(p_weighted) / n_eff,
        n_total, used, int(step), float(dt),
        float("nan") if white_p is None else white_p, float("nan") if input_p is None else input_p)


# ---------------------------------------------------------------------------------- the figures

def plot_experiment(name: str, t, y, y_hat, fit_percent: float | None = None,
                    noise_floor: float | None = None) -> Figure:
    """One experiment: the measured ``y`` and the model's free run ``y_hat`` overlaid (top), the
    residual ``y - y_hat`` beneath (with ``+-noise_floor`` dashed where it is known); time in s."""
    t, y, y_hat = (np.asarray(a, float) for a in (t, y, y_hat))
    fig = Figure(figsize=(8.0, 4.8), layout="constrained")
    top, bottom = fig.subplots(2, 1, sharex=True, height_ratios=(2, 1))
    top.plot(*decimate_envelope(t, y), lw=0.7, color="0.45", label="measured y", gid="measured")
    top.plot(*decimate_envelope(t, y_hat), lw=1.0, color="tab:red", label="model, free run", gid="model")
    top.set_ylabel("y")
    top.legend(fontsize=8, loc="best")
    residual = y - y_hat
    rms = float(np.sqrt(np.mean(residual ** 2))) if residual.size else float("nan")
    bottom.plot(*decimate_envelope(t, residual), lw=0.6, color="tab:blue", label="residual", gid="residual")
    bottom.axhline(0.0, color="k", lw=0.5)
    if noise_floor:
        for sign in (1, -1):
            bottom.axhline(sign * noise_floor, color="k", ls="--", lw=0.9, zorder=3,
                           label="+- noise floor" if sign > 0 else None, gid="noise_floor")
        bottom.legend(fontsize=7, loc="upper right")
    bottom.set_ylabel("y - model")
    bottom.set_xlabel("t [s]")
    fit = "" if fit_percent is None else f": fit {fit_percent:.1f} %"
    top.set_title(f"{name}{fit}, RMS residual {rms:.4g}", fontsize=10)
    return fig


def lag_label(corr: ResidualCorrelation) -> str:
    """The lag axis's label: samples of ``dt``, or of the decimated residual."""
    if corr.step == 1:
        return f"lag [samples, dt = {corr.dt:.4g} s]"
    return (f"lag [x {corr.step} samples = {corr.step * corr.dt:.4g} s]\nresidual decimated: "
            f"{corr.auto_lags.size} lags span G's settling time")


def plot_residual_tests(corr: ResidualCorrelation) -> Figure:
    """``resid``'s two panels: the residual's autocorrelation and its cross-correlation with the
    input, bars against the grey 99 % band (pooled over ``corr.experiments`` experiments)."""
    fig = Figure(figsize=(9.0, 3.8), layout="constrained")
    auto_ax, cross_ax = fig.subplots(1, 2)
    auto_ax.vlines(corr.auto_lags, 0, corr.auto, color="tab:blue", lw=1.5, gid="autocorrelation")
    auto_ax.plot(corr.auto_lags, corr.auto, "o", ms=3, color="tab:blue")
    cross_ax.vlines(corr.cross_lags, 0, corr.cross, color="tab:green", lw=1.5, gid="cross_correlation")
    cross_ax.plot(corr.cross_lags, corr.cross, "o", ms=3, color="tab:green")
    panels = ((auto_ax, corr.auto_band, f"residual autocorrelation; Ljung-Box p = {corr.whiteness_p:.3g}"),
              (cross_ax, corr.cross_band,
               f"residual vs input u(t-k); p = {corr.input_correlation_p:.3g} (k >= 0)"))
    for ax, band, title in panels:
        ax.axhspan(-band, band, color="0.85", zorder=0, gid="band", label=f"99 % band (+-{band:.3g})")
        ax.axhline(0.0, color="k", lw=0.5)
        ax.set_title(title, fontsize=9)
        ax.set_xlabel(lag_label(corr), fontsize=8)
        ax.legend(fontsize=7, loc="upper right")
        bars = corr.auto if ax is auto_ax else corr.cross
        reach = max(1.6 * band, 1.15 * float(np.max(np.abs(bars), initial=0.0)))
        ax.set_ylim(-reach, reach)
    auto_ax.set_ylabel("correlation")
    fig.suptitle(f"Residual tests (resid): {corr.experiments} experiment(s), N = {corr.samples} samples",
                 fontsize=10)
    return fig


# ----------------------------------------------------------------------------------- writing

def safe_name(name: str) -> str:
    """``name`` with anything but letters, digits, ``_``, ``-`` and ``.`` replaced by ``_``."""
    return re.sub(r"[^A-Za-z0-9_.-]", "_", str(name)) or "experiment"


def _write_png(fig: Figure, path: Path) -> None:
    """``fig`` as PNG (Agg canvas) at ``path``, written to ``path.tmp`` and moved into place."""
    buf = io.BytesIO()
    fig.savefig(buf, format="png", dpi=100)
    tmp = path.with_name(path.name + ".tmp")
    tmp.write_bytes(buf.getvalue())
    os.replace(tmp, path)


def compare_figures(model, records: Sequence, sims: Mapping, result) -> dict[str, Figure]:
    """The figures of one comparison by file name: ``compare_<experiment>.png`` per experiment and
    ``compare_residual_tests.png``; the residual tests decimated by :func:`hwid.adequacy.lag_step` over the
    settling time of ``model``'s G."""
    fits = {e.name: e.fit_percent for e in result.experiments}
    out = {}
    for rec in records:
        out[f"compare_{safe_name(rec.name)}.png"] = plot_experiment(
            rec.name, rec.t, rec.y, sims[rec.name], fits.get(rec.name), result.noise_floor)
    dt = float(records[0].dt) if records else 1.0
    corr = residual_correlation([rec.y - sims[rec.name] for rec in records], [rec.u for rec in records],
                                step=getattr(result, "lag_step", None) or lag_step(dt, settling_time(model)), dt=dt)
    out["compare_residual_tests.png"] = plot_residual_tests(corr)
    return out


def with_figures(result, out_dir, model, records: Sequence, sims: Mapping):
    """Write the comparison's figures into ``OUT/figures/`` and return ``result`` with their paths
    (relative to ``OUT``) under ``figures``."""
    folder = Path(out_dir) / FIGURES_DIR
    folder.mkdir(parents=True, exist_ok=True)
    written = []
    for file_name, fig in compare_figures(model, records, sims, result).items():
        _write_png(fig, folder / file_name)
        written.append(f"{FIGURES_DIR}/{file_name}")
    return dataclasses.replace(result, figures=tuple(written))
