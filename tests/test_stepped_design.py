"""What stepped inputs determine in the whole fit (issue 45, item 3): ``exclude`` windows that leave
every piece opening at a level and stepping to u = 0 see F at one point; stage 1 says so in one
line, and the whole model that `hwid run` falls back to reports F and h_bar's scale undetermined,
never as numbers with intervals."""
import json

import h5py
import numpy as np
import pytest
import yaml

from hwid.blocks.linear import LinearBlock
from hwid.blocks.static import PolynomialH
from hwid.cli import main
from hwid.identify.determinable import stepped_design, whole_undetermined
from hwid.model import HWModel, InputNonlinearity

DT = 0.05
TRUTH = HWModel(InputNonlinearity("backlash", 1.0, 1.0, 0.3, -0.3), LinearBlock((1.0,), (0.5, 1.0)),
                PolynomialH((0.0, 1.0)))


class _Rec:
    def __init__(self, name, u):
        self.name, self.u = name, np.asarray(u, float)


def _log(tmp_path, levels, exclude=()):
    n = int(4 / DT)
    u = np.repeat(levels, n)
    t = np.arange(u.size) * DT
    y = TRUTH.simulate(u, DT).x + 0.01 * np.random.default_rng(1).standard_normal(u.size)
    np.savetxt(tmp_path / "log.csv", np.c_[t, u, y], delimiter=",", header="time,command,position", comments="",
               fmt="%.6f")
    exp = {"file": "log.csv", "time": {"column": "time"}, "input": {"column": "command"},
           "output": {"column": "position"}}
    if exclude:
        exp["exclude"] = [list(w) for w in exclude]
    path = tmp_path / "excl.yaml"
    path.write_text(yaml.safe_dump({"name": "excl", "sampling": {"dt": DT},
                                    "plant": {"kind": "recorded", "experiments": [exp]}}, sort_keys=False))
    return path, 2 * n * DT


def test_the_count_of_stepped_inputs():
    des = stepped_design([_Rec("a", np.repeat([0.0, 1.0, 0.0, -1.0, 0.5], 30))])
    assert des.up == (0.5, 1.0) and des.down == (-1.0, 0.0)
    assert whole_undetermined([_Rec("a", np.repeat([0.0, 1.0, 0.0, -1.0, 0.5], 30))], 2) == {}
    # pieces that each open at a level and step to 0: nothing from below, one point from above
    pieces = [_Rec(f"p{k}", np.repeat([a, 0.0], 30)) for k, a in enumerate([1.0, 0.5, 1.2])]
    why = whole_undetermined(pieces, 2)
    assert set(why) == {"d_plus", "c1", "c2", "slope_down", "d_minus"}
    # a sine sweeps the borders: the count does not apply
    assert stepped_design([_Rec("s", np.sin(np.linspace(0, 20, 400)))]) is None


def test_exclude_windows_that_leave_one_point_say_so(tmp_path, capsys):
    levels = [1.0, 0.0, 0.5, 0.0, 1.2, 0.0, 0.8, 0.0, 1.4, 0.0, 0.6, 0.0]
    cfg, period = _log(tmp_path, levels)
    # cut from the end of each hold at 0 into the next level: every piece opens at a level, steps to 0
    windows = [(k * period - 1.0, k * period + 1.0) for k in range(1, len(levels) // 2)]
    cfg, _ = _log(tmp_path, levels, windows)
    with pytest.raises(SystemExit) as exc:
        main(["run", str(cfg), "--out", str(tmp_path / "out")])
    out = capsys.readouterr().out
    assert exc.value.code == 0
    assert "cannot determine d_plus, h_bar, slope_down, d_minus from these levels" in out
    line = out.split("whole model (")[1].split("\n")[0]
    assert "d+ = undetermined" in line and "S^d = undetermined" in line and "d- = undetermined" in line
    with h5py.File(tmp_path / "out" / "whole.h5") as f:
        res = json.loads(f.attrs["result"])
    assert {"d_plus", "slope_down", "d_minus", "c1"} <= set(res["undetermined"])
    assert res["d_plus_ci"] is None and res["slope_down_ci"] is None and res["d_minus_ci"] is None
    assert res["h_coefficients_ci"][1] is None
