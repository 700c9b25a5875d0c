"""Recorded logs in (hwid/recorded.py): every format, jittered timestamps, gaps and NaN runs, checked
against the signals the files were written from; the real STS3215 and damper logs where present."""
import json
from pathlib import Path

import h5py
import numpy as np
import pytest
import yaml

from hwid import config
from hwid.cli import main
from hwid.recorded import level_segments, load_records, periodic_segment, resample
from hwid.results import read_simulation

REAL = Path(__file__).resolve().parents[2] / "shared" / "data" / "real"
DT = 0.1


def _signals(n=400, seed=0):
    """Levels held by a rig (u) and a smooth output (y) sampled with 99-103 ms jitter."""
    rng = np.random.default_rng(seed)
    t = np.round(np.cumsum(np.concatenate([[0.0], rng.uniform(0.099, 0.103, n - 1)])), 6)   # ISO stamps hold us
    u = np.repeat(rng.integers(-5, 5, n // 20).astype(float), 20)[:n] * 10
    y = np.sin(0.3 * t) * 100
    return t, u, y


def _config(tmp_path, file, **exp):
    data = {"name": "rec", "sampling": {"dt": DT},
            "plant": {"kind": "recorded", "experiments": [{"file": str(file), **exp}]}}
    path = tmp_path / "rec.yaml"
    path.write_text(yaml.safe_dump(data, sort_keys=False))
    return config.load(path), path


def _csv(tmp_path, t, u, y, sep=",", iso=True, name="log.csv", blank_rows=0):
    stamps = (np.datetime64("2025-11-09T09:27:03.748") + np.round(t * 1e6).astype("int64").astype("timedelta64[us]")).astype(str)
    lines = [sep.join(["timestamp", "target", "pos"])] + [sep] * 0
    lines += [sep.join(["", "", ""])] * blank_rows
    for k in range(t.size):
        stamp = stamps[k] + "Z" if iso else f"{t[k]:.6f}"
        lines.append(sep.join([stamp, "" if np.isnan(u[k]) else f"{u[k]:g}", "" if np.isnan(y[k]) else f"{y[k]:.6f}"]))
    lines += [sep.join(["", "", ""])] * blank_rows
    path = tmp_path / name
    path.write_text("\n".join(lines) + "\n")
    return path


def test_jittered_iso_csv_goes_onto_the_grid(tmp_path):
    t, u, y = _signals()
    cfg, _ = _config(tmp_path, _csv(tmp_path, t, u, y, blank_rows=2), time={"column": "timestamp"},
                     input={"column": "target"}, output={"column": 2, "scale": 0.5, "offset": 1.0})
    [rec] = load_records(cfg)
    grid = np.arange(rec.u.size) * DT
    held = u[np.searchsorted(t, grid + 0.5 * DT, side="left") - 1]      # from the grid point nearest its stamp
    assert np.array_equal(rec.u, held)                                   # zero-order hold of the command
    np.testing.assert_allclose(rec.y, 0.5 * np.interp(grid, t, y) + 1.0, atol=1e-5)
    assert rec.attrs["rows_dropped_leading"] == 2 and rec.attrs["rows_dropped_trailing"] == 2
    assert 0.0005 < rec.attrs["jitter_median_s"] < 0.003 and rec.attrs["jitter_max_s"] <= 0.0031
    assert rec.attrs["output_resolution_source"] == "none"


@pytest.mark.parametrize("fmt", ["semicolon", "tab", "seconds", "h5", "npz", "json"])
def test_every_format_gives_the_same_record(fmt, tmp_path):
    t, u, y = _signals(seed=1)
    ref_cfg, _ = _config(tmp_path, _csv(tmp_path, t, u, y, name="ref.csv"), time={"column": "timestamp"},
                         input={"column": 1}, output={"column": 2})
    [ref] = load_records(ref_cfg)
    columns = {"time": {"column": 0}, "input": {"column": 1}, "output": {"column": 2}}
    if fmt in ("semicolon", "tab", "seconds"):
        sep = {"semicolon": ";", "tab": "\t", "seconds": ","}[fmt]
        path = _csv(tmp_path, t, u, y, sep=sep, iso=fmt != "seconds", name=f"{fmt}.txt")
    elif fmt == "h5":
        path = tmp_path / "log.h5"
        with h5py.File(path, "w") as f:
            for k, v in {"t": t, "u": u, "y": y}.items():
                f[f"run/{k}"] = v
        columns = {"key": "run", "time": {"column": "t"}, "input": {"column": "u"}, "output": {"column": "y"}}
    elif fmt == "npz":
        path = tmp_path / "log.npz"
        np.savez(path, t=t, u=u, y=y)
        columns = {"time": {"column": "t"}, "input": {"column": "u"}, "output": {"column": "y"}}
    else:
        path = tmp_path / "log.json"
        path.write_text(json.dumps({"data": np.column_stack([t, u, y]).tolist()}))
    cfg, _ = _config(tmp_path, path, **columns)
    [rec] = load_records(cfg)
    assert np.array_equal(rec.u, ref.u)
    np.testing.assert_allclose(rec.y, ref.y, atol=2e-5)


def test_gaps_and_nan_runs_split_or_fill(tmp_path):
    t, u, y = _signals(n=300, seed=2)
    t[150:] += 1.0                     # a 1 s gap (10 dt) after row 150: split
    y[40] = np.nan                     # one missing sample: interpolated
    y[80:82] = np.nan                  # two: interpolated
    u[200:206] = np.nan                # six: split
    cfg, _ = _config(tmp_path, _csv(tmp_path, t, u, y), time={"column": "timestamp"},
                     input={"column": 1}, output={"column": 2})
    recs = load_records(cfg)
    assert [r.name for r in recs] == ["log_part1", "log_part2", "log_part3"]
    assert recs[0].attrs["nan_interpolated"] == 3 and recs[0].attrs["splits"] == 2
    assert abs(recs[0].u.size * DT - (t[149] - t[0])) < 2 * DT
    assert all(np.all(np.isfinite(r.y)) and np.all(np.isfinite(r.u)) for r in recs)


def test_excluded_stretches_are_cut_out_and_never_bridged(tmp_path):
    t, u, y = _signals(n=300, seed=3)
    # one stretch of 2 s and one of a single sample (shorter than a gap that would split)
    cfg, _ = _config(tmp_path, _csv(tmp_path, t, u, y), time={"column": "timestamp"},
                     input={"column": 1}, output={"column": 2}, exclude=[[10.0, 12.0], [20.0, 20.05]])
    recs = load_records(cfg)
    assert [r.name for r in recs] == ["log_part1", "log_part2", "log_part3"]
    rel = t - t[0]
    gone = ((rel >= 10.0) & (rel <= 12.0)) | ((rel >= 20.0) & (rel <= 20.05))
    assert recs[0].attrs["rows_excluded"] == int(gone.sum())
    starts = [r.attrs["piece_start_s"] for r in recs]
    assert starts[1] > 12.0 and starts[2] > 20.05 and abs(recs[0].u.size * DT - 10.0) < 2 * DT


def test_output_resolution_detected_and_levels_found(tmp_path):
    t, u, _ = _signals(n=200, seed=3)
    counts = np.round(np.sin(0.2 * t) * 40)          # an encoder: whole counts
    cfg, _ = _config(tmp_path, _csv(tmp_path, t, u, counts), time={"column": "timestamp"},
                     input={"column": 1}, output={"column": 2, "scale": 0.088})
    [rec] = load_records(cfg)
    assert rec.attrs["output_resolution"] == pytest.approx(0.088) and rec.attrs["output_resolution_source"] == "detected"
    segs = json.loads(rec.attrs["segments"])
    values = [s["value"] for s in segs]
    # the written levels change every 20 rows (~2 s): each found, within a sample or two of its edge
    changes = np.flatnonzero(np.diff(u) != 0) + 1
    assert len(segs) == len(values) and len(segs) >= changes.size - 1
    for s in segs[1:]:
        assert np.min(np.abs(t[changes] - s["start"] * DT)) < 2 * DT


def test_level_segments_directions():
    u = np.array([0, 0, 0, 1, 1, 1, 1, 0.5, 0.5, 0.5, 0.5, 2])
    segs = level_segments(u)
    assert [(s["value"], s["direction"]) for s in segs] == [(0.0, "first"), (1.0, "up"), (0.5, "down")]


def test_resample_holds_the_command_and_interpolates_the_output():
    # each command holds from the grid point nearest its stamp; one stamped half a sample late or
    # more starts a sample later
    t = np.array([0.0, 0.12, 0.19, 0.31])
    u_grid, y_grid = resample(t, np.array([1.0, 2.0, 3.0, 4.0]), np.array([0.0, 1.2, 1.9, 3.1]), 0.1)
    assert u_grid.tolist() == [1.0, 2.0, 3.0, 4.0] and y_grid == pytest.approx([0.0, 1.0, 2.0, 3.0])
    t = np.array([0.0, 0.16, 0.2, 0.3])
    u_grid, _ = resample(t, np.array([1.0, 2.0, 3.0, 4.0]), np.zeros(4), 0.1)
    assert u_grid.tolist() == [1.0, 1.0, 3.0, 4.0]


def test_cli_simulate_writes_the_records_with_their_provenance(tmp_path, capsys):
    t, u, y = _signals(seed=4)
    cfg, path = _config(tmp_path, _csv(tmp_path, t, u, y), time={"column": "timestamp"},
                        input={"column": 1}, output={"column": 2})
    with pytest.raises(SystemExit) as ex:
        main(["simulate", str(path), "--out", str(tmp_path / "out")])
    assert ex.value.code == 0
    recs, truth = read_simulation(tmp_path / "out" / "simulation.h5", cfg)
    assert truth is None and list(recs) == ["log"]
    assert len(recs["log"].attrs["source_sha256"]) == 64 and "zero-order hold" in recs["log"].attrs["resampling"]


@pytest.mark.skipif(not (REAL / "sts3215").is_dir(), reason="the real logs (../shared/data/real/sts3215) are not here")
def test_real_sts3215_log():
    cfg = config.load(Path(__file__).resolve().parents[1] / "configs" / "recorded_sts3215.yaml")
    [rec] = load_records(cfg)
    assert rec.u.size == 275 and rec.attrs["output_resolution"] == 1.0
    assert rec.attrs["jitter_max_s"] < 0.005
    levels = [s["value"] for s in json.loads(rec.attrs["segments"])]
    assert len(levels) >= 5 and max(levels) - min(levels) >= 100      # the target's staircase, in counts


@pytest.mark.skipif(not (REAL / "brfd").is_dir(), reason="the real damper data (../shared/data/real/brfd) are not here")
def test_real_damper_json():
    cfg = config.load(Path(__file__).resolve().parents[1] / "configs" / "recorded_brfd.yaml")
    [rec] = load_records(cfg)
    assert rec.dt == pytest.approx(1 / 1024) and rec.u.size > 5000
    assert rec.attrs["jitter_max_s"] < 1e-6
    assert np.ptp(rec.u) == pytest.approx(2.0, rel=0.1)            # +-1 in displacement
    # the tapered 1 Hz test: its three full-amplitude periods found, the ramps in and out left out
    [seg] = json.loads(rec.attrs["segments"])
    assert seg["kind"] == "periodic" and seg["omega"] == pytest.approx(2 * np.pi, rel=1e-3)
    assert seg["periods"] == 3 and seg["start"] == pytest.approx(2048, abs=20) and seg["stop"] == pytest.approx(5120, abs=20)


def test_periodic_stretch_of_a_tapered_sine():
    """A 0.7 rad/s sine tapered in over 2 periods and out over 2, 6 periods at full amplitude
    between, with noise: the fundamental to 0.5 %, the full-amplitude periods kept (one period of
    slack at either end, where a period straddles the taper), the tapers left out."""
    dt, omega = 0.05, 0.7
    period = 2 * np.pi / omega
    t = np.arange(int(10 * period / dt)) * dt
    envelope = np.clip(np.minimum(t, t[-1] - t) / (2 * period), 0.0, 1.0)
    u = envelope * np.sin(omega * t) + 0.01 * np.random.default_rng(0).standard_normal(t.size)
    seg = periodic_segment(u, dt)
    assert seg["omega"] == pytest.approx(omega, rel=5e-3)
    assert 5 <= seg["periods"] <= 6
    assert 2 * period / dt - period / dt <= seg["start"] <= 2 * period / dt + period / dt
    assert envelope[seg["start"]:seg["stop"]].min() > 0.9


def test_auto_role_finds_levels_or_a_periodic_stretch(tmp_path):
    """role auto: a log of held levels gives levels only; a sine log gives one periodic stretch."""
    t = np.arange(600) * DT
    steps = np.repeat([0.0, 10.0, 20.0, 10.0, 0.0, -10.0], 100)
    cfg, _ = _config(tmp_path, _csv(tmp_path, t, steps, np.sin(t), name="steps.csv"), time={"column": "timestamp"},
                     input={"column": "target"}, output={"column": "pos"}, role="auto")
    [rec] = load_records(cfg)
    assert [seg["kind"] for seg in json.loads(rec.attrs["segments"])] == ["level"] * 6
    cfg, _ = _config(tmp_path, _csv(tmp_path, t, 10 * np.sin(0.5 * t), np.sin(t), name="sine.csv"),
                     time={"column": "timestamp"}, input={"column": "target"}, output={"column": "pos"}, role="auto")
    [rec] = load_records(cfg)
    periodic = [seg for seg in json.loads(rec.attrs["segments"]) if seg["kind"] == "periodic"]
    assert len(periodic) == 1 and periodic[0]["omega"] == pytest.approx(0.5, rel=0.01)
