"""``nearest-frame``: thumbnail retrieval, the floor of every leaderboard."""

from pathlib import Path

import numpy as np
import pytest

from baselines.nearest_frame import NearestFrame
from openreloc_bench import geometry
from openreloc_bench.data.scene import Scene
from openreloc_bench.errors import ConfigError, DataError
from openreloc_bench.methods import PoseEstimate, QueryFrame, method_config


def test_nearest_frame_retrieves_the_matching_mapping_frame(tiny_scene: Path, tmp_path: Path):
    scene = Scene(tiny_scene)
    mapping = scene.sequence("mapping")
    m = NearestFrame(thumb_size=8)
    m.build_map(mapping, tmp_path / "map")
    m2 = NearestFrame(thumb_size=8)
    m2.load_map(tmp_path / "map")
    for i in (0, 3):
        f = mapping[i]
        est = m2.localize(QueryFrame(f.name, f.color, f.K))
        assert isinstance(est, PoseEstimate)
        assert est.diagnostics["mapping_index"] == i
        assert geometry.translation_error(f.T_wc, est.T_wc) < 1e-6
    # brightness change must not change the answer (zero-mean, unit-norm thumbnails)
    f = mapping[4]
    darker = (f.color * 0.6).astype(np.uint8)
    assert m2.localize(QueryFrame(f.name, darker, f.K)).diagnostics["mapping_index"] == 4
    assert method_config(m2) == {"name": "nearest-frame", "config": {"thumb_size": 8}}


def test_load_missing_map(tmp_path: Path):
    with pytest.raises(DataError, match="no nearest-frame-map here"):
        NearestFrame().load_map(tmp_path)


def test_corrupted_or_mismatched_nearest_frame_map_is_a_one_line_error(tiny_scene: Path, tmp_path: Path):
    NearestFrame(thumb_size=8).build_map(Scene(tiny_scene).sequence("mapping"), tmp_path)
    with pytest.raises(DataError, match="config.json: map built with"):
        NearestFrame(thumb_size=16).load_map(tmp_path)
    blob = (tmp_path / "thumbs.npz").read_bytes()
    (tmp_path / "thumbs.npz").write_bytes(blob[: len(blob) // 2])
    with pytest.raises(DataError, match="thumbs.npz: checksum mismatch"):
        NearestFrame(thumb_size=8).load_map(tmp_path)


@pytest.mark.parametrize("value", [-5, 0, 1000, "big", 8.5])
def test_invalid_nearest_frame_settings_are_config_errors(value: object):
    with pytest.raises(ConfigError, match="thumb_size"):
        NearestFrame(thumb_size=value)


def test_query_track():
    img = np.zeros((2, 2, 3), np.uint8)
    assert QueryFrame("q/1", img, np.eye(3)).track == "predicted"
    assert QueryFrame("q/1", img, np.eye(3), instance=np.zeros((2, 2), int)).track == "oracle-mask"
