"""The run report: read a run directory, draw the figures, write one self-contained HTML page.

``write_report(DIR)`` reads whichever of these are present and reports what is missing:

=====================  =========================================================================
``simulation.h5``      the experiments (staircases, sines) and, for simulated plants, the truth
``nonlinear.h5``       stage 1 (:func:`hwid.results.read_nonlinear`)
``linear.h5``          stage 2 (:func:`hwid.results.read_linear`)
``batch.h5``           Monte Carlo summaries (:func:`hwid.results.read_batch_summary`)
=====================  =========================================================================

and writes into ``DIR/report/``: every figure as ``NAME.png`` and ``NAME.svg``, ``figures.json``
(the list of figures) and ``report.html``, with the figures embedded as base64 PNG so the page is
one file. A small script marks ``<body data-images-loaded="N/M">`` once the page has loaded, for
browser tests.
"""
from __future__ import annotations

import base64
import datetime as _dt
import html as _html
import io
import json
import os
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any

import numpy as np

from hwid import HwidError, __version__
from hwid.report import figures as F
from hwid.results import ResultsError, read_batch_summary, read_diagnosis, read_linear, read_nonlinear

FILES = ("simulation.h5", "nonlinear.h5", "linear.h5", "batch.h5", "diagnosis.h5")

# ---- the paper's published numbers (Section 6), shown beside ours when the config is the paper's
PAPER_CONFIG_NAME = "paper-section6"
# j -> (U_j, X_j(M) "true", X_hat_j(M)), Table 1
PAPER_TABLE1 = {5: (0.2, -0.075, -0.076), 6: (0.4, -0.047, -0.048), 7: (0.6, 0.047, 0.045),
                8: (0.8, 0.075, 0.074), 9: (1.0, 0.03, 0.028), 10: (1.2, 0.27, 0.26),
                16: (0.0, 0.03, 0.031), 17: (-0.3, 0.075, 0.076), 18: (-0.6, -0.047, -0.046),
                19: (-1.0, -0.03, -0.029), 20: (-1.2, -0.27, -0.265), 21: (-1.4, -1.78, -1.775)}
# Section 6.1: d_hat^+(M), S_hat^d(M), d_hat^-(M)
PAPER_PARAMS = {"d_plus": 0.503, "slope_down": 1.01, "d_minus": -0.49}
# omega_i -> (phi, phi_hat_N, |G|, |G_hat_N|), Table 2
PAPER_TABLE2 = {0.01: (0.07, 0.065, 0.998, 1.01), 0.02: (0.14, 0.147, 0.99, 0.97),
                0.05: (0.34, 0.33, 0.96, 0.95), 0.1: (0.66, 0.68, 0.87, 0.89),
                0.2: (1.16, 1.19, 0.65, 0.68)}


# ================================================================================ reading a run

@dataclass
class RunData:
    """Everything the report shows, read from a run directory (plain data and stage results)."""

    directory: Path
    present: dict[str, bool]
    provenance: dict[str, dict]                 # file name -> root attributes
    cfg: Any = None                             # hwid.config.Config, if the config text was stored
    config_name: str | None = None
    records: dict = field(default_factory=dict)   # name -> hwid.plant.Record
    truth: Any = None                           # normalised true HWModel (simulated plants)
    nonlinear: Any = None                       # stage 1 result
    linear: Any = None                          # stage 2 result
    batch: dict | None = None                   # hwid.results.read_batch_summary(...)
    diagnosis: dict | None = None               # hwid.diagnose.load_diagnosis(...)
    notes: list[str] = field(default_factory=list)   # what is missing, what could not be shown

    @property
    def is_paper(self) -> bool:
        return self.config_name == PAPER_CONFIG_NAME


def _attrs(f) -> dict:
    out = {}
    for k, v in f.attrs.items():
        if isinstance(v, bytes):
            v = v.decode()
        elif isinstance(v, np.generic):
            v = v.item()
        out[k] = v
    return out


def _model_from_dict(d: dict):
    """An :class:`hwid.model.HWModel` from ``HWModel.to_dict()`` as stored by ``write_dict``."""
    from hwid.blocks.linear import LinearBlock
    from hwid.blocks.static import PiecewiseH, PolynomialH
    from hwid.model import HWModel, InputNonlinearity
    f = d["input_nonlinearity"]
    lin = d["linear"]
    on = d["output_nonlinearity"]
    if "polynomial" in on:
        h = PolynomialH(tuple(float(c) for c in np.ravel(on["polynomial"])))
    else:
        pieces = on["pieces"]
        pieces = [pieces[k] for k in sorted(pieces, key=int)] if isinstance(pieces, dict) else list(pieces)
        h = PiecewiseH(tuple(float(b) for b in np.ravel(on["breaks"])),
                       tuple(tuple(float(c) for c in np.ravel(p)) for p in pieces))
    return HWModel(InputNonlinearity(str(f["type"]), float(f["slope_up"]), float(f["slope_down"]),
                                     float(f["d_plus"]), float(f["d_minus"])),
                   LinearBlock(tuple(float(c) for c in np.ravel(lin["num"])),
                               tuple(float(c) for c in np.ravel(lin["den"])), float(lin.get("delay", 0.0))),
                   h)


