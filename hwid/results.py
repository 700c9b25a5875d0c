"""HDF5 results: one writer, atomic files, provenance in attributes.

Every file is written to ``NAME.tmp`` in the same directory and moved into place with
``os.replace`` only once complete, so an interrupted run leaves the old file or the new one, never a
broken one. Root attributes of every file:

=================  ===========================================================
``hwid_kind``      ``simulation`` | ``nonlinear`` | ``linear`` | ``batch`` | ...
``hwid_format``    integer layout version (:data:`FORMAT`)
``hwid_version``   package version that wrote it
``config``         the config's YAML text; ``config_sha256`` its SHA-256
``seed``, ``dt``   the run's root seed and sample time
``argv``           the command line; ``created`` ISO time (UTC)
=================  ===========================================================
"""
from __future__ import annotations

import contextlib
import datetime as _dt
import json
import math
import os
import sys
from pathlib import Path
from typing import Any, Iterator

import h5py
import numpy as np

from hwid import HwidError, __version__
from hwid.identify.result import HistoryResult, LinearResult, NonlinearResult, WholeResult, plain
from hwid.plant import Record
from hwid.rundir import NONLINEAR

FORMAT = 1
LIBVER = ("v110", "latest")   # HDF5 >= 1.10 object layout: checksummed metadata
USERBLOCK = 512               # bytes before the HDF5 superblock, ignored by HDF5: hwid's checksum
_STAMP = b"hwid-sha256:"


class ResultsError(HwidError):
    """A results file that is missing, broken, foreign, of the wrong kind or from another config."""


@contextlib.contextmanager
def atomic_h5(path: str | Path, mode: str = "w") -> Iterator[h5py.File]:
    """Open ``path.tmp`` for writing and rename it to ``path`` when the block completes.

    Before the rename the SHA-256 of the HDF5 bytes is written into the file's user block (the
    first :data:`USERBLOCK` bytes, which HDF5 skips), so :func:`open_results` notices a file that was
    changed or cut off afterwards before the HDF5 library parses it (a damaged HDF5 file can make
    the library loop forever)."""
    path = Path(path)
    path.parent.mkdir(parents=True, exist_ok=True)
    tmp = path.with_name(path.name + ".tmp")
    with contextlib.suppress(FileNotFoundError):
        tmp.unlink()            # left by a writer that was killed: never build on it
    if mode == "a" and path.exists():
        import shutil
        shutil.copyfile(path, tmp)
    try:
        create = not tmp.exists()
        kw = {"userblock_size": USERBLOCK} if create else {}
        with h5py.File(tmp, "a" if mode == "a" else "w", libver=LIBVER, **kw) as f:
            yield f
            f.flush()
            stamp = f.userblock_size >= USERBLOCK
        with open(tmp, "rb+") as fh:
            if stamp:
                fh.seek(USERBLOCK)
                digest = _sha256(fh)
                fh.seek(0)
                fh.write((_STAMP + digest.encode() + b"\n").ljust(USERBLOCK, b"\0"))
            fh.flush()
            os.fsync(fh.fileno())
        os.replace(tmp, path)
        _fsync_dir(path.parent)
    except BaseException:
        with contextlib.suppress(FileNotFoundError):
            tmp.unlink()
        raise


def _sha256(fh) -> str:
    import hashlib
    h = hashlib.sha256()
    for chunk in iter(lambda: fh.read(1 << 20), b""):
        h.update(chunk)
    return h.hexdigest()


def verify_checksum(path: str | Path) -> bool | None:
    """True if ``path`` carries hwid's checksum and it matches, False if it does not match, None if
    the file has no hwid checksum (not written by :func:`atomic_h5`)."""
    with open(path, "rb") as fh:
        head = fh.read(USERBLOCK + 8)
        if not head.startswith(_STAMP):
            # a 512-byte user block without the stamp: hwid's own file with a damaged head
            return False if head[USERBLOCK:] == b"\x89HDF\r\n\x1a\n" else None
        fh.seek(USERBLOCK)
        want = head[len(_STAMP):len(_STAMP) + 64].decode("ascii", errors="replace")
        return _sha256(fh) == want


def _fsync_dir(directory: Path) -> None:
    """Make the rename itself durable (POSIX); harmless where directories cannot be opened."""
    with contextlib.suppress(OSError):
        fd = os.open(directory, os.O_RDONLY)
        try:
            os.fsync(fd)
        finally:
            os.close(fd)


