"""The report's tables as HTML: Table 1, the stage-1 parameters, Table 2, the batch summary, the
diagnosis, the identified model, the warnings and the provenance.

Each table shows a run's estimates with their 95 % intervals beside the truth (simulated plants) and,
for the paper's config, the paper's published values (:mod:`hwid.paper`).
"""
from __future__ import annotations

import datetime as _dt
import html as _html

import numpy as np
import yaml

from hwid import __version__, paper
from hwid.blocks.static import PolynomialH
from hwid.identify.result import FIXED
from hwid.report.rundir import RunData
from hwid.report.views import StaircaseView, true_phase_lag


# ------------------------------------------------------------------------------------ formatting

def _num(x, digits: int = 4) -> str:
    if x is None:
        return "—"
    try:
        x = float(x)
    except (TypeError, ValueError):
        return _html.escape(str(x))
    if not np.isfinite(x):
        return "—"
    if x == 0:
        return "0"
    if abs(x) >= 1e4 or abs(x) < 1e-3:
        return f"{x:.{digits - 1}e}"
    return f"{x:.{digits}g}"


def _pm(est, ci, digits: int = 4) -> str:
    """``estimate [lo, hi]`` for a 95 % interval."""
    if est is None:
        return "—"
    if ci is None:
        return _num(est, digits)
    lo, hi = ci
    return f"{_num(est, digits)} <span class='ci'>[{_num(lo, digits)}, {_num(hi, digits)}]</span>"


def _no_interval(name: str, undetermined: dict | None) -> str:
    """Why a parameter has no interval: fixed by the normalisation (:data:`FIXED`), or the reason it
    is undetermined."""
    if name in FIXED:
        return _html.escape(FIXED[name])
    return "undetermined: " + _html.escape((undetermined or {}).get(name, "not determined by these data"))


def _estimate(est, ci, name: str, undetermined: dict | None, digits: int = 4) -> str:
    """``estimate [lo, hi]``, or the estimate and why it has no interval."""
    if ci is None:
        return f"{_num(est, digits)} <span class='ci'>({_no_interval(name, undetermined)})</span>"
    return _pm(est, ci, digits)


def _tr(cells, head: bool = False) -> str:
    tag = "th" if head else "td"
    return "<tr>" + "".join(f"<{tag}>{c}</{tag}>" for c in cells) + "</tr>"


def poly_text(coefficients, var: str = "w", digits: int = 4) -> str:
    """Ascending coefficients as ``c_p w^p + ... + c_0`` (descending powers, as in the paper)."""
    c = np.asarray(coefficients, float)
    terms = []
    for i in range(c.size - 1, -1, -1):
        if c[i] == 0:
            continue
        magnitude = f"{abs(c[i]):.{digits}g}"
        monomial = var if i == 1 else f"{var}^{i}"
        body = magnitude if i == 0 else (monomial if magnitude == "1" else f"{magnitude} {monomial}")
        terms.append(("−" if c[i] < 0 else "+", body))
    if not terms:
        return "0"
    text = ("−" if terms[0][0] == "−" else "") + terms[0][1]
    for sign, body in terms[1:]:
        text += f" {sign} {body}"
    return text


def tf_text(num, den, delay: float = 0.0, digits: int = 4) -> str:
    """``num(s) / den(s) e^{-delay s}`` from descending coefficients."""
    def polynomial(c):
        return poly_text(np.asarray(c, float)[::-1], "s", digits)
    text = f"({polynomial(num)}) / ({polynomial(den)})"
    if delay:
        text += f" · e^(−{delay:.{digits}g} s)"
    return text


# -------------------------------------------------------------------------------------- stage 1

