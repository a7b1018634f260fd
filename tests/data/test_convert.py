"""Converting ScanNet exports and TUM RGB-D sequences (written here in their real formats) into scenes."""

from __future__ import annotations

import json
from pathlib import Path

import cv2
import numpy as np
import pytest

from openreloc_bench import geometry
from openreloc_bench.data import convert, io
from openreloc_bench.data.scene import Scene
from openreloc_bench.errors import ConfigError, DataError


def write_sens_export(root: Path, n: int = 45, bad_pose: int | None = 20, aggregation: bool = True) -> Path:
    """What ScanNet's SensReader writes (``color/<i>.jpg`` 64x48, ``depth/<i>.png`` 32x24 uint16 mm,
    ``pose/<i>.txt``, ``intrinsic/``), the 2D instance zip's ``instance-filt/<i>.png`` (8-bit,
    objectId + 1) and ``<scene>.aggregation.json`` beside it. Every camera looks along +x from x = 0,
    sliding along y, and sees a wall 1.5 m ahead; the left half of the image is a chair (objectId 0),
    the right half the wall (objectId 1)."""
    rng = np.random.default_rng(0)
    K4 = np.eye(4)
    K4[:3, :3] = geometry.intrinsics(58.0, 58.0, 31.5, 23.5)
    io.atomic_write_text(root / "intrinsic" / "intrinsic_color.txt", io.format_matrix(K4))
    io.atomic_write_text(root / "intrinsic" / "intrinsic_depth.txt", io.format_matrix(K4))
    (root / "color").mkdir(parents=True, exist_ok=True)
    for i in range(n):
        T = geometry.look_at([0.0, 0.01 * i, 1.0], [1.0, 0.01 * i, 1.0])
        if i == bad_pose:
            T = np.full((4, 4), -np.inf)
        io.atomic_write_text(root / "pose" / f"{i}.txt", io.format_matrix(T))
        cv2.imwrite(str(root / "color" / f"{i}.jpg"), rng.integers(0, 255, (48, 64, 3), dtype=np.uint8))
        io.write_png(root / "depth" / f"{i}.png", np.full((24, 32), 1500, np.uint16))
        inst = np.full((48, 64), 2, np.uint8)
        inst[:, :32] = 1
        io.write_png(root / "instance-filt" / f"{i}.png", inst)
    if aggregation:
        groups = [
            {"id": 0, "objectId": 0, "segments": [1, 2], "label": "chair"},
            {"id": 1, "objectId": 1, "segments": [3], "label": "wall"},
            {"id": 2, "objectId": 2, "segments": [4], "label": "lamp"},
        ]
        io.write_json(root / f"{root.name}.aggregation.json", {"sceneId": root.name, "segGroups": groups})
    return root


def write_tum_sequence(root: Path, n: int = 50) -> Path:
    """A TUM RGB-D sequence: ``rgb.txt`` / ``depth.txt`` (30 Hz, depth 5 ms after colour) and
    ``groundtruth.txt`` (100 Hz) with the benchmark's comment headers, depth at 5000 units per metre."""
    rng = np.random.default_rng(1)
    t0 = 1305031102.175304
    rgb = ["# color images", "# file: 'rgbd_dataset_freiburg1_xyz.bag'", "# timestamp filename"]
    depth = ["# depth maps", "# file: 'rgbd_dataset_freiburg1_xyz.bag'", "# timestamp filename"]
    for i in range(n):
        t = t0 + i / 30
        rgb.append(f"{t:.6f} rgb/{t:.6f}.png")
        depth.append(f"{t + 0.005:.6f} depth/{t + 0.005:.6f}.png")
        io.write_png(root / "rgb" / f"{t:.6f}.png", rng.integers(0, 255, (24, 32, 3), dtype=np.uint8))
        io.write_png(root / "depth" / f"{t + 0.005:.6f}.png", np.full((24, 32), 7500, np.uint16))
    gt = ["# ground truth trajectory", "# timestamp tx ty tz qx qy qz qw"]
    for k in range(int(n / 30 * 100) + 5):
        t = t0 - 0.01 + k / 100
        gt.append(f"{t:.4f} {0.1 * k / 100:.4f} 0.0 1.0 0.0 0.0 0.0 1.0")
    io.atomic_write_text(root / "rgb.txt", "\n".join(rgb) + "\n")
    io.atomic_write_text(root / "depth.txt", "\n".join(depth) + "\n")
    io.atomic_write_text(root / "groundtruth.txt", "\n".join(gt) + "\n")
    return root


