"""Typed configs: dataclasses with a docstring per field, strict YAML/dict in, YAML out.

Unknown keys, duplicate keys and wrongly typed values raise :class:`ConfigError` naming the key, so a
typo in a suite or method config fails at load time instead of silently using a default. Numbers are
checked generically: a float field takes no NaN or infinity (unless the field opts in with
``field(metadata=ALLOW_NONFINITE)``) and an integer field fits in 64 bits, so no value reaches numpy
or torch as an overflow. Ranges are the config's own business: a dataclass checks them in its
``__post_init__`` with :func:`check_ranges`, which :func:`from_dict` reports as a ConfigError naming
the section (``openreloc.refinement: 'lr_rotation' must be > 0, got -1.0``).
"""

from __future__ import annotations

import ast
import dataclasses
import inspect
import math
import textwrap
import types
import typing
from functools import cache
from pathlib import Path
from typing import Any, TypeVar

import yaml

from openreloc_bench.data import io
from openreloc_bench.errors import ConfigError

T = TypeVar("T")

ALLOW_NONFINITE = {"allow_nonfinite": True}
"""Field metadata of a float field that accepts NaN and infinities (``field(default=..., metadata=ALLOW_NONFINITE)``)."""

_INT64 = 2**63


def from_dict(cls: type[T], data: dict[str, Any] | None, where: str = "") -> T:
    """Build dataclass ``cls`` from plain data, recursing into nested dataclass fields."""
    data = {} if data is None else data
    prefix = f"{where}." if where else ""
    if not isinstance(data, dict):
        raise ConfigError(f"{where or cls.__name__}: expected a mapping, got {type(data).__name__}")
    hints = typing.get_type_hints(cls)
    known = {f.name: f for f in dataclasses.fields(cls)}  # type: ignore[arg-type]
    unknown = sorted((k for k in data if k not in known), key=str)
    if unknown:
        raise ConfigError(f"unknown key '{prefix}{unknown[0]}' (known: {', '.join(sorted(known))})")
    kwargs = {}
    for key, value in data.items():
        finite = not known[key].metadata.get("allow_nonfinite", False)
        kwargs[key] = _coerce(hints[key], value, f"{prefix}{key}", finite)
    try:
        return cls(**kwargs)
    except (TypeError, ValueError) as e:
        raise ConfigError(f"{where or cls.__name__}: {e}") from None


def merge(base: dict[str, Any], overrides: dict[str, Any]) -> dict[str, Any]:
    """``base`` with ``overrides`` applied key by key, recursing into nested mappings (so overriding
    one field of a section keeps the section's other fields); neither input is modified."""
    out = dict(base)
    for key, value in overrides.items():
        old = out.get(key)
        out[key] = merge(old, value) if isinstance(value, dict) and isinstance(old, dict) else value
    return out


def _coerce(tp: Any, value: Any, key: str, finite: bool = True) -> Any:
    origin = typing.get_origin(tp)
    if dataclasses.is_dataclass(tp):
        return from_dict(tp, value, key)  # type: ignore[arg-type]
    if origin in (typing.Union, types.UnionType):
        args = typing.get_args(tp)
        if value is None and type(None) in args:
            return None
        errors = []
        for a in args:
            if a is type(None):
                continue
            try:
                return _coerce(a, value, key, finite)
            except ConfigError as e:
                errors.append(e)
        if len(errors) == 1:  # ``X | None``: X's own message says what is wrong
            raise errors[0]
        raise ConfigError(f"'{key}': value {value!r} does not match {tp}")
    if origin is typing.Literal:
        if value not in typing.get_args(tp):
            raise ConfigError(f"'{key}': {value!r} is not one of {list(typing.get_args(tp))}")
        return value
    if origin in (list, tuple):
        if not isinstance(value, (list, tuple)):
            raise ConfigError(f"'{key}': expected a list, got {value!r}")
        args = typing.get_args(tp)
        if origin is tuple and args and args[-1] is not Ellipsis:  # a fixed-length tuple
            if len(value) != len(args):
                raise ConfigError(f"'{key}': expected {len(args)} values, got {len(value)}")
            return tuple(_coerce(a, v, f"{key}[{i}]", finite) for i, (a, v) in enumerate(zip(args, value)))
        item_t = args[0] if args else Any
        items = [_coerce(item_t, v, f"{key}[{i}]", finite) for i, v in enumerate(value)]
        return tuple(items) if origin is tuple else items
    if origin is dict or tp is dict:
        if not isinstance(value, dict):
            raise ConfigError(f"'{key}': expected a mapping, got {value!r}")
        return dict(value)
    if tp is Any:
        return value
    if tp is bool:
        if not isinstance(value, bool):
            raise ConfigError(f"'{key}': expected true/false, got {value!r}")
        return value
    if tp is float:
        if isinstance(value, bool) or not isinstance(value, (int, float)):
            raise ConfigError(f"'{key}': expected a number, got {value!r}{_number_hint(value)}")
        if finite and not math.isfinite(value):
            raise ConfigError(f"'{key}': expected a finite number, got {value!r}")
        return float(value)
    if tp is int:
        if isinstance(value, bool) or not isinstance(value, int):
            raise ConfigError(f"'{key}': expected an integer, got {value!r}{_number_hint(value)}")
        if not -_INT64 <= value < _INT64:
            raise ConfigError(f"'{key}': {value} is out of range (a 64-bit integer)")
        return value
    if tp is str:
        if not isinstance(value, str):
            raise ConfigError(f"'{key}': expected a string, got {value!r}")
        return value
    if tp is Path:
        if not isinstance(value, (str, Path)):
            raise ConfigError(f"'{key}': expected a path, got {value!r}")
        return Path(value)
    return value


