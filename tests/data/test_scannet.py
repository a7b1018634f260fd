from pathlib import Path

import cv2
import numpy as np
import pytest

from openreloc_bench import geometry
from openreloc_bench.data import io
from openreloc_bench.data.scannet import read_scannet, stride_split
from openreloc_bench.errors import DataError


def write_scannet_export(root: Path, n: int = 41, bad_pose: int | None = 7) -> Path:
    """A ScanNet-style export: 64x48 jpg colour, 32x24 depth, unpadded ids, one -inf pose."""
    rng = np.random.default_rng(0)
    Kc = geometry.intrinsics(58.0, 58.0, 31.5, 23.5)
    K4 = np.eye(4)
    K4[:3, :3] = Kc
    io.atomic_write_text(root / "intrinsic" / "intrinsic_color.txt", io.format_matrix(K4))
    for i in range(n):
        T = geometry.look_at([np.cos(i / 5), np.sin(i / 5), 1.4], [0, 0, 1])
        if i == bad_pose:
            T = np.full((4, 4), -np.inf)
        io.atomic_write_text(root / "pose" / f"{i}.txt", io.format_matrix(T))
        (root / "color").mkdir(parents=True, exist_ok=True)
        cv2.imwrite(str(root / "color" / f"{i}.jpg"), rng.integers(0, 255, (48, 64, 3), dtype=np.uint8))
        io.write_png(root / "depth" / f"{i}.png", np.full((24, 32), 1500, np.uint16))
        io.write_png(root / "instance-filt" / f"{i}.png", np.full((48, 64), 3, np.uint8))
    return root


def test_reads_export_and_rescales_intrinsics(tmp_path: Path):
    seq = read_scannet(write_scannet_export(tmp_path / "scene0000_00"))
    assert len(seq) == 40 and seq.skipped == {"7": "invalid pose (inf/NaN or not rigid)"}
    assert (seq.width, seq.height) == (32, 24)
    np.testing.assert_allclose(seq.K[0], [29.0, 0.0, 15.75])
    f = seq[0]
    assert f.color.shape == (24, 32, 3) and f.instance.shape == (24, 32)
    assert np.allclose(f.depth, 1.5)


def test_stride_split_follows_paper_protocol(tmp_path: Path):
    seq = read_scannet(write_scannet_export(tmp_path / "s", n=61, bad_pose=None))
    mapping, query = stride_split(seq, 20, 10)
    assert [r.frame_id for r in mapping.records] == ["0", "20", "40", "60"]
    assert [r.frame_id for r in query.records] == ["10", "30", "50"]
    assert query[0].name == "query/10" and query[0].color.shape == (24, 32, 3)


def test_missing_depth_is_named(tmp_path: Path):
    root = write_scannet_export(tmp_path / "s", n=3)
    (root / "depth" / "1.png").unlink()
    with pytest.raises(DataError, match=r"depth/1.png: file not found"):
        read_scannet(root)


def test_not_a_scannet_dir(tmp_path: Path):
    with pytest.raises(DataError, match="is this a ScanNet export"):
        read_scannet(tmp_path)
