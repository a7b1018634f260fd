"""SIFT with RootSIFT, and keypoints lifted to world points through depth."""

from __future__ import annotations

import numpy as np

from openreloc_bench import geometry
from openreloc_bench.vision.local_features import SiftConfig, extract_sift, lift, root_sift


def textured_image() -> np.ndarray:
    """A 240x320 RGB image of blurred random blobs: corners and blobs at every scale."""
    import cv2

    rng = np.random.default_rng(0)
    noise = cv2.resize(rng.integers(0, 255, (30, 40, 3), dtype=np.uint8), (320, 240), interpolation=cv2.INTER_CUBIC)
    return cv2.GaussianBlur(noise, (0, 0), 1.5)


def test_sift_and_root_sift() -> None:
    feats = extract_sift(textured_image(), SiftConfig(max_keypoints=500))
    assert 100 < len(feats) <= 500 and feats.descriptors.shape == (len(feats), 128)
    assert feats.descriptors.dtype == np.uint8 and feats.octaves is None
    r = root_sift(feats.descriptors)
    assert np.allclose(np.linalg.norm(r, axis=1), 1.0, atol=1e-5)


def test_lift_reprojects_and_rejects_depth_edges() -> None:
    K = geometry.intrinsics_from_fov(64, 48, 60.0)
    T_wc = geometry.look_at([1.0, -2.0, 1.0], [0.0, 0.0, 1.0])
    depth = np.full((48, 64), 2.0, np.float32)
    depth[:, 40:] = 3.0  # a depth edge at column 40
    depth[5, 5] = 0.0  # a hole
    xy = np.array([[20.3, 20.7], [39.6, 10.0], [5.0, 6.0], [50.0, 30.0]], np.float32)
    points, valid = lift(xy, depth, K, T_wc, max_depth_step=0.05)
    assert valid.tolist() == [True, False, False, True]
    uv, z = geometry.project(K, T_wc, points[valid])
    assert np.allclose(uv, xy[valid], atol=1e-3) and np.allclose(z, [2.0, 3.0], atol=1e-5)