def _number_hint(value: Any) -> str:
    """A hint for text that reads as a number: PyYAML (YAML 1.1) takes ``1e-3`` or ``'3'`` for text."""
    try:
        number = float(value) if isinstance(value, str) else math.nan
    except ValueError:
        return ""
    if not math.isfinite(number):
        return ""
    return " (text in YAML: write exponents with a dot and a sign, e.g. 1.0e-3, and numbers without quotes)"


def check_ranges(
    cfg: Any,
    positive: tuple[str, ...] = (),
    non_negative: tuple[str, ...] = (),
    at_least_one: tuple[str, ...] = (),
    share: tuple[str, ...] = (),
) -> None:
    """ValueError naming the first listed field of ``cfg`` outside its range: ``positive`` (> 0),
    ``non_negative`` (>= 0), ``at_least_one`` (>= 1: counts, sizes, strides) or ``share`` (in [0, 1]).
    A list or tuple field is checked item by item. NaN fails every range.

    For ``__post_init__``, so that a config built in code is checked as one read from YAML is."""
    rules = (
        (positive, lambda v: v > 0, "> 0"),
        (non_negative, lambda v: v >= 0, ">= 0"),
        (at_least_one, lambda v: v >= 1, ">= 1"),
        (share, lambda v: 0 <= v <= 1, "in [0, 1]"),
    )
    for names, ok, what in rules:
        for name in names:
            value = getattr(cfg, name)
            for v in value if isinstance(value, (list, tuple)) else (value,):
                if isinstance(v, bool) or not isinstance(v, (int, float)) or not ok(v):
                    raise ValueError(f"'{name}' must be {what}, got {value!r}")


def to_dict(cfg: Any) -> dict[str, Any]:
    """Plain data (paths as strings, tuples as lists) ready for YAML/JSON."""

    def plain(v: Any) -> Any:
        if dataclasses.is_dataclass(v):
            return {f.name: plain(getattr(v, f.name)) for f in dataclasses.fields(v)}
        if isinstance(v, (list, tuple)):
            return [plain(x) for x in v]
        if isinstance(v, dict):
            return {k: plain(x) for k, x in v.items()}
        if isinstance(v, Path):
            return str(v)
        return v

    return plain(cfg)


def load_yaml(path: Path | str) -> Any:
    """Parse a YAML file; a missing, binary, non-UTF-8 or malformed file is a one-line ConfigError."""
    path = Path(path)
    if not path.is_file():
        raise ConfigError(f"{path}: file not found")
    text = io.read_text(path)
    try:
        return parse_yaml(text)
    except yaml.YAMLError as e:
        raise ConfigError(f"{path}: invalid YAML ({_yaml_problem(e)})") from None


def load_mapping(path: Path | str) -> dict[str, Any]:
    """A YAML file of config keys (empty: no keys); ConfigError unless it is a mapping with text keys."""
    data = load_yaml(path)
    if data is None:
        return {}
    if not isinstance(data, dict):
        raise ConfigError(f"{path}: expected a mapping of config keys, got {type(data).__name__}")
    odd = [k for k in data if not isinstance(k, str)]
    if odd:
        raise ConfigError(f"{path}: key {odd[0]!r} is not a name (config keys are text)")
    return data


def parse_yaml(text: str) -> Any:
    """``yaml.safe_load`` that also refuses a key given twice in one mapping."""
    return yaml.load(text, Loader=_StrictLoader)  # a SafeLoader subclass: no arbitrary objects


def _yaml_problem(e: yaml.YAMLError) -> str:
    """One line: what is wrong and where (line, column), from a PyYAML error."""
    if isinstance(e, yaml.MarkedYAMLError) and e.problem:
        mark = e.problem_mark or e.context_mark
        where = f" at line {mark.line + 1}, column {mark.column + 1}" if mark else ""
        return f"{e.problem}{where}"
    return " ".join(str(e).split())


