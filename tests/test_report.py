"""`hwid report DIR`: the figures carry the right numbers, the page holds Tables 1-2 with the
stage results, the truth and the paper's values, partial and bad directories, and a real headless
browser loads every embedded figure."""
import html as _html
import json
import os
import re
import shutil
import subprocess
from pathlib import Path

import numpy as np
import pytest
from matplotlib.figure import Figure

import plants
from hwid import HwidError, config
from hwid.blocks.linear import LinearBlock
from hwid.cli import main
from hwid.report import figures, html, rundir, views

ROOT = Path(__file__).resolve().parents[1]

# the paper's Section 6 plant, shortened: dt 0.05 s, 40 s per level, 4 averaged periods
SMALL = ((ROOT / "configs" / "paper.yaml").read_text()
         .replace("dt: 0.01", "dt: 0.05").replace("hold: 150.0", "hold: 40.0")
         .replace("periods: 50, lead_in_periods: 3", "periods: 4, lead_in_periods: 2")
         .replace("[0.01, 0.02, 0.05, 0.1, 0.2]", "[0.1, 0.2, 0.5]"))
H_BAR = np.array([0, 0.5, 0, -3.36, 0, 6.4])                 # eq. (30c)
G_BAR = LinearBlock((0.1,), (1.0, 0.7, 0.1))                    # eq. (30b)
STAIR_FIGS = ["staircase_up_input", "staircase_up_output", "staircase_down_input", "staircase_down_output"]
SINE_FIGS = [f"sine_{i}_{k}" for i in range(3) for k in ("period", "spectrum")]


def _cfg(tmp_path_factory, text=SMALL, name="small.yaml"):
    p = tmp_path_factory.mktemp("cfg") / name
    p.write_text(text)
    return config.load(p)


@pytest.fixture(scope="module")
def cfg(tmp_path_factory):
    c = _cfg(tmp_path_factory)
    assert c.name == "paper-section6"
    return c


@pytest.fixture(scope="module")
def full_run(cfg, tmp_path_factory):
    """A complete run directory (both stages) with its report."""
    import warnings
    from hwid.pipeline import run
    out = tmp_path_factory.mktemp("full")
    with warnings.catch_warnings():
        warnings.simplefilter("ignore")
        run(cfg, out, report=True, echo=lambda *a: None)
    return out


def _rows(page, attr, key):
    m = re.search(rf"<tr {attr}='{re.escape(str(key))}'[^>]*>(.*?)</tr>", page, re.S)
    assert m, f"no row {attr}={key}"
    return [re.sub(r"<[^>]+>", " ", c) for c in re.findall(r"<td>(.*?)</td>", m.group(1), re.S)]


def _nums(cell):
    return [float(x) for x in re.findall(r"-?\d+(?:\.\d+)?(?:e[-+]?\d+)?", cell)]


def _line(ax, gid):
    lines = [l for l in ax.get_lines() if l.get_gid() == gid]
    assert len(lines) == 1, f"{gid}: {len(lines)} lines"
    return lines[0]


# --------------------------------------------------------------------------------- figures on plain data

def test_plot_h_truth_band_and_points():
    rng = np.random.default_rng(0)
    coef = H_BAR + rng.normal(0, 0.01, 6)
    A = rng.normal(size=(6, 6)) * 0.01
    cov = A @ A.T
    pts = {"up": (np.array([-0.3, 0.1, 0.5]), np.array([-0.07, 0.05, 0.03]), np.array([0.01, 0.01, 0.01]))}
    fig = figures.plot_h(coef, cov, (-0.9, 0.7), H_BAR, pts)
    assert isinstance(fig, Figure)
    ax = fig.axes[0]
    t = _line(ax, "truth")
    w = t.get_xdata()
    assert w.min() < -0.9 and w.max() > 0.7
    np.testing.assert_allclose(t.get_ydata(), np.polynomial.polynomial.polyval(w, H_BAR), rtol=1e-12, atol=1e-12)
    est = _line(ax, "estimate")
    np.testing.assert_allclose(est.get_ydata(), np.polynomial.polynomial.polyval(w, coef), rtol=1e-12, atol=1e-12)
    # band: h_hat +- 1.96 sqrt(phi' Sigma phi), checked at one grid point by hand
    band = [c for c in ax.collections if c.get_gid() == "band"][0]
    v = band.get_paths()[0].vertices
    i = 123
    phi = w[i] ** np.arange(6)
    half = 1.959963984540054 * np.sqrt(phi @ cov @ phi)
    ys = v[np.isclose(v[:, 0], w[i]), 1]
    assert ys.max() == pytest.approx(est.get_ydata()[i] + half, rel=1e-9)
    assert ys.min() == pytest.approx(est.get_ydata()[i] - half, rel=1e-9)
    p = _line(ax, "points")
    np.testing.assert_array_equal(p.get_xdata(), pts["up"][0])
    np.testing.assert_array_equal(p.get_ydata(), pts["up"][1])


