"""Bad input gets one clear line, exit code 2, no traceback (issue 7; issue 2's bad-config list).

Every case goes through the real command line (``hwid.cli.main``, a few through the installed
``hwid`` script in a subprocess) and states the part of the message it must produce. Config
problems must name the file and the key path: ``hwid: error: FILE: key.path: reason``.
Results files are checked through :func:`hwid.results.open_results`, which every command that reads
``simulation.h5`` / ``nonlinear.h5`` / ``linear.h5`` uses.
"""
from __future__ import annotations

import os
import shutil
import subprocess
import sys
from pathlib import Path

import h5py
import numpy as np
import pytest

import rigs
from hwid import config as C
from hwid.cli import main
from hwid.results import FORMAT, ResultsError, atomic_h5, open_results, read_records, read_simulation

D = rigs.DELETE
HWID = Path(sys.executable).with_name("hwid")


def run_cli(argv: list[str], capsys) -> tuple[int, str, str]:
    """Run ``hwid ARGV`` in-process; any exception other than SystemExit is a traceback escaping."""
    with pytest.raises(SystemExit) as exc:
        main([str(a) for a in argv])
    out, err = capsys.readouterr()
    return exc.value.code, out, err


def assert_one_line_error(code, err, *fragments):
    assert code == 2, f"exit code {code}, stderr: {err!r}"
    assert "Traceback" not in err
    lines = err.strip("\n").split("\n")
    assert len(lines) == 1, f"expected one line, got: {err!r}"
    assert lines[0].startswith("hwid: error: "), lines[0]
    for frag in fragments:
        assert frag in lines[0], f"{frag!r} not in {lines[0]!r}"
    return lines[0]


# ---------------------------------------------------------------- configs: (id, config, key path, message part)
# ``config`` is a dict of changes to tests/rigs.SMALL, or the raw YAML text; key "" = YAML-level.

NESTED = "a: " + "[" * 3000 + "]" * 3000 + "\n"

