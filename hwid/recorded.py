"""Recorded logs in: a user's files read, cleaned and put on the ``dt`` grid as hwid's ``Record``s.

One reader per format behind :func:`read_columns` (nothing downstream knows which format a record
came from): CSV by pandas (the delimiter sniffed or given, ``.`` or ``,`` as the decimal mark, a
header row, columns by name or 0-based index, ISO 8601 timestamps), HDF5 (dataset paths, under
``key`` when given), NPZ (array names), JSON (under ``key``, default ``data``, else the whole
document: a 2-D array with columns by index, a mapping of named columns, or a list of rows by name).

What is done to the data, and recorded in each ``Record``'s attributes (so in ``simulation.h5``,
and listed by ``hwid report``):

* leading and trailing rows without both signals are dropped;
* a gap in time longer than ``3 dt`` splits the record (never bridged); each split's time, length
  and cause are kept (``split_points``) and said by ``hwid check`` (:func:`split_lines`);
* interior NaN runs of at most 2 samples are interpolated (counted); longer ones split the record;
* uneven timestamps go onto the ``dt`` grid: the input by zero-order hold (a rig holds its
  command, from the grid point nearest its timestamp), the output by linear interpolation; the
  jitter of the sampling interval is reported;
* the output's resolution (its quantum, e.g. one encoder count) is given or detected;
* ``role: auto`` finds the piecewise-constant stretches of the input (levels, with the direction
  each was approached from).
"""
from __future__ import annotations

import csv
import difflib
import hashlib
import json
from pathlib import Path

import numpy as np

from hwid import HwidError
from hwid.masks import runs
from hwid.plant import Record

#: a gap in the timestamps longer than this many sample times splits a record
GAP_DT = 3.0
#: interior NaN runs up to this many samples are interpolated; longer ones split the record
MAX_NAN_RUN = 2
#: pieces shorter than this many samples after splitting are dropped (counted)
MIN_SAMPLES = 3
#: a level: the input constant for at least this many samples
MIN_LEVEL_SAMPLES = 3
#: CSV column separators by the name the config gives them (``separator``)
SEPARATORS = {"comma": ",", "semicolon": ";", "tab": "\t", "pipe": "|", "space": " "}


class RecordError(HwidError):
    """A recorded file that cannot be read as the config says (one line, names file and column)."""


# ----------------------------------------------------------------------------------- readers

def read_columns(path: Path, columns: list, key: str | None = None, decimal: str = ".",
                 separator: str | None = None) -> tuple[list[np.ndarray], int]:
    """The ``columns`` (names or 0-based indices) of the file at ``path`` as arrays (float, or
    ``datetime64`` for an ISO time column), and the number of data rows.

    ``decimal`` (``"."`` or ``","``) and ``separator`` (a name of :data:`SEPARATORS`; None: sniffed)
    apply to CSV files."""
    if not path.exists():
        raise RecordError(f"{path}: no such file")
    suffix = path.suffix.lower()
    if suffix in (".csv", ".tsv", ".txt"):
        return _read_csv(path, columns, decimal, separator)
    if suffix in (".h5", ".hdf5"):
        return _read_hdf5(path, columns, key)
    if suffix == ".npz":
        return _read_npz(path, columns)
    if suffix == ".json":
        return _read_json(path, columns, key)
    raise RecordError(f"{path}: cannot tell the format from the suffix '{suffix}' "
                      "(use .csv, .tsv, .txt, .h5, .hdf5, .npz or .json)")


def _pick(path: Path, names: list[str], column):
    """The name of ``column`` (a name or an index) among ``names``, or a one-line error listing them."""
    if isinstance(column, int):
        if column >= len(names):
            raise RecordError(f"{path}: column {column} does not exist (it has {len(names)} columns, 0-based)")
        return names[column]
    if column not in names:
        close = difflib.get_close_matches(str(column), [str(n) for n in names], n=1, cutoff=0.5)
        hint = f"; did you mean '{close[0]}'?" if close else ""
        shown = ", ".join(repr(str(n)) for n in names[:12]) + (" ..." if len(names) > 12 else "")
        raise RecordError(f"{path}: no column '{column}' (columns: {shown}){hint}")
    return column


