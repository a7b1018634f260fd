"""Reference agents for the environments, and the loop that runs them over seeded episodes.

- :class:`RandomAgent`: uniform over the action space (the floor every learned policy must beat).
- :class:`LookAroundAgent` (ActiveReloc's scripted agent): turns in place to see many objects, walks on
  after a full turn, and localizes once two relocalizer answers from different views agree after the
  agent's own motion is applied to the older one (or one answer matched ``min_matched`` objects).
  It uses only its observations and its own actions, as a learned policy would.
- :class:`ShortestPathAgent` (ObjectGoal's scripted agent): follows the geodesic distance to the goal
  and stops facing it. It reads the environment's privileged state (position, distance field), like
  Habitat's ShortestPathFollower: an upper bound for SPL, and a check of the metrics.

Episode ``e`` of :func:`run_episodes` resets with seed ``seed + e``, so two agents run on the same
episodes (paired comparisons).
"""

from __future__ import annotations

from typing import Any, Protocol

import gymnasium as gym
import numpy as np

from openreloc_bench import geometry
from openreloc_bench.envs.active_reloc import ActiveRelocEnv
from openreloc_bench.envs.base import DONE, FORWARD, LOOK_DOWN, LOOK_UP, TURN_LEFT, TURN_RIGHT
from openreloc_bench.envs.object_goal import ObjectGoalEnv
from openreloc_bench.errors import ConfigError


class Agent(Protocol):
    def reset(self, obs: dict[str, np.ndarray], info: dict[str, Any]) -> None: ...

    def act(self, obs: dict[str, np.ndarray], info: dict[str, Any]) -> int: ...


class RandomAgent:
    """Uniformly random actions (seeded)."""

    def __init__(self, env: gym.Env, seed: int = 0):
        self.space = env.action_space
        self.space.seed(seed)

    def reset(self, obs: dict[str, np.ndarray], info: dict[str, Any]) -> None:
        pass

    def act(self, obs: dict[str, np.ndarray], info: dict[str, Any]) -> int:
        return int(self.space.sample())


def estimate_pose(obs: dict[str, np.ndarray]) -> np.ndarray:
    """The camera-to-world pose of an ``estimate`` observation."""
    v = obs["estimate"].astype(np.float64)
    return geometry.qt_to_pose(v[3:], v[:3])


class LookAroundAgent:
    """ActiveReloc's scripted agent (see the module docstring).

    Two answers agree when they are within ``agree_m`` / ``agree_deg`` of each other (default: the
    environment's success thresholds); ``min_matched`` > 0 also localizes at once after an answer that
    matched that many objects (0: never on that ground alone).
    """

    def __init__(
        self, env: gym.Env, min_matched: int = 0, agree_m: float | None = None, agree_deg: float | None = None
    ):
        u = env.unwrapped
        if not isinstance(u, ActiveRelocEnv):
            raise ConfigError("LookAroundAgent drives ActiveReloc environments")
        cfg = u.config
        self.forward_m, self.turn, self.max_steps = cfg.forward_m, np.radians(cfg.turn_deg), cfg.max_steps
        self.min_matched = min_matched
        self.agree_m = cfg.success_m if agree_m is None else agree_m
        self.agree_deg = cfg.success_deg if agree_deg is None else agree_deg
        self.turns_per_circle = max(1, round(2 * np.pi / self.turn))

    def reset(self, obs: dict[str, np.ndarray], info: dict[str, Any]) -> None:
        self.answers: dict[tuple, np.ndarray] = {}
        """Fresh answers by view: (dead-reckoned x, y in the start frame, heading in turns)."""
        self.xy, self.heading = np.zeros(2), 0
        self.steps, self.turns, self.last = 0, 0, None
        self._take(obs, info)

    def _view(self) -> tuple:
        return (round(float(self.xy[0]), 3), round(float(self.xy[1]), 3), self.heading % self.turns_per_circle)

    def _take(self, obs: dict[str, np.ndarray], info: dict[str, Any]) -> bool:
        """Remember a fresh answer of a view not seen before; True when it agrees with the answer of
        another view or matched enough objects."""
        view = self._view()
        if not info.get("relocalized") or view in self.answers:
            return False
        T = estimate_pose(obs)
        confident = self.min_matched > 0 and obs["matched"][0] >= self.min_matched
        agree = any(
            geometry.translation_error(T, old) <= self.agree_m and geometry.rotation_error(T, old) <= self.agree_deg
            for old in self.answers.values()
        )
        self.answers[view] = T
        return bool(confident or agree)

    def _moved(self, action: int, collided: bool) -> None:
        """Apply the agent's own last motion to its dead reckoning and to every remembered answer."""
        if action in (TURN_LEFT, TURN_RIGHT):
            sign = 1 if action == TURN_LEFT else -1
            self.heading += sign
            c, s = np.cos(sign * self.turn), np.sin(sign * self.turn)
            for T in self.answers.values():
                T[:3, :3] = np.array([[c, -s, 0.0], [s, c, 0.0], [0.0, 0.0, 1.0]]) @ T[:3, :3]
        elif action == FORWARD and not collided:
            yaw = self.heading * self.turn
            self.xy += self.forward_m * np.array([np.cos(yaw), np.sin(yaw)])
            for T in self.answers.values():
                T[:2, 3] += self.forward_m * T[:2, 2] / max(float(np.linalg.norm(T[:2, 2])), 1e-9)

    def act(self, obs: dict[str, np.ndarray], info: dict[str, Any]) -> int:
        if self.last is not None:
            self._moved(self.last, bool(info.get("collided")))
            if self._take(obs, info):
                return DONE
        self.steps += 1
        if self.steps >= self.max_steps:
            return DONE
        if self.turns < self.turns_per_circle - 1 or info.get("collided"):
            action, self.turns = TURN_LEFT, self.turns + 1
        else:
            action, self.turns = FORWARD, 0
        self.last = action
        return action