def write_provenance(f: h5py.File, kind: str, cfg=None, seed: Any = None, extra: dict | None = None) -> None:
    f.attrs["hwid_kind"] = kind
    f.attrs["hwid_format"] = FORMAT
    f.attrs["hwid_version"] = __version__
    f.attrs["argv"] = " ".join(sys.argv)
    f.attrs["created"] = _dt.datetime.now(_dt.timezone.utc).isoformat(timespec="seconds")
    if cfg is not None:
        f.attrs["config"] = cfg.source_text
        f.attrs["config_sha256"] = cfg.sha256
        f.attrs["config_name"] = cfg.name
        f.attrs["dt"] = cfg.sampling.dt
        f.attrs["seed"] = cfg.seed if seed is None else seed
    for k, v in (extra or {}).items():
        f.attrs[k] = v


def write_dict(group: h5py.Group, data: dict) -> None:
    """Store a plain-data dict: arrays and lists of numbers as datasets, scalars and strings as
    attributes, nested dicts as subgroups, anything else as a JSON attribute."""
    for key, val in data.items():
        key = str(key)
        if isinstance(val, dict):
            write_dict(group.require_group(key), val)
        elif isinstance(val, np.ndarray) or (isinstance(val, (list, tuple)) and val and
                                              all(isinstance(x, (int, float, np.number)) and not isinstance(x, bool) for x in np.ravel(np.asarray(val, dtype=object)))):
            arr = np.asarray(val, dtype=float) if not isinstance(val, np.ndarray) else val
            if key in group:
                del group[key]
            group.create_dataset(key, data=arr, compression="gzip" if arr.size > 4096 else None)
        elif val is None:
            group.attrs[key] = "null"
            group.attrs[key + "__json"] = True
        elif isinstance(val, (str, int, float, bool, np.number, np.bool_)):
            group.attrs[key] = val
        else:
            group.attrs[key] = json.dumps(val)
            group.attrs[key + "__json"] = True


_H5_ERRORS = (OSError, KeyError, ValueError, TypeError, RuntimeError, AttributeError, OverflowError)


def read_dict(group: h5py.Group) -> dict:
    """Inverse of :func:`write_dict`."""
    out: dict = {}
    for key, val in group.attrs.items():
        if key.endswith("__json"):
            continue
        if group.attrs.get(key + "__json", False):
            out[key] = json.loads(val)
        elif isinstance(val, np.generic):
            out[key] = val.item()
        else:
            out[key] = val
    for key, item in group.items():
        out[key] = read_dict(item) if isinstance(item, h5py.Group) else item[()]
    return out


def write_records(group: h5py.Group, records, truth_tail: dict | None = None) -> None:
    """One subgroup per experiment: ``u, y`` (whole) and, for simulated plants, ``v, w, x`` (ground
    truth) and ``z``.

    ``truth_tail`` maps experiment names to a sample count: for those, only the last samples of
    ``v, w, x, z`` are stored (dataset attribute ``offset`` = index of the first stored sample), which
    keeps files of long periodic experiments small; :func:`read_records` pads the rest with NaN.
    The measured ``u, y`` are always stored whole."""
    for r in records:
        g = group.require_group(r.name)
        tail = (truth_tail or {}).get(r.name)
        for key in ("u", "y", "v", "w", "x", "z"):
            arr = getattr(r, key)
            if arr is not None:
                if key in g:
                    del g[key]
                arr = np.asarray(arr, float)
                offset = 0
                if key not in ("u", "y") and tail is not None and arr.size > tail:
                    offset = arr.size - int(tail)
                    arr = arr[offset:]
                ds = g.create_dataset(key, data=arr, compression="gzip", shuffle=True)
                if offset:
                    ds.attrs["offset"] = offset
                if key in ("v", "w", "x"):
                    ds.attrs["ground_truth"] = True
        g.attrs["dt"] = r.dt
        g.attrs["n"] = r.u.size
        for k, v in r.attrs.items():
            g.attrs[k] = v if isinstance(v, (str, int, float, bool)) else json.dumps(v)


