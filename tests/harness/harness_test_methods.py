"""Test-only methods and tiny scenes for the harness tests.

Importable by module name (``--plugin harness_test_methods``) so spawned workers register the same
methods as the test process.
"""

from __future__ import annotations

import multiprocessing
import multiprocessing.util
import os
import time
import zlib
from dataclasses import dataclass
from pathlib import Path
from typing import Any

import numpy as np
import pandas as pd
from scipy.spatial.transform import Rotation
from tqdm import tqdm

from openreloc_bench import geometry, methods
from openreloc_bench.data import io
from openreloc_bench.data.scene import DATA_VERSION, DIFFICULTY_COLUMNS, SceneWriter
from openreloc_bench.data.types import SceneSequence
from openreloc_bench.methods import Failure, PoseEstimate, QueryFrame

_KEPT: list[Any] = []
"""Objects ``build_map`` keeps for the life of its process."""


ORACLE_CONFIDENCE = 0.9
"""What the test oracles say of every pose they return."""


@dataclass
class OracleConfig:
    """Config of :class:`NoisyOracle`."""

    noise_m: float = 0.05
    """Translation noise (metres, fixed length, direction seeded by the query name)."""
    noise_deg: float = 1.0
    """Rotation noise (degrees, fixed angle, axis seeded by the query name)."""
    fail_on: str = ""
    """Query name answered with an explicit Failure."""
    raise_on: str = ""
    """Query name on which localize raises."""
    hang_on: str = ""
    """Query name on which localize sleeps for an hour."""
    hang_in: str = ""
    """``build_map`` or ``load_map``: that call sleeps for an hour."""
    delay_s: float = 0.0
    """Sleep per query (to make runs slow enough to kill)."""
    expect_track: str = ""
    """If set, raise when a query comes from another track."""
    map_tag: str = ""
    """Written into the map: the one map-time setting (the others act at query time)."""
    seed: int = 0
    """Adds ``seed`` x 10 cm to the translation noise, so runs over seeds differ by a known amount."""
    odd_diagnostics: bool = False
    """Diagnostics that JSON cannot hold as they are: NaN, infinity, a set, a numpy array with a NaN."""
    slow_exit_s: float = 0.0
    """``build_map`` leaves a semaphore and makes its process's exit take this long, as libraries that
    keep multiprocessing locks (tqdm, torch) do."""


class NoisyOracle:
    """Reads the query's ground truth from disk and perturbs it by a known amount."""

    name = "test-oracle"

    def __init__(self, **overrides: Any):
        self.config = OracleConfig(**overrides)
        self._root: Path | None = None

    def map_config(self) -> dict[str, Any]:
        return {"map_tag": self.config.map_tag}

    def build_map(self, mapping: SceneSequence, map_dir: Path) -> None:
        if self.config.hang_in == "build_map":
            time.sleep(3600)
        if self.config.slow_exit_s:
            _KEPT.append(multiprocessing.get_context("spawn").Lock())  # a semaphore the resource tracker knows
            multiprocessing.util.Finalize(None, time.sleep, args=(self.config.slow_exit_s,), exitpriority=100)
        root = mapping.records[0].color_path.parents[2]
        io.write_json(Path(map_dir) / "oracle.json", {"scene_root": str(root), "map_tag": self.config.map_tag})

    def load_map(self, map_dir: Path) -> None:
        if self.config.hang_in == "load_map":
            time.sleep(3600)
        self._root = Path(io.read_json(Path(map_dir) / "oracle.json")["scene_root"])

    def localize(self, query: QueryFrame) -> PoseEstimate | Failure:
        c = self.config
        if c.delay_s:
            time.sleep(c.delay_s)
        if c.expect_track and (
            query.track != c.expect_track or (query.instance is not None) != (query.track == "oracle-mask")
        ):
            raise RuntimeError(f"got a {query.track} query" + (" with masks" if query.instance is not None else ""))
        if query.name == c.raise_on:
            raise RuntimeError("boom")
        if query.name == c.hang_on:
            time.sleep(3600)
        if query.name == c.fail_on:
            return Failure("no objects recognised")
        split, fid = query.name.split("/")
        T = io.read_matrix(self._root / split / "pose" / f"{fid}.txt")
        odd = (
            {"nan": np.nan, "inf": np.inf, "set": {2, 1}, "array": np.array([np.nan, 1.0])} if c.odd_diagnostics else {}
        )
        T_est = perturb(T, query.name, c.noise_m + 0.1 * c.seed, c.noise_deg)
        return PoseEstimate(T_est, odd, confidence=ORACLE_CONFIDENCE)


