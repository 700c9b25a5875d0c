"""``hwid compare``'s figures: written for a simulated comparison, and the residual tests' bands
and correlations against sequences whose correlation is known."""
import json
import subprocess
import sys

import numpy as np
import pytest

import rigs
from hwid import config
from hwid.model import from_config
from hwid.adequacy import lag_step, settling_time
from hwid.report.compare_figures import Z99, plot_experiment, plot_residual_tests, residual_correlation

PNG = b"\x89PNG\r\n\x1a\n"


def test_compare_writes_its_figures_and_lists_them(tmp_path):
    """A simulated comparison: one PNG per experiment and one of the residual tests in
    OUT/figures/, listed under ``figures`` in compare.json; the report shows those files."""
    path = rigs.write(tmp_path / "small.yaml", rigs.small())
    out = tmp_path / "out"
    p = subprocess.run([sys.executable, "-m", "hwid", "compare", str(path), str(path), "--out", str(out)],
                       capture_output=True, text=True, timeout=300)
    assert p.returncode == 0, p.stderr
    d = json.loads((out / "compare.json").read_text())
    names = [e["name"] for e in d["experiments"]]
    assert d["figures"] == [f"figures/compare_{n}.png" for n in names] + ["figures/compare_residual_tests.png"]
    for rel in d["figures"]:
        assert (out / rel).read_bytes()[:8] == PNG
    _same_p_values_everywhere(path, d)
    assert not list((out / "figures").glob("*.tmp"))
    from hwid.report.html import write_report
    page = write_report(out).read_text()
    for rel in d["figures"]:
        stem = rel.split("/")[-1][:-4]
        assert f"fig-{stem}" in page and (out / "report" / f"{stem}.png").read_bytes() == (out / rel).read_bytes()
    # a comparison without its figures (moved away): the report draws the same ones from compare.h5
    (out / "figures").rename(tmp_path / "moved")
    page = write_report(out).read_text()
    names_shown = [f["name"] for f in json.loads((out / "report" / "figures.json").read_text())]
    assert names_shown == [rel.split("/")[-1][:-4] for rel in d["figures"]]
    assert all((out / "report" / f"{n}.svg").is_file() for n in names_shown)


def _same_p_values_everywhere(path, d):
    """The residual tests' p-values are one set of numbers: compare.json's, the figure's (drawn from
    the same residuals at the same decimation) and the adequacy verdict's."""
    from hwid.compare import compare_records, experiments_of
    cfg = config.load(path)
    model = from_config(cfg.plant)
    records, floor = experiments_of(cfg, path.parent / "again")
    result, sims = compare_records(model, records, floor)
    assert result.lag_step == d["residual"]["lag_step"] == lag_step(records[0].dt, settling_time(model))
    corr = residual_correlation([r.y - sims[r.name] for r in records], [r.u for r in records],
                                step=result.lag_step)
    assert corr.whiteness_p == pytest.approx(result.whiteness_p, rel=1e-12)
    assert corr.input_correlation_p == pytest.approx(result.input_correlation_p, rel=1e-12)
    assert result.adequacy.whiteness_p == pytest.approx(result.whiteness_p, rel=1e-12)
    assert d["residual"]["whiteness_p"] == pytest.approx(result.whiteness_p, rel=1e-9)   # the CLI's run, same seed


def _coloured(rng, n):
    return np.convolve(rng.standard_normal(n + 9), np.ones(10) / 10, mode="valid")


def test_white_residual_stays_inside_the_band_at_the_stated_rate():
    """Autocorrelations of white sequences (400 x 25 lags) fall outside the 99 % band about 1 % of the
    time: the count is binomial(10000, 0.01), mean 100, sd 10; the check allows 4 sd either way.
    The cross-correlation with an independent, coloured input the same."""
    rng = np.random.default_rng(11)
    outside_auto = outside_cross = 0
    trials, n = 400, 2000
    for _ in range(trials):
        e = rng.standard_normal(n)
        corr = residual_correlation([e], [_coloured(rng, n)])
        assert corr.auto_band == pytest.approx(Z99 / np.sqrt(n))
        outside_auto += int(np.sum(np.abs(corr.auto) > corr.auto_band))
        outside_cross += int(np.sum(np.abs(corr.cross[corr.cross_lags >= 0][:25]) > corr.cross_band))
    expected, sd = 0.01 * trials * 25, np.sqrt(0.01 * 0.99 * trials * 25)
    assert abs(outside_auto - expected) < 4 * sd, outside_auto
    assert abs(outside_cross - expected) < 4 * sd, outside_cross


