"""Environment test fixtures: one tiny generated scene per session, its caches in a temp folder, the
cheap ``nearest-frame`` relocalizer and a tiny random CLIP as the goal text encoder."""

from __future__ import annotations

from pathlib import Path
from typing import Any

import gymnasium as gym
import pytest

import openreloc_bench.envs  # noqa: F401  (registers the environments)
from generators.generate import generate_scene
from generators.spec import SceneSpec
from openreloc_bench.vision.testing import tiny_clip_checkpoint

TINY = dict(
    name="tiny-room",
    seed=3,
    width=64,
    height=48,
    objects_per_room=8,
    room_side_min=3.5,
    room_side_max=4.0,
    mapping_step_m=0.5,
    mapping_step_deg=30.0,
    max_mapping_frames=8,
    n_query=2,
    displaced_share=0.2,
    query_min_objects=2,
)


@pytest.fixture(scope="session")
def tiny_room(tmp_path_factory: pytest.TempPathFactory) -> Path:
    return generate_scene(SceneSpec(**TINY), tmp_path_factory.mktemp("scenes"), progress=False)


@pytest.fixture(scope="session")
def env_options(tiny_room: Path, tmp_path_factory: pytest.TempPathFactory) -> dict[str, dict[str, Any]]:
    """Options of each registered environment for the tiny room (small images, cheap models)."""
    common = dict(
        scene=str(tiny_room),
        cache_dir=str(tmp_path_factory.mktemp("cache")),
        width=48,
        height=40,
        method_options={"thumb_size": 8},
    )
    clip = str(tiny_clip_checkpoint(tmp_path_factory.mktemp("clip") / "tiny-clip"))
    return {
        "openreloc/ActiveReloc-v0": {**common, "method": "nearest-frame", "max_steps": 12},
        "openreloc/ObjectGoal-v0": {
            **common,
            "method": "nearest-frame",
            "max_steps": 40,
            "text_encoder": "clip",
            "text_encoder_options": {"model": clip},
        },
    }


@pytest.fixture
def make_env(env_options: dict[str, dict[str, Any]]):
    """``make_env(id, **overrides)``: the environment on the tiny room, closed after the test."""
    made: list[gym.Env] = []

    def make(env_id: str, **overrides: Any) -> gym.Env:
        env = gym.make(env_id, **{**env_options[env_id], **overrides})
        made.append(env)
        return env

    yield make
    for env in made:
        env.close()
