"""Generated lab sessions through the command line (issue 45, item 7): never a traceback.

A lab log is whatever the operator did: holds from a fifth of G's settling time to twenty of them,
plain sines, ramps, triangles, logger pauses between parts or one unbroken record, on a slow and a
fast plant (:func:`logs.write_lab`: hwid's own chain, asymmetric backlash, ``h = w + 0.25 w^2``,
noise of s.d. 0.02, written as a CSV in raw counts with jittered timestamps and a recorded config).
Each session goes through ``hwid run``, ``hwid identify-nonlinear``, ``hwid identify-linear`` and
``hwid diagnose`` exactly as a user types them (:func:`hwid.cli.main` in-process, so an escaping
exception fails the test with its own traceback). Allowed: exit 0, or exit 2 with one line
``hwid: error: ...``. A ``hwid run`` on a recorded config without the whole fit may exit 2 saying
to enable it. The stage commands write what ``hwid run`` wrote of the same stages, to the last digit.

Where stage 1 succeeds, the dead band it reports must be a number with an interval of positive
width, or undetermined (interval None) with a reason -- never a zero-width interval.
"""
from __future__ import annotations

import contextlib
import io
import json
import tempfile
from pathlib import Path

import numpy as np
import pytest
from hypothesis import HealthCheck, given, settings
from hypothesis import strategies as st

import logs
from hwid.cli import main

DT = logs.DT
#: G's time constant (s) of the fast and the slow plant; the settling time is four of them
PLANTS = {"fast": 0.05, "slow": 0.6}
#: the longest session generated (samples), so an example runs in seconds
MAX_SAMPLES = 6000


def _plant(tau: float) -> dict:
    return {"num": [1.0], "den": [tau, 1.0]}


@st.composite
def pieces(draw, settle: float) -> np.ndarray:
    """One stretch of input: a hold of 0.2-20 settling times, a sine, a ramp or a triangle."""
    kind = draw(st.sampled_from(["hold", "hold", "hold", "sine", "ramp", "triangle"]))
    level = draw(st.floats(-1.5, 1.5))
    if kind == "hold":
        n = max(1, int(round(draw(st.floats(0.2, 20.0)) * settle / DT)))
        return np.full(n, round(level, 3))
    seconds = draw(st.floats(1.0, 12.0))
    t = np.arange(max(2, int(seconds / DT))) * DT
    amp = draw(st.floats(0.1, 1.4))
    if kind == "sine":
        omega = draw(st.floats(0.3, 6.0))
        return np.clip(level, -0.5, 0.5) + amp * np.sin(omega * t)
    if kind == "ramp":
        end = draw(st.floats(-1.5, 1.5))
        return np.linspace(level, end, t.size)
    period = draw(st.floats(0.5, 6.0))
    s = (t / period) % 1.0
    return amp * (2 * np.abs(2 * s - 1) - 1)


@st.composite
def sessions(draw):
    """``(plant name, parts, one_record)``: 1-3 parts of 1-8 pieces each, at most MAX_SAMPLES."""
    name = draw(st.sampled_from(sorted(PLANTS)))
    settle = 4.0 * PLANTS[name]
    parts, total = [], 0
    for _ in range(draw(st.integers(1, 3))):
        part = []
        for _ in range(draw(st.integers(1, 8))):
            p = draw(pieces(settle))
            if total + p.size > MAX_SAMPLES:
                break
            part.append(p)
            total += p.size
        if part and sum(x.size for x in part) >= 64:
            parts.append(np.concatenate(part))
    if not parts:
        parts = [np.full(64, 0.3)]
    return name, parts, draw(st.booleans())


def _cli(argv) -> tuple[int, str]:
    """``hwid ARGV`` in-process: exit code and stderr (an exception other than SystemExit escapes)."""
    err = io.StringIO()
    with contextlib.redirect_stderr(err), contextlib.redirect_stdout(io.StringIO()):
        try:
            main([str(a) for a in argv])
        except SystemExit as exc:
            return int(exc.code or 0), err.getvalue()
    return 0, err.getvalue()