def table1_html(run: RunData, staircases: dict[str, StaircaseView]) -> str:
    """Table 1: ``X_hat_j(M)`` per level with 95 % intervals, the truth and the paper's values."""
    if not staircases:
        return "<p class='missing'>No staircase experiments: Table 1 cannot be shown.</p>"
    head = ["j", "U<sub>j</sub>", "X̂<sub>j</sub> [95 %]", "X<sub>j</sub> true"]
    if run.is_paper:
        head += ["paper X<sub>j</sub>", "paper X̂<sub>j</sub>"]
    rows = [_tr(head, True)]
    n_up = staircases["up"].levels.size if "up" in staircases else 0
    for direction in ("up", "down"):
        view = staircases.get(direction)
        if view is None:
            continue
        offset = 0 if direction == "up" else n_up
        for i, U in enumerate(view.levels):
            j = offset + i + 1
            est = None if view.X_hat is None else view.X_hat[i]
            ci = None if view.X_ci is None or est is None else (est - view.X_ci[i], est + view.X_ci[i])
            cells = [str(j), _num(U), _pm(est, ci), _num(None if view.X_true is None else view.X_true[i])]
            if run.is_paper:
                row = paper.table1_row(j)
                same_level = row is not None and np.isclose(row.U, U)
                cells += [_num(row.X) if same_level else "", _num(row.X_hat) if same_level else ""]
            flat = " class='flat'" if view.flat is not None and i < view.flat else ""
            rows.append(_tr(cells).replace("<tr>", f"<tr data-j='{j}'{flat}>", 1))
    note = ("<p class='note'>Rows in grey lie on a flat path (j ≤ j<sub>a</sub>, or the first j<sub>d</sub> "
            "descending levels: eqs. 7a, 14a).</p>")
    return f"<table class='t1' id='table1'>{''.join(rows)}</table>{note}"


def params_html(run: RunData) -> str:
    """The input nonlinearity's parameters and h_bar's coefficients (estimate [95 %], truth, paper)."""
    nl = run.nonlinear
    if nl is None:
        return ""
    truth = run.truth
    head = ["parameter", "estimate [95 %]", "truth"] + (["paper"] if run.is_paper else [])
    rows = [_tr(head, True)]
    labels = {"slope_up": "S<sup>a</sup> (normalised)", "slope_down": "S<sup>d</sup>/S<sup>a</sup>",
              "d_plus": "d<sup>+</sup>", "d_minus": "d<sup>−</sup>"}
    for key, label in labels.items():
        cells = [label, _estimate(getattr(nl, key), nl.ci.get(key), key, nl.undetermined),
                 _num(getattr(truth.input, key) if truth is not None else None)]
        if run.is_paper:
            cells.append(_num(paper.BORDERS[key]) if key in paper.BORDERS else "")
        rows.append(_tr(cells).replace("<tr>", f"<tr data-param='{key}'>", 1))
    true_coef = (np.asarray(truth.output.coefficients, float) if truth is not None
                 and isinstance(truth.output, PolynomialH) else np.array([]))
    for i, (c, ci) in enumerate(zip(nl.h_coefficients, nl.ci["h_coefficients"])):
        true_value = true_coef[i] if i < true_coef.size else (0.0 if true_coef.size else None)
        cells = [f"h̄ c<sub>{i}</sub>", _estimate(c, ci, f"c{i}", nl.undetermined), _num(true_value)] + \
            ([""] if run.is_paper else [])
        rows.append(_tr(cells).replace("<tr>", f"<tr data-param='h_c{i}'>", 1))
    return f"<table class='params' id='params'>{''.join(rows)}</table>"


# -------------------------------------------------------------------------------------- stage 2

def _other_estimate_cell(other: dict) -> str:
    """The other stage-2 estimator's ``phi / |G|`` at one frequency, or why it has none."""
    if "gain" not in other:
        return _html.escape(str(other.get("error", "—")))[:120]
    return (f"{_pm(other.get('phase'), _pair(other.get('phase_ci')))} / {_pm(other.get('gain'), _pair(other.get('gain_ci')))}"
            + (f" (k = {int(other['harmonic'])})" if other.get("harmonic") is not None else ""))


def _pair(ci):
    if ci is None:
        return None
    v = np.ravel(np.asarray(ci, float))
    return (float(v[0]), float(v[1])) if v.size == 2 else None


