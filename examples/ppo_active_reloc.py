"""Train stable-baselines3 PPO on ``openreloc/ActiveReloc-v0`` for a short while, then evaluate it.

    pip install -e ".[rl]"      # stable-baselines3
    python examples/ppo_active_reloc.py [--timesteps 4096] [--method openreloc] [--out runs/ppo]

The environments run in worker processes started by ``forkserver`` (SB3's ``SubprocVecEnv``): each
worker creates its own renderer, and the training process never holds an OpenGL context (a live
software-GL context and torch's lazy imports in PPO do not mix). The policy is ``MultiInputPolicy``
over the flat ``Dict`` observation (RGB through SB3's CNN, the estimate / validity / match count
through an MLP). By default the relocalizer runs only when the agent localizes
(``--relocalize-every 0``): with OpenReLoc a call costs about a second on a laptop CPU, so feeding an
estimate at every step (``--relocalize-every 1``) makes training that much slower.
"""

from __future__ import annotations

import argparse
from pathlib import Path

import numpy as np
from stable_baselines3 import PPO
from stable_baselines3.common.env_util import make_vec_env
from stable_baselines3.common.vec_env import SubprocVecEnv

ENV_ID = "openreloc_bench.envs:openreloc/ActiveReloc-v0"  # the module part registers it in each worker


def evaluate(model: PPO, envs, episodes: int) -> list[dict]:
    """Final infos of ``episodes`` episodes of the deterministic policy."""
    finals: list[dict] = []
    obs = envs.reset()
    while len(finals) < episodes:
        action, _ = model.predict(obs, deterministic=True)
        obs, _, dones, infos = envs.step(action)
        finals += [info for done, info in zip(dones, infos) if done]
    return finals[:episodes]


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    ap.add_argument("--timesteps", type=int, default=4096, help="PPO training steps (all workers together)")
    ap.add_argument("--envs", type=int, default=2, help="worker processes")
    ap.add_argument("--n-steps", type=int, default=256, help="PPO rollout length per worker")
    ap.add_argument("--method", default="openreloc", help="relocalizer in the loop")
    ap.add_argument("--relocalize-every", type=int, default=0, help="relocalizer call every N steps (0: at localize)")
    ap.add_argument("--size", type=int, default=64, help="square RGB observation side (SB3's CNN needs >= 36)")
    ap.add_argument("--max-steps", type=int, default=30, help="episode length limit")
    ap.add_argument("--scene", help="scene directory or smoke-suite scene (default: the smoke scene)")
    ap.add_argument("--cache-dir", help="environment cache (default: ~/.cache/openreloc-bench)")
    ap.add_argument("--eval-episodes", type=int, default=20)
    ap.add_argument("--seed", type=int, default=0)
    ap.add_argument("--out", type=Path, default=Path("runs/ppo_active_reloc"))
    args = ap.parse_args()

    env_kwargs = dict(
        scene=args.scene,
        cache_dir=args.cache_dir,
        method=args.method,
        relocalize_every=args.relocalize_every,
        width=args.size,
        height=args.size,
        max_steps=args.max_steps,
    )
    envs = make_vec_env(
        ENV_ID,
        n_envs=args.envs,
        seed=args.seed,
        env_kwargs=env_kwargs,
        vec_env_cls=SubprocVecEnv,
        vec_env_kwargs={"start_method": "forkserver"},
    )
    try:
        model = PPO(
            "MultiInputPolicy",
            envs,
            n_steps=args.n_steps,
            batch_size=min(64, args.n_steps * args.envs),
            seed=args.seed,
            verbose=1,
        )
        model.learn(total_timesteps=args.timesteps)
        args.out.mkdir(parents=True, exist_ok=True)
        model.save(args.out / "ppo_active_reloc")
        finals = evaluate(model, envs, args.eval_episodes)
    finally:
        envs.close()
    success = np.mean([f["success"] for f in finals])
    steps = np.mean([f["episode_steps"] for f in finals])
    print(
        f"PPO after {args.timesteps} steps: success {success:.3f}, mean episode steps {steps:.1f} over {len(finals)} episodes"
    )
    print(f"model saved to {args.out / 'ppo_active_reloc.zip'}")


if __name__ == "__main__":
    main()