def test_scannet_export_becomes_a_scene_with_the_paper_split(tmp_path: Path) -> None:
    src = write_sens_export(tmp_path / "scans" / "scene0000_00")
    report = convert.import_scannet(src, tmp_path / "data" / "scene0000_00")
    scene = Scene(report.scene)
    mapping, query = scene.sequence("mapping"), scene.sequence("query")
    assert [r.frame_id for r in mapping.records] == ["000000", "000040"]  # 20 had no valid pose
    assert [r.frame_id for r in query.records] == ["000010", "000030"]
    assert report.frames == {"mapping": 2, "query": 2} and report.skipped == {
        "20": "invalid pose (inf/NaN or not rigid)"
    }
    f = query[0]
    assert f.color.shape == (24, 32, 3) and (mapping.width, mapping.height) == (32, 24)
    np.testing.assert_allclose(f.K[0], [29.0, 0.0, 15.75])  # colour intrinsics rescaled to the depth size
    np.testing.assert_allclose(f.depth, 1.5)
    assert set(np.unique(f.instance)) == {1, 2}
    np.testing.assert_allclose(f.T_wc, geometry.look_at([0.0, 0.1, 1.0], [1.0, 0.1, 1.0]), atol=1e-9)
    assert scene.info["source"]["format"] == "scannet" and scene.info["splits"] == {"mapping": 2, "query": 2}
    assert (report.scene / "source_frames.txt").read_text().splitlines()[1:3] == [
        "mapping/000000 0",
        "mapping/000040 40",
    ]


def test_scannet_labels_and_boxes_come_from_the_aggregation_and_masks(tmp_path: Path) -> None:
    src = write_sens_export(tmp_path / "scene0001_00")
    report = convert.import_scannet(src, tmp_path / "out" / "scene0001_00")
    objects = Scene(report.scene).objects
    assert report.objects == 3
    assert {i: (o.category, o.structural) for i, o in objects.items()} == {
        1: ("chair", False),
        2: ("wall", True),
        3: ("lamp", False),
    }
    chair, wall = objects[1].aabb_array, objects[2].aabb_array
    np.testing.assert_allclose([chair[0, 0], chair[1, 0], wall[0, 0]], 1.5, atol=1e-6)  # on the plane x = 1.5
    assert chair[0, 1] > 0.15 and wall[1, 1] < 0.4  # left of the image is +y of the cameras (y 0..0.4)
    assert np.all(objects[3].aabb_array == 0)  # labelled but in no frame: an empty box


def test_scannet_without_aggregation_writes_no_objects(tmp_path: Path) -> None:
    src = write_sens_export(tmp_path / "scene0002_00", aggregation=False)
    report = convert.import_scannet(src, tmp_path / "out" / "scene0002_00")
    assert report.objects == 0 and not (report.scene / "objects.json").exists()
    assert Scene(report.scene).sequence("query").has_instances


def test_tum_sequence_is_associated_and_converted_to_millimetres(tmp_path: Path) -> None:
    src = write_tum_sequence(tmp_path / "rgbd_dataset_freiburg1_xyz")
    report = convert.import_tum(src, tmp_path / "data" / "fr1_xyz")
    scene = Scene(report.scene)
    mapping, query = scene.sequence("mapping"), scene.sequence("query")
    assert [r.frame_id for r in mapping.records] == ["000000", "000020", "000040"]
    assert [r.frame_id for r in query.records] == ["000010", "000030"]
    assert io.read_depth(query.records[0].depth_path).max() == pytest.approx(1.5)  # 7500 / 5000 m, stored as mm
    assert cv2.imread(str(query.records[0].depth_path), cv2.IMREAD_UNCHANGED).max() == 1500
    np.testing.assert_allclose(query[0].T_wc[:3, 3], [0.1 * (10 / 30), 0.0, 1.0], atol=2e-3)
    np.testing.assert_allclose(query.K, [[525.0, 0, 319.5], [0, 525.0, 239.5], [0, 0, 1]])
    lines = (report.scene / "source_frames.txt").read_text().splitlines()
    assert "query/000010 1305031102.508637" in lines
    assert not query.has_instances and not (report.scene / "objects.json").exists()


def test_tum_intrinsics_can_be_given(tmp_path: Path) -> None:
    src = write_tum_sequence(tmp_path / "seq", n=12)
    K = geometry.intrinsics(517.3, 516.5, 318.6, 255.3)
    report = convert.import_tum(src, tmp_path / "out", stride=4, offset=2, K=K)
    assert report.frames == {"mapping": 3, "query": 3}
    np.testing.assert_allclose(Scene(report.scene).sequence("query").K, K)


def test_import_refuses_a_non_empty_output_and_bad_splits(tmp_path: Path) -> None:
    src = write_sens_export(tmp_path / "scene0003_00", n=12, bad_pose=None)
    (tmp_path / "busy").mkdir()
    (tmp_path / "busy" / "keep.txt").write_text("mine")
    with pytest.raises(ConfigError, match="not empty"):
        convert.import_scannet(src, tmp_path / "busy")
    assert (tmp_path / "busy" / "keep.txt").read_text() == "mine"
    with pytest.raises(ConfigError, match="overlaps the input"):
        convert.import_scannet(src, src / "scene")
    with pytest.raises(ConfigError, match="--offset"):
        convert.import_scannet(src, tmp_path / "o1", stride=10, offset=10)
    with pytest.raises(DataError, match="no frame for the 'query' split"):
        convert.import_scannet(src, tmp_path / "o2", stride=20, offset=15)


def test_malformed_aggregation_is_named(tmp_path: Path) -> None:
    src = write_sens_export(tmp_path / "scene0004_00", n=12, bad_pose=None)
    (src / "scene0004_00.aggregation.json").write_text(json.dumps({"segGroups": [{"label": "chair"}]}))
    with pytest.raises(DataError, match="aggregation.json: every segGroups entry"):
        convert.import_scannet(src, tmp_path / "out")
