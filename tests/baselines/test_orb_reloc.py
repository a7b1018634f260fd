from __future__ import annotations

from collections.abc import Callable
from pathlib import Path

import numpy as np
import pytest

from baselines.features import FeatureMap, extract_orb
from baselines.frame_retrieval import hamming_matrix
from baselines.orb_reloc import MAP_FORMAT, MAP_VERSION, OrbReloc, OrbRelocConfig, PnPRansac, optimize_pose
from openreloc_bench import geometry
from openreloc_bench.data.scene import Scene
from openreloc_bench.errors import ConfigError
from openreloc_bench.methods import create_method
from tests.baselines import contract

NAME = "orb-reloc"


def test_map_holds_what_queries_need(built_map: Callable[[str], Path], scenes: tuple[Scene, Scene]) -> None:
    fmap = FeatureMap.load(built_map(NAME), MAP_FORMAT, MAP_VERSION)
    assert fmap.features.descriptors.shape[1] == 32 and fmap.features.octaves is not None
    assert len(fmap.arrays["words"]) == len(fmap.points) == len(fmap.arrays["nodes"])
    cov = fmap.arrays["covisible"]
    assert cov.shape == (fmap.n_frames, OrbRelocConfig().covisible_neighbours)
    # consecutive mapping frames overlap: each keyframe has co-visible neighbours, never itself
    assert np.all(cov[:, 0] >= 0) and not np.any(cov == np.arange(fmap.n_frames)[:, None])


def test_sift_map_is_refused(built_map: Callable[[str], Path]) -> None:
    with pytest.raises(Exception, match="not a orb-reloc-map"):
        contract.loaded(NAME, built_map("sift-pnp"))


def test_candidates_include_the_frame_itself(built_map: Callable[[str], Path], scenes: tuple[Scene, Scene]) -> None:
    method = contract.loaded(NAME, built_map(NAME))
    fmap = method.map
    for kf in (0, 7):
        rows = fmap.rows([kf])
        assert kf in method.candidates(method.words[rows])


def _synthetic(n: int = 120, outliers: int = 40, seed: int = 0) -> tuple[np.ndarray, ...]:
    rng = np.random.default_rng(seed)
    K = geometry.intrinsics_from_fov(640, 480, 60.0)
    T_wc = geometry.look_at([0.3, -2.0, 1.2], [0.0, 0.0, 1.0])
    X = rng.uniform([-1, -0.5, 0.2], [1, 0.5, 2.0], (n, 3))
    xy, _ = geometry.project(K, T_wc, X)
    xy = xy + rng.normal(0, 0.5, xy.shape)
    xy[:outliers] = rng.uniform([0, 0], [640, 480], (outliers, 2))
    return K, geometry.invert(T_wc), X, xy


def test_pnp_ransac_and_pose_optimisation_recover_the_pose() -> None:
    K, T_cw, X, xy = _synthetic()
    sigma2 = np.ones(len(X))
    ransac = PnPRansac(xy, X, sigma2, K, OrbRelocConfig(), np.random.default_rng(0))
    pose, inliers, _ = ransac.iterate(300)
    assert pose is not None and inliers[:40].sum() <= 2 and inliers[40:].mean() > 0.9
    noisy = geometry.make_pose(np.eye(3), [0.02, -0.01, 0.03]) @ pose
    refined, good = optimize_pose(noisy, xy, X, sigma2, K)
    t_err, r_err = geometry.pose_errors(geometry.invert(T_cw), geometry.invert(refined))
    assert t_err < 0.01 and r_err < 0.2
    assert good[40:].mean() > 0.9 and good[:40].sum() <= 2


def test_rotation_histogram_keeps_the_consistent_matches() -> None:
    method = OrbReloc()
    rot = np.r_[np.full(50, 30.0), np.full(10, 45.0), np.full(3, 200.0), [359.0]]
    keep = method.rotation_consistent(rot)
    assert keep[:60].all() and not keep[60:63].any()


@pytest.mark.parametrize(
    "overrides",
    [{"min_inliers": 3}, {"bow_ratio": 0}, {"direct_index_level": 9}, {"features": {"scale_factor": 1.0}}, {"x": 1}],
)
def test_config_validation(overrides: dict) -> None:
    with pytest.raises(ConfigError):
        create_method(NAME, **overrides)


def test_search_by_projection_finds_the_keyframes_own_points(
    built_map: Callable[[str], Path], scenes: tuple[Scene, Scene]
) -> None:
    method = contract.loaded(NAME, built_map(NAME))
    kf = 5
    query, T_wc = contract.query_of(scenes[0], "mapping", kf)
    feats = extract_orb(query.color, method.config.features)
    rows = method.map.rows([kf])
    dist = hamming_matrix(method.map.features.descriptors[rows], feats.descriptors)
    T_cw = geometry.invert(T_wc @ geometry.make_pose(np.eye(3), [0.01, 0.0, -0.01]))
    none = np.zeros(0, int)
    qi, ri = method.search_by_projection(T_cw, rows, dist, feats, none, none, 10, 100, query)
    assert len(qi) > 0.8 * len(rows) and len(np.unique(qi)) == len(qi)
    same_place = np.linalg.norm(feats.xy[qi] - method.map.features.xy[rows[ri]], axis=1) < 1.0
    assert same_place.mean() > 0.9
    # points already found are not searched again
    qi2, ri2 = method.search_by_projection(T_cw, rows, dist, feats, qi, ri, 10, 100, query)
    assert not set(ri2) & set(ri) and not set(qi2) & set(qi)