def perturb(T: np.ndarray, name: str, noise_m: float, noise_deg: float) -> np.ndarray:
    """T moved by exactly ``noise_m`` and rotated by exactly ``noise_deg`` (directions seeded by name)."""
    rng = np.random.default_rng(zlib.crc32(name.encode()))
    d, axis = rng.normal(size=3), rng.normal(size=3)
    out = T.copy()
    out[:3, 3] += noise_m * d / np.linalg.norm(d)
    out[:3, :3] = T[:3, :3] @ Rotation.from_rotvec(np.radians(noise_deg) * axis / np.linalg.norm(axis)).as_matrix()
    return out


class MaskFreeOracle(NoisyOracle):
    """The same, declared to read no masks (its map serves both tracks; its rows stand in both tables)."""

    name = "test-oracle-mask-free"
    uses_masks = False


class SeededMapOracle(NoisyOracle):
    """The same with a map that depends on the seed, as a trained pose regressor's does."""

    name = "test-oracle-seeded-map"

    def map_config(self) -> dict[str, Any]:
        return {**super().map_config(), "seed": self.config.seed}


methods.register("test-oracle", NoisyOracle)
methods.register("test-oracle-mask-free", MaskFreeOracle)
methods.register("test-oracle-seeded-map", SeededMapOracle)


def make_scene(
    root: Path, name: str, n_map: int = 4, n_query: int = 3, splits: tuple[str, ...] = ("query",), seed: int = 0
) -> Path:
    """A tiny scene (32x24 random images with depth, instances and random poses in a 4 m room)."""
    rng = np.random.default_rng(seed)
    w = SceneWriter(root / name)
    K = geometry.intrinsics_from_fov(32, 24, 60.0)
    w.write_scene_info({"name": name, "spec_hash": f"hash-{name}-{seed}", "seed": seed})
    for split, n in [("mapping", n_map), *[(s, n_query) for s in splits]]:
        w.write_intrinsics(split, K)
        for i in range(n):
            eye = np.array([rng.uniform(0, 4), rng.uniform(0, 4), 1.5])
            target = eye + np.array([np.cos(a := rng.uniform(0, 2 * np.pi)), np.sin(a), -0.2])
            w.write_frame(
                split,
                i,
                rng.integers(0, 255, (24, 32, 3), dtype=np.uint8),
                np.full((24, 32), 2.0),
                rng.integers(0, 4, (24, 32)),
                geometry.look_at(eye, target),
            )
    return root / name


DIFFICULTY = {
    "split": ["query", "query", "query", "query_light1", "query_light1"],
    "frame": ["000000", "000001", "000002", "000000", "000002"],
    "gap_m": [0.4, 0.7, 1.5, 0.4, 1.5],
    "gap_deg": [25.0, 40.0, 90.0, 25.0, 90.0],
    "light_level": [1.0, 1.0, 1.0, 0.7, 0.7],
    "visible_objects": [4, 2, 0, 4, 0],
    "object_area": [0.3, 0.1, 0.0, 0.3, 0.0],
    "displaced_in_view": [0, 0, 0, 0, 0],
    "lookalikes_in_view": [1, 0, 0, 1, 0],
}
"""A difficulty table for :func:`difficulty_scene`; query_light1's frame 000001 has no row."""


def difficulty_scene(root: Path, name: str, rows: dict[str, list]) -> Path:
    """A tiny scene of the current data version with query and query_light1 splits (three queries each)
    and ``rows`` as its difficulty.csv."""
    path = make_scene(root, name, splits=("query", "query_light1"), seed=5)
    w = SceneWriter(path)
    w.write_scene_info({**io.read_json(path / "scene.json"), "data_version": DATA_VERSION})
    w.write_difficulty(pd.DataFrame(rows, columns=list(DIFFICULTY_COLUMNS)))
    return path


def napping_map_build(flag: str) -> dict[str, Any]:
    """A map build that touches ``flag`` inside its (silent) progress bar, then sleeps for two minutes
    (Ctrl-C tests)."""
    for _ in tqdm(range(1), disable=True):
        Path(flag).touch()
        time.sleep(120)
    return {}


def open_after_a_nap(flag: str) -> tuple[Any, float]:
    """A query opener that touches ``flag``, then loads for two seconds (tests of a parent that goes
    while its query server loads)."""
    Path(flag).touch()
    time.sleep(2)
    return (lambda i: None), 2.0


def nap(seconds: float) -> int:
    """A pool job that sleeps inside a (silent) progress bar, as map builds do, then returns its worker's
    pid (executor tests)."""
    for _ in tqdm(range(1), disable=True):
        time.sleep(seconds)
    return os.getpid()
