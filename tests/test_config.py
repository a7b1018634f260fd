from dataclasses import dataclass, field
from pathlib import Path
from typing import Literal

import pytest

from openreloc_bench.config import describe, dump_yaml, field_docs, from_dict, load_yaml, merge
from openreloc_bench.errors import ConfigError


@dataclass
class Inner:
    k: int = 5
    """How many views."""


@dataclass
class Outer:
    lr: float = 0.025
    """Adam learning rate."""
    mode: Literal["diou", "visibility"] = "diou"
    """Retrieval ranking."""
    inner: Inner = field(default_factory=Inner)
    """Nested config."""
    path: Path | None = None
    """Optional file."""


def test_round_trip_yaml(tmp_path: Path):
    cfg = from_dict(Outer, {"lr": 1, "mode": "visibility", "inner": {"k": 3}, "path": "a/b"})
    assert cfg == Outer(lr=1.0, mode="visibility", inner=Inner(3), path=Path("a/b"))
    (tmp_path / "c.yaml").write_text(dump_yaml(cfg))
    assert from_dict(Outer, load_yaml(tmp_path / "c.yaml")) == cfg


@pytest.mark.parametrize(
    "data, message",
    [
        ({"lrr": 1}, "unknown key 'lrr'"),
        ({"inner": {"kk": 1}}, "unknown key 'inner.kk'"),
        ({"lr": "fast"}, "'lr': expected a number"),
        ({"mode": "bogus"}, "'mode': 'bogus' is not one of"),
        ({"inner": {"k": 1.5}}, "'inner.k': expected an integer"),
    ],
)
def test_errors_name_the_key(data, message):
    with pytest.raises(ConfigError, match=message):
        from_dict(Outer, data)


def test_field_docs_and_describe():
    assert field_docs(Outer)["lr"] == "Adam learning rate."
    assert "Retrieval ranking." in describe(Outer)


def test_invalid_yaml(tmp_path: Path):
    (tmp_path / "x.yaml").write_text("a: [1, 2\n")
    with pytest.raises(ConfigError, match="invalid YAML"):
        load_yaml(tmp_path / "x.yaml")


def test_merge_overrides_section_by_section_without_touching_its_inputs():
    base = {"a": 1, "inner": {"x": 1, "y": {"deep": 1, "keep": 2}}, "replaced": {"x": 1}}
    overrides = {"inner": {"y": {"deep": 3}, "z": 4}, "replaced": 5, "new": {"k": 6}}
    assert merge(base, overrides) == {
        "a": 1,
        "inner": {"x": 1, "y": {"deep": 3, "keep": 2}, "z": 4},
        "replaced": 5,
        "new": {"k": 6},
    }
    assert base["inner"]["y"] == {"deep": 1, "keep": 2} and overrides["inner"] == {"y": {"deep": 3}, "z": 4}