CONFIG_CASES = [
    # malformed YAML
    ("yaml-unclosed-bracket", "name: x\nsampling: {dt: [0.05\n", "line 3", "malformed YAML"),
    ("yaml-bad-indent", "name: x\n  sampling: 1\n", "line 2", "mapping values are not allowed"),
    ("yaml-tab", "name: x\n\tsampling: 1\n", "line 2", "cannot start any token"),
    ("yaml-duplicate-key", "name: a\nname: b\n", "line 2", "key 'name' is given twice (first on line 1)"),
    ("yaml-empty-file", "", "", "the config must be a YAML mapping of keys, got NoneType"),
    ("yaml-top-level-list", "- 1\n- 2\n", "", "the config must be a YAML mapping of keys, got list"),
    ("yaml-python-tag", "name: !!python/object/apply:os.system ['true']\n", "line 1",
     "could not determine a constructor for the tag"),
    ("yaml-nested-too-deeply", NESTED, "YAML", "nested too deeply"),
    ("yaml-undefined-alias", "name: *x\n", "line 1", "undefined alias"),
    # unknown / misspelt keys, with the nearest valid one
    ("misspelt-noise-std", {"plant.noise.sdt": 0.01}, "plant.noise.sdt", "unknown key 'sdt' (did you mean 'std'?)"),
    ("misspelt-top-level", {"smapling": {"dt": 0.05}}, "smapling", "did you mean 'sampling'?"),
    ("misspelt-num", {"plant.linear.nums": [1.0]}, "plant.linear.nums", "did you mean 'num'?"),
    ("misspelt-levels", {"protocols.staircase.levels_upp": [1.0, 2.0]}, "protocols.staircase.levels_upp",
     "did you mean 'levels_up'?"),
    ("misspelt-slope", {"plant.input_nonlinearity.slope_upp": 1.0}, "plant.input_nonlinearity.slope_upp",
     "did you mean 'slope_up'?"),
    ("unknown-key-lists-valid", {"plant.noise.zzzz": 1}, "plant.noise.zzzz", "valid keys: std, ar"),
    # a key holding a newline or a tab is shown escaped, so the message stays one line
    ("unknown-key-newline", {"\n": 1}, "'\\n'", "unknown key '\\n' (valid keys: name, seed"),
    ("unknown-key-tab", {"plant.noise.a\tb": 1}, "plant.noise.'a\\tb'", "unknown key 'a\\tb'"),
    ("missing-required", {"sampling.dt": D}, "sampling.dt", "required key is missing"),
    ("missing-plant", {"plant": D}, "plant", "required key is missing"),
    # wrong types
    ("dt-string", {"sampling.dt": "fast"}, "sampling.dt", "must be a valid number (got 'fast')"),
    ("dt-quoted-number", "name: x\nsampling: {dt: '0.05'}\n", "sampling.dt", "a quoted number is a string"),
    ("seed-float", {"seed": 1.5}, "seed", "must be a valid integer (got 1.5)"),
    ("seed-bool", {"seed": True}, "seed", "must be a valid integer (got True)"),
    ("name-list", {"name": [1, 2]}, "name", "must be a valid string (got a list)"),
    ("name-path", {"name": "../../etc/passwd"}, "name", "may contain only letters, digits and _ . + -"),
    ("noise-not-mapping", {"plant.noise": [0.01]}, "plant.noise", "must be a mapping of keys (got a list)"),
    ("kind-unknown", {"plant.kind": "wiener"}, "plant.kind", "must be 'hammerstein_wiener', 'external' or 'recorded'"),
    ("input-type-unknown", {"plant.input_nonlinearity.type": "dead_zone"}, "plant.input_nonlinearity.type",
     "must be 'backlash' or 'backlash_inverse'"),
    ("num-entry-string", {"plant.linear.num": ["one"]}, "plant.linear.num[0]", "must be a valid number"),
    # NaN / inf (written as YAML .nan / .inf by safe_dump)
    ("dt-nan", {"sampling.dt": float("nan")}, "sampling.dt", "must be a finite number (no NaN or inf)"),
    ("dt-inf", {"sampling.dt": float("inf")}, "sampling.dt", "must be a finite number (no NaN or inf)"),
    ("num-nan", {"plant.linear.num": [float("nan")]}, "plant.linear.num[0]", "must be a finite number"),
    ("d-plus-minus-inf", {"plant.input_nonlinearity.d_plus": float("-inf")}, "plant.input_nonlinearity.d_plus",
     "must be a finite number"),
    ("level-inf", {"protocols.staircase.levels_up": [0.0, float("inf")]}, "protocols.staircase.levels_up[1]",
     "must be a finite number"),
    # empty lists
    ("levels-up-empty", {"protocols.staircase.levels_up": []}, "protocols.staircase.levels_up",
     "must have at least 2 item(s), got 0"),
    ("frequencies-empty", {"protocols.sine.frequencies": []}, "protocols.sine.frequencies",
     "must have at least 1 item(s), got 0"),
    ("den-empty", {"plant.linear.den": []}, "plant.linear.den", "must have at least 1 item(s), got 0"),
    ("no-protocols", {"protocols": {}}, "protocols", "give at least one of 'staircase' or 'sine'"),
    # G(s)
    ("G-unstable", {"plant.linear.den": [1.0, -2.0]}, "plant.linear", "not asymptotically stable (pole at 2)"),
    ("G-marginal", {"plant.linear.den": [1.0, 0.0, 1.0]}, "plant.linear", "not asymptotically stable"),
    ("G-integrator", {"plant.linear.den": [1.0, 0.0]}, "plant.linear", "not asymptotically stable (pole at 0)"),
    ("G-improper", {"plant.linear.num": [1.0, 2.0, 3.0]}, "plant.linear", "G(s) is improper"),
    ("G0-zero", {"plant.linear.num": [1.0, 0.0]}, "plant.linear", "G(0) must be nonzero"),
    ("G-den-zero", {"plant.linear.den": [0.0, 0.0]}, "plant.linear", "den is all zeros"),
    ("G-delay-negative", {"plant.linear.delay": -0.1}, "plant.linear.delay", "must be greater than or equal to 0"),
    # backlash
    ("slope-up-zero", {"plant.input_nonlinearity.slope_up": 0.0}, "plant.input_nonlinearity.slope_up",
     "must be greater than 0 (got 0.0)"),
    ("slope-down-negative", {"plant.input_nonlinearity.slope_down": -1.0}, "plant.input_nonlinearity.slope_down",
     "must be greater than 0 (got -1.0)"),
    ("d-plus-equals-d-minus", {"plant.input_nonlinearity.d_plus": -0.5}, "plant.input_nonlinearity",
     "d_plus (-0.5) must be greater than d_minus (-0.5)"),
    ("d-plus-below-d-minus", {"plant.input_nonlinearity.d_plus": -1.0}, "plant.input_nonlinearity",
     "must be greater than d_minus"),
    ("borders-cross", {"plant.input_nonlinearity.slope_up": 4.0}, "plant.input_nonlinearity",
     "the borders cross inside the staircase range at u = 1"),
    ("borders-cross-inverse", {"plant.input_nonlinearity.type": "backlash_inverse",
                               "plant.input_nonlinearity.slope_down": 0.2}, "plant.input_nonlinearity",
     "the borders cross inside the staircase range"),
    # h
    ("h-not-through-zero", {"plant.output_nonlinearity.polynomial": [1.0, 1.0]}, "plant.output_nonlinearity",
     "h(0) must be 0"),
    ("h-two-forms", {"plant.output_nonlinearity.pieces": [{"polynomial": [0, 1]}]}, "plant.output_nonlinearity",
     "give exactly one of 'polynomial' or 'pieces'"),
    # staircase
    ("levels-up-not-monotone", {"protocols.staircase.levels_up": [-1.0, 0.5, 0.0, 1.0]}, "protocols.staircase",
     "levels_up must be strictly increasing"),
    ("levels-down-not-monotone", {"protocols.staircase.levels_down": [1.0, 0.0, 0.5, -1.0]}, "protocols.staircase",
     "levels_down must be strictly decreasing"),
    ("too-few-levels-for-degree", {"identification.nonlinear.degree": 6}, "protocols.staircase.levels_up",
     "5 levels cannot support degree 6"),
    ("hold-too-short", {"protocols.staircase.hold": 0.5}, "protocols.staircase.hold",
     "0.5 s is fewer than 20 samples of dt = 0.05 s"),
    ("staircase-too-long", {"protocols.staircase.hold": 1e9}, "protocols.staircase.hold", "more than the limit"),
    # sines
    ("omega-zero", {"protocols.sine.frequencies": [0.0]}, "protocols.sine.frequencies[0]",
     "must be greater than 0 (got 0.0)"),
    ("omega-negative", {"protocols.sine.frequencies": [0.5, -1.0]}, "protocols.sine.frequencies[1]",
     "must be greater than 0"),
    ("omega-above-nyquist", {"protocols.sine.frequencies": [100.0]}, "protocols.sine.frequencies[0]",
     "at or above the Nyquist frequency pi/dt = 62.83 rad/s"),
    ("omega-too-few-samples", {"protocols.sine.frequencies": [50.0]}, "protocols.sine.frequencies[0]",
     "fewer than 8 samples per period"),
    ("periods-zero", {"protocols.sine.periods": 0}, "protocols.sine.periods", "must be greater than or equal to 1"),
    ("periods-huge", {"protocols.sine.periods": 10**30}, "protocols.sine.periods", "more than the limit of 1e+08"),
    ("seed-too-big-for-hdf5", {"seed": 2**70}, "seed", "must be less than"),
    # external plants: the config itself
    ("external-no-callable", {"plant": {"kind": "external"}}, "plant",
     "an external plant needs callable"),
    ("callable-bad-format", {"plant": {"kind": "external", "callable": "rm -rf /"}}, "plant.callable",
     "must look like package.module:function"),
]


