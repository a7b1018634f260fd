"""The compiled dual-path loss: its Huber kernel and its backward path's nearest points."""

from __future__ import annotations

import numpy as np
import pytest
from scipy.spatial.distance import cdist

from openreloc_bench.openreloc.icp_kernel import BIG, _huber, dual_path


def test_huber_is_quadratic_then_linear_in_distance() -> None:
    delta = np.float32(10.0)
    values = [_huber(np.float32(d * d), delta) for d in (0.0, 3.0, 10.0, 20.0)]
    assert np.allclose([v for v, _ in values], [0.0, 9.0, 100.0, 2 * 10 * 20 - 100.0])
    assert np.allclose([s for _, s in values], [1.0, 1.0, 1.0, 0.5])  # d huber / d sq: delta / distance beyond


@pytest.mark.parametrize("absent", [0, 7])
def test_backward_path_pairs_each_pixel_with_its_nearest_point(absent: int) -> None:
    """Points straight ahead project to known pixels; those behind the camera (parked at 1e6) or padding
    must never be the nearest of a real pixel, and padded pixels count for nothing."""
    rng = np.random.default_rng(absent)
    P, M = 40, 50
    uv = rng.uniform(-40, 360, (P, 2)).astype(np.float32)
    depth = np.full(P, 2.0, np.float32)
    depth[P - absent :] = -1.0  # behind the camera
    fx = fy = np.float32(100.0)
    pts = np.stack([(uv[:, 0] - 160) * depth / fx, (uv[:, 1] - 120) * depth / fy, depth], -1)[None, None]
    pix = rng.uniform(0, 320, (1, 1, M, 2)).astype(np.float32)
    pix_valid = np.ones((1, 1, M), bool)
    pix_valid[..., -3:] = False
    nn_idx = np.zeros((1, 1, M), np.int64)
    table = np.zeros((240 * 320, 4), np.float32)
    dual_path(
        np.eye(3, dtype=np.float32)[None],
        np.zeros((1, 3), np.float32),
        pts.astype(np.float32),
        np.ones((1, 1, P), bool),
        table,
        np.zeros((1, 1), np.int64),
        pix,
        pix_valid,
        nn_idx,
        np.array([fx, fy, 160, 120], np.float32),
        240,
        320,
        0.05,
        10.0,
        True,
    )
    ahead = uv[: P - absent]
    exact = cdist(pix[0, 0, :-3], ahead).min(1)
    found = np.linalg.norm(uv[nn_idx[0, 0, :-3]] - pix[0, 0, :-3], axis=1)
    assert np.allclose(found, exact, atol=1e-3) and (nn_idx[0, 0, :-3] < P - absent).all()
    assert BIG > 1e5
