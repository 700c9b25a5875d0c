"""The report's figures (paper Figs. 9-16, Bode, batch summaries, the diagnosis), one function per
figure, each on plain data.

Every function takes ``ax=None`` (or a pair of axes for two-panel figures), draws, and returns the
:class:`matplotlib.figure.Figure`; none shows it. Figures are created with
:class:`matplotlib.figure.Figure` directly, not through ``pyplot``, so there is no global figure
state and saving uses the Agg (PNG) and SVG canvases whatever the session's backend.

Artists carry labels (``Line2D.get_label()``) and ``gid`` s so tests and readers can find the curve
they mean: ``"truth"``, ``"estimate"``, ``"band"``, ``"points"``, ``"parametric"``...
"""
from __future__ import annotations

from typing import Callable, Mapping, Sequence

import numpy as np
from matplotlib.colors import LogNorm
from matplotlib.figure import Figure
from matplotlib.ticker import FormatStrFormatter, LogLocator, NullFormatter

Z95 = 1.959963984540054     # two-sided 95 % normal quantile

C_EST = "#1f77b4"      # estimate
C_TRUE = "#444444"     # truth
C_PAPER = "#d62728"    # the paper's values
C_DATA = "#7f7f7f"     # raw measurements
C_WIN = "#ff7f0e"      # steady-state windows / X_hat


def _axes(ax, n: int = 1, figsize=(7.0, 3.6), sharex: bool = True):
    """``(fig, axes)``: new figure with ``n`` stacked axes, or the figure of the given axes."""
    if ax is None:
        # fixed margins (in inches) rather than a layout engine: these figures have a known shape,
        # and constrained layout costs more than drawing them
        w, h = figsize
        fig = Figure(figsize=figsize)
        fig.subplots_adjust(left=0.8 / w, right=1 - 0.15 / w, bottom=0.5 / h, top=1 - 0.32 / h,
                            hspace=0.12 if sharex else 0.3)
        axes = fig.subplots(n, 1, sharex=sharex, squeeze=False)[:, 0]
        return fig, list(axes)
    axes = list(ax) if isinstance(ax, (list, tuple, np.ndarray)) else [ax]
    if len(axes) != n:
        raise ValueError(f"this figure needs {n} axes, got {len(axes)}")
    return axes[0].figure, axes


def _errorbar(ax, *args, gid=None, **kw):
    """``ax.errorbar`` with ``gid`` on the data line only (not on the caps and bars)."""
    cont = ax.errorbar(*args, **kw)
    if gid is not None:
        cont.lines[0].set_gid(gid)
    return cont


def decimate_envelope(t, y, max_points: int = 4000):
    """Reduce a long signal to at most ``max_points`` points, keeping each bucket's min and max
    (the plotted envelope is the same as the full signal's at screen resolution)."""
    t = np.asarray(t, float)
    y = np.asarray(y, float)
    n = y.size
    if n <= max_points:
        return t, y
    b = max_points // 2
    edges = np.linspace(0, n, b + 1).astype(int)
    lo = np.minimum.reduceat(y, edges[:-1])
    hi = np.maximum.reduceat(y, edges[:-1])
    ilo = np.array([s + np.argmin(y[s:e]) for s, e in zip(edges[:-1], edges[1:])])
    ihi = np.array([s + np.argmax(y[s:e]) for s, e in zip(edges[:-1], edges[1:])])
    first = ilo <= ihi
    idx = np.empty(2 * b, dtype=int)
    idx[0::2] = np.where(first, ilo, ihi)
    idx[1::2] = np.where(first, ihi, ilo)
    del lo, hi
    return t[idx], y[idx]


# ------------------------------------------------------------------ staircases (Figs. 10, 11, 13, 14)

