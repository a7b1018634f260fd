"""Reading 7-Scenes (written here in its real layout): sequences, splits, invalid poses and depth, and the
re-projection of depth into the colour camera."""

from __future__ import annotations

from pathlib import Path

import numpy as np
import pytest

from openreloc_bench import geometry
from openreloc_bench.data import io
from openreloc_bench.data.sevenscenes import (
    COLOR_K,
    DEPTH_K,
    T_COLOR_DEPTH,
    at_size,
    read_7scenes,
    read_split_file,
    sequences,
)
from openreloc_bench.errors import DataError

WALL_MM = 2000
FAR_MM = 12000


def write_7scenes_scene(root: Path, n_sequences: int = 3, n: int = 25, bad_pose: tuple[int, int] = (1, 20)) -> Path:
    """A 7-Scenes scene: ``seq-01..`` of ``n`` 64x48 frames and ``TrainSplit.txt`` (all but the last
    sequence) / ``TestSplit.txt`` (the last). The depth camera slides along x facing a wall 2 m ahead
    (KinectFusion's frame: y down); the top 8 depth rows are 65535 and column 5 is 0 (no reading), frame
    10 sees a 12 m patch, and frame ``bad_pose`` (sequence, frame) has an -inf pose."""
    rng = np.random.default_rng(7)
    for s in range(1, n_sequences + 1):
        folder = root / f"seq-{s:02d}"
        for i in range(n):
            T = geometry.make_pose(np.eye(3), [0.01 * i + s, 0.0, 0.0])
            pose = "\n".join("\t".join(f"{v:.7e}" for v in row) for row in T)
            if (s, i) == bad_pose:
                pose = "\n".join(["-inf\t-inf\t-inf\t-inf"] * 4)
            io.atomic_write_text(folder / f"frame-{i:06d}.pose.txt", pose + "\n")
            io.write_png(folder / f"frame-{i:06d}.color.png", rng.integers(0, 255, (48, 64, 3), dtype=np.uint8))
            depth = np.full((48, 64), WALL_MM, np.uint16)
            depth[:8] = io.NO_DEPTH
            depth[:, 5] = 0
            if i == 10:
                depth[30:40, 24:40] = FAR_MM
            io.write_png(folder / f"frame-{i:06d}.depth.png", depth)
    train = [f"sequence{s}" for s in range(1, n_sequences)]
    io.atomic_write_text(root / "TrainSplit.txt", "\n".join(train) + "\n")
    io.atomic_write_text(root / "TestSplit.txt", f"sequence{n_sequences}\n")
    return root


def test_frames_are_seen_by_the_colour_camera(tmp_path: Path) -> None:
    seq = read_7scenes(write_7scenes_scene(tmp_path / "chess"), "seq-01")
    assert seq.split == "seq-01" and len(seq) == 24 and (seq.width, seq.height) == (64, 48)
    assert seq.skipped == {"seq-01/frame-000020": "invalid pose (inf/NaN or not rigid)"}
    np.testing.assert_allclose(seq.K, [[52.5, 0, 32.0], [0, 52.5, 24.0], [0, 0, 1]])  # f = 525 at 640x480
    # the colour camera sits 2.5 cm right of the depth camera, whose pose the recording holds
    depth_centre = np.array([1.0 + 0.01 * 3, 0.0, 0.0])
    np.testing.assert_allclose(seq[3].T_wc[:3, 3] - depth_centre, [0.0256, 0.0, -0.0021], atol=2e-4)
    depth = seq[3].depth
    assert depth.shape == (48, 64) and depth.dtype == np.float32
    valid = depth > 0
    np.testing.assert_allclose(depth[valid], 2.0, atol=0.02)  # the wall, tilted by 0.5 deg in the colour frame
    # no reading stays no reading: the 65535 rows come out as a band of zeros at the top, and the colour
    # camera, wider than the depth camera (f 525 vs 585), sees beyond the depth map at its borders
    assert not valid[:8].any() and valid[24, 10:50].all() and not valid[:, 0].any() and not valid[:, -1].any()


def test_depth_lands_where_the_calibration_puts_it(tmp_path: Path) -> None:
    """Colour pixel (u, v) shows the wall point on its ray: depth (2 + n.t) / (n . K^-1 (u, v, 1)) with n
    the wall's normal and t the offset in the colour camera's frame."""
    seq = read_7scenes(write_7scenes_scene(tmp_path / "chess", n_sequences=1, n=2), "seq-01")
    depth = seq[0].depth
    n, t = T_COLOR_DEPTH[:3, 2], T_COLOR_DEPTH[:3, 3]
    v, u = np.nonzero(depth)
    rays = np.linalg.inv(seq.K) @ np.stack([u, v, np.ones_like(u)]).astype(float)
    np.testing.assert_allclose(depth[v, u], (WALL_MM / 1000 + n @ t) / (n @ rays), atol=2e-3)
    np.testing.assert_allclose(at_size(DEPTH_K, (480, 640)), DEPTH_K)
    np.testing.assert_allclose(at_size(COLOR_K, (48, 64))[0], [52.5, 0.0, 32.0])


def test_intrinsics_can_be_given(tmp_path: Path) -> None:
    K = geometry.intrinsics(50.0, 51.0, 31.0, 23.0)
    seq = read_7scenes(write_7scenes_scene(tmp_path / "chess", n_sequences=1, n=2), "seq-01", K=K)
    np.testing.assert_allclose(seq[0].K, K)


def test_sequences_and_splits(tmp_path: Path) -> None:
    root = write_7scenes_scene(tmp_path / "chess", n=1)
    assert sequences(root) == ["seq-01", "seq-02", "seq-03"]
    assert read_split_file(root / "TrainSplit.txt") == ["seq-01", "seq-02"]
    assert read_split_file(root / "TestSplit.txt") == ["seq-03"]
    (root / "TestSplit.txt").write_text("sequence3\nseq-4\n")
    with pytest.raises(DataError, match="TestSplit.txt: line 2: expected 'sequenceN', got 'seq-4'"):
        read_split_file(root / "TestSplit.txt")
    with pytest.raises(DataError, match="no such sequence; the scene has seq-01, seq-02, seq-03"):
        read_7scenes(root, "seq-09")


def test_missing_depth_is_named(tmp_path: Path) -> None:
    root = write_7scenes_scene(tmp_path / "chess", n_sequences=1, n=3)
    (root / "seq-01" / "frame-000001.depth.png").unlink()
    with pytest.raises(DataError, match=r"frame-000001.depth.png: file not found \(pose exists"):
        read_7scenes(root, "seq-01")