def load_run(directory: str | Path) -> RunData:
    """Read a run directory. Raises :class:`hwid.HwidError` (one line) when ``directory`` is not a
    directory, holds no hwid results, or holds a file that is broken, foreign or from another config."""
    from hwid.results import open_results, read_dict
    d = Path(directory)
    if not d.exists():
        raise HwidError(f"{d}: no such directory")
    if not d.is_dir():
        raise HwidError(f"{d}: not a directory (give the run directory that holds simulation.h5 ...)")
    present = {name: (d / name).is_file() for name in FILES}
    if not any(present.values()):
        raise HwidError(f"{d}: no hwid results here (expected one of {', '.join(FILES)})")
    run = RunData(d, present, {})

    # the config: from the first file that stored it (all files must agree, checked below)
    for name in FILES:
        if present[name]:
            kind = name.split(".")[0]
            with open_results(d / name, kind) as f:
                run.provenance[name] = _attrs(f)
    texts = {n: p.get("config") for n, p in run.provenance.items() if p.get("config")}
    hashes = {n: p.get("config_sha256") for n, p in run.provenance.items() if p.get("config_sha256")}
    if len(set(hashes.values())) > 1:
        raise HwidError(f"{d}: the results files come from different configs "
                        f"({', '.join(f'{n} {h[:12]}' for n, h in hashes.items())}); rerun the stages")
    if texts:
        from hwid import config as C
        text = next(iter(texts.values()))
        try:
            run.cfg = C.loads(text, source_path=f"{d}/{next(iter(texts))}:config")
        except HwidError as err:
            run.notes.append(f"the stored config could not be read again ({err}); truth and protocol "
                             "details from it are not shown")
    run.config_name = (run.cfg.name if run.cfg is not None else
                       next((p.get("config_name") for p in run.provenance.values() if p.get("config_name")), None))

    if present["simulation.h5"]:
        with open_results(d / "simulation.h5", "simulation") as f:
            if "experiments" in f:
                run.records.update(read_signals(f["experiments"]))
            if "truth" in f and "normalised" in f["truth"]:
                try:
                    run.truth = _model_from_dict(read_dict(f["truth/normalised"]))
                except (KeyError, TypeError, ValueError) as err:
                    run.notes.append(f"simulation.h5: the stored truth could not be read ({err})")
    if run.truth is None and run.cfg is not None and run.cfg.plant.kind == "hammerstein_wiener":
        from hwid.model import from_config
        run.truth = from_config(run.cfg.plant).normalised()

    batch_only = (present["batch.h5"] or present["diagnosis.h5"]) and not any(present[n] for n in FILES[:3])
    if present["nonlinear.h5"]:
        run.nonlinear = read_nonlinear(d / "nonlinear.h5", run.cfg)
        _records_from(d / "nonlinear.h5", "nonlinear", run)
    elif not batch_only:
        run.notes.append("nonlinear.h5 is missing: stage 1 (the input and output nonlinearities) has not "
                         "run here; run `hwid run` or the stage 1 command to get Table 1 and Figs. 9, 12")
    if present["linear.h5"]:
        run.linear = read_linear(d / "linear.h5", run.cfg)
        _records_from(d / "linear.h5", "linear", run)
    elif not batch_only:
        run.notes.append("linear.h5 is missing: stage 2 (G(jω)) has not run here; Table 2 and the Bode "
                         "plot are not shown")
    if not present["simulation.h5"] and not run.records and not batch_only:
        run.notes.append("simulation.h5 is missing: no measured experiments to plot")
    if present["batch.h5"]:
        run.batch = read_batch_summary(d / "batch.h5")
    if present["diagnosis.h5"]:
        try:
            run.diagnosis = read_diagnosis(d / "diagnosis.h5")
        except ResultsError as err:
            run.notes.append(f"diagnosis.h5 could not be read ({err})")
    return run


SIGNALS = ("u", "y", "x")     # what the figures draw (v, w, z are not read: they are large)


def read_signals(group, keys=SIGNALS, skip=()) -> dict:
    """Like :func:`hwid.results.read_records`, reading only the datasets ``keys`` of the experiments
    not named in ``skip``."""
    from hwid.plant import Record
    from hwid.results import ResultsError, read_padded
    out = {}
    for name, g in group.items():
        if name in skip:
            continue
        try:
            # the sine figures use y and x only: u (as long as y) is not read for them
            want = [k for k in keys if not (k == "u" and name.startswith("sine_"))]
            kw = {k: (read_padded(g[k], int(g.attrs.get("n", 0))) if k in want and k in g else None)
                  for k in SIGNALS}
            attrs = {k: v for k, v in g.attrs.items() if k not in ("dt", "n")}
            if kw.get("y") is None:
                raise KeyError("y")
            out[name] = Record(name, float(g.attrs["dt"]), attrs=attrs, **kw)
        except (KeyError, OSError, TypeError, ValueError) as err:
            raise ResultsError(f"{group.file.filename}: experiment {name!r} is unreadable ({err})") from None
    return out


def _records_from(path: Path, kind: str, run: RunData) -> None:
    """Experiments stored in a stage file (``experiments/``) fill in those simulation.h5 lacks."""
    from hwid.results import open_results
    with open_results(path, kind) as f:
        if "experiments" in f:
            run.records.update(read_signals(f["experiments"], skip=set(run.records)))


# ================================================================================ small helpers

def _get(obj, *names, default=None):
    """The first attribute (or mapping key) of ``obj`` among ``names`` that exists and is not None."""
    if obj is None:
        return default
    for n in names:
        v = obj.get(n) if isinstance(obj, dict) else getattr(obj, n, None)
        if v is not None:
            return v
    return default


def _attr_list(rec, key):
    v = rec.attrs.get(key)
    if v is None:
        return None
    if isinstance(v, bytes):
        v = v.decode()
    if isinstance(v, str):
        v = json.loads(v)
    return np.asarray(v, float)


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
    return f"{x:.{digits}g}" if abs(x) >= 1 else f"{x:.{digits}g}"


def _pm(est, ci, digits: int = 4) -> str:
    """``estimate [lo, hi]`` for a 95 % interval."""
    if est is None:
        return "—"
    if ci is None:
        return _num(est, digits)
    lo, hi = ci
    return f"{_num(est, digits)} <span class='ci'>[{_num(lo, digits)}, {_num(hi, digits)}]</span>"


def poly_text(coefficients, var: str = "w", digits: int = 4) -> str:
    """Ascending coefficients as ``c_p w^p + ... + c_0`` (descending powers, as in the paper)."""
    c = np.asarray(coefficients, float)
    terms = []
    for i in range(c.size - 1, -1, -1):
        ci = c[i]
        if ci == 0:
            continue
        mag = f"{abs(ci):.{digits}g}"
        mono = var if i == 1 else f"{var}^{i}"
        body = mag if i == 0 else (mono if mag == "1" else f"{mag} {mono}")
        sign = "−" if ci < 0 else "+"
        terms.append((sign, body))
    if not terms:
        return "0"
    s = ("−" if terms[0][0] == "−" else "") + terms[0][1]
    for sign, body in terms[1:]:
        s += f" {sign} {body}"
    return s


def tf_text(num, den, delay: float = 0.0, digits: int = 4) -> str:
    """``num(s) / den(s) e^{-delay s}`` from descending coefficients."""
    def p(c):
        c = np.asarray(c, float)
        return poly_text(c[::-1], "s", digits)
    s = f"({p(num)}) / ({p(den)})"
    if delay:
        s += f" · e^(−{delay:.{digits}g} s)"
    return s


# ================================================================================ stage-result views

def _ci(nl, key):
    ci = _get(nl, "ci", default={}) or {}
    v = ci.get(key) if isinstance(ci, dict) else None
    if v is None:
        v = _get(nl, f"{key}_ci")
    if v is None:
        return None
    v = np.asarray(v, float).ravel()
    return (float(v[0]), float(v[1])) if v.size == 2 else None


def _h_coef_ci(nl, n):
    ci = _get(nl, "ci", default={}) or {}
    v = ci.get("h_coefficients") if isinstance(ci, dict) else None
    if v is None:
        v = _get(nl, "h_coefficients_ci")
    if v is None and isinstance(ci, dict):
        cand = [ci.get(f"h_c{i}", ci.get(f"c{i}")) for i in range(n)]
        v = cand if all(c is not None for c in cand) else None
    if v is None:
        return [None] * n
    v = np.asarray(v, float).reshape(-1, 2)
    return [tuple(r) for r in v]


