"""Undetermined is a result (issue 45, item 3): no interval anywhere has zero width.

A parameter fixed by the normalisation (``slope_up``, h_bar's constant: eqs. 4a-c) or left
undetermined by the data has the interval None and a reason, never ``[a, a]``. The structural tests
walk every results file of a ``hwid run`` -- every JSON file, every HDF5 attribute (JSON payloads
parsed) and dataset -- and every interval they hold; the others check the staircase path's
undetermined parameters against the truth and the HDF5 round trip of "no interval".
"""
import json
from pathlib import Path

import h5py
import numpy as np
import pytest
import yaml

import logs
import rigs
from hwid import config
from hwid.cli import main
from hwid.identify.result import FIXED, NonlinearResult
from hwid.model import from_config

ROOT = Path(__file__).resolve().parents[1]
# the paper's Section 6 plant on a short design: dt 0.05 s, 40 s per level, 4 averaged periods
PAPER_SHORT = ((ROOT / "configs" / "paper.yaml").read_text()
               .replace("dt: 0.01", "dt: 0.05").replace("hold: 150.0", "hold: 40.0")
               .replace("periods: 50, lead_in_periods: 3", "periods: 4, lead_in_periods: 2")
               .replace("[0.01, 0.02, 0.05, 0.1, 0.2]", "[0.1, 0.2, 0.5]"))
INTERVAL_KEYS = ("ci", "interval", "intervals")


# ------------------------------------------------------------------------------------ the walker

def _is_interval_key(key: str) -> bool:
    return key.endswith("_ci") or key in INTERVAL_KEYS


def _pairs(value, where: str):
    """Every ``(where, [lo, hi])`` in an interval value: a pair, a list of pairs (h_bar's
    coefficients, the levels), an array of shape (n, 2), or a mapping name -> any of these. None
    (no interval) yields nothing; anything else is a walker that misreads the file: it fails."""
    if value is None:
        return
    if isinstance(value, dict):
        for k, v in value.items():
            if k in ("undetermined", "fixed"):      # reasons, not intervals
                assert all(isinstance(r, str) and r for r in v.values()), f"{where}.{k}: a reason is empty"
                continue
            yield from _pairs(v, f"{where}.{k}")
        return
    arr = np.asarray(value, dtype=object)
    if arr.ndim == 1 and arr.size % 2 == 0 and arr.size and not any(isinstance(x, (list, tuple)) for x in arr):
        # a row of intervals side by side (a pole's ``[Re lo, Re hi, Im lo, Im hi]``); None: no interval
        for k in range(0, arr.size, 2):
            lo, hi = arr[k], arr[k + 1]
            if lo is None and hi is None:
                continue
            assert isinstance(lo, (int, float, np.number)) and isinstance(hi, (int, float, np.number)), \
                f"{where}: {value!r} is not an interval"
            yield (where if arr.size == 2 else f"{where}[{k}:{k + 2}]"), [float(lo), float(hi)]
        return
    assert arr.ndim >= 1 and arr.size, f"{where}: {value!r} is not an interval, a list of them, or None"
    for i, v in enumerate(value):
        yield from _pairs(None if v is None else (v.tolist() if isinstance(v, np.ndarray) else v), f"{where}[{i}]")


def intervals(obj, where: str = ""):
    """Every interval under a key ending in ``_ci`` or named ``ci``/``interval``/``intervals``, at any
    depth of plain data (dicts, lists), with its path."""
    if isinstance(obj, dict):
        for k, v in obj.items():
            path = f"{where}.{k}"
            if _is_interval_key(str(k)):
                yield from _pairs(v, path)
            else:
                yield from intervals(v, path)
    elif isinstance(obj, (list, tuple)):
        for i, v in enumerate(obj):
            yield from intervals(v, f"{where}[{i}]")


def _plain(value):
    """An HDF5 attribute or dataset as plain data: JSON strings parsed, NaN pairs kept as NaN."""
    if isinstance(value, bytes):
        value = value.decode()
    if isinstance(value, str) and value[:1] in "[{":
        try:
            return json.loads(value)
        except ValueError:
            return value
    if isinstance(value, np.ndarray):
        return value.tolist()
    return value.item() if isinstance(value, np.generic) else value


def h5_tree(path: Path) -> dict:
    """Every attribute and every dataset of ``path`` (records' samples left out: no interval sits
    in ``u``, ``y``, ...), groups as nested dicts."""
    def read(group) -> dict:
        out = {k: _plain(v) for k, v in group.attrs.items()}
        for k, item in group.items():
            if isinstance(item, h5py.Group):
                out[k] = read(item)
            elif _is_interval_key(k) or item.size <= 4096:
                out[k] = _plain(item[()])
        return out
    with h5py.File(path, "r") as f:
        return read(f)