def read_padded(ds, n: int) -> np.ndarray:
    """A dataset as float64; one stored from ``offset`` on is NaN-padded to ``n`` samples."""
    data = np.asarray(ds[()], dtype=float)
    offset = int(ds.attrs.get("offset", 0))
    if offset and n == offset + data.size:
        full = np.full(n, np.nan)
        full[offset:] = data
        return full
    return data


def read_records(group: h5py.Group, keys=("u", "y", "v", "w", "x", "z"), names=None) -> dict:
    """Inverse of :func:`write_records`; a damaged group raises :class:`ResultsError`.

    ``keys`` (which must hold ``y``) limits the datasets read, the others are None; ``names``
    limits the experiments read (default: all). Readers of a few signals of long records (the
    report) use them; ``u`` is checked against ``y`` when it is read."""
    out = {}
    where = f"{group.file.filename}:{group.name}"
    try:
        for name, g in group.items():
            if names is not None and name not in names:
                continue
            where = f"{group.file.filename}:{g.name}"
            kw = {k: (read_padded(g[k], int(g.attrs.get("n", 0))) if k in keys and k in g else None)
                  for k in ("u", "y", "v", "w", "x", "z")}
            attrs = {k: v for k, v in g.attrs.items() if k not in ("dt", "n")}
            r = out[name] = Record(name, float(g.attrs["dt"]), attrs=attrs, **kw)
            if r.y is None or r.y.ndim != 1 or ("u" in keys and (r.u is None or r.u.shape != r.y.shape)):
                raise ResultsError(f"{where}: experiment without matching one-dimensional 'u' and 'y' datasets")
            if not (math.isfinite(r.dt) and r.dt > 0):
                raise ResultsError(f"{where}: sample time dt = {r.dt} is not a positive number")
    except ResultsError:
        raise
    except _H5_ERRORS as err:
        raise ResultsError(f"{where}: cannot be read ({type(err).__name__}: {err})") from None
    return out


def read_simulation(path: str | Path, cfg=None) -> tuple[dict, dict | None]:
    """The experiments (``{name: Record}``) and the stored truth (or None) of a ``simulation.h5``.

    Checks the file with :func:`open_results` and reads every dataset; anything damaged raises
    :class:`ResultsError` (one line), never an h5py error."""
    with open_results(path, "simulation", cfg) as f:
        try:
            group = f["experiments"]
        except _H5_ERRORS:
            raise ResultsError(f"{path}: has no readable 'experiments' group (damaged file)") from None
        records = read_records(group)
        try:
            truth = read_dict(f["truth"]) if "truth" in f else None
        except _H5_ERRORS as err:
            raise ResultsError(f"{path}:/truth: cannot be read ({type(err).__name__}: {err})") from None
    return records, truth


def open_results(path: str | Path, kind: str | tuple[str, ...], cfg=None) -> h5py.File:
    """Open an hwid results file for reading and check it is what the caller expects.

    Raises :class:`ResultsError` (one line) when it is missing, not HDF5, not written by hwid, of a
    newer layout, of another kind, or (when ``cfg`` is given) written for a different config."""
    path = Path(path)
    kinds = (kind,) if isinstance(kind, str) else kind
    if not path.exists():
        raise ResultsError(f"{path}: no such file")
    if path.is_dir():
        raise ResultsError(f"{path}: is a directory, expected an hwid results file")
    try:
        intact = verify_checksum(path)
    except OSError as err:
        raise ResultsError(f"{path}: cannot be read ({err.strerror or type(err).__name__})") from None
    if intact is False:
        raise ResultsError(f"{path}: damaged (its checksum does not match: cut off or changed after hwid wrote it)")
    try:
        f = h5py.File(path, "r")
    except (OSError, ValueError, RuntimeError):
        raise ResultsError(f"{path}: not a readable HDF5 file (truncated or foreign)") from None
    try:
        try:
            got = f.attrs.get("hwid_kind")
            fmt = f.attrs.get("hwid_format", -1)
            fmt = int(fmt) if np.ndim(fmt) == 0 else -1
            stored_hash = f.attrs.get("config_sha256")
        except (OSError, ValueError, TypeError, KeyError, RuntimeError):
            raise ResultsError(f"{path}: its hwid attributes cannot be read (corrupt file)") from None
        if got is None:
            raise ResultsError(f"{path}: not written by hwid (no hwid_kind attribute)")
        got = got.decode(errors="replace") if isinstance(got, bytes) else got
        if not isinstance(got, str):
            raise ResultsError(f"{path}: not written by hwid (its hwid_kind attribute is not a name)")
        if fmt != FORMAT:
            raise ResultsError(f"{path}: written with results format {fmt}, this hwid reads format {FORMAT}")
        if got not in kinds:
            raise ResultsError(f"{path}: is a {got!r} file, expected {' or '.join(repr(k) for k in kinds)}")
        if isinstance(stored_hash, bytes):
            stored_hash = stored_hash.decode(errors="replace")
        if cfg is not None and stored_hash is not None and (not isinstance(stored_hash, str) or stored_hash != cfg.sha256):
            raise ResultsError(f"{path}: was written for a different config than {cfg.source_path} "
                               f"(config hash differs); rerun with the matching config")
    except ResultsError:
        f.close()
        raise
    return f


