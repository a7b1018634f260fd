"""TSDF fusion of the analytic box room: the cloud lies on the boxes; bad frames are skipped or named."""

from __future__ import annotations

from pathlib import Path

import numpy as np
import pytest

from openreloc_bench.data import io
from openreloc_bench.data.scene import Scene
from openreloc_bench.errors import DataError
from openreloc_bench.reconstruction.fusion import FusionConfig, fuse_tsdf
from tests.openreloc.boxworld import ROOM, boxworld_sequence
from tests.reconstruction.conftest import VOXEL


def box_distance(points: np.ndarray) -> np.ndarray:
    """Distance of each point to the nearest box surface of the room (exact, analytic)."""
    d = []
    for b in ROOM:
        lo, hi = np.array(b.lo), np.array(b.hi)
        outside = np.linalg.norm(np.maximum(0, np.maximum(lo - points, points - hi)), axis=1)
        inside = np.min(np.minimum(points - lo, hi - points), axis=1)
        d.append(np.where(outside > 0, outside, inside))
    return np.min(d, axis=0)


def test_fused_cloud_lies_on_the_boxes(room: tuple) -> None:
    _, rec, _ = room
    assert len(rec.points) > 5000 and rec.usable.all() and not rec.skipped
    assert np.median(box_distance(rec.points)) < 0.02
    assert np.quantile(box_distance(rec.points), 0.95) < VOXEL


def test_fusion_of_subsampled_depth_stays_on_the_surfaces(room: tuple) -> None:
    seq, rec, _ = room
    half = fuse_tsdf(seq, FusionConfig(voxel_size=0.05, max_fusion_width=64), progress=False)
    assert len(half.points) > 0.8 * len(rec.points)
    assert np.median(box_distance(half.points)) < 0.02


def test_frames_without_depth_are_skipped_and_reported(tmp_path: Path) -> None:
    seq = boxworld_sequence(tmp_path / "s", n_frames=8)
    io.write_png(seq.records[2].depth_path, np.zeros((seq.height, seq.width), np.uint16))
    seq.records[5].depth_path.unlink()
    cfg = FusionConfig(voxel_size=0.05, min_weight=1.0)
    rec = fuse_tsdf(Scene(tmp_path / "s").sequence("mapping"), cfg, progress=False)
    assert set(rec.skipped) == {"mapping/000002", "mapping/000005"}
    assert rec.usable.sum() == 6


def test_non_rigid_pose_names_the_frame(tmp_path: Path) -> None:
    seq = boxworld_sequence(tmp_path / "s", n_frames=4)
    seq.records[1].T_wc = seq.records[1].T_wc * np.array([2.0, 1, 1, 1])[:, None]
    with pytest.raises(DataError, match="mapping/000001.*rigid"):
        fuse_tsdf(seq, FusionConfig(voxel_size=VOXEL), progress=False)