def _read_csv(path: Path, columns: list, decimal: str = ".", separator: str | None = None):
    import pandas as pd
    with open(path, newline="", encoding="utf-8", errors="replace") as fh:
        head = fh.read(8192)
    if not head.strip():
        raise RecordError(f"{path}: the file is empty")
    delimiter = SEPARATORS[separator] if separator else _sniff(head, decimal)
    try:
        names = list(pd.read_csv(path, sep=delimiter, nrows=0).columns)
        wanted = list(dict.fromkeys(_pick(path, names, c) for c in columns))
        # numbers by the C parser's own conversion (the fast path); a column it cannot convert
        # comes as text, read again by _csv_column (timestamps, or a bad cell named by its row)
        frame = pd.read_csv(path, sep=delimiter, usecols=wanted, engine="c", keep_default_na=True,
                            decimal=decimal)
    except RecordError:
        raise
    except (ValueError, pd.errors.ParserError, UnicodeDecodeError) as err:
        raise RecordError(f"{path}: not a readable CSV file ({type(err).__name__}: {' '.join(str(err).split())[:120]})") from None
    out = [_csv_column(path, frame, _pick(path, names, c), decimal) for c in columns]
    return out, len(frame)


def _sniff(head: str, decimal: str) -> str:
    """The delimiter of a CSV file's first lines; with comma decimals, never the comma."""
    candidates = ";\t| " if decimal == "," else ",;\t| "
    try:
        return csv.Sniffer().sniff(head, delimiters=candidates).delimiter
    except csv.Error:
        return ";" if decimal == "," else ","


def _csv_column(path: Path, frame, name, decimal: str = ".") -> np.ndarray:
    """Numbers, or timestamps for a column of ISO 8601 text; a cell that is neither is an error
    naming its row and column (empty cells become NaN)."""
    import pandas as pd
    text = frame[name]
    if pd.api.types.is_numeric_dtype(text.dtype):
        return text.to_numpy(float)
    present = text.notna()
    if decimal != ".":      # a column the C parser left as text: its numbers with the '.' mark
        text = text.where(~present, text.astype(str).str.replace(decimal, ".", regex=False))
    first = text[present].iloc[0] if present.any() else ""
    try:
        float(first)
        stamps = None
    except ValueError:     # text: timestamps, or a column that is not a signal
        stamps = pd.to_datetime(text, format="ISO8601", utc=True, errors="coerce")
        bad = stamps.isna() & present
        if not bad.any():
            return stamps.dt.tz_localize(None).to_numpy(dtype="datetime64[ns]")
    if stamps is None:
        numbers = pd.to_numeric(text, errors="coerce")
        bad = numbers.isna() & present & (text.astype(str).str.strip() != "")
        if not bad.any():
            return numbers.to_numpy(float)
    row = int(np.argmax(bad.to_numpy()))
    raise RecordError(f"{path}: row {row + 1} (data row, 1-based), column '{name}': "
                      f"'{text.iloc[row]}' is not a number")


def _read_hdf5(path: Path, columns: list, key: str | None):
    import h5py
    try:
        with h5py.File(path, "r") as f:
            group = f[key] if key else f
            names = [n for n, item in group.items() if isinstance(item, h5py.Dataset)]
            out = [np.asarray(group[_pick(path, names, c)][()], float).ravel() for c in columns]
    except (OSError, KeyError) as err:
        raise RecordError(f"{path}: cannot be read as HDF5 ({type(err).__name__}: {err})") from None
    return out, max(a.size for a in out)


def _read_npz(path: Path, columns: list):
    try:
        with np.load(path) as f:
            names = list(f.files)
            out = [np.asarray(f[_pick(path, names, c)], float).ravel() for c in columns]
    except (OSError, ValueError) as err:
        raise RecordError(f"{path}: cannot be read as NPZ ({type(err).__name__})") from None
    return out, max(a.size for a in out)