def test_plot_h_into_given_axes_returns_its_figure():
    fig = Figure()
    ax = fig.add_subplot()
    assert figures.plot_h([0, 1.0], ax=ax) is fig
    with pytest.raises(ValueError, match="needs 2 axes"):
        figures.plot_bode([1.0], [1.0], [0.1], ax=ax)


def test_plot_bode_truth_is_G_and_estimates_with_bars():
    om = np.array([0.01, 0.1, 0.2])
    G = G_BAR.freqresp(om) / G_BAR.dc_gain
    gain, phase = np.abs(G) * 1.01, -np.angle(G) + 0.01
    gci = np.c_[gain - 0.02, gain + 0.03]
    fig = figures.plot_bode(om, gain, phase, (gci[:, 0], gci[:, 1]), None,
                      parametric=LinearBlock((0.11,), (1.0, 0.7, 0.11)), truth=LinearBlock((1.0,), (10.0, 7.0, 1.0)))
    ag, ap = fig.axes
    t = _line(ag, "truth")
    wg = t.get_xdata()
    np.testing.assert_allclose(t.get_ydata(), np.abs(0.1 / ((1j * wg + 0.5) * (1j * wg + 0.2))), rtol=1e-12)
    tp = _line(ap, "truth_phase")
    np.testing.assert_allclose(tp.get_ydata(), np.arctan(wg / 0.5) + np.arctan(wg / 0.2), rtol=1e-10)
    np.testing.assert_allclose(_line(ag, "parametric").get_ydata(), np.abs(0.11 / ((1j * wg) ** 2 + 0.7j * wg + 0.11)))
    e = _line(ag, "estimate")
    np.testing.assert_array_equal(e.get_xdata(), om)
    np.testing.assert_array_equal(e.get_ydata(), gain)
    np.testing.assert_array_equal(_line(ap, "estimate_phase").get_ydata(), phase)
    # the interval bars span [lo, hi]
    segs = [c for c in ag.collections if len(c.get_segments()) == 3][0].get_segments()
    np.testing.assert_allclose([s[:, 1].min() for s in segs], gci[:, 0])
    np.testing.assert_allclose([s[:, 1].max() for s in segs], gci[:, 1])
    assert ag.get_xscale() == "log"


def test_plot_borders_truth_and_estimate():
    from hwid.model import InputNonlinearity
    tr = InputNonlinearity("backlash", 1.0, 1.0, 0.5, -0.5)
    est = InputNonlinearity("backlash", 1.0, 1.02, 0.51, -0.49)
    fig = figures.plot_borders(est, tr, (-1.5, 1.5), {"d_plus": (0.5, 0.52), "d_minus": (-0.5, -0.48)})
    ax = fig.axes[0]
    u = _line(ax, "truth_ascending").get_xdata()
    np.testing.assert_allclose(_line(ax, "truth_ascending").get_ydata(), u - 0.5)
    np.testing.assert_allclose(_line(ax, "truth_descending").get_ydata(), u + 0.5)
    np.testing.assert_allclose(_line(ax, "estimate_descending").get_ydata(), 1.02 * (u + 0.49))
    cu, cv = _line(ax, "truth_cycle").get_data()
    assert cv.max() == pytest.approx(1.0) and cv.min() == pytest.approx(-1.0)   # the closed cycle over [-1.5, 1.5]
    assert _line(ax, "ci_d_plus").get_xdata()[0] == pytest.approx(0.51)


