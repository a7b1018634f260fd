"""Regenerate the leaderboard in one command: generate the plan's suites, build every method's maps,
run every method on every suite, track, split and seed (and the ablations), then write one board per
suite, a screenshot of each, and OUT/campaign.md (the commit, wall time by stage, the longest steps,
the summary table); --verdict-into FILE replaces the block between FILE's verdict markers with the
verdict table (scripts/leaderboard.sh: README.md and leaderboard/README.md).

Every row comes from one code version, the last commit that changed the code (commits of results, docs
or tests keep it): uncommitted changes to the code are refused, and a WORK folder started at another code
version too. Resumable: run the same command again and only the steps
not yet finished run (inside a step, only its unfinished jobs). Steps run in priority order (the query
split of every method first, then the robustness splits, the further seeds of the query split, the ablations), so an
unfinished campaign already renders useful boards (--render-only).

Example:
  openreloc-bench campaign leaderboard/plan.yaml --data data --work results/campaign --out leaderboard
"""

from __future__ import annotations

import argparse
from pathlib import Path

from openreloc_bench.data import paths
from openreloc_bench.harness.executors import EXECUTORS

NAME = "campaign"
HELP = "regenerate every board: all methods, suites, tracks, splits, seeds at one code version"
ORDER = 45


def add_arguments(p: argparse.ArgumentParser) -> None:
    p.add_argument(
        "plan", type=Path, metavar="PLAN", help="plan YAML (leaderboard/plan.yaml: the committed boards' plan)"
    )
    p.add_argument("--data", type=Path, required=True, help="dataset folder (missing suites are generated into it)")
    p.add_argument("--work", type=Path, required=True, help="results of every step, and the campaign's record")
    p.add_argument("--out", type=Path, default=Path("leaderboard"), help="boards folder")
    p.add_argument("--executor", default="local", choices=EXECUTORS, help="where each step's jobs run")
    p.add_argument("--workers", type=int, default=2, help="parallel jobs per step (local executor)")
    p.add_argument("--ray-address", help="existing Ray cluster (default: $RAY_ADDRESS, else a local instance)")
    p.add_argument("--render-only", action="store_true", help="render the boards from the finished steps only")
    p.add_argument("--no-screenshot", action="store_true", help="skip the boards' screenshots")
    p.add_argument("--allow-dirty", action="store_true", help="run with uncommitted changes (a trial run)")
    p.add_argument(
        "--verdict-into", type=Path, action="append", default=[], metavar="FILE",
        help="a README whose verdict block (between its verdict markers) the verdict table replaces; repeatable",
    )  # fmt: skip
    p.add_argument("--list", action="store_true", help="print the plan's steps and whether each is done")


def run(args: argparse.Namespace) -> int:
    from openreloc_bench.harness import campaign

    plan = campaign.load_plan(args.plan)
    for flag, folder in (("--work", args.work), ("--out", args.out)):
        if folder is not None and not args.list:
            paths.check_output_folder(folder, [], flag)
    if args.list:
        campaign.list_steps(plan, args.work)
        return 0
    cfg = campaign.CampaignConfig(
        plan=plan, data=args.data, work=args.work, out=args.out, executor=args.executor, workers=args.workers,
        ray_address=args.ray_address, allow_dirty=args.allow_dirty, render_only=args.render_only,
        screenshot=not args.no_screenshot, verdict_into=args.verdict_into,
    )  # fmt: skip
    failed = campaign.run_campaign(cfg)
    if failed:
        print(f"{failed} step(s) had errors (listed above); run the same command again to retry them")
    return 1 if failed else 0