def plot_staircase_input(t, u, levels=None, level_spans=None, title: str = "Staircase input",
                         ax=None) -> Figure:
    """The piecewise-constant input ``u(t)`` of eq. (6) or (13) (paper Figs. 10, 13).

    Parameters
    ----------
    t, u : array
        Time (s) and input samples.
    levels : array, optional
        ``U_j`` of the staircase proper (lead-in excluded), annotated at their spans.
    level_spans : sequence of (t0, t1), optional
        Time span (s) of each level in ``levels``.
    """
    fig, (a,) = _axes(ax)
    tt, uu = decimate_envelope(t, u)
    a.plot(tt, uu, color=C_EST, lw=1.2, label="u(t)", gid="input")
    if levels is not None and level_spans is not None:
        for U, (t0, t1) in zip(levels, level_spans):
            a.annotate(f"{U:g}", ((t0 + t1) / 2, U), textcoords="offset points", xytext=(0, 4),
                       ha="center", fontsize=7, color="0.3")
    a.set_xlabel("t (s)")
    a.set_ylabel("u")
    a.set_title(title)
    a.grid(alpha=0.3)
    return fig


def plot_staircase_output(t, y, windows=None, X_hat=None, X_hat_ci=None, x_true=None, flat=None,
                          title: str = "Staircase output", ax=None) -> Figure:
    """The measured output ``y(t)`` with the steady-state windows and ``X_hat_j`` (Figs. 11, 14, eq. 9).

    Parameters
    ----------
    t, y : array
        Time (s) and measured output.
    windows : sequence of (t0, t1), optional
        The averaging window of each level (shaded); ``X_hat[j]`` is drawn across window ``j``.
    X_hat, X_hat_ci : array, optional
        Estimated steady-state outputs and their 95 % half-widths (drawn as error bars).
    x_true : array, optional
        The undisturbed output ``x(t)`` (simulated plants).
    flat : int, optional
        ``j_a`` / ``j_d``: the number of leading levels on the flat path (eqs. 7a, 14a), marked.
    """
    fig, (a,) = _axes(ax)
    tt, yy = decimate_envelope(t, y)
    a.plot(tt, yy, color=C_DATA, lw=0.6, label="y(t) measured", gid="measured")
    if x_true is not None:
        tx, xx = decimate_envelope(t, x_true)
        a.plot(tx, xx, color=C_TRUE, lw=1.0, ls="--", label="x(t) true", gid="truth")
    if windows is not None:
        for i, (t0, t1) in enumerate(windows):
            a.axvspan(t0, t1, color=C_WIN, alpha=0.12, lw=0, label="steady-state window" if i == 0 else None)
        if X_hat is not None:
            X_hat = np.asarray(X_hat, float)
            mids = np.array([(w0 + w1) / 2 for w0, w1 in windows])
            a.hlines(X_hat, [w[0] for w in windows], [w[1] for w in windows], color=C_WIN, lw=2.0,
                     label=r"$\hat X_j$", gid="X_hat")
            if X_hat_ci is not None:
                _errorbar(a, mids, X_hat, yerr=np.asarray(X_hat_ci, float), fmt="none", ecolor=C_WIN,
                           capsize=3, lw=1.0)
            if flat is not None and 0 < flat <= len(windows):
                a.axvline(windows[flat - 1][1], color="k", lw=0.8, ls=":", gid="flat")
                a.annotate(f"flat path: j ≤ {flat}", (windows[flat - 1][1], 1.0), xycoords=("data", "axes fraction"),
                           xytext=(3, -12), textcoords="offset points", fontsize=7)
    a.set_xlabel("t (s)")
    a.set_ylabel("y")
    a.set_title(title)
    a.grid(alpha=0.3)
    a.legend(fontsize=7, loc="best")
    return fig


# ------------------------------------------------------------------------------ h (Fig. 12)

def poly_band(coefficients, cov, w, z: float = Z95):
    """``h(w)`` and the half-width ``z sqrt(phi(w)^T Sigma phi(w))`` with ``phi = (1, w, w^2, ...)``:
    the delta-method band of a polynomial whose ascending coefficients have covariance ``cov``."""
    c = np.asarray(coefficients, float)
    w = np.asarray(w, float)
    Phi = w[:, None] ** np.arange(c.size)
    h = Phi @ c
    if cov is None:
        return h, None
    cov = np.asarray(cov, float)
    var = np.einsum("ni,ij,nj->n", Phi, cov, Phi)
    return h, z * np.sqrt(np.clip(var, 0.0, None))


