"""Property-based robustness (issue 7): thousands of generated bad configs and damaged results files.

The only outcomes allowed:

* configs (``hwid.config.loads`` / ``parse`` and the CLI's ``hwid check``): success, or a
  :class:`~hwid.config.ConfigError` / exit code 2 whose message is one line naming the file;
* results files (``hwid.results.read_simulation`` (open_results + every dataset)): success, or
  :class:`~hwid.results.ResultsError`.

Generated configs are mutations of ``configs/paper.yaml``: keys deleted, renamed or misspelt, values
replaced by wrong types, NaN/inf, negatives, huge numbers, random strings, lists and mappings, nesting
changed; and character-level damage to its YAML text. Results files are ``hwid simulate`` outputs with
bytes flipped, overwritten or cut off.

Hypothesis settings come from the ``hwid`` profile (no deadline; ``HYPOTHESIS_PROFILE=hwid-long`` for
a longer hunt). The number of examples each test must run is asserted, so the README's figure holds.
"""
from __future__ import annotations

import contextlib
import copy
import io
import math
import os
import tempfile
from pathlib import Path

import h5py
import numpy as np
import pytest
import yaml
from hypothesis import HealthCheck, given, settings
from hypothesis import strategies as st

import rigs
from hwid import HwidError
from hwid import config as C
from hwid.cli import main
from hwid.model import from_config
from hwid.results import ResultsError, atomic_h5, read_simulation

settings.register_profile("hwid", deadline=None, derandomize=False, print_blob=True,
                          suppress_health_check=[HealthCheck.too_slow, HealthCheck.data_too_large])
settings.register_profile("hwid-long", parent=settings.get_profile("hwid"), max_examples=20_000)
settings.load_profile(os.environ.get("HYPOTHESIS_PROFILE", "hwid"))

SCALE = 10 if os.environ.get("HYPOTHESIS_PROFILE") == "hwid-long" else 1
N_DICT = 900 * SCALE         # structured mutations -> loads (YAML text) and parse (mapping)
N_TEXT = 700 * SCALE         # character-level damage to the YAML text -> loads
N_CLI = 400 * SCALE          # structured mutations -> hwid check FILE (the CLI path)
N_H5 = 400 * SCALE           # damaged simulation.h5 -> read_simulation

ROOT = Path(__file__).resolve().parents[1]
PAPER_TEXT = (ROOT / "configs" / "paper.yaml").read_text()
PAPER = yaml.safe_load(PAPER_TEXT)

# ---------------------------------------------------------------- strategies

KEY_NAMES = ["name", "seed", "sampling", "dt", "plant", "kind", "input_nonlinearity", "type", "slope_up",
             "slope_down", "d_plus", "d_minus", "linear", "num", "den", "delay", "output_nonlinearity",
             "polynomial", "pieces", "upper", "noise", "std", "ar", "protocols", "staircase", "levels_up",
             "levels_down", "hold", "sine", "amplitude", "frequencies", "periods", "lead_in_periods",
             "identification", "nonlinear", "degree", "max_degree", "method", "callable", "timeout"]

floats = st.one_of(
    st.floats(allow_nan=True, allow_infinity=True),
    st.sampled_from([0.0, -0.0, -1.0, 1e-300, 1e300, -1e300, 1.7976931348623157e308, 5e-324,
                     math.nan, math.inf, -math.inf, 0.5, -0.5, 1.0, 2.0]),
    st.floats(-10, 10),
)
ints = st.one_of(st.integers(-10, 10), st.integers(), st.sampled_from([0, -1, 2**63, 2**63 - 1, 10**40, -(10**40)]))
words = st.one_of(
    st.text(max_size=12),
    st.sampled_from(["", " ", "nan", ".inf", "1e-3", "0x10", "yes", "~", "null", "backlash", "external",
                     "hammerstein_wiener", "backlash_inverse", "paper", "nls", "../../x", "a" * 200,
                     "rigs:good", "rigs:wrong_signature", "no_such_module_hwid:f"]),
)
scalars = st.one_of(floats, ints, words, st.booleans(), st.none())
values = st.recursive(scalars, lambda inner: st.one_of(st.lists(inner, max_size=4),
                                                       st.dictionaries(st.sampled_from(KEY_NAMES) | st.text(max_size=6),
                                                                       inner, max_size=3)), max_leaves=8)