def _h_cov(nl, n):
    """Covariance of the ``n`` h-coefficients, cut from the result's full covariance by its names."""
    c = _get(nl, "h_cov", "h_coefficients_cov")
    if c is not None:
        return np.asarray(c, float)
    cov = _get(nl, "cov")
    names = _get(nl, "param_names")
    if cov is None:
        return None
    cov = np.asarray(cov, float)
    if names is None:
        return cov if cov.shape == (n, n) else None
    names = [str(x.decode() if isinstance(x, bytes) else x) for x in np.ravel(names)]
    idx = []
    for i in range(n):
        for cand in (f"h_c{i}", f"c{i}", f"c_{i}"):
            if cand in names:
                idx.append(names.index(cand))
                break
        else:
            if i == 0:          # h(0) = 0 (Section 4): c_0 is fixed, not estimated
                idx.append(-1)
                continue
            return None
    out = np.zeros((n, n))
    sel = [k for k, j in enumerate(idx) if j >= 0]
    out[np.ix_(sel, sel)] = cov[np.ix_([idx[k] for k in sel], [idx[k] for k in sel])]
    return out


def _level_split(v, rec_up, rec_down):
    """``(up, down)`` arrays of a per-level quantity of stage 1, stored per staircase or concatenated
    (ascending levels first)."""
    if v is None:
        return None, None
    if isinstance(v, dict):
        return (np.asarray(v.get("up", v.get("staircase_up")), float) if v.get("up", v.get("staircase_up")) is not None else None,
                np.asarray(v.get("down", v.get("staircase_down")), float) if v.get("down", v.get("staircase_down")) is not None else None)
    if isinstance(v, (tuple, list)) and len(v) == 2 and np.ndim(v[0]) == 1:
        return np.asarray(v[0], float), np.asarray(v[1], float)
    v = np.asarray(v, float).ravel()
    n_up = _attr_list(rec_up, "levels").size if rec_up is not None else None
    if n_up is None:
        return v, None
    return v[:n_up], v[n_up:]


@dataclass
class StaircaseView:
    name: str
    direction: str
    t: np.ndarray
    u: np.ndarray
    y: np.ndarray
    x: np.ndarray | None
    levels: np.ndarray
    spans: list                       # (t0, t1) of each level, s
    stops: np.ndarray                 # one past the last sample of each level
    windows: list | None = None       # averaging windows, s
    windows_assumed: bool = False
    X_hat: np.ndarray | None = None
    X_ci: np.ndarray | None = None    # 95 % half-widths
    X_true: np.ndarray | None = None
    flat: int | None = None


