"""Poses fitted to object boxes: from exact boxes the true pose, in a batch as one at a time, and the
extreme points whose projected box is the object's."""

from __future__ import annotations

import numpy as np
import pytest
from scipy.spatial.transform import Rotation

from openreloc_bench import geometry
from openreloc_bench.openreloc.box_fit import extreme_points, fit_boxes_many

K = geometry.intrinsics_from_fov(320, 240, 70.0)


@pytest.mark.parametrize("eye", [(0.0, -3.0, 1.5), (0.8, -1.6, 1.5)])  # all boxes inside; one cut by the border
def test_fit_boxes_recovers_the_pose_from_exact_boxes(eye: tuple[float, float, float]) -> None:
    rng = np.random.default_rng(0)
    corners = [
        np.array([[x, y, z] for x in (0, 1) for y in (0, 1) for z in (0, 1)]) * rng.uniform(0.3, 0.8, 3)
        + rng.uniform([-1.5, -0.5, 0.0], [1.5, 1.5, 0.8])
        for _ in range(5)
    ]
    extremes = np.array([extreme_points(c) for c in corners])
    w, h = 640, 480
    Kw = geometry.intrinsics_from_fov(w, h, 60.0)
    T_wc = geometry.look_at(np.array(eye), np.array([0.3, 0.5, 0.4]))
    T_cw = geometry.invert(T_wc)
    uv, _ = geometry.project(Kw, T_wc, extremes.reshape(-1, 3))
    uv = uv.reshape(5, -1, 2)
    boxes = np.clip(np.concatenate([uv.min(1), uv.max(1)], 1), 0, [w, h, w, h])  # what a mask shows
    cut = (boxes[:, :2] <= 0).any() or (boxes[:, 2:] >= (w, h)).any()
    assert cut == (eye[0] != 0.0)
    for _ in range(10):
        R0 = Rotation.from_rotvec(rng.normal(0, 0.08, 3)).as_matrix() @ T_cw[:3, :3]
        fit = fit_one(extremes, boxes, Kw, (w, h), R0, T_cw[:3, 3] + rng.normal(0, 0.3, 3))
        assert fit is not None
        t_err, r_err = geometry.pose_errors(T_wc, geometry.invert(geometry.make_pose(*fit)))
        assert t_err < 1e-3 and r_err < 0.01


def test_batched_box_fits_equal_one_at_a_time_fits() -> None:
    """Starts with different box counts, padded into one batch, each with its own damping and stopping,
    land exactly where their fits one at a time land."""
    rng = np.random.default_rng(1)
    w, h = 640, 480
    Kw = geometry.intrinsics_from_fov(w, h, 60.0)
    T_cw = geometry.invert(geometry.look_at(np.array([0.3, -3.0, 1.5]), np.array([0.3, 0.5, 0.4])))
    starts = []
    for n in (3, 5, 4):
        corners = [
            np.array([[x, y, z] for x in (0, 1) for y in (0, 1) for z in (0, 1)]) * rng.uniform(0.3, 0.8, 3)
            + rng.uniform([-1.5, -0.5, 0.0], [1.5, 1.5, 0.8])
            for _ in range(n)
        ]
        extremes = np.array([extreme_points(c) for c in corners])
        uv, _ = geometry.project(Kw, geometry.invert(T_cw), extremes.reshape(-1, 3))
        uv = uv.reshape(n, -1, 2)
        boxes = np.clip(np.concatenate([uv.min(1), uv.max(1)], 1), 0, [w, h, w, h]) + rng.normal(0, 2, (n, 4))
        R0 = Rotation.from_rotvec(rng.normal(0, 0.1, 3)).as_matrix() @ T_cw[:3, :3]
        starts.append((extremes, boxes, R0, T_cw[:3, 3] + rng.normal(0, 0.3, 3)))
    E = np.zeros((3, 5, 14, 3))
    B = np.zeros((3, 5, 4))
    valid = np.zeros((3, 5), bool)
    for s, (e, b, _, _) in enumerate(starts):
        E[s, : len(b)], B[s, : len(b)], valid[s, : len(b)] = e, b, True
    R, t, ok = fit_boxes_many(
        E, B, valid, Kw, (w, h), np.stack([s[2] for s in starts]), np.stack([s[3] for s in starts]), scale=10.0
    )
    assert ok.all()
    for s, (e, b, R0, t0) in enumerate(starts):
        single = fit_one(e, b, Kw, (w, h), R0, t0)
        assert (
            single is not None and np.allclose(single[0], R[s], atol=1e-9) and np.allclose(single[1], t[s], atol=1e-9)
        )


def fit_one(extremes, boxes, K, size, R, t):
    """One start of :func:`fit_boxes_many`, alone in its batch: (R, t), or None where it diverged."""
    R_fit, t_fit, ok = fit_boxes_many(
        extremes[None], boxes[None], np.ones((1, len(boxes)), bool), K, size, R[None], t[None], scale=10.0
    )
    return (R_fit[0], t_fit[0]) if ok[0] else None


def test_extreme_points_bound_a_box_from_any_view() -> None:
    rng = np.random.default_rng(1)
    pts = rng.uniform([-1, -0.5, 0], [1, 0.5, 0.8], size=(2000, 3))
    ext = extreme_points(pts)
    assert ext.shape == (14, 3)
    for _ in range(5):
        T = geometry.look_at(rng.uniform(-4, 4, 3) + [0, 0, 6], np.zeros(3))
        uv_all, _ = geometry.project(K, T, pts)
        uv_ext, _ = geometry.project(K, T, ext)
        span = uv_all.max(0) - uv_all.min(0)
        # the extremes' box covers at least 90% of the true box's width and height
        assert np.all(uv_ext.max(0) - uv_ext.min(0) >= 0.9 * span)
