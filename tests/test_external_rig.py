"""Rigs that misbehave (issue 7) and the external-plant contract (issue 2).

``plant.kind: external`` calls ``function(u, dt) -> y`` once per experiment. A rig that raises,
returns the wrong length, NaN or nothing, quits, or hangs past ``plant.timeout`` stops
``hwid simulate`` with one line naming the call and exit code 2; every (u, y) already recorded stays
in ``OUT/rig_journal``, and a rerun resumes from it without driving the rig again for those
experiments. The rig drivers are in ``tests/rigs.py``; they count their calls.
"""
from __future__ import annotations

import os
import subprocess
import sys
import time
from pathlib import Path

import numpy as np
import pytest

import rigs
from hwid.cli import main
from hwid.plant import RigJournal
from hwid.results import read_simulation

HWID = Path(sys.executable).with_name("hwid")
EXPERIMENTS = ["staircase_up", "staircase_down", "sine_0", "sine_1"]     # the order hwid runs them in


@pytest.fixture(autouse=True)
def _fresh_rigs():
    rigs.reset()
    yield
    rigs.RELEASE.set()          # let any hung rig thread finish
    rigs.reset()


def simulate(cfg: Path, out: Path, capsys) -> tuple[int, str]:
    with pytest.raises(SystemExit) as exc:
        main(["simulate", str(cfg), "--out", str(out)])
    _, err = capsys.readouterr()
    return exc.value.code, err


def one_line(err: str) -> str:
    assert "Traceback" not in err
    lines = err.strip("\n").split("\n")
    assert len(lines) == 1, err
    return lines[0]


def journal_entries(out: Path) -> list[str]:
    return sorted(p.name.rsplit("-", 1)[0] for p in (out / "rig_journal").glob("*.npz"))


# ---------------------------------------------------------------- a good rig: the protocol's calls, no more

def test_good_rig_one_call_per_experiment_and_rerun_reuses_journal(tmp_path, capsys):
    cfg = rigs.write(tmp_path / "rig.yaml", rigs.external("rigs:good"))
    out = tmp_path / "out"
    code, err = simulate(cfg, out, capsys)
    assert code == 0, err
    records, truth = read_simulation(out / "simulation.h5")
    assert truth is None                                  # nothing is known about a rig
    assert sorted(records) == sorted(EXPERIMENTS)
    assert len(rigs.CALLS) == rigs.N_EXPERIMENTS          # one call per experiment
    assert rigs.CALLS == [records[n].u.size for n in EXPERIMENTS]
    for r in records.values():                            # hwid stored exactly what the rig answered
        np.testing.assert_array_equal(r.y, rigs._respond(r.u, 0.05))
    assert journal_entries(out) == sorted(EXPERIMENTS)

    first = (out / "simulation.h5").read_bytes()
    code, err = simulate(cfg, out, capsys)                 # a rerun drives the rig not once
    assert code == 0, err
    assert len(rigs.CALLS) == rigs.N_EXPERIMENTS
    again, _ = read_simulation(out / "simulation.h5")
    for n in EXPERIMENTS:
        np.testing.assert_array_equal(again[n].y, records[n].y)
    assert len(first) > 0


# ---------------------------------------------------------------- misbehaving rigs

@pytest.mark.parametrize("driver,fragment", [
    ("raising", "failed on experiment 'staircase_up': RuntimeError: motor driver fault encoder 2 not responding"),
    ("wrong_length", "returned 697 samples for experiment 'staircase_up', expected 700"),
    ("with_nan", "returned NaN or inf for experiment 'staircase_up' (first at sample 7)"),
    ("returns_none", "returned None for experiment 'staircase_up' (expected an array of 700 samples)"),
    ("exits", "failed on experiment 'staircase_up': SystemExit: 0"),
])
def test_misbehaving_rig_stops_with_one_line(driver, fragment, tmp_path, capsys):
    cfg = rigs.write(tmp_path / "rig.yaml", rigs.external(f"rigs:{driver}"))
    out = tmp_path / "out"
    code, err = simulate(cfg, out, capsys)
    line = one_line(err)
    assert code == 2
    assert line.startswith(f"hwid: error: external plant 'rigs:{driver}' ")
    assert fragment in line, line
    assert len(rigs.CALLS) == 1                          # stopped at the failing call
    assert not (out / "simulation.h5").exists()
    if driver in ("wrong_length", "with_nan"):           # the rig's answer is kept, never reused
        kept = list((out / "rig_journal" / "rejected").glob("staircase_up-*.npz"))
        assert len(kept) == 1 and "the output is kept in" in line
        assert journal_entries(out) == []


def test_hanging_rig_times_out(tmp_path, capsys):
    cfg = rigs.write(tmp_path / "rig.yaml", rigs.external("rigs:hanging", timeout=0.5))
    t0 = time.perf_counter()
    code, err = simulate(cfg, tmp_path / "out", capsys)
    assert time.perf_counter() - t0 < 10
    assert code == 2
    assert one_line(err) == ("hwid: error: external plant 'rigs:hanging' call for experiment 'staircase_up' "
                             "did not return within 0.5 s (plant.timeout)")
    assert len(rigs.CALLS) == 1