def run_documents(out: Path) -> dict:
    """Every JSON file and results file of a run directory as plain data."""
    docs = {p.name: json.loads(p.read_text()) for p in out.rglob("*.json")}
    docs.update({p.name: h5_tree(p) for p in out.rglob("*.h5")})
    return docs


def zero_width(docs: dict) -> list[str]:
    bad = []
    for name, doc in docs.items():
        for where, (lo, hi) in intervals(doc, name):
            if lo == hi or not (np.isfinite(lo) or np.isnan(lo) and np.isnan(hi)):
                bad.append(f"{where} = [{lo}, {hi}]")
    return bad


def test_the_walker_finds_a_zero_width_interval():
    """The walker is honest: it finds ``[0, 0]`` wherever the old results put it, and passes None."""
    old = {"h_coefficients_ci": [[0.0, 0.0], [0.1, 0.2]], "ci": {"d_plus": None, "h_coefficients": [None, [1, 2]]},
           "adequacy": {"floor": {"interval": [0.3, 0.3]}}, "gain_ci": [[1.0, 1.1], [2.0, 2.0]],
           "parametric": {"poles_ci": [[-0.6, -0.4, 0.0, 0.0], [-0.3, -0.1, None, None]]}}
    assert sorted(zero_width({"r": old})) == ["r.adequacy.floor.interval = [0.3, 0.3]", "r.gain_ci[1] = [2.0, 2.0]",
                                              "r.h_coefficients_ci[0] = [0.0, 0.0]",
                                              "r.parametric.poles_ci[0][2:4] = [0.0, 0.0]"]
    with pytest.raises(AssertionError):
        list(intervals({"d_plus_ci": "wide"}))


# ------------------------------------------------------------------------------ the structural tests

def _run(cfg_path: Path, out: Path) -> dict:
    with pytest.raises(SystemExit) as done:
        main(["run", str(cfg_path), "--out", str(out), "--no-report"])
    assert done.value.code in (0, None)
    return run_documents(out)


def test_no_zero_width_interval_in_a_simulated_run(tmp_path):
    """``hwid run`` on the paper's plant with a short design: nonlinear.h5, linear.h5 and
    identification.json hold intervals (stage 1's borders and coefficients, each level's X_hat,
    stage 2's gain and phase), none of zero width; h_bar's constant and slope_up have none (NaN on
    disk, None read back), with the reason."""
    cfg = tmp_path / "paper_short.yaml"
    cfg.write_text(PAPER_SHORT)
    docs = _run(cfg, tmp_path / "run")
    assert {"nonlinear.h5", "linear.h5", "identification.json"} <= set(docs)
    found = [w for name in docs for w, _ in intervals(docs[name], name)]
    assert any(".d_plus_ci" in w for w in found) and any(".gain_ci" in w for w in found)
    assert zero_width(docs) == []
    res = docs["nonlinear.h5"]["result"]
    assert np.all(np.isnan(res["h_coefficients_ci"][0])) and np.all(np.isnan(res["slope_up_ci"]))
    from hwid.results import read_nonlinear
    nl = read_nonlinear(tmp_path / "run")
    assert nl.ci["h_coefficients"][0] is None and nl.ci["slope_up"] is None
    assert all(ci is not None for ci in nl.ci["h_coefficients"][1:])
    assert nl.to_dict()["fixed"]["c0"] == FIXED["c0"] == "fixed by the normalisation h(0) = 0"


def test_no_zero_width_interval_in_a_recorded_run(tmp_path):
    """``hwid run`` on a recorded log of 16 levels (tests/logs.write_log_csv; the whole fit
    enabled): history.h5, whole.h5 and identification.json hold no zero-width interval, and
    h_bar's constant has none in either result, with the reason. The cubic h_bar has three real
    roots: where a fit's second root falls in the levels' range (history.h5 here, at its edge), h_bar
    and the borders have no interval either, the reason is the readings, and one reading holds
    the truth's d+ within its interval."""
    truth = from_config(config.loads(yaml.safe_dump(rigs.small(**{
        "plant.output_nonlinearity.polynomial": [0, 1.0, 0.8, -0.6],
        "plant.input_nonlinearity.slope_down": 1.3}))).plant)
    rng = np.random.default_rng(12)
    u = np.repeat(rng.uniform(-1.2, 1.2, 16), rng.integers(40, 80, 16))
    y = truth.simulate(u, 0.05, gear=0.0).x + 0.01 * rng.standard_normal(u.size)
    docs = _run(logs.write_log_csv(tmp_path, u, y, 0.05), tmp_path / "run")
    assert {"history.h5", "whole.h5", "identification.json"} <= set(docs)
    assert zero_width(docs) == []
    for name in ("history.h5", "whole.h5"):
        res = docs[name]["result"]
        ci = res["ci"]["h_coefficients"] if "ci" in res else res["h_coefficients_ci"]
        assert res["fixed"]["c0"] == "fixed by the normalisation h(0) = 0"
        if len(res.get("readings") or []) > 1:
            assert all(c is None for c in ci) and "h_bar vanishes at" in res["undetermined"]["h_coefficients"], name
            with_ci = [r for r in res["readings"] if "ci" in r]
            assert not with_ci or any(r["ci"]["d_plus"][0] <= 0.5 <= r["ci"]["d_plus"][1] for r in with_ci), name
        else:
            assert ci[0] is None and all(c is not None for c in ci[1:]), name


