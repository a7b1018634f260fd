"""Every registered environment: gymnasium's checker, seeding, pickling, motion, rendering, bad input."""

from __future__ import annotations

import pickle
import shutil
import warnings
from pathlib import Path

import gymnasium as gym
import numpy as np
import pytest
from gymnasium.utils.env_checker import check_env

from openreloc_bench import geometry
from openreloc_bench.envs import ENVIRONMENTS, EnvConfigError
from openreloc_bench.envs.base import FORWARD, LOOK_DOWN, LOOK_UP, TURN_LEFT, TURN_RIGHT
from tests.conftest import write_tiny_scene

IDS = sorted(ENVIRONMENTS)


def test_every_environment_is_registered() -> None:
    assert set(IDS) == {i for i in gym.registry if i.startswith("openreloc/")}
    assert IDS == ["openreloc/ActiveReloc-v0", "openreloc/ObjectGoal-v0"]


def test_the_module_form_of_the_id_imports_the_package(env_options) -> None:
    env = gym.make("openreloc_bench.envs:openreloc/ActiveReloc-v0", **env_options["openreloc/ActiveReloc-v0"])
    assert env.unwrapped.spec.id == "openreloc/ActiveReloc-v0"
    env.close()


@pytest.mark.parametrize("env_id", IDS)
def test_check_env_passes_without_warnings(make_env, env_id: str) -> None:
    env = make_env(env_id, render_mode="rgb_array")
    with warnings.catch_warnings():
        warnings.simplefilter("error")
        check_env(env.unwrapped)  # with its defaults: it also makes the env in every render mode listed
        env.reset(seed=0)
        frame = env.render()
    assert frame.dtype == np.uint8 and frame.ndim == 3 and frame.shape[2] == 3


@pytest.mark.parametrize("env_id", IDS)
def test_observations_are_flat_and_in_their_space(make_env, env_id: str) -> None:
    env = make_env(env_id, depth=True)
    obs, _ = env.reset(seed=1)
    space = env.observation_space
    assert all(not isinstance(s, gym.spaces.Dict) for s in space.spaces.values())
    assert {"rgb", "depth", "estimate", "valid", "matched"} <= set(obs)
    assert obs["rgb"].shape == (40, 48, 3) and obs["depth"].shape == (40, 48, 1)
    assert float(obs["depth"].max()) > 0.3  # a room, not a blank frame
    env.action_space.seed(1)  # the same actions on every run
    for _ in range(5):
        obs, _, terminated, truncated, _ = env.step(env.action_space.sample())
        assert space.contains(obs)
        if terminated or truncated:  # an ended episode takes no further step
            obs, _ = env.reset()


@pytest.mark.parametrize("env_id", IDS)
def test_seeded_episodes_repeat_exactly(make_env, env_id: str) -> None:
    actions = [TURN_LEFT, FORWARD, FORWARD, LOOK_DOWN, TURN_RIGHT, FORWARD]

    def rollout(env: gym.Env, seed: int) -> list:
        obs, info = env.reset(seed=seed)
        out = [(obs, info)]
        for a in actions:
            obs, reward, *_, info = env.step(a)
            out.append((obs, reward, info))
        return out

    a, b = make_env(env_id), make_env(env_id)
    first, again = rollout(a, 5), rollout(b, 5)
    for x, y in zip(first, again):
        assert gym.utils.env_checker.data_equivalence(x, y)
    other = rollout(a, 6)
    assert not np.array_equal(first[0][0]["rgb"], other[0][0]["rgb"])


@pytest.mark.parametrize("env_id", IDS)
def test_pickled_environment_recreates_itself(make_env, env_id: str) -> None:
    env = make_env(env_id).unwrapped
    obs, _ = env.reset(seed=3)
    clone = pickle.loads(pickle.dumps(env))
    try:
        obs2, _ = clone.reset(seed=3)
        assert gym.utils.env_checker.data_equivalence(obs, obs2)
    finally:
        clone.close()


