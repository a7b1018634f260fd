import json
import os
import stat
from pathlib import Path

import numpy as np
import pandas as pd
import pytest

from openreloc_bench.data import io
from openreloc_bench.data.scene import DATA_VERSION, DIFFICULTY_COLUMNS, ObjectInfo, Scene, SceneWriter
from openreloc_bench.errors import DataError
from tests.conftest import write_tiny_scene


def test_round_trip(tiny_scene: Path):
    scene = Scene(tiny_scene)
    assert scene.splits() == ["mapping", "query"]
    assert scene.objects[1].category == "box"
    seq = scene.sequence("mapping")
    assert len(seq) == 6 and seq.has_depth and seq.has_instances
    f = seq[2]
    assert f.name == "mapping/000002"
    assert f.color.shape == (24, 32, 3) and f.color.dtype == np.uint8
    assert f.depth is not None and np.allclose(f.depth, 3.0)
    assert f.instance is not None and set(np.unique(f.instance)) == {0, 1}
    assert np.allclose(seq.poses[2], f.T_wc)


def test_depth_png_is_millimetres_and_invalid_is_zero(tmp_path: Path):
    d = np.array([[1.25, 0.0], [np.nan, 70.0]], np.float32)  # 70 m overflows uint16 mm
    png = io.depth_to_png(d)
    assert png.dtype == np.uint16 and png.tolist() == [[1250, 0], [0, 0]]
    io.write_png(tmp_path / "d.png", png)
    back = io.read_depth(tmp_path / "d.png")
    assert back.tolist() == [[1.25, 0.0], [0.0, 0.0]]
    assert io.depth_to_png(np.array([65.534, 65.535])).tolist() == [65534, 0]  # 65535 would read as no reading
    io.write_png(tmp_path / "sentinel.png", np.array([[65534, 65535]], np.uint16))
    assert io.read_depth(tmp_path / "sentinel.png").tolist() == [[np.float32(65.534), 0.0]]


def test_same_content_gives_identical_bytes(tmp_path: Path):
    a = write_tiny_scene(tmp_path / "a")
    b = write_tiny_scene(tmp_path / "b")
    files_a = sorted(p.relative_to(a) for p in a.rglob("*") if p.is_file())
    assert files_a == sorted(p.relative_to(b) for p in b.rglob("*") if p.is_file())
    assert all((a / f).read_bytes() == (b / f).read_bytes() for f in files_a)


def test_no_temp_files_left(tiny_scene: Path):
    assert not list(tiny_scene.rglob("*.tmp"))


def test_stray_temps_of_a_killed_writer_are_removed(tmp_path: Path):
    """SIGKILL mid-write leaves '.<name>.<random>.tmp' (the except clause never runs); resumes remove them."""
    io.atomic_write_bytes(tmp_path / "a" / "kept.png", b"x")
    stray = tmp_path / "a" / ".000008.png.ppbykng7.tmp"
    stray.write_bytes(b"partial")
    io.remove_stray_temps(tmp_path)
    assert not stray.exists() and (tmp_path / "a" / "kept.png").read_bytes() == b"x"


def test_temps_of_a_live_writer_are_kept_and_dead_ones_removed(tmp_path: Path):
    """Clean-up must not remove another running process's file in flight (its pid is in the name)."""
    live = tmp_path / f".000001.png.{os.getpid()}-abcd1234.tmp"
    dead = tmp_path / ".000002.png.999999999-abcd1234.tmp"
    for p in (live, dead):
        p.write_bytes(b"partial")
    io.remove_stray_temps(tmp_path)
    assert live.exists() and not dead.exists()


def test_written_files_honour_the_umask(tmp_path: Path):
    old = os.umask(0o027)
    try:
        io._UMASK = None  # read the umask again
        io.atomic_write_bytes(tmp_path / "f.txt", b"x")
    finally:
        os.umask(old)
        io._UMASK = None
    assert stat.S_IMODE((tmp_path / "f.txt").stat().st_mode) == 0o640


def _first(scene: Path, sub: str) -> Path:
    return sorted((scene / "mapping" / sub).iterdir())[0]