def staircase_views(run: RunData) -> dict[str, StaircaseView]:
    """The staircase experiments with their levels, windows and ``X_hat_j`` (stage 1), when present."""
    out = {}
    nl = run.nonlinear
    recs = {d: run.records.get(f"staircase_{d}") for d in ("up", "down")}
    split = lambda v: _level_split(v, recs["up"], recs["down"]) if nl is not None else (None, None)  # noqa: E731
    X = split(_get(nl, "X_hat"))
    S = split(_get(nl, "X_hat_se"))
    ci = (_get(nl, "ci", default={}) or {}).get("X_hat") if nl is not None else None
    CI = split(None if ci is None else [0.5 * (hi - lo) for lo, hi in np.reshape(np.asarray(ci, float), (-1, 2))])
    fit = _get(nl, "fit", default={}) or {}
    W0 = split(fit.get("first_sample"))
    WN = split(fit.get("n_averaged"))
    for k, d in enumerate(("up", "down")):
        rec = recs[d]
        if rec is None:
            continue
        levels = _attr_list(rec, "levels")
        lead = _attr_list(rec, "lead_in")
        hold = float(rec.attrs.get("hold", np.nan))
        if levels is None or lead is None or not np.isfinite(hold):
            run.notes.append(f"{rec.name}: level attributes missing, cannot mark the levels")
            continue
        n_hold = int(round(hold / rec.dt))
        starts = (np.arange(levels.size) + lead.size) * n_hold
        stops = starts + n_hold
        t = rec.t
        spans = [(s * rec.dt, e * rec.dt) for s, e in zip(starts, stops)]
        v = StaircaseView(rec.name, d, t, rec.u, rec.y, rec.x, levels, spans, stops)
        if rec.x is not None:
            v.X_true = rec.x[stops - 1]
        elif run.truth is not None:
            v.X_true = run.truth.staircase_steady(lead, levels)
        if X[k] is not None and X[k].size == levels.size:
            v.X_hat = X[k]
            if CI[k] is not None and CI[k].size == levels.size:
                v.X_ci = CI[k]
            elif S[k] is not None and S[k].size == levels.size:
                v.X_ci = F.Z95 * S[k]
            if W0[k] is not None and WN[k] is not None:
                v.windows = [(a * rec.dt, (a + n) * rec.dt) for a, n in zip(W0[k], WN[k])]
            else:   # the stage did not say: show the second half of each hold (the usual steady part)
                v.windows = [((s + n_hold // 2) * rec.dt, e * rec.dt) for s, e in zip(starts, stops)]
                v.windows_assumed = True
            v.flat = _get(nl, f"flat_{d}")
            v.flat = int(v.flat) if v.flat is not None else None
        out[d] = v
    return out


@dataclass
class SineView:
    name: str
    omega: float
    amplitude: float
    dt: float
    start: int                      # first steady-state sample (after the lead-in periods)
    t_fold: np.ndarray
    y_fold: np.ndarray
    x_fold: np.ndarray | None
    raw: tuple | None
    ks: np.ndarray
    coef: np.ndarray                # measured C_k
    se: np.ndarray | None
    dc: float
    model: np.ndarray | None = None  # fitted model's C_k
    model_dc: float = 0.0
    truth_coef: np.ndarray | None = None
    truth_dc: float = 0.0


def ls_harmonics(sig, dt: float, omega: float, start: int, k_max: int):
    """Least-squares ``dc + sum_k Im(C_k e^{j k omega t})`` fit of ``sig`` over the whole periods from
    the period that begins at sample ``start`` on (exact frequencies, no leakage whatever ``T/dt``):
    stage 2's :func:`hwid.identify.harmonics.fit_harmonics` with white-noise standard errors and no
    further periods dropped. Returns ``(C_k for k = 1..k_max, dc, se)``, ``se`` the standard error of
    each real component of ``C_k`` (eqs. 26a-e in least-squares form); NaN without a whole period."""
    from hwid.identify.harmonics import fit_harmonics
    first = int(round(start * dt * omega / (2 * np.pi)))
    try:
        f = fit_harmonics(sig, dt, omega, k_max, first_period=first, noise_model="white", steady_alpha=0.0)
    except ValueError:
        return np.full(k_max, np.nan + 0j), float("nan"), np.full(k_max, np.nan)
    return np.asarray(f.coef), float(f.dc), np.sqrt(np.asarray(f.var))


def _harmonics_for(lin, i: int, omega: float):
    """(ks, coef, se, model, dc, model_dc) of stage 2 at frequency index ``i``, or None."""
    H = _get(lin, "harmonics")
    if H is None:
        return None
    h = H[i] if isinstance(H, (list, tuple)) else (H.get(i) or H.get(str(i)) or H.get(f"{omega:g}")
                                                   if isinstance(H, dict) else None)
    if h is None:
        return None
    ks = _get(h, "ks")
    coef = _get(h, "coef")
    if coef is None and _get(h, "coef_re") is not None:
        coef = np.asarray(_get(h, "coef_re")) + 1j * np.asarray(_get(h, "coef_im"))
    if ks is None or coef is None:
        return None
    se = _get(h, "se")
    if se is None and _get(h, "var") is not None:
        se = np.sqrt(np.asarray(_get(h, "var"), float))
    ks = np.asarray(ks).astype(int)
    model = None
    if _get(h, "predicted_re") is not None:
        # the fitted model (eq. 20) at the harmonics it uses; every other harmonic is zero in the model
        pred = np.asarray(_get(h, "predicted_re"), float) + 1j * np.asarray(_get(h, "predicted_im"), float)
        used = np.asarray(_get(h, "used_harmonics", default=ks[:pred.size]), float).astype(int)
        model = np.zeros(ks.size, complex)
        for k, c in zip(np.ravel(used), np.ravel(pred)):
            model[ks == k] = c
    dc = float(_get(h, "dc", default=0.0))
    return (ks, np.asarray(coef, complex), None if se is None else np.asarray(se, float), model, dc, dc)


def sine_views(run: RunData) -> list[SineView]:
    recs = sorted((r for n, r in run.records.items() if n.startswith("sine_")),
                  key=lambda r: float(r.attrs.get("omega", 0)))
    lin = run.linear
    freqs = np.asarray(_get(lin, "frequencies", default=[]), float)
    degree = None
    if run.nonlinear is not None:
        degree = _get(run.nonlinear, "degree")
    if degree is None and run.truth is not None:
        degree = len(getattr(run.truth.output, "coefficients", ())) - 1 or None
    out = []
    for rec in recs:
        omega = float(rec.attrs["omega"])
        U = float(rec.attrs.get("amplitude", 1.0))
        T = 2 * np.pi / omega
        lead = int(rec.attrs.get("lead_in_periods", 0))
        start = int(np.ceil(lead * T / rec.dt - 1e-9))
        t_f, y_f, cnt = F.fold_period(rec.y, rec.dt, omega, start)
        x_f = None
        if rec.x is not None:
            # x is noise-free and T-periodic: interpolate it on phase (it may be stored for the
            # last periods only, which leaves phase bins empty if folded)
            idx = np.flatnonzero(np.isfinite(rec.x))
            idx = idx[idx >= start]
            if idx.size:
                ph = np.mod(idx * rec.dt, T)
                order = np.argsort(ph)
                x_f = np.interp(t_f, ph[order], rec.x[idx][order], period=T)
        n1 = int(np.ceil(T / rec.dt))
        raw = (np.arange(n1) * rec.dt, rec.y[start:start + n1]) if rec.y.size >= start + n1 else None
        kmax = int(max(3, min((degree or 5) + 2, np.floor(np.pi / (omega * rec.dt)) - 1)))
        ks = np.arange(1, kmax + 1)
        h = None
        if freqs.size:
            j = np.flatnonzero(np.isclose(freqs, omega, rtol=1e-9))
            if j.size:
                h = _harmonics_for(lin, int(j[0]), omega)
        if h is not None:
            ks, coef, se, model, dc, model_dc = h
        else:
            coef, dc, se = ls_harmonics(rec.y, rec.dt, omega, start, int(ks[-1]))
            model, model_dc = None, 0.0
        v = SineView(rec.name, omega, U, rec.dt, start, t_f, y_f, x_f, raw, ks, coef, se, dc, model, model_dc)
        if rec.x is not None:
            # x is noise-free and periodic: its last two whole periods give its harmonics exactly
            P = int(np.floor((rec.x.size - start) * rec.dt / T + 1e-9))
            first = start + int(np.ceil(max(P - 2, 0) * T / rec.dt - 1e-9))
            c, v.truth_dc, _ = ls_harmonics(rec.x, rec.dt, omega, first, int(ks.max()))
            v.truth_coef = c[ks - 1]
        out.append(v)
    return out


# ================================================================================ figures

@dataclass
class FigureItem:
    name: str
    section: str
    caption: str
    figure: Any
    group: str = ""          # figures of one group share a row of the page


def steady_w(f, rec) -> np.ndarray | None:
    """``W_j = F_bar[U_j]`` of each level of a staircase record through the operator ``f`` along the
    whole level sequence, lead-in included (eqs. 5, 7a-b, 14a-b): ``U_j - d^+`` on the ascending
    border, the flat path's value before it."""
    levels, lead = _attr_list(rec, "levels"), _attr_list(rec, "lead_in")
    if levels is None or lead is None:
        return None
    return f.staircase_steady(lead, levels)


def _points_on_w(run, views, f_est):
    """Stage-1 points ``(F_hat[U_j], X_hat_j)`` on the ``w`` axis (Fig. 12): ``(U_j - d_hat^+, X_hat_j)``
    on the ascending border, the flat path's ``W_1`` before ``j_a``."""
    pts = {}
    for d, label in (("up", r"ascending staircase $(\hat F[U_j],\ \hat X_j)$"),
                     ("down", r"descending staircase $(\hat F[U_j],\ \hat X_j)$")):
        v = views.get(d)
        rec = run.records.get(f"staircase_{d}")
        if v is None or v.X_hat is None or rec is None:
            continue
        w = steady_w(f_est, rec)
        if w is not None and w.size == v.X_hat.size:
            pts[label] = (w, v.X_hat, v.X_ci)
    return pts


def build_figures(run: RunData) -> list[FigureItem]:
    """Every figure the run's data allow, in report order."""
    items: list[FigureItem] = []
    views = staircase_views(run)
    fig_no = {"up": ("10", "11"), "down": ("13", "14")}
    for d, v in views.items():
        a, b = fig_no[d]
        word = "ascending (eq. 6)" if d == "up" else "descending (eq. 13)"
        items.append(FigureItem(f"{v.name}_input", "stage1",
                                f"Fig. {a}: the {word} staircase input u(t).",
                                F.plot_staircase_input(v.t, v.u, v.levels, v.spans,
                                                       title=f"Staircase input, {word} (Fig. {a})"), v.name))
        cap = f"Fig. {b}: the measured output y(t) of the {word} staircase"
        if v.X_hat is not None:
            cap += (", the averaging windows (shaded" + (", assumed: the stage did not store them" if v.windows_assumed else "")
                    + ") and X̂_j (eq. 9) with 95 % bars")
        if v.x is not None:
            cap += "; dashed: the undisturbed output x(t) (simulation ground truth)"
        items.append(FigureItem(f"{v.name}_output", "stage1", cap + ".",
                                F.plot_staircase_output(v.t, v.y, v.windows, v.X_hat, v.X_ci, v.x, v.flat,
                                                        title=f"Staircase output, {word} (Fig. {b})"), v.name))
    nl = run.nonlinear
    truth = run.truth
    if nl is not None:
        f_est = nl.input_nonlinearity() if hasattr(nl, "input_nonlinearity") else None
        coef = np.asarray(_get(nl, "h_coefficients"), float)
        cov = _h_cov(nl, coef.size)
        w_range = _get(nl, "w_range")
        t_h = truth.output if truth is not None else None
        pts = _points_on_w(run, views, f_est) if f_est is not None else {}
        w_plot = None
        if run.linear is not None and np.size(_get(run.linear, "gain", default=[])):
            r = float(_get(run.linear, "amplitude", default=1.0)) * float(np.max(_get(run.linear, "gain")))
            w_plot = (-r, r)      # where the sines drive w (eq. 17)
        items.append(FigureItem("h", "stage1",
                                "Fig. 12: the estimated output nonlinearity ĥ (eq. 12) with its 95 % band "
                                "(delta method on the coefficients' covariance), the true h̄ (eq. 4c) when "
                                "known, and the staircase points on the w axis through the estimated borders; "
                                "shaded grey: the w range the staircases identified h on (outside it, as far as "
                                "the sines drive w, h is extrapolated).",
                                F.plot_h(coef, cov, None if w_range is None else tuple(np.ravel(w_range)[:2]),
                                         t_h, pts, w_plot=w_plot), "nonlinearities"))
        if f_est is not None:
            lv = np.concatenate([v.levels for v in views.values()]) if views else np.array([-1.5, 1.5])
            pad = 0.1 * (lv.max() - lv.min())
            ci = {k: _ci(nl, k) for k in ("d_plus", "d_minus")}
            items.append(FigureItem("borders", "stage1",
                                    "Fig. 9: the estimated ascending and descending borders of the normalised "
                                    "input nonlinearity F̄ (eq. 4a) and its cycle, against the truth; bars: 95 % "
                                    "intervals of d⁺ and d⁻.",
                                    F.plot_borders(f_est, truth.input if truth is not None else None,
                                                   (lv.min() - pad, lv.max() + pad), ci), "nonlinearities"))
    lin = run.linear
    if lin is not None:
        om = np.asarray(_get(lin, "frequencies"), float)
        gain_ci = _pairs(_get(lin, "gain_ci"))
        phase_ci = _pairs(_get(lin, "phase_ci"))
        par = _get(lin, "parametric")
        par = _parametric_block(par)
        items.append(FigureItem("bode", "stage2",
                                "Bode plot of Ḡ(jω): the frequency-by-frequency estimates (eq. 37 or the "
                                "harmonic fit) with 95 % interval bars, the parametric fit"
                                + (" and the true Ḡ (eq. 4b)" if truth is not None else "") + ".",
                                F.plot_bode(om, _get(lin, "gain"), _get(lin, "phase"),
                                            gain_ci, phase_ci, par, truth.linear if truth is not None else None)))
    for s in sine_views(run):
        t = s.t_fold
        model = F.harmonic_series(t, s.omega, s.model, s.model_dc, s.ks) if s.model is not None else None
        items.append(FigureItem(f"{s.name}_period", "stage2",
                                f"Fig. 15 at ω = {s.omega:g} rad/s: one period of the raw output y(t) (grey), the "
                                "period average x̂_N(t) of eq. (23a)"
                                + (", the fitted harmonic model (eq. 20)" if model is not None else "")
                                + (", and the undisturbed x(t) (dashed)" if s.x_fold is not None else "") + ".",
                                F.plot_period(t, s.y_fold, s.omega, model, s.x_fold, s.raw), s.name))
        items.append(FigureItem(f"{s.name}_spectrum", "stage2",
                                f"Fig. 16 at ω = {s.omega:g} rad/s: modulus s_k and phase ψ_k (eqs. 26a-b) of the "
                                "harmonics of the steady-state output, 95 % bars"
                                + (", the fitted model (circles)" if s.model is not None else "")
                                + (", the truth (crosses)" if s.truth_coef is not None else "") + ".",
                                F.plot_spectrum(s.ks, s.coef, s.se, s.model, s.truth_coef,
                                                title=f"Harmonic spectrum, ω = {s.omega:g} rad/s (Fig. 16)"), s.name))
    if run.batch is not None and run.batch.get("points"):
        names = list(dict.fromkeys(n for p in run.batch["points"] for n in p.get("stats", {})))
        for key, sel, what in (("nonlinear", [n for n in names if "@" not in n], "stage 1 (borders, h̄)"),
                               ("linear", [n for n in names if "@" in n], "stage 2 (|G|, φ per ω)")):
            if sel:
                items.append(FigureItem(f"batch_{key}", "batch",
                                        f"Monte Carlo, {what}: RMSE of each estimate (relative to |truth|, absolute "
                                        "where the truth is 0) with the CRLB standard deviation (dashed, where "
                                        "known), and the coverage of the 95 % intervals, against the swept key.",
                                        F.plot_batch_summary(run.batch, sel), "batch"))
    if run.diagnosis is not None:
        from hwid.report.figures import plot_ranking, plot_residual_map
        items.append(FigureItem("diagnosis_residual_map", "diagnosis",
                                "Residual map of the validation experiments: local RMS gap over the noise floor, "
                                "before (left) and after (right) adding the verdict's effect.",
                                plot_residual_map(run.diagnosis), "diagnosis_map"))
        items.append(FigureItem("diagnosis_ranking", "diagnosis",
                                "Ranking of the catalogue: the share of the gap above the noise floor that each "
                                "effect explains on validation data its fit did not use.",
                                plot_ranking(run.diagnosis), "diagnosis_ranking"))
    return items


def diagnosis_html(diag: dict) -> str:
    """The verdict table of ``hwid diagnose`` (the numbers of its JSON summary) and the candidates."""
    s = diag["summary"]
    v, w = s["verdict"], s.get("where", {})
    rows = [_tr(["verdict", "block", "explained", "gap before", "gap after", "noise floor", "where", "trend"], True),
            _tr([_html.escape(str(v["effect"])), _html.escape(str(v["block"])), _num(v["explained_fraction"], 3),
                 _num(s["gap_before"]), _num(s["gap_after"]), _num(s["noise_floor"]),
                 _html.escape(str(w.get("region", ""))), _html.escape(str(w.get("trend", "")))])]
    out = [f"<table id='diagnosis'>{''.join(rows)}</table>"]
    if "gap_model_refit" in s and s.get("model", {}).get("source") == "identified":
        out.append(f"<p>Model identified from the same plant; with h re-estimated on the diagnosis's fit "
                   f"experiments its gap is {_num(s['gap_model_refit'])}.</p>")
    exps = w.get("experiments", [])[:8]
    if exps:
        er = [_tr(["experiment", "gap before / noise", "gap after / noise"], True)]
        er += [_tr([_html.escape(e["name"]), _num(e["before_over_noise"], 3), _num(e["after_over_noise"], 3)])
               for e in exps]
        out.append(f"<details><summary>per experiment (largest gaps)</summary><table>{''.join(er)}</table></details>")
    cr = [_tr(["candidate", "block", "explained", "gap after", "score", "parameters"], True)]
    for c in s.get("candidates", []):
        par = ", ".join(f"{k} = {_num(x)}" for k, x in c.get("params", {}).items())
        cr.append(_tr([_html.escape(c["effect"]), _html.escape(str(c.get("block", ""))),
                       _num(c["explained_fraction"], 3), _num(c["gap_after"]), _num(c["score"], 4),
                       _html.escape(par)]))
    out.append(f"<table id='candidates'>{''.join(cr)}</table>")
    return "".join(out)


def _pair(ci):
    if ci is None:
        return None
    v = np.ravel(np.asarray(ci, float))
    return (float(v[0]), float(v[1])) if v.size == 2 else None


def _pairs(ci):
    """``(lo, hi)`` arrays from an interval array of shape (n, 2) or (2, n) or a pair of arrays."""
    if ci is None:
        return None
    a = np.asarray(ci, float)
    if a.ndim == 2 and a.shape[1] == 2 and (a.shape[0] != 2 or np.all(a[:, 0] <= a[:, 1])):
        return a[:, 0], a[:, 1]
    if a.ndim == 2 and a.shape[0] == 2:
        return a[0], a[1]
    return None


def _parametric_block(par):
    """A :class:`hwid.blocks.linear.LinearBlock` from the stage 2 parametric fit (dict or object)."""
    if par is None:
        return None
    from hwid.blocks.linear import LinearBlock
    if hasattr(par, "freqresp"):
        return par
    num, den = _get(par, "num"), _get(par, "den")
    if num is None or den is None or np.size(num) == 0 or np.size(den) == 0:
        return None
    return LinearBlock(tuple(float(c) for c in np.ravel(num)), tuple(float(c) for c in np.ravel(den)),
                       float(_get(par, "delay", default=0.0)))


# ================================================================================ tables

def _tr(cells, head: bool = False) -> str:
    tag = "th" if head else "td"
    return "<tr>" + "".join(f"<{tag}>{c}</{tag}>" for c in cells) + "</tr>"


def table1_html(run: RunData) -> str:
    """Table 1: ``X_hat_j(M)`` per level with 95 % intervals, the truth and the paper's values."""
    views = staircase_views(run)
    if not views:
        return "<p class='missing'>No staircase experiments: Table 1 cannot be shown.</p>"
    paper = run.is_paper
    head = ["j", "U<sub>j</sub>", "X̂<sub>j</sub> [95 %]", "X<sub>j</sub> true"]
    if paper:
        head += ["paper X<sub>j</sub>", "paper X̂<sub>j</sub>"]
    rows = [_tr(head, True)]
    n_up = views["up"].levels.size if "up" in views else 0
    for d in ("up", "down"):
        v = views.get(d)
        if v is None:
            continue
        offset = 0 if d == "up" else n_up
        for i, U in enumerate(v.levels):
            j = offset + i + 1
            est = None if v.X_hat is None else v.X_hat[i]
            ci = None if v.X_ci is None or est is None else (est - v.X_ci[i], est + v.X_ci[i])
            cells = [str(j), _num(U), _pm(est, ci), _num(None if v.X_true is None else v.X_true[i])]
            if paper:
                p = PAPER_TABLE1.get(j)
                ok = p is not None and np.isclose(p[0], U)
                cells += [_num(p[1]) if ok else "", _num(p[2]) if ok else ""]
            cls = " class='flat'" if v.flat is not None and i < v.flat else ""
            rows.append(_tr(cells).replace("<tr>", f"<tr data-j='{j}'{cls}>", 1))
    note = ("<p class='note'>Rows in grey lie on a flat path (j ≤ j<sub>a</sub>, or the first j<sub>d</sub> "
            "descending levels: eqs. 7a, 14a).</p>")
    return f"<table class='t1' id='table1'>{''.join(rows)}</table>{note}"


def params_html(run: RunData) -> str:
    """The input nonlinearity's parameters and h_bar's coefficients (estimate [95 %], truth, paper)."""
    nl = run.nonlinear
    if nl is None:
        return ""
    t = run.truth
    paper = run.is_paper
    head = ["parameter", "estimate [95 %]", "truth"] + (["paper"] if paper else [])
    rows = [_tr(head, True)]
    names = {"slope_up": "S<sup>a</sup> (normalised)", "slope_down": "S<sup>d</sup>/S<sup>a</sup>",
             "d_plus": "d<sup>+</sup>", "d_minus": "d<sup>−</sup>"}
    for k, label in names.items():
        est = _get(nl, k)
        tv = getattr(t.input, k) if t is not None else None
        cells = [label, _pm(est, _ci(nl, k)), _num(tv)]
        if paper:
            cells.append(_num(PAPER_PARAMS.get(k)) if k in PAPER_PARAMS else "")
        rows.append(_tr(cells).replace("<tr>", f"<tr data-param='{k}'>", 1))
    coef = np.asarray(_get(nl, "h_coefficients", default=[]), float)
    cis = _h_coef_ci(nl, coef.size)
    tcoef = np.asarray(getattr(t.output, "coefficients", []), float) if t is not None else np.array([])
    for i, c in enumerate(coef):
        tv = tcoef[i] if i < tcoef.size else (0.0 if tcoef.size else None)
        cells = [f"h̄ c<sub>{i}</sub>", _pm(c, cis[i]), _num(tv)] + ([""] if paper else [])
        rows.append(_tr(cells).replace("<tr>", f"<tr data-param='h_c{i}'>", 1))
    return f"<table class='params' id='params'>{''.join(rows)}</table>"


def table2_html(run: RunData) -> str:
    """Table 2: ``phi_hat_N(omega_i)`` and ``|G_hat_N(j omega_i)|`` with 95 % intervals, CRLB, truth, paper."""
    lin = run.linear
    if lin is None:
        return "<p class='missing'>linear.h5 is missing: Table 2 cannot be shown.</p>"
    om = np.asarray(_get(lin, "frequencies"), float)
    gain = np.asarray(_get(lin, "gain"), float)
    phase = np.asarray(_get(lin, "phase"), float)
    gci = _pairs(_get(lin, "gain_ci"))
    pci = _pairs(_get(lin, "phase_ci"))
    cg = _get(lin, "crlb_gain")
    cp = _get(lin, "crlb_phase")
    amp = _get(lin, "amplitude")
    if amp is None and run.cfg is not None and run.cfg.protocols.sine is not None:
        amp = run.cfg.protocols.sine.amplitude
    method = str(_get(lin, "method", default="nls"))
    other = "paper" if method == "nls" else "nls"
    others = [((_get(h, "estimates", default={}) or {}).get(other) or {}) for h in (_get(lin, "harmonics") or ())]
    show_other = any("gain" in o for o in others)
    G = run.truth.linear.freqresp(om) if run.truth is not None else None
    phi_true = None
    if run.truth is not None:
        phi_true = np.array([float(-np.unwrap(np.angle(run.truth.linear.freqresp(np.linspace(0, w, 512)[1:])))[-1])
                             for w in om])
    paper = run.is_paper
    extrap = _get(lin, "extrapolated")
    head = ["i", "U<sub>i</sub>", "ω<sub>i</sub> (rad/s)", "φ̂(ω<sub>i</sub>) [95 %]", "φ true",
            "|Ĝ(jω<sub>i</sub>)| [95 %]", "|G| true", "CRLB sd φ / |G|"]
    if show_other:
        head += ["eq. (37), one harmonic: φ̂ / |Ĝ|" if other == "paper" else "NLS, all harmonics: φ̂ / |Ĝ|"]
    if paper:
        head += ["paper φ", "paper φ̂", "paper |G|", "paper |Ĝ|"]
    rows = [_tr(head, True)]
    for i, w in enumerate(om):
        cr = ""
        if cp is not None and cg is not None:   # stage 2 stores variance bounds
            cr = f"{_num(np.sqrt(cp[i]), 3)} / {_num(np.sqrt(cg[i]), 3)}"
        cells = [str(i + 1), _num(amp), _num(w),
                 _pm(phase[i], None if pci is None else (pci[0][i], pci[1][i])),
                 _num(None if phi_true is None else phi_true[i]),
                 _pm(gain[i], None if gci is None else (gci[0][i], gci[1][i])),
                 _num(None if G is None else abs(G[i])), cr]
        if show_other:
            o = others[i] if i < len(others) else {}
            cells.append(f"{_pm(o.get('phase'), _pair(o.get('phase_ci')))} / {_pm(o.get('gain'), _pair(o.get('gain_ci')))}"
                         + (f" (k = {int(o['harmonic'])})" if o.get("harmonic") is not None else "")
                         if "gain" in o else _html.escape(str(o.get("error", "—")))[:120])
        if extrap is not None and bool(np.ravel(extrap)[i]):
            cells[2] += " <span class='flag' title='extrapolated'>*</span>"
        if paper:
            key = next((k for k in PAPER_TABLE2 if np.isclose(k, w)), None)
            p = PAPER_TABLE2.get(key)
            cells += [_num(x) for x in p] if p else [""] * 4
        rows.append(_tr(cells).replace("<tr>", f"<tr data-omega='{w:g}'>", 1))
    return f"<table class='t2' id='table2'>{''.join(rows)}</table>"


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


def model_html(run: RunData) -> str:
    rows = []
    nl, lin = run.nonlinear, run.linear
    if nl is not None:
        f = nl.input_nonlinearity() if hasattr(nl, "input_nonlinearity") else None
        typ = str(_get(nl, "type", default="?"))
        rows.append(("input nonlinearity F̄", f"{typ.replace('_', '-')}"
                     + (f" (evidence: {_html.escape(str(_get(nl, 'evidence')))})" if _get(nl, "evidence") is not None else "")))
        if f is not None:
            if f.type == "backlash":
                rows.append(("ascending border", f"v = {f.slope_up:.4g} (u − {f.d_plus:.4g})"))
                rows.append(("descending border", f"v = {f.slope_down:.4g} (u − ({f.d_minus:.4g}))"))
            else:
                rows.append(("ascending branch", f"v = u / {f.slope_up:.4g} + {f.d_plus:.4g}"))
                rows.append(("descending branch", f"v = u / {f.slope_down:.4g} + ({f.d_minus:.4g})"))
        coef = _get(nl, "h_coefficients")
        if coef is not None:
            w_range = _get(nl, "w_range")
            rng = f" on w ∈ [{_num(np.ravel(w_range)[0])}, {_num(np.ravel(w_range)[1])}]" if w_range is not None else ""
            rows.append(("output nonlinearity h̄(w)", poly_text(coef) + rng
                         + f" (degree {_get(nl, 'degree', default=len(np.ravel(coef)) - 1)}, method {_html.escape(str(_get(nl, 'method', default='?')))})"))
    if lin is not None:
        par = _get(lin, "parametric")
        if par is not None and _get(par, "error") is not None:
            rows.append(("linear block Ḡ(s)", f"no parametric fit ({_html.escape(str(_get(par, 'error')))})"))
        elif par is not None and np.size(_get(par, "num", default=[])) > 0:
            rows.append(("linear block Ḡ(s)", tf_text(_get(par, "num"), _get(par, "den"),
                                                      float(_get(par, "delay", default=0.0)))))
            poles = _get(par, "poles")
            if poles is None:
                poles = np.roots(np.ravel(_get(par, "den")))
            poles = np.asarray(poles)
            if poles.dtype.names is None and np.iscomplexobj(poles) is False and poles.ndim == 2:
                poles = poles[:, 0] + 1j * poles[:, 1]
            rows.append(("poles of Ḡ", ", ".join(f"{complex(p).real:.4g}" + (f"{complex(p).imag:+.4g}j" if abs(complex(p).imag) > 1e-12 else "")
                                               for p in np.ravel(poles))))
        rows.append(("stage 2 method", _html.escape(str(_get(lin, "method", default="?")))))
    if run.truth is not None:
        t = run.truth
        rows.append(("truth: F̄", f"{t.input.type.replace('_', '-')}, S<sup>a</sup> = {t.input.slope_up:.4g}, "
                     f"S<sup>d</sup> = {t.input.slope_down:.4g}, d<sup>+</sup> = {t.input.d_plus:.4g}, "
                     f"d<sup>−</sup> = {t.input.d_minus:.4g}"))
        if hasattr(t.output, "coefficients"):
            rows.append(("truth: h̄(w)", poly_text(t.output.coefficients)))
        rows.append(("truth: Ḡ(s)", tf_text(t.linear.num, t.linear.den, t.linear.delay)))
    if not rows:
        return "<p class='missing'>No identified model in this directory.</p>"
    return "<table class='model'>" + "".join(_tr([f"<b>{k}</b>", v]) for k, v in rows) + "</table>"


def warnings_html(run: RunData) -> str:
    items = []
    for src, obj in (("stage 1", run.nonlinear), ("stage 2", run.linear)):
        for w in _get(obj, "warnings", default=()) or ():
            items.append(f"<li><b>{src}:</b> {_html.escape(str(w))}</li>")
    if run.batch:
        for i, p in enumerate(run.batch.get("points", [])):
            if p.get("n_errors"):
                items.append(f"<li><b>batch point {i}:</b> {p['n_errors']} run(s) failed</li>")
    if not items:
        return "<p>No warnings were raised.</p>"
    return f"<ul class='warn' id='warnings'>{''.join(items)}</ul>"


def provenance_html(run: RunData) -> str:
    rows = [_tr(["file", "config sha256", "hwid", "seed", "dt (s)", "created (UTC)", "command"], True)]
    for name, p in run.provenance.items():
        rows.append(_tr([name, f"<code>{_html.escape(str(p.get('config_sha256', '—'))[:16])}</code>",
                         _html.escape(str(p.get("hwid_version", "—"))), _html.escape(str(p.get("seed", "—"))),
                         _html.escape(str(p.get("dt", "—"))), _html.escape(str(p.get("created", "—"))),
                         f"<code>{_html.escape(str(p.get('argv', '—')))}</code>"]))
    text = next((p.get("config") for p in run.provenance.values() if p.get("config")), None)
    cfg = (f"<details><summary>config ({_html.escape(run.config_name or '?')})</summary>"
           f"<pre>{_html.escape(text)}</pre></details>") if text else ""
    now = _dt.datetime.now(_dt.timezone.utc).isoformat(timespec="seconds")
    return (f"<table id='provenance'>{''.join(rows)}</table>{cfg}"
            f"<p class='note'>Report written {now} by hwid {__version__}.</p>")


def render_html(run: RunData, items: list[FigureItem], pngs: dict[str, bytes]) -> str:
    def figs(section):
        rows: dict[str, list[str]] = {}
        for i in items:
            if i.section == section:
                rows.setdefault(i.group or i.name, []).append(_figure_html(i, pngs[i.name]))
        return "".join(f"<div class='row'>{''.join(r)}</div>" for r in rows.values())

    title = f"hwid report: {run.config_name or run.directory.name}"
    present = ", ".join(f"{n} {'✓' if ok else '✗'}" for n, ok in run.present.items())
    notes = "".join(f"<p class='missing'>{_html.escape(n)}</p>" for n in run.notes)
    parts = [f"<!DOCTYPE html><html lang='en'><head><meta charset='utf-8'><title>{_html.escape(title)}</title>",
             f"<style>{CSS}</style><script>{SCRIPT}</script></head>",
             f"<body data-figures='{len(items)}'><h1>{_html.escape(title)}</h1>",
             f"<p>Run directory <code>{_html.escape(str(run.directory))}</code>: {present}.</p>", notes,
             "<h2>Identified model</h2>", model_html(run)]
    if run.records or run.nonlinear is not None:
        parts += ["<h2>Stage 1: the nonlinearities (Section 4, Table 1)</h2>",
                  "<h3>Table 1: steady-state outputs X̂<sub>j</sub>(M), eq. (9)</h3>", table1_html(run)]
        if run.nonlinear is not None:
            parts += ["<h3>Estimated parameters (normalised model, eqs. 4a-c)</h3>", params_html(run)]
        parts.append(figs("stage1"))
    if run.linear is not None or any(n.startswith("sine_") for n in run.records):
        parts += ["<h2>Stage 2: the linear block G(jω) (Section 5, Table 2)</h2>",
                  "<h3>Table 2: frequency gain estimates</h3>", table2_html(run), figs("stage2")]
    if run.batch is not None:
        parts += ["<h2>Monte Carlo batch</h2>", batch_table_html(run.batch), figs("batch")]
    if run.diagnosis is not None:
        parts += ["<h2>Diagnosis: where and why the plant and the model part</h2>",
                  diagnosis_html(run.diagnosis), figs("diagnosis")]
    parts += ["<h2>Warnings</h2>", warnings_html(run), "<h2>Provenance</h2>", provenance_html(run),
              "</body></html>"]
    return "\n".join(parts)


def batch_table_html(summary: dict) -> str:
    pts = summary.get("points", [])
    if not pts:
        return "<p class='missing'>batch.h5 holds no sweep points yet.</p>"
    rows = [_tr(["point", "overrides", "runs", "estimate", "truth", "bias", "std", "RMSE", "coverage",
                 "CRLB sd"], True)]
    for i, p in enumerate(pts):
        ov = ", ".join(f"{k}={v}" for k, v in (p.get("overrides") or {}).items()) or "base"
        for name, s in p.get("stats", {}).items():
            rows.append(_tr([str(i), _html.escape(ov), str(p.get("n_runs", "")), _html.escape(name),
                             _num(s.get("truth")), _num(s.get("bias"), 3), _num(s.get("std"), 3),
                             _num(s.get("rmse"), 3), _num(s.get("coverage"), 3), _num(s.get("crlb_std"), 3)]))
    return f"<details><summary>summary table</summary><table id='batch'>{''.join(rows)}</table></details>"


# ================================================================================ writing

def _save(fig, path_stem: Path) -> bytes:
    """Save ``fig`` as PNG and SVG next to each other; return the PNG bytes. The layout is computed
    once and then frozen, so both formats share it (and it is not computed twice)."""
    if fig.get_layout_engine() is not None:
        fig.draw_without_rendering()
        fig.set_layout_engine("none")
    buf = io.BytesIO()
    fig.savefig(buf, format="png", dpi=100)
    png = buf.getvalue()
    _atomic_bytes(path_stem.with_suffix(".png"), png)
    sbuf = io.BytesIO()
    fig.savefig(sbuf, format="svg")
    _atomic_bytes(path_stem.with_suffix(".svg"), sbuf.getvalue())
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
    items = build_figures(run)
    pngs = {}
    for it in items:
        pngs[it.name] = _save(it.figure, out / it.name)
    manifest = [{"name": i.name, "section": i.section, "caption": i.caption} for i in items]
    _atomic_bytes(out / "figures.json", (json.dumps(manifest, indent=1) + "\n").encode())
    page = render_html(run, items, pngs)
    path = out / "report.html"
    _atomic_bytes(path, page.encode("utf-8"))
    return path