def _read_json(path: Path, columns: list, key: str | None):
    """A 2-D array (columns by index), a mapping ``{name: [values]}`` or a list of rows
    ``[{name: value}]`` (columns by name, or by index in the order of the names), under ``key``;
    without ``key``, under ``data`` or else the whole document."""
    try:
        document = json.loads(path.read_text(encoding="utf-8"))
    except (OSError, ValueError) as err:
        raise RecordError(f"{path}: not a readable JSON file ({type(err).__name__})") from None
    where = f"key '{key or 'data'}'"
    if key is None and not (isinstance(document, dict) and "data" in document):
        data, where = document, "the top level"
    elif isinstance(document, dict) and (key or "data") in document:
        data = document[key or "data"]
    else:
        raise RecordError(f"{path}: no key '{key or 'data'}' in the file")
    if isinstance(data, dict) or (isinstance(data, list) and data and all(isinstance(r, dict) for r in data)):
        return _json_named_columns(path, data, columns, where)
    try:
        table = np.asarray(data, float)
    except (ValueError, TypeError) as err:
        raise RecordError(f"{path}: no numeric table under {where} ({type(err).__name__})") from None
    if table.ndim != 2:
        raise RecordError(f"{path}: the array under {where} is not 2-D (shape {table.shape})")
    for c in columns:
        if not isinstance(c, int) or c >= table.shape[1]:
            raise RecordError(f"{path}: column {c!r}: JSON columns are 0-based indices below {table.shape[1]} "
                              f"in the 2-D array under {where} (names need a mapping of columns or a list of rows)")
    return [table[:, c] for c in columns], table.shape[0]


def _json_named_columns(path: Path, data, columns: list, where: str):
    """Columns by name from ``{name: [values]}`` or ``[{name: value}]`` (a row without the name,
    or with null, gives NaN); ``datetime64`` for a column of ISO 8601 text."""
    if isinstance(data, dict):
        names = list(data)
        get = lambda name: data[name]                                        # noqa: E731
    else:
        names = list(dict.fromkeys(n for row in data for n in row))
        get = lambda name: [row.get(name) for row in data]                   # noqa: E731
    out = []
    for c in columns:
        name = _pick(path, names, c)
        values = get(name)
        if not isinstance(values, list):
            raise RecordError(f"{path}: column '{name}' under {where} is not a list of values")
        out.append(_json_values(path, name, values))
    if len({a.size for a in out}) > 1:
        raise RecordError(f"{path}: the columns under {where} differ in length "
                          f"({', '.join(str(a.size) for a in out)})")
    return out, out[0].size


def _json_values(path: Path, name, values: list) -> np.ndarray:
    """A JSON column as floats (null -> NaN), or as timestamps when it holds ISO 8601 text."""
    if any(isinstance(v, str) for v in values):
        try:                                       # numbers written as text
            return np.array([np.nan if v is None else float(v) for v in values], dtype=float)
        except (ValueError, TypeError):
            return np.array([np.datetime64("NaT") if v is None else _iso(path, name, v) for v in values],
                            dtype="datetime64[ns]")
    try:
        return np.array([np.nan if v is None else v for v in values], dtype=float)
    except (ValueError, TypeError):
        row = next(i for i, v in enumerate(values) if not isinstance(v, (int, float)) and v is not None)
        raise RecordError(f"{path}: row {row + 1}, column '{name}': {values[row]!r} is not a number") from None


def _iso(path: Path, name, value) -> np.datetime64:
    import pandas as pd
    try:
        stamp = pd.Timestamp(value)
    except (ValueError, TypeError):
        raise RecordError(f"{path}: column '{name}': {value!r} is neither a number nor an ISO 8601 time") from None
    if stamp.tzinfo is not None:
        stamp = stamp.tz_convert("UTC").tz_localize(None)
    return np.datetime64(stamp.to_datetime64(), "ns")


# -------------------------------------------------------------------------------- the records

def sha256(path: Path) -> str:
    h = hashlib.sha256()
    with open(path, "rb") as fh:
        for chunk in iter(lambda: fh.read(1 << 20), b""):
            h.update(chunk)
    return h.hexdigest()


def load_records(cfg) -> list[Record]:
    """Every experiment of a recorded plant, read, cleaned and put on the ``dt`` grid."""
    base = Path(cfg.source_path).parent if cfg.source_path not in ("", "<config>") else Path(".")
    records: list[Record] = []
    for index, exp in enumerate(cfg.plant.experiments):
        records += load_experiment(exp, index, base, cfg.sampling.dt, cfg.plant.output_resolution)
    names = [r.name for r in records]
    if len(set(names)) != len(names):
        for k, r in enumerate(records):
            r.name = f"{r.name}_{k}"
    return records


