"""List the registered relocalization methods: the built-ins, installed packages' ``openreloc_bench.methods``
entry points, and what ``--plugin`` modules or files register.

  openreloc-bench methods --plugin ./hist_nn.py
"""

from __future__ import annotations

import argparse

from openreloc_bench.commands.options import add_plugin_argument
from openreloc_bench.methods import available_methods

NAME = "methods"
HELP = "list registered relocalization methods"
ORDER = 90


def add_arguments(parser: argparse.ArgumentParser) -> None:
    add_plugin_argument(parser)


def run(args: argparse.Namespace) -> int:
    for name, factory in sorted(available_methods().items()):
        doc = (factory.__doc__ or "").strip().splitlines()
        print(f"{name:30s} {doc[0] if doc else f'registered by {factory.__module__}'}")
    return 0