def write_json(path: str | Path, data: dict) -> None:
    """Atomic JSON write (``--json FILE``)."""
    path = Path(path)
    path.parent.mkdir(parents=True, exist_ok=True)
    tmp = path.with_name(path.name + ".tmp")
    tmp.write_text(json.dumps(data, indent=2, default=_json_default) + "\n")
    os.replace(tmp, path)


def write_text(path: str | Path, text: str) -> Path:
    """Atomic text write (a model file such as a diagnosis's ``corrected.yaml``): ``PATH.tmp``,
    flushed to disk, then renamed over ``PATH``."""
    path = Path(path)
    path.parent.mkdir(parents=True, exist_ok=True)
    tmp = path.with_name(path.name + ".tmp")
    with open(tmp, "w", encoding="utf-8") as fh:
        fh.write(text)
        fh.flush()
        os.fsync(fh.fileno())
    os.replace(tmp, path)
    return path


def _json_default(o):
    if isinstance(o, (np.ndarray, np.generic)):
        return plain(o)
    raise TypeError(f"not JSON serialisable: {type(o).__name__}")


# ------------------------------------------------------------------------------- simulation.h5

def write_simulation(path: str | Path, cfg, records, truth: dict | None = None) -> Path:
    """Write ``simulation.h5`` (``hwid_kind = "simulation"``): group ``experiments`` (one subgroup a
    record, :func:`write_records`) and, for a simulated plant, group ``truth`` (the true model and
    its normalised form, eqs. 4a-c)."""
    path = Path(path)
    with atomic_h5(path) as f:
        write_provenance(f, "simulation", cfg)
        write_records(f.require_group("experiments"), records)
        if truth is not None:
            write_dict(f.require_group("truth"), truth)
    return path


# -------------------------------------------------------------------------- nonlinear.h5 (stage 1)

def write_nonlinear(path: str | Path, cfg, result: NonlinearResult, records=()) -> Path:
    """Write ``nonlinear.h5`` (``hwid_kind = "nonlinear"``; ``path`` may be its directory): group
    ``result`` (the plain data of :meth:`NonlinearResult.to_dict`) and group ``experiments`` (the
    staircase records)."""
    path = Path(path)
    out = path if path.suffix == ".h5" else path / NONLINEAR
    d = result.to_dict()
    fit = d.pop("fit")
    for key in [k for k in d if k.endswith("_ci")]:
        d[key] = _nan_for_none(d[key])
    with atomic_h5(out) as f:
        write_provenance(f, "nonlinear", cfg)
        g = f.require_group("result")
        write_dict(g, {k: v for k, v in d.items() if k not in ("warnings", "param_names")})
        g.attrs["warnings"] = json.dumps(list(result.warnings))
        g.attrs["param_names"] = json.dumps(list(result.param_names))
        g.attrs["fit"] = json.dumps(fit, default=lambda o: o.tolist() if hasattr(o, "tolist") else str(o))
        if records:
            write_records(f.require_group("experiments"), records)
    return out


def _nan_for_none(interval):
    """An interval (or a list of them) for a numeric dataset: ``[NaN, NaN]`` stands for "no
    interval" (None: fixed by the normalisation, or undetermined); read back as None by
    :func:`hwid.identify.result.stored_interval`."""
    if interval is None:
        return [np.nan, np.nan]
    if interval and isinstance(interval[0], (list, tuple)) or (interval and interval[0] is None):
        return [_nan_for_none(v) for v in interval]
    return interval