def plot_h(coefficients, cov=None, w_range=None, truth: Callable | Sequence[float] | None = None,
           points: Mapping[str, tuple] | None = None, n_grid: int = 400, title: str | None = None,
           w_plot: tuple[float, float] | None = None, ax=None) -> Figure:
    """The estimated output nonlinearity ``h_bar`` with its 95 % band against the truth (Fig. 12).

    Parameters
    ----------
    coefficients : array
        Ascending coefficients of the estimate ``h_hat``.
    cov : array, optional
        Their covariance; the band is ``h_hat(w) +- 1.96 sd`` (delta method, :func:`poly_band`).
    w_range : (float, float), optional
        Range of ``w`` over which ``h`` was identified (default: the points' range, or [-1, 1]).
    truth : callable or array, optional
        ``h_bar`` of the true normalised model (eq. 4c): a function of ``w``, or its ascending
        coefficients. Drawn with ``gid="truth"`` on the same grid as the estimate.
    points : mapping label -> (w_j, X_hat_j[, ci_j]), optional
        The staircase points mapped to the ``w`` axis (``U_j - d_hat^+`` for the ascending ones, eq. 8b).
    w_plot : (float, float), optional
        Draw over this wider range too (e.g. the ``[-U|G|, U|G|]`` the sines drive ``w`` over), so
        any extrapolation of ``h`` outside ``w_range`` (shaded) shows.
    """
    fig, (a,) = _axes(ax, figsize=(6.0, 4.2))
    if w_range is None:
        ws = [np.asarray(p[0], float) for p in (points or {}).values() if len(p[0])]
        w_range = (min(x.min() for x in ws), max(x.max() for x in ws)) if ws else (-1.0, 1.0)
    lo, hi = float(w_range[0]), float(w_range[1])
    pad = 0.05 * (hi - lo or 1.0)
    a_lo, a_hi = lo - pad, hi + pad
    if w_plot is not None:
        a_lo, a_hi = min(a_lo, float(w_plot[0])), max(a_hi, float(w_plot[1]))
    w = np.linspace(a_lo, a_hi, n_grid)
    h, half = poly_band(coefficients, cov, w)
    if half is not None:
        a.fill_between(w, h - half, h + half, color=C_EST, alpha=0.25, lw=0, label="95 % band", gid="band")
    a.plot(w, h, color=C_EST, lw=2.4, alpha=0.8, label=r"$\hat h$ estimate", gid="estimate")
    if truth is not None:
        ht = truth(w) if callable(truth) else np.polynomial.polynomial.polyval(w, np.asarray(truth, float))
        a.plot(w, ht, color=C_TRUE, lw=1.2, ls="--", label=r"$\bar h$ true", gid="truth", zorder=4)
    markers = iter(["o", "s", "^", "D"])
    for label, p in (points or {}).items():
        pw, px = np.asarray(p[0], float), np.asarray(p[1], float)
        ci = np.asarray(p[2], float) if len(p) > 2 and p[2] is not None else None
        _errorbar(a, pw, px, yerr=ci, fmt=next(markers, "o"), ms=5, mfc="white", capsize=2, lw=1,
                   label=label, gid="points")
    a.axvspan(lo, hi, color="0.9", zorder=-5, lw=0)
    a.axhline(0, color="0.6", lw=0.6)
    a.set_xlabel("w")
    a.set_ylabel("h(w)")
    a.set_title(title or r"Output nonlinearity $\bar h$ (Fig. 12)")
    a.grid(alpha=0.3)
    a.legend(fontsize=7)
    return fig


# ------------------------------------------------------------------------ borders (Fig. 9)

