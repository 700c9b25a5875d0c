"""The run report's page: which figures a run's data allow, with their captions, and one
self-contained HTML page that holds them and the tables.

``write_report(DIR)`` reads the run directory (:func:`hwid.report.rundir.load_run`), prepares the
views once (:func:`hwid.report.views.prepare`) and writes into ``DIR/report/``: every figure as
``NAME.png`` and ``NAME.svg``, ``figures.json`` (the list of figures) and ``report.html``, with the
figures embedded as base64 PNG so the page is one file. A small script marks
``<body data-images-loaded="N/M">`` once the page has loaded, for browser tests. Every file is
written to ``NAME.tmp`` and moved into place.
"""
from __future__ import annotations

import base64
import html as _html
import io
import json
import os
from dataclasses import dataclass
from pathlib import Path

import numpy as np
from matplotlib.figure import Figure

from hwid import HwidError
from hwid.report import compare_figures, figures, tables
from hwid.report.rundir import RunData, load_run
from hwid.report.views import ReportViews, h_covariance, parametric_block, points_on_w, prepare


@dataclass(frozen=True)
class FigureItem:
    name: str
    section: str
    caption: str
    figure: Figure | None
    group: str = ""          # figures of one group share a row of the page
    png: bytes | None = None  # a figure a command already drew (PNG), shown as it is


# ================================================================================ the figures

def build_figures(run: RunData, views: ReportViews | None = None) -> list[FigureItem]:
    """Every figure the run's data allow, in report order."""
    views = prepare(run) if views is None else views
    return (_staircase_figures(views) + _nonlinearity_figures(run, views) + _linear_figures(run, views)
            + _batch_figures(run) + _diagnosis_figures(run) + _compare_figures(run))


def _staircase_figures(views: ReportViews) -> list[FigureItem]:
    """Figs. 10-11 (ascending) and 13-14 (descending): each staircase's input and output."""
    items = []
    fig_numbers = {"up": ("10", "11"), "down": ("13", "14")}
    for direction, view in views.staircases.items():
        input_no, output_no = fig_numbers[direction]
        word = "ascending (eq. 6)" if direction == "up" else "descending (eq. 13)"
        items.append(FigureItem(f"{view.name}_input", "stage1",
                                f"Fig. {input_no}: the {word} staircase input u(t).",
                                figures.plot_staircase_input(view.t, view.u, view.levels, view.spans,
                                                             title=f"Staircase input, {word} (Fig. {input_no})"),
                                view.name))
        caption = f"Fig. {output_no}: the measured output y(t) of the {word} staircase"
        if view.X_hat is not None:
            caption += ", the averaging windows (shaded) and X̂_j (eq. 9) with 95 % bars"
        if view.x is not None:
            caption += "; dashed: the undisturbed output x(t) (simulation ground truth)"
        items.append(FigureItem(f"{view.name}_output", "stage1", caption + ".",
                                figures.plot_staircase_output(view.t, view.y, view.windows, view.X_hat, view.X_ci,
                                                              view.x, view.flat,
                                                              title=f"Staircase output, {word} (Fig. {output_no})"),
                                view.name))
    return items


def _nonlinearity_figures(run: RunData, views: ReportViews) -> list[FigureItem]:
    """Fig. 12 (h with its band, the staircase points) and Fig. 9 (the borders) of stage 1."""
    nl = run.nonlinear
    if nl is None:
        return []
    truth = run.truth
    f_est = nl.input_nonlinearity()
    w_plot = None
    if run.linear is not None and np.size(run.linear.gain):
        reach = float(run.linear.amplitude) * float(np.max(run.linear.gain))
        w_plot = (-reach, reach)      # where the sines drive w (eq. 17)
    h_figure = figures.plot_h(np.asarray(nl.h_coefficients, float), h_covariance(nl), tuple(nl.w_range),
                              truth.output if truth is not None else None, points_on_w(run, views.staircases, f_est),
                              w_plot=w_plot)
    levels = (np.concatenate([v.levels for v in views.staircases.values()]) if views.staircases
              else np.array([-1.5, 1.5]))
    pad = 0.1 * (levels.max() - levels.min())
    borders_figure = figures.plot_borders(f_est, truth.input if truth is not None else None,
                                          (levels.min() - pad, levels.max() + pad),
                                          {k: nl.ci.get(k) for k in ("d_plus", "d_minus")})
    return [FigureItem("h", "stage1",
                       "Fig. 12: the estimated output nonlinearity ĥ (eq. 12) with its 95 % band "
                       "(delta method on the coefficients' covariance), the true h̄ (eq. 4c) when "
                       "known, and the staircase points on the w axis through the estimated borders; "
                       "shaded grey: the w range the staircases identified h on (outside it, as far as "
                       "the sines drive w, h is extrapolated).", h_figure, "nonlinearities"),
            FigureItem("borders", "stage1",
                       "Fig. 9: the estimated ascending and descending borders of the normalised "
                       "input nonlinearity F̄ (eq. 4a) and its cycle, against the truth; bars: 95 % "
                       "intervals of d⁺ and d⁻.", borders_figure, "nonlinearities")]