def test_motion_turns_tilts_and_collides(make_env) -> None:
    env = make_env("openreloc/ActiveReloc-v0", relocalize_every=0)
    env.reset(seed=2)
    u = env.unwrapped
    yaw = u.agent_pose.yaw
    env.step(TURN_LEFT)
    assert np.isclose(np.cos(u.agent_pose.yaw - yaw - np.radians(30)), 1.0)
    for _ in range(4):
        env.step(LOOK_UP)
    assert np.isclose(u.agent_pose.pitch, np.radians(60))  # clamped at max_tilt_deg
    env.step(LOOK_DOWN)
    env.step(LOOK_DOWN)
    env.step(LOOK_DOWN)
    assert np.isclose(u.agent_pose.pitch, np.radians(-30))
    assert np.isclose(u.camera_pose[2, 2], -0.5)  # the optical axis points 30 degrees down
    eye, pose = u.camera_pose[:3, 3], u.agent_pose
    forward = [np.cos(pose.pitch) * np.cos(pose.yaw), np.cos(pose.pitch) * np.sin(pose.yaw), np.sin(pose.pitch)]
    np.testing.assert_allclose(u.camera_pose, geometry.look_at(eye, eye + forward), atol=1e-12)
    collided = False
    for _ in range(40):  # a 4 m room: walking straight on ends at a wall or a piece of furniture
        before = u.agent_pose.xy
        *_, info = env.step(FORWARD)
        step = np.linalg.norm(u.agent_pose.xy - before)
        assert np.isclose(step, 0.25) or (step == 0.0 and info["collided"])
        assert u.world.walkable_at(u.agent_pose.floor, u.agent_pose.xy[None])[0]
        if info["collided"]:
            collided = True
            break
        if info.get("episode_steps"):
            env.reset(seed=2)
    assert collided


def test_estimate_is_carried_by_the_agents_motion(make_env) -> None:
    env = make_env("openreloc/ActiveReloc-v0", relocalize_every=3)
    obs, info = env.reset(seed=4)
    u = env.unwrapped
    assert info["relocalized"] and obs["valid"][0] == 1
    T_est, T_cam = _pose(obs), u.camera_pose
    obs, _, _, _, info = env.step(TURN_RIGHT)
    assert not info["relocalized"]
    expected = T_est @ geometry.invert(T_cam) @ u.camera_pose
    np.testing.assert_allclose(_pose(obs), expected, atol=1e-5)


def test_by_default_the_relocalizer_is_asked_every_fifth_step(make_env) -> None:
    env = make_env("openreloc/ActiveReloc-v0", max_steps=20)
    _, info = env.reset(seed=4)
    asked = [info["relocalized"]] + [env.step(TURN_RIGHT)[4]["relocalized"] for _ in range(10)]
    assert [i for i, fresh in enumerate(asked) if fresh] == [0, 5, 10]


def _pose(obs: dict) -> np.ndarray:
    v = obs["estimate"].astype(np.float64)
    return geometry.qt_to_pose(v[3:], v[:3])


def test_rgb_array_draws_the_agent_on_the_map(make_env) -> None:
    env = make_env("openreloc/ObjectGoal-v0", render_mode="rgb_array")
    env.reset(seed=0)
    frame = env.render()
    green = (frame[..., 1] > 150) & (frame[..., 0] < 60) & (frame[..., 2] < 100)
    blue = (frame[..., 2] > 200) & (frame[..., 0] < 60)
    assert green.sum() > 20 and blue.sum() > 10
    with pytest.warns(UserWarning, match="render_mode"):
        assert make_env("openreloc/ObjectGoal-v0").unwrapped.render() is None


# ------------------------------------------------------------------------------------- bad input


@pytest.mark.parametrize("env_id", IDS)
def test_invalid_actions_and_order_are_one_line_errors(make_env, env_id: str) -> None:
    env = make_env(env_id).unwrapped
    with pytest.raises(gym.error.ResetNeeded):
        env.step(0)
    env.reset(seed=0)
    for bad in (6, -1, 2.5, "forward", np.array([1, 2])):
        with pytest.raises(gym.error.InvalidAction, match=r"invalid action .*Discrete\(6\): 0 forward") as e:
            env.step(bad)
        assert "\n" not in str(e.value)
    env.step(np.int64(1))  # numpy integers are valid actions