def _cycle(f, lo: float, hi: float, n: int = 400):
    """The closed cycle of the operator ``f`` (an :class:`hwid.model.InputNonlinearity`) over ``[lo, hi]``."""
    u = np.concatenate([np.linspace(lo, hi, n), np.linspace(hi, lo, n), np.linspace(lo, hi, n)])
    v = f.apply(u)
    return u[n:], v[n:]


def plot_borders(estimate=None, truth=None, u_range=(-1.5, 1.5), ci: Mapping[str, tuple] | None = None,
                 title: str | None = None, ax=None) -> Figure:
    """The estimated ascending and descending borders against the truth (Fig. 9).

    Parameters
    ----------
    estimate, truth : :class:`hwid.model.InputNonlinearity`, optional
        Normalised input nonlinearities (eq. 4a). Each is drawn as its two borders
        (``ascending(u)``, ``descending(u)``) and its closed cycle over ``u_range``.
    ci : mapping, optional
        ``{"d_plus": (lo, hi), "d_minus": (lo, hi)}``: drawn as horizontal bars where the estimated
        borders cross ``v = 0`` (a Backlash's ``d^+`` and ``d^-``).
    """
    fig, (a,) = _axes(ax, figsize=(5.6, 4.6))
    lo, hi = u_range
    u = np.linspace(lo, hi, 200)
    for f, color, ls, name in ((estimate, C_EST, "-", "estimated"), (truth, C_TRUE, "--", "true")):
        if f is None:
            continue
        lw, z = (2.4, 2) if f is estimate else (1.2, 4)
        a.plot(u, f.ascending(u), color=color, ls=ls, lw=lw, zorder=z, label=f"ascending border, {name}",
               gid=f"{'truth' if f is truth else 'estimate'}_ascending")
        a.plot(u, f.descending(u), color=color, ls=ls, lw=lw, zorder=z, alpha=0.55,
               label=f"descending border, {name}", gid=f"{'truth' if f is truth else 'estimate'}_descending")
        cu, cv = _cycle(f, lo, hi)
        a.plot(cu, cv, color=color, ls=ls, lw=0.8, alpha=0.5, gid=f"{'truth' if f is truth else 'estimate'}_cycle")
    if estimate is not None and ci and estimate.type == "backlash":
        for key in ("d_plus", "d_minus"):
            if key in ci and ci[key] is not None:
                l, h = ci[key]
                _errorbar(a, [getattr(estimate, key)], [0.0], xerr=[[getattr(estimate, key) - l], [h - getattr(estimate, key)]],
                           fmt="o", color=C_EST, capsize=3, ms=4, gid=f"ci_{key}")
    a.axhline(0, color="0.6", lw=0.6)
    a.axvline(0, color="0.6", lw=0.6)
    a.set_xlabel("u")
    a.set_ylabel("v = F̄[u]")
    kind = (estimate or truth).type.replace("_", "-") if (estimate or truth) is not None else ""
    a.set_title(title or f"Input nonlinearity borders ({kind}, Fig. 9)")
    a.grid(alpha=0.3)
    a.legend(fontsize=7)
    return fig


# -------------------------------------------------------------------- sines (Figs. 15, 16)

def plot_period(t, x_hat, omega: float, model=None, truth=None, raw=None, title: str | None = None,
                ax=None) -> Figure:
    """One period of the averaged output ``x_hat_N(t)`` (eq. 23a, Fig. 15b) with the fitted harmonic
    model (eq. 20) and, when known, the undisturbed output ``x(t)``.

    Parameters
    ----------
    t, x_hat : array
        Time within the period (s, in ``[0, T)``) and the period average.
    model, truth : array, optional
        The fitted model and the true ``x(t)`` on the same ``t``.
    raw : (t, y), optional
        One period of the raw measurement (Fig. 15a), drawn faintly.
    """
    fig, (a,) = _axes(ax)
    if raw is not None:
        rt, ry = decimate_envelope(*raw)
        a.plot(rt, ry, color=C_DATA, lw=0.5, alpha=0.5, label="y(t), one period", gid="raw")
    a.plot(t, x_hat, color=C_WIN, lw=1.0, label=r"$\hat x_N(t)$ period average", gid="average")
    if model is not None:
        a.plot(t, model, color=C_EST, lw=1.6, label="harmonic model", gid="model")
    if truth is not None:
        a.plot(t, truth, color=C_TRUE, lw=1.0, ls="--", label="x(t) true", gid="truth")
    a.set_xlabel("t (s) within one period")
    a.set_ylabel("output")
    a.set_title(title or f"One period, ω = {omega:g} rad/s (Fig. 15)")
    a.grid(alpha=0.3)
    a.legend(fontsize=7)
    return fig


