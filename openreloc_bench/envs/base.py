"""What every openreloc environment shares: a camera agent walking a generated scene with discrete
actions, an optional relocalizer in the loop, flat ``Dict`` observations and a top-down rendering.

Actions (``Discrete(6)``, Habitat's set): 0 forward ``forward_m``, 1 / 2 turn left / right
``turn_deg``, 3 / 4 look up / down ``tilt_deg`` (within +-``max_tilt_deg``), 5 the task's final action
(``localize`` or ``stop``), which ends the episode. A forward move that would leave the walkable free
space (walls, furniture, with the generator's clearance) does not happen (``info["collided"]``).

Observations (a flat ``Dict``, as stable-baselines3's ``MultiInputPolicy`` needs):

- ``rgb``: uint8 (height, width, 3), the agent's camera with the scene's vertical field of view;
- ``depth`` (option ``depth``): float32 (height, width, 1) metres along the optical axis, 0 = nothing;
- with a relocalizer (option ``method``): ``estimate`` float32 (7,) = camera-to-world position (x, y, z)
  and quaternion (w, x, y, z) of its latest answer, carried along by the agent's own motion since
  (noise-free odometry), zeros while there is none; ``valid`` (``MultiBinary(1)``) whether there is one;
  ``matched`` float32 (1,) objects the latest call matched to the map.

The relocalizer sees the view rendered at the scene's own resolution and intrinsics (those its map was
built from), after every ``relocalize_every``-th step (0: only when the task asks); the agent's image
size is independent of it. A view it was already asked about is not asked again (methods are
deterministic). ``info`` always has ``collided`` and ``relocalized`` (this view got a fresh pose from
the relocalizer); the final ``info`` of an episode has the task's metrics. Subclasses define the task:
:meth:`IndoorEnv._task_reset`, :meth:`IndoorEnv._task_step` and :meth:`IndoorEnv._episode_metrics`.

Episodes truncate themselves after ``max_steps``, which ``env.spec.max_episode_steps`` reports (register
no ``TimeLimit`` on top). Autoreset is
gymnasium's default for vector environments (next step).
"""

from __future__ import annotations

import dataclasses
import logging
import os
import sys
from dataclasses import dataclass, field
from typing import Any

import gymnasium as gym
import numpy as np
from gymnasium import spaces
from gymnasium.envs.registration import EnvSpec
from gymnasium.utils import EzPickle

from openreloc_bench import config, geometry
from openreloc_bench.data.paths import cache_root
from openreloc_bench.data.scene import Scene
from openreloc_bench.envs.relocalizer import Estimate, InLoopRelocalizer
from openreloc_bench.envs.scenes import resolve_scene
from openreloc_bench.envs.world import AgentPose, World, scene_spec
from openreloc_bench.errors import ConfigError, OpenRelocError
from openreloc_bench.tracks import DEFAULT_TRACK, ORACLE_MASK, Track

log = logging.getLogger(__name__)

MOVES = ("forward", "turn_left", "turn_right", "look_up", "look_down")
FORWARD, TURN_LEFT, TURN_RIGHT, LOOK_UP, LOOK_DOWN, DONE = range(6)


class EnvConfigError(ConfigError, gym.error.Error):
    """A bad environment option, scene or method: one line, and a ``gymnasium.error.Error`` too."""