def table2_html(run: RunData) -> str:
    """Table 2: ``phi_hat_N(omega_i)`` and ``|G_hat_N(j omega_i)|`` with 95 % intervals, CRLB, truth,
    the other stage-2 estimator, paper."""
    lin = run.linear
    if lin is None:
        return "<p class='missing'>linear.h5 is missing: Table 2 cannot be shown.</p>"
    omegas = lin.frequencies
    other_method = "paper" if lin.method == "nls" else "nls"
    others = [h["estimates"].get(other_method, {}) for h in lin.harmonics]
    show_other = any("gain" in o for o in others)
    true_response = run.truth.linear.freqresp(omegas) if run.truth is not None else None
    true_phase = true_phase_lag(run.truth.linear, omegas) if run.truth is not None else None
    head = ["i", "U<sub>i</sub>", "ω<sub>i</sub> (rad/s)", "φ̂(ω<sub>i</sub>) [95 %]", "φ true",
            "|Ĝ(jω<sub>i</sub>)| [95 %]", "|G| true", "CRLB sd φ / |G|"]
    if show_other:
        head += ["eq. (37), one harmonic: φ̂ / |Ĝ|" if other_method == "paper" else "NLS, all harmonics: φ̂ / |Ĝ|"]
    if run.is_paper:
        head += ["paper φ", "paper φ̂", "paper |G|", "paper |Ĝ|"]
    rows = [_tr(head, True)]
    for i, omega in enumerate(omegas):
        cells = [str(i + 1), _num(lin.amplitude), _num(omega),
                 _pm(lin.phase[i], tuple(lin.phase_ci[i])),
                 _num(None if true_phase is None else true_phase[i]),
                 _pm(lin.gain[i], tuple(lin.gain_ci[i])),
                 _num(None if true_response is None else abs(true_response[i])),
                 f"{_num(np.sqrt(lin.crlb_phase[i]), 3)} / {_num(np.sqrt(lin.crlb_gain[i]), 3)}"]
        if show_other:
            cells.append(_other_estimate_cell(others[i] if i < len(others) else {}))
        if bool(lin.extrapolated[i]):
            cells[2] += " <span class='flag' title='extrapolated'>*</span>"
        if run.is_paper:
            row = paper.table2_row(omega)
            cells += [_num(x) for x in (row.phi, row.phi_hat, row.gain, row.gain_hat)] if row else [""] * 4
        rows.append(_tr(cells).replace("<tr>", f"<tr data-omega='{omega:g}'>", 1))
    return f"<table class='t2' id='table2'>{''.join(rows)}</table>"


# ----------------------------------------------------------------------------- batch, diagnosis

def batch_table_html(summary: dict) -> str:
    """Every estimate's statistics at every sweep point (:func:`hwid.results.read_batch_summary`)."""
    points = summary.get("points", [])
    if not points:
        return "<p class='missing'>batch.h5 holds no sweep points yet.</p>"
    rows = [_tr(["point", "overrides", "runs", "estimate", "truth", "bias", "std", "RMSE", "coverage",
                 "runs without interval", "CRLB sd"], True)]
    for i, p in enumerate(points):
        overrides = ", ".join(f"{k}={v}" for k, v in (p.get("overrides") or {}).items()) or "base"
        for name, s in p.get("stats", {}).items():
            rows.append(_tr([str(i), _html.escape(overrides), str(p.get("n_runs", "")), _html.escape(name),
                             _num(s.get("truth")), _num(s.get("bias"), 3), _num(s.get("std"), 3),
                             _num(s.get("rmse"), 3), _num(s.get("coverage"), 3),
                             str(int(s["without_interval"])) if "without_interval" in s else "",
                             _num(s.get("crlb_std"), 3)]))
    note = ("<p class='note'>Coverage counts only the runs whose estimate has a 95 % interval: a parameter "
            "fixed by the normalisation (h̄'s constant) or left undetermined by a run's data has none, and is "
            "neither covered nor missed; those runs are counted in “runs without interval”.</p>")
    return f"<details><summary>summary table</summary><table id='batch'>{''.join(rows)}</table>{note}</details>"


