"""Write the dataset card of a suite: ``OUT/<suite>.md`` and its pictures in ``OUT/<suite>/``.

The card reads the suite's generated scenes under --data (it generates nothing: run ``generate``
first) and describes them: the suite's description, purpose, data and generator versions and image
size; per scene its kind, floors, rooms, frames per split, objects and categories; the categories and
look-alike groups (identical twins) over the suite; histograms and percentiles of every difficulty
axis of ``difficulty.csv``; a contact sheet of thumbnails and a top-down plan per scene. The same data
gives the same files, small enough to commit.

  openreloc-bench card scenes/smoke.yaml --data data --out cards
"""

from __future__ import annotations

import argparse
from pathlib import Path

NAME = "card"
HELP = "dataset card of a generated suite (markdown, histograms, contact sheets, plans)"
ORDER = 13


def add_arguments(parser: argparse.ArgumentParser) -> None:
    parser.add_argument(
        "suite", metavar="SUITE", help="suite YAML (e.g. scenes/smoke.yaml) or a bundled suite's name (smoke)"
    )
    parser.add_argument("--data", type=Path, required=True, help="dataset directory holding the suite's scenes")
    parser.add_argument(
        "--out", type=Path, required=True, help="output directory: OUT/<suite>.md, pictures in OUT/<suite>/"
    )


def run(args: argparse.Namespace) -> int:
    from openreloc_bench.data import paths
    from openreloc_bench.harness.card import write_card  # matplotlib: only when used
    from openreloc_bench.harness.suites import suite_file

    suite = suite_file(args.suite)
    paths.check_output(args.out, [args.data], "--out", fills=True)
    files = write_card(suite, args.data, args.out)
    print(files[0])
    print(f"wrote {len(files) - 1} pictures to {files[0].with_suffix('')}")
    return 0