def test_plot_staircase_output_marks_windows_and_X_hat():
    t = np.arange(400) * 0.5
    y = np.repeat([0.1, 0.2, 0.3, 0.4], 100)
    win = [(25.0, 50.0), (75.0, 100.0), (125.0, 150.0), (175.0, 200.0)]
    X = np.array([0.1, 0.2, 0.3, 0.4]) + 0.001
    fig = figures.plot_staircase_output(t, y, win, X, np.full(4, 0.01), x_true=y, flat=1)
    ax = fig.axes[0]
    hl = [c for c in ax.collections if c.get_gid() == "X_hat"][0]
    segs = hl.get_segments()
    np.testing.assert_allclose([s[0, 1] for s in segs], X)
    np.testing.assert_allclose([(s[0, 0], s[1, 0]) for s in segs], win)
    np.testing.assert_array_equal(_line(ax, "truth").get_ydata(), y)
    assert _line(ax, "flat").get_xdata()[0] == 50.0


def test_decimate_keeps_envelope():
    t = np.arange(100_000) * 0.01
    y = np.sin(t) + (np.arange(t.size) == 54_321) * 5.0
    tt, yy = figures.decimate_envelope(t, y, 2000)
    assert yy.size <= 2000 and yy.max() == y.max() and yy.min() == y.min()
    assert np.all(np.diff(tt) >= 0)


def test_ls_harmonics_exact_at_non_integer_samples_per_period():
    dt, omega = 0.05, 0.3       # T/dt = 418.88...
    t = np.arange(int(10 * 2 * np.pi / omega / dt)) * dt
    C = np.array([0.8 - 0.3j, 0.0, 0.2 + 0.1j, 0, 0.05j])
    x = 0.1 + views.harmonic_series(t, omega, C)
    c, dc, se = views.ls_harmonics(x, dt, omega, 100, 5)
    np.testing.assert_allclose(c, C, atol=1e-10)
    assert dc == pytest.approx(0.1, abs=1e-10)
    noisy = x + np.random.default_rng(1).normal(0, 0.1, x.size)
    c, dc, se = views.ls_harmonics(noisy, dt, omega, 0, 5)
    n = x.size
    np.testing.assert_allclose(se, 0.1 * np.sqrt(2 / n), rtol=0.1)   # white-noise SE of Re, Im C_k
    assert np.all(np.abs(c - C) < 5 * se)


def test_plot_spectrum_bars_are_moduli():
    ks = np.arange(1, 6)
    C = np.array([0.8 - 0.3j, 1e-4, 0.2 + 0.1j, 1e-4, 0.05j])
    fig = figures.plot_spectrum(ks, C, np.full(5, 1e-3), model=C * 1.01, truth=C)
    am, ap = fig.axes
    bars = [p for p in am.patches]
    np.testing.assert_allclose([b.get_height() for b in bars], np.abs(C))
    np.testing.assert_allclose(_line(am, "model").get_ydata(), np.abs(C) * 1.01)
    # phases drawn only where the harmonic stands out of its 95 % bar
    mp = _line(ap, "measured_phase")
    np.testing.assert_array_equal(mp.get_xdata(), [1, 3, 5])
    np.testing.assert_allclose(mp.get_ydata(), np.angle(C[[0, 2, 4]]))


SUMMARY = {"sweep_keys": ["plant.noise.std"], "points": [
    {"overrides": {"plant.noise.std": s}, "n_runs": 50, "stats": {
        "d_plus": {"truth": 0.5, "mean": 0.5, "bias": 0.0, "std": 0.02 * s / 0.01, "rmse": 0.02 * s / 0.01,
                   "coverage": c},
        "gain@0.1": {"truth": 0.87, "mean": 0.87, "bias": 1e-3, "std": 0.01 * s / 0.01,
                     "rmse": 0.011 * s / 0.01, "coverage": 0.96, "crlb_std": 0.009 * s / 0.01}}}
    for s, c in ((0.1, 0.9), (0.001, 0.94), (0.01, 0.95))]}


def test_plot_batch_summary_synthetic():
    fig = figures.plot_batch_summary(SUMMARY)
    ar, ac = fig.axes
    r = _line(ar, "rmse:d_plus")
    np.testing.assert_allclose(r.get_xdata(), [0.001, 0.01, 0.1])          # sorted by the swept key
    np.testing.assert_allclose(r.get_ydata(), np.array([0.002, 0.02, 0.2]) / 0.5)   # relative to |truth|
    np.testing.assert_allclose(_line(ar, "crlb:gain@0.1").get_ydata(), np.array([0.0009, 0.009, 0.09]) / 0.87)
    with pytest.raises(AssertionError):
        _line(ar, "crlb:d_plus")                                              # no CRLB for it: no line
    np.testing.assert_allclose(_line(ac, "coverage:d_plus").get_ydata(), [0.94, 0.95, 0.9])
    assert _line(ac, "nominal").get_ydata()[0] == 0.95
    assert ar.get_xscale() == "log" and ar.get_yscale() == "log"
    assert ac.get_xlabel() == "plant.noise.std"