def diagnosis_html(diagnosis: dict) -> str:
    """The verdict table of ``hwid diagnose`` (the numbers of its JSON summary) and the candidates."""
    summary = diagnosis["summary"]
    verdict, where = summary["verdict"], summary["where"]
    rows = [_tr(["verdict", "block", "explained", "gap before", "gap after", "noise floor", "where", "trend"], True),
            _tr([_html.escape(str(verdict["effect"])), _html.escape(str(verdict["block"])),
                 _num(verdict["explained_fraction"], 3), _num(summary["gap_before"]), _num(summary["gap_after"]),
                 _num(summary["noise_floor"]), _html.escape(str(where["region"])), _html.escape(str(where["trend"]))])]
    out = [f"<table id='diagnosis'>{''.join(rows)}</table>"]
    if verdict.get("why"):
        out.append(f"<p id='verdict-why'>{_html.escape(verdict['why'])}.</p>")
    conf = summary.get("confirmation")
    if conf:
        again = (f"; run again for {conf['times']}x its length: z = {_num(conf['z_rerun'], 3)}, excess "
                 f"{_num(conf['excess_rerun'], 3)}" if conf.get("runs") else "")
        out.append(f"<p id='confirmation'>Confirmation of {_html.escape(conf['effect'])} against the model without "
                   f"it, on the experiment it makes worst ({_html.escape(conf['experiment'])}): z = "
                   f"{_num(conf['z'], 3)}, excess {_num(conf['excess'], 3)} of the noise power{again}: "
                   f"{'contradicted' if conf['contradicted'] else 'not contradicted'}.</p>")
    rails = summary.get("output_rails") or []
    if rails:
        out.append("<p id='output-rails'>The measured output rests on the sensor's rail: " + "; ".join(
            f"{r['side']} {_num(r['value'])} for {r['samples']} samples in {r['runs']} run(s)" for r in rails)
            + ".</p>")
    out += _from_logs_html(summary)
    if summary["model"]["source"] == "identified":
        out.append(f"<p>Model identified from the same plant; with h re-estimated on the diagnosis's fit "
                   f"experiments its gap is {_num(summary['gap_model_refit'])}.</p>")
    largest = where["experiments"][:8]
    if largest:
        experiment_rows = [_tr(["experiment", "gap before / noise", "gap after / noise"], True)]
        experiment_rows += [_tr([_html.escape(e["name"]), _num(e["before_over_noise"], 3),
                                 _num(e["after_over_noise"], 3)]) for e in largest]
        out.append(f"<details><summary>per experiment (largest gaps)</summary>"
                   f"<table>{''.join(experiment_rows)}</table></details>")
    candidate_rows = [_tr(["candidate", "block", "explained", "gap after", "score", "parameters"], True)]
    for c in summary["candidates"]:
        params = ", ".join(f"{k} = {_num(x)}" for k, x in c["params"].items())
        candidate_rows.append(_tr([_html.escape(c["effect"]), _html.escape(str(c["block"])),
                                   _num(c["explained_fraction"], 3), _num(c["gap_after"]), _num(c["score"], 4),
                                   _html.escape(params)]))
    out.append(f"<table id='candidates'>{''.join(candidate_rows)}</table>")
    return "".join(out)


def _from_logs_html(summary: dict) -> list[str]:
    """What a diagnosis from logs adds: the split and the noise source, the effects the records
    cannot tell apart, and the experiment that would."""
    out = []
    data = summary.get("data")
    if data:
        out.append(f"<p id='diagnosis-data'>From the logs alone: split by {_html.escape(data['split'])} (fit "
                   f"{_html.escape(', '.join(data['fit']))}; validation {_html.escape(', '.join(data['validation']))}); "
                   f"noise floor from the {_html.escape(data['noise_source'])}.</p>")
    for group in summary.get("indistinguishable") or []:
        out.append("<p class='indistinguishable'>Indistinguishable on these records: "
                   + ", ".join(f"{_html.escape(e)} (gap after {_num(g)})" for e, g in group["gap_after"].items())
                   + ".</p>")
    nxt = summary.get("next_experiment")
    if nxt:
        fragment = _html.escape(yaml.safe_dump(nxt["config"], sort_keys=False))
        out.append(f"<p id='next-experiment'>Next experiment: {_html.escape(nxt['why'])}.</p><pre>{fragment}</pre>")
    return out