def _linear_figures(run: RunData, views: ReportViews) -> list[FigureItem]:
    """The Bode plot of stage 2 and, per sine, Fig. 15 (one period) and Fig. 16 (the spectrum)."""
    items = []
    lin, truth = run.linear, run.truth
    if lin is not None:
        items.append(FigureItem("bode", "stage2",
                                "Bode plot of Ḡ(jω): the frequency-by-frequency estimates (eq. 37 or the "
                                "harmonic fit) with 95 % interval bars, the parametric fit"
                                + (" and the true Ḡ (eq. 4b)" if truth is not None else "") + ".",
                                figures.plot_bode(lin.frequencies, lin.gain, lin.phase,
                                                  (lin.gain_ci[:, 0], lin.gain_ci[:, 1]),
                                                  (lin.phase_ci[:, 0], lin.phase_ci[:, 1]), parametric_block(lin),
                                                  truth.linear if truth is not None else None)))
    for s in views.sines:
        model = s.model_curve()
        items.append(FigureItem(f"{s.name}_period", "stage2",
                                f"Fig. 15 at ω = {s.omega:g} rad/s: one period of the raw output y(t) (grey), the "
                                "period average x̂_N(t) of eq. (23a)"
                                + (", the fitted harmonic model (eq. 20)" if model is not None else "")
                                + (", and the undisturbed x(t) (dashed)" if s.x_fold is not None else "") + ".",
                                figures.plot_period(s.t_fold, s.y_fold, s.omega, model, s.x_fold, s.raw), s.name))
        items.append(FigureItem(f"{s.name}_spectrum", "stage2",
                                f"Fig. 16 at ω = {s.omega:g} rad/s: modulus s_k and phase ψ_k (eqs. 26a-b) of the "
                                "harmonics of the steady-state output, 95 % bars"
                                + (", the fitted model (circles)" if s.model is not None else "")
                                + (", the truth (crosses)" if s.truth_coef is not None else "") + ".",
                                figures.plot_spectrum(s.ks, s.coef, s.se, s.model, s.truth_coef,
                                                      title=f"Harmonic spectrum, ω = {s.omega:g} rad/s (Fig. 16)"),
                                s.name))
    return items


def _batch_figures(run: RunData) -> list[FigureItem]:
    """The Monte Carlo summaries: stage-1 estimates in one figure, the per-frequency ones in another."""
    if run.batch is None or not run.batch.get("points"):
        return []
    items = []
    names = list(dict.fromkeys(n for p in run.batch["points"] for n in p.get("stats", {})))
    for key, selected, what in (("nonlinear", [n for n in names if "@" not in n], "stage 1 (borders, h̄)"),
                                ("linear", [n for n in names if "@" in n], "stage 2 (|G|, φ per ω)")):
        if selected:
            items.append(FigureItem(f"batch_{key}", "batch",
                                    f"Monte Carlo, {what}: RMSE of each estimate (relative to |truth|, absolute "
                                    "where the truth is 0) with the CRLB standard deviation (dashed, where "
                                    "known), and the coverage of the 95 % intervals, against the swept key.",
                                    figures.plot_batch_summary(run.batch, selected), "batch"))
    return items


def _diagnosis_figures(run: RunData) -> list[FigureItem]:
    """The residual map before and after the verdict's effect, and the ranking of the catalogue."""
    if run.diagnosis is None:
        return []
    return [FigureItem("diagnosis_residual_map", "diagnosis",
                       "Residual map of the validation experiments: local RMS gap over the noise floor, "
                       "before (left) and after (right) adding the verdict's effect.",
                       figures.plot_residual_map(run.diagnosis), "diagnosis_map"),
            FigureItem("diagnosis_ranking", "diagnosis",
                       "Ranking of the catalogue: the share of the gap above the noise floor that each "
                       "effect explains on validation data its fit did not use.",
                       figures.plot_ranking(run.diagnosis), "diagnosis_ranking")]


COMPARE_EXPERIMENT_CAPTION = ("{name}: the measured output and the model's free run from its estimated "
                              "initial state (top), and the residual y - model beneath (dashed: +- the noise "
                              "floor where it is known).")
COMPARE_TESTS_CAPTION = ("Residual tests (resid), pooled over the experiments: the residual's autocorrelation "
                         "and its cross-correlation with the input u(t-k); the grey band holds 99 % of the "
                         "values of a white residual independent of the input (+-2.58/sqrt(N); for the "
                         "cross-correlation +-2.58 sqrt(P/N), P = sum_k r_e(k) r_u(k)). Bars outside it: "
                         "structure the model misses. The lag axis says whether the residual was decimated.")


