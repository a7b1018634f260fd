"""Checks every baseline passes (run for each by test_contract.py); ``overrides`` are the settings
its test map was built with."""

from __future__ import annotations

import shutil
from pathlib import Path

import numpy as np
import pytest

from openreloc_bench import geometry
from openreloc_bench.data.scene import Scene
from openreloc_bench.errors import DataError
from openreloc_bench.methods import Failure, PoseEstimate, QueryFrame, Relocalizer, available_methods, create_method
from tests.baselines.conftest import CHEAP


def loaded(name: str, map_dir: Path, **overrides: object) -> Relocalizer:
    method = create_method(name, **{**CHEAP.get(name, {}), **overrides})
    method.load_map(map_dir)
    return method


def query_of(scene: Scene, split: str, i: int, masks: bool = False) -> tuple[QueryFrame, np.ndarray]:
    f = scene.sequence(split)[i]
    return QueryFrame(f.name, f.color, f.K, f.instance if masks else None), f.T_wc


def check_registered(name: str) -> None:
    """Found by name in the registry (:data:`~openreloc_bench.methods.BUILTIN_METHODS`) and created from it."""
    assert name in available_methods()
    method = create_method(name)
    assert isinstance(method, Relocalizer) and method.name == name and method.uses_masks is False


def check_mapping_frames_localize(name: str, map_dir: Path, scene: Scene) -> None:
    """A mapping frame fed back as a query comes back within 2 cm and 0.5 degrees."""
    method = loaded(name, map_dir)
    for i in (0, len(scene.sequence("mapping")) // 2):
        query, T_gt = query_of(scene, "mapping", i)
        est = method.localize(query)
        assert isinstance(est, PoseEstimate), est
        t_err, r_err = geometry.pose_errors(T_gt, est.T_wc)
        assert t_err < 0.02 and r_err < 0.5, (i, t_err, r_err)


def check_confidence_is_inliers(name: str, map_dir: Path, scene: Scene) -> None:
    """A structure-based method's confidence is the inlier count its diagnostics report, at least its
    acceptance threshold."""
    method = loaded(name, map_dir)
    est = method.localize(query_of(scene, "mapping", 0)[0])
    assert isinstance(est, PoseEstimate)
    assert est.confidence == est.diagnostics["inliers"] >= method.config.min_inliers


def check_other_scene_fails(name: str, map_dir: Path, other: Scene) -> None:
    """Images of another room give a Failure with a reason, never a pose."""
    method = loaded(name, map_dir)
    for split in ("mapping", "query"):
        for i in range(0, len(other.sequence(split)), 5):
            res = method.localize(query_of(other, split, i)[0])
            assert isinstance(res, Failure) and res.reason, (split, i, res)


def check_ignores_masks(name: str, map_dir: Path, scene: Scene) -> None:
    """The oracle-mask and predicted tracks give bit-identical answers."""
    method = loaded(name, map_dir)
    with_masks, _ = query_of(scene, "mapping", 1, masks=True)
    assert with_masks.instance is not None
    without = query_of(scene, "mapping", 1)[0]
    a, b = method.localize(with_masks), method.localize(without)
    assert type(a) is type(b)
    if isinstance(a, PoseEstimate):
        assert np.array_equal(a.T_wc, b.T_wc)


def check_damaged_maps(name: str, map_dir: Path, tmp_path: Path) -> None:
    """A truncated or edited map file, or a missing map, is a one-line DataError naming the file."""
    for damage in ("truncate", "flip"):
        copy = tmp_path / damage
        shutil.copytree(map_dir, copy)
        arrays = copy / "arrays.npz"
        data = bytearray(arrays.read_bytes())
        if damage == "truncate":
            data = data[: len(data) // 2]
        else:
            data[len(data) // 2] ^= 0xFF
        arrays.write_bytes(bytes(data))
        with pytest.raises(DataError, match="arrays.npz") as err:
            loaded(name, copy)
        assert "\n" not in str(err.value)
    with pytest.raises(DataError, match="nothing-here"):
        loaded(name, tmp_path / "nothing-here")
