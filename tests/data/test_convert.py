"""Converting ScanNet exports, TUM RGB-D sequences, 7-Scenes and 12-Scenes scenes (written here in their
real formats) into scenes."""

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
from tests.data.test_sevenscenes import write_7scenes_scene
from tests.data.test_twelvescenes import write_12scenes_scene


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


@pytest.mark.parametrize(
    ("groups", "match"),
    [
        ([{"label": "chair"}], "every segGroups entry"),
        ([{"objectId": -1, "label": "chair"}], "objectId -1 is negative"),
        ([{"objectId": 2, "label": "chair"}, {"objectId": 2, "label": "desk"}], "objectId 2 is listed twice"),
    ],
)
def test_malformed_aggregation_is_named(tmp_path: Path, groups: list, match: str) -> None:
    src = write_sens_export(tmp_path / "scene0004_00", n=12, bad_pose=None)
    (src / "scene0004_00.aggregation.json").write_text(json.dumps({"segGroups": groups}))
    with pytest.raises(DataError, match=f"aggregation.json: {match}"):
        convert.import_scannet(src, tmp_path / "out")
    assert not (tmp_path / "out").exists()


def test_7scenes_sequence_is_split_by_the_stride_protocol(tmp_path: Path) -> None:
    src = write_7scenes_scene(tmp_path / "7scenes" / "chess")
    report = convert.import_7scenes(src, tmp_path / "data" / "chess")
    scene = Scene(report.scene)
    mapping, query = scene.sequence("mapping"), scene.sequence("query")
    assert [r.frame_id for r in mapping.records] == ["000000"] and [r.frame_id for r in query.records] == ["000010"]
    assert report.skipped == {"seq-01/frame-000020": "invalid pose (inf/NaN or not rigid)"}
    assert (report.scene / "source_frames.txt").read_text().splitlines()[1:] == [
        "mapping/000000 seq-01/frame-000000",
        "query/000010 seq-01/frame-000010",
    ]
    source = scene.info["source"]
    assert (source["format"], source["protocol"], source["sequence"], source["converter_version"]) == (
        "7scenes",
        "stride",
        "seq-01",
        2,
    )
    np.testing.assert_allclose(query.K[0], [52.5, 0.0, 32.0])  # the colour camera's, f = 525 at 640x480
    np.testing.assert_allclose(query[0].T_wc[:3, 3], [1.1256, 0.0, -0.0021], atol=2e-4)  # colour camera's centre
    other = convert.import_7scenes(src, tmp_path / "data" / "chess2", sequence="seq-02", stride=5, offset=2)
    assert other.frames == {"mapping": 5, "query": 5} and not other.skipped


def test_7scenes_splits_map_the_training_sequences_and_query_the_test_ones(tmp_path: Path) -> None:
    src = write_7scenes_scene(tmp_path / "chess")
    report = convert.import_7scenes(src, tmp_path / "data" / "chess", protocol="splits")
    assert report.frames == {"mapping": 3, "query": 1}
    assert report.skipped == {"seq-01/frame-000020": "invalid pose (inf/NaN or not rigid)"}
    assert (report.scene / "source_frames.txt").read_text().splitlines()[1:] == [
        "mapping/000000 seq-01/frame-000000",
        "mapping/000001 seq-02/frame-000000",
        "mapping/000002 seq-02/frame-000020",
        "query/000000 seq-03/frame-000010",
    ]
    scene = Scene(report.scene)
    np.testing.assert_allclose(scene.sequence("mapping")[1].T_wc[:3, 3], [2.0256, 0.0, -0.0021], atol=2e-4)
    every = convert.import_7scenes(src, tmp_path / "data" / "all", protocol="splits", stride=1, offset=0)
    assert every.frames == {"mapping": 49, "query": 25}
    with pytest.raises(ConfigError, match="--sequence is for the stride protocol"):
        convert.import_7scenes(src, tmp_path / "o1", protocol="splits", sequence="seq-01")
    with pytest.raises(ConfigError, match=r"splits protocol needs --stride >= 1 and 0 <= --offset < --stride"):
        convert.import_7scenes(src, tmp_path / "o2", protocol="splits", stride=1, offset=1)