def _compare_figures(run: RunData) -> list[FigureItem]:
    """``hwid compare``: the figures it wrote into ``DIR/figures/`` (listed under ``figures`` in its
    summary), shown as they are; for a comparison written without them, the same figures drawn
    from ``compare.h5`` (residual tests not decimated: the model is not stored there)."""
    if run.compare is None:
        return []
    folder = run.directory / compare_figures.FIGURES_DIR
    listed = [run.directory / f for f in run.compare["summary"].get("figures", [])]
    if listed and all(f.parent == folder and f.suffix == ".png" and f.is_file() for f in listed):
        return [FigureItem(f.stem, "compare", _compare_caption(f.stem), None, f"compare_{k // 2}", f.read_bytes())
                for k, f in enumerate(listed)]
    summary, sims = run.compare["summary"], run.compare["y_model"]
    fits = {e["name"]: e["fit_percent"] for e in summary["experiments"]}
    records = {name: run.compare["experiments"][name] for name in fits if name in run.compare["experiments"]}
    items = [FigureItem(f"compare_{compare_figures.safe_name(name)}", "compare",
                        COMPARE_EXPERIMENT_CAPTION.format(name=name),
                        compare_figures.plot_experiment(name, rec.t, rec.y, sims[name], fits.get(name),
                                                        summary.get("noise_floor")), f"compare_{k // 2}")
             for k, (name, rec) in enumerate(records.items())]
    dt = float(next(iter(records.values())).dt) if records else 1.0
    corr = compare_figures.residual_correlation([rec.y - sims[n] for n, rec in records.items()],
                                                [rec.u for rec in records.values()], dt=dt,
                                                step=int(summary.get("residual", {}).get("lag_step") or 1))
    items.append(FigureItem("compare_residual_tests", "compare", COMPARE_TESTS_CAPTION,
                            compare_figures.plot_residual_tests(corr), f"compare_{len(items) // 2}"))
    return items


def _compare_caption(stem: str) -> str:
    if stem == "compare_residual_tests":
        return COMPARE_TESTS_CAPTION
    return COMPARE_EXPERIMENT_CAPTION.format(name=stem.removeprefix("compare_"))


# ================================================================================ the page

CSS = """
body{font-family:system-ui,-apple-system,Segoe UI,Helvetica,Arial,sans-serif;max-width:1100px;margin:1.5em auto;
padding:0 1em;color:#222;line-height:1.4}
h1{font-size:1.5em}h2{border-bottom:1px solid #ccc;padding-bottom:.2em;margin-top:1.6em}
table{border-collapse:collapse;margin:.6em 0;font-size:.88em}td,th{border:1px solid #ccc;padding:.25em .5em;text-align:right}
th{background:#f3f3f3}tr.flat td{color:#999}.ci{color:#666;font-size:.9em}
.row{display:flex;gap:1%;align-items:flex-start}figure{margin:.6em 0;flex:0 1 49.5%;min-width:0}figure img{max-width:100%;height:auto;border:1px solid #eee}
figcaption{font-size:.85em;color:#444;max-width:700px}.missing,.warn{background:#fff4e5;border-left:4px solid #f0a030;padding:.4em .8em}
.note{font-size:.85em;color:#555}code,pre{font-size:.85em}pre{background:#f7f7f7;padding:.6em;overflow:auto;max-height:24em}
.model td{text-align:left}
"""

SCRIPT = """
window.addEventListener("load", function () {
  var imgs = document.images, n = 0;
  for (var i = 0; i < imgs.length; i++) {
    if (imgs[i].complete && imgs[i].naturalWidth > 0) { n++; }
  }
  document.body.setAttribute("data-images-loaded", n + "/" + imgs.length);
});
"""


def _figure_html(item: FigureItem, png: bytes) -> str:
    b64 = base64.b64encode(png).decode("ascii")
    return (f"<figure id='fig-{item.name}'><img alt='{_html.escape(item.name)}' "
            f"src='data:image/png;base64,{b64}'><figcaption>{_html.escape(item.caption)}</figcaption></figure>")