def _config_text(spec) -> str:
    import yaml
    return spec if isinstance(spec, str) else yaml.safe_dump(rigs.small(**spec), sort_keys=False)


@pytest.mark.parametrize("case_id,spec,key,fragment", CONFIG_CASES, ids=[c[0] for c in CONFIG_CASES])
def test_bad_config(case_id, spec, key, fragment, tmp_path, capsys):
    path = rigs.write(tmp_path / "bad.yaml", _config_text(spec))
    code, out, err = run_cli(["check", path], capsys)
    line = assert_one_line_error(code, err, fragment)
    prefix = f"hwid: error: {path}: {key}" if key else f"hwid: error: {path}: "
    assert line.startswith(prefix), f"{line!r} does not start with {prefix!r}"
    # the library raises the same one line as ConfigError
    with pytest.raises(C.ConfigError) as exc:
        C.load(path)
    assert str(exc.value) == line[len("hwid: error: "):]


# ---------------------------------------------------------------- external callables (checked by hwid check)

CALLABLE_CASES = [
    ("callable-module-missing", "no_such_module_hwid:rig", "cannot import module 'no_such_module_hwid' (ModuleNotFoundError"),
    ("callable-function-missing", "rigs:no_such_function", "module 'rigs' has no function 'no_such_function'"),
    ("callable-not-callable", "rigs:NOT_CALLABLE", "module 'rigs' has no function 'NOT_CALLABLE'"),
    ("callable-wrong-signature", "rigs:wrong_signature",
     "'rigs:wrong_signature' must accept (u: numpy.ndarray, dt: float), its signature is wrong_signature(u)"),
]