# --------------------------------------------------------------------------------- the full report

def test_full_report_files_and_figures(full_run):
    rep = full_run / "report"
    names = [f["name"] for f in json.loads((rep / "figures.json").read_text())]
    assert names == STAIR_FIGS + ["h", "borders", "bode"] + SINE_FIGS
    for n in names:
        assert (rep / f"{n}.png").read_bytes()[:8] == b"\x89PNG\r\n\x1a\n"
        assert b"<svg" in (rep / f"{n}.svg").read_bytes()[:2000]
    page = (rep / "report.html").read_text()
    srcs = re.findall(r"<img [^>]*src='([^']*)'", page)
    assert len(srcs) == len(names) and all(s.startswith("data:image/png;base64,") for s in srcs)
    assert "http://" not in page and "https://" not in page          # self-contained
    assert f"data-figures='{len(names)}'" in page


def test_full_report_figures_hold_truth_and_estimates(full_run):
    from hwid.results import read_linear, read_nonlinear
    run = rundir.load_run(full_run)
    nl, lin = read_nonlinear(full_run / "nonlinear.h5"), read_linear(full_run / "linear.h5")
    figs = {i.name: i.figure for i in html.build_figures(run)}
    # Fig. 12: the truth is h_bar of eq. (30c) on the plotted grid, the estimate is stage 1's h
    ax = figs["h"].axes[0]
    w, ht = _line(ax, "truth").get_data()
    np.testing.assert_allclose(ht, np.polynomial.polynomial.polyval(w, H_BAR), rtol=1e-9, atol=1e-12)
    np.testing.assert_allclose(_line(ax, "estimate").get_ydata(), nl.h(w), rtol=1e-9, atol=1e-12)
    # the points: ascending levels on the border sit at U_j - d_hat^+, the flat ones at W_1
    up = [l for l in ax.get_lines() if l.get_gid() == "points"][0]
    U = np.array(config.loads(SMALL).protocols.staircase.levels_up)
    ja = nl.flat_up
    np.testing.assert_allclose(up.get_xdata()[ja:], U[ja:] - nl.d_plus, rtol=1e-12)
    np.testing.assert_allclose(up.get_ydata(), np.asarray(nl.X_hat)[:U.size])
    # Bode: the truth is |G_bar(j omega)| (eq. 30b), the estimates are stage 2's
    ag, ap = figs["bode"].axes
    wg, gt = _line(ag, "truth").get_data()
    np.testing.assert_allclose(gt, np.abs(0.1 / ((1j * wg + 0.5) * (1j * wg + 0.2))), rtol=1e-12)
    np.testing.assert_allclose(_line(ag, "estimate").get_ydata(), lin.gain)
    np.testing.assert_allclose(_line(ap, "estimate_phase").get_ydata(), lin.phase)
    # Fig. 15: the model through the stage-2 harmonics; truth = period average of x(t)
    ax = figs["sine_0_period"].axes[0]
    t, xm = _line(ax, "model").get_data()
    _, xt = _line(ax, "truth").get_data()
    assert np.max(np.abs(xm - xt)) < 0.05 * np.ptp(xt)
    # Fig. 16: the measured moduli are stage 2's harmonic LS coefficients
    h0 = lin.harmonics[0]
    am = figs["sine_0_spectrum"].axes[0]
    np.testing.assert_allclose([b.get_height() for b in am.patches],
                               np.abs(np.asarray(h0["coef_re"]) + 1j * np.asarray(h0["coef_im"])))
    # Fig. 9: the true borders of the paper's backlash
    ab = figs["borders"].axes[0]
    u, v = _line(ab, "truth_ascending").get_data()
    np.testing.assert_allclose(v, u - 0.5)
    np.testing.assert_allclose(_line(ab, "estimate_ascending").get_ydata(), u - nl.d_plus)