def _paths(node, prefix=()):
    """Every key path (tuples of keys / list indices) in a nested structure."""
    out = []
    if isinstance(node, dict):
        for k, v in node.items():
            out.append(prefix + (k,))
            out += _paths(v, prefix + (k,))
    elif isinstance(node, list):
        for i, v in enumerate(node):
            out.append(prefix + (i,))
            out += _paths(v, prefix + (i,))
    return out


def _parent(root, path):
    node = root
    for p in path[:-1]:
        node = node[p]
    return node


def _typo(data, key: str) -> str:
    if not key:
        return "x"
    i = data.draw(st.integers(0, len(key) - 1))
    how = data.draw(st.sampled_from(["drop", "double", "swap", "case", "char"]))
    if how == "drop":
        return key[:i] + key[i + 1:] or "x"
    if how == "double":
        return key[:i] + key[i] + key[i:]
    if how == "swap" and i + 1 < len(key):
        return key[:i] + key[i + 1] + key[i] + key[i + 2:]
    if how == "case":
        return key.upper()
    return key[:i] + data.draw(st.characters(codec="utf-8")) + key[i + 1:]


def mutate(data, base: dict) -> dict:
    """Apply 1-4 random structural mutations to a deep copy of ``base``."""
    d = copy.deepcopy(base)
    for _ in range(data.draw(st.integers(1, 4), label="n_mutations")):
        paths = _paths(d)
        if not paths:
            break
        path = paths[data.draw(st.integers(0, len(paths) - 1), label="path")]
        parent, last = _parent(d, path), path[-1]
        op = data.draw(st.sampled_from(["delete", "rename", "replace", "replace", "replace", "wrap",
                                        "unwrap", "add", "sibling-number"]), label="op")
        if op == "delete":
            del parent[last]
        elif op == "rename" and isinstance(parent, dict):
            new = data.draw(st.one_of(st.sampled_from(KEY_NAMES), st.text(max_size=10),
                                      st.builds(lambda: None).map(lambda _: _typo(data, str(last)))), label="new key")
            parent[new] = parent.pop(last)
        elif op == "replace":
            parent[last] = data.draw(values, label="value")
        elif op == "wrap":
            parent[last] = data.draw(st.sampled_from(["list", "dict"])) == "list" and [parent[last]] or {"value": parent[last]}
        elif op == "unwrap":
            v = parent[last]
            if isinstance(v, dict) and v:
                parent[last] = next(iter(v.values()))
            elif isinstance(v, list) and v:
                parent[last] = v[0]
        elif op == "add" and isinstance(parent[last], dict):
            parent[last][data.draw(st.sampled_from(KEY_NAMES) | st.text(max_size=8), label="add key")] = \
                data.draw(values, label="add value")
        elif op == "sibling-number" and isinstance(parent[last], (int, float)) and not isinstance(parent[last], bool):
            parent[last] = parent[last] * data.draw(st.sampled_from([-1, 0, 1e-9, 1e9, 1e300, math.nan]))
    return d


def _dump(d) -> str | None:
    try:
        return yaml.safe_dump(d, sort_keys=False, allow_unicode=True)
    except yaml.YAMLError:
        return None


def _check_clean_error(err: C.ConfigError, source: str) -> None:
    msg = str(err)
    assert "\n" not in msg, msg
    assert msg.startswith(f"{source}: "), msg
    assert len(msg) < 400, msg


def _check_valid(cfg: C.Config) -> None:
    """A config that passes must be usable: the model builds and its numbers are sane."""
    if cfg.plant.kind == "hammerstein_wiener":
        f = cfg.plant.input_nonlinearity
        assert f.slope_up > 0 and f.slope_down > 0 and f.d_plus > f.d_minus
        try:
            from_config(cfg.plant).normalised().to_dict()
        except HwidError:
            pass