@pytest.mark.parametrize("case_id,spec,fragment", CALLABLE_CASES, ids=[c[0] for c in CALLABLE_CASES])
@pytest.mark.parametrize("command", ["check", "simulate"])
def test_bad_external_callable(case_id, spec, fragment, command, tmp_path, capsys):
    path = rigs.write(tmp_path / "rig.yaml", rigs.external(spec))
    argv = [command, path] + (["--out", tmp_path / "out"] if command == "simulate" else [])
    code, _, err = run_cli(argv, capsys)
    assert_one_line_error(code, err, f"{path}: plant.callable: ", fragment)
    assert not (tmp_path / "out" / "simulation.h5").exists()


# ---------------------------------------------------------------- files and paths

def test_missing_config_file(tmp_path, capsys):
    code, _, err = run_cli(["check", tmp_path / "nope.yaml"], capsys)
    assert_one_line_error(code, err, f"{tmp_path / 'nope.yaml'}: no such config file")


def test_directory_as_config(tmp_path, capsys):
    code, _, err = run_cli(["simulate", tmp_path, "--out", tmp_path / "out"], capsys)
    assert_one_line_error(code, err, f"{tmp_path}: cannot read the config (IsADirectoryError)")


def test_binary_config(tmp_path, capsys):
    path = tmp_path / "bin.yaml"
    path.write_bytes(b"\xff\xfe\x00garbage\x89PNG")
    code, _, err = run_cli(["check", path], capsys)
    assert_one_line_error(code, err, f"{path}: cannot read the config (UnicodeDecodeError)")


def test_out_is_a_file(tmp_path, capsys):
    cfg = rigs.write(tmp_path / "ok.yaml", rigs.small())
    out = tmp_path / "taken"
    out.write_text("not a directory")
    code, _, err = run_cli(["simulate", cfg, "--out", out], capsys)
    assert_one_line_error(code, err, f"--out {out}: exists and is not a directory")
    assert out.read_text() == "not a directory"


def test_out_below_a_file(tmp_path, capsys):
    cfg = rigs.write(tmp_path / "ok.yaml", rigs.small())
    (tmp_path / "taken").write_text("x")
    code, _, err = run_cli(["simulate", cfg, "--out", tmp_path / "taken" / "sub"], capsys)
    assert_one_line_error(code, err, "cannot create the directory (Not a directory)")


