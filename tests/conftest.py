"""Shared fixtures: tiny scenes written in the project's layout (no renderer needed)."""

from __future__ import annotations

import sys
from collections.abc import Iterator
from pathlib import Path

import numpy as np
import pytest

from openreloc_bench import geometry
from openreloc_bench.data.paths import CACHE_ENV
from openreloc_bench.data.scene import ObjectInfo, SceneWriter


def write_tiny_scene(
    root: Path, n_mapping: int = 6, n_query: int = 3, hw: tuple[int, int] = (24, 32), seed: int = 0
) -> Path:
    """A scene of random-texture frames on a circle of poses, with one box-shaped 'object' id 1.

    Good for format, harness and method-contract tests; not geometrically consistent imagery.
    """
    rng = np.random.default_rng(seed)
    h, w = hw
    K = geometry.intrinsics_from_fov(w, h, 60.0)
    writer = SceneWriter(root)
    writer.write_scene_info({"spec_hash": f"tiny-{seed}", "seed": seed, "width": w, "height": h})
    writer.write_objects([ObjectInfo(id=1, category="box", aabb=[[-0.5, -0.5, 0.0], [0.5, 0.5, 1.0]])])
    for split, n, phase in (("mapping", n_mapping, 0.0), ("query", n_query, 0.5)):
        writer.write_intrinsics(split, K)
        for i in range(n):
            a = 2 * np.pi * (i + phase) / n
            T = geometry.look_at([3 * np.cos(a), 3 * np.sin(a), 1.5], [0, 0, 0.5])
            color = rng.integers(0, 255, (h, w, 3), dtype=np.uint8)
            depth = np.full((h, w), 3.0, np.float32)
            inst = np.zeros((h, w), np.int32)
            inst[h // 4 : 3 * h // 4, w // 4 : 3 * w // 4] = 1
            writer.write_frame(split, i, color, depth, inst, T)
    return root


@pytest.fixture(autouse=True)
def user_cache(tmp_path_factory: pytest.TempPathFactory, monkeypatch: pytest.MonkeyPatch) -> Path:
    """Each test's user cache (:func:`~openreloc_bench.data.paths.cache_root`), also for the commands it
    starts: a fresh folder, never the tester's own cache."""
    root = tmp_path_factory.mktemp("user-cache")
    monkeypatch.setenv(CACHE_ENV, str(root))
    return root


@pytest.fixture
def tiny_scene(tmp_path: Path) -> Path:
    return write_tiny_scene(tmp_path / "tiny")


FREE_PLUGIN = """
from baselines.nearest_frame import NearestFrame
from openreloc_bench.methods import register


class Free(NearestFrame):
    name = "free-plugin"


register("free-plugin", Free)
"""
"""A plugin registering ``free-plugin``: nearest-frame under another name, declaring it reads no masks."""


@pytest.fixture
def plugin_sandbox(tmp_path: Path, monkeypatch: pytest.MonkeyPatch) -> Iterator[Path]:
    """A folder for plugin files (``tmp_path``); what they register and import is forgotten after the test."""
    from openreloc_bench import methods

    monkeypatch.setattr(methods, "_REGISTRY", dict(methods._REGISTRY))
    monkeypatch.setattr(sys, "path", list(sys.path))
    yield tmp_path
    for name, module in list(sys.modules.items()):
        file = getattr(module, "__file__", None)
        if file and Path(file).resolve().is_relative_to(tmp_path.resolve()):
            del sys.modules[name]
