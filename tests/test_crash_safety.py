"""Nothing lost (issue 7): writers killed with SIGKILL at random moments leave either no file, the old
complete file or the new complete file, never a broken one; rig journal entries survive.

Each writer is a separate process (killed for real, no chance to clean up). After each kill the file
is opened with :func:`hwid.results.read_simulation`, which verifies hwid's checksum and reads every
dataset, and its content is compared bit for bit with what that generation must contain.
"""
from __future__ import annotations

import hashlib
import os
import signal
import subprocess
import sys
import textwrap
import time
from pathlib import Path

import numpy as np
import pytest

import rigs
from hwid import config as C
from hwid.cli import main
from hwid.plant import RigJournal
from hwid.results import open_results, read_simulation

pytestmark = pytest.mark.skipif(not hasattr(signal, "SIGKILL"), reason="needs POSIX SIGKILL")

N_KILLS_H5 = 24          # kills of a loop of atomic_h5 writers
N_KILLS_JOURNAL = 12     # kills of a loop of RigJournal.put
N_KILLS_SIMULATE = 3     # kills of the real `hwid simulate`

H5_WRITER = textwrap.dedent("""
    import sys
    import numpy as np
    from hwid.plant import Record
    from hwid.results import atomic_h5, write_provenance, write_records

    path, gen = sys.argv[1], int(sys.argv[2])

    def records(gen):
        rng = np.random.default_rng(gen)
        n = 20_000 + (gen % 5) * 10_000
        return [Record(f"exp{k}", 0.01, rng.standard_normal(n), rng.standard_normal(n)) for k in range(3)]

    print("ready", flush=True)
    while True:
        gen += 1
        with atomic_h5(path) as f:
            write_provenance(f, "simulation")
            f.attrs["generation"] = gen
            write_records(f.require_group("experiments"), records(gen))
        print(gen, flush=True)
""")

JOURNAL_WRITER = textwrap.dedent("""
    import sys
    import numpy as np
    from hwid.plant import RigJournal

    journal, i = RigJournal(sys.argv[1]), int(sys.argv[2])
    print("ready", flush=True)
    while True:
        i += 1
        rng = np.random.default_rng(i)
        u = rng.standard_normal(50_000)
        journal.put(f"exp{i}", u, np.tanh(u), 0.01)
        print(i, flush=True)
""")


def _expected(gen: int) -> dict:
    rng = np.random.default_rng(gen)
    n = 20_000 + (gen % 5) * 10_000
    return {f"exp{k}": (rng.standard_normal(n), rng.standard_normal(n)) for k in range(3)}


def _start(script: Path, *args) -> subprocess.Popen:
    p = subprocess.Popen([sys.executable, str(script), *map(str, args)], stdout=subprocess.PIPE, text=True)
    assert p.stdout.readline().strip() == "ready"
    return p


def _kill(p: subprocess.Popen) -> list[int]:
    os.kill(p.pid, signal.SIGKILL)
    p.wait()
    return [int(line) for line in p.stdout.read().split()]


def _check_h5(path: Path) -> int:
    """The file is complete and exactly one generation's content; returns that generation."""
    records, _ = read_simulation(path)          # checksum, header, every dataset
    with open_results(path, "simulation") as f:
        gen = int(f.attrs["generation"])
    want = _expected(gen)
    assert sorted(records) == sorted(want)
    for name, (u, y) in want.items():
        np.testing.assert_array_equal(records[name].u, u)
        np.testing.assert_array_equal(records[name].y, y)
    return gen


def test_sigkill_atomic_h5_writer(tmp_path):
    rng = np.random.default_rng(20240607)
    script = tmp_path / "writer.py"
    script.write_text(H5_WRITER)
    path = tmp_path / "out" / "simulation.h5"
    known = None               # the last generation known to be complete on disk
    mid_write = 0              # kills that hit while a .tmp was being written
    for k in range(N_KILLS_H5):
        p = _start(script, path, known or 0)
        time.sleep(rng.uniform(0.0, 0.4))
        done = _kill(p)
        if path.with_name(path.name + ".tmp").exists():
            mid_write += 1
        if not path.exists():
            assert known is None and not done, "a completed file disappeared"
            continue
        gen = _check_h5(path)
        last = done[-1] if done else known
        # the old complete file, or the new one (killed between the rename and the print)
        allowed = {last, (last or 0) + 1}
        assert gen in allowed, f"kill {k}: generation {gen} on disk, expected one of {allowed}"
        known = gen
    assert known is not None, "no writer ever completed a file"
    assert mid_write >= N_KILLS_H5 // 4, f"only {mid_write} kills hit a write in progress"
    print(f"\natomic_h5: {N_KILLS_H5} kills, {mid_write} in the middle of a write, nothing lost")


def test_sigkill_rig_journal_writer(tmp_path):
    rng = np.random.default_rng(7)
    script = tmp_path / "journal_writer.py"
    script.write_text(JOURNAL_WRITER)
    jdir = tmp_path / "rig_journal"
    journal = RigJournal(jdir)
    completed: list[int] = []
    nxt = 0
    for _ in range(N_KILLS_JOURNAL):
        p = _start(script, jdir, nxt)
        time.sleep(rng.uniform(0.0, 0.3))
        done = _kill(p)
        completed += done
        nxt = (done[-1] if done else nxt) + 1      # the entry being written may or may not have landed
    assert completed, "no journal entry was ever completed"
    for i in completed:                            # every recorded call is found again, intact
        u = np.random.default_rng(i).standard_normal(50_000)
        y = journal.get(f"exp{i}", u, 0.01)
        assert y is not None, f"journal entry exp{i} lost"
        np.testing.assert_array_equal(y, np.tanh(u))
    for entry in jdir.glob("*.npz"):               # and no entry file is broken
        with np.load(entry) as f:
            assert f["u"].shape == f["y"].shape == (50_000,)
    print(f"\nrig journal: {N_KILLS_JOURNAL} kills, {len(completed)} entries, all intact")


def test_sigkill_hwid_simulate(tmp_path):
    """The real command: an existing simulation.h5 survives a killed rerun with another config."""
    rng = np.random.default_rng(11)
    old_cfg = rigs.write(tmp_path / "old.yaml", rigs.small(**{"seed": 1}))
    new_cfg = rigs.write(tmp_path / "new.yaml", rigs.small(**{"seed": 2}))
    out = tmp_path / "out"
    with pytest.raises(SystemExit) as exc:
        main(["simulate", str(old_cfg), "--out", str(out)])
    assert exc.value.code == 0
    hashes = {C.load(old_cfg).sha256: "old", C.load(new_cfg).sha256: "new"}
    hwid = Path(sys.executable).with_name("hwid")
    cmd = [str(hwid), "simulate", str(new_cfg), "--out"]
    t0 = time.perf_counter()                       # how long a full run takes, to aim near its end
    subprocess.run(cmd + [str(tmp_path / "timing")], check=True, capture_output=True)
    full = time.perf_counter() - t0
    seen = []
    for _ in range(N_KILLS_SIMULATE):
        p = subprocess.Popen(cmd + [str(out)], stdout=subprocess.DEVNULL, stderr=subprocess.DEVNULL)
        time.sleep(rng.uniform(0.7, 1.3) * full)
        os.kill(p.pid, signal.SIGKILL)
        p.wait()
        path = out / "simulation.h5"
        assert path.exists()
        read_simulation(path)                      # complete and readable
        with open_results(path, "simulation") as f:
            seen.append(hashes[f.attrs["config_sha256"]])
    print(f"\nhwid simulate: {N_KILLS_SIMULATE} kills, file afterwards: {seen}")
