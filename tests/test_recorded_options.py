"""Recorded logs as users write them: comma decimals in CSV, JSON columns by name, and a split
record said by ``hwid check``."""
import json

import numpy as np
import pytest
import yaml

from hwid import config
from hwid.cli import main
from hwid.recorded import load_records

DT = 0.1


def signals(n=300, seed=0):
    """Held levels (u) and a smooth output (y), stamped 99-103 ms apart (seconds, 6 decimals)."""
    rng = np.random.default_rng(seed)
    t = np.round(np.cumsum(np.concatenate([[0.0], rng.uniform(0.099, 0.103, n - 1)])), 6)
    u = np.repeat(rng.integers(-5, 5, n // 20).astype(float), 20)[:n] * 0.25
    y = np.round(np.sin(0.3 * t) * 1.5, 6)
    return t, u, y


def write_csv(path, t, u, y, sep=",", decimal="."):
    rows = [sep.join(["time", "command", "position"])]
    rows += [sep.join(f"{v:.6f}".replace(".", decimal) for v in (tk, uk, yk)) for tk, uk, yk in zip(t, u, y)]
    path.write_text("\n".join(rows) + "\n")
    return path


def write_config(tmp_path, file, **exp):
    data = {"name": "rec", "sampling": {"dt": DT},
            "plant": {"kind": "recorded", "experiments": [{"file": str(file), **exp}]}}
    path = tmp_path / "rec.yaml"
    path.write_text(yaml.safe_dump(data, sort_keys=False))
    return path


BY_NAME = {"time": {"column": "time"}, "input": {"column": "command"}, "output": {"column": "position"}}


def read(tmp_path, file, **exp):
    return load_records(config.load(write_config(tmp_path, file, **exp)))


def assert_same_records(got, ref):
    assert [r.name for r in got] == [r.name for r in ref]
    for a, b in zip(got, ref):
        assert np.array_equal(a.u, b.u) and np.array_equal(a.y, b.y)


@pytest.mark.parametrize("sep, given", [(";", None), ("\t", None), (";", "semicolon"), (" ", "space"),
                                        ("|", "pipe")])
def test_comma_decimal_csv_reads_as_the_plain_one(tmp_path, sep, given):
    t, u, y = signals()
    ref = read(tmp_path, write_csv(tmp_path / "plain.csv", t, u, y), **BY_NAME)
    comma = write_csv(tmp_path / "comma.csv", t, u, y, sep=sep, decimal=",")
    extra = {"separator": given} if given else {}
    got = read(tmp_path, comma, decimal=",", **extra, **BY_NAME)
    for r in got:
        r.name = r.name.replace("comma", "plain")
    assert_same_records(got, ref)
    assert got[0].attrs["jitter_max_s"] == ref[0].attrs["jitter_max_s"]


def test_comma_decimal_bad_cell_is_named(tmp_path):
    t, u, y = signals(n=40)
    path = write_csv(tmp_path / "comma.csv", t, u, y, sep=";", decimal=",")
    lines = path.read_text().split("\n")
    lines[5] = lines[5].rsplit(";", 1)[0] + ";1,2x"
    path.write_text("\n".join(lines))
    with pytest.raises(config.HwidError, match=r"row 5 \(data row, 1-based\), column 'position': '1\.2x' is not a number"):
        read(tmp_path, path, decimal=",", **BY_NAME)


@pytest.mark.parametrize("layout", ["dict-of-lists", "list-of-rows", "top-level-dict"])
def test_json_columns_by_name_read_as_the_plain_table(tmp_path, layout):
    t, u, y = signals(seed=1)
    ref = read(tmp_path, write_csv(tmp_path / "log.csv", t, u, y), **BY_NAME)
    columns = {"time": t.tolist(), "command": u.tolist(), "position": y.tolist(), "current": [0.0] * t.size}
    key = {}
    if layout == "dict-of-lists":
        document, key = {"meta": {"rig": "servo"}, "log": columns}, {"key": "log"}
    elif layout == "list-of-rows":
        document, key = {"log": [dict(zip(columns, row)) for row in zip(*columns.values())]}, {"key": "log"}
    else:
        document = columns
    path = tmp_path / "log.json"
    path.write_text(json.dumps(document))
    assert_same_records(read(tmp_path, path, **key, **BY_NAME), ref)
    by_index = {"time": {"column": 0}, "input": {"column": 1}, "output": {"column": 2}}
    assert_same_records(read(tmp_path, path, **key, **by_index), ref)     # indices: the names' order


def test_json_named_column_missing_is_one_line(tmp_path, capsys):
    path = tmp_path / "log.json"
    path.write_text(json.dumps({"data": {"time": [0, 0.1, 0.2], "command": [1, 1, 2], "position": [0, 1, 2]}}))
    cfg = write_config(tmp_path, path, time={"column": "time"}, input={"column": "comand"},
                       output={"column": "position"})
    code, _, err = run(["check", cfg], capsys)
    assert code == 2 and err.count("\n") == 1
    assert "no column 'comand'" in err and "did you mean 'command'?" in err


def run(argv, capsys):
    with pytest.raises(SystemExit) as exc:
        main([str(a) for a in argv])
    out, err = capsys.readouterr()
    return exc.value.code, out, err


def test_check_says_where_a_gap_split_the_record(tmp_path, capsys):
    """A 1.5 s pause of the logger after the 120th row: one line names the file, the time of the
    last sample before it and the time to the next sample; exit 0."""
    t, u, y = signals(seed=2)
    t[120:] += 1.5
    path = write_csv(tmp_path / "log.csv", t, u, y)
    code, out, err = run(["check", write_config(tmp_path, path, **BY_NAME)], capsys)
    assert code == 0, err
    lines = out.strip().split("\n")
    assert "2 experiment(s)" in lines[0]
    [split] = lines[1:]
    assert split.startswith(f"{path}: split at t = {t[119] - t[0]:.6g} s, {t[120] - t[119]:.6g} s to the next sample")
    assert "gap in the timestamps" in split


def test_check_lists_every_split_with_its_cause(tmp_path, capsys):
    t, u, y = signals(seed=3)
    t[200:] += 1.0
    y[100:110] = np.nan
    path = tmp_path / "log.csv"
    write_csv(path, t, u, y)
    path.write_text(path.read_text().replace("nan", ""))
    code, out, _ = run(["check", write_config(tmp_path, path, exclude=[[5.0, 6.0]], **BY_NAME)], capsys)
    assert code == 0
    splits = out.strip().split("\n")[1:]
    assert len(splits) == 3
    assert "excluded stretch" in splits[0] and "missing values" in splits[1] and "gap in the timestamps" in splits[2]
    assert f"split at t = {t[99] - t[0]:.6g} s, {t[110] - t[99]:.6g} s to the next sample" in splits[1]


@pytest.mark.parametrize("change, fragment", [
    ({"decimal": ";"}, "plant.experiments[0].decimal: must be '.' or ','"),
    ({"decimal": ",", "separator": "comma"}, "separator and decimal must differ"),
    ({"separator": ";"}, "plant.experiments[0].separator: must be 'comma', 'semicolon', 'tab', 'pipe' or 'space'"),
])
def test_bad_decimal_or_separator_is_one_line(tmp_path, capsys, change, fragment):
    t, u, y = signals(n=40)
    cfg = write_config(tmp_path, write_csv(tmp_path / "log.csv", t, u, y), **change, **BY_NAME)
    code, _, err = run(["check", cfg], capsys)
    assert code == 2 and err.count("\n") == 1 and err.startswith("hwid: error: ")
    assert fragment in err


def test_decimal_on_a_json_file_is_one_line(tmp_path, capsys):
    path = tmp_path / "log.json"
    path.write_text(json.dumps({"data": [[0, 1, 2], [0.1, 1, 2]]}))
    cfg = write_config(tmp_path, path, decimal=",", time={"column": 0}, input={"column": 1}, output={"column": 2})
    code, _, err = run(["check", cfg], capsys)
    assert code == 2 and err.count("\n") == 1 and "decimal and separator are for CSV files" in err