def test_simulation_overflow_is_an_error(tmp_path, capsys):
    """Numbers that pass the schema but overflow the simulation: a message, not a file of NaN."""
    cfg = rigs.write(tmp_path / "big.yaml", rigs.small(**{"protocols.sine.amplitude": 1e300}))
    code, _, err = run_cli(["simulate", cfg, "--out", tmp_path / "out"], capsys)
    assert_one_line_error(code, err, "simulating experiment 'sine_0' gave NaN or inf")
    assert not (tmp_path / "out" / "simulation.h5").exists()


# ---------------------------------------------------------------- sweep keys (hwid batch --sweep -> config.with_overrides)

@pytest.mark.parametrize("sweep,fragment", [
    ("seed.x=1", "seed.x: cannot set it, seed is not a mapping of keys"),
    ("protocols.sine.frequencies.0=1.0", "protocols.sine.frequencies is not a mapping of keys"),
    ("plant.noise.sdt=0.1", "plant.noise.sdt: unknown key 'sdt' (did you mean 'std'?)"),
    ("sampling.dt=.nan", "sampling.dt: must be a finite number"),
    ("plant.noise.std", "expected KEY=V1,V2,..."),
], ids=["through-scalar", "through-list", "misspelt", "nan", "no-values"])
def test_bad_sweep(sweep, fragment, tmp_path, capsys):
    cfg = rigs.write(tmp_path / "ok.yaml", rigs.small())
    code, _, err = run_cli(["batch", cfg, "--runs", "1", "--out", tmp_path / "out", "--sweep", sweep], capsys)
    assert_one_line_error(code, err, fragment)


def test_with_overrides_names_the_file():
    cfg = C.loads(_config_text({}), source_path="base.yaml")
    with pytest.raises(C.ConfigError, match=r"^base\.yaml: seed\.x: cannot set it"):
        C.with_overrides(cfg, {"seed.x": 1})


# ---------------------------------------------------------------- usage errors (click) are one line too

@pytest.mark.parametrize("argv,fragment", [
    (["simulate"], "Missing argument 'config'"),
    (["frobnicate"], "No such command 'frobnicate'"),
    (["check", "x.yaml", "--bogus"], "No such option: --bogus"),
], ids=["missing-argument", "unknown-command", "unknown-option"])
def test_usage_errors(argv, fragment, capsys):
    code, _, err = run_cli(argv, capsys)
    assert_one_line_error(code, err, fragment, "--help")


# ---------------------------------------------------------------- the installed script, in a subprocess

@pytest.mark.parametrize("make,fragment", [
    (lambda d: ["check", rigs.write(d / "c.yaml", "a: [1\n")], "malformed YAML"),
    (lambda d: ["check", rigs.write(d / "c.yaml", rigs.small(**{"plant.noise.sdt": 0.01}))],
     "plant.noise.sdt: unknown key 'sdt' (did you mean 'std'?)"),
    (lambda d: ["check", d / "missing.yaml"], "no such config file"),
    (lambda d: ["simulate", rigs.write(d / "c.yaml", rigs.small()), "--out", rigs.write(d / "f", "x")],
     "exists and is not a directory"),
    (lambda d: ["simulate"], "Missing argument 'config'"),
], ids=["malformed", "misspelt", "missing-file", "out-is-file", "usage"])
def test_subprocess(make, fragment, tmp_path):
    argv = [str(a) for a in make(tmp_path)]
    r = subprocess.run([str(HWID)] + argv, capture_output=True, text=True, timeout=60, cwd=tmp_path)
    assert_one_line_error(r.returncode, r.stderr, fragment)
    assert r.stdout == ""


# ---------------------------------------------------------------- results files

@pytest.fixture(scope="module")
def simulated(tmp_path_factory):
    """A real ``hwid simulate`` output and the config it came from."""
    d = tmp_path_factory.mktemp("sim")
    cfg_path = rigs.write(d / "small.yaml", rigs.small(**{"plant.noise.std": 0.0}))
    with pytest.raises(SystemExit) as exc:
        main(["simulate", str(cfg_path), "--out", str(d / "out")])
    assert exc.value.code == 0
    return d / "out" / "simulation.h5", C.load(cfg_path)


