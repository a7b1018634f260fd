"""Arguments several commands share (not a command itself: it has no ``NAME``)."""

from __future__ import annotations

import argparse
from pathlib import Path
from typing import Any

from openreloc_bench import config, plugins
from openreloc_bench.errors import ConfigError
from openreloc_bench.tracks import DEFAULT_TRACK, TRACKS


def add_method_arguments(p: argparse.ArgumentParser) -> None:
    """``--method``, ``--plugin``, ``--config`` and ``--set``: shared by ``map`` and ``localize``."""
    p.add_argument("--method", required=True, help="registered method name (see `openreloc-bench methods`)")
    add_plugin_argument(p)
    add_method_config_arguments(p)


def add_plugin_argument(p: argparse.ArgumentParser) -> None:
    """``--plugin``: every command that names a method (the CLI imports them before the command runs)."""
    p.add_argument(
        "--plugin",
        action="append",
        default=[],
        metavar="MODULE|FILE",
        help="a module name or a .py file (a path relative to the working folder) whose import registers "
        "methods with openreloc_bench.methods.register; imported first; repeatable",
    )


def load_plugin_arguments(args: argparse.Namespace) -> None:
    """Import the ``--plugin``s of ``args`` (none for commands without the option), each replaced by the
    form worker processes import it by; a bad plugin is a one-line ConfigError."""
    if getattr(args, "plugin", None):
        args.plugin = plugins.load_plugins(args.plugin)


def add_track_argument(p: argparse.ArgumentParser, text: str, choices: tuple[str, ...] = TRACKS) -> None:
    """``--track``, defaulting to the one default track (``tracks.DEFAULT_TRACK``)."""
    p.add_argument("--track", default=DEFAULT_TRACK, choices=choices, help=text)


TRACK_HELP = (
    "predicted: no instance image anywhere, a method segments for itself; oracle-mask: the dataset's instance "
    "masks with every frame (a perfect detector). Methods that read no masks are recorded as mask-free"
)
"""What ``--track`` means, for the commands that run methods."""


def comma_list(text: str, flag: str) -> list[str]:
    """The comma-separated names of ``flag``'s value, each once, in order; ConfigError when there is none."""
    names = list(dict.fromkeys(x.strip() for x in text.split(",") if x.strip()))
    if not names:
        raise ConfigError(f"{flag} names nothing: give comma-separated names")
    return names


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
