"""List the relocalization methods registered through the ``openreloc_bench.methods`` entry points."""

from __future__ import annotations

import argparse

from openreloc_bench.methods import available_methods

NAME = "methods"
HELP = "list registered relocalization methods"
ORDER = 90


def add_arguments(parser: argparse.ArgumentParser) -> None:
    pass


def run(args: argparse.Namespace) -> int:
    for name, factory in sorted(available_methods().items()):
        print(f"{name:30s} {factory.__doc__ or ''}")
    return 0
