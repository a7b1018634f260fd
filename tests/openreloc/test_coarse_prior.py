"""DIoU by hand and the co-visibility-then-DIoU choice of the coarse prior."""

from __future__ import annotations

import numpy as np
import pytest

from openreloc_bench import geometry
from openreloc_bench.openreloc.coarse_prior import (
    CoarseConfig,
    diou_distance,
    place_landmarks,
    pnp_prior,
    rank_reference_frames,
    solve_pnp,
)
from openreloc_bench.openreloc.map import ReferenceFrame


@pytest.mark.parametrize(
    "a, b, expected",
    [
        ([0, 0, 2, 2], [0, 0, 2, 2], 0.0),
        # IoU = 2 / 6; centres 1 apart; enclosing 3x2 -> c^2 = 13
        ([0, 0, 2, 2], [1, 0, 3, 2], 1 - 2 / 6 + 1 / 13),
        # disjoint: IoU 0; centres (1,1) and (5,1): 16; enclosing 6x2 -> 40
        ([0, 0, 2, 2], [4, 0, 6, 2], 1 + 16 / 40),
    ],
)
def test_diou_by_hand(a, b, expected) -> None:
    assert diou_distance(np.array(a), np.array(b)) == pytest.approx(expected)


def test_diou_ranks_far_disjoint_boxes_lower_than_near_ones() -> None:
    q = np.array([0, 0, 2, 2])
    assert diou_distance(q, np.array([3, 0, 5, 2])) < diou_distance(q, np.array([10, 0, 12, 2]))


def frame(index: int, boxes: dict[int, list[float]], vis: dict[int, float] | None = None) -> ReferenceFrame:
    return ReferenceFrame(index, np.eye(4) * 1.0, {k: np.array(v, np.float32) for k, v in boxes.items()}, vis or {})


def test_the_prior_is_the_most_shared_then_lowest_diou_frame() -> None:
    query = {1: np.array([0, 0, 10, 10.0]), 2: np.array([20, 0, 30, 10.0]), 3: np.array([40, 0, 50, 10.0])}
    frames = [
        frame(0, {1: [0, 0, 10, 10], 2: [20, 0, 30, 10]}),  # perfect boxes but only 2 shared
        frame(1, {1: [5, 5, 15, 15], 2: [25, 5, 35, 15], 3: [45, 5, 55, 15]}, {1: 0.2, 2: 0.2, 3: 0.2}),
        frame(2, {1: [1, 0, 11, 10], 2: [21, 0, 31, 10], 3: [41, 0, 51, 10]}, {1: 0.1, 2: 0.1, 3: 0.1}),
        frame(3, {7: [0, 0, 10, 10]}),
    ]
    r = rank_reference_frames(query, frames, "diou")
    assert r is not None and r.frame.index == 2 and r.shared == [1, 2, 3]
    assert [c[0] for c in r.candidates] == [2, 1]
    v = rank_reference_frames(query, frames, "visibility")
    assert v is not None and v.frame.index == 1 and v.score == pytest.approx(0.2)


def test_no_shared_landmark_gives_none() -> None:
    assert rank_reference_frames({5: np.array([0, 0, 1, 1.0])}, [frame(0, {1: [0, 0, 1, 1]})]) is None
    assert rank_reference_frames({5: np.array([0, 0, 1, 1.0])}, []) is None


def test_ranked_lists_every_sharing_frame_most_shared_first() -> None:
    query = {1: np.array([0, 0, 10, 10.0]), 2: np.array([20, 0, 30, 10.0]), 3: np.array([40, 0, 50, 10.0])}
    frames = [
        frame(0, {1: [0, 0, 10, 10], 2: [20, 0, 30, 10]}),
        frame(1, {1: [5, 5, 15, 15], 2: [25, 5, 35, 15], 3: [45, 5, 55, 15]}),
        frame(2, {1: [1, 0, 11, 10], 2: [21, 0, 31, 10], 3: [41, 0, 51, 10]}),
        frame(3, {7: [0, 0, 10, 10]}),
    ]
    r = rank_reference_frames(query, frames, "diou")
    assert r is not None and [f.index for f in r.ranked] == [2, 1, 0] and r.ranked[0] is r.frame


# landmarks 0-1: a chair and a lamp in room A; 2-3: their look-alikes in room B; 4: a wall (-inf: not matchable)
PLACE_SCORES = np.array(
    [
        [0.90, 0.30, 0.92, 0.30, -np.inf],  # the chair: its room-B twin looks a little more alike
        [0.20, 0.80, 0.20, 0.70, -np.inf],
    ]
)  # the lamp: room A's is clearly its own
PLACE_VISIBLE = np.array(
    [
        [1, 1, 0, 0, 1],  # a frame of room A
        [0, 0, 1, 1, 1],  # a frame of room B
        [0, 0, 1, 0, 0],
    ],
    bool,
)  # room B's chair alone