def _allowed(code: int, err: str, what: str) -> None:
    assert "Traceback" not in err, f"{what}: {err}"
    assert code in (0, 2), f"{what}: exit {code}: {err}"
    if code == 2:
        lines = err.strip("\n").split("\n")
        errors = [ln for ln in lines if ln.startswith("hwid: error: ")]
        assert len(errors) == 1 and lines[-1] == errors[0], f"{what}: not one error line: {err!r}"


def _dead_band_honest(path: Path) -> None:
    """A stage-1 JSON's dead band: a number with an interval of positive width, or None with a reason."""
    res = json.loads(path.read_text())
    ci = res["ci"]["dead_band"]
    if ci is None:
        assert res.get("undetermined", {}).get("dead_band"), res
    else:
        assert ci[1] > ci[0], f"zero-width dead band interval {ci}"


def _same_stages(tmp: Path, cmd: str, code: int, codes: dict) -> None:
    """The stage commands take ``hwid run``'s own steps (:func:`hwid.identify.path.stage1`,
    :func:`~hwid.identify.path.stage2`): what one writes, ``hwid run`` wrote beside its model, to
    the last digit; where one cannot, ``hwid run`` did not either."""
    from hwid.results import read_history, read_linear
    name = {"identify-nonlinear": "history.h5", "identify-linear": "linear.h5"}[cmd]
    ran, own = tmp / "run" / name, tmp / cmd / name
    if code == 0 and ran.exists():
        if cmd == "identify-nonlinear":
            assert read_history(own).to_dict() == read_history(ran).to_dict()
        else:
            np.testing.assert_equal(read_linear(own).to_dict(), read_linear(ran).to_dict())
    elif code == 2 and codes.get("run") == 0 and codes.get("identify-nonlinear") == 0:
        assert not ran.exists(), f"hwid {cmd} refused what hwid run read"


def _check_session(session, commands=("run", "identify-nonlinear", "identify-linear", "diagnose")) -> None:
    name, parts, one_record = session
    with tempfile.TemporaryDirectory() as tmp:
        tmp = Path(tmp)
        cfg = logs.write_lab(tmp, parts=parts, one_record=one_record, linear=_plant(PLANTS[name]), seed=len(parts))
        codes: dict = {}
        for cmd in commands:
            argv = [cmd, cfg, "--out", tmp / cmd]
            if cmd == "identify-nonlinear":
                argv += ["--json", tmp / "stage1.json"]
            if cmd == "identify-linear":
                if codes.get("identify-nonlinear") != 0:
                    continue
                argv += ["--nonlinear", tmp / "identify-nonlinear"]
            code, err = _cli(argv)
            codes[cmd] = code
            _allowed(code, err, f"hwid {cmd} ({name}, {[p.size for p in parts]}, one record {one_record})")
            if cmd == "identify-nonlinear" and code == 0:
                _dead_band_honest(tmp / "stage1.json")
            if cmd.startswith("identify-") and "run" in codes:
                _same_stages(tmp, cmd, code, codes)


COMMON = dict(deadline=None, derandomize=True, print_blob=True,
              suppress_health_check=[HealthCheck.too_slow, HealthCheck.data_too_large])


@settings(max_examples=6, **COMMON)
@given(sessions())
def test_stage1_commands_on_generated_sessions(session):
    _check_session(session, commands=("run", "identify-nonlinear", "identify-linear"))


@pytest.mark.slow
def test_diagnose_on_one_unbroken_record_of_the_lab_run():
    """The issue's case (about a minute): the ordinary lab run as one unbroken record, which the
    diagnosis splits into fit and validation blocks, on the fast plant. Before the fix stage 1
    stopped with ``ValueError: a level holds only 0 samples`` (the blocks kept the whole record's
    level list; :func:`hwid.identify.history.record_levels`)."""
    _check_session(("fast", logs.lab_parts(hold=4.0), True), commands=("diagnose",))


@pytest.mark.slow
@settings(max_examples=40, **COMMON)
@given(sessions())
def test_every_command_on_generated_sessions(session):
    _check_session(session)