def plot_spectrum(ks, coef, se=None, model=None, truth=None, dc=None, title: str | None = None,
                  ax=None) -> Figure:
    """Modulus ``s_k`` and phase ``psi_k`` of the harmonics of ``x_hat_N`` (eqs. 26a-b, Fig. 16a-b).

    Parameters
    ----------
    ks : array of int
        Harmonic numbers.
    coef : complex array
        Measured ``C_k = s_k e^{j psi_k}``.
    se : array, optional
        Standard error of each real component of ``C_k``; the modulus bars are ``1.96 se`` and the
        phase bars ``1.96 se / s_k``.
    model, truth : complex array, optional
        ``C_k`` of the fitted harmonic model and of the true ``x(t)``.
    """
    fig, (am, ap) = _axes(ax, 2, figsize=(6.4, 5.0))
    ks = np.asarray(ks)
    coef = np.asarray(coef, complex)
    s = np.abs(coef)
    err = None if se is None else Z95 * np.asarray(se, float)
    am.bar(ks, s, width=0.5, color=C_WIN, alpha=0.7, label=r"$\hat s_k$ measured", gid="measured")
    if err is not None:
        _errorbar(am, ks, s, yerr=err, fmt="none", ecolor="k", capsize=3, lw=0.8)
    if model is not None:
        am.plot(ks, np.abs(model), "o", color=C_EST, mfc="none", ms=7, label="model", gid="model")
    if truth is not None:
        am.plot(ks, np.abs(truth), "x", color=C_TRUE, ms=7, label="true", gid="truth")
    am.set_ylabel(r"$s_k$")
    am.set_yscale("log")
    top = float(np.nanmax(s)) if s.size else 1.0
    pos = s[s > 0]
    if top > 0 and pos.size:
        am.set_ylim(max(pos.min() / 10, 1e-7 * top), top * 3)
    am.grid(alpha=0.3, which="both")
    am.legend(fontsize=7)
    am.set_title(title or "Harmonic spectrum (Fig. 16)")
    # phase only where the harmonic stands out of the noise
    sig = s > (err if err is not None else 0.0)
    perr = None if err is None else np.where(sig, err / np.where(s > 0, s, 1), np.nan)
    _errorbar(ap, ks[sig], np.angle(coef)[sig], yerr=None if perr is None else perr[sig], fmt="s", color=C_WIN,
                capsize=3, ms=5, label=r"$\hat\psi_k$", gid="measured_phase")
    if model is not None:
        mo = np.asarray(model, complex)
        keep = np.abs(mo) > 1e-9 * max(float(np.abs(mo).max()), 1e-300)     # a zero harmonic has no phase
        ap.plot(ks[keep], np.angle(mo)[keep], "o", color=C_EST, mfc="none", ms=7, label="model", gid="model_phase")
    if truth is not None:
        tr = np.asarray(truth, complex)
        keep = np.abs(tr) > 1e-9 * max(float(np.abs(tr).max()), 1e-300)   # phase of a zero is noise
        ap.plot(ks[keep], np.angle(tr)[keep], "x", color=C_TRUE, ms=7, label="true", gid="truth_phase")
    ap.set_ylim(-np.pi * 1.1, np.pi * 1.1)
    ap.set_ylabel(r"$\psi_k$ (rad)")
    ap.set_xlabel("harmonic k")
    ap.set_xticks(ks)
    ap.grid(alpha=0.3)
    return fig


# ----------------------------------------------------------------------------------- Bode