def test_full_report_tables(full_run):
    from hwid.results import read_linear, read_nonlinear
    from hwid.results import read_records
    import h5py
    page = (full_run / "report" / "report.html").read_text()
    nl, lin = read_nonlinear(full_run / "nonlinear.h5"), read_linear(full_run / "linear.h5")
    with h5py.File(full_run / "simulation.h5") as f:
        recs = read_records(f["experiments"])
    # Table 1, j = 5 (U = 0.2) and j = 21 (U = -1.4): estimate [interval], truth, the paper's two values
    for j, U, paper in ((5, 0.2, (-0.075, -0.076)), (21, -1.4, (-1.78, -1.775))):
        cells = _rows(page, "data-j", j)
        assert _nums(cells[1]) == [U]
        est, lo, hi = _nums(cells[2])
        lo_r, hi_r = nl.ci["X_hat"][j - 1]
        assert est == pytest.approx(nl.X_hat[j - 1], rel=1e-3)
        assert (lo, hi) == (pytest.approx(lo_r, rel=1e-3), pytest.approx(hi_r, rel=1e-3))
        rec = recs["staircase_up" if j <= 10 else "staircase_down"]
        n_hold = int(round(40.0 / 0.05))
        i = (j - 1) if j <= 10 else (j - 11)
        x_true = rec.x[(i + 3) * n_hold - 1]
        assert _nums(cells[3])[0] == pytest.approx(x_true, rel=1e-3)
        assert _nums(cells[4]) == [paper[0]] and _nums(cells[5]) == [paper[1]]
    # flat levels are marked (j_a = 4 for the paper's plant)
    assert re.search(r"<tr data-j='4' class='flat'>", page) and not re.search(r"<tr data-j='5' class='flat'>", page)
    # the borders: estimate [interval], truth, paper
    cells = _rows(page, "data-param", "d_plus")
    assert _nums(cells[1]) == pytest.approx([nl.d_plus, *nl.ci["d_plus"]], rel=1e-3)
    assert _nums(cells[2]) == [0.5] and _nums(cells[3]) == [0.503]
    cells = _rows(page, "data-param", "h_c5")
    assert _nums(cells[1])[0] == pytest.approx(nl.h_coefficients[5], rel=1e-3) and _nums(cells[2]) == [6.4]
    # Table 2 at omega = 0.1: phi_hat, |G_hat| with intervals, truth, CRLB, the paper's four values
    i = 0
    cells = _rows(page, "data-omega", "0.1")
    assert _nums(cells[2])[0] == 0.1
    assert _nums(cells[3]) == pytest.approx([lin.phase[i], *lin.phase_ci[i]], rel=1e-3)
    assert _nums(cells[4])[0] == pytest.approx(np.arctan(0.1 / 0.5) + np.arctan(0.1 / 0.2), rel=1e-3)
    assert _nums(cells[5]) == pytest.approx([lin.gain[i], *lin.gain_ci[i]], rel=1e-3)
    assert _nums(cells[6])[0] == pytest.approx(abs(G_BAR.freqresp(0.1)) / G_BAR.dc_gain, rel=1e-3)
    assert _nums(cells[7]) == pytest.approx([np.sqrt(lin.crlb_phase[i]), np.sqrt(lin.crlb_gain[i])], rel=6e-3)
    # the other estimator (eq. 37 on one harmonic) beside the NLS one
    o = lin.harmonics[i]["estimates"]["paper"]
    assert _nums(cells[8]) == pytest.approx([o["phase"], *o["phase_ci"], o["gain"], *o["gain_ci"], o["harmonic"]],
                                            rel=1e-3)
    assert _nums(" ".join(cells[9:13])) == [0.66, 0.68, 0.87, 0.89]
    assert _rows(page, "data-omega", "0.5")[9:] == ["", "", "", ""]       # not in the paper's Table 2
    # the model, the warnings, the provenance
    assert "6.4 w^5 − 3.36 w^3 + 0.5 w" in page                               # true h_bar
    assert "(0.1) / (s^2 + 0.7 s + 0.1)" in page                            # true G_bar
    for w in list(nl.warnings) + list(lin.warnings):
        assert _html.escape(w) in page
    sha = config.loads(SMALL).sha256
    assert sha[:16] in page and ">1<" in page                                  # config hash, seed


