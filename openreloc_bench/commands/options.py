"""Arguments several commands share (not a command itself: it has no ``NAME``)."""

from __future__ import annotations

import argparse
from pathlib import Path
from typing import Any

from openreloc_bench import config


def add_method_arguments(p: argparse.ArgumentParser) -> None:
    """``--method``, ``--config`` and ``--set``: shared by ``map`` and ``localize``."""
    p.add_argument("--method", required=True, help="registered method name (see `openreloc-bench methods`)")
    add_method_config_arguments(p)


def add_method_config_arguments(p: argparse.ArgumentParser) -> None:
    """``--config`` and ``--set``: a method's settings (``map``, ``localize``, ``config``)."""
    p.add_argument("--config", type=Path, help="YAML mapping of method config fields (`openreloc-bench config METHOD`)")
    p.add_argument(
        "--set",
        dest="overrides",
        action="append",
        default=[],
        metavar="KEY=VALUE",
        help="override one config field (dotted keys for nested sections; YAML values); repeatable",
    )


def method_overrides(args: argparse.Namespace) -> dict[str, Any]:
    """The method config from ``--config`` then ``--set`` (later wins)."""
    base = config.load_mapping(args.config) if args.config else {}
    return config.merge(base, config.parse_overrides(args.overrides))
