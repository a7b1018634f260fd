"""Gymnasium environments: relocalization and language-goal navigation for embodied agents.

Importing this package registers (one environment per module)

- ``openreloc/ActiveReloc-v0`` (:mod:`.active_reloc`): a kidnapped camera agent looks around and
  localizes itself with a relocalizer in the loop;
- ``openreloc/ObjectGoal-v0`` (:mod:`.object_goal`): walk to an object described in language.

gymnasium >= 1.0 no longer discovers environments through package entry points, so import this
package first, or name it in the id, which imports it (also inside vector-environment workers)::

    import gymnasium as gym
    env = gym.make("openreloc_bench.envs:openreloc/ActiveReloc-v0", method="nearest-frame")

Options are the fields of :class:`~.active_reloc.ActiveRelocConfig` / :class:`~.object_goal.ObjectGoalConfig`.
"""

from gymnasium.envs.registration import register, registry

from openreloc_bench.envs.base import EnvConfig, EnvConfigError, IndoorEnv  # noqa: F401

NAMESPACE = "openreloc"
ENVIRONMENTS = {
    f"{NAMESPACE}/ActiveReloc-v0": "openreloc_bench.envs.active_reloc:ActiveRelocEnv",
    f"{NAMESPACE}/ObjectGoal-v0": "openreloc_bench.envs.object_goal:ObjectGoalEnv",
}

for _id, _entry_point in ENVIRONMENTS.items():
    if _id not in registry:
        register(id=_id, entry_point=_entry_point)
