from __future__ import annotations

from pathlib import Path

import numpy as np
import pytest

from baselines.features import FeatureMap, OrbConfig, build_feature_map, extract_orb
from openreloc_bench import geometry
from openreloc_bench.config import from_dict
from openreloc_bench.data.scene import Scene
from openreloc_bench.errors import ConfigError, DataError
from openreloc_bench.vision.local_features import Keypoints, SiftConfig, extract_sift


def test_orb_spreads_keypoints_over_levels_and_image(scenes: tuple[Scene, Scene]) -> None:
    frame = scenes[0].sequence("mapping")[0]
    cfg = OrbConfig(max_keypoints=400)
    feats = extract_orb(frame.color, cfg)
    assert 200 < len(feats) <= 400 and feats.descriptors.shape[1] == 32
    per_level = np.bincount(feats.octaves, minlength=cfg.levels)
    assert per_level[0] > per_level[-1] > 0  # a geometric share per level
    cells = np.unique((feats.xy[feats.octaves == 0] // 80).astype(int), axis=0)
    assert len(cells) >= 8  # level 0 is spread over the 4x3 grid of 80 px cells, not clustered


def test_orb_falls_back_to_the_low_threshold_in_dark_images(scenes: tuple[Scene, Scene]) -> None:
    dark = (scenes[0].sequence("mapping")[0].color * 0.15).astype(np.uint8)
    low = extract_orb(dark, OrbConfig(max_keypoints=400))
    high_only = extract_orb(dark, OrbConfig(max_keypoints=400, fast_threshold_min=20))
    assert len(low) > 2 * len(high_only)


def make_feature_map() -> FeatureMap:
    """Two mapping frames at the origin: 3 and 4 keypoints with random world points."""
    rng = np.random.default_rng(0)
    n = 7
    return FeatureMap(
        "test-map",
        3,
        geometry.intrinsics_from_fov(64, 48, 60.0),
        64,
        48,
        np.stack([np.eye(4)] * 2),
        np.array([0, 3, n]),
        Keypoints(
            rng.random((n, 2), dtype=np.float32),
            rng.integers(0, 255, (n, 32), dtype=np.uint8),
            rng.integers(0, 8, n).astype(np.int8),
            rng.random(n, dtype=np.float32),
        ),
        rng.random((n, 3), dtype=np.float32),
        {"extra": np.arange(5)},
        {"config": {"a": 1}},
    )


def test_feature_map_round_trip(tmp_path: Path) -> None:
    fmap = make_feature_map()
    fmap.save(tmp_path)
    back = FeatureMap.load(tmp_path, "test-map", 3)
    for name in ("K", "poses", "offsets", "points"):
        assert np.array_equal(getattr(back, name), getattr(fmap, name))
    for name in ("xy", "descriptors", "octaves", "angles"):
        assert np.array_equal(getattr(back.features, name), getattr(fmap.features, name))
    assert np.array_equal(back.arrays["extra"], np.arange(5)) and back.meta == {"config": {"a": 1}}
    assert back.frame_of().tolist() == [0, 0, 0, 1, 1, 1, 1] and back.rows([1]).tolist() == [3, 4, 5, 6]
    with pytest.raises(DataError, match="version"):
        FeatureMap.load(tmp_path, "test-map", 4)
    with pytest.raises(DataError, match="not a other-map"):
        FeatureMap.load(tmp_path, "other-map", 3)


def test_build_needs_depth(scenes: tuple[Scene, Scene]) -> None:
    seq = scenes[0].sequence("mapping")
    seq.records = [r.__class__(r.frame_id, r.color_path, r.T_wc) for r in seq.records]  # no depth paths
    with pytest.raises(DataError, match="depth"):
        build_feature_map(seq, lambda rgb: extract_sift(rgb, SiftConfig()), 0.05, "m", 1)


@pytest.mark.parametrize("cls,bad", [(SiftConfig, {"max_keypoints": 0}), (OrbConfig, {"fast_threshold_min": 30})])
def test_config_validation(cls: type, bad: dict) -> None:
    with pytest.raises(ConfigError):
        from_dict(cls, bad)


def test_a_feature_map_draws_its_points_by_the_frame_that_saw_them() -> None:
    fmap = make_feature_map()
    mp = fmap.drawn()
    assert np.array_equal(mp.points, fmap.points) and mp.group.tolist() == [0, 0, 0, 1, 1, 1, 1]
    assert mp.labels[1] == "seen from mapping frame 1 (4 points)" and len(mp.cameras) == 2
    assert mp.summary == "7 points from 2 mapping frames"
