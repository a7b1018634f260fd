"""The end-to-end demo: generate the smoke scene, build each method's map, localize every query split
(normal, lighting decay 1-4, displaced objects), print the metrics table and write the leaderboard
(tables, HTML, plots) for the run.

It runs what these two commands run (printed as it runs, so you can take them from there):

  openreloc-bench eval --suite scenes/smoke.yaml --methods openreloc,nearest-frame \\
      --data OUT/data --out OUT/results --robustness --resume
  openreloc-bench leaderboard OUT/results --out OUT/leaderboard

A second run reuses the scene, the maps and the finished queries (--resume). Put your own method
beside the others with ``--methods openreloc,nearest-frame,hist-nn --plugin ./hist_nn.py``.
"""

from __future__ import annotations

import argparse
import shlex
from pathlib import Path

from openreloc_bench.commands.options import add_plugin_argument, comma_list
from openreloc_bench.errors import ConfigError

NAME = "demo"
HELP = "run the end-to-end demo on the smoke scene (a couple of minutes on a laptop CPU)"
ORDER = 1

SMOKE_SUITE = Path(__file__).resolve().parents[2] / "scenes" / "smoke.yaml"


def add_arguments(p: argparse.ArgumentParser) -> None:
    p.add_argument("--out", type=Path, default=Path("runs/demo"), help="output directory")
    p.add_argument("--suite", type=Path, default=SMOKE_SUITE, help="suite YAML (default: the smoke suite)")
    p.add_argument("--methods", default="openreloc,nearest-frame", help="comma-separated registered methods")
    add_plugin_argument(p)


def run(args: argparse.Namespace) -> int:
    from openreloc_bench.harness import evaluation, leaderboard, runner
    from openreloc_bench.harness.ablations import ROBUSTNESS_ROWS

    if not args.suite.is_file():
        raise ConfigError(f"suite file {args.suite} not found (run from a checkout, or pass --suite)")
    data, results, board = args.out / "data", args.out / "results", args.out / "leaderboard"
    _say_command(["eval", "--suite", str(args.suite), "--methods", args.methods, "--data", str(data),
                  "--out", str(results), "--robustness", "--resume",
                  *(x for spec in args.plugin for x in ("--plugin", spec))])  # fmt: skip
    cfg = runner.EvalConfig(
        data=data, out=results, scenes=[], runs=runner.variant_runs(comma_list(args.methods, "--methods"), {}, False),
        splits=[r.key for r in ROBUSTNESS_ROWS], resume=True, plugins=args.plugin,
    )  # fmt: skip
    if evaluation.main(cfg, args.suite).errors:
        return 1
    _say_command(["leaderboard", str(results), "--out", str(board)])
    leaderboard.main([results], board)
    print(f"\ndemo done: open {board / 'index.html'} (plots in the same folder)")
    return 0


def _say_command(argv: list[str]) -> None:
    """The command line that does the step the demo runs next."""
    print(f"\n$ openreloc-bench {shlex.join(argv)}", flush=True)