def read_nonlinear(path: str | Path, cfg=None) -> NonlinearResult:
    """The :class:`NonlinearResult` of ``nonlinear.h5`` (or of a directory holding it). An interval
    stored as ``[NaN, NaN]`` reads as None; in a file written before, h_bar's constant and
    ``slope_up`` (``[0, 0]``, ``[1, 1]``) read as None too (:meth:`NonlinearResult.from_dict`)."""
    path = Path(path)
    if path.is_dir():
        path = path / NONLINEAR
    with open_results(path, "nonlinear", cfg) as f:
        if "result" not in f:
            raise ResultsError(f"{path}: holds no stage-1 result")
        g = f["result"]
        d = read_dict(g)
        d["warnings"] = json.loads(g.attrs["warnings"])
        d["param_names"] = json.loads(g.attrs["param_names"])
        d["fit"] = json.loads(g.attrs["fit"])
    return NonlinearResult.from_dict(d)


def read_experiments(path: str | Path, kind: str | tuple[str, ...], cfg=None) -> dict:
    """The ``experiments`` group of any hwid results file, as ``{name: Record}`` (empty if none)."""
    with open_results(path, kind, cfg) as f:
        return read_records(f["experiments"]) if "experiments" in f else {}


# ----------------------------------------------------------------------------- linear.h5 (stage 2)

def write_linear(path: str | Path, cfg, result: LinearResult, records=()) -> Path:
    """Write ``linear.h5`` (``hwid_kind = "linear"``): group ``result`` (:meth:`LinearResult.to_dict`
    with the per-frequency harmonic fits) and the sine records, whose ground-truth internals keep
    only their last two periods (they are periodic)."""
    path = Path(path)
    with atomic_h5(path) as f:
        write_provenance(f, "linear", cfg)
        write_dict(f.require_group("result"), result.to_dict(full=True))
        if records:
            tail = {r.name: int(np.ceil(2 * 2 * np.pi / float(r.attrs["omega"]) / r.dt)) + 2
                    for r in records if "omega" in r.attrs}
            write_records(f.require_group("experiments"), records, truth_tail=tail)
    return path


def read_linear(path: str | Path, cfg=None) -> LinearResult:
    """The :class:`LinearResult` of ``linear.h5``."""
    with open_results(path, "linear", cfg) as f:
        if "result" not in f:
            raise ResultsError(f"{path}: has no 'result' group (an interrupted write?)")
        d = read_dict(f["result"])
    harm = d.get("harmonics", {})
    harmonics = tuple(harm[k] for k in sorted(harm, key=int))
    arr = lambda k: np.asarray(d[k], float)  # noqa: E731
    par = d.get("parametric", {}) or {}
    return LinearResult(arr("frequencies"), float(d["amplitude"]), arr("gain"), arr("gain_ci").reshape(-1, 2),
                        arr("phase"), arr("phase_ci").reshape(-1, 2), arr("cov").reshape(-1, 2, 2),
                        str(d["method"]), arr("crlb_gain"), arr("crlb_phase"), par, harmonics,
                        np.asarray(d["extrapolated"], bool), tuple(d.get("warnings", ()) or ()),
                        str(d.get("precompensator", "auto")))


# --------------------------------------------------------------------------------- diagnosis.h5

def write_diagnosis(path: str | Path, cfg, summary: dict, experiments: list[dict]) -> Path:
    """Write ``diagnosis.h5`` (``hwid_kind = "diagnosis"``): the JSON summary as the root attribute
    ``summary``, and one group per experiment in the order run (root attribute
    ``experiment_order``) with datasets ``u, y, y_model, mask, region`` and, where present, ``z``
    and ``y_after`` (validation experiments), attributes ``dt, kind, role, repeat_of, variable`` and,
    where the verdict's effect is in ``corrected.yaml``, ``start_after`` (JSON: the ``gear``,
    ``rest`` and ``position`` that model starts from to give ``y_after``)."""
    path = Path(path)
    with atomic_h5(path) as f:
        write_provenance(f, "diagnosis", cfg)
        f.attrs["summary"] = json.dumps(summary, default=_json_default)
        g = f.require_group("experiments")
        for e in experiments:
            h = g.require_group(e["name"])
            for key in ("u", "y", "y_model", "mask", "region", "z", "y_after"):
                if e.get(key) is not None:
                    arr = np.asarray(e[key])
                    h.create_dataset(key, data=arr.astype(np.int8) if arr.dtype == bool else arr,
                                     compression="gzip", shuffle=True)
            h.attrs["dt"] = e["dt"]
            h.attrs["kind"] = e["kind"]
            h.attrs["role"] = e["role"]
            h.attrs["repeat_of"] = e.get("repeat_of") or ""
            h.attrs["variable"] = json.dumps(e["variable"])
            if e.get("start_after") is not None:
                h.attrs["start_after"] = json.dumps(e["start_after"])
        f.attrs["experiment_order"] = json.dumps([e["name"] for e in experiments])
    return path