def test_12scenes_by_the_stride_protocol_and_by_its_split(tmp_path: Path) -> None:
    src = write_12scenes_scene(tmp_path / "apt1_kitchen")
    stride = convert.import_12scenes(src, tmp_path / "data" / "stride")
    assert [r.frame_id for r in Scene(stride.scene).sequence("mapping").records] == ["000000", "000020", "000040"]
    assert [r.frame_id for r in Scene(stride.scene).sequence("query").records] == ["000010"]  # 30 is lost
    assert len(stride.skipped) == 2
    splits = convert.import_12scenes(src, tmp_path / "data" / "splits", protocol="splits", stride=10, offset=0)
    scene = Scene(splits.scene)
    assert [r.frame_id for r in scene.sequence("mapping").records] == ["000020", "000040"]  # 30 is lost
    assert [r.frame_id for r in scene.sequence("query").records] == ["000000", "000010"]  # test frames < 15
    assert scene.info["source"]["test_frames"] == 15 and scene.sequence("query").K[0, 0] == pytest.approx(29.0)
    assert "query/000010 data/frame-000010" in (splits.scene / "source_frames.txt").read_text().splitlines()


FAR_MM = 12000


def _far_and_unread(path: Path, units_per_mm: float) -> None:
    """Rewrite a recording's depth PNG with a patch 12 m away and a row of 65535 (no reading)."""
    depth = cv2.imread(str(path), cv2.IMREAD_UNCHANGED)
    h, w = depth.shape
    depth[h // 2 : h // 2 + 4, w // 4 : w // 2] = round(FAR_MM * units_per_mm)
    depth[-1] = io.NO_DEPTH
    io.write_png(path, depth)


FRAME_10 = {
    "scannet": (lambda root: write_sens_export(root, n=12, bad_pose=None), lambda src: src / "depth" / "10.png", 1),
    "tum": (lambda root: write_tum_sequence(root, n=12), lambda src: sorted((src / "depth").glob("*.png"))[10], 5),
    "7scenes": (
        lambda root: write_7scenes_scene(root, n_sequences=1, n=12),
        lambda src: src / "seq-01" / "frame-000010.depth.png",
        1,
    ),
    "12scenes": (
        lambda root: write_12scenes_scene(root, n=12, n_test=1),
        lambda src: src / "data" / "frame-000010.depth.png",
        1,
    ),
}
"""Per format: a 12-frame recording, the depth file of its frame 10 (a query frame), its units per mm."""


@pytest.mark.parametrize("fmt", convert.FORMATS)
def test_depth_beyond_max_depth_or_unread_is_written_as_missing(tmp_path: Path, fmt: str) -> None:
    write, frame_10, units_per_mm = FRAME_10[fmt]
    src = write(tmp_path / "rec")
    _far_and_unread(frame_10(src), units_per_mm)
    importer = getattr(convert, f"import_{fmt}")
    cut = importer(src, tmp_path / "cut")
    kept = importer(src, tmp_path / "kept", max_depth=15.0)
    assert Scene(cut.scene).info["source"]["max_depth"] == convert.MAX_DEPTH_M
    cut_mm, kept_mm = (cv2.imread(str(r.scene / "query/depth/000010.png"), cv2.IMREAD_UNCHANGED) for r in (cut, kept))
    assert io.NO_DEPTH not in cut_mm and io.NO_DEPTH not in kept_mm
    assert (cut_mm == 0).any() and 1000 < cut_mm.max() < 2100  # only the wall is left
    assert (abs(kept_mm.astype(int) - FAR_MM) < 100).any() and kept_mm.max() < FAR_MM + 100


@pytest.mark.parametrize(
    ("fmt", "write", "found"),
    [
        ("7scenes", write_tum_sequence, "it looks like a TUM RGB-D sequence (`import tum`)"),
        ("scannet", write_7scenes_scene, "it looks like a 7-Scenes scene (`import 7scenes`)"),
        ("12scenes", write_sens_export, "it looks like a ScanNet export (`import scannet`)"),
        ("tum", write_12scenes_scene, "it looks like a 12-Scenes scene (`import 12scenes`)"),
    ],
)
def test_each_importer_refuses_another_layout_and_names_it(tmp_path: Path, fmt: str, write, found: str) -> None:
    src = write(tmp_path / "rec")
    expected = convert.LAYOUTS[fmt]
    with pytest.raises(DataError, match=f"not {expected.what}: expected ") as refused:
        getattr(convert, f"import_{fmt}")(src, tmp_path / "out")
    assert str(refused.value).endswith(found) and expected.expected in str(refused.value)
    assert not (tmp_path / "out").exists()


def test_an_unknown_folder_is_described(tmp_path: Path) -> None:
    (tmp_path / "chess" / "images").mkdir(parents=True)
    for name in ("seq-01.zip", "seq-02.zip", "TrainSplit.txt", ".DS_Store"):
        (tmp_path / "chess" / name).write_text("")
    with pytest.raises(DataError, match=r"it holds TrainSplit.txt, images/, seq-01.zip, seq-02.zip \(unpack the"):
        convert.import_7scenes(tmp_path / "chess", tmp_path / "out")
    with pytest.raises(DataError, match="no such folder"):
        convert.import_tum(tmp_path / "missing", tmp_path / "out")
