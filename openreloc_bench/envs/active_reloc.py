"""``openreloc/ActiveReloc-v0``: a kidnapped camera agent must look around and localize itself.

Each episode starts at a uniformly random walkable position of the scene with a random heading (the
agent is not told where). Action 5, ``localize``, ends the episode with the relocalizer's answer for
the current view (its odometry-carried estimate where the method fails there); it succeeds when
that answer is within ``success_m`` and ``success_deg`` of the true camera pose (25 cm, 5 degrees:
the benchmark's combined threshold). Reward: ``success_reward`` or ``failure_reward`` at
``localize``, minus ``step_penalty`` at every step (as in active camera localization with a
relocalizer in the loop, Fang et al. 2022). A truncated episode has not localized: it is a failure
without the terminal reward.

Final ``info``: ``success``, ``translation_error`` (m) and ``rotation_error`` (deg) of the answer (inf
without one), ``episode_steps``, ``path_length`` (m), ``relocalizer_calls``.
"""

from __future__ import annotations

from dataclasses import dataclass
from typing import Any

from openreloc_bench import geometry
from openreloc_bench.envs.base import DONE, EnvConfig, IndoorEnv


@dataclass
class ActiveRelocConfig(EnvConfig):
    """Options of ``openreloc/ActiveReloc-v0`` (on top of :class:`~openreloc_bench.envs.base.EnvConfig`)."""

    success_m: float = 0.25
    """Largest camera-centre error (m) of a successful localization."""
    success_deg: float = 5.0
    """Largest rotation error (degrees) of a successful localization."""
    success_reward: float = 1.0
    """Reward of a successful ``localize``."""
    failure_reward: float = -1.0
    """Reward of a failed ``localize``."""

    def __post_init__(self) -> None:
        super().__post_init__()
        if self.method is None:
            raise ValueError("ActiveReloc needs a relocalizer: 'method' cannot be None")
        if self.success_m <= 0 or self.success_deg <= 0:
            raise ValueError("success_m and success_deg must be positive")


class ActiveRelocEnv(IndoorEnv):
    """Kidnapped-robot relocalization with a relocalizer in the loop (see the module docstring)."""

    config_class = ActiveRelocConfig
    final_action = "localize"
    config: ActiveRelocConfig

    def _task_reset(self, options: dict[str, Any]) -> dict[str, Any]:
        self._pose = self.world.sample_pose(self.np_random)
        self._localized = False
        return {}

    def _task_step(self, action: int) -> tuple[float, bool, dict[str, Any]]:
        if action != DONE:
            return 0.0, False, {}
        self._relocalize()
        self._localized = True
        cfg = self.config
        return (cfg.success_reward if self._errors()[2] else cfg.failure_reward), True, {}

    def _errors(self) -> tuple[float, float, bool]:
        """(translation error m, rotation error deg, success) of the current estimate."""
        est = None if self._estimate is None else self._estimate.T_wc
        if est is None:
            return float("inf"), float("inf"), False
        t_err, r_err = (float(e) for e in geometry.pose_errors(self.camera_pose, est))
        return t_err, r_err, self._localized and t_err <= self.config.success_m and r_err <= self.config.success_deg

    def _episode_metrics(self) -> dict[str, Any]:
        t_err, r_err, success = self._errors()
        return {"success": success, "translation_error": t_err, "rotation_error": r_err, **self._base_metrics()}
