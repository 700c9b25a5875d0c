import os
from pathlib import Path

import pytest

ROOT = Path(__file__).resolve().parents[1]
os.environ.setdefault("MPLBACKEND", "Agg")
if os.environ.get("PYTEST_XDIST_WORKER"):
    # pytest-xdist's workers are the parallelism: fits inside a test (and the hwid processes a test
    # starts) run in one process with one BLAS thread, instead of each worker forking a pool per fit
    # and spinning BLAS threads on the cores the other worker uses. Tests of the parallel paths set
    # HWID_WORKERS themselves.
    for _name in ("HWID_WORKERS", "OPENBLAS_NUM_THREADS", "OMP_NUM_THREADS", "MKL_NUM_THREADS"):
        os.environ.setdefault(_name, "1")


@pytest.fixture
def paper_cfg():
    from hwid import config
    return config.load(ROOT / "configs" / "paper.yaml")