# ---------------------------------------------------------------- configs

def test_mutated_configs_loads_and_parse():
    seen = []

    @settings(max_examples=N_DICT)
    @given(st.data())
    def prop(data):
        d = mutate(data, PAPER)
        seen.append(1)
        for how in ("parse", "loads"):
            try:
                if how == "parse":
                    cfg = C.parse(d, source_path="gen.yaml")
                else:
                    text = _dump(d)
                    if text is None:
                        continue
                    cfg = C.loads(text, source_path="gen.yaml")
            except C.ConfigError as err:
                _check_clean_error(err, "gen.yaml")
            else:
                _check_valid(cfg)

    prop()
    assert len(seen) >= N_DICT


def test_damaged_yaml_text():
    seen = []

    @settings(max_examples=N_TEXT)
    @given(st.data())
    def prop(data):
        text = PAPER_TEXT
        for _ in range(data.draw(st.integers(1, 3))):
            i = data.draw(st.integers(0, len(text)))
            j = data.draw(st.integers(i, min(len(text), i + 40)))
            how = data.draw(st.sampled_from(["cut", "delete", "insert", "duplicate-line", "replace"]))
            if how == "cut":
                text = text[:i]
            elif how == "delete":
                text = text[:i] + text[j:]
            elif how == "insert":
                text = text[:i] + data.draw(st.text(max_size=8) | st.sampled_from(
                    ["\t", ":", "- ", "{", "]", "&a ", "*a", "!!python/name:os.system ", "\n  ", "'", "\x00"])) + text[i:]
            elif how == "duplicate-line":
                lines = text.splitlines(keepends=True)
                if lines:
                    k = data.draw(st.integers(0, len(lines) - 1))
                    text = "".join(lines[:k + 1] + [lines[k]] + lines[k + 1:])
            else:
                text = text[:i] + data.draw(st.sampled_from(["nan", ".nan", "-.inf", "1e999", "-1", "0", "[]", "{}",
                                                             "x", "'1'", "true"])) + text[j:]
        seen.append(1)
        try:
            cfg = C.loads(text, source_path="damaged.yaml")
        except C.ConfigError as err:
            _check_clean_error(err, "damaged.yaml")
        else:
            _check_valid(cfg)

    prop()
    assert len(seen) >= N_TEXT


def test_mutated_configs_through_cli_check():
    seen, outcomes = [], {0: 0, 2: 0}
    with tempfile.TemporaryDirectory() as tmp:
        path = Path(tmp) / "gen.yaml"

        @settings(max_examples=N_CLI)
        @given(st.data())
        def prop(data):
            text = _dump(mutate(data, PAPER))
            if text is None:
                text = "name: [unterminated\n"
            path.write_text(text, encoding="utf-8")
            out, err = io.StringIO(), io.StringIO()
            with contextlib.redirect_stdout(out), contextlib.redirect_stderr(err):
                try:
                    main(["check", str(path)])
                except SystemExit as exc:
                    code = exc.code
                else:
                    code = None
            seen.append(1)
            assert code in (0, 2), (code, err.getvalue())
            outcomes[code] += 1
            if code == 0:
                assert ": OK (" in out.getvalue()
            else:
                lines = err.getvalue().splitlines()
                assert len(lines) == 1 and lines[0].startswith(f"hwid: error: {path}: "), err.getvalue()

        prop()
    assert len(seen) >= N_CLI
    assert outcomes[2] > 0


# ---------------------------------------------------------------- results files

@pytest.fixture(scope="module")
def simulation_bytes(tmp_path_factory) -> tuple[bytes, C.Config]:
    d = tmp_path_factory.mktemp("prop_sim")
    cfg = rigs.write(d / "small.yaml", rigs.small(**{"protocols.sine.frequencies": [1.0]}))
    with pytest.raises(SystemExit) as exc:
        main(["simulate", str(cfg), "--out", str(d / "out")])
    assert exc.value.code == 0
    return (d / "out" / "simulation.h5").read_bytes(), C.load(cfg)