def _freqresp(g, omega):
    if g is None:
        return None
    if callable(g) and not hasattr(g, "freqresp"):
        return np.asarray(g(omega), complex)
    if hasattr(g, "freqresp"):
        return np.asarray(g.freqresp(omega), complex)
    s = 1j * np.asarray(omega, float)
    return (np.polyval(np.asarray(g["num"], float), s) / np.polyval(np.asarray(g["den"], float), s)
            * np.exp(-s * float(g.get("delay", 0.0) or 0.0)))


def plot_bode(omega, gain, phase, gain_ci=None, phase_ci=None, parametric=None, truth=None,
              omega_grid=None, title: str | None = None, ax=None) -> Figure:
    """Bode plot of the estimates ``|G_hat(j omega_i)|`` and ``phi_hat(omega_i) = -arg G_hat`` with
    their intervals, the parametric fit and the truth.

    Parameters
    ----------
    omega, gain, phase : array
        Frequencies (rad/s), gain estimates and phase lags ``phi = -arg G`` (rad), as in Table 2.
    gain_ci, phase_ci : (lo, hi) arrays, optional
        95 % intervals, drawn as bars.
    parametric, truth : optional
        Anything with ``freqresp(omega) -> complex`` (e.g. :class:`hwid.blocks.linear.LinearBlock`),
        a callable, or a dict with ``num``, ``den`` (descending powers) and ``delay``.
        Drawn on ``omega_grid`` (default: log grid around ``omega``); gids ``"parametric"``/``"truth"``
        (gain) and ``"parametric_phase"``/``"truth_phase"``.
    """
    fig, (ag, ap) = _axes(ax, 2, figsize=(6.4, 5.4))
    omega = np.asarray(omega, float)
    gain = np.asarray(gain, float)
    phase = np.asarray(phase, float)
    if omega_grid is None:
        lo, hi = (omega.min(), omega.max()) if omega.size else (0.01, 1.0)
        omega_grid = np.logspace(np.log10(lo) - 0.5, np.log10(hi) + 0.5, 300)
    for g, color, ls, name in ((parametric, C_EST, "-", "parametric"), (truth, C_TRUE, "--", "truth")):
        G = _freqresp(g, omega_grid)
        if G is None:
            continue
        lw, z = (2.4, 2) if name == "parametric" else (1.2, 4)
        ag.plot(omega_grid, np.abs(G), color=color, ls=ls, lw=lw, zorder=z, alpha=0.8 if z == 2 else 1,
                label="true G" if name == "truth" else "parametric fit", gid=name)
        ap.plot(omega_grid, -np.unwrap(np.angle(G)), color=color, ls=ls, lw=lw, zorder=z,
                alpha=0.8 if z == 2 else 1, gid=f"{name}_phase")

    def _yerr(v, ci):
        if ci is None:
            return None
        lo, hi = np.asarray(ci[0], float), np.asarray(ci[1], float)
        return np.vstack([np.clip(v - lo, 0, None), np.clip(hi - v, 0, None)])

    _errorbar(ag, omega, gain, yerr=_yerr(gain, gain_ci), fmt="o", color=C_WIN, capsize=3, ms=5, zorder=5,
                label=r"$|\hat G(j\omega_i)|$ ± 95 %", gid="estimate")
    _errorbar(ap, omega, phase, yerr=_yerr(phase, phase_ci), fmt="o", color=C_WIN, capsize=3, ms=5, zorder=5,
                label=r"$\hat\varphi(\omega_i)$ ± 95 %", gid="estimate_phase")
    ag.set_xscale("log")
    ag.set_yscale("log")
    # a gain axis often spans less than a decade: label 1-2-5 steps in plain numbers, no minor labels
    ag.yaxis.set_major_locator(LogLocator(subs=(1.0, 2.0, 5.0)))
    ag.yaxis.set_major_formatter(FormatStrFormatter("%g"))
    ag.yaxis.set_minor_formatter(NullFormatter())
    ag.set_ylabel(r"$|G(j\omega)|$")
    ag.set_title(title or r"Bode plot of $\bar G(j\omega)$")
    ag.grid(alpha=0.3, which="both")
    ag.legend(fontsize=7)
    ap.set_xscale("log")
    ap.set_ylabel(r"$\varphi = -\angle G$ (rad)")
    ap.set_xlabel(r"$\omega$ (rad/s)")
    ap.grid(alpha=0.3, which="both")
    return fig


