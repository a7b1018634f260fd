"""Render the leaderboard from one or more results directories (of ``eval``, or ``score``'s --out):
a markdown table, a CSV, a static HTML page with sortable columns, and plots (cumulative
translation / rotation error curves, per-scene recall bars, top-down ground truth vs estimates (over
each scene's floor plan with --data), recall against each query's difficulty, whose numbers go to
difficulty.csv).

Each row stands under the track its run recorded: mask-free for a method that declared it reads no
masks (its rows stand in both tracks' tables). Results written before tracks were recorded that way
are read by the earlier rule, the method's declaration as registered now: --plugin registers a
plugin's methods for that.
"""

from __future__ import annotations

import argparse
from pathlib import Path

from openreloc_bench.commands.options import add_plugin_argument

NAME = "leaderboard"
HELP = "render the leaderboard (markdown, CSV, HTML, plots) from results"
ORDER = 50


def add_arguments(p: argparse.ArgumentParser) -> None:
    p.add_argument("results", type=Path, nargs="+", metavar="RESULTS", help="results directories")
    p.add_argument(
        "--out",
        type=Path,
        help="output directory (default: beside the first RESULTS, named after it: results/mine -> results/mine-board)",
    )
    p.add_argument(
        "--data",
        type=Path,
        help="dataset directory the results ran on: draws each scene's floor plan under its top-down plot",
    )
    add_plugin_argument(p)


def default_out(results: Path) -> Path:
    """The board's folder when --out is not given: a sibling of the results, never inside them nor in the
    repository's committed ``leaderboard/``."""
    resolved = results.resolve()
    return resolved.parent / f"{resolved.name}-board"


def run(args: argparse.Namespace) -> int:
    from openreloc_bench.harness import leaderboard  # matplotlib: only when used

    leaderboard.main(args.results, args.out or default_out(args.results[0]), args.data)
    return 0
