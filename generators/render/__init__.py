"""Offscreen rendering of a :class:`~generators.layout.Layout`: RGB, metric depth and instance ids.

The interface is :class:`~generators.render.base.Renderer` (``render(T_wc, K, width, height)``,
``set_lighting``, ``set_instance_pose``), with what both backends share (:mod:`~generators.render.base`);
:func:`create_renderer` picks a backend by name: MuJoCo (:mod:`~generators.render.mujoco_backend`, the
default) or pyrender (:mod:`~generators.render.pyrender_backend`, the optional extra, imported on demand).
Importing this package sets ``MUJOCO_GL`` before MuJoCo loads; no GL context is created before the first
render.
"""

from pathlib import Path

from generators.layout import Layout
from generators.render.base import Renderer
from generators.render.mujoco_backend import MujocoRenderer
from openreloc_bench.errors import ConfigError

__all__ = ["Renderer", "create_renderer"]


def create_renderer(
    layout: Layout, backend: str = "mujoco", max_width: int = 640, max_height: int = 480, compiled: Path | None = None
) -> Renderer:
    """Renderer for ``layout``; ``backend`` is 'mujoco' (default) or 'pyrender' (the optional extra).
    ``compiled``: where MuJoCo keeps the compiled scene for the next renderer (pyrender compiles none)."""
    if backend == "mujoco":
        return MujocoRenderer(layout, max_width, max_height, compiled)
    if backend == "pyrender":
        from generators.render.pyrender_backend import PyrenderRenderer  # optional extra: imported on demand

        return PyrenderRenderer(layout, max_width, max_height)
    raise ConfigError(f"unknown renderer backend '{backend}' (known: mujoco, pyrender)")
