"""The simulator and `hwid simulate` against the paper's Section 6 system."""
import h5py
import numpy as np
import pytest

from hwid import config, protocols
from hwid.cli import main
from hwid.model import from_config
from hwid.plant import make_plant

TABLE1_X = {0.2: -0.075, 0.4: -0.047, 0.6: 0.047, 0.8: 0.075, 1.0: 0.03, 1.2: 0.27}
TABLE1_X_DOWN = {0.0: 0.03, -0.3: 0.075, -0.6: -0.047, -1.0: -0.03, -1.2: -0.27, -1.4: -1.78}


def noiseless(cfg):
    return config.with_overrides(cfg, {"plant.noise.std": 0.0})


def test_paper_steady_states_match_model_and_table1(paper_cfg):
    cfg = noiseless(paper_cfg)
    plant = make_plant(cfg)
    m = from_config(cfg.plant)
    g0 = m.linear.dc_gain
    for st, table in zip(protocols.staircases(cfg), (TABLE1_X, TABLE1_X_DOWN)):
        r = plant.run(st.name, st.u)
        x_end = r.y[st.stops - 1]
        # truth from the config alone: h(G(0) F[U_j]) along the whole level sequence
        V = m.input.steady(st.all_levels, state=0.0)[st.lead_in.size:]
        np.testing.assert_allclose(x_end, m.output(g0 * V), rtol=0, atol=1e-9)
        for U, X in table.items():
            j = int(np.argmin(np.abs(st.levels - U)))
            assert st.levels[j] == pytest.approx(U)
            digits = len(str(X).split(".")[1])
            assert round(float(x_end[j]), digits) == pytest.approx(X, abs=10 ** -digits / 2 + 1e-12)


def test_paper_flat_paths(paper_cfg):
    cfg = noiseless(paper_cfg)
    plant = make_plant(cfg)
    up, down = protocols.staircases(cfg)
    xu = plant.run(up.name, up.u).y[up.stops - 1]
    xd = plant.run(down.name, down.u).y[down.stops - 1]
    assert np.ptp(xu[:4]) < 1e-12 and abs(xu[4] - xu[0]) > 0.01        # j_a = 4
    assert np.ptp(xd[:5]) < 1e-12 and abs(xd[4] - xd[5]) > 0.01        # j_d = 5, flat at X_N
    assert xd[0] == pytest.approx(xu[-1], abs=1e-12)


def test_noise_reproducible_and_order_independent(paper_cfg):
    up, down = protocols.staircases(paper_cfg)
    a = make_plant(paper_cfg)
    ya = a.run(up.name, up.u).y
    b = make_plant(paper_cfg)
    b.run(down.name, down.u)
    yb = b.run(up.name, up.u).y
    c = make_plant(paper_cfg, seed=np.random.SeedSequence(2))
    yc = c.run(up.name, up.u).y
    x = a.run(up.name, up.u).x
    np.testing.assert_array_equal(ya, yb)
    assert not np.allclose(ya, yc)
    assert np.std(ya - x) == pytest.approx(0.01, rel=0.02)


def test_ar1_noise_statistics():
    from hwid.plant import noise
    e = noise(np.random.default_rng(np.random.SeedSequence(5)), 400_000, 0.02, 0.9)
    assert np.std(e) == pytest.approx(0.02, rel=0.03)
    assert np.corrcoef(e[:-1], e[1:])[0, 1] == pytest.approx(0.9, abs=0.01)


def test_cli_simulate_layout(tmp_path):
    cfg_text = (__import__("pathlib").Path(__file__).parents[1] / "configs" / "paper.yaml").read_text()
    cfg_text = cfg_text.replace("periods: 50", "periods: 2").replace("hold: 150.0", "hold: 20.0")
    cfg_text = cfg_text.replace("[0.01, 0.02, 0.05, 0.1, 0.2]", "[0.1, 0.2]")
    p = tmp_path / "c.yaml"
    p.write_text(cfg_text)
    with pytest.raises(SystemExit) as e:
        main(["simulate", str(p), "--out", str(tmp_path / "o")])
    assert e.value.code == 0
    with h5py.File(tmp_path / "o" / "simulation.h5") as f:
        assert f.attrs["hwid_kind"] == "simulation"
        assert len(f.attrs["config_sha256"]) == 64 and f.attrs["seed"] == 1 and f.attrs["dt"] == 0.01
        assert set(f["experiments"]) == {"staircase_up", "staircase_down", "sine_0", "sine_1"}
        g = f["experiments/sine_1"]
        assert g["x"].attrs["ground_truth"] and g.attrs["precompensator"] == "true"
        # the true pre-compensator makes v = S^a z exactly (Lemma 1)
        np.testing.assert_allclose(g["v"][()], g["z"][()], atol=1e-12)
        np.testing.assert_allclose(f["truth/normalised/output_nonlinearity/polynomial"][()],
                                   [0, 0.5, 0, -3.36, 0, 6.4], atol=1e-12)   # eq. (30c)
    assert not (tmp_path / "o" / "simulation.h5.tmp").exists()


@pytest.mark.parametrize("kind", ["backlash", "backlash_inverse"])
@pytest.mark.parametrize("ar", [0.0, 0.8])
@pytest.mark.parametrize("delay", [0.0, 0.013], ids=["fused chain", "three passes"])
def test_noisy_output_is_the_chain_plus_noise_bit_for_bit(kind, ar, delay):
    """y of a seeded plant is the y of the chain, then ``noise()``, then the sum, bit for bit, with the
    white noise drawn in the chain's own pass: seeded results do not change with the kernel."""
    from hwid.blocks.linear import LinearBlock
    from hwid.blocks.static import PolynomialH
    from hwid.model import HWModel, InputNonlinearity
    from hwid.plant import SimulatedPlant, experiment_rng, noise
    model = HWModel(InputNonlinearity(kind, 1.2, 0.8, 0.4, -0.3), LinearBlock((0.2,), (1.0, 0.7, 0.1), delay),
                    PolynomialH((0.05, 0.25, 0.1, -0.42, 0, 0.2)))
    steps = np.repeat(np.random.default_rng(1).normal(size=400), 25)          # held levels and reversals
    u = np.concatenate([steps, 1.3 * np.sin(np.arange(5003) * 0.01)])
    plant = SimulatedPlant(model, 0.01, 0.02, ar, seed=np.random.SeedSequence(11), initial_state=0.1)
    for name in ("first", "second", "first"):
        gear = plant.state
        rec = plant.run(name, u)
        y = noise(experiment_rng(plant.seed_seq, name), u.size, 0.02, ar)
        y += model.simulate(u, 0.01, gear).x
        assert rec.y.tobytes() == y.tobytes()