class ShortestPathAgent:
    """ObjectGoal's scripted agent (see the module docstring)."""

    def __init__(self, env: gym.Env):
        u = env.unwrapped
        if not isinstance(u, ObjectGoalEnv):
            raise ConfigError("ShortestPathAgent drives ObjectGoal environments")
        self.env = u
        cfg = u.config
        self.forward_m, self.turn, self.tilt = cfg.forward_m, np.radians(cfg.turn_deg), np.radians(cfg.tilt_deg)

    def reset(self, obs: dict[str, np.ndarray], info: dict[str, Any]) -> None:
        pass

    def _turn_towards(self, yaw: float, target: float) -> int | None:
        diff = float(np.arctan2(np.sin(target - yaw), np.cos(target - yaw)))
        if abs(diff) <= self.turn / 2:
            return None
        return TURN_LEFT if diff > 0 else TURN_RIGHT

    def act(self, obs: dict[str, np.ndarray], info: dict[str, Any]) -> int:
        env = self.env
        pose = env.agent_pose
        if env.goal_footprint_distance(pose.xy) <= env.config.success_distance:
            want = env.facing(pose.xy)
            turn = self._turn_towards(pose.yaw, want.yaw)
            if turn is not None:
                return turn
            if abs(want.pitch - pose.pitch) > self.tilt / 2:
                return LOOK_UP if want.pitch > pose.pitch else LOOK_DOWN
            if env.world.in_view(env.world.visible_share(env.camera_pose, env.goal_object.id)):
                return DONE
            closer = pose.xy + self.forward_m * pose.heading  # not in view from here: step towards it
            if not env.world.passable(pose.floor, pose.xy, closer):
                return DONE
            return FORWARD
        if pose.pitch != 0.0:
            return LOOK_UP if pose.pitch < 0 else LOOK_DOWN
        best_yaw, best_d = pose.yaw, np.inf
        for k in range(round(2 * np.pi / self.turn)):
            yaw = pose.yaw + k * self.turn
            nxt = pose.xy + self.forward_m * np.array([np.cos(yaw), np.sin(yaw)])
            if env.world.passable(pose.floor, pose.xy, nxt) and (d := env.geodesic_distance(nxt)) < best_d - 1e-9:
                best_yaw, best_d = yaw, d
        return self._turn_towards(pose.yaw, best_yaw) or FORWARD


def scripted_agent(env: gym.Env) -> Agent:
    """The scripted agent of ``env``'s task."""
    u = env.unwrapped
    if isinstance(u, ActiveRelocEnv):
        return LookAroundAgent(env)
    if isinstance(u, ObjectGoalEnv):
        return ShortestPathAgent(env)
    raise ConfigError(f"no scripted agent for {type(u).__name__}")


def run_episodes(env: gym.Env, agent: Agent, episodes: int, seed: int = 0) -> list[dict[str, Any]]:
    """Run ``episodes`` episodes (episode e seeded ``seed + e``); the final ``info`` of each, plus its ``return``."""
    out = []
    for e in range(episodes):
        obs, info = env.reset(seed=seed + e)
        agent.reset(obs, info)
        total, done = 0.0, False
        while not done:
            obs, reward, terminated, truncated, info = env.step(agent.act(obs, info))
            total += reward
            done = terminated or truncated
        out.append({**info, "return": total})
    return out
