"""`hwid batch`: seeds independent of J and of the executor, SIGKILL-safe journal, resume, summaries."""
import json
import os
import signal
import subprocess
import sys
import time
from pathlib import Path

import numpy as np
import pytest

import plants
from hwid import config
from hwid.batch import read_journal, run_batch
from hwid.results import read_batch_runs, read_batch_summary


@pytest.fixture
def fast_cfg(tmp_path):
    p = tmp_path / "fast.yaml"
    p.write_text(plants.config_text(plants.BATCH))
    return config.load(p)


def _estimates(path, point=0):
    r = read_batch_runs(path, point)
    order = np.argsort(r["run"])
    return {k: v[order] for k, v in r.items() if not k.startswith("seconds")}


def test_identical_whatever_jobs(fast_cfg, tmp_path):
    a = run_batch(fast_cfg, 4, tmp_path / "a", jobs=1, progress=False)
    b = run_batch(fast_cfg, 4, tmp_path / "b", jobs=2, progress=False)
    ea, eb = _estimates(a), _estimates(b)
    assert set(ea) == set(eb) and "d_plus" in ea and "gain@0.5" in ea
    for k in ea:
        np.testing.assert_array_equal(ea[k], eb[k], err_msg=k)
    # the runs differ from each other (independent noise) yet each lands near the truth
    assert np.ptp(ea["d_plus"]) > 0
    s = read_batch_summary(a)["points"][0]["stats"]
    assert abs(s["d_plus"]["bias"]) < 0.01 and s["d_plus"]["truth"] == pytest.approx(0.4)
    assert abs(s["gain@0.5"]["truth"] - 1 / abs(1 + 0.25j)) < 1e-12


def test_dask_local_cluster_gives_identical_results(fast_cfg, tmp_path):
    distributed = pytest.importorskip("distributed")
    a = run_batch(fast_cfg, 3, tmp_path / "a", jobs=1, progress=False)
    with distributed.LocalCluster(n_workers=2, threads_per_worker=1, processes=True,
                                  dashboard_address=None) as cluster:
        b = run_batch(fast_cfg, 3, tmp_path / "b", scheduler=cluster.scheduler_address, progress=False)
        # hwid closed only its own client: the cluster still serves
        with distributed.Client(cluster.scheduler_address) as c:
            assert c.submit(lambda: 41 + 1).result() == 42
    ea, eb = _estimates(a), _estimates(b)
    for k in ea:
        np.testing.assert_array_equal(ea[k], eb[k], err_msg=k)


def test_sweep_crosses_points(fast_cfg, tmp_path):
    path = run_batch(fast_cfg, 2, tmp_path / "s", sweeps=[("plant.noise.std", [0.001, 0.02])], progress=False)
    s = read_batch_summary(path)
    assert s["sweep_keys"] == ["plant.noise.std"]
    assert [p["overrides"]["plant.noise.std"] for p in s["points"]] == [0.001, 0.02]
    e0, e1 = _estimates(path, 0), _estimates(path, 1)
    # common random numbers: same seeds, so the error scales with sigma (x20) run by run
    err0, err1 = e0["d_plus"] - 0.4, e1["d_plus"] - 0.4
    assert np.all(np.abs(err1) > np.abs(err0))


def test_sigkill_loses_only_runs_in_flight_and_resume_completes(fast_cfg, tmp_path):
    out = tmp_path / "k"
    cfg_path = Path(fast_cfg.source_path)
    cmd = [sys.executable, "-m", "hwid", "batch", str(cfg_path), "--runs", "8", "--jobs", "2", "--out", str(out)]
    proc = subprocess.Popen(cmd, stdout=subprocess.DEVNULL, stderr=subprocess.DEVNULL, start_new_session=True)
    journal = out / "batch.jsonl"
    deadline = time.monotonic() + 120
    while time.monotonic() < deadline and len(read_journal(journal)) < 3:
        time.sleep(0.05)
    os.killpg(proc.pid, signal.SIGKILL)
    proc.wait()
    before = read_journal(journal)
    assert 3 <= len(before) < 8
    # every journalled run is whole and unique
    assert len({(r["point"], r["run"]) for r in before}) == len(before)
    # the same command again computes only the missing runs
    path = run_batch(fast_cfg, 8, out, jobs=1, progress=False)
    after = read_journal(journal)
    assert sorted(r["run"] for r in after) == list(range(8))
    kept = {r["run"]: r["estimates"] for r in before}
    for r in after:
        if r["run"] in kept:
            assert r["estimates"] == kept[r["run"]]
    ref = run_batch(fast_cfg, 8, tmp_path / "ref", jobs=2, progress=False)
    ea, eb = _estimates(path), _estimates(ref)
    for k in ea:
        np.testing.assert_array_equal(ea[k], eb[k], err_msg=k)


def test_different_batch_in_same_dir_is_refused(fast_cfg, tmp_path):
    from hwid import HwidError
    run_batch(fast_cfg, 1, tmp_path / "d", progress=False)
    with pytest.raises(HwidError, match="different batch"):
        run_batch(fast_cfg, 2, tmp_path / "d", progress=False)
