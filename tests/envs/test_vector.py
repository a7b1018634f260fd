"""Vector environments: asynchronous workers started by forkserver or spawn (each renders for itself)."""

from __future__ import annotations

import gymnasium as gym
import numpy as np
import pytest

import openreloc_bench.envs  # noqa: F401  (registers the environments)


@pytest.mark.timeout(180)
@pytest.mark.parametrize(
    "env_id,context", [("openreloc/ActiveReloc-v0", "forkserver"), ("openreloc/ObjectGoal-v0", "spawn")]
)
def test_async_vector_env_steps(env_options, env_id: str, context: str) -> None:
    options = {**env_options[env_id], "max_steps": 10}  # every episode ends within the 15 steps below
    envs = gym.make_vec(env_id, num_envs=2, vectorization_mode="async", vector_kwargs={"context": context}, **options)
    try:
        obs, info = envs.reset(seed=0)
        envs.action_space.seed(0)  # the same actions on every run
        assert obs["rgb"].shape == (2, 40, 48, 3)
        assert not np.array_equal(obs["rgb"][0], obs["rgb"][1])  # seeds 0 and 1
        ended = 0
        for _ in range(15):
            obs, reward, terminated, truncated, info = envs.step(envs.action_space.sample())
            assert envs.observation_space.contains(obs) and reward.shape == (2,)
            ended += int((terminated | truncated).sum())
        assert ended >= 2  # each env localizes or runs out of steps: autoreset goes on
    finally:
        envs.close()
