"""Each record's unknown start (hwid/diagnose/starts.py): estimated through the model and written
as a virtual pre-input, checked against the start the record was simulated from; and the
recorded diagnosis that falls back to it where burning the starts in would leave nothing."""
from __future__ import annotations

import numpy as np
import pytest

import logs
from hwid import config
from hwid.blocks.linear import LinearBlock
from hwid.blocks.static import PolynomialH
from hwid.diagnose import diagnose, starts
from hwid.model import HWModel, InputNonlinearity

F, G = logs.F, logs.G
MODEL = HWModel(InputNonlinearity(F["type"], F["slope_up"], F["slope_down"], F["d_plus"], F["d_minus"]),
                LinearBlock(tuple(G["num"]), tuple(G["den"]), 0.0), PolynomialH(tuple(logs.H)))


def _quiet(*_):
    pass


def _record(gear, level, seed):
    """A record that holds 2 s at its first level (the gear's start shows), then moves: simulated
    from the gear at ``gear`` (clipped into the play) and G at rest at ``level``."""
    dt = logs.DT
    t = np.arange(int(6 / dt)) * dt
    u = np.where(t < 2.0, 0.3, 0.3 + 0.9 * np.sin(1.4 * (t - 2.0)))
    g = float(np.clip(gear, MODEL.input.ascending(u[0]), MODEL.input.descending(u[0])))
    y = MODEL.output(MODEL.linear.simulate(MODEL.input.apply(u, g), dt, level))
    return u, y + logs.SIGMA * np.random.default_rng(seed).standard_normal(u.size), g


@pytest.mark.parametrize("gear, level", [(0.0, 0.9), (0.3, -0.8), (-0.1, 0.1)])
def test_the_start_is_found_where_the_record_shows_it(gear, level):
    """The level (-0.8 lies below anything this record drives F to) and the gear's place come back;
    the record's opening is then fitted to the noise."""
    u, y, g = _record(gear, level, seed=int(10 * (gear + 1) + 100 * (level + 1)))
    clean = MODEL.output(MODEL.linear.simulate(MODEL.input.apply(u, g), logs.DT, level))
    quiet = starts.estimate(MODEL, u, clean, logs.DT)
    # noise-free: G sees the gear's place one sample (20 ms of a 3-s response) before the record,
    # so the pre-input's start is not exactly the simulated one (G at rest at the level while the
    # gear is elsewhere): the opening is reproduced to a quarter of the noise (3 % of it in
    # quadrature), the level to a few per cent of (level - gear)
    assert quiet["rms_after"] <= 0.25 * logs.SIGMA
    assert abs(quiet["level"] - level) <= 0.03 * abs(level - g) + 1e-3
    assert quiet["gear"] == pytest.approx(g, abs=0.01)
    # with noise: 300 held samples of s.d. 0.02 set the level to ~0.002 and the gear to ~0.001
    st = starts.estimate(MODEL, u, y, logs.DT)
    assert st["level"] == pytest.approx(quiet["level"], abs=0.01)
    assert st["gear"] == pytest.approx(quiet["gear"], abs=0.01)
    assert st["rms_after"] <= 1.1 * logs.SIGMA < st["rms_before"]
    # the pre-input reproduces the estimated start: the chain run through it gives the fit reported
    x = MODEL.output(MODEL.linear.simulate(MODEL.input.apply(np.r_[st["pre"], u]), logs.DT))[starts.PRE:]
    assert np.sqrt(np.mean((y - x) ** 2)) == pytest.approx(st["rms_after"], rel=1e-9)


def _short_parts():
    """Records too short to burn their starts in (each ends before G has settled 1.5 times after
    the input first spans the play): sines and steps of 4 s each."""
    dt = logs.DT
    t = np.arange(int(4 / dt)) * dt
    parts = []
    for k, w in enumerate((1.6, 2.2, 1.9, 2.6)):
        parts.append(0.2 * k - 0.3 + 1.3 * np.sin(w * t + 0.5 * k))
        parts.append(np.repeat([0.9, -0.9, 0.5, -0.5][k % 4] * np.array([1, -1, 1, -1]), t.size // 4))
    return parts


@pytest.mark.parametrize("rate", [None, 1.5])
def test_short_records_are_diagnosed_from_estimated_starts(tmp_path, rate):
    """Burning in the starts would leave no part to score (the diagnosis exited 2); with the starts
    estimated, a plain log is no false alarm and a rate-limited one is named, its rate found."""
    cfg = config.load(logs.write_lab(tmp_path, "short", rate=rate, seed=8, parts=_short_parts()))
    s = diagnose(cfg, tmp_path / "out", model=logs.write_model(tmp_path), echo=_quiet)
    assert set(s["data"]["starts"]) == {f"short_part{k}" for k in range(1, 9)}
    if rate is None:
        assert s["verdict"]["effect"] == "none"
        assert s["gap_before"] <= 1.15 * s["noise_floor"]
    else:
        # the starts are estimated through the model without the rate limit and are not re-estimated
        # with it: part of the slow actuator's footprint on the openings stays (gap after 1.8x the
        # floor here, 0.3x the gap before); the effect is named and its rate found all the same
        assert s["verdict"]["effect"] == "rate_limit"
        assert s["gap_after"] <= 0.25 * s["gap_before"]
        found = next(c for c in s["candidates"] if c["effect"] == "rate_limit")["params"]["rate"]
        assert found == pytest.approx(rate, rel=0.1)