def load_experiment(exp, index: int, base: Path, dt: float, resolution: float | None) -> list[Record]:
    """One configured file as one or more records (split at gaps and long NaN runs)."""
    path = (base / exp.file) if not Path(exp.file).is_absolute() else Path(exp.file)
    where = f"plant.experiments[{index}] ({exp.file})"
    columns = [exp.input.column, exp.output.column] + ([exp.time.column] if exp.time is not None else [])
    arrays, n_rows = read_columns(path, columns, exp.key, exp.decimal, exp.separator)
    u_raw, y_raw = arrays[0], arrays[1]
    u = exp.input.scale * u_raw + exp.input.offset
    y = exp.output.scale * y_raw + exp.output.offset
    t = _seconds(arrays[2], path, exp.time.column) if exp.time is not None else np.arange(u.size) * dt
    present = np.isfinite(u) & np.isfinite(y) & np.isfinite(t)
    if not present.any():
        raise RecordError(f"{where}: the record is empty (no row holds both signals)")
    first, last = int(np.argmax(present)), int(present.size - np.argmax(present[::-1]) - 1)
    u, y, t, y_raw = u[first:last + 1], y[first:last + 1], t[first:last + 1], y_raw[first:last + 1]
    _check_time(t, path, first)
    t = t - t[0]
    keep = np.ones(t.size, bool)
    if exp.start is not None:
        keep &= t >= exp.start
    if exp.stop is not None:
        keep &= t <= exp.stop
    if keep.sum() < MIN_SAMPLES:
        raise RecordError(f"{where}: fewer than {MIN_SAMPLES} samples between start and stop")
    u, y, t, y_raw = u[keep], y[keep], t[keep], y_raw[keep]
    quantum, quantum_source = _resolution(y_raw, exp.output.scale, resolution)
    # the excluded stretches out, the record always cut where one was (never bridged)
    out = np.zeros(t.size, bool)
    for a, b in exp.exclude:
        out |= (t >= a) & (t <= b)
    cut_after = np.flatnonzero(out[1:] & ~out[:-1])          # last kept sample before a stretch
    forced = np.searchsorted(np.flatnonzero(~out), cut_after, side="right")
    u, y, t = u[~out], y[~out], t[~out]
    decisions = {"rows_read": int(n_rows), "rows_dropped_leading": first,
                 "rows_dropped_trailing": int(n_rows - last - 1), "nan_interpolated": 0, "dropped_short_pieces": 0,
                 "rows_excluded": int(out.sum())}
    if t.size < MIN_SAMPLES:
        raise RecordError(f"{where}: fewer than {MIN_SAMPLES} samples are left outside the excluded stretches")
    split_points: list[dict] = []
    pieces = _split(t, u, y, dt, decisions, forced, split_points)
    if not pieces:
        raise RecordError(f"{where}: no stretch of at least {MIN_SAMPLES} samples without a gap "
                          f"longer than {GAP_DT:g} dt or a NaN run longer than {MAX_NAN_RUN}")
    step = np.diff(t)
    step = step[step <= GAP_DT * dt]      # a pause of the logger splits the record; it is not jitter
    provenance = {"source_file": str(path), "source_sha256": sha256(path),
                  "columns": json.dumps({"input": exp.input.column, "output": exp.output.column,
                                         "time": None if exp.time is None else exp.time.column}),
                  "input_scale": exp.input.scale, "input_offset": exp.input.offset,
                  "output_scale": exp.output.scale, "output_offset": exp.output.offset,
                  "start": -1.0 if exp.start is None else exp.start, "stop": -1.0 if exp.stop is None else exp.stop,
                  "exclude": json.dumps([list(w) for w in exp.exclude]),
                  "resampling": "input zero-order hold, output linear interpolation, onto t0 + k dt",
                  "jitter_median_s": float(np.median(np.abs(step - dt))) if step.size else 0.0,
                  "jitter_max_s": float(np.max(np.abs(step - dt))) if step.size else 0.0,
                  "output_resolution": quantum if quantum is not None else 0.0,
                  "output_resolution_source": quantum_source, "role": exp.role,
                  "splits": len(pieces) - 1, "split_points": json.dumps(split_points), **decisions}
    stem = Path(exp.file).stem
    records = []
    for k, (tk, uk, yk) in enumerate(pieces):
        u_grid, y_grid = resample(tk, uk, yk, dt)
        name = stem if len(pieces) == 1 else f"{stem}_part{k + 1}"
        attrs = {**provenance, "piece": k, "piece_start_s": float(tk[0]), **segment_attrs(u_grid, dt, exp.role)}
        records.append(Record(name, dt, u_grid, y_grid, attrs=attrs))
    return records