def compare_html(compare: dict) -> str:
    """``hwid compare``: fit, RMS error and residual tests, overall and per experiment."""
    summary = compare["summary"]
    floor = summary.get("rms_over_floor")
    rows = [_tr(["", "fit %", "RMS error", "RMS / noise floor", "samples", "initial gear", "G at rest at",
                 "whiteness p", "input correlation p"], True)]
    for e in summary["experiments"]:
        rows.append(_tr([_html.escape(e["name"]), _num(e["fit_percent"], 4), _num(e["rms"]),
                         _num(e["rms"] / summary["noise_floor"], 3) if summary.get("noise_floor") else "",
                         str(e["samples"]), _num(e["gear"]), _num(e["rest"]), _num(e["whiteness_p"], 3),
                         _num(e["input_correlation_p"], 3)]))
    rows.append(_tr(["<b>all</b>", _num(summary["fit_percent"], 4), _num(summary["rms"]),
                     _num(floor, 3) if floor is not None else "", str(sum(e["samples"] for e in summary["experiments"])),
                     "", "", _num(summary["residual"]["whiteness_p"], 3),
                     _num(summary["residual"]["input_correlation_p"], 3)]))
    source = _html.escape(str(summary.get("model", {}).get("path", summary.get("model", {}).get("source", ""))))
    return (f"<p>Model <code>{source}</code> simulated on each experiment from the initial gear state and "
            f"G rest level that fit it best (the state a record starts in is unknown).</p>"
            f"<table id='compare'>{''.join(rows)}</table>")


def whole_html(whole) -> str:
    """The whole-model output-error fit: estimates with 95 % intervals, and its selection table."""
    rows = [_tr(["parameter", "estimate", "95 % interval"], True)]
    und = whole.undetermined

    def interval(ci, name):
        return _no_interval(name, und) if ci is None else f"[{_num(ci[0])}, {_num(ci[1])}]"

    for name in ("d_plus", "slope_down", "d_minus"):
        rows.append(_tr([name, _num(getattr(whole, name)), interval(whole.ci[name], name)]))
    for i, (c, ci) in enumerate(zip(whole.h_coefficients, whole.ci["h_coefficients"])):
        rows.append(_tr([f"h_bar c{i}", _num(c), interval(ci, f"c{i}")]))
    selection = [_tr(["type", "G structure", "degree", "RSS", "parameters", "criterion"], True)]
    for s in sorted(whole.selection, key=lambda s: s["aic"]):
        selection.append(_tr([s["type"], s["structure"], str(s["degree"]), _num(s["rss"]), str(s["parameters"]),
                              _num(s["aic"], 6)]))
    return (f"<p>{whole.type}; G(s) = {_html.escape(tf_text(whole.num, whole.den, whole.delay))} "
            f"({whole.structure}); residual σ = {_num(whole.sigma)} on {whole.samples} samples.</p>"
            f"<table id='whole'>{''.join(rows)}</table>"
            f"<details><summary>selection (BIC penalty on F and G, AIC on ĥ; smallest first)</summary><table>{''.join(selection)}</table></details>")


