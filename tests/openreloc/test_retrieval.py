"""DIoU by hand and the co-visibility-then-DIoU choice of the coarse prior."""

from __future__ import annotations

import numpy as np
import pytest

from openreloc_bench.openreloc.map import ReferenceFrame
from openreloc_bench.openreloc.retrieval import diou_distance, retrieve_reference


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


def test_retrieval_prefers_most_shared_then_lowest_diou() -> None:
    query = {1: np.array([0, 0, 10, 10.0]), 2: np.array([20, 0, 30, 10.0]), 3: np.array([40, 0, 50, 10.0])}
    frames = [
        frame(0, {1: [0, 0, 10, 10], 2: [20, 0, 30, 10]}),  # perfect boxes but only 2 shared
        frame(1, {1: [5, 5, 15, 15], 2: [25, 5, 35, 15], 3: [45, 5, 55, 15]}, {1: 0.2, 2: 0.2, 3: 0.2}),
        frame(2, {1: [1, 0, 11, 10], 2: [21, 0, 31, 10], 3: [41, 0, 51, 10]}, {1: 0.1, 2: 0.1, 3: 0.1}),
        frame(3, {7: [0, 0, 10, 10]}),
    ]
    r = retrieve_reference(query, frames, "diou")
    assert r is not None and r.frame.index == 2 and r.shared == [1, 2, 3]
    assert [c[0] for c in r.candidates] == [2, 1]
    v = retrieve_reference(query, frames, "visibility")
    assert v is not None and v.frame.index == 1 and v.score == pytest.approx(0.2)


def test_no_shared_landmark_gives_none() -> None:
    assert retrieve_reference({5: np.array([0, 0, 1, 1.0])}, [frame(0, {1: [0, 0, 1, 1]})]) is None
    assert retrieve_reference({5: np.array([0, 0, 1, 1.0])}, []) is None
