"""Stage 2 from a recorded plant's plain sines (hwid/identify/periodic.py): no pre-compensator, the
input's offset and the backlash's distortion read from F_hat[u]; G(j omega) checked against the
rig's true G."""
from __future__ import annotations

import numpy as np
import pytest
from scipy import stats

import logs
from hwid import config
from hwid.cli import main
from hwid.identify.history import identify_recorded
from hwid.identify.periodic import identify_periodic
from hwid.recorded import load_records
from hwid.results import read_linear

OMEGAS = (0.7, 1.4, 2.8)


def G(w):
    num, den = logs.G["num"], logs.G["den"]
    s = 1j * np.asarray(w, float)
    return np.polyval(num, s) / np.polyval(den, s)


@pytest.fixture(scope="module")
def log(tmp_path_factory):
    """Levels (a staircase and steps) for stage 1, then one plain sine per record, offset 0.3."""
    tmp = tmp_path_factory.mktemp("periodic")
    parts = logs.lab_parts()
    sines = []
    for w in OMEGAS:
        t = np.arange(int(6 * 2 * np.pi / w / logs.DT)) * logs.DT
        sines.append(0.3 + np.sin(w * t))
    return logs.write_lab(tmp, "sines", parts=[parts[0], parts[2]] + sines, seed=2), tmp


def test_plain_sines_give_g_at_their_frequencies(log):
    path, _ = log
    cfg = config.load(path)
    records = load_records(cfg)
    res, pieces = identify_periodic(cfg, records, identify_recorded(cfg, records))
    np.testing.assert_allclose(res.frequencies, OMEGAS, rtol=2e-3)
    truth = G(res.frequencies)
    # every gain and phase against the truth in units of its own standard error (the 95 % half
    # width / 1.96): jointly a chi-square with 6 degrees of freedom
    z_gain = (res.gain - np.abs(truth)) / (np.diff(res.gain_ci, axis=1)[:, 0] / (2 * 1.96))
    z_phase = (res.phase - (-np.angle(truth))) / (np.diff(res.phase_ci, axis=1)[:, 0] / (2 * 1.96))
    assert float(np.sum(z_gain ** 2 + z_phase ** 2)) < stats.chi2.ppf(0.999, 6)
    # and the intervals say something (six periods a frequency at a noise of 2 % of the output's
    # span: 4-21 % of the gain wide)
    assert np.all(np.diff(res.gain_ci, axis=1)[:, 0] < 0.3 * res.gain)
    assert all(p.attrs["precompensator"] == "none (recorded)" for p in pieces)


def test_cli_stage2_from_the_history(log, capsys):
    path, tmp = log
    out = tmp / "out"
    with pytest.raises(SystemExit) as exc:
        main(["identify-nonlinear", str(path), "--out", str(out)])
    assert exc.value.code in (0, None)
    with pytest.raises(SystemExit) as exc:
        main(["identify-linear", str(path), "--nonlinear", str(out / "history.h5"), "--out", str(out)])
    assert exc.value.code in (0, None)
    res = read_linear(out / "linear.h5")
    assert len(res.frequencies) == len(OMEGAS)