def history_html(hist) -> str:
    """Stage 1 from a recorded history: estimates with 95 % intervals, the fit's chi-square (a
    misfit said as such), every settled level used, and the selection table."""
    rows = [_tr(["parameter", "estimate", "95 % interval"], True)]
    und = getattr(hist, "undetermined", {}) or {}

    def interval(ci, name):
        return _no_interval(name, und) if ci is None else f"[{_num(ci[0])}, {_num(ci[1])}]"

    for name in ("d_plus", "d_minus", "dead_band", "slope_down"):
        rows.append(_tr([name, _num(getattr(hist, name)), interval(hist.ci[name], name)]))
    for i, (c, ci) in enumerate(zip(hist.h_coefficients, hist.ci["h_coefficients"])):
        rows.append(_tr([f"h_bar c{i}", _num(c), interval(ci, f"c{i}" if i == 0 or f"c{i}" in und
                                                          else "h_coefficients")]))
    levels = [_tr(["record", "#", "u", "settled output", "standard error", "samples", "scored"], True)]
    for lv in hist.levels:
        levels.append(_tr([_html.escape(lv.record), str(lv.index), _num(lv.u), _num(lv.x), _num(lv.se), str(lv.n),
                           "yes" if lv.scored else ("no (not settled)" if lv.n == 0 else "no (state unknown)")]))
    selection = [_tr(["type", "degree", "chi2", "criterion"], True)]
    for s in sorted(hist.table, key=lambda s: s["criterion"]):
        selection.append(_tr([s["type"], str(s["degree"]), _num(s["chi2"]), _num(s["criterion"], 6)]))
    verdict = (f"<b>a misfit</b>: chi2 = {_num(hist.chi2)} on {hist.dof} dof (p = {hist.p_value:.2g}); the "
               "estimates do not rest on a model that reaches the levels' noise" if hist.misfit else
               f"chi2 = {_num(hist.chi2)} on {hist.dof} dof (p = {hist.p_value:.2g})")
    return (f"<p>{hist.type}; {verdict}.</p><table id='history'>{''.join(rows)}</table>"
            f"<details><summary>settled levels ({len(hist.levels)})</summary><table>{''.join(levels)}</table></details>"
            f"<details><summary>selection (BIC charge on F, AIC on ĥ; smallest first)</summary>"
            f"<table>{''.join(selection)}</table></details>")


# ------------------------------------------------------------------- model, warnings, provenance

def _nonlinear_model_rows(nl) -> list[tuple[str, str]]:
    f = nl.input_nonlinearity()
    rows = [("input nonlinearity F̄", f"{nl.type.replace('_', '-')} (evidence: {_html.escape(nl.evidence)})")]
    if f.type == "backlash":
        rows.append(("ascending border", f"v = {f.slope_up:.4g} (u − {f.d_plus:.4g})"))
        rows.append(("descending border", f"v = {f.slope_down:.4g} (u − ({f.d_minus:.4g}))"))
    else:
        rows.append(("ascending branch", f"v = u / {f.slope_up:.4g} + {f.d_plus:.4g}"))
        rows.append(("descending branch", f"v = u / {f.slope_down:.4g} + ({f.d_minus:.4g})"))
    w_lo, w_hi = nl.w_range[0], nl.w_range[1]
    rows.append(("output nonlinearity h̄(w)", poly_text(nl.h_coefficients) + f" on w ∈ [{_num(w_lo)}, {_num(w_hi)}]"
                 + f" (degree {nl.degree}, method {_html.escape(nl.method)})"))
    return rows


def _linear_model_rows(lin) -> list[tuple[str, str]]:
    par = lin.parametric
    rows = []
    if "error" in par:
        rows.append(("linear block Ḡ(s)", f"no parametric fit ({_html.escape(str(par['error']))})"))
    elif np.size(par.get("num", [])) > 0:
        rows.append(("linear block Ḡ(s)", tf_text(par["num"], par["den"], float(par["delay"]))))
        poles = np.asarray(par["poles"], float).reshape(-1, 2)
        rows.append(("poles of Ḡ", ", ".join(f"{re:.4g}" + (f"{im:+.4g}j" if abs(im) > 1e-12 else "")
                                             for re, im in poles)))
    rows.append(("stage 2 method", _html.escape(lin.method)))
    return rows