@dataclass
class EnvConfig:
    """Options every environment takes (``gymnasium.make(id, **options)``)."""

    scene: str | None = None
    """A generated scene directory, or the name of a scene of ``suite`` (None: the suite's first scene)."""
    suite: str = "smoke"
    """A suite YAML, or the name of a suite in the checkout's ``scenes/``; a suite scene is generated on
    first use into the cache."""
    cache_dir: str | None = None
    """Generated scenes, maps and goal embeddings (None: ``$OPENRELOC_BENCH_CACHE``, else
    ``~/.cache/openreloc-bench``)."""
    width: int = 128
    """Width of the ``rgb`` (and ``depth``) observation in pixels."""
    height: int = 128
    """Height of the ``rgb`` (and ``depth``) observation in pixels."""
    depth: bool = False
    """Add a ``depth`` observation."""
    method: str | None = "openreloc"
    """Registered relocalization method in the loop (``openreloc-bench methods``); None: no relocalizer."""
    method_options: dict[str, Any] = field(default_factory=dict)
    """The method's config overrides (as ``--set`` gives them to ``openreloc-bench map``)."""
    track: Track = DEFAULT_TRACK
    """What the relocalizer is given: the image only, or the image and perfect instance masks."""
    relocalize_every: int = 5
    """Ask the relocalizer about the view after every this many steps (and after reset); 0: only when
    the task's final action needs it. Between calls the agent's own motion carries the estimate. With
    ``openreloc`` on the smoke scene at 128x128 (2 cores): 2-3 steps/s at 1, 10 at 5, 600-750 at 0."""
    max_steps: int = 50
    """Steps after which the episode is truncated."""
    forward_m: float = 0.25
    """Length of a forward move (m)."""
    turn_deg: float = 30.0
    """Angle of a turn (degrees)."""
    tilt_deg: float = 30.0
    """Angle of a look up / down (degrees)."""
    max_tilt_deg: float = 60.0
    """Largest camera tilt up or down (degrees)."""
    camera_height: float = 1.5
    """Camera height above the floor (m)."""
    step_penalty: float = 0.01
    """Reward subtracted at every step."""

    def __post_init__(self) -> None:
        if not (16 <= self.width <= 4096 and 16 <= self.height <= 4096):
            raise ValueError(f"width and height must be in [16, 4096], got {self.width}x{self.height}")
        if self.relocalize_every < 0 or self.max_steps < 1:
            raise ValueError("relocalize_every must be >= 0 and max_steps >= 1")
        if min(self.forward_m, self.turn_deg, self.tilt_deg, self.camera_height) <= 0:
            raise ValueError("forward_m, turn_deg, tilt_deg and camera_height must be positive")
        if not 0 <= self.max_tilt_deg < 90:
            raise ValueError(f"max_tilt_deg must be in [0, 90), got {self.max_tilt_deg}")


def has_display() -> bool:
    """Whether a window can be opened (an X11 / Wayland display, or macOS / Windows)."""
    return sys.platform in ("darwin", "win32") or bool(os.environ.get("DISPLAY") or os.environ.get("WAYLAND_DISPLAY"))


class _Window:
    """A matplotlib window showing frames (``render_mode="human"``)."""

    def __init__(self, title: str, fps: float):
        import matplotlib.pyplot as plt

        self.plt, self.pause = plt, 1.0 / fps
        self.fig = plt.figure(title)
        self.image = None

    def show(self, frame: np.ndarray) -> None:
        if self.image is None:
            self.image = self.fig.gca().imshow(frame)
            self.fig.gca().set_axis_off()
        else:
            self.image.set_data(frame)
        self.plt.pause(self.pause)

    def close(self) -> None:
        self.plt.close(self.fig)