@pytest.mark.parametrize(
    "corrupt, message",
    [
        (lambda s: _first(s, "color").unlink(), "file not found"),
        (lambda s: _first(s, "color").write_bytes(b"not a png"), "unreadable image"),
        (lambda s: _first(s, "pose").write_text("1 0 0\n0 1 0\n"), "malformed matrix"),
        (lambda s: _first(s, "pose").write_text("1 0 0 0\n0 1 0 0\n0 0 1 x\n0 0 0 1\n"), "malformed matrix"),
        (lambda s: _first(s, "pose").write_text("2 0 0 0\n0 1 0 0\n0 0 1 0\n0 0 0 1\n"), "not a rigid"),
        (lambda s: _first(s, "pose").write_text("nan 0 0 0\n0 1 0 0\n0 0 1 0\n0 0 0 1\n"), "not a rigid"),
    ],
    ids=["missing-color", "corrupt-png", "short-pose", "non-numeric-pose", "scaled-pose", "nan-pose"],
)
def test_bad_files_raise_one_line_errors_naming_the_file(tiny_scene: Path, corrupt, message):
    corrupt(tiny_scene)
    with pytest.raises(DataError) as e:
        seq = Scene(tiny_scene).sequence("mapping")
        _ = [seq[i] for i in range(len(seq))]
    assert message in str(e.value) and "mapping" in str(e.value) and "\n" not in str(e.value)


def test_wrong_image_size_is_an_error(tiny_scene: Path):
    io.write_png(_first(tiny_scene, "depth"), np.zeros((10, 10), np.uint16))
    with pytest.raises(DataError, match="expected 32x24"):
        Scene(tiny_scene).sequence("mapping")[0]


def test_depth_must_be_uint16(tiny_scene: Path):
    io.write_png(_first(tiny_scene, "depth"), np.zeros((24, 32), np.uint8))
    with pytest.raises(DataError, match="uint16"):
        Scene(tiny_scene).sequence("mapping")[0]


def test_objects_json_validation(tiny_scene: Path):
    (tiny_scene / "objects.json").write_text(json.dumps([{"id": 0, "category": "x"}]))
    with pytest.raises(DataError, match="id must be an integer >= 1"):
        Scene(tiny_scene)
    (tiny_scene / "objects.json").write_text(json.dumps([{"id": 1, "category": "x", "aabb": [[1, 1, 1], [0, 0, 0]]}]))
    with pytest.raises(DataError, match="min <= max"):
        Scene(tiny_scene)
    (tiny_scene / "objects.json").write_text("{broken")
    with pytest.raises(DataError, match="not valid JSON"):
        Scene(tiny_scene)


def test_writer_rejects_non_rigid_pose_and_writes_nothing(tmp_path: Path):
    w = SceneWriter(tmp_path)
    w.write_objects([ObjectInfo(id=1, category="a")])
    with pytest.raises(ValueError):
        w.write_frame("mapping", 0, np.zeros((4, 4, 3), np.uint8), None, None, np.diag([1, 1, 2, 1.0]))
    assert not w.has_frame("mapping", 0)


@pytest.mark.parametrize(
    "info, message",
    [
        ([1, 2], "expected a JSON object, got list"),
        ({"splits": {"mapping": "many"}}, "'splits' must map each split name to its number of frames"),
        ({"intrinsics": {"K": "x", "width": 32, "height": 24}}, "'intrinsics' must hold"),
        ({"intrinsics": {"K": [[1, 2]], "width": 32, "height": 24}}, "'intrinsics' must hold"),
        ({"intrinsics": {"width": "32", "height": 24}}, "'intrinsics' must hold"),
    ],
    ids=["a-list", "counts-not-numbers", "K-text", "K-wrong-shape", "width-text"],
)
def test_scene_json_is_checked_where_readers_rely_on_it(tiny_scene: Path, info, message: str) -> None:
    (tiny_scene / "scene.json").write_text(json.dumps(info))
    with pytest.raises(DataError, match=message) as e:
        Scene(tiny_scene)
    assert "scene.json" in str(e.value)


