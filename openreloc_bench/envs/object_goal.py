"""``openreloc/ObjectGoal-v0``: walk to an object described in language and stop in front of it.

The goal is one of the scene's objects, named by its ``objects.json`` description and its room
("a club armchair in orange in the bedroom"): as text in ``info["goal"]`` and as a fixed-size text
embedding in the ``goal`` observation (the project's text encoder, ``text_encoder``; embeddings are
computed once per scene and cached). Action 5, ``stop``, ends the episode; it succeeds when the camera
stands within ``success_distance`` (horizontally) of the object's box and the object is in view
(covering at least the generator's 0.5 % of the image), Habitat ObjectNav's rule with its 1 m.

Distances are geodesic: shortest paths through the walkable free space (10 cm grid, 8-connected) to
the goal zone, the walkable cells within ``success_distance`` of the object. Reward: the decrease of
that distance, ``success_reward`` at a successful ``stop``, minus ``step_penalty`` per step.

Final ``info``: ``success``, ``spl`` = S * l / max(p, l) (l: geodesic start distance, p: path walked),
``soft_spl`` = max(0, 1 - d_T / l) * l / max(p, l), ``distance_to_goal`` (d_T, m), ``start_distance``
(l), ``episode_steps``, ``path_length``, ``relocalizer_calls``. No relocalizer by default (``method``).
"""

from __future__ import annotations

from dataclasses import dataclass, field
from typing import Any

import numpy as np
from gymnasium import spaces
from scipy.sparse.csgraph import dijkstra

from generators.layout.free_space import GRID_RES
from generators.trajectories import grid_graph
from openreloc_bench.data import io
from openreloc_bench.data.scene import ObjectInfo
from openreloc_bench.envs.base import DONE, EnvConfig, EnvConfigError, IndoorEnv
from openreloc_bench.envs.scenes import locked, scene_key
from openreloc_bench.envs.world import AgentPose
from openreloc_bench.errors import ConfigError
from openreloc_bench.harness.cache import config_hash


@dataclass
class ObjectGoalConfig(EnvConfig):
    """Options of ``openreloc/ObjectGoal-v0`` (on top of :class:`~openreloc_bench.envs.base.EnvConfig`)."""

    method: str | None = None
    """Registered relocalization method in the loop; None (default): pure navigation."""
    max_steps: int = 500
    """Steps after which the episode is truncated (Habitat ObjectNav's 500)."""
    success_distance: float = 1.0
    """Largest horizontal distance (m) from the camera to the object's box at a successful ``stop``."""
    success_reward: float = 2.5
    """Reward of a successful ``stop``."""
    min_start_distance: float = 1.0
    """Smallest geodesic distance (m) from the start to the goal zone."""
    text_encoder: str = "offline"
    """Registered text encoder of the ``goal`` embedding (``offline``: MiniLM, 384-d; ``clip``)."""
    text_encoder_options: dict[str, Any] = field(default_factory=dict)
    """Its options (e.g. ``{"model": DIR}`` for ``clip``)."""

    def __post_init__(self) -> None:
        super().__post_init__()
        if self.success_distance <= 0 or self.min_start_distance < 0:
            raise ValueError("success_distance must be positive and min_start_distance >= 0")
        if self.method is not None and not self.relocalize_every:
            raise ValueError("with a relocalizer, relocalize_every must be >= 1 (stop never asks it)")


def goal_text(obj: ObjectInfo, room_kinds: dict[str, str]) -> str:
    """The goal's description and its room, e.g. "a club armchair in orange in the bedroom"."""
    kind = room_kinds.get(obj.room or "")
    return f"{obj.description} in the {kind.replace('_', ' ')}" if kind else obj.description