def _copy(src: Path, dst: Path, **attrs) -> Path:
    """A copy of ``src`` with root attributes changed, rewritten (and checksummed) by hwid's writer."""
    shutil.copyfile(src, dst)
    with atomic_h5(dst, "a") as f:
        for k, v in attrs.items():
            if v is None:
                del f.attrs[k]
            else:
                f.attrs[k] = v
    return dst


def _truncated(src, dst):
    dst.write_bytes(src.read_bytes()[: src.stat().st_size * 2 // 3])
    return dst


def _flip(src, dst, pos):
    b = bytearray(src.read_bytes())
    b[pos] ^= 0x10
    dst.write_bytes(bytes(b))
    return dst


def _foreign(src, dst):
    with h5py.File(dst, "w") as f:
        f["data"] = np.arange(10.0)
        f.attrs["creator"] = "someone else"
    return dst


RESULTS_CASES = [
    ("missing", lambda s, d: d / "nope.h5", "simulation", "no such file"),
    ("directory", lambda s, d: d, "simulation", "is a directory, expected an hwid results file"),
    ("truncated", _truncated, "simulation", "damaged (its checksum does not match: cut off or changed"),
    ("one-bit-flipped", lambda s, d: _flip(s, d, s.stat().st_size // 2), "simulation", "damaged (its checksum"),
    ("checksum-wiped", lambda s, d: _flip(s, d, 3), "simulation", "damaged (its checksum"),
    ("truncated-unstamped", lambda s, d: _truncated(_foreign(s, d.with_name("f.h5")), d), "simulation",
     "not a readable HDF5 file (truncated or foreign)"),
    ("text-file", lambda s, d: rigs.write(d, "name: not hdf5\n"), "simulation", "not a readable HDF5 file"),
    ("empty-file", lambda s, d: (d.write_bytes(b""), d)[1], "simulation", "not a readable HDF5 file"),
    ("foreign-hdf5", _foreign, "simulation", "not written by hwid (no hwid_kind attribute)"),
    ("wrong-kind", lambda s, d: _copy(s, d), "nonlinear", "is a 'simulation' file, expected 'nonlinear'"),
    ("wrong-kind-nonlinear-for-linear", lambda s, d: _copy(s, d, hwid_kind="nonlinear"), "linear",
     "is a 'nonlinear' file, expected 'linear'"),
    ("newer-format", lambda s, d: _copy(s, d, hwid_format=FORMAT + 98), "simulation",
     f"written with results format {FORMAT + 98}, this hwid reads format {FORMAT}"),
    ("format-garbage", lambda s, d: _copy(s, d, hwid_format="one"), "simulation", "cannot be read (corrupt file)"),
]


@pytest.mark.parametrize("case_id,make,kind,fragment", RESULTS_CASES, ids=[c[0] for c in RESULTS_CASES])
def test_bad_results_file(case_id, make, kind, fragment, simulated, tmp_path):
    src, _ = simulated
    path = make(src, tmp_path / "case.h5") if case_id != "directory" else make(src, tmp_path)
    with pytest.raises(ResultsError) as exc:
        open_results(path, kind)
    msg = str(exc.value)
    assert "\n" not in msg and msg.startswith(f"{path}: "), msg
    assert fragment in msg, msg


# the same checks through the commands that read results files
COMMAND_CASES = [
    ("nonlinear-data-missing", lambda s, d: d / "nope.h5", "identify-nonlinear", "no such file"),
    ("nonlinear-data-truncated", _truncated, "identify-nonlinear", "damaged (its checksum does not match"),
    ("nonlinear-data-foreign", _foreign, "identify-nonlinear", "not written by hwid"),
    ("nonlinear-data-newer-format", lambda s, d: _copy(s, d, hwid_format=FORMAT + 1), "identify-nonlinear",
     "this hwid reads format"),
    ("linear-given-simulation", lambda s, d: _copy(s, d), "identify-linear", "is a 'simulation' file, expected 'nonlinear'"),
    ("linear-nonlinear-missing", lambda s, d: d / "nope.h5", "identify-linear", "no such file"),
    ("linear-nonlinear-flipped", lambda s, d: _flip(s, d, 1000), "identify-linear", "damaged (its checksum"),
]


@pytest.mark.parametrize("case_id,make,command,fragment", COMMAND_CASES, ids=[c[0] for c in COMMAND_CASES])
def test_bad_results_file_through_commands(case_id, make, command, fragment, simulated, tmp_path, capsys):
    src, cfg = simulated
    path = make(src, tmp_path / "case.h5")
    cfg_path = rigs.write(tmp_path / "cfg.yaml", cfg.source_text)
    opt = "--data" if command == "identify-nonlinear" else "--nonlinear"
    code, _, err = run_cli([command, cfg_path, opt, path, "--out", tmp_path / "out"], capsys)
    assert_one_line_error(code, err, f"{path}: ", fragment)


def test_results_from_another_config(simulated, tmp_path):
    src, cfg = simulated
    other = C.loads(cfg.source_text.replace("seed: 3", "seed: 4"), source_path=str(tmp_path / "other.yaml"))
    with pytest.raises(ResultsError, match=r"was written for a different config than .*other\.yaml "
                                           r"\(config hash differs\)"):
        open_results(src, "simulation", cfg=other)
    with open_results(src, "simulation", cfg=cfg) as f:     # the matching config opens fine
        recs = read_records(f["experiments"])
    assert sorted(recs) == ["sine_0", "sine_1", "staircase_down", "staircase_up"]


def test_damaged_experiment_group(simulated, tmp_path):
    """A file whose header is fine but an experiment lost its 'y': ResultsError naming the group."""
    path = _copy(simulated[0], tmp_path / "damaged.h5")
    with atomic_h5(path, "a") as f:
        del f["experiments/sine_1/y"]
    with pytest.raises(ResultsError, match=r"sine_1: experiment without matching one-dimensional 'u' and 'y'"):
        read_simulation(path)



# ---------------------------------------------------------------- safety: YAML is data, never code

@pytest.mark.parametrize("tag", ["!!python/object/apply:os.mkdir", "!!python/object/new:os.mkdir",
                                 "!!python/name:os.mkdir"])
def test_yaml_tags_never_run_code(tag, tmp_path, capsys):
    marker = tmp_path / "pwned"
    path = rigs.write(tmp_path / "evil.yaml", f"name: {tag} ['{marker}']\n" if "name:" not in tag
                      else f"name: {tag} ''\n")
    code, _, err = run_cli(["check", path], capsys)
    assert_one_line_error(code, err, f"{path}: line 1", "could not determine a constructor")
    assert not marker.exists()


def test_config_loader_is_a_safe_loader():
    """Static check of the package: one YAML loader (a SafeLoader), no eval/exec/pickle of input."""
    import re
    import yaml
    assert issubclass(C._SafeLoader, yaml.SafeLoader)
    root = Path(C.__file__).parent
    offenders = []
    for src in root.rglob("*.py"):
        text = src.read_text()
        offenders += [f"{src.relative_to(root)}: {line.strip()}" for line in text.splitlines()
                      if "yaml.load(" in line and "_SafeLoader" not in line]
        for pat in (r"yaml\.unsafe_load", r"yaml\.full_load",
                    r"(?<![\w.])eval\(", r"(?<![\w.])exec\(", r"pickle\.loads?\(", r"allow_pickle\s*=\s*True"):
            offenders += [f"{src.relative_to(root)}: {m.group(0)}" for m in re.finditer(pat, text)]
    assert not offenders, offenders


# ---------------------------------------------------------------- recorded logs (plant.kind: recorded)

def _log(d, text, name="log.csv"):
    path = d / name
    path.write_text(text)
    return path


def _recorded(d, file, **exp):
    import yaml
    data = {"name": "rec", "sampling": {"dt": 0.1},
            "plant": {"kind": "recorded", "experiments": [{"file": str(file), "input": {"column": "u"},
                                                           "output": {"column": "y"}, **exp}]}}
    return rigs.write(d / "rec.yaml", yaml.safe_dump(data, sort_keys=False))


GOOD_LOG = "t,u,y\n" + "".join(f"{0.1 * k:.1f},{k // 5},{0.5 * k}\n" for k in range(30))

RECORDED_CASES = [
    ("missing-file", lambda d: _recorded(d, d / "nope.csv"), "nope.csv: no such file"),
    ("missing-column", lambda d: _recorded(d, _log(d, GOOD_LOG), output={"column": "yy"}),
     "no column 'yy' (columns: 't', 'u', 'y'); did you mean 'y'?"),
    ("column-index-too-large", lambda d: _recorded(d, _log(d, GOOD_LOG), output={"column": 7}),
     "column 7 does not exist (it has 3 columns, 0-based)"),
    ("non-numeric-cell", lambda d: _recorded(d, _log(d, GOOD_LOG.replace("\n1.0,2,5.0\n", "\n1.0,2,five\n"))),
     "row 11 (data row, 1-based), column 'y': 'five' is not a number"),
    ("time-backwards", lambda d: _recorded(d, _log(d, GOOD_LOG.replace("\n1.0,2,5.0\n", "\n0.5,2,5.0\n")),
                                           time={"column": "t"}),
     "row 11 (data row, 1-based): the timestamp goes backwards"),
    ("time-repeats", lambda d: _recorded(d, _log(d, GOOD_LOG.replace("\n1.0,2,5.0\n", "\n0.9,2,5.0\n")),
                                         time={"column": "t"}),
     "the timestamp repeats"),
    ("empty-record", lambda d: _recorded(d, _log(d, "t,u,y\n,,\n,,\n")), "the record is empty"),
    ("empty-file", lambda d: _recorded(d, _log(d, "")), "the file is empty"),
    ("too-short", lambda d: _recorded(d, _log(d, GOOD_LOG), start=2.85), "fewer than 3 samples between start and stop"),
    ("start-after-stop", lambda d: _recorded(d, _log(d, GOOD_LOG), start=2.0, stop=1.0),
     "plant.experiments[0]: start (2.0) must be before stop (1.0)"),
    ("exclude-backwards", lambda d: _recorded(d, _log(d, GOOD_LOG), exclude=[[2.0, 1.0]]),
     "exclude: each stretch must start before it stops, not [2.0, 1.0]"),
    ("exclude-everything", lambda d: _recorded(d, _log(d, GOOD_LOG), exclude=[[0.0, 100.0]]),
     "samples are left outside the excluded stretches"),
    ("scale-zero", lambda d: _recorded(d, _log(d, GOOD_LOG), input={"column": "u", "scale": 0.0}),
     "plant.experiments[0].input: scale must not be 0"),
    ("unknown-suffix", lambda d: _recorded(d, _log(d, GOOD_LOG, name="log.xlsx")),
     "cannot tell the format from the suffix '.xlsx'"),
    ("json-column-by-name", lambda d: _recorded(d, _log(d, '{"data": [[0, 1, 2]]}', name="log.json")),
     "JSON columns are 0-based indices"),
    ("misspelt-required-key", lambda d: rigs.write(d / "c.yaml", rigs.small(**{
        "plant.linear.den": rigs.DELETE, "plant.linear.dem": [1.0, 2.0]})),
     "plant.linear.dem: unknown key 'dem' (did you mean 'den'?)"),
]


@pytest.mark.parametrize("case_id,make,fragment", RECORDED_CASES, ids=[c[0] for c in RECORDED_CASES])
@pytest.mark.parametrize("command", ["check", "simulate"])
def test_bad_recorded_input(case_id, make, fragment, command, tmp_path, capsys):
    path = make(tmp_path)
    argv = [command, path] + (["--out", tmp_path / "out"] if command == "simulate" else [])
    code, _, err = run_cli(argv, capsys)
    assert_one_line_error(code, err, fragment)
    assert not (tmp_path / "out" / "simulation.h5").exists()
