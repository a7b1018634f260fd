from __future__ import annotations

from collections.abc import Callable
from pathlib import Path

import numpy as np
import pytest

from baselines.features import FeatureMap
from baselines.sift_pnp import MAP_FORMAT, MAP_VERSION, SiftPnP
from openreloc_bench.data.scene import Scene
from openreloc_bench.errors import ConfigError
from openreloc_bench.methods import DRAWN_POINTS, create_method
from tests.baselines import contract

NAME = "sift-pnp"


def test_map_holds_what_queries_need(built_map: Callable[[str], Path], scenes: tuple[Scene, Scene]) -> None:
    fmap = FeatureMap.load(built_map(NAME), MAP_FORMAT, MAP_VERSION)
    n_frames = len(scenes[0].sequence("mapping"))
    assert fmap.n_frames == n_frames and fmap.features.descriptors.shape[1] == 128
    assert fmap.features.octaves is None  # SIFT's orientation and octave are not used at query time
    assert fmap.arrays["vlad"].shape[0] == n_frames
    assert fmap.meta["config"] == SiftPnP().map_config()


def test_query_time_settings_share_maps() -> None:
    assert SiftPnP(retrieval_k=3, ratio=0.7).map_config() == SiftPnP().map_config()
    assert SiftPnP(features={"max_keypoints": 100}).map_config() != SiftPnP().map_config()


def test_few_keypoints_fail(built_map: Callable[[str], Path], scenes: tuple[Scene, Scene]) -> None:
    query, _ = contract.query_of(scenes[0], "query", 0)
    query.color = np.full_like(query.color, 128)  # a flat image has no SIFT keypoint
    res = contract.loaded(NAME, built_map(NAME)).localize(query)
    assert "keypoints" in res.reason


@pytest.mark.parametrize(
    "overrides",
    [{"ratio": 1.5}, {"retrieval_k": 0}, {"min_inliers": 2}, {"features": {"contrast_threshold": -1}}, {"nope": 1}],
)
def test_config_validation(overrides: dict) -> None:
    with pytest.raises(ConfigError):
        create_method(NAME, **overrides)


def test_the_drawn_keypoints_are_the_matches_and_the_kept_ones_the_inliers(
    built_map: Callable[[str], Path], scenes: tuple[Scene, Scene]
) -> None:
    query, _ = contract.query_of(scenes[0], "query", 0)
    res = contract.loaded(NAME, built_map(NAME)).localize(query)
    points = np.asarray(res.diagnostics[DRAWN_POINTS])
    assert 0 < len(points) <= res.diagnostics["matches"] and points[:, 2].sum() == res.diagnostics["inliers"]
