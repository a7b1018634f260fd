"""Print a method's settings with each field's documentation, as YAML that the method's config
options read back: ``eval --method-config NAME=FILE`` and ``map``/``localize --config FILE``.

Example:
  openreloc-bench config openreloc > my-openreloc.yaml   # edit, then
  openreloc-bench eval --suite scenes/validation.yaml --methods openreloc \\
      --method-config openreloc=my-openreloc.yaml --data data --out results
"""

from __future__ import annotations

import argparse
import dataclasses

from openreloc_bench import config
from openreloc_bench.commands.options import add_method_config_arguments, add_plugin_argument, method_overrides
from openreloc_bench.methods import create_method

NAME = "config"
HELP = "print a method's default settings, documented, as YAML for --method-config"
ORDER = 91


def add_arguments(p: argparse.ArgumentParser) -> None:
    p.add_argument("method", metavar="METHOD", help="registered method name (see `openreloc-bench methods`)")
    add_plugin_argument(p)
    add_method_config_arguments(p)


def run(args: argparse.Namespace) -> int:
    method = create_method(args.method, **method_overrides(args))
    cfg = getattr(method, "config", None)
    changed = " with the given changes" if args.config or args.overrides else " (defaults)"
    print(f"# {args.method} settings{changed}: --method-config {args.method}=FILE or --config FILE reads them")
    if dataclasses.is_dataclass(cfg) and not isinstance(cfg, type):
        print(config.commented_yaml(cfg), end="")
    else:
        print(f"# {args.method} declares no typed settings")
    return 0