# ------------------------------------------------------------------------- the staircase path

def _small(tmp_path, **changes) -> Path:
    return rigs.write(tmp_path / "small.yaml", rigs.small(**changes))


def test_one_level_on_the_descending_branch_is_one_line_and_exit_2(tmp_path, capsys):
    """A descending staircase whose first level is where the ascending one ended reaches the
    descending branch at one level only (-1): S^d and d- are not recoverable -- two plants whose
    descending borders cross at u = -1 give the same steady outputs at every level of the design --
    and ``hwid identify-nonlinear`` says so in one line naming them and the levels that would
    determine them, exit 2."""
    from hwid import protocols
    from hwid.model import InputNonlinearity
    path = _small(tmp_path, **{"protocols.staircase.levels_down": [1.0, -1.0]})
    cfg = config.load(path)
    up, down = protocols.staircases(cfg)
    # the truth (S^d = 1, d- = -0.5) and another plant with S^d (u - d-) equal at u = -1
    a = InputNonlinearity("backlash", 1.0, 1.0, 0.5, -0.5)
    b = InputNonlinearity("backlash", 1.0, 1.6, 0.5, -1.0 + 0.5 / 1.6)
    assert b.descending(-1.0) == pytest.approx(a.descending(-1.0))
    for s in (up, down):
        np.testing.assert_allclose(b.steady(s.all_levels, b.ascending(s.all_levels[0])),
                                   a.steady(s.all_levels, a.ascending(s.all_levels[0])), atol=1e-12)
    with pytest.raises(SystemExit) as done:
        main(["identify-nonlinear", str(path), "--out", str(tmp_path / "out")])
    assert done.value.code == 2
    err = capsys.readouterr().err.strip()
    assert len(err.splitlines()) == 1
    assert "cannot determine slope_down, d_minus" in err and "1 from above (-1)" in err
    assert "hold at least 2 distinct levels above d+ approached from below and 2 below d- approached from above" in err
    assert "Traceback" not in err


def test_staircase_estimates_inside_their_intervals_and_the_constant_fixed(tmp_path):
    """The small rig (truth: d+ = 0.5, d- = -0.5, S^d = 1, h linear-cubic): every estimate with
    an interval holds the truth; slope_up and h_bar's constant have no interval and say why; the
    printed summary says it too."""
    from hwid.identify.nonlinear import identify_nonlinear
    from hwid.identify.result import format_summary
    cfg = config.load(_small(tmp_path))
    res, _ = identify_nonlinear(cfg)
    truth = from_config(cfg.plant).normalised()
    for name in ("d_plus", "d_minus", "slope_down"):
        lo, hi = res.ci[name]
        assert lo <= getattr(truth.input, name) <= hi, name
    assert res.ci["slope_up"] is None and res.ci["h_coefficients"][0] is None and res.h_coefficients[0] == 0.0
    assert not res.undetermined
    text = format_summary(res)
    assert "c0 = 0 (fixed by the normalisation h(0) = 0)" in text and "slope_up   = 1 (fixed by" in text