class IndoorEnv(gym.Env, EzPickle):
    """Base of the openreloc environments (see the module docstring)."""

    metadata = {"render_modes": ["rgb_array", "human"], "render_fps": 4}
    config_class: type[EnvConfig] = EnvConfig
    final_action = "done"
    """Name of action 5."""
    reset_options: tuple[str, ...] = ()
    """The keys ``reset(options=...)`` reads; any other is a ValueError (a typo would pass unnoticed)."""

    @property
    def spec(self) -> EnvSpec | None:
        """The registration ``gym.make`` made this from, with ``max_episode_steps`` the episode's own
        truncation (``max_steps``: the environment truncates itself, so no ``TimeLimit`` wraps it)."""
        spec = self.__dict__.get("_spec")
        return None if spec is None else dataclasses.replace(spec, max_episode_steps=self.config.max_steps)

    @spec.setter
    def spec(self, value: EnvSpec | None) -> None:
        self._spec = value

    def __init__(self, render_mode: str | None = None, **options: Any):
        EzPickle.__init__(self, render_mode, **options)
        try:
            self.config = cfg = config.from_dict(self.config_class, options)
            if render_mode is not None and render_mode not in self.metadata["render_modes"]:
                raise ConfigError(
                    f"render_mode {render_mode!r} is not one of {self.metadata['render_modes']} (or None)"
                )
            self._headless = render_mode == "human" and not has_display()
            if self._headless:  # as gymnasium's check_env makes every mode it lists: show nothing, say so once
                log.info("render_mode 'human' without a display shows nothing; render_mode='rgb_array' returns frames")
            self._cache = cache_root(cfg.cache_dir)
            self.scene = Scene(resolve_scene(cfg.scene, cfg.suite, cfg.cache_dir))
            self.scene_spec = scene_spec(self.scene)
            self.relocalizer = (
                InLoopRelocalizer(cfg.method, cfg.method_options, self.scene, self._cache, cfg.track)
                if cfg.method
                else None
            )
            if self.relocalizer is not None and "mapping" not in self.scene.splits():
                raise ConfigError(f"scene {self.scene.root} has no 'mapping' split (the relocalizer's map needs it)")
            self._task_setup()
        except OpenRelocError as e:
            raise EnvConfigError(f"{type(self).__name__}: {e}") from None
        self.render_mode = render_mode
        self.action_space = spaces.Discrete(len(MOVES) + 1)
        self.observation_space = spaces.Dict(self._observation_spaces())
        self._K_obs = geometry.intrinsics_from_fov(cfg.width, cfg.height, self.scene_spec.fov_y)
        self._world: World | None = None
        self._window: _Window | None = None
        self._pose: AgentPose | None = None
        self._ended = False
        self._camera = np.eye(4)
        self._estimate: Estimate | None = None
        self._answer: Estimate | None = None
        self._answer_view: np.ndarray | None = None
        self._rgb: np.ndarray | None = None

    # ---------------------------------------------------------------------------- spaces

    def _observation_spaces(self) -> dict[str, spaces.Space]:
        cfg, info = self.config, self.scene.info
        out: dict[str, spaces.Space] = {"rgb": spaces.Box(0, 255, (cfg.height, cfg.width, 3), np.uint8)}
        top = info["floors"][-1]["z"] + info["floors"][-1]["ceiling_height"]
        extent = np.array([*info["footprint"], top])
        self._depth_max = float(np.linalg.norm(extent)) + 1.0
        if cfg.depth:
            out["depth"] = spaces.Box(0.0, self._depth_max, (cfg.height, cfg.width, 1), np.float32)
        if self.relocalizer is not None:
            margin = 1.0
            self._estimate_low = np.r_[-margin * np.ones(3), -np.ones(4)].astype(np.float32)
            self._estimate_high = np.r_[extent + margin, np.ones(4)].astype(np.float32)
            out["estimate"] = spaces.Box(self._estimate_low, self._estimate_high, (7,), np.float32)
            out["valid"] = spaces.MultiBinary(1)
            out["matched"] = spaces.Box(0.0, float(len(self.scene.objects)), (1,), np.float32)
        out.update(self._task_spaces())
        return out

    # ---------------------------------------------------------------------------- task hooks

    def _task_setup(self) -> None:
        """Validate the scene for the task (runs in the constructor)."""

    def _task_spaces(self) -> dict[str, spaces.Space]:
        return {}

    def _task_observation(self) -> dict[str, np.ndarray]:
        return {}

    def _task_reset(self, options: dict[str, Any]) -> dict[str, Any]:
        """Choose the episode (the start pose at least, in ``self._pose``); returns extra reset info."""
        raise NotImplementedError

    def _task_step(self, action: int) -> tuple[float, bool, dict[str, Any]]:
        """(reward, terminated, info) of the step just taken."""
        raise NotImplementedError

    def _episode_metrics(self) -> dict[str, Any]:
        """The final ``info`` of an episode (terminated or truncated)."""
        raise NotImplementedError

    # ---------------------------------------------------------------------------- gymnasium API

    @property
    def world(self) -> World:
        """The scene's layout, free space and renderer (built on first use, in this process)."""
        if self._world is None:
            self._world = World(self.scene, self.config.width, self.config.height, self._cache / "renders")
        return self._world

    def reset(
        self, *, seed: int | None = None, options: dict[str, Any] | None = None
    ) -> tuple[dict[str, np.ndarray], dict[str, Any]]:
        unknown = sorted(set(options or {}) - set(self.reset_options))
        if unknown:
            known = ", ".join(self.reset_options) or "none"
            raise ValueError(
                f"unknown reset option(s) {', '.join(map(repr, unknown))} (this environment reads: {known})"
            )
        super().reset(seed=seed)
        self._steps = 0
        self._ended = False
        self._path_m = 0.0
        self._calls = 0
        self._estimate, self._answer, self._answer_view = None, None, None
        self._fresh = False
        info = self._task_reset(dict(options or {}))
        self._camera = self.world.camera(self._pose, self.config.camera_height)
        if self.relocalizer is not None and self.config.relocalize_every:
            self._relocalize()
        obs = self._observe()
        if self.render_mode == "human":
            self.render()
        return obs, {**info, "collided": False, "relocalized": self._fresh}

    def step(self, action: Any) -> tuple[dict[str, np.ndarray], float, bool, bool, dict[str, Any]]:
        if self._pose is None:
            raise gym.error.ResetNeeded("call reset() before step()")
        if self._ended:
            raise gym.error.ResetNeeded("the episode has ended (terminated or truncated): call reset() before step()")
        if not self.action_space.contains(action):
            names = ", ".join(f"{i} {n}" for i, n in enumerate(self.action_names))
            raise gym.error.InvalidAction(f"invalid action {action!r} (Discrete(6): {names})")
        cfg, action = self.config, int(action)
        self._steps += 1
        self._fresh = False
        T_before = self._camera
        moved = 0.0
        if action == FORWARD:
            target = self._pose.xy + cfg.forward_m * self._pose.heading
            if self.world.passable(self._pose.floor, self._pose.xy, target):
                self._pose.xy, moved = target, cfg.forward_m
        elif action in (TURN_LEFT, TURN_RIGHT):
            yaw = self._pose.yaw + np.radians(cfg.turn_deg) * (1 if action == TURN_LEFT else -1)
            self._pose.yaw = float(np.arctan2(np.sin(yaw), np.cos(yaw)))
        elif action in (LOOK_UP, LOOK_DOWN):
            pitch = self._pose.pitch + np.radians(cfg.tilt_deg) * (1 if action == LOOK_UP else -1)
            limit = np.radians(cfg.max_tilt_deg)
            self._pose.pitch = float(np.clip(pitch, -limit, limit))
        self._path_m += moved
        self._camera = self.world.camera(self._pose, cfg.camera_height)
        if self._estimate is not None and self._estimate.T_wc is not None:  # odometry carries the estimate
            motion = geometry.invert(T_before) @ self._camera
            self._estimate = Estimate(self._estimate.T_wc @ motion, self._estimate.matched)
        every = cfg.relocalize_every
        if action != DONE and self.relocalizer is not None and every and self._steps % every == 0:
            self._relocalize()
        reward, terminated, info = self._task_step(action)
        reward -= cfg.step_penalty
        truncated = not terminated and self._steps >= cfg.max_steps
        info["collided"] = action == FORWARD and moved == 0.0
        info["relocalized"] = self._fresh
        if terminated or truncated:
            self._ended = True
            info.update(self._episode_metrics())
        obs = self._observe()
        if self.render_mode == "human":
            self.render()
        return obs, float(reward), terminated, truncated, info

    def render(self) -> np.ndarray | None:
        """``rgb_array``: the top-down map (agent green, estimate orange, goal blue) beside the agent's view."""
        if self.render_mode is None:
            gym.logger.warn("render() without a render_mode: pass render_mode='rgb_array' or 'human'")
            return None
        if self._pose is None or self._rgb is None:
            raise gym.error.ResetNeeded("call reset() before render()")
        if self._headless:
            return None
        estimate = None if self._estimate is None else self._estimate.T_wc
        top = self.world.top_down(self._pose.floor, self.camera_pose, estimate, self._goal_box())
        h = top.shape[0]
        view = self._rgb if self._rgb.shape[0] == h else _resize(self._rgb, h)
        frame = np.concatenate([top, view], axis=1)
        if self.render_mode == "rgb_array":
            return frame
        if self._window is None:
            self._window = _Window(self.spec.id if self.spec else type(self).__name__, self.metadata["render_fps"])
        self._window.show(frame)
        return None

    def close(self) -> None:
        if self._world is not None:
            self._world.close()
            self._world = None
        if self._window is not None:
            self._window.close()
            self._window = None

    # ---------------------------------------------------------------------------- helpers

    @property
    def action_names(self) -> tuple[str, ...]:
        return (*MOVES, self.final_action)

    @property
    def agent_pose(self) -> AgentPose:
        """The agent's true floor, position, heading and tilt (privileged: for metrics, scripts and tests)."""
        assert self._pose is not None
        return self._pose.copy()

    @property
    def camera_pose(self) -> np.ndarray:
        """The agent camera's true camera-to-world pose (privileged: for metrics, scripts and tests)."""
        assert self._pose is not None
        return self._camera.copy()

    def _goal_box(self) -> np.ndarray | None:
        """World box of the goal object drawn on the map (None: no goal)."""
        return None

    def _relocalize(self) -> Estimate:
        """Ask the relocalizer about the current view (once per view) and make its answer the estimate,
        unless it fails and an earlier (carried) estimate exists."""
        assert self.relocalizer is not None
        cfg, world = self.config, self.world
        T = self._camera
        if self._answer is not None and np.array_equal(T, self._answer_view):
            self._fresh = self._answer.T_wc is not None
            return self._answer
        spec = self.scene_spec
        name = f"agent/{self._steps:06d}"
        if cfg.track == ORACLE_MASK:
            rgb, _, instance = world.renderer.render(T, world.K, spec.width, spec.height)
        else:
            rgb, instance = world.render(T, world.K, spec.width, spec.height)[0], None
        answer = self.relocalizer.localize(name, rgb, world.K, instance)
        self._calls += 1
        self._answer, self._answer_view = answer, T
        self._fresh = answer.T_wc is not None
        if answer.T_wc is not None or self._estimate is None:
            self._estimate = answer
        else:
            self._estimate = Estimate(self._estimate.T_wc, answer.matched, answer.reason)
        return answer

    def _observe(self) -> dict[str, np.ndarray]:
        cfg = self.config
        rgb, depth = self.world.render(self._camera, self._K_obs, cfg.width, cfg.height, cfg.depth)
        self._rgb = rgb
        obs: dict[str, np.ndarray] = {"rgb": rgb}
        if depth is not None:
            obs["depth"] = np.clip(depth, 0.0, self._depth_max)[..., None]
        if self.relocalizer is not None:
            est = self._estimate
            vec = np.zeros(7, np.float32)
            if est is not None and est.T_wc is not None:
                q, t = geometry.pose_to_qt(est.T_wc)
                vec = np.clip(np.r_[t, q], self._estimate_low, self._estimate_high).astype(np.float32)
            obs["estimate"] = vec
            obs["valid"] = np.array([est is not None and est.T_wc is not None], dtype=np.int8)
            obs["matched"] = np.array([0.0 if est is None else est.matched], dtype=np.float32)
        obs.update(self._task_observation())
        return obs

    def _base_metrics(self) -> dict[str, Any]:
        return {"episode_steps": self._steps, "path_length": self._path_m, "relocalizer_calls": self._calls}


def _resize(image: np.ndarray, height: int) -> np.ndarray:
    import cv2

    width = max(1, round(image.shape[1] * height / image.shape[0]))
    return cv2.resize(image, (width, height), interpolation=cv2.INTER_NEAREST)