def read_diagnosis(path: str | Path) -> dict:
    """Plain data of ``diagnosis.h5``: ``summary`` (the JSON summary) and ``experiments``, a dict
    name -> {t, u, y, y_model, y_after (validation only), z, mask, region, dt, kind, role,
    repeat_of, variable, start_after (where written)}, in the order they were run."""
    path = Path(path)
    with open_results(path, "diagnosis") as f:
        try:
            summary = json.loads(f.attrs["summary"])
            order = json.loads(f.attrs["experiment_order"])
            exps = {}
            for name in order:
                g = f["experiments"][name]
                dt = float(g.attrs["dt"])
                e = {k: np.asarray(g[k][()]) for k in g.keys()}
                e["mask"] = e["mask"].astype(bool)
                e["t"] = np.arange(e["u"].size) * dt
                e.update({"dt": dt, "kind": str(g.attrs["kind"]), "role": str(g.attrs["role"]),
                          "repeat_of": str(g.attrs["repeat_of"]) or None,
                          "variable": json.loads(g.attrs["variable"])})
                if "start_after" in g.attrs:
                    e["start_after"] = json.loads(g.attrs["start_after"])
                exps[name] = e
        except (KeyError, ValueError, OSError, TypeError) as err:
            raise ResultsError(f"{path}: not a complete diagnosis ({type(err).__name__}: {err})") from None
    return {"summary": summary, "experiments": exps}


# ------------------------------------------------------------------------------------- batch.h5

def write_batch(path: str | Path, cfg, runs: int, points: list[dict]) -> Path:
    """Write ``batch.h5`` (``hwid_kind = "batch"``): one group ``points/p<i>`` a sweep point with
    attributes ``overrides`` (JSON), ``n_runs``, ``n_errors`` (and ``errors``, the first 20), group
    ``runs`` (one dataset a per-run column: ``run``, ``seconds``, ..., every estimate) and group
    ``summary`` (one subgroup an estimate, its statistics as attributes).

    ``points``: dicts with ``overrides``, ``columns`` (name -> array), ``summary`` (name -> dict)
    and ``errors`` (list of strings)."""
    path = Path(path)
    with atomic_h5(path) as f:
        write_provenance(f, "batch", cfg, extra={"runs": runs,
                                                 "sweeps": json.dumps([p["overrides"] for p in points])})
        for i, p in enumerate(points):
            g = f.create_group(f"points/p{i}")
            g.attrs["overrides"] = json.dumps(p["overrides"])
            g.attrs["n_runs"] = len(p["columns"]["run"])
            g.attrs["n_errors"] = len(p["errors"])
            runs_g = g.create_group("runs")
            for name, col in p["columns"].items():
                runs_g.create_dataset(name, data=np.asarray(col))
            sg = g.create_group("summary")
            for name, s in p["summary"].items():
                sg.create_group(name).attrs.update(s)
            if p["errors"]:
                g.attrs["errors"] = json.dumps(p["errors"][:20])
    return path


def read_batch_summary(path: str | Path) -> dict:
    """``{"sweep_keys": [...], "points": [{"overrides", "n_runs", "n_errors", "stats": {name: {...}}}]}``."""
    with open_results(path, "batch") as f:
        points = []
        for name in sorted(f["points"], key=lambda s: int(s[1:])):
            g = f["points"][name]
            stats = {n: {k: (v.item() if hasattr(v, "item") else v) for k, v in g["summary"][n].attrs.items()}
                     for n in g["summary"]}
            points.append({"overrides": json.loads(g.attrs["overrides"]), "n_runs": int(g.attrs["n_runs"]),
                           "n_errors": int(g.attrs.get("n_errors", 0)), "stats": stats})
    keys = list(points[0]["overrides"]) if points else []
    return {"sweep_keys": keys, "points": points}


