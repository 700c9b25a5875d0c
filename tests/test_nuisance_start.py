"""The diagnosis's nuisance starts (``ModelSim.gear_start``, ``ModelSim.rest_level``) against known
truth: a rig started with its gear somewhere in the play, or with G at rest at some level, that
the experiment's moves do not reveal before the scored samples."""
from __future__ import annotations

import numpy as np
import pytest

from hwid.blocks.linear import LinearBlock
from hwid.blocks.static import PolynomialH
from hwid.diagnose.modelsim import ModelSim
from hwid.model import HWModel, InputNonlinearity

DT = 0.05
F = InputNonlinearity("backlash", 1.0, 1.0, 0.4, -0.4)
G = LinearBlock((1.0,), (1.0, 1.0))
H = PolynomialH((0.0, 1.0, 0.0, -0.1))
SIGMA = 0.01


def _measured(u, v, w0_level=None, seed=0):
    rng = np.random.default_rng(seed)
    w = G.simulate(v, DT, w0_level)
    return H(w) + SIGMA * rng.standard_normal(u.size)


def test_gear_start_found_where_the_moves_leave_it_open():
    """Moves of 0.3 inside a play of 0.8 never reach a border: the gear stays where it started
    (0.25 above the lower border at u[0]), 0.15 from the model's default start."""
    n = 4000
    u = 0.15 * np.sin(2 * np.pi * np.arange(n) * DT / 20.0)
    truth = float(F.ascending(u[0])) + 0.25
    v = F.apply(u, truth)
    y = _measured(u, v)
    mask = np.arange(n) >= 400
    sim = ModelSim(HWModel(F, G, H), DT, [u]).measure([y], [mask], H, SIGMA)
    g0 = sim.gear_start(u, 0)
    assert g0 is not None and abs(g0 - truth) < 0.005
    r = (y - sim.from_input(u, i=0))[mask]
    assert np.sqrt(np.mean(r ** 2)) < 1.1 * SIGMA
    # once the input crosses the play before the scored samples, the start does not matter
    u2 = np.concatenate([np.linspace(-1.0, 1.0, 400), np.full(n - 400, 1.0)])
    assert ModelSim(HWModel(F, G, H), DT, [u2]).measure([y], [mask], H, SIGMA).gear_start(u2, 0) is None


def test_rest_level_found_where_g_still_remembers_it():
    """G (time constant 1 s) at rest at -0.6 before a call scored from 1 s on: the level shows for
    about 5 time constants and is recovered; scored from 30 s on it no longer matters."""
    n = 600
    u = np.full(n, 0.8)
    v = F.apply(u)
    y = _measured(u, v, w0_level=-0.6)
    other = np.linspace(-1.0, 1.0, 100)         # another experiment: the working range
    sim = ModelSim(HWModel(F, G, H), DT, [u, other])
    mask = np.arange(n) >= 20
    sim.measure([y, H(other)], [mask, np.zeros(100, bool)], H, SIGMA)
    w = sim.rest_level(v, 0, G, sim.w[0])
    assert w is not None
    r = (y - H(w))[mask]
    assert np.sqrt(np.mean(r ** 2)) < 1.1 * SIGMA
    assert abs(w[0] - G.dc_gain * -0.6) < 0.01
    late = np.arange(n) >= 600 - 1
    sim.measure([y, H(other)], [late, np.zeros(100, bool)], H, SIGMA)
    assert sim.rest_level(v, 0, G, sim.w[0]) is None


def test_a_slow_mode_rings_past_the_lead_in_from_any_start_and_its_free_response_is_found():
    """G with a lightly damped mode (0.4 rad/s, zeta 0.08: its envelope decays in 31 s), started
    mid-swing with its gear held at another place for the first seconds, scored from 30 s on: the
    mode still carries the start there. Its free response from the first scored sample (two
    amplitudes) takes the residual to the noise; G's rest level alone does not."""
    wn, z = 0.4, 0.08
    Gm = LinearBlock((wn * wn,), tuple(np.convolve([1.0, 1.0], [1.0, 2 * z * wn, wn * wn])))
    mode = np.roots([1.0, 2 * z * wn, wn * wn])
    n = 3000
    t = np.arange(n) * DT
    u = np.where(t < 5.0, 1.2, -1.0) + 0.4 * (t > 80.0) * np.sin(0.3 * t)
    v = F.apply(u)
    v_rig = v.copy()
    v_rig[t < 5.0] += 0.7                              # the gear elsewhere in the play at first
    rng = np.random.default_rng(8)
    w_rig = Gm.simulate(v_rig, DT, -0.3)               # G at rest at another level
    y = H(w_rig) + SIGMA * rng.standard_normal(n)
    mask = t >= 30.0
    sim = ModelSim(HWModel(F, Gm, H), DT, [u]).measure([y], [mask], H, SIGMA)
    rms = lambda x: float(np.sqrt(np.mean((y - x)[mask] ** 2)))
    assert rms(sim.from_v(v, Gm, 0)) > 5 * SIGMA                  # rest level only
    assert rms(sim.from_v(v, Gm, 0, ringing=mode)) < 1.1 * SIGMA
    assert rms(sim.from_v(v, Gm, 0, ringing=np.roots([1.0, 8.0, 25.0]))) > 5 * SIGMA   # a fast mode: nothing rings


def test_g_may_rest_a_play_beyond_the_experiments_reach():
    """A rig parked at the top of the range on the border its moves never reach there: G's rest
    levels span F's outputs from both borders at the ends of the input's range."""
    u = np.linspace(-1.0, 1.0, 200)
    sim = ModelSim(HWModel(F, G, H), DT, [u])
    lo, hi = sim.v_span
    assert lo == pytest.approx(float(F.ascending(-1.0))) and hi == pytest.approx(float(F.descending(1.0)))
    assert hi - float(np.max(sim.v[0])) == pytest.approx(0.8)