def render_html(run: RunData, items: list[FigureItem], pngs: dict[str, bytes],
                views: ReportViews | None = None) -> str:
    """The page: the model, stage 1 (Table 1, parameters), stage 2 (Table 2), batch, diagnosis,
    warnings and provenance, each section with its figures."""
    views = prepare(run) if views is None else views

    def section_figures(section):
        rows: dict[str, list[str]] = {}
        for item in items:
            if item.section == section:
                rows.setdefault(item.group or item.name, []).append(_figure_html(item, pngs[item.name]))
        return "".join(f"<div class='row'>{''.join(r)}</div>" for r in rows.values())

    title = f"hwid report: {run.config_name or run.directory.name}"
    present = ", ".join(f"{n} {'✓' if ok else '✗'}" for n, ok in run.present.items())
    notes = "".join(f"<p class='missing'>{_html.escape(n)}</p>" for n in run.notes + views.notes)
    parts = [f"<!DOCTYPE html><html lang='en'><head><meta charset='utf-8'><title>{_html.escape(title)}</title>",
             f"<style>{CSS}</style><script>{SCRIPT}</script></head>",
             f"<body data-figures='{len(items)}'><h1>{_html.escape(title)}</h1>",
             f"<p>Run directory <code>{_html.escape(str(run.directory))}</code>: {present}.</p>", notes,
             "<h2>Identified model</h2>", tables.model_html(run), tables.adequacy_html(run)]
    if run.records or run.nonlinear is not None:
        parts += ["<h2>Stage 1: the nonlinearities (Section 4, Table 1)</h2>",
                  "<h3>Table 1: steady-state outputs X̂<sub>j</sub>(M), eq. (9)</h3>",
                  tables.table1_html(run, views.staircases)]
        if run.nonlinear is not None:
            parts += ["<h3>Estimated parameters (normalised model, eqs. 4a-c)</h3>", tables.params_html(run)]
        parts.append(section_figures("stage1"))
    if run.linear is not None or any(n.startswith("sine_") for n in run.records):
        parts += ["<h2>Stage 2: the linear block G(jω) (Section 5, Table 2)</h2>",
                  "<h3>Table 2: frequency gain estimates</h3>", tables.table2_html(run), section_figures("stage2")]
    if run.batch is not None:
        parts += ["<h2>Monte Carlo batch</h2>", tables.batch_table_html(run.batch), section_figures("batch")]
    if run.history is not None:
        parts += ["<h2>Stage 1 from the recorded levels</h2>", tables.history_html(run.history)]
    if run.whole is not None:
        parts += ["<h2>The whole model by output error (identification.whole)</h2>", tables.whole_html(run.whole)]
    if run.compare is not None:
        parts += ["<h2>Compare: the model against the measured experiments</h2>",
                  tables.compare_html(run.compare), section_figures("compare")]
    if run.diagnosis is not None:
        parts += ["<h2>Diagnosis: where and why the plant and the model part</h2>",
                  tables.diagnosis_html(run.diagnosis), section_figures("diagnosis")]
    parts += ["<h2>Warnings</h2>", tables.warnings_html(run), "<h2>Provenance</h2>", tables.provenance_html(run),
              "</body></html>"]
    return "\n".join(parts)


# ================================================================================ writing

def _save(fig: Figure, path_stem: Path) -> bytes:
    """Save ``fig`` as PNG and SVG next to each other; return the PNG bytes. The layout is computed
    once and then frozen, so both formats share it (and it is not computed twice)."""
    if fig.get_layout_engine() is not None:
        fig.draw_without_rendering()
        fig.set_layout_engine("none")
    buf = io.BytesIO()
    fig.savefig(buf, format="png", dpi=100)
    png = buf.getvalue()
    _atomic_bytes(path_stem.with_suffix(".png"), png)
    svg = io.BytesIO()
    fig.savefig(svg, format="svg")
    _atomic_bytes(path_stem.with_suffix(".svg"), svg.getvalue())
    return png


def _atomic_bytes(path: Path, data: bytes) -> None:
    tmp = path.with_name(path.name + ".tmp")
    tmp.write_bytes(data)
    os.replace(tmp, path)


def write_report(directory: str | Path, out_dir: str | Path | None = None) -> Path:
    """Write ``DIR/report/`` (figures as PNG and SVG, ``figures.json``, ``report.html``); return the
    path of ``report.html``."""
    run = load_run(directory)
    out = Path(out_dir) if out_dir is not None else run.directory / "report"
    try:
        out.mkdir(parents=True, exist_ok=True)
    except OSError as err:
        raise HwidError(f"{out}: cannot create the report directory ({err.strerror or type(err).__name__})") from None
    views = prepare(run)
    items = build_figures(run, views)
    pngs = {}
    for item in items:
        if item.png is not None:
            _atomic_bytes(out / f"{item.name}.png", item.png)
            pngs[item.name] = item.png
        else:
            pngs[item.name] = _save(item.figure, out / item.name)
    manifest = [{"name": i.name, "section": i.section, "caption": i.caption} for i in items]
    _atomic_bytes(out / "figures.json", (json.dumps(manifest, indent=1) + "\n").encode())
    path = out / "report.html"
    _atomic_bytes(path, render_html(run, items, pngs, views).encode("utf-8"))
    return path
