"""The end-to-end demo: generate the demo room, build each method's map, localize its queries in normal
light, in the dark and with objects moved, on the predicted track (RGB only) and, for the methods that
read masks, on the oracle-mask track too; print the metrics and write the leaderboard (tables, HTML,
plots, floor plan).

It runs what these three commands run (printed as it runs, so you can take them from there):

  openreloc-bench eval --suite scenes/demo.yaml --methods openreloc,sift-pnp,nearest-frame \\
      --splits query,query_light3,query_displaced --data OUT/data --out OUT/results/predicted --resume
  openreloc-bench eval --suite scenes/demo.yaml --methods openreloc --track oracle-mask \\
      --data OUT/data --out OUT/results/oracle-mask --resume
  openreloc-bench leaderboard OUT/results/predicted OUT/results/oracle-mask --data OUT/data --out OUT/leaderboard

The room has 40 queries a split, so one query is 2.5 points of recall; the intervals on the board say
how far that carries. A second run reuses the scene, the maps and the finished queries (--resume). Put
your own method beside the others with ``--methods openreloc,sift-pnp,hist-nn --plugin ./hist_nn.py``.
"""

from __future__ import annotations

import argparse
import shlex
from pathlib import Path

from openreloc_bench.commands.options import add_plugin_argument, comma_list
from openreloc_bench.processes import available_cores
from openreloc_bench.tracks import ORACLE_MASK, PREDICTED

NAME = "demo"
HELP = "run the end-to-end demo on one room (about three minutes on two CPU cores)"
ORDER = 1

DEMO_SUITE = Path(__file__).resolve().parents[2] / "scenes" / "demo.yaml"
DEMO_METHODS = "openreloc,sift-pnp,nearest-frame"
DEMO_SPLITS = ("query", "query_light3", "query_displaced")
"""Normal light, the second-darkest setting and moved objects: the paper's three conditions, one each."""


def add_arguments(p: argparse.ArgumentParser) -> None:
    p.add_argument("--out", type=Path, default=Path("runs/demo"), help="output directory")
    p.add_argument(
        "--suite", default=str(DEMO_SUITE), help="suite YAML or a bundled suite's name (default: the demo room)"
    )
    p.add_argument("--methods", default=DEMO_METHODS, help="comma-separated registered methods")
    add_plugin_argument(p)


def run(args: argparse.Namespace) -> int:
    from openreloc_bench.harness import evaluation, leaderboard, runner
    from openreloc_bench.harness.suites import suite_file
    from openreloc_bench.methods import uses_masks

    suite = suite_file(args.suite)
    names = comma_list(args.methods, "--methods")
    data, board = args.out / "data", args.out / "leaderboard"
    workers = available_cores()
    plugin_args = [x for spec in args.plugin for x in ("--plugin", spec)]
    steps = [(PREDICTED, names, list(DEMO_SPLITS))]
    masked = [n for n in names if uses_masks(n)]
    if masked:  # the oracle track on the query split: how much segmentation costs each masked method
        steps.append((ORACLE_MASK, masked, ["query"]))
    results = []
    for track, methods, splits in steps:
        out = args.out / "results" / track
        _say_command(["eval", "--suite", str(suite), "--methods", ",".join(methods), "--track", track,
                      "--splits", ",".join(splits), "--data", str(data), "--out", str(out),
                      "--workers", str(workers), "--resume", *plugin_args])  # fmt: skip
        cfg = runner.EvalConfig(
            data=data, out=out, scenes=[], runs=runner.variant_runs(methods, {}, False), splits=splits,
            track=track, workers=workers, resume=True, plugins=args.plugin,
        )  # fmt: skip
        if evaluation.main(cfg, suite).errors:
            return 1
        results.append(out)
    _say_command(["leaderboard", *map(str, results), "--data", str(data), "--out", str(board)])
    leaderboard.main(results, board, data)
    print(f"\ndemo done: open {board / 'index.html'} (plots in the same folder)")
    return 0


def _say_command(argv: list[str]) -> None:
    """The command line that does the step the demo runs next."""
    print(f"\n$ openreloc-bench {shlex.join(argv)}", flush=True)