def segment_attrs(u: np.ndarray, dt: float, role: str = "auto") -> dict:
    """The ``segments`` attribute of a record of input ``u`` on the ``dt`` grid in ``role``: its
    levels (``auto``, ``staircase``) and, where levels hold less than half of it (``auto``) or
    always (``sine``), its steady periodic stretches; empty for ``validation`` and ``other``."""
    if role not in ("auto", "staircase", "sine"):
        return {}
    segments = level_segments(u) if role in ("auto", "staircase") else []
    held = sum(seg["stop"] - seg["start"] for seg in segments)
    if role == "sine" or (role == "auto" and held < 0.5 * u.size):
        segments += periodic_segments(u, dt)
    return {"segments": json.dumps(segments)}


def _seconds(column: np.ndarray, path: Path, name) -> np.ndarray:
    if np.issubdtype(column.dtype, np.datetime64):
        stamps = column.astype("datetime64[ns]")
        valid = ~np.isnat(stamps)
        origin = stamps[valid][0] if valid.any() else np.datetime64(0, "ns")
        seconds = (stamps - origin).astype("timedelta64[ns]").astype(float) * 1e-9
        seconds[~valid] = np.nan
        return seconds
    return np.asarray(column, float)


def _check_time(t: np.ndarray, path: Path, offset: int) -> None:
    """Timestamps must increase: one that repeats or goes back is named by its data row."""
    step = np.diff(t)
    bad = np.flatnonzero(~(step > 0) & np.isfinite(step))
    if bad.size:
        row = offset + int(bad[0]) + 2
        what = "repeats" if step[bad[0]] == 0 else "goes backwards"
        raise RecordError(f"{path}: row {row} (data row, 1-based): the timestamp {what} ({t[bad[0] + 1]:.6g} s after "
                          f"{t[bad[0]]:.6g} s)")


def _resolution(y_raw: np.ndarray, scale: float, given: float | None) -> tuple[float | None, str]:
    """The output's quantum: given, or the smallest step of the raw output when every step is a
    whole multiple of it (an encoder's count), in output units; else none."""
    if given is not None:
        return float(given), "given"
    raw = y_raw[np.isfinite(y_raw)]
    steps = np.abs(np.diff(raw))
    steps = steps[steps > 0]
    if steps.size < 3:
        return None, "none"
    q = float(steps.min())
    if np.all(np.abs(steps / q - np.round(steps / q)) < 1e-6):
        return q * abs(scale), "detected"
    return None, "none"


def _split(t, u, y, dt: float, decisions: dict, forced=(), points: list | None = None) -> list[tuple]:
    """Pieces without a gap longer than :data:`GAP_DT` ``dt`` or a NaN run longer than
    :data:`MAX_NAN_RUN`; shorter NaN runs interpolated (counted in ``decisions``); also cut before
    the samples ``forced`` (where an excluded stretch was). Each cut is appended to ``points`` as
    ``{"time_s", "gap_s", "cause"}``: the last sample's time before it (s from the record's first
    sample), the time to the next sample after it, and ``gap``, ``excluded`` or ``missing``."""
    forced = np.asarray(forced, int)
    cuts = np.union1d(np.flatnonzero(np.diff(t) > GAP_DT * dt) + 1, forced)
    cuts = cuts[(cuts > 0) & (cuts < t.size)]
    points = [] if points is None else points
    for c in cuts.tolist():
        points.append({"time_s": float(t[c - 1]), "gap_s": float(t[c] - t[c - 1]),
                       "cause": "excluded" if c in forced else "gap"})
    pieces = []
    for tk, uk, yk in zip(np.split(t, cuts), np.split(u, cuts), np.split(y, cuts)):
        missing = ~(np.isfinite(uk) & np.isfinite(yk))
        gaps = runs(missing)
        long_runs = [(a, b) for a, b in gaps if b - a > MAX_NAN_RUN]
        points += [{"time_s": float(tk[a - 1]), "gap_s": float(tk[b] - tk[a - 1]), "cause": "missing"}
                   for a, b in long_runs if 0 < a and b < tk.size]
        for a, b in gaps:
            if b - a <= MAX_NAN_RUN:
                decisions["nan_interpolated"] += b - a
        ok = np.flatnonzero(~missing)
        uk, yk = uk.copy(), yk.copy()
        if ok.size:
            for arr in (uk, yk):
                bad = ~np.isfinite(arr)
                arr[bad] = np.interp(tk[bad], tk[ok], arr[ok])
        bounds = [0] + [x for a, b in long_runs for x in (a, b)] + [tk.size]
        for a, b in zip(bounds[::2], bounds[1::2]):
            if b - a >= MIN_SAMPLES:
                pieces.append((tk[a:b], uk[a:b], yk[a:b]))
            elif b > a:
                decisions["dropped_short_pieces"] += 1
    return pieces


