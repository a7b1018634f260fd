"""Render-and-compare: the true pose explains a box room's segmentation better than shifted or turned
poses, occluded landmarks are not drawn, and appearance weights follow the visual ranking."""

from __future__ import annotations

import numpy as np
import pytest

from openreloc_bench import geometry
from openreloc_bench.openreloc.consistency import (
    ConsistencyConfig,
    LabelRenderer,
    candidate_weights,
    consistency,
    query_labels,
)
from tests.openreloc.boxworld import ROOM, render

HW = (240, 320)
K = geometry.intrinsics_from_fov(HW[1], HW[0], 70.0)
T_WC = geometry.look_at(np.array([0.0, -1.5, 1.4]), np.array([1.5, 1.5, 0.5]))


def _surface_points(lo: tuple[float, ...], hi: tuple[float, ...], n: int, rng: np.random.Generator) -> np.ndarray:
    """``n`` points spread over the six faces of a box (what a mapped landmark keeps)."""
    lo_, hi_ = np.asarray(lo, float), np.asarray(hi, float)
    p = rng.uniform(lo_, hi_, (n, 3))
    axis = rng.integers(0, 3, n)
    side = rng.random(n) < 0.5
    p[np.arange(n), axis] = np.where(side, lo_[axis], hi_[axis])
    return p


@pytest.fixture(scope="module")
def room() -> dict:
    rng = np.random.default_rng(0)
    points = [_surface_points(b.lo, b.hi, 4000, rng) for b in ROOM]
    _, _, inst = render(ROOM, K, T_WC, HW)
    masks = [inst == b.id for b in ROOM if (inst == b.id).sum() > 50]
    ids = [b.id for b in ROOM if (inst == b.id).sum() > 50]
    row_of = {b.id: r for r, b in enumerate(ROOM)}
    similarity = np.full((len(masks), len(ROOM)), 0.1)
    similarity[np.arange(len(masks)), [row_of[i] for i in ids]] = 0.9  # each mask looks like its own landmark
    return {"points": points, "masks": masks, "similarity": similarity}


def _score(room: dict, T_wc: np.ndarray, cfg: ConsistencyConfig | None = None) -> float:
    cfg = cfg or ConsistencyConfig(points_per_landmark=4000, stride=4)
    renderer = LabelRenderer(room["points"], HW[1], HW[0], cfg)
    return consistency(
        renderer.render(T_wc, K), query_labels(room["masks"], cfg.stride), candidate_weights(room["similarity"], cfg)
    )


def test_true_pose_explains_most_of_the_segmentation(room: dict) -> None:
    # the room's walls and furniture: most masks are recovered with a high IoU
    assert _score(room, T_WC) > 0.6 * len(room["masks"])


@pytest.mark.parametrize("offset", [(0.6, 0.0, 0.0), (0.0, 0.8, 0.0), (-0.7, 0.4, 0.0)])
def test_shifted_poses_explain_less(room: dict, offset: tuple[float, float, float]) -> None:
    T = T_WC.copy()
    T[:3, 3] += offset
    assert _score(room, T) < _score(room, T_WC) - 0.5


@pytest.mark.parametrize("degrees", [15.0, 40.0])
def test_turned_poses_explain_less(room: dict, degrees: float) -> None:
    c, s = np.cos(np.radians(degrees)), np.sin(np.radians(degrees))
    T = T_WC.copy()
    T[:3, :3] = np.array([[c, -s, 0], [s, c, 0], [0, 0, 1]]) @ T_WC[:3, :3]
    assert _score(room, T) < _score(room, T_WC) - 0.5


def test_wrong_appearance_lowers_the_score(room: dict) -> None:
    wrong = dict(room, similarity=room["similarity"][:, ::-1].copy())  # every mask looks like another landmark
    cfg = ConsistencyConfig(points_per_landmark=4000, stride=4, candidates=1)
    assert _score(wrong, T_WC, cfg) < 0.5 * _score(room, T_WC, cfg)


def test_nearest_landmark_wins_each_cell() -> None:
    near = np.array([[0.0, 0.0, 2.0]])
    far = np.array([[0.0, 0.0, 5.0]])
    cfg = ConsistencyConfig(stride=8)
    T = np.eye(4)  # camera at the origin looking along +z
    Kc = geometry.intrinsics_from_fov(64, 64, 60.0)
    for order in ([near, far], [far, near]):
        renderer = LabelRenderer(order, 64, 64, cfg)
        drawn = renderer.render(T, Kc)
        assert drawn[drawn >= 0].tolist() == [
            next(r for r, p in enumerate(order) if p is near)
        ]  # one cell, the near one
    behind = LabelRenderer([np.array([[0.0, 0.0, -2.0]])], 64, 64, cfg)
    assert (behind.render(T, Kc) < 0).all()


@pytest.mark.parametrize(("splat", "holes"), [(0.0, True), (1.0, False)])
def test_a_near_landmark_is_drawn_solid_and_hides_what_is_behind_it(splat: float, holes: bool) -> None:
    """Points 4 cm apart at 0.8 m fall ~1.4 cells apart on an 8-px grid (f = 229 px): as single cells they
    let a wall behind show through; as squares of their spacing they cover the landmark's silhouette."""
    g = np.arange(-0.2, 0.2001, 0.04)
    near = np.array([[x, y, 0.8] for x in g for y in g])  # a 40 cm panel facing the camera
    wall = np.array([[x, y, 3.0] for x in np.arange(-2.0, 2.0, 0.02) for y in np.arange(-2.0, 2.0, 0.02)])
    Kc = geometry.intrinsics_from_fov(320, 240, 70.0)
    drawn = LabelRenderer([near, wall], 320, 240, ConsistencyConfig(stride=8, splat=splat)).render(np.eye(4), Kc)
    # cells well inside the panel's silhouette (it spans +-0.2 * f / 0.8 px around the image centre)
    half = int(0.15 * Kc[0, 0] / 0.8 / 8)
    cy, cx = 120 // 8, 160 // 8
    inside = drawn[cy - half : cy + half, cx - half : cx + half]
    assert ((inside != 0).any()) == holes
    assert (drawn == 1).any()  # the wall around the panel is drawn either way


def test_candidate_weights_follow_the_visual_ranking() -> None:
    sims = np.array([[0.9, 0.1, 0.5, 0.3], [0.0, 0.2, 0.1, 0.8]])
    w = candidate_weights(sims, ConsistencyConfig(candidates=2, off_candidate_weight=0.25))
    assert np.array_equal(w, [[1.0, 0.25, 1.0, 0.25], [0.25, 1.0, 0.25, 1.0]])


def test_each_mask_and_landmark_count_once() -> None:
    labels = np.array([[0, 0, 1, 1]])
    drawn = np.array([[5, 5, 5, 5]])  # one landmark covers both masks: only one may claim it
    score = consistency(drawn, labels, np.ones((2, 6)))
    assert score == pytest.approx(0.5)
