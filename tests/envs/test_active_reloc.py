"""ActiveReloc-v0: localize ends the episode, success needs the answer within 25 cm / 5 degrees."""

from __future__ import annotations

import json
from collections.abc import Callable
from pathlib import Path
from typing import Any

import numpy as np
import pytest

from openreloc_bench import methods
from openreloc_bench.envs.base import DONE, FORWARD, TURN_LEFT
from openreloc_bench.methods import Failure, PoseEstimate, QueryFrame


class Teleported:
    """A test method answering ``Teleported.answer()`` (set by the test), or failing while it is None."""

    name = "test-teleported"
    answer: Callable[[], np.ndarray] | None = None

    def __init__(self, **_: Any):
        self.config = None

    def build_map(self, mapping: Any, map_dir: Path) -> None:
        Path(map_dir, "map.json").write_text(json.dumps({"frames": len(mapping)}))

    def load_map(self, map_dir: Path) -> None:
        assert Path(map_dir, "map.json").is_file()

    def localize(self, query: QueryFrame) -> PoseEstimate | Failure:
        if Teleported.answer is None:
            return Failure("nothing to say", {"matches": [1, 2]})
        return PoseEstimate(Teleported.answer(), {"matches": [1, 2, 3]})


@pytest.fixture
def teleported(make_env):
    methods.register(Teleported.name, Teleported)
    Teleported.answer = None
    yield lambda **kw: make_env("openreloc/ActiveReloc-v0", method=Teleported.name, method_options={}, **kw)
    Teleported.answer = None


def test_localize_with_the_true_pose_succeeds(teleported) -> None:
    env = teleported(relocalize_every=0)  # the relocalizer is asked at localize only
    obs, info = env.reset(seed=0)
    assert obs["valid"][0] == 0 and obs["matched"][0] == 0 and not info["relocalized"]
    u = env.unwrapped
    Teleported.answer = lambda: u.camera_pose
    obs, reward, terminated, truncated, info = env.step(DONE)
    assert terminated and not truncated and info["success"]
    assert info["translation_error"] < 1e-6 and info["rotation_error"] < 1e-3
    assert reward == pytest.approx(1.0 - 0.01)
    assert obs["valid"][0] == 1 and obs["matched"][0] == 3
    assert info["episode_steps"] == 1 and info["relocalizer_calls"] == 1


def test_a_failed_answer_is_no_estimate(teleported) -> None:
    obs, info = teleported().reset(seed=0)
    assert obs["valid"][0] == 0 and obs["matched"][0] == 2 and not info["relocalized"]
    assert not obs["estimate"].any()


def test_localize_off_by_more_than_the_threshold_fails(teleported) -> None:
    env = teleported(relocalize_every=0)
    env.reset(seed=0)
    T = env.unwrapped.camera_pose.copy()
    T[0, 3] += 0.3
    Teleported.answer = lambda: T
    _, reward, terminated, _, info = env.step(DONE)
    assert terminated and not info["success"] and info["translation_error"] == pytest.approx(0.3)
    assert reward == pytest.approx(-1.0 - 0.01)


def test_a_failed_view_keeps_the_carried_estimate(teleported) -> None:
    env = teleported(relocalize_every=1)
    env.reset(seed=1)
    u = env.unwrapped
    Teleported.answer = lambda: u.camera_pose
    env.step(TURN_LEFT)  # a fresh, exact answer
    Teleported.answer = None  # from now on the method fails
    env.step(TURN_LEFT)
    env.step(FORWARD)
    _, _, terminated, _, info = env.step(DONE)
    assert terminated and info["success"]  # the exact answer, carried by odometry, still holds


def test_truncation_is_a_failure_without_terminal_reward(teleported) -> None:
    env = teleported(max_steps=3, relocalize_every=0)
    env.reset(seed=2)
    for _ in range(2):
        *_, terminated, truncated, _ = env.step(TURN_LEFT)
        assert not (terminated or truncated)
    _, reward, terminated, truncated, info = env.step(TURN_LEFT)
    assert truncated and not terminated and not info["success"]
    assert reward == pytest.approx(-0.01) and info["relocalizer_calls"] == 0
    assert info["translation_error"] == float("inf")
