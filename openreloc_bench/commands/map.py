"""Build a method's map from the ``mapping`` split of one scene.

Works for every registered method (``openreloc-bench methods`` lists them). Method settings come from
``--config`` (a YAML mapping of the method's config fields) and ``--set key=value`` (repeatable; dotted
keys reach nested sections, values are parsed as YAML), e.g.::

  openreloc-bench map --method openreloc --scene data/smoke-room --out maps/smoke \\
      --set mapping.landmark_voxel=0.03 --set encoder=clip
"""

from __future__ import annotations

import argparse
import time
from pathlib import Path
from typing import Any

import yaml

from openreloc_bench import config
from openreloc_bench.data.scene import Scene
from openreloc_bench.errors import ConfigError
from openreloc_bench.methods import create_method

NAME = "map"
HELP = "build a method's map from a scene's mapping split"
ORDER = 20


def add_method_arguments(p: argparse.ArgumentParser) -> None:
    """``--method``, ``--config`` and ``--set``: shared with ``localize``."""
    p.add_argument("--method", required=True, help="registered method name (see `openreloc-bench methods`)")
    p.add_argument("--config", type=Path, help="YAML mapping of method config fields")
    p.add_argument(
        "--set",
        dest="overrides",
        action="append",
        default=[],
        metavar="KEY=VALUE",
        help="override one config field (dotted keys for nested sections; YAML values); repeatable",
    )


def add_arguments(p: argparse.ArgumentParser) -> None:
    add_method_arguments(p)
    p.add_argument("--scene", type=Path, required=True, help="scene directory (with a mapping split)")
    p.add_argument("--out", type=Path, required=True, help="map directory to write")


def parse_overrides(items: list[str]) -> dict[str, Any]:
    """``["a.b=1", "c=true"]`` -> ``{"a": {"b": 1}, "c": True}`` (values parsed as YAML)."""
    out: dict[str, Any] = {}
    for item in items:
        key, sep, raw = item.partition("=")
        if not sep or not key.strip():
            raise ConfigError(f"--set expects KEY=VALUE, got {item!r}")
        try:
            value = yaml.safe_load(raw) if raw.strip() else ""
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


def _merge(base: dict[str, Any], extra: dict[str, Any]) -> dict[str, Any]:
    out = dict(base)
    for k, v in extra.items():
        out[k] = _merge(out[k], v) if isinstance(v, dict) and isinstance(out.get(k), dict) else v
    return out


def method_overrides(args: argparse.Namespace) -> dict[str, Any]:
    """The method config from ``--config`` then ``--set`` (later wins)."""
    base = config.load_yaml(args.config) if args.config else {}
    if base is None:
        base = {}
    if not isinstance(base, dict):
        raise ConfigError(f"{args.config}: expected a mapping of config fields")
    return _merge(base, parse_overrides(args.overrides))


def run(args: argparse.Namespace) -> int:
    method = create_method(args.method, **method_overrides(args))
    seq = Scene(args.scene).sequence("mapping")
    t0 = time.perf_counter()
    method.build_map(seq, args.out)
    elapsed = time.perf_counter() - t0
    size = sum(p.stat().st_size for p in Path(args.out).rglob("*") if p.is_file())
    print(
        f"{args.method}: map of {len(seq)} mapping frames written to {args.out} ({size / 1e6:.3f} MB, {elapsed:.1f} s)"
    )
    return 0