def resample(t, u, y, dt: float) -> tuple[np.ndarray, np.ndarray]:
    """``u`` (zero-order hold) and ``y`` (linear) on the grid ``t[0] + k dt``.

    A command holds from the grid point nearest its timestamp: a logger whose clock jitters by less
    than half a sample around the grid its rig runs on keeps every command on its own sample, where
    holding strictly from the stamp would delay a late-stamped command by a whole sample."""
    n = int(np.floor((t[-1] - t[0]) / dt + 1e-9)) + 1
    grid = t[0] + np.arange(n) * dt
    held = np.clip(np.searchsorted(t, grid + 0.5 * dt, side="left") - 1, 0, t.size - 1)
    return u[held], np.interp(grid, t, y)


def level_segments(u: np.ndarray) -> list[dict]:
    """The piecewise-constant stretches of ``u`` (at least :data:`MIN_LEVEL_SAMPLES` equal samples):
    ``{"kind": "level", "start", "stop", "value", "direction"}``, direction ``up`` or ``down`` from
    the level before (``first`` for the first)."""
    out: list[dict] = []
    change = np.flatnonzero(np.diff(u) != 0) + 1
    bounds = np.concatenate([[0], change, [u.size]])
    previous = None
    for a, b in zip(bounds[:-1], bounds[1:]):
        if b - a < MIN_LEVEL_SAMPLES:
            continue
        value = float(u[a])
        direction = "first" if previous is None else ("up" if value > previous else "down")
        out.append({"kind": "level", "start": int(a), "stop": int(b), "value": value, "direction": direction})
        previous = value
    return out