def test_report_in_browser_loads_every_figure(full_run, tmp_path):
    exe = _chromium()
    names = json.loads((full_run / "report" / "figures.json").read_text())
    m = len(names)
    assert m == 13
    cmd = [exe, "--headless", "--no-sandbox", "--disable-gpu", "--disable-background-networking",
           "--disable-component-update", "--disable-sync", "--no-first-run", f"--user-data-dir={tmp_path / 'prof'}",
           "--virtual-time-budget=5000", "--dump-dom", (full_run / "report" / "report.html").as_uri()]
    r = subprocess.run(cmd, capture_output=True, text=True, timeout=120)
    assert r.returncode == 0, r.stderr[-2000:]
    got = re.search(r'<body[^>]*data-images-loaded="(\d+)/(\d+)"', r.stdout)
    assert got, f"the page's load script did not run: {r.stdout[:500]}"
    assert got.group(0) and (int(got.group(1)), int(got.group(2))) == (m, m)


def _chromium() -> str:
    """Debian's chromium; installed with apt-get when missing (root only), else skip with the reason."""
    for name in ("chromium", "chromium-browser"):
        if shutil.which(name):
            return shutil.which(name)
    if os.geteuid() != 0 or not shutil.which("apt-get"):
        pytest.skip("no chromium and cannot install it (not root or no apt-get): the browser check needs "
                    "Debian's chromium package")
    env = dict(os.environ, DEBIAN_FRONTEND="noninteractive")
    try:
        subprocess.run(["apt-get", "update", "-q"], check=True, capture_output=True, timeout=600, env=env)
        subprocess.run(["apt-get", "install", "-y", "-q", "chromium"], check=True, capture_output=True,
                       timeout=900, env=env)
    except (subprocess.SubprocessError, OSError) as err:
        pytest.skip(f"chromium is not installed and apt-get could not install it ({type(err).__name__})")
    exe = shutil.which("chromium")
    if exe is None:
        pytest.skip("apt-get install chromium did not provide a chromium executable")
    return exe


# --------------------------------------------------------------------------------- partial and bad directories

def test_simulation_only(tmp_path, capsys, tmp_path_factory):
    from hwid.simulate import simulate
    simulate(_cfg(tmp_path_factory, SMALL.replace("[0.1, 0.2, 0.5]", "[0.2]")), tmp_path, progress=False)
    with pytest.raises(SystemExit) as e:
        main(["report", str(tmp_path)])
    assert e.value.code == 0
    assert "report.html" in capsys.readouterr().out
    page = (tmp_path / "report" / "report.html").read_text()
    names = [f["name"] for f in json.loads((tmp_path / "report" / "figures.json").read_text())]
    assert names == STAIR_FIGS + ["sine_0_period", "sine_0_spectrum"]
    assert "nonlinear.h5 is missing" in page and "linear.h5 is missing" in page
    assert "id='table2'" not in page and "Table 2 cannot be shown" in page
    # Table 1 shows the levels and the truth, no estimates
    cells = _rows(page, "data-j", 7)
    assert _nums(cells[1]) == [0.6] and cells[2] == "—" and _nums(cells[3])[0] == pytest.approx(0.0467, abs=1e-3)
    # the spectra are measured from the data (harmonic LS) when stage 2 is absent: x(t) is odd in w
    run = rundir.load_run(tmp_path)
    s = views.sine_views(run)[0]
    assert s.model is None
    np.testing.assert_allclose(np.abs(s.truth_coef[1::2]), 0, atol=1e-6)     # even harmonics of the truth
    assert np.all(np.abs(s.coef[[0, 2, 4]] - s.truth_coef[[0, 2, 4]]) < 5 * s.se[[0, 2, 4]])


def test_without_linear(full_run, tmp_path):
    for n in ("simulation.h5", "nonlinear.h5"):
        shutil.copy(full_run / n, tmp_path / n)
    path = html.write_report(tmp_path)
    page = path.read_text()
    names = [f["name"] for f in json.loads((tmp_path / "report" / "figures.json").read_text())]
    assert names == STAIR_FIGS + ["h", "borders"]      # the pipeline stores the sines in linear.h5
    assert "linear.h5 is missing" in page and "nonlinear.h5 is missing" not in page
    assert "id='table1'" in page and "id='params'" in page


