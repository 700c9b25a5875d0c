"""The config reference (docs/reference/config.md) is rendered from the schema: every key must
carry a description, and the committed page must be the one the schema renders."""
from __future__ import annotations

import importlib.util
import sys
from pathlib import Path

import pytest

ROOT = Path(__file__).resolve().parents[1]


@pytest.fixture(scope="module")
def gen():
    spec = importlib.util.spec_from_file_location("gen_config_ref", ROOT / "docs" / "gen_config_ref.py")
    module = importlib.util.module_from_spec(spec)
    sys.modules.setdefault("gen_config_ref", module)     # its dataclass looks its module up
    spec.loader.exec_module(module)
    return module


def test_every_key_of_the_schema_has_a_description(gen):
    keys = gen.keys()
    missing = [k.path for k in keys if not k.description]
    assert not missing, f"config keys without Field(description=...) in hwid/config.py: {missing}"


def test_every_recorded_data_key_is_in_the_reference(gen):
    paths = {k.path for k in gen.keys()}
    for name in ("file", "time", "key", "role", "exclude", "start", "stop", "input", "output"):
        assert f"plant.experiments[].{name}" in paths
    assert "plant.output_resolution" in paths
    kind = next(k for k in gen.keys() if k.path == "plant.kind")
    assert kind.allowed.count("`") == 6 and "`recorded`" in kind.allowed


def test_the_committed_reference_is_the_schema_rendered(gen):
    assert gen.PAGE.read_text(encoding="utf-8") == gen.render(), (
        "docs/reference/config.md is stale: run `python docs/gen_config_ref.py` (or `make docs`)")


def test_a_key_without_a_description_is_caught(gen):
    from pydantic import BaseModel, Field

    class Bare(BaseModel):
        said: int = Field(default=1, description="has one")
        unsaid: int = 2

    assert [k.path for k in gen.keys(Bare) if not k.description] == ["unsaid"]