def test_an_exactly_fitted_border_is_undetermined():
    """A fit whose interval for d- came out of zero width (the levels leave it unconstrained) and
    one whose S^d interval reaches below zero: both reported undetermined, interval None, the
    reason in ``undetermined`` and the warnings; the others untouched."""
    from hwid.identify.nonlinear import undetermined
    ci = {"slope_up": None, "slope_down": (-0.2, 2.0), "d_plus": (0.45, 0.55), "d_minus": (-0.5, -0.5),
          "h_coefficients": [None, (0.9, 1.1)], "X_hat": [(0.0, 0.1)]}
    res = NonlinearResult("backlash", 1.0, 0.9, 0.5, -0.5, (0.0, 1.0), 1, (-1.0, 1.0), ci, np.eye(4),
                          ("c1", "d_plus", "slope_down", "d_minus"), (0.0,), (0.05,), (0.01,), 1, 1, "nls",
                          "", (), {"dof": 3})
    out = undetermined(res, width=2.0)
    assert out.ci["d_minus"] is None and "zero width" in out.undetermined["d_minus"]
    assert out.ci["slope_down"] is None and "zero or below" in out.undetermined["slope_down"]
    assert out.ci["d_plus"] == (0.45, 0.55) and out.ci["h_coefficients"] == [None, (0.9, 1.1)]
    assert any(w.startswith("undetermined d_minus:") for w in out.warnings)


# ----------------------------------------------------------------------------------- HDF5

def test_none_survives_hdf5_and_an_old_file_with_zero_width_still_reads(tmp_path):
    """``nonlinear.h5``: an undetermined border and the fixed constant written as ``[NaN, NaN]``
    read back as None with the reason; a file written the old way (``[0, 0]`` for the constant,
    ``[1, 1]`` for slope_up, no ``undetermined``) reads, the two as None."""
    from hwid.identify.nonlinear import identify_nonlinear
    from hwid.results import atomic_h5, read_nonlinear, write_dict, write_nonlinear, write_provenance
    from dataclasses import replace
    cfg = config.load(_small(tmp_path))
    res, records = identify_nonlinear(cfg)
    und = replace(res, ci={**res.ci, "d_minus": None}, undetermined={"d_minus": "a reason"})
    back = read_nonlinear(write_nonlinear(tmp_path / "a", cfg, und, records), cfg)
    assert back.ci["d_minus"] is None and back.undetermined == {"d_minus": "a reason"}
    assert back.ci["h_coefficients"] == und.ci["h_coefficients"] and back.ci["d_plus"] == und.ci["d_plus"]
    old = res.to_dict()                       # as the writer before stored it
    fit = old.pop("fit")
    del old["fixed"], old["undetermined"]
    old.update(slope_up_ci=[1.0, 1.0], h_coefficients_ci=[[0.0, 0.0]] + old["h_coefficients_ci"][1:])
    path = tmp_path / "old" / "nonlinear.h5"
    path.parent.mkdir()
    with atomic_h5(path) as f:
        write_provenance(f, "nonlinear", cfg)
        g = f.require_group("result")
        write_dict(g, {k: v for k, v in old.items() if k not in ("warnings", "param_names")})
        g.attrs["warnings"] = json.dumps(old["warnings"])
        g.attrs["param_names"] = json.dumps(old["param_names"])
        g.attrs["fit"] = json.dumps(fit, default=lambda o: o.tolist() if hasattr(o, "tolist") else str(o))
    assert h5_tree(path)["result"]["h_coefficients_ci"][0] == [0.0, 0.0]
    old_back = read_nonlinear(path, cfg)
    assert old_back.ci["slope_up"] is None and old_back.ci["h_coefficients"][0] is None
    assert old_back.ci["h_coefficients"][1:] == res.ci["h_coefficients"][1:] and old_back.undetermined == {}


def test_batch_coverage_counts_only_runs_with_an_interval():
    """``hwid.batch.summarise``: a run whose estimate has no interval (h_bar's constant always; a
    border one run's data left undetermined) is neither covered nor missed; it is counted apart."""
    from hwid.batch import flatten, summarise
    runs = [{"estimates": flatten({"d_plus": 0.5, "d_plus_ci": [0.4, 0.6], "h_coefficients": [0.0, 1.0],
                                   "h_coefficients_ci": [None, [0.9, 1.1]], "degree": 1}, None)},
            {"estimates": flatten({"d_plus": 0.52, "d_plus_ci": [0.51, 0.53], "h_coefficients": [0.0, 1.0],
                                   "h_coefficients_ci": [None, [0.95, 1.05]], "degree": 1}, None)},
            {"estimates": flatten({"d_plus": 0.9, "d_plus_ci": None, "h_coefficients": [0.0, 1.0],
                                   "h_coefficients_ci": [None, [0.8, 1.2]], "degree": 1}, None)}]
    stats = summarise(runs, {"d_plus": 0.5, "h_c0": 0.0, "h_c1": 1.0})
    assert stats["d_plus"]["coverage"] == 0.5 and stats["d_plus"]["without_interval"] == 1
    assert "coverage" not in stats["h_c0"] and stats["h_c0"]["without_interval"] == 3
    assert stats["h_c1"]["coverage"] == 1.0 and stats["h_c1"]["without_interval"] == 0
