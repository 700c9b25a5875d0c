import os
from pathlib import Path

import pytest

ROOT = Path(__file__).resolve().parents[1]
os.environ.setdefault("MPLBACKEND", "Agg")


@pytest.fixture
def paper_cfg():
    from hwid import config
    return config.load(ROOT / "configs" / "paper.yaml")