def test_hanging_rig_does_not_keep_the_process_alive(tmp_path):
    """The real script exits at once after a timeout, although the rig's call never returns."""
    cfg = rigs.write(tmp_path / "rig.yaml", rigs.external("rigs:hanging", timeout=0.5))
    env = {**os.environ, "PYTHONPATH": str(rigs.TESTS)}
    t0 = time.perf_counter()
    r = subprocess.run([str(HWID), "simulate", str(cfg), "--out", str(tmp_path / "out")],
                       capture_output=True, text=True, env=env, timeout=60)
    assert time.perf_counter() - t0 < 19          # the hung call waits 20 s; hwid does not
    assert r.returncode == 2
    assert "did not return within 0.5 s (plant.timeout)" in one_line(r.stderr)


# ---------------------------------------------------------------- nothing lost, nothing repeated

def test_failure_keeps_recorded_calls_and_rerun_resumes(tmp_path, capsys):
    cfg = rigs.write(tmp_path / "rig.yaml", rigs.external("rigs:flaky"))
    out = tmp_path / "out"
    rigs.reset(fail_after=2)                              # the rig dies on the third experiment
    code, err = simulate(cfg, out, capsys)
    assert code == 2
    assert "external plant 'rigs:flaky' failed on experiment 'sine_0': ConnectionError: rig connection lost" \
        in one_line(err)
    assert journal_entries(out) == ["staircase_down", "staircase_up"]     # both recorded calls kept
    assert not (out / "simulation.h5").exists()

    rigs.reset(fail_after=None)                           # the rig is fixed
    code, err = simulate(cfg, out, capsys)
    assert code == 0, err
    assert len(rigs.CALLS) == 2                            # only sine_0 and sine_1 were run on the rig
    records, _ = read_simulation(out / "simulation.h5")
    assert sorted(records) == sorted(EXPERIMENTS)
    assert rigs.CALLS == [records["sine_0"].u.size, records["sine_1"].u.size]
    for n in EXPERIMENTS:
        np.testing.assert_array_equal(records[n].y, rigs._respond(records[n].u, 0.05))


def test_resume_across_processes(tmp_path):
    """The same story with the installed script: calls counted in a log file across two processes."""
    cfg = rigs.write(tmp_path / "rig.yaml", rigs.external("rigs:flaky"))
    out, log = tmp_path / "out", tmp_path / "calls.log"
    env = {**os.environ, "PYTHONPATH": str(rigs.TESTS), "HWID_TEST_RIG_LOG": str(log),
           "HWID_TEST_RIG_FAIL_AFTER": "3"}
    r = subprocess.run([str(HWID), "simulate", str(cfg), "--out", str(out)], capture_output=True, text=True,
                       env=env, timeout=120)
    assert r.returncode == 2 and "experiment 'sine_1'" in one_line(r.stderr)
    assert len(log.read_text().split()) == 3
    env["HWID_TEST_RIG_FAIL_AFTER"] = "-1"
    r = subprocess.run([str(HWID), "simulate", str(cfg), "--out", str(out)], capture_output=True, text=True,
                       env=env, timeout=120)
    assert r.returncode == 0, r.stderr
    assert len(log.read_text().split()) == 4             # 3 + the one experiment still missing
    records, _ = read_simulation(out / "simulation.h5")
    assert sorted(records) == sorted(EXPERIMENTS)


def test_changed_protocol_is_not_served_from_the_journal(tmp_path, capsys):
    """The journal matches calls by input, not only by name: a different staircase runs on the rig."""
    out = tmp_path / "out"
    code, _ = simulate(rigs.write(tmp_path / "a.yaml", rigs.external("rigs:good")), out, capsys)
    assert code == 0 and len(rigs.CALLS) == 4
    changed = rigs.external("rigs:good")
    changed["protocols"]["staircase"]["hold"] = 6.0
    code, _ = simulate(rigs.write(tmp_path / "b.yaml", changed), out, capsys)
    assert code == 0
    assert len(rigs.CALLS) == 6                            # the two staircases again, the sines reused


# ---------------------------------------------------------------- safety: names never become paths outside --out

NASTY_NAMES = ["../../../etc/passwd", "/abs/path", "a/b\\c", "..", ".", "", "x" * 1000, "名前", "nul\x00byte",
               "C:\\windows", "~root", "-rf", "sine_0/../../up"]


@pytest.mark.parametrize("name", NASTY_NAMES, ids=range(len(NASTY_NAMES)))
def test_journal_names_stay_inside_the_journal(name, tmp_path):
    jdir = tmp_path / "out" / "rig_journal"
    u = np.linspace(0, 1, 10)
    key = RigJournal.key(name, u, 0.05)
    assert "/" not in key and "\\" not in key and "\x00" not in key and key not in (".", "..")
    assert len(key + ".npz") <= 255
    p = RigJournal(jdir).put(name, u, u * 2, 0.05)
    assert p.resolve().parent == jdir.resolve()
    np.testing.assert_array_equal(RigJournal(jdir).get(name, u, 0.05), u * 2)
    assert sorted(x.name for x in tmp_path.rglob("*") if x.is_file()) == [p.name]


def test_simulate_writes_only_inside_out(tmp_path, capsys):
    cfg = rigs.write(tmp_path / "rig.yaml", rigs.external("rigs:good"))
    before = set(tmp_path.rglob("*"))
    code, _ = simulate(cfg, tmp_path / "out", capsys)
    assert code == 0
    created = set(tmp_path.rglob("*")) - before
    assert created and all(p.resolve().is_relative_to((tmp_path / "out").resolve()) for p in created)
    assert not any(p.name.endswith(".tmp") for p in created)