def test_cross_band_holds_when_residual_and_input_are_both_coloured():
    """A coloured residual independent of a coloured input: r_eu then has variance P/N, not 1/N
    (Ljung's P = sum_k r_e(k) r_u(k), about 6.7 for two 10-sample moving averages), and the band
    built from P holds 99 % of the values. Lags 0 and 20 only (further apart than the two smooths'
    memory, so nearly independent): 2000 x 2 values, binomial mean 40, sd 6.3; 4 sd allowed. The
    band 2.58/sqrt(N) alone would leave about a third of them outside."""
    rng = np.random.default_rng(12)
    trials, n = 2000, 500
    outside = naive = 0
    for _ in range(trials):
        corr = residual_correlation([_coloured(rng, n)], [_coloured(rng, n)])
        values = corr.cross[np.isin(corr.cross_lags, (0, 20))]
        outside += int(np.sum(np.abs(values) > corr.cross_band))
        naive += int(np.sum(np.abs(values) > corr.auto_band))
    expected, sd = 0.01 * trials * 2, np.sqrt(0.01 * 0.99 * trials * 2)
    assert abs(outside - expected) < 4 * sd, outside
    assert naive > 10 * expected


@pytest.mark.parametrize("step", [1, 3])
def test_ar1_residual_gives_its_lag_one_autocorrelation(step):
    """e(t) = a e(t-1) + w(t), a = 0.6: the lag-1 autocorrelation is a (a^step after decimation by
    ``step``), within 3.3 of its sampling standard deviations sqrt((1 - r^2)/N) (Bartlett, AR(1) at
    lag 1), and far outside the white band."""
    a, n = 0.6, 30000
    rng = np.random.default_rng(5)
    w = rng.standard_normal(n)
    e = np.empty(n)
    e[0] = w[0] / np.sqrt(1 - a * a)
    for k in range(1, n):
        e[k] = a * e[k - 1] + w[k]
    corr = residual_correlation([e], [rng.standard_normal(n)], step=step)
    r1 = a ** step
    n_used = corr.samples
    assert n_used == len(range(0, n, step))
    assert abs(corr.auto[0] - r1) < 3.3 * np.sqrt((1 - r1 * r1) / n_used), corr.auto[0]
    assert corr.auto[0] > 5 * corr.auto_band and corr.whiteness_p < 1e-6


def test_pooled_band_and_decimation_step(tmp_path):
    """Two experiments pool to N = n1 + n2 in the band; the step makes 25 lags span G's settling
    (4 time constants of its slowest pole): the paper's G (poles -0.5, -0.2) at dt = 0.01 -> 80."""
    rng = np.random.default_rng(2)
    corr = residual_correlation([rng.standard_normal(3000), rng.standard_normal(1000)],
                                [rng.standard_normal(3000), rng.standard_normal(1000)])
    assert corr.samples == 4000 and corr.auto_band == pytest.approx(Z99 / np.sqrt(4000))
    paper = from_config(config.load(rigs.write(tmp_path / "p.yaml", rigs.small(**{
        "plant.linear.num": [0.2], "plant.linear.den": [1.0, 0.7, 0.1]}))).plant)
    assert settling_time(paper) == pytest.approx(20.0)
    assert lag_step(0.01, settling_time(paper)) == 80
    assert lag_step(0.05, 2.0) == 1                      # the small rig: 25 samples already span it


def test_figures_draw_what_they_are_given():
    t = np.arange(500) * 0.02
    y = np.sin(t)
    fig = plot_experiment("run", t, y, 0.9 * y, fit_percent=90.0, noise_floor=0.05)
    top, bottom = fig.axes
    assert bottom.get_xlabel() == "t [s]" and "fit 90.0 %" in top.get_title()
    residual = next(line for line in bottom.get_lines() if line.get_gid() == "residual")
    np.testing.assert_allclose(residual.get_ydata(), 0.1 * y)
    rng = np.random.default_rng(0)
    corr = residual_correlation([rng.standard_normal(4000)], [rng.standard_normal(4000)], step=4, dt=0.01)
    fig = plot_residual_tests(corr)
    assert "x 4 samples = 0.04 s" in fig.axes[0].get_xlabel() and "decimated" in fig.axes[0].get_xlabel()