# ------------------------------------------------------------------------------- batch summaries

def _sweep_axis(summary: Mapping):
    """x values and label for the summary's points: the first swept key's values if numeric, else
    the point index with the overrides as tick labels."""
    pts = summary.get("points", [])
    keys = list(summary.get("sweep_keys") or [])
    if len(keys) == 1:
        try:
            x = np.array([float(p["overrides"][keys[0]]) for p in pts])
            return x, keys[0], None
        except (KeyError, TypeError, ValueError):
            pass
    labels = [", ".join(f"{k}={v}" for k, v in (p.get("overrides") or {}).items()) or "base" for p in pts]
    return np.arange(len(pts), dtype=float), "sweep point", labels


def plot_batch_summary(summary: Mapping, names: Sequence[str] | None = None, ax=None) -> Figure:
    """RMSE (with the CRLB standard deviation as a dashed line) and 95 % interval coverage of each
    estimate against the swept key, from :func:`hwid.results.read_batch_summary`'s dict.

    RMSE is drawn relative to ``|truth|`` where the truth is nonzero (so estimates of different scale
    share one axis); the CRLB line is scaled the same way.
    """
    fig, (ar, ac) = _axes(ax, 2, figsize=(7.0, 6.0))
    pts = list(summary.get("points", []))
    x, xlabel, ticklabels = _sweep_axis(summary)
    if names is None:
        names = []
        for p in pts:
            for n in p.get("stats", {}):
                if n not in names:
                    names.append(n)
    order = np.argsort(x, kind="stable")
    colors = [f"C{i % 10}" for i in range(len(names))]
    for name, color in zip(names, colors):
        def col(field):
            out = []
            for p in pts:
                v = p.get("stats", {}).get(name, {}).get(field)
                out.append(np.nan if v is None else float(v))
            return np.array(out)
        truth = col("truth")
        scale = np.where(np.isfinite(truth) & (np.abs(truth) > 0), np.abs(truth), 1.0)
        rel = np.all(np.isfinite(truth) & (np.abs(truth) > 0))
        scale = scale if rel else np.ones_like(scale)
        rmse = col("rmse") / scale
        crlb = col("crlb_std") / scale
        ar.plot(x[order], rmse[order], "o-", color=color, ms=4, lw=1.2, label=name if rel else f"{name} (abs.)",
                gid=f"rmse:{name}")
        if np.any(np.isfinite(crlb)):
            ar.plot(x[order], crlb[order], "--", color=color, lw=1.0, gid=f"crlb:{name}")
        ac.plot(x[order], col("coverage")[order], "o-", color=color, ms=4, lw=1.2, gid=f"coverage:{name}")
    ac.axhline(0.95, color="k", lw=0.8, ls=":", gid="nominal")
    ar.set_ylabel("RMSE (relative to |truth|)")
    ar.set_title("Monte Carlo summary: RMSE (—) and CRLB (- -)")
    ar.grid(alpha=0.3, which="both")
    if len(names) <= 12:
        ar.legend(fontsize=6, ncol=2)
    if ticklabels is None and x.size and np.all(x > 0) and x.max() / max(x.min(), 1e-300) > 20:
        ar.set_xscale("log")
    ys = np.concatenate([np.asarray(l.get_ydata(), float) for l in ar.get_lines()] or [np.array([])])
    ys = ys[np.isfinite(ys)]
    if ys.size and np.all(ys > 0):
        ar.set_yscale("log")
    ac.set_ylim(-0.02, 1.02)
    ac.set_ylabel("95 % interval coverage")
    ac.set_xlabel(xlabel)
    ac.grid(alpha=0.3)
    if ticklabels is not None:
        ac.set_xticks(x)
        ac.set_xticklabels(ticklabels, rotation=20, fontsize=7, ha="right")
    return fig


