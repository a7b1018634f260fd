"""The reference agents and the ``agent`` command."""

from __future__ import annotations

import numpy as np
import pytest

from openreloc_bench.cli import main
from openreloc_bench.envs.agents import LookAroundAgent, RandomAgent, run_episodes, scripted_agent
from openreloc_bench.envs.base import DONE, FORWARD, TURN_LEFT


def test_random_agent_episodes_end_with_final_metrics(make_env) -> None:
    env = make_env("openreloc/ActiveReloc-v0")
    finals = run_episodes(env, RandomAgent(env, seed=0), episodes=3, seed=0)
    assert len(finals) == 3
    for f in finals:
        assert {"success", "translation_error", "rotation_error", "episode_steps", "return"} <= set(f)
        assert 1 <= f["episode_steps"] <= 12


def test_look_around_agent_turns_then_walks_and_localizes(make_env) -> None:
    env = make_env("openreloc/ActiveReloc-v0", max_steps=20)
    agent = scripted_agent(env)
    assert isinstance(agent, LookAroundAgent)
    obs, info = env.reset(seed=0)
    agent.reset(obs, info)
    actions = []
    done = False
    while not done:
        actions.append(agent.act(obs, info))
        obs, _, terminated, truncated, info = env.step(actions[-1])
        done = terminated or truncated
    assert actions[-1] == DONE and terminated
    assert actions[:11] == [TURN_LEFT] * 11 or DONE in actions[:11]  # a full circle first, unless two views agree
    if len(actions) > 12:
        assert actions[11] in (FORWARD, TURN_LEFT)


def test_look_around_agent_stops_when_two_views_agree(make_env) -> None:
    """Answers that are the truth agree after the agent's own motion: it localizes at the second view."""
    env = make_env("openreloc/ActiveReloc-v0")
    agent = LookAroundAgent(env)
    obs, info = env.reset(seed=1)
    u = env.unwrapped
    truth = dict(obs, estimate=_vector(u.camera_pose))
    agent.reset(truth, {"relocalized": True})
    action = agent.act(truth, {"relocalized": True})
    assert action == TURN_LEFT
    obs, *_ = env.step(action)
    assert agent.act(dict(obs, estimate=_vector(u.camera_pose)), {"relocalized": True, "collided": False}) == DONE


def _vector(T: np.ndarray) -> np.ndarray:
    from openreloc_bench import geometry

    q, t = geometry.pose_to_qt(T)
    return np.r_[t, q].astype(np.float32)


def test_agent_command_prints_success(env_options, capsys: pytest.CaptureFixture) -> None:
    opts = env_options["openreloc/ActiveReloc-v0"]
    argv = ["agent", "ActiveReloc-v0", "--agent", "random", "--episodes", "2", "--scene", opts["scene"]]
    argv += ["--method", "nearest-frame", "--set", f"cache_dir={opts['cache_dir']}", "--set", "width=48"]
    argv += ["--set", "height=40", "--set", "method_options={thumb_size: 8}"]
    assert main(argv) == 0
    out = capsys.readouterr().out
    assert "episode 1:" in out and "random agent, 2 episodes" in out and "success" in out


def test_agent_command_bad_input_is_one_line(capsys: pytest.CaptureFixture) -> None:
    assert main(["agent", "Nope-v0"]) == 2
    assert "unknown environment 'Nope-v0'" in capsys.readouterr().err
    assert main(["agent", "ActiveReloc-v0", "--scene", "no-such-scene"]) == 2
    err = capsys.readouterr().err
    assert "unknown scene 'no-such-scene'" in err and len(err.strip().splitlines()) == 1