@pytest.mark.parametrize(
    "entry, message",
    [
        (5, "expected a mapping, got int"),
        ({"id": 1, "category": "x", "aabb": "no"}, "aabb must be"),
        ({"id": 1, "category": "x", "aabb": [[float("nan"), 0, 0], [1, 1, 1]]}, "aabb must be"),
        ({"id": 1, "category": "x", "transform": [[1, 0], [0, 1]]}, "transform must be a 4x4"),
        ({"id": True, "category": "x"}, "id must be an integer"),
    ],
)
def test_object_entries_of_the_wrong_shape_are_data_errors(tiny_scene: Path, entry, message: str) -> None:
    (tiny_scene / "objects.json").write_text(json.dumps([entry]))
    with pytest.raises(DataError, match=message):
        Scene(tiny_scene)


@pytest.mark.parametrize(
    "info, message",
    [
        (
            {"rooms": [{"rect": "x", "floor": 0, "name": "a", "kind": "b"}]},
            "'rooms' must be a list of entries with rect",
        ),
        ({"rooms": [{"rect": [0, 0, 1, 1], "name": "a", "kind": "b"}]}, "'rooms' must be a list"),
        ({"floors": [{"z": None}]}, "'floors' must be a list of entries with z"),
    ],
)
def test_the_layout_a_preview_draws_is_checked(tiny_scene: Path, info, message: str) -> None:
    (tiny_scene / "scene.json").write_text(json.dumps(info))
    with pytest.raises(DataError, match=message):
        Scene(tiny_scene)


def test_displacements_must_name_objects_of_the_scene(tiny_scene: Path) -> None:
    path = tiny_scene / "query_displaced" / "displacements.json"
    path.parent.mkdir()
    path.write_text(json.dumps([{"id": 7, "aabb_after": [[0, 0, 0], [1, 1, 1]]}]))
    with pytest.raises(DataError, match="displacements.json: expected a list of moved objects"):
        Scene(tiny_scene).displacements()


def test_generated_scene_of_another_data_version_is_refused(tiny_scene: Path) -> None:
    path = tiny_scene / "scene.json"
    info = json.loads(path.read_text())
    Scene(tiny_scene)  # no generator version: imported data, read whatever its age
    path.write_text(json.dumps({**info, "generator_version": "0.1.0+gen2"}))
    with pytest.raises(DataError, match=rf"benchmark data v1, this openreloc-bench reads v{DATA_VERSION}: regenerate"):
        Scene(tiny_scene)
    path.write_text(json.dumps({**info, "generator_version": "0.1.0+gen3", "data_version": DATA_VERSION}))
    assert Scene(tiny_scene).info["data_version"] == DATA_VERSION


def test_difficulty_table_is_read_and_checked(tiny_scene: Path) -> None:
    assert Scene(tiny_scene).difficulty() is None  # imported data has none
    row = {"split": "query", "frame": "000000", **{c: 1.0 for c in DIFFICULTY_COLUMNS[2:]}}
    SceneWriter(tiny_scene).write_difficulty(pd.DataFrame([row]))
    table = Scene(tiny_scene).difficulty()
    assert table["frame"].tolist() == ["000000"] and table["gap_m"].tolist() == [1.0]
    (tiny_scene / "difficulty.csv").write_text("split,frame\nquery,000000\n")
    with pytest.raises(DataError, match="missing column"):
        Scene(tiny_scene).difficulty()


def test_a_sequence_carries_the_track_it_was_opened_for(tiny_scene: Path):
    scene = Scene(tiny_scene)
    oracle = scene.sequence("query", "oracle-mask")
    assert oracle.track == "oracle-mask" and oracle.has_instances and oracle[0].instance is not None
    for track in ("predicted", "mask-free"):
        seq = scene.sequence("query", track)
        assert seq.track == track and not seq.has_instances and seq[0].instance is None
        assert seq.subset([0]).track == track
    # opened without a track: the one its instance images say (every frame has one here)
    assert scene.sequence("query").track == "oracle-mask"
    unmasked = scene.sequence("query")
    unmasked.records[0].instance_path = None
    assert unmasked.track == "predicted" and unmasked[1].instance is not None


def test_a_sequence_knows_the_folder_it_was_read_from(tiny_scene: Path):
    """Where its objects.json lies (the map builder reads it there), for every split."""
    scene = Scene(tiny_scene)
    assert scene.sequence("mapping").root == scene.sequence("query").root == tiny_scene
    assert scene.sequence("mapping").subset([0]).root == tiny_scene