@pytest.mark.parametrize("case", ["missing", "empty", "file", "foreign", "wrong_kind", "other_config"])
def test_bad_directories_one_line_exit_2(case, full_run, tmp_path, capsys, tmp_path_factory):
    d = tmp_path / "d"
    if case == "empty":
        d.mkdir()
    elif case == "file":
        d.write_text("x")
    elif case == "foreign":
        d.mkdir()
        (d / "simulation.h5").write_bytes(b"not hdf5 at all")
    elif case == "wrong_kind":
        d.mkdir()
        shutil.copy(full_run / "nonlinear.h5", d / "linear.h5")
    elif case == "other_config":
        from hwid.simulate import simulate
        d.mkdir()
        simulate(_cfg(tmp_path_factory, SMALL.replace("seed: 1", "seed: 2")), d, progress=False)
        shutil.copy(full_run / "nonlinear.h5", d / "nonlinear.h5")
    with pytest.raises(SystemExit) as e:
        main(["report", str(d)])
    assert e.value.code == 2
    err = capsys.readouterr().err
    assert err.startswith("hwid: error: ") and err.count("\n") == 1
    assert {"missing": "no such directory", "empty": "no hwid results", "file": "not a directory",
            "foreign": "not a readable HDF5", "wrong_kind": "expected 'linear'",
            "other_config": "different config"}[case] in err
    with pytest.raises(HwidError):
        rundir.load_run(d)


# --------------------------------------------------------------------------------- batches



def test_batch_directory(tmp_path, tmp_path_factory):
    import concurrent.futures as cf
    from hwid.batch import run_batch
    from hwid.results import read_batch_summary
    cfg = _cfg(tmp_path_factory, plants.config_text(plants.BATCH, **{"protocols.sine": plants.DELETE}), "fast.yaml")
    with cf.ThreadPoolExecutor(1) as ex:      # in-process: no worker start-up in a unit test
        run_batch(cfg, 1, tmp_path, [("plant.noise.std", [0.01, 0.03])], executor=ex, progress=False)
    path = html.write_report(tmp_path)
    page = path.read_text()
    names = [f["name"] for f in json.loads((tmp_path / "report" / "figures.json").read_text())]
    assert names == ["batch_nonlinear"]                          # no sines: no stage 2 estimates
    assert "id='batch'" in page and "Monte Carlo" in page
    assert "is missing" not in page                               # a batch directory has no stage files
    summ = read_batch_summary(tmp_path / "batch.h5")
    run = rundir.load_run(tmp_path)
    fig = [i.figure for i in html.build_figures(run) if i.name == "batch_nonlinear"][0]
    r = _line(fig.axes[0], "rmse:d_plus")
    np.testing.assert_allclose(r.get_xdata(), [0.01, 0.03])
    np.testing.assert_allclose(r.get_ydata(), [p["stats"]["d_plus"]["rmse"] / 0.4 for p in summ["points"]])


def test_batch_figures_split_by_stage():
    run = rundir.RunData(Path("."), {n: n == "batch.h5" for n in rundir.FILES}, {}, batch=SUMMARY)
    items = html.build_figures(run)
    assert [i.name for i in items] == ["batch_nonlinear", "batch_linear"]
    lin = items[1].figure.axes[0]
    assert [l.get_gid() for l in lin.get_lines()] == ["rmse:gain@0.1", "crlb:gain@0.1"]
    page = html.render_html(run, items, {i.name: b"png" for i in items})
    cells = _rows(page.replace("<tr><td>2</td>", "<tr data-x='p2'><td>2</td>", 1), "data-x", "p2")
    assert cells[3] == "d_plus" and _nums(cells[7]) == [0.02] and _nums(cells[8]) == [0.95]