def read_batch_runs(path: str | Path, point: int = 0) -> dict[str, np.ndarray]:
    """The per-run columns of one sweep point of ``batch.h5``."""
    with open_results(path, "batch") as f:
        g = f[f"points/p{point}/runs"]
        return {k: g[k][()] for k in g}


# ----------------------------------------------------------------------------------- compare.h5

def write_compare(path: str | Path, cfg, summary: dict, records, simulated: dict) -> Path:
    """Write ``compare.h5`` (``hwid_kind = "compare"``): the JSON summary as the root attribute
    ``summary``, and the compared experiments (:func:`write_records`) each with a dataset
    ``y_model`` (the model's free run from the estimated initial state)."""
    path = Path(path)
    with atomic_h5(path) as f:
        write_provenance(f, "compare", cfg)
        f.attrs["summary"] = json.dumps(summary, default=_json_default)
        group = f.require_group("experiments")
        write_records(group, records)
        for name, y_model in simulated.items():
            group[name].create_dataset("y_model", data=np.asarray(y_model, float), compression="gzip", shuffle=True)
    return path


def read_compare(path: str | Path) -> dict:
    """``{"summary": ..., "experiments": {name: Record}, "y_model": {name: array}}`` of ``compare.h5``."""
    with open_results(path, "compare") as f:
        try:
            summary = json.loads(f.attrs["summary"])
            records = read_records(f["experiments"])
            y_model = {name: np.asarray(f["experiments"][name]["y_model"][()], float) for name in records}
        except (KeyError, ValueError, OSError, TypeError) as err:
            raise ResultsError(f"{path}: not a complete comparison ({type(err).__name__}: {err})") from None
    return {"summary": summary, "experiments": records, "y_model": y_model}


# ---------------------------------------------------------------------------- whole.h5 (whole model)

def _write_json_result(path: str | Path, cfg, kind: str, result, attrs: dict | None = None) -> Path:
    """A results file whose payload is one result's plain data (``result.to_dict()``) as the root
    attribute ``result`` (JSON), with ``attrs`` as root attributes."""
    path = Path(path)
    with atomic_h5(path) as f:
        write_provenance(f, kind, cfg)
        f.attrs["result"] = json.dumps(result.to_dict(), default=_json_default)
        for key, val in (attrs or {}).items():
            f.attrs[key] = val
    return path


def _read_json_result(path: str | Path, kind: str, cls, what: str, cfg=None):
    with open_results(path, kind, cfg) as f:
        try:
            return cls.from_dict(json.loads(f.attrs["result"]))
        except (KeyError, ValueError, TypeError) as err:
            raise ResultsError(f"{path}: not a complete {what} ({type(err).__name__}: {err})") from None


def write_whole(path: str | Path, cfg, result: WholeResult, role: str = "model") -> Path:
    """Write ``whole.h5`` (``hwid_kind = "whole"``): the whole-model fit's plain data
    (:meth:`WholeResult.to_dict`, every fitted block included) as the root attribute ``result``
    (JSON); ``role``: ``"model"`` where it is the run's model, ``"beside"`` where it was fitted
    beside the two stages, whose model the run's is."""
    return _write_json_result(path, cfg, "whole", result, {"role": role})


def whole_role(path: str | Path) -> str:
    """``whole.h5``'s role (:func:`write_whole`); ``"beside"`` for a file written without one (the
    stages' model was then the run's wherever there were stages)."""
    with open_results(path, "whole") as f:
        return str(f.attrs.get("role", "beside"))


def read_whole(path: str | Path, cfg=None) -> WholeResult:
    """The :class:`WholeResult` of ``whole.h5``."""
    return _read_json_result(path, "whole", WholeResult, "whole-model result", cfg)


def write_history(path: str | Path, cfg, result: HistoryResult) -> Path:
    """Write ``history.h5`` (``hwid_kind = "history"``): stage 1 from a recorded history, its plain
    data (:meth:`HistoryResult.to_dict`) as the root attribute ``result`` (JSON)."""
    return _write_json_result(path, cfg, "history", result)


def read_history(path: str | Path, cfg=None) -> HistoryResult:
    """The :class:`HistoryResult` of ``history.h5``."""
    return _read_json_result(path, "history", HistoryResult, "stage-1 history result", cfg)