# ------------------------------------------------------------------------------------- diagnosis

def _validation(diagnosis: Mapping):
    """The validation experiments the verdict's effect was scored on, ``(name, experiment)``."""
    return [(n, e) for n, e in diagnosis["experiments"].items() if e["role"] == "validation" and "y_after" in e]


def plot_residual_map(diagnosis: Mapping, ax=None) -> Figure:
    """The residual map before and after: for every validation experiment (rows), the local RMS
    of the residual over windows of its scored samples, in units of the noise floor (colour).
    Left: the model as given; right: with the verdict's effect added.

    Parameters
    ----------
    diagnosis : dict
        :func:`hwid.results.read_diagnosis` output.
    ax : pair of Axes, optional
    """
    summary = diagnosis["summary"]
    sigma = max(float(summary["noise_floor"]), 1e-300)
    rows = _validation(diagnosis)
    n_bins = 60
    maps = []
    for _, e in rows:
        scored = e["mask"]
        per_model = []
        for key in ("y_model", "y_after"):
            r = (e["y"] - e[key])[scored] / sigma
            edges = np.linspace(0, r.size, n_bins + 1).astype(int)
            per_model.append([np.sqrt(np.mean(r[a:b] ** 2)) if b > a else np.nan
                              for a, b in zip(edges[:-1], edges[1:])])
        maps.append(per_model)
    maps = np.asarray(maps, float) if maps else np.ones((1, 2, n_bins))
    if ax is None:
        fig = Figure(figsize=(11, 0.3 * len(rows) + 2), layout="constrained")
        ax = fig.subplots(1, 2, sharey=True)
    else:
        fig = ax[0].figure
    norm = LogNorm(vmin=0.5, vmax=max(np.nanmax(maps), 2.0))
    image = None
    for k, title in enumerate(("before: model as given", f"after: + {summary['verdict']['effect']}")):
        image = ax[k].imshow(np.clip(maps[:, k, :], 0.5, None), aspect="auto", cmap="magma", norm=norm,
                             extent=(0, 1, len(rows) - 0.5, -0.5), interpolation="nearest")
        ax[k].set_title(title)
        ax[k].set_xlabel("fraction of the scored experiment")
    ax[0].set_yticks(range(len(rows)))
    ax[0].set_yticklabels([n for n, _ in rows], fontsize=7)
    fig.colorbar(image, ax=list(ax), label="local RMS gap / noise floor")
    fig.suptitle(f"gap {summary['gap_before']:.3g} -> {summary['gap_after']:.3g} "
                 f"(noise floor {summary['noise_floor']:.3g})")
    return fig


def plot_ranking(diagnosis: Mapping, ax=None) -> Figure:
    """Explained fraction of the excess gap per catalogue effect (bars), the verdict highlighted,
    the 0.5 threshold of a verdict dashed; candidates whose BIC score is not positive are hatched."""
    summary = diagnosis["summary"]
    candidates = summary["candidates"]
    if ax is None:
        fig = Figure(figsize=(7, 0.35 * len(candidates) + 1.5), layout="constrained")
        ax = fig.subplots()
    else:
        fig = ax.figure
    names = [c["effect"] for c in candidates][::-1]
    fractions = [c["explained_fraction"] for c in candidates][::-1]
    verdict = summary["verdict"]["effect"]
    bars = ax.barh(names, fractions, color=["tab:red" if n == verdict else "tab:gray" for n in names])
    for bar, c in zip(bars, candidates[::-1]):
        if c["score"] <= 0:
            bar.set_hatch("//")
    ax.axvline(0.5, ls="--", color="k", lw=0.8)
    ax.set_xlim(0, 1.05)
    ax.set_xlabel("explained fraction of the gap above the noise floor (validation data)")
    ax.set_title(f"verdict: {verdict} ({summary['verdict']['block']})")
    return fig