class _StrictLoader(yaml.SafeLoader):
    """``yaml.safe_load`` that refuses a key given twice in one mapping (PyYAML keeps the last one
    silently, so ``seed: 1`` followed by ``seed: 2`` would run with 2 without a word)."""

    def construct_mapping(self, node: yaml.MappingNode, deep: bool = False) -> dict[Any, Any]:
        seen: set[Any] = set()
        for key_node, _ in node.value:
            key = self.construct_object(key_node, deep=True)
            try:
                duplicate = key in seen
                seen.add(key)
            except TypeError:  # an unhashable key: the base class reports it
                break
            if duplicate:
                raise yaml.constructor.ConstructorError(
                    "while constructing a mapping", node.start_mark, f"found duplicate key {key!r}", key_node.start_mark
                )
        return super().construct_mapping(node, deep=deep)


def parse_overrides(items: list[str]) -> dict[str, Any]:
    """``["a.b=1", "c=true"]`` -> ``{"a": {"b": 1}, "c": True}`` (``--set`` values parsed as YAML)."""
    out: dict[str, Any] = {}
    for item in items:
        key, sep, raw = item.partition("=")
        if not sep or not key.strip():
            raise ConfigError(f"--set expects KEY=VALUE, got {item!r}")
        try:
            value = parse_yaml(raw) if raw.strip() else ""
        except yaml.YAMLError:
            value = raw
        node = out
        parts = key.strip().split(".")
        for part in parts[:-1]:
            nxt = node.setdefault(part, {})
            if not isinstance(nxt, dict):
                raise ConfigError(f"--set {key}: '{part}' was already set to a value")
            node = nxt
        node[parts[-1]] = value
    return out


def dump_yaml(cfg: Any) -> str:
    return yaml.safe_dump(to_dict(cfg), sort_keys=False)


def commented_yaml(cfg: Any, width: int = 100) -> str:
    """``cfg`` (a dataclass instance) as YAML with each field's docstring as a comment above it, nested
    sections indented: a settings file to read and edit, which :func:`from_dict` reads back to ``cfg``."""
    lines: list[str] = []
    _commented(cfg, 0, width, lines)
    return "\n".join(lines) + "\n"


def _commented(cfg: Any, depth: int, width: int, lines: list[str]) -> None:
    indent = "  " * depth
    docs = field_docs(type(cfg))
    for f in dataclasses.fields(cfg):
        value = getattr(cfg, f.name)
        doc = docs.get(f.name) or (_section_doc(type(value)) if dataclasses.is_dataclass(value) else "")
        if doc:
            lines += textwrap.wrap(doc, width, initial_indent=f"{indent}# ", subsequent_indent=f"{indent}# ")
        if dataclasses.is_dataclass(value):
            lines.append(f"{indent}{f.name}:")
            _commented(value, depth + 1, width, lines)
        else:  # one flow-style line; dumping a one-item list quotes strings that would read as another type
            flow = yaml.safe_dump([to_dict(value)], default_flow_style=True, width=math.inf).strip()[1:-1]
            lines.append(f"{indent}{f.name}: {flow}")


def _section_doc(cls: type) -> str:
    """The first paragraph of a nested config's class docstring (not the one dataclasses makes up)."""
    doc = inspect.getdoc(cls) or ""
    return "" if doc.startswith(f"{cls.__name__}(") else " ".join(doc.split("\n\n")[0].split())


@cache
def field_docs(cls: type) -> dict[str, str]:
    """The docstring written under each field of a dataclass (for --help and generated docs)."""
    docs: dict[str, str] = {}
    for klass in reversed(cls.__mro__):
        if not dataclasses.is_dataclass(klass):
            continue
        try:
            tree = ast.parse(textwrap.dedent(inspect.getsource(klass)))
        except (OSError, TypeError):
            continue
        body = tree.body[0].body  # type: ignore[attr-defined]
        for node, nxt in zip(body, body[1:]):
            if (
                isinstance(node, ast.AnnAssign)
                and isinstance(node.target, ast.Name)
                and isinstance(nxt, ast.Expr)
                and isinstance(nxt.value, ast.Constant)
                and isinstance(nxt.value.value, str)
            ):
                docs[node.target.id] = " ".join(nxt.value.value.split())
    return docs


def describe(cls: type) -> str:
    """Human-readable listing of a config's fields, defaults and docs."""
    docs = field_docs(cls)
    lines = []
    for f in dataclasses.fields(cls):
        default = (
            f.default
            if f.default is not dataclasses.MISSING
            else (
                f.default_factory() if f.default_factory is not dataclasses.MISSING else "required"  # type: ignore[misc]
            )
        )
        lines.append(f"  {f.name} = {default!r}\n      {docs.get(f.name, '')}")
    return "\n".join(lines)
