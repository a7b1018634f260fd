from __future__ import annotations

import numpy as np
import pytest

from openreloc_bench import geometry
from openreloc_bench.config import from_dict
from openreloc_bench.errors import ConfigError
from openreloc_bench.vision.absolute_pose import AbsolutePoseConfig, estimate_absolute_pose


def test_recovers_the_pose_despite_outliers() -> None:
    rng = np.random.default_rng(0)
    K = geometry.intrinsics_from_fov(640, 480, 60.0)
    T_wc = geometry.look_at([0.5, -2.5, 1.4], [0.0, 0.0, 1.0])
    X = rng.uniform([-1.5, -0.5, 0.0], [1.5, 0.5, 2.0], (200, 3))
    xy, _ = geometry.project(K, T_wc, X)
    xy += rng.normal(0, 0.3, xy.shape)
    xy[:60] = rng.uniform([0, 0], [640, 480], (60, 2))
    est = estimate_absolute_pose(xy, X, K, 640, 480, AbsolutePoseConfig(max_error_px=4.0))
    assert est is not None
    t_err, r_err = geometry.pose_errors(T_wc, est.T_wc)
    assert t_err < 0.01 and r_err < 0.2
    assert est.inliers[60:].mean() > 0.95 and est.inliers[:60].sum() <= 3 and est.n_inliers == est.inliers.sum()
    again = estimate_absolute_pose(xy, X, K, 640, 480, AbsolutePoseConfig(max_error_px=4.0))
    assert np.array_equal(again.T_wc, est.T_wc)  # seeded


def test_too_few_matches() -> None:
    K = geometry.intrinsics_from_fov(64, 48, 60.0)
    assert estimate_absolute_pose(np.zeros((3, 2)), np.ones((3, 3)), K, 64, 48, AbsolutePoseConfig()) is None


def test_config_validation() -> None:
    with pytest.raises(ConfigError):
        from_dict(AbsolutePoseConfig, {"confidence": 1.0})