@pytest.mark.parametrize(("frames", "expected"), [(1, [1, 1, 0, 0, 1]), (2, [1, 1, 1, 1, 1]), (0, [0, 0, 0, 0, 0])])
def test_place_landmarks_are_those_of_the_frames_explaining_every_object(frames: int, expected: list[int]) -> None:
    """Room A's frame explains both objects within 0.02 of their best; room B's falls 0.1 short on the
    lamp, and the frame seeing only B's chair is clipped (0.2) for the lamp: A, then B."""
    np.testing.assert_array_equal(place_landmarks(PLACE_SCORES, PLACE_VISIBLE, frames), np.array(expected, bool))


def test_place_landmarks_bound_what_one_object_costs_a_frame() -> None:
    """Room A's frame sees the chair's and the lamp's own landmarks but not a third object's (0.6 short);
    room B's sees the third object's and is 0.15 short on the chair and the lamp. Each object costs a
    frame at most 0.2, so the frame explaining two objects outright wins (unbounded, B would: 0.3 < 0.6)."""
    scores = np.array(
        [
            [0.90, 0.30, 0.75, 0.30, -np.inf, 0.0],
            [0.20, 0.80, 0.20, 0.65, -np.inf, 0.0],
            [0.10, 0.10, 0.10, 0.10, -np.inf, 0.7],
        ]
    )
    visible = np.array([[1, 1, 0, 0, 1, 0], [0, 0, 1, 1, 1, 1]], bool)
    np.testing.assert_array_equal(place_landmarks(scores, visible, 1), [1, 1, 0, 0, 1, 0])
    np.testing.assert_array_equal(place_landmarks(scores, visible, 1, clip=1.0), [0, 0, 1, 1, 1, 1])


K = geometry.intrinsics_from_fov(160, 120, 60.0)
T_TRUE = geometry.look_at([0.5, -3.0, 1.4], [0.0, 0.0, 0.8])


def blob(centre: np.ndarray, n: int = 200, seed: int = 0) -> np.ndarray:
    return centre + np.random.default_rng(seed).normal(0, 0.05, (n, 3))


@pytest.mark.parametrize("iterations", [0, 2])
def test_pnp_recovers_the_pose_from_object_centroids(iterations: int) -> None:
    centres = np.array([[-1.0, 0.0, 0.5], [1.0, 0.5, 0.3], [0.2, 1.0, 1.5], [-0.5, -0.8, 1.0], [0.8, -0.5, 1.2]])
    points = [blob(c, seed=i) for i, c in enumerate(centres)]
    uv = np.stack([geometry.project(K, T_TRUE, p)[0].mean(0) for p in points])  # ~ projected centres
    T = pnp_prior(uv, np.zeros(len(uv), bool), points, K, (160, 120), CoarseConfig(pnp_iterations=iterations))
    assert T is not None
    te, re = geometry.pose_errors(T_TRUE, T)
    assert te < 0.1 and re < 2.0, (te, re)


def test_pnp_needs_four_objects() -> None:
    pts = [blob(np.array([x, 0.0, 1.0])) for x in (-1.0, 0.0, 1.0)]
    uv = np.stack([geometry.project(K, T_TRUE, p)[0].mean(0) for p in pts])
    assert pnp_prior(uv, np.zeros(3, bool), pts, K, (160, 120), CoarseConfig()) is None


@pytest.mark.parametrize(("ransac_threshold", "outlier"), [(None, False), (4.0, False), (4.0, True)])
def test_solve_pnp_recovers_the_camera(ransac_threshold: float | None, outlier: bool) -> None:
    """Exact correspondences give the pose back; with RANSAC, a grossly wrong one is ignored."""
    K = geometry.intrinsics_from_fov(640, 480, 60.0)
    T_wc = geometry.look_at([0.5, -3.0, 1.4], [0.0, 0.0, 0.8])
    X = np.random.default_rng(0).uniform([-1.5, -1.0, 0.0], [1.5, 1.0, 2.0], (8, 3))
    uv, _ = geometry.project(K, T_wc, X)
    if outlier:
        uv[0] += 120.0
    T_cw = solve_pnp(X, uv, K, ransac_threshold)
    assert T_cw is not None and geometry.translation_error(T_wc, geometry.invert(T_cw)) < 1e-3


def test_solve_pnp_with_too_few_points_is_none() -> None:
    K = geometry.intrinsics_from_fov(640, 480, 60.0)
    assert solve_pnp(np.zeros((2, 3)), np.zeros((2, 2)), K) is None
    assert solve_pnp(np.zeros((3, 3)), np.zeros((3, 2)), K, ransac_threshold=4.0) is None