def periodic_segment(u: np.ndarray, dt: float, harmonics: int = 5, share: float = 0.8,
                     steady: float = 0.05) -> dict | None:
    """The steady periodic stretch of ``u``, if ``u`` is periodic: ``{"kind": "periodic", "start",
    "stop", "omega", "periods"}``, or None.

    The fundamental is the largest peak of the Hann-windowed spectrum (refined between bins); ``u``
    counts as periodic when the fundamental and its harmonics up to ``harmonics`` hold ``share`` of
    the power. The record is cut into whole periods from its start; the stretch kept is the longest
    run of periods whose peak-to-peak stays within ``steady`` of the largest (ramps in and out, as a
    tapered test has, are left out), at least two periods."""
    u = np.asarray(u, float)
    n = u.size
    if n < 64:
        return None
    x = (u - u.mean()) * np.hanning(n)
    power = np.abs(np.fft.rfft(x)) ** 2
    power[0] = 0.0
    if power.sum() <= 0:
        return None
    k = int(np.argmax(power[1:])) + 1
    if 0 < k < power.size - 1:
        a, b, c = np.log(power[k - 1:k + 2] + 1e-300)
        k_hat = k + 0.5 * (a - c) / (a - 2 * b + c) if (a - 2 * b + c) != 0 else float(k)
    else:
        k_hat = float(k)
    near = np.zeros(power.size, bool)
    for h in range(1, harmonics + 1):
        centre = int(round(h * k_hat))
        near[max(centre - 3, 1):centre + 4] = True
    if power[near].sum() < share * power.sum():
        return None
    period = n / k_hat                                  # samples
    whole = int(n // period)
    if whole < 2 or period < 4:
        return None
    edges = np.round(np.arange(whole + 1) * period).astype(int)
    amp = np.array([np.ptp(u[edges[i]:edges[i + 1]]) for i in range(whole)])
    first, last = max(runs(amp >= (1.0 - steady) * amp.max()), key=lambda ab: ab[1] - ab[0])
    if last - first < 2:
        return None
    return {"kind": "periodic", "start": int(edges[first]), "stop": int(edges[last]),
            "omega": float(2 * np.pi / (period * dt)), "periods": last - first}


def periodic_segments(u: np.ndarray, dt: float) -> list[dict]:
    """Every steady periodic stretch of ``u`` (:func:`periodic_segment` on each): a record may hold
    several sines one after the other (a lab's frequency steps).

    The input's upward crossings of its mean (with a hysteresis of a tenth of its amplitude, so a
    held level or noise does not cross) mark its periods; runs of at least three periods whose
    lengths stay within 10 % of their neighbours' are candidate stretches, each tested as one over
    the samples from halfway to the run before to halfway to the run after. With fewer than four
    crossings, the record as a whole."""
    u = np.asarray(u, float)
    s = u - float(np.mean(u))
    amp = float(np.percentile(np.abs(s), 95)) if s.size else 0.0
    ups: list[int] = []
    if amp > 0:
        # the samples past the hysteresis band, in order: an upward crossing is the first above
        # after one below
        past = np.flatnonzero(np.abs(s) > 0.1 * amp)
        side = s[past] > 0
        ups = past[1:][side[1:] & ~side[:-1]].tolist()
    out = []
    if len(ups) >= 4:
        periods = np.diff(ups).astype(float)
        alike = np.abs(periods[1:] / periods[:-1] - 1.0) < 0.1
        groups, start = [], 0
        for i in range(1, len(periods) + 1):
            if i == len(periods) or not alike[i - 1]:
                if i - start >= 2:                                  # periods start .. i-1
                    groups.append((ups[start], ups[i]))
                start = i
        # each run tested on the stretch from halfway to the run before to halfway to the run after
        # (the record's ends for the first and the last): periodic_segment lays its own grid of
        # whole periods and keeps those at full amplitude
        for j, (a, b) in enumerate(groups):
            lo = 0 if j == 0 else (groups[j - 1][1] + a) // 2
            hi = u.size if j == len(groups) - 1 else (b + groups[j + 1][0]) // 2
            seg = periodic_segment(u[lo:hi], dt)
            if seg is not None:
                out.append({**seg, "start": seg["start"] + lo, "stop": seg["stop"] + lo})
    if len(ups) < 4:        # too few crossings to mark periods: the record as a whole
        seg = periodic_segment(u, dt)
        out = [seg] if seg is not None else []
    return out


def split_lines(records: list[Record]) -> list[str]:
    """One line per place a file's record was cut (``hwid check``): the file, the time of the last
    sample before the cut (s from the record's first sample), how long until the next sample, and why."""
    why = {"gap": f"a gap in the timestamps longer than {GAP_DT:g} dt",
           "excluded": "an excluded stretch (exclude)",
           "missing": f"a run of missing values longer than {MAX_NAN_RUN} samples"}
    lines = []
    for r in records:
        if r.attrs.get("piece", 0) != 0:
            continue
        for point in sorted(json.loads(r.attrs.get("split_points", "[]")), key=lambda p: p["time_s"]):
            lines.append(f"{r.attrs.get('source_file', r.name)}: split at t = {point['time_s']:.6g} s, "
                         f"{point['gap_s']:.6g} s to the next sample: {why[point['cause']]}")
    return lines


def describe(records: list[Record]) -> str:
    """One line on what reading the records did (``hwid check``)."""
    n = sum(r.u.size for r in records)
    dropped = sum(int(r.attrs.get("rows_dropped_leading", 0)) + int(r.attrs.get("rows_dropped_trailing", 0))
                  for r in records if r.attrs.get("piece", 0) == 0)
    filled = sum(int(r.attrs.get("nan_interpolated", 0)) for r in records if r.attrs.get("piece", 0) == 0)
    jitter = max(float(r.attrs.get("jitter_max_s", 0.0)) for r in records)
    segments = [seg for r in records for seg in json.loads(r.attrs.get("segments", "[]"))]
    levels = sum(seg["kind"] == "level" for seg in segments)
    periodic = [seg for seg in segments if seg["kind"] == "periodic"]
    found = f"{levels} level(s)" + "".join(f", a periodic stretch ({seg['periods']} steady periods at "
                                            f"{seg['omega']:.4g} rad/s)" for seg in periodic)
    return (f"{len(records)} experiment(s), {n} samples on the grid; {dropped} empty row(s) dropped, "
            f"{filled} sample(s) interpolated, jitter up to {jitter * 1e3:.3g} ms, {found} found")
