"""Run a reference agent in one of the gymnasium environments and print its success rate (and SPL for ObjectGoal).

``random`` acts uniformly at random; ``scripted`` is the task's heuristic (ActiveReloc: look around
and localize once two answers agree; ObjectGoal: follow the shortest path and stop facing the goal).
Episode e starts from seed ``--seed + e``, so two agents are compared on the same episodes::

  openreloc-bench agent ActiveReloc-v0 --agent scripted --episodes 20
  openreloc-bench agent ObjectGoal-v0 --agent random --episodes 20 --set max_steps=200

Environment options (the env's config fields) come from ``--set key=value`` (YAML values); the
scene defaults to the smoke suite's, generated into the cache on first use.
"""

from __future__ import annotations

import argparse
from pathlib import Path

import numpy as np
import pandas as pd

from openreloc_bench import config
from openreloc_bench.commands.options import add_plugin_argument
from openreloc_bench.data import io, paths
from openreloc_bench.errors import ConfigError

NAME = "agent"
HELP = "run a random or scripted agent in a gymnasium environment; print success (and SPL)"
ORDER = 70


def add_arguments(p: argparse.ArgumentParser) -> None:
    p.add_argument(
        "env_id", metavar="ENV_ID", help="ActiveReloc-v0 or ObjectGoal-v0 (the openreloc/ prefix is optional)"
    )
    p.add_argument("--agent", choices=("random", "scripted"), default="scripted", help="which agent")
    p.add_argument("--episodes", type=int, default=10, help="number of episodes")
    p.add_argument("--seed", type=int, default=0, help="episode e resets with seed SEED + e")
    p.add_argument("--scene", help="scene directory, or a scene name of --suite (default: the suite's first)")
    p.add_argument("--suite", help="suite YAML or bundled suite name (default: smoke)")
    p.add_argument("--method", help="relocalization method in the loop (default: the environment's)")
    add_plugin_argument(p)
    p.add_argument(
        "--set",
        dest="overrides",
        action="append",
        default=[],
        metavar="KEY=VALUE",
        help="environment option (a field of its config; YAML values); repeatable",
    )
    p.add_argument("--out", type=Path, help="also write one CSV row per episode (its final info)")


def run(args: argparse.Namespace) -> int:
    import gymnasium as gym

    from openreloc_bench.envs import ENVIRONMENTS, NAMESPACE
    from openreloc_bench.envs.agents import RandomAgent, run_episodes, scripted_agent

    env_id = args.env_id if "/" in args.env_id else f"{NAMESPACE}/{args.env_id}"
    if env_id not in ENVIRONMENTS:
        raise ConfigError(f"unknown environment '{args.env_id}' (known: {', '.join(ENVIRONMENTS)})")
    if args.episodes < 1:
        raise ConfigError("--episodes must be at least 1")
    if args.seed < 0:
        raise ConfigError(f"--seed must be at least 0 (gymnasium seeds are non-negative), got {args.seed}")
    if args.out:
        paths.check_output_file(args.out, [], "--out")  # not inside a scene or map
    options = config.parse_overrides(args.overrides)
    for key in ("scene", "suite", "method"):
        if getattr(args, key) is not None:
            options[key] = getattr(args, key)
    env = gym.make(env_id, **options)
    try:
        agent = RandomAgent(env, args.seed) if args.agent == "random" else scripted_agent(env)
        finals = run_episodes(env, agent, args.episodes, args.seed)
    finally:
        env.close()
    table = pd.DataFrame(finals).drop(columns=["collided", "relocalized", "goal"], errors="ignore")
    for e, row in table.iterrows():
        shown = {k: v for k, v in row.items() if isinstance(v, (bool, np.bool_, int, float, np.number))}
        print(f"episode {e}: " + ", ".join(f"{k} {_fmt(v)}" for k, v in shown.items()))
    metrics = {"success": table["success"].astype(float)}
    if "spl" in table:
        metrics.update(spl=table["spl"], soft_spl=table["soft_spl"])
    metrics.update(episode_steps=table["episode_steps"], path_length=table["path_length"])
    summary = ", ".join(f"{k} {v.mean():.3f}" for k, v in metrics.items())
    print(
        f"{env_id}, {args.agent} agent, {len(table)} episodes (seeds {args.seed}..{args.seed + len(table) - 1}): {summary}"
    )
    if args.out:
        io.atomic_write_text(args.out, table.to_csv(index_label="episode"))
    return 0


def _fmt(v: object) -> str:
    return f"{v:.3f}" if isinstance(v, (float, np.floating)) else str(v)