def _damage_bytes(data, b: bytearray) -> None:
    for _ in range(data.draw(st.integers(1, 3))):
        how = data.draw(st.sampled_from(["truncate", "flip", "flip", "overwrite", "zero"]))
        pos = data.draw(st.one_of(st.integers(0, 4095), st.integers(0, max(len(b) - 1, 0))))
        if how == "truncate":
            del b[pos:]
        elif how == "flip" and pos < len(b):
            b[pos] ^= 1 << data.draw(st.integers(0, 7))
        elif how in ("overwrite", "zero") and pos < len(b):
            n = data.draw(st.integers(1, 64))
            fill = bytes(n) if how == "zero" else data.draw(st.binary(min_size=n, max_size=n))
            b[pos:pos + n] = fill[: len(b) - pos]


JUNK = st.one_of(st.integers(-5, 5), st.floats(allow_nan=True), st.text(st.characters(codec="utf-8", exclude_characters="\x00"), max_size=5), st.just(np.zeros((2, 2))),
                 st.just(np.array([], float)), st.just(np.array([b"a", b"b"])), st.just(np.arange(3)))


def _damage_structure(data, f: h5py.File) -> None:
    """hwid-shaped but wrong content: objects deleted or swapped, attributes of the wrong type."""
    names: list[str] = []
    f.visit(names.append)
    for _ in range(data.draw(st.integers(1, 3))):
        how = data.draw(st.sampled_from(["delete", "replace-dataset", "attr", "del-attr", "root-attr", "add-junk"]))
        live = [n for n in names if n in f]
        if how in ("delete", "replace-dataset", "attr", "del-attr") and not live:
            continue
        name = data.draw(st.sampled_from(live)) if live else ""
        if how == "delete":
            del f[name]
        elif how == "replace-dataset":
            del f[name]
            f[name] = data.draw(JUNK)
        elif how == "attr":
            keys = list(f[name].attrs) or ["dt"]
            f[name].attrs[data.draw(st.sampled_from(keys))] = data.draw(JUNK)
        elif how == "del-attr" and len(f[name].attrs):
            del f[name].attrs[data.draw(st.sampled_from(list(f[name].attrs)))]
        elif how == "root-attr":
            key = data.draw(st.sampled_from(["hwid_kind", "hwid_format", "config_sha256", "dt", "seed", "config"]))
            if data.draw(st.booleans()) and key in f.attrs:
                del f.attrs[key]
            else:
                f.attrs[key] = data.draw(JUNK)
        elif isinstance(f.get("experiments"), h5py.Group):
            g, key = f["experiments"], data.draw(st.text("abc_", min_size=1, max_size=4))
            if key in g:
                del g[key]
            g[key] = data.draw(JUNK)


def test_damaged_results_files(simulation_bytes):
    """Byte damage (caught by the checksum or by HDF5) and structural damage written by hwid's own
    writer (so the checksum is valid and the content checks must catch it)."""
    seen, outcomes = [], {"ok": 0, "error": 0}
    simulation_bytes, cfg = simulation_bytes
    with tempfile.TemporaryDirectory() as tmp:
        path = Path(tmp) / "simulation.h5"

        @settings(max_examples=N_H5)
        @given(st.data())
        def prop(data):
            path.write_bytes(simulation_bytes)
            if data.draw(st.booleans(), label="structural"):
                with atomic_h5(path, "a") as f:
                    _damage_structure(data, f)
            else:
                b = bytearray(simulation_bytes)
                _damage_bytes(data, b)
                path.write_bytes(bytes(b))
            seen.append(1)
            try:
                read_simulation(path, cfg=cfg if data.draw(st.booleans(), label="with cfg") else None)
            except ResultsError as err:
                assert "\n" not in str(err) and str(err).startswith(str(path)), str(err)
                outcomes["error"] += 1
            else:
                outcomes["ok"] += 1

        prop()
    assert len(seen) >= N_H5
    assert outcomes["error"] > 0
