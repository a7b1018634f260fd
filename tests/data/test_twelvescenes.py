"""Reading 12-Scenes (written here in its real layout): the header, the split and lost-tracking poses."""

from __future__ import annotations

from pathlib import Path

import cv2
import numpy as np
import pytest

from openreloc_bench import geometry
from openreloc_bench.data import io
from openreloc_bench.data.twelvescenes import read_12scenes, read_test_frames
from openreloc_bench.errors import DataError

INFO = """m_versionNumber = 4
m_sensorName = StructureSensor
m_colorWidth = 64
m_colorHeight = 48
m_depthWidth = 32
m_depthHeight = 24
m_depthShift = 1000
m_calibrationColorIntrinsic = 58 0 31.5 0 0 58 23.5 0 0 0 1 0 0 0 0 1
m_calibrationColorExtrinsic = 1 0 0 0 0 1 0 0 0 0 1 0 0 0 0 1
m_calibrationDepthIntrinsic = 29 0 15.75 0 0 29 11.75 0 0 0 1 0 0 0 0 1
m_calibrationDepthExtrinsic = 1 0 0 0 0 1 0 0 0 0 1 0 0 0 0 1
m_frames.size = {n}
"""
LOST = {5: "-inf", 30: "-1.#INF00"}
"""Frames whose tracking was lost, and how their pose file says so (MSVC writes -1.#INF00)."""


def write_12scenes_scene(root: Path, n: int = 45, n_test: int = 15) -> Path:
    """A 12-Scenes scene: ``info.txt``, ``split.txt`` (frames 0..n_test-1 are the test sequence) and
    ``data/`` of 64x48 jpg colour, 32x24 depth (1.5 m) and poses, two of them lost."""
    rng = np.random.default_rng(12)
    data = root / "data"
    data.mkdir(parents=True)
    io.atomic_write_text(root / "info.txt", INFO.format(n=n))
    split = f"sequence0 [frames={n_test}]  [start=0 ; end={n_test - 1}]\nsequence1 [frames={n - n_test}]\n"
    io.atomic_write_text(root / "split.txt", split)
    for i in range(n):
        T = geometry.make_pose(np.eye(3), [0.01 * i, 0.0, 0.0])
        pose = io.format_matrix(T) if i not in LOST else " ".join([LOST[i]] * 4) + "\n" * 4
        io.atomic_write_text(data / f"frame-{i:06d}.pose.txt", pose)
        cv2.imwrite(str(data / f"frame-{i:06d}.color.jpg"), rng.integers(0, 255, (48, 64, 3), dtype=np.uint8))
        io.write_png(data / f"frame-{i:06d}.depth.png", np.full((24, 32), 1500, np.uint16))
    return root


def test_reads_frames_at_the_depth_size(tmp_path: Path) -> None:
    seq = read_12scenes(write_12scenes_scene(tmp_path / "apt1_kitchen"))
    assert len(seq) == 43 and seq.skipped == {
        "data/frame-000005": "invalid pose (inf/NaN or not rigid)",
        "data/frame-000030": "invalid pose (inf/NaN or not rigid)",
    }
    assert (seq.width, seq.height) == (32, 24) and seq.records[5].frame_id == "6"
    np.testing.assert_allclose(seq.K[0], [29.0, 0.0, 15.75])  # colour intrinsics rescaled to the depth size
    f = seq[0]
    assert f.color.shape == (24, 32, 3) and np.allclose(f.depth, 1.5)
    assert read_test_frames(tmp_path / "apt1_kitchen") == 15


def test_malformed_header_and_split_are_named(tmp_path: Path) -> None:
    root = write_12scenes_scene(tmp_path / "apt1_kitchen", n=2, n_test=1)
    (root / "split.txt").write_text("sequence0 357\n")
    with pytest.raises(DataError, match=r"split.txt: expected a first line 'sequence0 \[frames=N\] ...'"):
        read_test_frames(root)
    (root / "info.txt").write_text(INFO.format(n=2).replace("m_calibrationColorIntrinsic", "m_colorK"))
    with pytest.raises(DataError, match="info.txt: no m_calibrationColorIntrinsic line"):
        read_12scenes(root)
    (root / "info.txt").write_text("m_depthShift 1000\n")
    with pytest.raises(DataError, match="info.txt: line 1: expected 'key = value'"):
        read_12scenes(root)