@pytest.mark.parametrize("env_id", IDS)
def test_an_ended_episode_needs_a_reset_and_reset_options_are_checked(make_env, env_id: str) -> None:
    env = make_env(env_id, max_steps=1).unwrapped
    env.reset(seed=0)
    *_, terminated, truncated, _ = env.step(1)  # a turn: the one step allowed
    assert terminated or truncated
    with pytest.raises(gym.error.ResetNeeded, match="the episode has ended"):
        env.step(1)  # it used to go on: another reward, a step count past max_steps
    env.reset(seed=0)
    env.step(1)  # a new episode steps again
    with pytest.raises(ValueError, match=r"unknown reset option\(s\) 'goal'"):
        env.reset(seed=0, options={"goal": 3})  # a typo of goal_id used to pick a random goal


def test_bad_scene_method_and_options_are_one_line_errors(env_options, tmp_path: Path) -> None:
    base = env_options["openreloc/ActiveReloc-v0"]
    not_generated = write_tiny_scene(tmp_path / "real-data")  # scene.json without a generator spec
    no_mapping = tmp_path / "no-mapping"
    no_mapping.mkdir()
    for name in ("scene.json", "objects.json"):
        shutil.copy(Path(base["scene"]) / name, no_mapping / name)
    cases = {
        "unknown scene 'nowhere'": dict(scene="nowhere"),
        "not a generated scene directory": dict(scene=str(tmp_path)),
        "no generator spec": dict(scene=str(not_generated)),
        "no 'mapping' split": dict(scene=str(no_mapping)),
        "unknown method 'no-such-method'": dict(method="no-such-method"),
        "suite 'no-such-suite' not found": dict(scene=None, suite="no-such-suite"),
        "unknown key 'widht'": dict(widht=64),
        "width and height": dict(width=4),
        "needs a relocalizer": dict(method=None),
    }
    for message, overrides in cases.items():
        with pytest.raises(EnvConfigError, match=message) as e:
            gym.make("openreloc/ActiveReloc-v0", **{**base, **overrides})
        assert isinstance(e.value, gym.error.Error) and "\n" not in str(e.value)
    with pytest.raises(EnvConfigError, match="render_mode 'ascii'"), pytest.warns(UserWarning, match="ascii"):
        gym.make("openreloc/ActiveReloc-v0", render_mode="ascii", **base)


def test_human_rendering_without_a_display_shows_nothing_and_says_so(
    env_options, monkeypatch: pytest.MonkeyPatch, caplog
) -> None:
    monkeypatch.delenv("DISPLAY", raising=False)
    monkeypatch.delenv("WAYLAND_DISPLAY", raising=False)
    monkeypatch.setattr("sys.platform", "linux")
    with caplog.at_level("INFO", logger="openreloc_bench.envs.base"):
        env = gym.make("openreloc/ActiveReloc-v0", render_mode="human", **env_options["openreloc/ActiveReloc-v0"])
    assert "without a display shows nothing" in caplog.text
    env.reset(seed=0)
    assert env.render() is None and env.unwrapped._window is None
    env.close()


@pytest.mark.parametrize("env_id", IDS)
def test_stable_baselines3_accepts_the_spaces(make_env, env_id: str) -> None:
    sb3_checker = pytest.importorskip("stable_baselines3.common.env_checker")
    env = make_env(env_id)
    with warnings.catch_warnings():
        warnings.simplefilter("error")
        sb3_checker.check_env(env.unwrapped, warn=True)


@pytest.mark.parametrize("env_id", IDS)
def test_the_spec_reports_the_episodes_own_step_limit(make_env, env_id: str) -> None:
    env = make_env(env_id, max_steps=7)
    assert env.spec.max_episode_steps == 7 and env.unwrapped.spec.max_episode_steps == 7
    assert "TimeLimit" not in repr(env)  # the environment truncates itself: no second limit on top
    env.reset(seed=0)
    steps, truncated = 0, False
    while not truncated:
        *_, terminated, truncated, _ = env.step(0)  # forward only: never ends the task
        steps += 1
        assert not terminated
    assert steps == 7
