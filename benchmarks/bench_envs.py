"""Speed and memory of the gymnasium environments (prints numbers; not a test).

    python benchmarks/bench_envs.py [--scene DIR] [--method openreloc] [--sizes 128x128,640x480]
        [--steps 1000] [--reloc-steps 30] [--random-steps 10000]

For ``openreloc/ActiveReloc-v0`` on one scene (default: the smoke scene, generated into the cache on
first use), at each image size: environment steps per second of one environment and of an async
vector environment of 2 (forkserver workers), without relocalizer calls (``relocalize_every=0`` and
random moves only, so the task never asks) and with one call per step (``--method``). Then
``--random-steps`` uniformly random actions (localize included, which ends episodes; relocalizer
``--memory-method``) in one environment, with the resident memory before and after (first measured
after a warm-up, so the renderer's and the map's one-time allocations are not counted as growth).
Targets (issue 38): >= 300 steps/s at 128x128 without relocalizer calls (one env, 2 cores); 10,000
random steps without an error and without memory growth.
"""

from __future__ import annotations

import argparse
import os
import sys
import time
from pathlib import Path

import gymnasium as gym
import numpy as np

sys.path.insert(0, str(Path(__file__).resolve().parents[1]))

import openreloc_bench.envs  # noqa: E402,F401  (registers the environments)
from openreloc_bench.envs.base import MOVES  # noqa: E402

ENV_ID = "openreloc/ActiveReloc-v0"


def rss_mb() -> float:
    """Resident set size of this process (MB), from /proc (Linux)."""
    with open("/proc/self/status") as fh:
        kb = next(int(line.split()[1]) for line in fh if line.startswith("VmRSS:"))
    return kb / 1024


def single(options: dict, steps: int, rng: np.random.Generator) -> float:
    env = gym.make(ENV_ID, **options)
    env.reset(seed=0)
    env.step(0)  # GL context, textures, map: not part of the rate
    t = time.perf_counter()
    for _ in range(steps):
        *_, terminated, truncated, _ = env.step(int(rng.integers(len(MOVES))))
        if terminated or truncated:
            env.reset()
    rate = steps / (time.perf_counter() - t)
    env.close()
    return rate


def vector(options: dict, steps: int, rng: np.random.Generator, n: int = 2) -> float:
    envs = gym.make_vec(
        ENV_ID, num_envs=n, vectorization_mode="async", vector_kwargs={"context": "forkserver"}, **options
    )
    envs.reset(seed=0)
    envs.step(np.zeros(n, dtype=np.int64))
    t = time.perf_counter()
    for _ in range(steps // n):
        envs.step(rng.integers(len(MOVES), size=n))  # autoreset handles episode ends
    rate = n * (steps // n) / (time.perf_counter() - t)
    envs.close()
    return rate


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    ap.add_argument("--scene", help="scene directory or a scene of --suite (default: the smoke scene)")
    ap.add_argument("--suite", default="smoke")
    ap.add_argument(
        "--cache-dir", help="environment cache (default: $OPENRELOC_BENCH_CACHE or ~/.cache/openreloc-bench)"
    )
    ap.add_argument("--method", default="openreloc", help="relocalizer of the with-calls rows")
    ap.add_argument("--memory-method", default="nearest-frame", help="relocalizer of the random-steps run")
    ap.add_argument("--sizes", default="128x128,640x480", help="comma-separated WxH")
    ap.add_argument("--steps", type=int, default=1000, help="steps per row without relocalizer calls")
    ap.add_argument("--reloc-steps", type=int, default=30, help="steps per row with a relocalizer call each")
    ap.add_argument("--random-steps", type=int, default=10_000)
    args = ap.parse_args()
    base = {"scene": args.scene, "suite": args.suite, "cache_dir": args.cache_dir, "max_steps": 50}
    rng = np.random.default_rng(0)
    print(f"{ENV_ID} on {args.scene or args.suite}, load average {os.getloadavg()[0]:.1f} on {os.cpu_count()} CPUs")
    print(f"{'size':>9} {'relocalizer':>14} {'1 env steps/s':>14} {'async x2 steps/s':>17}")
    for size in args.sizes.split(","):
        w, h = (int(v) for v in size.lower().split("x"))
        for label, extra, steps in (
            ("none", {"method": args.memory_method, "relocalize_every": 0}, args.steps),
            (args.method, {"method": args.method, "relocalize_every": 1}, args.reloc_steps),
        ):
            options = {**base, **extra, "width": w, "height": h}
            one, two = single(options, steps, rng), vector(options, steps, rng)
            print(f"{size:>9} {label:>14} {one:14.1f} {two:17.1f}", flush=True)

    env = gym.make(ENV_ID, **base, method=args.memory_method, relocalize_every=0)
    env.action_space.seed(0)
    env.reset(seed=0)
    warmup = min(500, args.random_steps // 2)
    episodes, t = 0, time.perf_counter()
    for i in range(args.random_steps):
        if i == warmup:
            before = rss_mb()
        *_, terminated, truncated, _ = env.step(env.action_space.sample())
        if terminated or truncated:
            episodes += 1
            env.reset()
    dt = time.perf_counter() - t
    after = rss_mb()
    env.close()
    print(
        f"{args.random_steps} random steps ({episodes} episodes, relocalizer {args.memory_method} at localize): "
        f"{args.random_steps / dt:.0f} steps/s, RSS {before:.1f} MB after {warmup} steps -> {after:.1f} MB "
        f"({after - before:+.1f} MB)"
    )


if __name__ == "__main__":
    main()
