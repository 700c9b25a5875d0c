"""``hwid identify-nonlinear``: the command round trip and its errors (exit 0 / exit 2, one line)."""
from __future__ import annotations

import json
import subprocess
import sys
from pathlib import Path

import numpy as np
import pytest

import plants
from hwid import config
from hwid.model import from_config

ROOT = Path(__file__).resolve().parents[1]

CFG = plants.config_text(plants.PAPER_FAST_G, name="cli", seed=8,
                         **{"identification": {"nonlinear": {"max_degree": 5}}})
NARROW = {"protocols.staircase.levels_up": [-0.3, 0.0, 0.3], "protocols.staircase.levels_down": [0.2, -0.1, -0.4]}

KEYS = {"type", "slope_up", "slope_down", "d_plus", "d_minus", "h_coefficients", "degree", "levels", "X_hat",
        "X_hat_se", "flat_up", "flat_down", "slope_down_ci", "d_plus_ci", "d_minus_ci", "h_coefficients_ci",
        "X_hat_ci", "evidence", "warnings", "method", "w_range"}


def hwid(*args, cwd=None):
    return subprocess.run([sys.executable, "-m", "hwid", *map(str, args)], capture_output=True, text=True,
                          cwd=cwd, timeout=300)


def test_cli_round_trip(tmp_path):
    cfg_path = tmp_path / "cli.yaml"
    cfg_path.write_text(CFG)
    r = hwid("identify-nonlinear", cfg_path, "--out", tmp_path / "out", "--json", tmp_path / "nl.json")
    assert r.returncode == 0, r.stderr
    assert "input nonlinearity: backlash" in r.stdout and "j_a = 4, j_d = 5" in r.stdout
    assert (tmp_path / "out" / "nonlinear.h5").exists()
    d = json.loads((tmp_path / "nl.json").read_text())
    assert KEYS <= set(d)
    assert d["type"] == "backlash" and d["degree"] == 5 and d["slope_up"] == 1.0
    assert len(d["levels"]) == len(d["X_hat"]) == len(d["X_hat_se"]) == len(d["X_hat_ci"]) == 21
    assert len(d["h_coefficients"]) == len(d["h_coefficients_ci"]) == 6
    truth = from_config(config.loads(CFG).plant).normalised().input
    for k in ("d_plus", "slope_down", "d_minus"):
        lo, hi = d[f"{k}_ci"]
        assert lo < d[k] < hi
        assert abs(d[k] - getattr(truth, k)) < 2 * (hi - lo)
    # --data: the staircases of a simulation.h5 give the same numbers as running them (same seed)
    from hwid.simulate import simulate
    simulate(config.load(cfg_path), tmp_path / "sim")
    r2 = hwid("identify-nonlinear", cfg_path, "--data", tmp_path / "sim" / "simulation.h5",
              "--out", tmp_path / "out2", "--json", tmp_path / "nl2.json")
    assert r2.returncode == 0, r2.stderr
    d2 = json.loads((tmp_path / "nl2.json").read_text())
    assert d2["d_plus"] == d["d_plus"] and d2["X_hat"] == d["X_hat"]


@pytest.mark.parametrize("case", ["missing_data", "not_hdf5", "narrow"])
def test_cli_bad_input_exits_2_with_one_line(tmp_path, case, capsys):
    cfg_path = tmp_path / "cli.yaml"
    text = CFG
    args = []
    if case == "missing_data":
        args = ["--data", tmp_path / "nope.h5"]
        expect = "no such file"
    elif case == "not_hdf5":
        (tmp_path / "bad.h5").write_text("not hdf5")
        args = ["--data", tmp_path / "bad.h5"]
        expect = "HDF5"
    else:
        text = plants.config_text(plants.PAPER_FAST_G, name="cli", seed=8,
                                  **{"identification": {"nonlinear": {"max_degree": 5}}}, **NARROW)
        expect = "too narrow"
    cfg_path.write_text(text)
    from hwid.cli import main
    with pytest.raises(SystemExit) as exc:
        main(["identify-nonlinear", str(cfg_path), *map(str, args), "--out", str(tmp_path / "out")])
    assert exc.value.code == 2
    err = capsys.readouterr().err
    lines = [ln for ln in err.splitlines() if ln.strip()]
    assert len(lines) == 1 and lines[0].startswith("hwid: error:") and expect in lines[0], err
    assert "Traceback" not in err
