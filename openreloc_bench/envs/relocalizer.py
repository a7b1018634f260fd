"""A registered relocalization method in the agent's loop: its map built once per (map key, scene) and
cached, then one ``localize`` call per view the environment asks about.

The map is built on the environment's track (the dataset's masks on the oracle-mask track only, none for
a method that reads no masks), as ``eval`` builds it. Maps go to
``<cache>/maps/<method>/<map key>/<scene>-<spec hash>/`` through the harness's
:func:`~openreloc_bench.harness.cache.cached_map` (the same completion record, so a map is rebuilt when
the scene's spec changes), under a lock so that the workers of a vector environment build it once
between them.
"""

from __future__ import annotations

import logging
from dataclasses import dataclass
from pathlib import Path
from typing import Any

import numpy as np

from openreloc_bench.data.scene import Scene
from openreloc_bench.envs.scenes import locked, scene_key
from openreloc_bench.harness import cache
from openreloc_bench.methods import QueryFrame, create_method, localize_safely, map_config, recorded_track
from openreloc_bench.tracks import ORACLE_MASK, Track

log = logging.getLogger(__name__)


@dataclass
class Estimate:
    """One answer of the relocalizer."""

    T_wc: np.ndarray | None
    """Camera-to-world pose, or None when the method failed."""
    matched: int
    """Objects the method matched to its map (the length of its diagnostics' ``matches``; 0 if it reports none)."""
    reason: str = ""
    """Why there is no pose ("" when there is one)."""


class InLoopRelocalizer:
    """One method with its map of one scene; the map is built or loaded on first use."""

    def __init__(self, method: str, options: dict[str, Any], scene: Scene, cache_root: Path, track: Track):
        self.method = create_method(method, **options)
        self.name = method
        self.scene = scene
        self.track = recorded_track(self.method, track)
        """The masks the map is built from and the queries carry: ``mask-free`` for a method that reads none."""
        self.map_dir = cache.map_folder(cache_root, method, cache.map_key(self.method, self.track), scene_key(scene))
        self._cache_root = cache_root
        self._loaded = False

    def ensure_loaded(self) -> None:
        """Build the map unless a valid cached one exists (once across processes), then load it."""
        if self._loaded:
            return
        with locked(self._cache_root, f"map-{self.name}-{self.map_dir.parent.name}-{self.map_dir.name}"):
            if cache.read_map_record(self.map_dir, self.scene.spec_hash) is None:
                log.info("building the %s map of %s (once; cached in %s)", self.name, self.scene.name, self.map_dir)
            extra = {"method": self.name, "scene": self.scene.name, "map_config": map_config(self.method)}
            cache.cached_map(self.method, self.scene, self.track, self.map_dir, extra)
        self.method.load_map(self.map_dir)
        self._loaded = True

    def localize(self, name: str, rgb: np.ndarray, K: np.ndarray, instance: np.ndarray | None = None) -> Estimate:
        """Ask the method about one view. A method that raises or answers nonsense fails this view (with
        the reason), as in the harness: a bug in a method must not end a training run."""
        self.ensure_loaded()
        query = QueryFrame(name, rgb, K, instance if self.track == ORACLE_MASK else None, self.track)
        answer = localize_safely(self.method, query)
        matches = answer.diagnostics.get("matches")
        return Estimate(answer.T_wc, len(matches) if isinstance(matches, list) else 0, answer.reason)