def test_diagnosis_section_holds_the_json_numbers(tmp_path):
    """A ``hwid diagnose`` output directory (trusted simulator as ``--model``, a rig with a sensor
    lag): the report shows the verdict table with the JSON's numbers, the candidates, and the
    residual map and ranking figures."""
    import yaml
    from hwid.diagnose import diagnose
    import diagnose_rigs
    lv = [-1.0, -0.5, 0.0, 0.5, 1.0]
    cfg_p = tmp_path / "lag.yaml"
    cfg_p.write_text(yaml.safe_dump({
        "name": "lag", "seed": 3, "sampling": {"dt": 0.04},
        "plant": {"kind": "external", "callable": "diagnose_rigs:sensor_lag"},
        "protocols": {"staircase": {"levels_up": lv, "levels_down": lv[::-1], "hold": 6.0},
                      "sine": {"amplitude": 0.6, "frequencies": [0.5, 1.0], "periods": 2}}}))
    model_p = tmp_path / "base.yaml"
    model_p.write_text(yaml.safe_dump({"plant": diagnose_rigs.BASE}))
    out = tmp_path / "out"
    s = diagnose(config.load(cfg_p), out, model=model_p, echo=lambda *a: None)
    js = json.loads((out / "diagnosis.json").read_text())
    path = html.write_report(out)
    page = path.read_text()
    names = [f["name"] for f in json.loads((out / "report" / "figures.json").read_text())]
    assert names == ["diagnosis_residual_map", "diagnosis_ranking"]
    assert "is missing" not in page                        # a diagnosis directory needs no stage files
    m = re.search(r"<table id='diagnosis'>(.*?)</table>", page, re.S)
    cells = [re.sub(r"<[^>]+>", "", c).strip() for c in re.findall(r"<td>(.*?)</td>", m.group(1), re.S)]
    assert cells[0] == js["verdict"]["effect"] == s["verdict"]["effect"] == "sensor_lag"
    assert cells[1] == js["verdict"]["block"]
    for cell, key in zip(cells[3:6], ("gap_before", "gap_after", "noise_floor")):
        assert _nums(cell)[0] == pytest.approx(js[key], rel=1e-3)
    assert _nums(cells[2])[0] == pytest.approx(js["verdict"]["explained_fraction"], abs=1e-3)
    cand = re.search(r"<table id='candidates'>(.*?)</table>", page, re.S).group(1)
    first = [re.sub(r"<[^>]+>", "", c).strip() for c in re.findall(r"<td>(.*?)</td>", cand, re.S)][:4]
    assert first[0] == js["candidates"][0]["effect"]
    assert _nums(first[3])[0] == pytest.approx(js["candidates"][0]["gap_after"], rel=1e-3)


def test_diagnosis_section_says_why_and_what_the_confirmation_found():
    """A verdict turned `unexplained` by the confirmation: the section gives ``verdict.why`` and the
    confirmation's numbers, as in the JSON."""
    from hwid.report.tables import diagnosis_html
    conf = {"effect": "curved_borders", "experiment": "sine_validation_A1_w2.83", "z": 0.86, "excess": 0.04,
            "runs": 1, "times": 24, "z_rerun": 5.3, "excess_rerun": 0.051, "rig_seconds": 540.0,
            "contradicted": True}
    summary = {"verdict": {"effect": "unexplained", "block": "input", "explained_fraction": 0.0,
                           "why": "curved_borders removes the gap where it is largest but makes the model worse"},
               "where": {"region": "extremes", "trend": "none", "experiments": []},
               "gap_before": 4.06, "gap_after": 4.06, "noise_floor": 0.01, "model": {"source": "given"},
               "candidates": [], "confirmation": conf}
    page = diagnosis_html({"summary": summary})
    why = re.search(r"<p id='verdict-why'>(.*?)</p>", page).group(1)
    assert why.startswith("curved_borders removes the gap")
    line = re.search(r"<p id='confirmation'>(.*?)</p>", page).group(1)
    assert "sine_validation_A1_w2.83" in line and "24x" in line and line.endswith("contradicted.")
    assert _nums(line.split("run again")[1])[1:3] == pytest.approx([5.3, 0.051])
    assert "output-rails" not in page


def test_diagnosis_section_gives_the_output_rails():
    from hwid.report.tables import diagnosis_html
    summary = {"verdict": {"effect": "sensor_saturation", "block": "output", "explained_fraction": 1.0},
               "where": {"region": "extremes", "trend": "none", "experiments": []},
               "gap_before": 0.2, "gap_after": 0.01, "noise_floor": 0.01, "model": {"source": "identified"},
               "gap_model_refit": 0.1, "candidates": [],
               "output_rails": [{"side": "low", "value": -1.3, "samples": 900, "runs": 12, "records": ["a"]}]}
    line = re.search(r"<p id='output-rails'>(.*?)</p>", diagnosis_html({"summary": summary})).group(1)
    assert "low" in line and _nums(line)[-3:] == pytest.approx([-1.3, 900, 12])