def model_html(run: RunData) -> str:
    """The identified model (stage 1's F and h, stage 2's G) and the true one."""
    rows = []
    if run.nonlinear is not None:
        rows += _nonlinear_model_rows(run.nonlinear)
    if run.linear is not None:
        rows += _linear_model_rows(run.linear)
    if run.truth is not None:
        f, g, h = run.truth.input, run.truth.linear, run.truth.output
        rows.append(("truth: F̄", f"{f.type.replace('_', '-')}, S<sup>a</sup> = {f.slope_up:.4g}, "
                     f"S<sup>d</sup> = {f.slope_down:.4g}, d<sup>+</sup> = {f.d_plus:.4g}, "
                     f"d<sup>−</sup> = {f.d_minus:.4g}"))
        if isinstance(h, PolynomialH):
            rows.append(("truth: h̄(w)", poly_text(h.coefficients)))
        rows.append(("truth: Ḡ(s)", tf_text(g.num, g.den, g.delay)))
    if not rows:
        return "<p class='missing'>No identified model in this directory.</p>"
    return "<table class='model'>" + "".join(_tr([f"<b>{k}</b>", v]) for k, v in rows) + "</table>"


def adequacy_html(run: RunData) -> str:
    """The model's route (stages or whole fit, and why) and its adequacy against a noise floor
    estimated from the data (:mod:`hwid.adequacy`), from ``identification.json``."""
    ident = run.identification or {}
    ad = ident.get("adequacy")
    if not ident:
        return ""
    rows = [("route", _html.escape(f"{ident.get('route')}: {ident.get('why', '')}"))]
    if ad:
        floor = ad.get("floor") or {}
        held = ad.get("rms_held_out")
        rows += [("adequacy", f"<b>{_html.escape(str(ad.get('verdict')).upper())}</b>: {_html.escape(str(ad.get('reason', '')))}"),
                 ("RMS on the fit records", f"{ad.get('rms_fit'):.4g}" if ad.get("rms_fit") is not None else "–"),
                 ("RMS on held-out records", "none held out" if held is None else f"{held:.4g}"),
                 ("noise floor", _html.escape(f"{floor.get('sigma', float('nan')):.4g} ({floor.get('source')})"))]
    return "<table class='model'>" + "".join(_tr([f"<b>{k}</b>", v]) for k, v in rows) + "</table>"


def warnings_html(run: RunData) -> str:
    """The stages' warnings and the failed runs of a batch."""
    items = []
    for stage, result in (("stage 1", run.nonlinear), ("stage 2", run.linear)):
        for w in (result.warnings if result is not None else ()):
            items.append(f"<li><b>{stage}:</b> {_html.escape(str(w))}</li>")
    if run.batch:
        for i, p in enumerate(run.batch.get("points", [])):
            if p.get("n_errors"):
                items.append(f"<li><b>batch point {i}:</b> {p['n_errors']} run(s) failed</li>")
    if not items:
        return "<p>No warnings were raised.</p>"
    return f"<ul class='warn' id='warnings'>{''.join(items)}</ul>"


def provenance_html(run: RunData) -> str:
    """Each file's provenance attributes and the config text."""
    rows = [_tr(["file", "config sha256", "hwid", "seed", "dt (s)", "created (UTC)", "command"], True)]
    for name, p in run.provenance.items():
        rows.append(_tr([name, f"<code>{_html.escape(str(p.get('config_sha256', '—'))[:16])}</code>",
                         _html.escape(str(p.get("hwid_version", "—"))), _html.escape(str(p.get("seed", "—"))),
                         _html.escape(str(p.get("dt", "—"))), _html.escape(str(p.get("created", "—"))),
                         f"<code>{_html.escape(str(p.get('argv', '—')))}</code>"]))
    text = next((p.get("config") for p in run.provenance.values() if p.get("config")), None)
    config_text = (f"<details><summary>config ({_html.escape(run.config_name or '?')})</summary>"
                   f"<pre>{_html.escape(text)}</pre></details>") if text else ""
    now = _dt.datetime.now(_dt.timezone.utc).isoformat(timespec="seconds")
    return (f"<table id='provenance'>{''.join(rows)}</table>{config_text}"
            f"<p class='note'>Report written {now} by hwid {__version__}.</p>")
