from dataclasses import dataclass, field
from pathlib import Path
from typing import Literal

import pytest

from openreloc_bench.config import (
    ALLOW_NONFINITE,
    check_ranges,
    describe,
    dump_yaml,
    field_docs,
    from_dict,
    load_mapping,
    load_yaml,
    merge,
)
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


@dataclass
class Numbers:
    rate: float = 0.5
    """A share."""
    count: int = 3
    """A count."""
    bound: float = field(default=1.0, metadata=ALLOW_NONFINITE)
    """May be infinite (opts in)."""
    levels: list[float] = field(default_factory=lambda: [0.5])
    """Shares."""

    def __post_init__(self) -> None:
        check_ranges(self, at_least_one=("count",), share=("rate", "levels"))


@pytest.mark.parametrize(
    "data, message",
    [
        ({"rate": float("nan")}, "'rate': expected a finite number, got nan"),
        ({"rate": float("-inf")}, "'rate': expected a finite number"),
        ({"levels": [0.5, float("inf")]}, "'levels[1]': expected a finite number"),
        ({"count": 2**63}, "'count': 9223372036854775808 is out of range"),
        ({"rate": "1e-3"}, "write exponents with a dot"),
        ({"rate": 1.5}, "Numbers: 'rate' must be in [0, 1], got 1.5"),
        ({"count": 0}, "Numbers: 'count' must be >= 1, got 0"),
        ({"levels": [0.5, -0.1]}, "'levels' must be in [0, 1]"),
        ({1: 2, "b": 3}, "unknown key '1'"),
    ],
)
def test_numbers_are_finite_and_in_range(data, message):
    with pytest.raises(ConfigError) as e:
        from_dict(Numbers, data)
    assert message in str(e.value)


def test_a_field_may_opt_in_to_infinity_and_code_is_checked_like_yaml():
    assert from_dict(Numbers, {"bound": float("inf")}).bound == float("inf")
    with pytest.raises(ValueError, match="'count' must be >= 1"):
        Numbers(count=-2)


@pytest.mark.parametrize(
    "text, message",
    [
        ("seed: 1\nseed: 2\n", "found duplicate key 'seed' at line 2, column 1"),
        ("scenes:\n  - name: a\n    name: b\n", "found duplicate key 'name' at line 3"),
    ],
)
def test_a_key_given_twice_is_an_error_not_the_last_one_silently(tmp_path: Path, text: str, message: str):
    (tmp_path / "x.yaml").write_text(text)
    with pytest.raises(ConfigError, match=message):
        load_yaml(tmp_path / "x.yaml")


def test_a_mapping_file_needs_text_keys(tmp_path: Path):
    (tmp_path / "x.yaml").write_text("1: a\n")
    with pytest.raises(ConfigError, match="key 1 is not a name"):
        load_mapping(tmp_path / "x.yaml")
    (tmp_path / "y.yaml").write_text("")
    assert load_mapping(tmp_path / "y.yaml") == {}


def _config_classes() -> list[type]:
    """Every dataclass of the project that a user's YAML or ``--set`` fills (``from_dict`` with no keys
    builds it): method, scene, environment and campaign configs and their sections."""
    import dataclasses
    import importlib
    import inspect
    import pkgutil

    import baselines
    import generators
    import openreloc_bench

    found = {}
    for package in (openreloc_bench, generators, baselines):
        for info in pkgutil.walk_packages(package.__path__, package.__name__ + "."):
            module = importlib.import_module(info.name)
            for _, cls in inspect.getmembers(module, dataclasses.is_dataclass):
                if isinstance(cls, type) and cls.__module__ == info.name:
                    try:
                        from_dict(cls, {})
                    except Exception:  # noqa: BLE001 -- required fields: not filled from a user's file
                        continue
                    found[f"{cls.__module__}.{cls.__qualname__}"] = cls
    return [found[k] for k in sorted(found)]


def _float_fields(cls: type, prefix: tuple[str, ...] = ()) -> list[tuple[str, ...]]:
    import dataclasses
    import typing

    hints = typing.get_type_hints(cls)
    out = []
    for f in dataclasses.fields(cls):
        tp = hints[f.name]
        if tp is float and not f.metadata.get("allow_nonfinite"):
            out.append((*prefix, f.name))
        elif dataclasses.is_dataclass(tp):
            out += _float_fields(tp, (*prefix, f.name))
    return out


@pytest.mark.parametrize("cls", _config_classes(), ids=lambda c: f"{c.__module__}.{c.__qualname__}")
def test_every_float_field_refuses_nan_and_infinity(cls: type) -> None:
    for path in _float_fields(cls):
        for bad in (float("nan"), float("inf"), float("-inf")):
            data: dict = {}
            node = data
            for key in path[:-1]:
                node = node.setdefault(key, {})
            node[path[-1]] = bad
            with pytest.raises(ConfigError, match="finite"):
                from_dict(cls, data)