class ObjectGoalEnv(IndoorEnv):
    """Language-goal object navigation (see the module docstring)."""

    config_class = ObjectGoalConfig
    final_action = "stop"
    reset_options = ("goal_id",)
    config: ObjectGoalConfig

    # ---------------------------------------------------------------------------- setup

    def _task_setup(self) -> None:
        rooms = {r["name"]: r["kind"] for r in self.scene.info.get("rooms", [])}
        self.goals = [o for o in self.scene.objects.values() if not o.structural and o.description.strip()]
        if not self.goals:
            raise ConfigError(f"scene {self.scene.root}: no object has a description (objects.json)")
        self.goal_texts = [goal_text(o, rooms) for o in self.goals]
        self.goal_embeddings = self._embed(self.goal_texts)
        self._fields: dict[int, np.ndarray] = {}
        self._reachable: list[int] | None = None

    def _embed(self, texts: list[str]) -> np.ndarray:
        """Text embeddings of the goals, computed once per (scene, encoder) and cached on disk."""
        from openreloc_bench.vision.base import create_encoder, encoder_fingerprint

        cfg = self.config
        key = config_hash(
            {
                "encoder": cfg.text_encoder,
                "options": cfg.text_encoder_options,
                "weights": encoder_fingerprint(cfg.text_encoder, cfg.text_encoder_options),
                "texts": texts,
            }
        )
        path = self._cache / "goals" / scene_key(self.scene) / f"{cfg.text_encoder}-{key}.npy"
        if not path.is_file():
            with locked(self._cache, f"goals-{scene_key(self.scene)}-{key}"):
                if not path.is_file():
                    encoder = create_encoder(cfg.text_encoder, **cfg.text_encoder_options)
                    emb = np.clip(np.asarray(encoder.encode_texts(texts), np.float32), -1.0, 1.0)
                    io.atomic_write_npy(path, emb)
        return np.load(path)

    def _task_spaces(self) -> dict[str, spaces.Space]:
        return {"goal": spaces.Box(-1.0, 1.0, (self.goal_embeddings.shape[1],), np.float32)}

    # ---------------------------------------------------------------------------- geometry of the goal

    @property
    def goal_object(self) -> ObjectInfo:
        """This episode's goal object."""
        return self.goals[self._goal]

    def goal_footprint_distance(self, xy: np.ndarray, k: int | None = None) -> np.ndarray:
        """Horizontal distance (m) from points ``xy`` (..., 2) to goal ``k``'s box footprint (0 inside;
        default: this episode's goal)."""
        box = self.goals[self._goal if k is None else k].aabb_array
        gap = np.maximum(np.maximum(box[0, :2] - xy, xy - box[1, :2]), 0.0)
        return np.linalg.norm(gap, axis=-1)

    def _zone(self, k: int) -> np.ndarray:
        """(N, 2) walkable cells (row, column) within ``success_distance`` of goal ``k``'s footprint."""
        cells = self.world.walkable_cells(self.goals[k].floor)
        centres = self.world.grids[self.goals[k].floor].centre(cells[:, 0], cells[:, 1])
        return cells[self.goal_footprint_distance(centres, k) <= self.config.success_distance]

    def distance_field(self, k: int) -> np.ndarray:
        """Geodesic distance (m) from every cell of goal ``k``'s floor to its goal zone (inf: unreachable)."""
        if k not in self._fields:
            grid, zone = self.world.grids[self.goals[k].floor], self._zone(k)
            out = np.full(grid.free.shape, np.inf)
            if len(zone):
                graph, index, free_cells = grid_graph(grid)
                dist = dijkstra(graph, directed=False, indices=index[zone[:, 0], zone[:, 1]], min_only=True)
                out[free_cells[:, 0], free_cells[:, 1]] = dist * GRID_RES
            self._fields[k] = out
        return self._fields[k]

    def facing(self, xy: np.ndarray, k: int | None = None) -> AgentPose:
        """The pose at ``xy`` that looks at goal ``k``'s box centre as nearly as the action set allows
        (any heading, tilt a multiple of ``tilt_deg``)."""
        k = self._goal if k is None else k
        obj, cfg = self.goals[k], self.config
        centre = obj.aabb_array.mean(axis=0)
        offset = centre[:2] - xy
        rise = centre[2] - (self.world.layout.floor_z[obj.floor] + cfg.camera_height)
        step, limit = np.radians(cfg.tilt_deg), np.radians(cfg.max_tilt_deg)
        tilt = np.arctan2(rise, max(float(np.linalg.norm(offset)), 1e-6))
        tilt = float(
            np.clip(np.round(tilt / step) * step, -np.floor(limit / step) * step, np.floor(limit / step) * step)
        )
        return AgentPose(obj.floor, np.asarray(xy, float), float(np.arctan2(offset[1], offset[0])), tilt)

    def _seen_from_zone(self, k: int, probes: int = 8) -> bool:
        """Whether goal ``k`` is in view from one of the ``probes`` zone cells nearest to it, facing it."""
        zone = self._zone(k)
        grid = self.world.grids[self.goals[k].floor]
        centres = grid.centre(zone[:, 0], zone[:, 1])
        nearest = centres[np.argsort(self.goal_footprint_distance(centres, k), kind="stable")[:probes]]
        cams = (self.world.camera(self.facing(xy, k), self.config.camera_height) for xy in nearest)
        return any(self.world.in_view(self.world.visible_share(T, self.goals[k].id)) for T in cams)

    def geodesic_distance(self, xy: np.ndarray, k: int | None = None) -> float:
        """Geodesic distance (m) from ``xy`` on the goal's floor to goal ``k``'s zone (default: this episode's)."""
        k = self._goal if k is None else k
        field = self.distance_field(k)
        r, c = self.world.grids[self.goals[k].floor].cell(xy)
        if not (0 <= r[0] < field.shape[0] and 0 <= c[0] < field.shape[1]):
            return float("inf")
        return float(field[r[0], c[0]])

    def _starts(self, k: int) -> np.ndarray:
        """Walkable cells of goal ``k``'s floor at least ``min_start_distance`` from its zone (and reachable)."""
        field = self.distance_field(k)
        cells = self.world.walkable_cells(self.goals[k].floor)
        d = field[cells[:, 0], cells[:, 1]]
        return cells[np.isfinite(d) & (d >= max(self.config.min_start_distance, GRID_RES))]

    # ---------------------------------------------------------------------------- episode

    @property
    def reachable_goals(self) -> list[int]:
        """Indices (into ``goals``) of the objects that are goals of some episode: a start at least
        ``min_start_distance`` from their zone exists, and the object is in view from its zone (a goal
        hidden from everywhere near it, e.g. behind a shelf's rim, could never be reached)."""
        if self._reachable is None:
            self._reachable = [k for k in range(len(self.goals)) if len(self._starts(k)) and self._seen_from_zone(k)]
            if not self._reachable:
                raise EnvConfigError(f"{type(self).__name__}: scene {self.scene.root}: no goal object has a start")
        return self._reachable

    def _task_reset(self, options: dict[str, Any]) -> dict[str, Any]:
        if "goal_id" in options:
            ids = {self.goals[k].id: k for k in self.reachable_goals}
            if options["goal_id"] not in ids:
                raise ValueError(f"goal_id {options['goal_id']!r} is not a reachable goal object ({sorted(ids)})")
            self._goal = ids[options["goal_id"]]
        else:
            self._goal = self.reachable_goals[int(self.np_random.integers(len(self.reachable_goals)))]
        starts = self._starts(self._goal)
        r, c = starts[int(self.np_random.integers(len(starts)))]
        floor = self.goals[self._goal].floor
        xy = self.world.grids[floor].centre(np.array([r]), np.array([c]))[0]
        self._pose = AgentPose(floor, xy, float(self.np_random.uniform(-np.pi, np.pi)), 0.0)
        self._start_distance = self._distance = self.geodesic_distance(self._pose.xy)
        self._stopped_in_view = False
        return self._goal_info()

    def _goal_info(self) -> dict[str, Any]:
        return {"goal": self.goal_texts[self._goal], "goal_id": self.goals[self._goal].id}

    def _task_observation(self) -> dict[str, np.ndarray]:
        return {"goal": self.goal_embeddings[self._goal].copy()}

    def _goal_box(self) -> np.ndarray:
        return self.goals[self._goal].aabb_array

    def _task_step(self, action: int) -> tuple[float, bool, dict[str, Any]]:
        previous, self._distance = self._distance, self.geodesic_distance(self._pose.xy)
        reward = previous - self._distance
        if action == DONE:
            near = self.goal_footprint_distance(self._pose.xy) <= self.config.success_distance
            self._stopped_in_view = bool(
                near and self.world.in_view(self.world.visible_share(self.camera_pose, self.goals[self._goal].id))
            )
            reward += self.config.success_reward * self._stopped_in_view
        return reward, action == DONE, self._goal_info()

    def _episode_metrics(self) -> dict[str, Any]:
        success, d0, d, p = self._stopped_in_view, self._start_distance, self._distance, self._path_m
        return {
            "success": success,
            "spl": float(success) * d0 / max(p, d0),
            "soft_spl": max(0.0, 1.0 - d / d0) * d0 / max(p, d0),
            "distance_to_goal": d,
            "start_distance": d0,
            **self._base_metrics(),
        }
